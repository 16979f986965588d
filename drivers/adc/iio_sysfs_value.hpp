// Values read from IIO sysfs attributes (sampling_frequency, scan_elements/*_index): the text as the
// kernel prints it ("25600\n", "3\n"), parsed strictly so that a wrong attribute is an error naming
// the file instead of a silently wrapped or truncated number. Pure functions: unit-tested and fuzzed
// (tests/fuzz/fuzz_iio_sysfs.cpp).
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

namespace ptda::drivers {

/// The attribute text without the trailing newlines and spaces sysfs adds. Thread: any. Never allocates.
[[nodiscard]] std::string_view trim_sysfs_text(std::string_view text) noexcept;

/// A sample rate in Hz ("25600", "1600.5", "1.6e3"; trailing newline/space allowed): a decimal
/// number that fills the text and is finite and > 0. Throws ptda::Error "<where>: not a positive
/// sample rate: '<text>'" otherwise (leading space, sign, hex, "inf", junk after the number). Thread:
/// any. Allocates only to throw.
[[nodiscard]] double parse_sysfs_rate_hz(std::string_view text, const std::string& where);

/// A scan index ("0".."4294967295"; trailing newline/space allowed): decimal digits only. Throws
/// ptda::Error "<where>: not a scan index: '<text>'" otherwise (sign, space, junk, above 2^32 - 1).
/// Thread: any. Allocates only to throw.
[[nodiscard]] std::uint32_t parse_sysfs_index(std::string_view text, const std::string& where);

}  // namespace ptda::drivers
