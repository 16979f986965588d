#pragma once

#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>

namespace ptda {

inline constexpr std::int64_t kNsPerS = 1'000'000'000;

/// The latest UNIX time (seconds) a recording, log or configuration may name: 4e9 s, in 2096. It
/// leaves more than 5e9 s of int64 nanoseconds above it, so a time plus any recording duration or
/// offset the tools compute stays representable (issue 14 item 1: 9.3e9 s overflowed to 0 windows).
inline constexpr double kMaxUnixTimeS = 4.0e9;

/// t_s in integer nanoseconds, rounded to nearest, or nullopt when t_s is not finite or its
/// nanoseconds do not fit in int64 (|t_s| >= about 9.22e9 s). Thread: any; never allocates.
[[nodiscard]] inline std::optional<std::int64_t> checked_seconds_to_ns(double t_s) noexcept {
  const double ns = t_s * 1e9;
  // 2^63 is exactly representable; every double below it converts without overflow.
  constexpr double kLimit = 9223372036854775808.0;
  if (!(ns > -kLimit && ns < kLimit)) return std::nullopt;  // also NaN
  const double r = std::round(ns);
  if (!(r > -kLimit && r < kLimit)) return std::nullopt;
  return static_cast<std::int64_t>(r);
}

/// Seconds (double, e.g. UNIX time from recording.toml) to integer nanoseconds, rounded to nearest.
/// Out of range values saturate (NaN gives 0) instead of the undefined behaviour of llround: readers
/// reject such times with a located error first (checked_seconds_to_ns). Thread: any; never allocates.
[[nodiscard]] inline std::int64_t seconds_to_ns(double t_s) noexcept {
  if (const auto ns = checked_seconds_to_ns(t_s)) return *ns;
  if (std::isnan(t_s)) return 0;
  return t_s > 0.0 ? std::numeric_limits<std::int64_t>::max() : std::numeric_limits<std::int64_t>::min();
}
[[nodiscard]] inline double ns_to_seconds(std::int64_t t_ns) noexcept {
  return static_cast<double>(t_ns) * 1e-9;
}

}  // namespace ptda
