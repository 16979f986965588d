// Small text helpers for the tool's human-readable output. Thread: any. Allocates.
#pragma once

#include <cstdint>
#include <string>

namespace ptda::cli {

/// printf-style "%.<decimals>f".
[[nodiscard]] std::string fixed(double v, int decimals);
/// printf-style "%.<digits>g".
[[nodiscard]] std::string general(double v, int digits = 6);
/// Left-pads s with spaces to width (no truncation).
[[nodiscard]] std::string pad_left(const std::string& s, std::size_t width);
/// Right-pads s with spaces to width (no truncation).
[[nodiscard]] std::string pad_right(const std::string& s, std::size_t width);
/// UNIX seconds as "YYYY-MM-DD hh:mm:ss.mmm UTC".
[[nodiscard]] std::string utc_time(double unix_s);

}  // namespace ptda::cli
