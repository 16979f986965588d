// Escaping of untrusted text (paths, reasons, phase names from the configuration or a baseline file)
// for status.json and the Prometheus file. The output is always valid UTF-8: each ill-formed byte
// sequence of the input (stray continuation bytes, overlong forms, surrogates, code points above
// U+10FFFF, a sequence cut short) becomes one U+FFFD REPLACEMENT CHARACTER per maximal subpart
// (Unicode 15 §3.9, "U+FFFD substitution of maximal subparts": the same count Python's
// bytes.decode("utf-8", "replace") and WHATWG decoders give).
//
// JSON (RFC 8259): \" \\ \b \f \n \r \t, \u00XX for the other C0 controls (NUL is \u0000), and
// nothing else escaped. Prometheus label values (text exposition format 0.0.4): \\ \" \n, and NUL (which
// some scrapers treat as the end of the text) becomes U+FFFD; other bytes are copied.
//
// Both write into a caller's fixed buffer: no allocation, no exceptions, any thread.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string_view>

namespace ptda::daemon {

/// Returned by the escapers when the output does not fit `cap` (what was written is then unspecified).
inline constexpr std::size_t kEscapeOverflow = static_cast<std::size_t>(-1);

/// The UTF-8 encoding of U+FFFD.
inline constexpr std::string_view kReplacementChar = "\xEF\xBF\xBD";

/// Classifies the UTF-8 sequence at the start of `s` (non-empty): returns its length (1-4) when it is
/// a well-formed scalar value, or minus the length of its maximal ill-formed subpart (-1 to -3) that
/// is to be replaced by one U+FFFD. Any thread; does not allocate.
int utf8_sequence(std::string_view s) noexcept;

/// True when `s` is well-formed UTF-8. Any thread; does not allocate.
bool is_valid_utf8(std::string_view s) noexcept;

/// Writes the body of a JSON string literal for `in` (no quotes) to out[0, cap) and returns the bytes
/// written, or kEscapeOverflow. Any thread; does not allocate.
std::size_t escape_json_body(std::string_view in, char* out, std::size_t cap) noexcept;

/// Writes a Prometheus label value for `in` (no quotes) to out[0, cap) and returns the bytes
/// written, or kEscapeOverflow. Any thread; does not allocate.
std::size_t escape_prom_label_value(std::string_view in, char* out, std::size_t cap) noexcept;

}  // namespace ptda::daemon
