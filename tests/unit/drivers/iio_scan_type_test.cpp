#include "adc/iio_scan_type.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "ptda/common/error.hpp"

namespace ptda::drivers {
namespace {

IioScanType parse(const std::string& s) {
  return parse_iio_scan_type(s, "in_test_type");
}

TEST(IioScanType, ParsesTheKernelForms) {
  const IioScanType a = parse("le:s24/32>>0");
  EXPECT_FALSE(a.big_endian);
  EXPECT_TRUE(a.is_signed);
  EXPECT_EQ(a.bits, 24);
  EXPECT_EQ(a.storage_bits, 32);
  EXPECT_EQ(a.repeat, 1);
  EXPECT_EQ(a.shift, 0);

  const IioScanType b = parse("be:u12/16>>4\n");  // as read from sysfs, with the newline
  EXPECT_TRUE(b.big_endian);
  EXPECT_FALSE(b.is_signed);
  EXPECT_EQ(b.bits, 12);
  EXPECT_EQ(b.storage_bits, 16);
  EXPECT_EQ(b.shift, 4);

  const IioScanType ts = parse("le:s64/64>>0");
  EXPECT_EQ(ts.bits, 64);
  EXPECT_EQ(ts.storage_bytes(), 8u);

  const IioScanType q = parse("le:s16/16X4>>0");
  EXPECT_EQ(q.repeat, 4);
  EXPECT_EQ(q.total_bytes(), 8u);

  const IioScanType no_shift = parse("le:u8/8");
  EXPECT_EQ(no_shift.shift, 0);
  EXPECT_EQ(no_shift.bits, 8);
}

TEST(IioScanType, FormatsLikeTheKernelAndRoundTrips) {
  for (const std::string s :
       {"le:s24/32>>0", "be:u12/16>>4", "le:s64/64>>0", "le:s16/16X4>>0", "be:s20/32>>12"}) {
    EXPECT_EQ(format_iio_scan_type(parse(s)), s);
  }
}

TEST(IioScanType, RejectsMalformedOrInconsistentTypes) {
  for (const std::string s :
       {"", "xx:s12/16>>0", "le:q12/16>>0", "le:s0/16>>0", "le:s17/16>>0", "le:s12/12>>0", "le:s12/16>>5",
        "le:s12/16>>4junk", "le:s12-16", "le:s12/16X0>>0", "le:s/16>>0", "LE:s12/16>>0"}) {
    EXPECT_THROW((void)parse(s), Error) << "'" << s << "'";
  }
  try {
    (void)parse("le:s17/16>>0");
    FAIL();
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("in_test_type"), std::string::npos) << what;
    EXPECT_NE(what.find("le:s17/16>>0"), std::string::npos) << what;
  }
}

IioChannelSpec spec(const std::string& name, std::uint32_t index, const std::string& type) {
  return IioChannelSpec{name, index, parse(type)};
}

TEST(IioScanLayout, ThreeAxes24In32PlusTimestamp) {
  const std::vector<IioChannelSpec> ch{spec("timestamp", 3, "le:s64/64>>0"),
                                       spec("accel_z", 2, "le:s24/32>>0"), spec("accel_x", 0, "le:s24/32>>0"),
                                       spec("accel_y", 1, "le:s24/32>>0")};
  const IioScanLayout l = compute_iio_scan_layout(ch);
  ASSERT_EQ(l.elements.size(), 4u);
  EXPECT_EQ(l.elements[0].name, "accel_x");
  EXPECT_EQ(l.elements[0].offset, 0u);
  EXPECT_EQ(l.elements[1].offset, 4u);
  EXPECT_EQ(l.elements[2].offset, 8u);
  EXPECT_EQ(l.elements[3].name, "timestamp");
  EXPECT_EQ(l.elements[3].offset, 16u);  // 12 rounded up to 8
  EXPECT_EQ(l.scan_bytes, 24u);
  EXPECT_EQ(l.timestamp_element, 3);
  EXPECT_EQ(l.find("accel_y"), 1);
  EXPECT_EQ(l.find("gyro_x"), -1);
}

TEST(IioScanLayout, PacksLikeTheKernel) {
  {  // three 16-bit channels: packed, no padding without a timestamp
    const std::vector<IioChannelSpec> ch{spec("a", 0, "le:s16/16>>0"), spec("b", 1, "le:s16/16>>0"),
                                         spec("c", 2, "le:s16/16>>0")};
    const IioScanLayout l = compute_iio_scan_layout(ch);
    EXPECT_EQ(l.elements[2].offset, 4u);
    EXPECT_EQ(l.scan_bytes, 6u);
    EXPECT_EQ(l.timestamp_element, -1);
  }
  {  // ... and with a timestamp: 6 -> 8, scan 16
    const std::vector<IioChannelSpec> ch{spec("a", 0, "le:s16/16>>0"), spec("b", 1, "le:s16/16>>0"),
                                         spec("c", 2, "le:s16/16>>0"), spec("timestamp", 7, "le:s64/64>>0")};
    const IioScanLayout l = compute_iio_scan_layout(ch);
    EXPECT_EQ(l.elements[3].offset, 8u);
    EXPECT_EQ(l.scan_bytes, 16u);
  }
  {  // 16 then 32: the 32-bit element is aligned to 4; the scan padded to its largest element
    const std::vector<IioChannelSpec> ch{spec("a", 0, "le:s16/16>>0"), spec("b", 1, "le:s32/32>>0"),
                                         spec("c", 2, "le:u8/8>>0")};
    const IioScanLayout l = compute_iio_scan_layout(ch);
    EXPECT_EQ(l.elements[1].offset, 4u);
    EXPECT_EQ(l.elements[2].offset, 8u);
    EXPECT_EQ(l.scan_bytes, 12u);
  }
  {  // a repeated channel is aligned to its whole size (4 x 16 bit = 8)
    const std::vector<IioChannelSpec> ch{spec("a", 0, "le:u8/8>>0"), spec("quat", 1, "le:s16/16X4>>0")};
    const IioScanLayout l = compute_iio_scan_layout(ch);
    EXPECT_EQ(l.elements[1].offset, 8u);
    EXPECT_EQ(l.scan_bytes, 16u);
  }
}

TEST(IioScanLayout, RejectsDuplicatesAndOddTimestamps) {
  EXPECT_THROW((void)compute_iio_scan_layout(std::vector<IioChannelSpec>{}), Error);
  EXPECT_THROW((void)compute_iio_scan_layout(
                   std::vector<IioChannelSpec>{spec("a", 0, "le:s16/16>>0"), spec("b", 0, "le:s16/16>>0")}),
               Error);
  EXPECT_THROW((void)compute_iio_scan_layout(
                   std::vector<IioChannelSpec>{spec("a", 0, "le:s16/16>>0"), spec("a", 1, "le:s16/16>>0")}),
               Error);
  EXPECT_THROW(
      (void)compute_iio_scan_layout(std::vector<IioChannelSpec>{spec("timestamp", 1, "le:s32/32>>0")}),
      Error);
}

IioScanElement element(const std::string& type, std::size_t offset = 0) {
  return IioScanElement{"x", 0, parse(type), offset};
}

TEST(IioDecode, SignExtendsShiftsAndMasks) {
  {  // le:s24/32: the top byte is not part of the value even when it holds garbage
    const std::array<std::uint8_t, 4> scan{0x01, 0x00, 0x80, 0xFF};
    EXPECT_EQ(decode_iio_value(scan.data(), element("le:s24/32>>0")), -8388607);  // 0x800001 sign-extended
    EXPECT_EQ(decode_iio_value(scan.data(), element("le:u24/32>>0")), 0x800001);
  }
  {  // be:u12/16>>4: 0xABC0 -> 0xABC
    const std::array<std::uint8_t, 2> scan{0xAB, 0xC0};
    EXPECT_EQ(decode_iio_value(scan.data(), element("be:u12/16>>4")), 0xABC);
  }
  {  // be:s12/16>>4: 0xFFF0 -> -1; 0x8000 -> -2048; the low nibble (status bits) is ignored
    const std::array<std::uint8_t, 2> m1{0xFF, 0xF7};
    EXPECT_EQ(decode_iio_value(m1.data(), element("be:s12/16>>4")), -1);
    const std::array<std::uint8_t, 2> min{0x80, 0x0F};
    EXPECT_EQ(decode_iio_value(min.data(), element("be:s12/16>>4")), -2048);
  }
  {                                                                  // ADXL355 style: be:s20/32>>12
    const std::array<std::uint8_t, 4> scan{0xFF, 0xFF, 0xE0, 0x00};  // 0xFFFFE000 >> 12 = 0xFFFFE -> -2
    EXPECT_EQ(decode_iio_value(scan.data(), element("be:s20/32>>12")), -2);
  }
  {  // timestamp, at an offset
    std::array<std::uint8_t, 16> scan{};
    const std::int64_t t = 1'700'000'000'123'456'789;
    for (int i = 0; i < 8; ++i)
      scan[8 + i] = static_cast<std::uint8_t>(static_cast<std::uint64_t>(t) >> (8 * i));
    EXPECT_EQ(decode_iio_value(scan.data(), element("le:s64/64>>0", 8)), t);
  }
  {  // repeats
    const std::array<std::uint8_t, 4> scan{0x01, 0x00, 0xFE, 0xFF};
    EXPECT_EQ(decode_iio_value(scan.data(), element("le:s16/16X2>>0"), 0), 1);
    EXPECT_EQ(decode_iio_value(scan.data(), element("le:s16/16X2>>0"), 1), -2);
  }
}

TEST(IioDecode, EncodeDecodeRoundTripsOverTheWholeRange) {
  std::mt19937_64 rng(7);
  for (const std::string type : {"le:s24/32>>0", "be:s20/32>>12", "be:u12/16>>4", "le:s16/16>>0",
                                 "le:u8/8>>0", "le:s64/64>>0", "be:s14/16>>2"}) {
    const IioScanElement e = element(type, 8);
    const int bits = e.type.bits;
    const std::int64_t lo =
        e.type.is_signed ? (bits == 64 ? INT64_MIN : -(std::int64_t{1} << (bits - 1))) : 0;
    const std::int64_t hi = bits == 64         ? INT64_MAX
                            : e.type.is_signed ? (std::int64_t{1} << (bits - 1)) - 1
                                               : (std::int64_t{1} << bits) - 1;
    std::uniform_int_distribution<std::int64_t> dist(lo, hi);
    for (int i = 0; i < 2000; ++i) {
      std::array<std::uint8_t, 32> scan{};
      const std::int64_t v = i == 0 ? lo : i == 1 ? hi : dist(rng);
      encode_iio_value(scan.data(), e, v);
      ASSERT_EQ(decode_iio_value(scan.data(), e), v) << type;
    }
  }
}

}  // namespace
}  // namespace ptda::drivers
