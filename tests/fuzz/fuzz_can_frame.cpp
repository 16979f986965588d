// libFuzzer target: a received CAN frame, from the kernel's bytes to every decoder of the daemon:
// from_kernel_frame (drivers/can/socketcan_channel.cpp), apply_error_frame (can_error.cpp), the speed
// codec (config/src/speed_codec.cpp) with the default layout and with a layout picked by the input,
// and the alarm frame (drivers/alarm/can_alarm_output.cpp).
// Input: byte 0 bit 0 = CAN FD MTU (else classic), bytes 1-8 choose a speed-frame layout, the rest is
// the kernel's canfd_frame (zero-padded). Checks: an accepted frame converts back to the same kernel
// frame; an error frame moves the bus state machine to a valid state; a decoded speed is finite and
// re-encodes to the same signal bytes; a decoded alarm frame re-encodes to the same frame.
#include <linux/can.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>

#include "alarm/can_alarm_output.hpp"
#include "can/socketcan_channel.hpp"
#include "ptda/config/speed_codec.hpp"
#include "ptda/drivers/can_channel.hpp"

namespace {

using ptda::CanFrame;
using ptda::config::DecodedSpeed;
using ptda::config::DecodeResult;
using ptda::config::SignalSpec;
using ptda::config::SpeedFrameSpec;

bool same_frame(const CanFrame& a, const CanFrame& b) {
  return a.id == b.id && a.len == b.len && a.flags == b.flags && a.t_ns == b.t_ns &&
         std::memcmp(a.data.data(), b.data.data(), a.len) == 0;
}

/// A layout from 8 selector bytes (find_problem() decides whether it is usable).
SpeedFrameSpec spec_from(const std::uint8_t* s) {
  static constexpr double kScales[8] = {1e-4, 1e-5, 1.0, -0.5, 0.125, 3.0, 1e-9, 1e6};
  static constexpr double kOffsets[4] = {0.0, 10.5, -3.0, 0.25};
  SpeedFrameSpec spec;
  const std::uint32_t id = s[0] | (s[1] << 8) | (s[2] << 16) | (static_cast<std::uint32_t>(s[3]) << 24);
  spec.extended = (s[3] & 0x80) != 0;
  spec.id = spec.extended ? (id & CAN_EFF_MASK) : (id & CAN_SFF_MASK);
  spec.dlc = static_cast<std::uint8_t>(s[4] % 9);
  const auto signal = [&](std::uint8_t pos, std::uint8_t flags) {
    SignalSpec g;
    g.start_byte = static_cast<std::uint8_t>(pos & 7);
    g.length = static_cast<std::uint8_t>(1 + ((pos >> 3) & 7));
    g.little_endian = (flags & 1) != 0;
    g.is_signed = (flags & 2) != 0;
    g.scale = kScales[(flags >> 2) & 7];
    g.offset = kOffsets[(flags >> 5) & 3];
    return g;
  };
  spec.speed = signal(s[5], s[7]);
  spec.has_angle = (s[6] & 0x80) != 0;
  spec.angle = signal(s[6], static_cast<std::uint8_t>(s[7] ^ 0x55));
  return spec;
}

/// decode -> encode -> the signal bytes are the same, when the raw value is exact in a double.
void check_speed(const CanFrame& f, const SpeedFrameSpec& spec) {
  DecodedSpeed d;
  if (ptda::config::decode_speed(f, spec, d) != DecodeResult::kOk) return;
  if (!std::isfinite(d.speed_rad_s) || !std::isfinite(d.angle_rad)) __builtin_trap();
  if (d.has_angle != spec.has_angle) __builtin_trap();
  const CanFrame again = ptda::config::encode_speed(spec, f.t_ns, d.speed_rad_s, d.angle_rad);
  if (again.id != f.id || again.len != f.len || again.extended() != f.extended()) __builtin_trap();
  const auto same_bytes = [&](const SignalSpec& g) {
    if (g.length > 6) return;  // above 2^48 a raw value need not survive the double
    if (std::memcmp(again.data.data() + g.start_byte, f.data.data() + g.start_byte, g.length) != 0)
      __builtin_trap();
  };
  same_bytes(spec.speed);
  if (spec.has_angle) same_bytes(spec.angle);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 9) return 0;
  const std::size_t nbytes = (data[0] & 1) != 0 ? CANFD_MTU : CAN_MTU;
  canfd_frame k{};
  std::memcpy(&k, data + 9, std::min(size - 9, sizeof k));

  CanFrame f;
  if (!ptda::drivers::from_kernel_frame(k, nbytes, 1234, f)) return 0;
  if (f.len > (f.fd() ? 64 : 8)) __builtin_trap();

  if (f.error()) {
    if (nbytes != CAN_MTU) __builtin_trap();
    ptda::drivers::CanChannelStats stats;
    ptda::drivers::apply_error_frame(f, stats);
    const auto st = static_cast<unsigned>(stats.state.load());
    if (st > static_cast<unsigned>(ptda::drivers::CanBusState::kBusOff) || stats.rx_error_frames.get() != 1)
      __builtin_trap();
  } else {
    // Back to the kernel and in again: the same frame.
    canfd_frame k2{};
    if (ptda::drivers::to_kernel_frame(f, k2) != nbytes) __builtin_trap();
    CanFrame back;
    if (!ptda::drivers::from_kernel_frame(k2, nbytes, 1234, back) || !same_frame(f, back)) __builtin_trap();
  }

  check_speed(f, SpeedFrameSpec{});
  const SpeedFrameSpec spec = spec_from(data + 1);
  if (!ptda::config::find_problem(spec)) check_speed(f, spec);

  const ptda::drivers::CanAlarmConfig alarm;
  ptda::drivers::AlarmReport report;
  std::uint8_t alive = 0;
  if (ptda::drivers::decode_alarm_frame(f, alarm, report, alive)) {
    CanFrame again = ptda::drivers::encode_alarm_frame(report, alarm, alive);
    again.t_ns = f.t_ns;
    if (!same_frame(again, f)) __builtin_trap();
  }
  return 0;
}
