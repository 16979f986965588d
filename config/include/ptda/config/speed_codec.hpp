// Joint speed (and optional angle) carried in a CAN frame, described by configuration.
// Default (nothing configured): standard id 0x184, DLC 8, bytes 0-3 joint-4 speed as little-endian
// int32 in 1e-4 rad/s, bytes 4-7 joint-4 angle as little-endian int32 in 1e-5 rad, every 4 ms.
#pragma once

#include <cstdint>
#include <optional>

#include "ptda/common/can_frame.hpp"

namespace ptda::config {

struct SignalSpec {
  std::uint8_t start_byte = 0;
  std::uint8_t length = 4;          ///< bytes, 1..8
  bool little_endian = true;
  bool is_signed = true;
  double scale = 1e-4;              ///< physical = raw * scale + offset
  double offset = 0.0;
};

struct SpeedFrameSpec {
  std::uint32_t id = 0x184;
  bool extended = false;
  std::uint8_t dlc = 8;             ///< frames with another length are rejected (counted)
  SignalSpec speed{0, 4, true, true, 1e-4, 0.0};
  bool has_angle = true;
  SignalSpec angle{4, 4, true, true, 1e-5, 0.0};
  double period_s = 0.004;          ///< nominal transmit period (staleness is judged against it)
};

enum class DecodeResult : std::uint8_t {
  kOk = 0,
  kOtherId,     ///< not the speed frame (not an error)
  kWrongDlc,    ///< the speed id with an unexpected length
  kRtr,         ///< remote frame with the speed id
  kErrorFrame,  ///< a bus error frame
};

struct DecodedSpeed {
  double speed_rad_s = 0.0;
  double angle_rad = 0.0;
  bool has_angle = false;
};

/// Decodes frame with spec. Never allocates or throws (real-time safe).
[[nodiscard]] DecodeResult decode_speed(const CanFrame& frame, const SpeedFrameSpec& spec,
                                        DecodedSpeed& out) noexcept;
/// Encodes a speed (and angle) into a frame (rounding to the nearest raw step, saturating).
[[nodiscard]] CanFrame encode_speed(const SpeedFrameSpec& spec, std::int64_t t_ns, double speed_rad_s,
                                    double angle_rad) noexcept;
/// Throws ptda::Error when the spec is inconsistent (signal beyond dlc, length 0 or > 8, scale 0...).
void validate(const SpeedFrameSpec& spec);

}  // namespace ptda::config
