// Speed frame codec: exact raw bytes (worked out by hand in the comments), frame classification,
// saturation and spec validation. Real-time path checked for allocations.
#include "ptda/config/speed_codec.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <initializer_list>
#include <limits>
#include <string>

#include "alloc_counter.hpp"
#include "ptda/common/error.hpp"

namespace ptda::config {
namespace {

CanFrame make_frame(std::uint32_t id, std::uint8_t flags, std::initializer_list<std::uint8_t> bytes) {
  CanFrame f;
  f.id = id;
  f.flags = flags;
  f.len = static_cast<std::uint8_t>(bytes.size());
  std::size_t i = 0;
  for (auto b : bytes) f.data[i++] = b;
  return f;
}

void expect_bytes(const CanFrame& f, std::initializer_list<std::uint8_t> bytes) {
  ASSERT_EQ(f.len, bytes.size());
  std::size_t i = 0;
  for (auto b : bytes) {
    EXPECT_EQ(f.data[i], b) << "byte " << i;
    ++i;
  }
}

std::string error_of(const SpeedFrameSpec& spec) {
  try {
    validate(spec);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(SpeedCodec, DefaultFrameEncodesExactBytes) {
  const SpeedFrameSpec spec;  // 0x184, int32 LE speed 1e-4 rad/s in 0..3, int32 LE angle 1e-5 rad in 4..7
  // 3.4907 rad/s -> raw 34907 = 0x0000885B -> 5B 88 00 00.
  // 1.5 rad      -> raw 150000 = 0x000249F0 -> F0 49 02 00.
  const CanFrame f = encode_speed(spec, 123456789, 3.4907, 1.5);
  EXPECT_EQ(f.id, 0x184U);
  EXPECT_FALSE(f.extended());
  EXPECT_FALSE(f.rtr());
  EXPECT_EQ(f.t_ns, 123456789);
  expect_bytes(f, {0x5B, 0x88, 0x00, 0x00, 0xF0, 0x49, 0x02, 0x00});
}

TEST(SpeedCodec, DefaultFrameNegativeValues) {
  const SpeedFrameSpec spec;
  // -3.4907 rad/s -> raw -34907 -> 2^32 - 34907 = 0xFFFF77A5 -> A5 77 FF FF.
  // -0.5 rad      -> raw -50000 -> 2^32 - 50000 = 0xFFFF3CB0 -> B0 3C FF FF.
  const CanFrame f = encode_speed(spec, 0, -3.4907, -0.5);
  expect_bytes(f, {0xA5, 0x77, 0xFF, 0xFF, 0xB0, 0x3C, 0xFF, 0xFF});
  DecodedSpeed out;
  ASSERT_EQ(decode_speed(f, spec, out), DecodeResult::kOk);
  EXPECT_DOUBLE_EQ(out.speed_rad_s, -3.4907);
  EXPECT_DOUBLE_EQ(out.angle_rad, -0.5);
  EXPECT_TRUE(out.has_angle);
}

TEST(SpeedCodec, DecodesHandWrittenDefaultFrame) {
  const SpeedFrameSpec spec;
  const CanFrame f = make_frame(0x184, 0, {0x5B, 0x88, 0x00, 0x00, 0xF0, 0x49, 0x02, 0x00});
  DecodedSpeed out;
  ASSERT_EQ(decode_speed(f, spec, out), DecodeResult::kOk);
  EXPECT_DOUBLE_EQ(out.speed_rad_s, 3.4907);
  EXPECT_DOUBLE_EQ(out.angle_rad, 1.5);
  EXPECT_TRUE(out.has_angle);
}

TEST(SpeedCodec, RoundsToNearestRawStep) {
  const SpeedFrameSpec spec;
  // 3.49074 / 1e-4 = 34907.4 -> 34907 (5B 88); 3.49076 -> 34907.6 -> 34908 = 0x885C (5C 88).
  EXPECT_EQ(encode_speed(spec, 0, 3.49074, 0.0).data[0], 0x5B);
  EXPECT_EQ(encode_speed(spec, 0, 3.49076, 0.0).data[0], 0x5C);
  // -3.49076 -> -34908 -> 0xFFFF77A4.
  EXPECT_EQ(encode_speed(spec, 0, -3.49076, 0.0).data[0], 0xA4);
}

TEST(SpeedCodec, RoundTripsOverRange) {
  const SpeedFrameSpec spec;
  for (int i = -2000; i <= 2000; ++i) {
    const double speed = i * 0.00537;  // not a multiple of the raw step
    const double angle = i * -0.00311;
    DecodedSpeed out;
    ASSERT_EQ(decode_speed(encode_speed(spec, 0, speed, angle), spec, out), DecodeResult::kOk);
    EXPECT_NEAR(out.speed_rad_s, speed, 0.5e-4 + 1e-12);
    EXPECT_NEAR(out.angle_rad, angle, 0.5e-5 + 1e-12);
  }
}

TEST(SpeedCodec, BigEndianTwoByteSigned) {
  SpeedFrameSpec spec;
  spec.dlc = 4;
  spec.has_angle = false;
  spec.speed = SignalSpec{2, 2, false, true, 0.01, 0.0};
  // -1.23 / 0.01 = -123 -> 16-bit 0xFF85, big endian at byte 2: FF 85.
  const CanFrame f = encode_speed(spec, 0, -1.23, 99.0);
  expect_bytes(f, {0x00, 0x00, 0xFF, 0x85});
  DecodedSpeed out;
  ASSERT_EQ(decode_speed(f, spec, out), DecodeResult::kOk);
  EXPECT_DOUBLE_EQ(out.speed_rad_s, -1.23);
  EXPECT_FALSE(out.has_angle);
  EXPECT_EQ(out.angle_rad, 0.0);
  // 0x0102 big endian = 258 -> 2.58; the same bytes little endian would be 0x0201 = 513.
  ASSERT_EQ(decode_speed(make_frame(0x184, 0, {0x00, 0x00, 0x01, 0x02}), spec, out), DecodeResult::kOk);
  EXPECT_DOUBLE_EQ(out.speed_rad_s, 2.58);
  spec.speed.little_endian = true;
  ASSERT_EQ(decode_speed(make_frame(0x184, 0, {0x00, 0x00, 0x01, 0x02}), spec, out), DecodeResult::kOk);
  EXPECT_DOUBLE_EQ(out.speed_rad_s, 5.13);
}

TEST(SpeedCodec, BigEndianFourByteWithAngle) {
  SpeedFrameSpec spec;
  spec.speed.little_endian = false;
  spec.angle.little_endian = false;
  // Same raw values as the default frame, most significant byte first.
  const CanFrame f = encode_speed(spec, 0, 3.4907, 1.5);
  expect_bytes(f, {0x00, 0x00, 0x88, 0x5B, 0x00, 0x02, 0x49, 0xF0});
}

TEST(SpeedCodec, UnsignedOneByteWithOffset) {
  SpeedFrameSpec spec;
  spec.has_angle = false;
  spec.speed = SignalSpec{7, 1, true, false, 0.1, -10.0};
  // (5 - (-10)) / 0.1 = 150 = 0x96 at byte 7.
  const CanFrame f = encode_speed(spec, 0, 5.0, 0.0);
  expect_bytes(f, {0, 0, 0, 0, 0, 0, 0, 0x96});
  DecodedSpeed out;
  // 0xFF unsigned = 255 -> 25.5 - 10 = 15.5 (signed it would be -1 -> -10.1).
  ASSERT_EQ(decode_speed(make_frame(0x184, 0, {0, 0, 0, 0, 0, 0, 0, 0xFF}), spec, out), DecodeResult::kOk);
  EXPECT_DOUBLE_EQ(out.speed_rad_s, 15.5);
  spec.speed.is_signed = true;
  ASSERT_EQ(decode_speed(make_frame(0x184, 0, {0, 0, 0, 0, 0, 0, 0, 0xFF}), spec, out), DecodeResult::kOk);
  EXPECT_DOUBLE_EQ(out.speed_rad_s, -10.1);
}

TEST(SpeedCodec, ThreeByteSignedSignExtends) {
  SpeedFrameSpec spec;
  spec.dlc = 5;
  spec.has_angle = false;
  spec.speed = SignalSpec{1, 3, true, true, 1e-3, 0.0};
  // -2.5 / 1e-3 = -2500 -> 24-bit 2^24 - 2500 = 0xFFF63C -> LE at byte 1: 3C F6 FF.
  const CanFrame f = encode_speed(spec, 0, -2.5, 0.0);
  expect_bytes(f, {0x00, 0x3C, 0xF6, 0xFF, 0x00});
  DecodedSpeed out;
  ASSERT_EQ(decode_speed(f, spec, out), DecodeResult::kOk);
  EXPECT_DOUBLE_EQ(out.speed_rad_s, -2.5);
  // 0x800000 is the most negative 24-bit value: -8388608 -> -8388.608.
  ASSERT_EQ(decode_speed(make_frame(0x184, 0, {0xAA, 0x00, 0x00, 0x80, 0xAA}), spec, out), DecodeResult::kOk);
  EXPECT_DOUBLE_EQ(out.speed_rad_s, -8388.608);
  // 0x7FFFFF = 8388607 stays positive.
  ASSERT_EQ(decode_speed(make_frame(0x184, 0, {0x00, 0xFF, 0xFF, 0x7F, 0x00}), spec, out), DecodeResult::kOk);
  EXPECT_DOUBLE_EQ(out.speed_rad_s, 8388.607);
  // Big endian 80 00 01 = 0x800001 = -8388607.
  spec.speed.little_endian = false;
  ASSERT_EQ(decode_speed(make_frame(0x184, 0, {0x00, 0x80, 0x00, 0x01, 0x00}), spec, out), DecodeResult::kOk);
  EXPECT_DOUBLE_EQ(out.speed_rad_s, -8388.607);
}

TEST(SpeedCodec, EightByteSignals) {
  SpeedFrameSpec spec;
  spec.has_angle = false;
  spec.speed = SignalSpec{0, 8, true, true, 1.0, 0.0};
  expect_bytes(encode_speed(spec, 0, -1.0, 0.0), {0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF});
  DecodedSpeed out;
  const CanFrame all_ones = make_frame(0x184, 0, {0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF});
  ASSERT_EQ(decode_speed(all_ones, spec, out), DecodeResult::kOk);
  EXPECT_EQ(out.speed_rad_s, -1.0);
  spec.speed.is_signed = false;
  ASSERT_EQ(decode_speed(all_ones, spec, out), DecodeResult::kOk);
  EXPECT_EQ(out.speed_rad_s, 18446744073709551615.0);  // 2^64 - 1 rounds to 2^64 in double
  // Saturation of a 64-bit unsigned signal at its top.
  expect_bytes(encode_speed(spec, 0, 1e30, 0.0), {0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF});
  spec.speed.is_signed = true;
  // Signed 64-bit saturates to 0x7FFF'FFFF'FFFF'FFFF and 0x8000'0000'0000'0000.
  expect_bytes(encode_speed(spec, 0, 1e30, 0.0), {0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0x7F});
  expect_bytes(encode_speed(spec, 0, -1e30, 0.0), {0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x80});
}

TEST(SpeedCodec, Saturates) {
  const SpeedFrameSpec spec;
  // 1e6 rad/s / 1e-4 = 1e10 > INT32_MAX -> 0x7FFFFFFF; -1e6 -> INT32_MIN = 0x80000000.
  expect_bytes(encode_speed(spec, 0, 1e6, -1e6), {0xFF, 0xFF, 0xFF, 0x7F, 0x00, 0x00, 0x00, 0x80});
  expect_bytes(encode_speed(spec, 0, std::numeric_limits<double>::infinity(), 0.0),
               {0xFF, 0xFF, 0xFF, 0x7F, 0x00, 0x00, 0x00, 0x00});
  // NaN encodes raw 0.
  expect_bytes(encode_speed(spec, 0, std::nan(""), std::nan("")), {0, 0, 0, 0, 0, 0, 0, 0});

  SpeedFrameSpec small;
  small.has_angle = false;
  small.dlc = 2;
  small.speed = SignalSpec{0, 2, true, true, 0.01, 0.0};
  // 400 / 0.01 = 40000 > 32767 -> 7F FF (LE: FF 7F); -400 -> -32768 = 0x8000 (LE: 00 80).
  expect_bytes(encode_speed(small, 0, 400.0, 0.0), {0xFF, 0x7F});
  expect_bytes(encode_speed(small, 0, -400.0, 0.0), {0x00, 0x80});
  small.speed.is_signed = false;
  expect_bytes(encode_speed(small, 0, -5.0, 0.0), {0x00, 0x00});
  expect_bytes(encode_speed(small, 0, 1000.0, 0.0), {0xFF, 0xFF});  // 100000 > 65535
}

TEST(SpeedCodec, ClassifiesFrames) {
  const SpeedFrameSpec spec;
  DecodedSpeed out;
  out.speed_rad_s = 42.0;  // sentinel: only kOk may write out
  const std::initializer_list<std::uint8_t> payload = {0x5B, 0x88, 0x00, 0x00, 0xF0, 0x49, 0x02, 0x00};

  EXPECT_EQ(decode_speed(make_frame(0x184, kCanExtended, payload), spec, out), DecodeResult::kOtherId);
  EXPECT_EQ(decode_speed(make_frame(0x185, 0, payload), spec, out), DecodeResult::kOtherId);
  EXPECT_EQ(decode_speed(make_frame(0x184, kCanError, payload), spec, out), DecodeResult::kErrorFrame);
  // Error frames are recognised whatever their class bits are.
  EXPECT_EQ(decode_speed(make_frame(0x4, kCanError, payload), spec, out), DecodeResult::kErrorFrame);
  CanFrame rtr = make_frame(0x184, kCanRtr, {});
  rtr.len = 8;  // RTR frames carry the requested DLC
  EXPECT_EQ(decode_speed(rtr, spec, out), DecodeResult::kRtr);
  EXPECT_EQ(decode_speed(make_frame(0x184, 0, {0x5B, 0x88, 0x00, 0x00, 0xF0, 0x49}), spec, out),
            DecodeResult::kWrongDlc);
  EXPECT_EQ(decode_speed(make_frame(0x184, 0, {}), spec, out), DecodeResult::kWrongDlc);
  EXPECT_EQ(out.speed_rad_s, 42.0);
  EXPECT_EQ(decode_speed(make_frame(0x184, 0, payload), spec, out), DecodeResult::kOk);
  EXPECT_DOUBLE_EQ(out.speed_rad_s, 3.4907);
}

TEST(SpeedCodec, ExtendedIdIsDistinctFromStandard) {
  SpeedFrameSpec spec;
  spec.id = 0x18FF0184;
  spec.extended = true;
  const std::initializer_list<std::uint8_t> payload = {0x5B, 0x88, 0x00, 0x00, 0xF0, 0x49, 0x02, 0x00};
  DecodedSpeed out;
  EXPECT_EQ(decode_speed(make_frame(0x18FF0184, kCanExtended, payload), spec, out), DecodeResult::kOk);
  EXPECT_EQ(decode_speed(make_frame(0x184, 0, payload), spec, out), DecodeResult::kOtherId);
  // A standard frame whose id equals the extended one numerically is still another frame.
  spec.id = 0x184;
  EXPECT_EQ(decode_speed(make_frame(0x184, kCanExtended, payload), spec, out), DecodeResult::kOk);
  EXPECT_EQ(decode_speed(make_frame(0x184, 0, payload), spec, out), DecodeResult::kOtherId);
  const CanFrame enc = encode_speed(spec, 0, 1.0, 0.0);
  EXPECT_TRUE(enc.extended());
  EXPECT_EQ(enc.id, 0x184U);
}

TEST(SpeedCodec, InvalidSpecDoesNotReadPastFrame) {
  SpeedFrameSpec spec;
  spec.dlc = 4;  // the default angle (bytes 4..7) no longer fits
  DecodedSpeed out;
  EXPECT_EQ(decode_speed(make_frame(0x184, 0, {1, 2, 3, 4}), spec, out), DecodeResult::kWrongDlc);
  spec.has_angle = false;
  EXPECT_EQ(decode_speed(make_frame(0x184, 0, {0x5B, 0x88, 0x00, 0x00}), spec, out), DecodeResult::kOk);
  EXPECT_DOUBLE_EQ(out.speed_rad_s, 3.4907);
}

TEST(SpeedCodec, DecodeAndEncodeDoNotAllocate) {
  const SpeedFrameSpec spec;
  DecodedSpeed out;
  double sum = 0.0;
  test::AllocScope scope;
  for (int i = 0; i < 1000; ++i) {
    const CanFrame f = encode_speed(spec, i, i * 0.001, i * -0.002);
    if (decode_speed(f, spec, out) == DecodeResult::kOk) sum += out.speed_rad_s;
  }
  EXPECT_EQ(scope.count(), 0U);
  EXPECT_NEAR(sum, 499.5, 1e-6);  // sum of i/1000 for i < 1000, each exact to the 1e-4 step
}

TEST(SpeedCodec, ValidateAcceptsDefaultAndReportsProblems) {
  EXPECT_NO_THROW(validate(SpeedFrameSpec{}));
  EXPECT_FALSE(find_problem(SpeedFrameSpec{}).has_value());

  SpeedFrameSpec s;
  s.id = 0x800;
  EXPECT_EQ(error_of(s), "speed frame: id 2048 does not fit a 11-bit standard identifier (max 2047)");
  EXPECT_EQ(find_problem(s)->key, "id");
  s.extended = true;
  EXPECT_EQ(error_of(s), "");
  s.id = 0x20000000;
  EXPECT_EQ(error_of(s),
            "speed frame: id 536870912 does not fit a 29-bit extended identifier (max 536870911)");

  s = SpeedFrameSpec{};
  s.dlc = 9;
  EXPECT_EQ(error_of(s), "speed frame: dlc 9 is outside 1..8");
  s.dlc = 0;
  EXPECT_EQ(find_problem(s)->key, "dlc");

  s = SpeedFrameSpec{};
  s.speed.length = 0;
  EXPECT_EQ(find_problem(s)->key, "speed.length");
  s.speed.length = 9;
  EXPECT_EQ(find_problem(s)->key, "speed.length");

  s = SpeedFrameSpec{};
  s.dlc = 6;
  EXPECT_EQ(error_of(s),
            "speed frame: angle signal (bytes 4..7, dlc 6): bytes extend beyond the frame's dlc");
  EXPECT_EQ(find_problem(s)->key, "angle.start_byte");
  s.has_angle = false;  // an unused angle is not checked
  EXPECT_EQ(error_of(s), "");

  s = SpeedFrameSpec{};
  s.speed.scale = 0.0;
  EXPECT_EQ(error_of(s), "speed frame: speed signal (bytes 0..3, dlc 8): scale must be finite and non-zero");
  s.speed.scale = std::nan("");
  EXPECT_EQ(find_problem(s)->key, "speed.scale");
  s = SpeedFrameSpec{};
  s.angle.offset = std::numeric_limits<double>::infinity();
  EXPECT_EQ(find_problem(s)->key, "angle.offset");

  s = SpeedFrameSpec{};
  s.angle.start_byte = 2;
  EXPECT_EQ(error_of(s), "speed frame: speed signal (bytes 0..3) and angle signal (bytes 2..5) overlap");

  s = SpeedFrameSpec{};
  s.period_s = 0.0;
  EXPECT_EQ(error_of(s), "speed frame: period_s must be a positive number of seconds");
}

}  // namespace
}  // namespace ptda::config
