#pragma once

#include <cmath>
#include <cstdint>

namespace ptda {

inline constexpr std::int64_t kNsPerS = 1'000'000'000;

/// Seconds (double, e.g. UNIX time from recording.toml) to integer nanoseconds, rounded to nearest.
[[nodiscard]] inline std::int64_t seconds_to_ns(double t_s) noexcept {
  return static_cast<std::int64_t>(std::llround(t_s * 1e9));
}
[[nodiscard]] inline double ns_to_seconds(std::int64_t t_ns) noexcept {
  return static_cast<double>(t_ns) * 1e-9;
}

}  // namespace ptda
