// Byte-aligned CAN signal codec for the joint speed frame (see speed_codec.hpp).
#include "ptda/config/speed_codec.hpp"

#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>

#include "ptda/common/error.hpp"

namespace ptda::config {
namespace {

constexpr std::uint32_t kMaxStandardId = 0x7FFU;
constexpr std::uint32_t kMaxExtendedId = 0x1FFFFFFFU;
constexpr std::uint8_t kMaxClassicDlc = 8;

// Raw bits of a signal: byte start_byte is the least significant byte (little endian) or the most
// significant one (big endian, byte-aligned "Motorola" layout).
std::uint64_t read_raw(const CanFrame& frame, const SignalSpec& sig) noexcept {
  std::uint64_t raw = 0;
  for (std::uint8_t i = 0; i < sig.length; ++i) {
    const std::uint8_t byte = frame.data[static_cast<std::size_t>(sig.start_byte) + i];
    const unsigned shift = sig.little_endian ? 8U * i : 8U * (sig.length - 1U - i);
    raw |= static_cast<std::uint64_t>(byte) << shift;
  }
  return raw;
}

void write_raw(CanFrame& frame, const SignalSpec& sig, std::uint64_t raw) noexcept {
  for (std::uint8_t i = 0; i < sig.length; ++i) {
    const unsigned shift = sig.little_endian ? 8U * i : 8U * (sig.length - 1U - i);
    frame.data[static_cast<std::size_t>(sig.start_byte) + i] =
        static_cast<std::uint8_t>((raw >> shift) & 0xFFU);
  }
}

double to_physical(std::uint64_t raw, const SignalSpec& sig) noexcept {
  const unsigned bits = 8U * sig.length;
  double value = 0.0;
  if (sig.is_signed) {
    // Sign-extend from the signal's top bit; for 8-byte signals the cast alone does it.
    std::uint64_t extended = raw;
    if (bits < 64U && (raw >> (bits - 1U)) != 0U) extended |= ~std::uint64_t{0} << bits;
    value = static_cast<double>(static_cast<std::int64_t>(extended));
  } else {
    value = static_cast<double>(raw);
  }
  return value * sig.scale + sig.offset;
}

// Nearest raw step of a physical value, saturated to what the signal can carry. NaN encodes as 0.
std::uint64_t to_raw(double physical, const SignalSpec& sig) noexcept {
  const unsigned bits = 8U * sig.length;
  const double steps = (physical - sig.offset) / sig.scale;
  if (sig.is_signed) {
    const std::int64_t hi =
        bits == 64U ? std::numeric_limits<std::int64_t>::max() : (std::int64_t{1} << (bits - 1U)) - 1;
    const std::int64_t lo = -hi - 1;
    std::int64_t r = 0;
    if (std::isnan(steps)) {
      r = 0;
    } else if (steps >= static_cast<double>(hi)) {
      // Comparisons in double: for 64-bit signals hi is not representable, so test before llround.
      r = hi;
    } else if (steps <= static_cast<double>(lo)) {
      r = lo;
    } else {
      r = std::llround(steps);
      if (r > hi) r = hi;
      if (r < lo) r = lo;
    }
    const std::uint64_t mask = bits == 64U ? ~std::uint64_t{0} : (std::uint64_t{1} << bits) - 1U;
    return static_cast<std::uint64_t>(r) & mask;
  }
  const std::uint64_t hi = bits == 64U ? ~std::uint64_t{0} : (std::uint64_t{1} << bits) - 1U;
  if (std::isnan(steps) || steps <= 0.0) return 0;
  if (steps >= static_cast<double>(hi)) return hi;
  const double rounded = std::floor(steps + 0.5);
  const auto r = static_cast<std::uint64_t>(rounded);
  return r > hi ? hi : r;
}

// First problem of a signal, or nullptr.
const char* signal_problem(const SignalSpec& sig, std::uint8_t dlc, const char** key) noexcept {
  if (sig.length < 1 || sig.length > 8) {
    *key = "length";
    return "length must be 1..8 bytes";
  }
  if (static_cast<unsigned>(sig.start_byte) + sig.length > dlc) {
    *key = "start_byte";
    return "bytes extend beyond the frame's dlc";
  }
  if (!std::isfinite(sig.scale) || sig.scale == 0.0) {
    *key = "scale";
    return "scale must be finite and non-zero";
  }
  if (!std::isfinite(sig.offset)) {
    *key = "offset";
    return "offset must be finite";
  }
  return nullptr;
}

}  // namespace

DecodeResult decode_speed(const CanFrame& frame, const SpeedFrameSpec& spec, DecodedSpeed& out) noexcept {
  // Error frames carry class bits in `id`: check the flag before comparing identifiers.
  if (frame.error()) return DecodeResult::kErrorFrame;
  if (frame.id != spec.id || frame.extended() != spec.extended) return DecodeResult::kOtherId;
  if (frame.rtr()) return DecodeResult::kRtr;
  if (frame.len != spec.dlc) return DecodeResult::kWrongDlc;
  // A spec that failed validate() must not read past the frame; treat it like a length mismatch.
  const auto fits = [&](const SignalSpec& s) {
    return s.length >= 1 && s.length <= 8 && static_cast<unsigned>(s.start_byte) + s.length <= frame.len;
  };
  if (!fits(spec.speed) || (spec.has_angle && !fits(spec.angle))) return DecodeResult::kWrongDlc;

  out.speed_rad_s = to_physical(read_raw(frame, spec.speed), spec.speed);
  out.has_angle = spec.has_angle;
  out.angle_rad = spec.has_angle ? to_physical(read_raw(frame, spec.angle), spec.angle) : 0.0;
  return DecodeResult::kOk;
}

CanFrame encode_speed(const SpeedFrameSpec& spec, std::int64_t t_ns, double speed_rad_s,
                      double angle_rad) noexcept {
  CanFrame frame;
  frame.t_ns = t_ns;
  frame.id = spec.id;
  frame.flags = spec.extended ? static_cast<std::uint8_t>(kCanExtended) : std::uint8_t{0};
  frame.len = spec.dlc <= kMaxClassicDlc ? spec.dlc : kMaxClassicDlc;
  const auto fits = [&](const SignalSpec& s) {
    return s.length >= 1 && s.length <= 8 && static_cast<unsigned>(s.start_byte) + s.length <= frame.len &&
           s.scale != 0.0;
  };
  if (fits(spec.speed)) write_raw(frame, spec.speed, to_raw(speed_rad_s, spec.speed));
  if (spec.has_angle && fits(spec.angle)) write_raw(frame, spec.angle, to_raw(angle_rad, spec.angle));
  return frame;
}

std::optional<SpecProblem> find_problem(const SpeedFrameSpec& spec) {
  const std::uint32_t max_id = spec.extended ? kMaxExtendedId : kMaxStandardId;
  if (spec.id > max_id) {
    return SpecProblem{"id",
                       "id " + std::to_string(spec.id) + " does not fit a " +
                           (spec.extended ? "29-bit extended" : "11-bit standard") + " identifier (max " +
                           std::to_string(max_id) + ")",
                       {"extended"}};
  }
  if (spec.dlc < 1 || spec.dlc > kMaxClassicDlc) {
    return SpecProblem{"dlc", "dlc " + std::to_string(spec.dlc) + " is outside 1..8", {}};
  }
  const auto signal = [&](const char* name, const SignalSpec& sig) -> std::optional<SpecProblem> {
    const char* key = "";
    const char* p = signal_problem(sig, spec.dlc, &key);
    if (p == nullptr) return std::nullopt;
    const std::string prefix = std::string(name) + ".";
    SpecProblem problem{prefix + key,
                        std::string(name) + " signal (bytes " + std::to_string(sig.start_byte) + ".." +
                            std::to_string(sig.start_byte + sig.length - 1) + ", dlc " +
                            std::to_string(spec.dlc) + "): " + p,
                        {}};
    // Bytes beyond the frame: the signal's length or the frame's dlc may be what changed.
    if (problem.key == prefix + "start_byte") problem.related = {prefix + "length", "dlc"};
    return problem;
  };
  if (auto problem = signal("speed", spec.speed)) return problem;
  if (spec.has_angle) {
    if (auto problem = signal("angle", spec.angle)) return problem;
    const unsigned s0 = spec.speed.start_byte;
    const unsigned s1 = s0 + spec.speed.length;
    const unsigned a0 = spec.angle.start_byte;
    const unsigned a1 = a0 + spec.angle.length;
    if (s0 < a1 && a0 < s1) {
      return SpecProblem{"angle.start_byte",
                         "speed signal (bytes " + std::to_string(s0) + ".." + std::to_string(s1 - 1) +
                             ") and angle signal (bytes " + std::to_string(a0) + ".." +
                             std::to_string(a1 - 1) + ") overlap",
                         {"angle.length", "speed.length", "speed.start_byte", "has_angle"}};
    }
  }
  if (!std::isfinite(spec.period_s) || spec.period_s <= 0.0) {
    return SpecProblem{"period_s", "period_s must be a positive number of seconds", {}};
  }
  return std::nullopt;
}

void validate(const SpeedFrameSpec& spec) {
  if (auto problem = find_problem(spec)) throw Error("speed frame: " + problem->what);
}

}  // namespace ptda::config
