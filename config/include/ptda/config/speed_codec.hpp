// Joint speed (and optional angle) carried in a CAN frame, described by configuration.
// Default (nothing configured): standard id 0x184, DLC 8, bytes 0-3 joint-4 speed as little-endian
// int32 in 1e-4 rad/s, bytes 4-7 joint-4 angle as little-endian int32 in 1e-5 rad, every 4 ms.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "ptda/common/can_frame.hpp"

namespace ptda::config {

struct SignalSpec {
  std::uint8_t start_byte = 0;
  std::uint8_t length = 4;  ///< bytes, 1..8
  bool little_endian = true;
  bool is_signed = true;
  double scale = 1e-4;  ///< physical = raw * scale + offset
  double offset = 0.0;
};

struct SpeedFrameSpec {
  std::uint32_t id = 0x184;
  bool extended = false;
  std::uint8_t dlc = 8;  ///< frames with another length are rejected (counted)
  SignalSpec speed{0, 4, true, true, 1e-4, 0.0};
  bool has_angle = true;
  SignalSpec angle{4, 4, true, true, 1e-5, 0.0};
  double period_s = 0.004;  ///< nominal transmit period (staleness is judged against it)
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

/// Decodes frame with spec. Checks in this order: error frame (kErrorFrame), id and id format
/// (an extended 0x184 is not the standard 0x184: kOtherId), remote frame (kRtr), length (kWrongDlc).
/// Only kOk writes `out`. Signals are byte aligned: little endian puts the least significant byte at
/// start_byte, big endian the most significant one; signed signals are sign-extended from their top
/// bit. A spec whose signals do not fit its dlc (see validate()) yields kWrongDlc instead of reading
/// out of bounds. Thread: any. Never allocates, throws or blocks (real-time safe).
[[nodiscard]] DecodeResult decode_speed(const CanFrame& frame, const SpeedFrameSpec& spec,
                                        DecodedSpeed& out) noexcept;
/// Encodes a speed (and angle) into a frame (rounding to the nearest raw step, saturating to the
/// signal's range; NaN encodes raw 0). Unused payload bytes are 0. Thread: any. Never allocates,
/// throws or blocks.
[[nodiscard]] CanFrame encode_speed(const SpeedFrameSpec& spec, std::int64_t t_ns, double speed_rad_s,
                                    double angle_rad) noexcept;
/// What is wrong with a spec: `key` names the configuration key at fault relative to
/// [can.speed_frame] ("id", "dlc", "speed.length", "angle.start_byte", "period_s", ...); `related`
/// lists the other keys that together make the problem, most likely culprit first (the config
/// parser points at the first of them that a file actually set).
struct SpecProblem {
  std::string key;
  std::string what;
  std::vector<std::string> related;
};

/// The first inconsistency of spec (id too large for its format, dlc outside 1..8, signal length
/// outside 1..8 or beyond dlc, zero/non-finite scale, speed and angle overlapping, period_s <= 0),
/// or nullopt. Thread: any. Allocates only to describe a problem.
[[nodiscard]] std::optional<SpecProblem> find_problem(const SpeedFrameSpec& spec);

/// Throws ptda::Error "speed frame: <what>" when find_problem() reports something. Thread: any.
void validate(const SpeedFrameSpec& spec);

}  // namespace ptda::config
