#include "adc/iio_sysfs_value.hpp"

#include <charconv>
#include <cmath>
#include <system_error>

#include "ptda/common/error.hpp"

namespace ptda::drivers {
namespace {

bool is_digit(char c) noexcept {
  return c >= '0' && c <= '9';
}

/// Quoted text for a message: at most 64 bytes, non-printable bytes as '?'.
std::string quoted(std::string_view t) {
  std::string q = "'";
  for (std::size_t i = 0; i < t.size() && i < 64; ++i) {
    const auto u = static_cast<unsigned char>(t[i]);
    q += u >= 0x20 && u < 0x7F ? t[i] : '?';
  }
  if (t.size() > 64) q += "...";
  return q + "'";
}

}  // namespace

std::string_view trim_sysfs_text(std::string_view text) noexcept {
  while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.remove_suffix(1);
  return text;
}

double parse_sysfs_rate_hz(std::string_view text, const std::string& where) {
  const std::string_view t = trim_sysfs_text(text);
  // from_chars (fixed or scientific, no sign allowed here, no hex, no "inf"/"nan" since the first
  // character must be a digit) must consume the whole text.
  double v = 0.0;
  bool ok = !t.empty() && is_digit(t.front());
  if (ok) {
    const auto r = std::from_chars(t.data(), t.data() + t.size(), v, std::chars_format::general);
    ok = r.ec == std::errc() && r.ptr == t.data() + t.size() && std::isfinite(v) && v > 0.0;
  }
  if (!ok) throw Error(where, 0, 0, "not a positive sample rate: " + quoted(t));
  return v;
}

std::uint32_t parse_sysfs_index(std::string_view text, const std::string& where) {
  const std::string_view t = trim_sysfs_text(text);
  std::uint32_t v = 0;
  bool ok = !t.empty() && is_digit(t.front());
  if (ok) {
    const auto r = std::from_chars(t.data(), t.data() + t.size(), v, 10);
    ok = r.ec == std::errc() && r.ptr == t.data() + t.size();
  }
  if (!ok) throw Error(where, 0, 0, "not a scan index: " + quoted(t));
  return v;
}

}  // namespace ptda::drivers
