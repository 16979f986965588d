#include "ptda/cli/text.hpp"

#include <cmath>
#include <cstdio>
#include <ctime>

namespace ptda::cli {

std::string fixed(double v, int decimals) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  return buf;
}

std::string general(double v, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*g", digits, v);
  return buf;
}

std::string pad_left(const std::string& s, std::size_t width) {
  return s.size() >= width ? s : std::string(width - s.size(), ' ') + s;
}

std::string pad_right(const std::string& s, std::size_t width) {
  return s.size() >= width ? s : s + std::string(width - s.size(), ' ');
}

std::string utc_time(double unix_s) {
  const double whole = std::floor(unix_s);
  const auto t = static_cast<std::time_t>(whole);
  int ms = static_cast<int>(std::lround((unix_s - whole) * 1000.0));
  std::time_t tt = t;
  if (ms == 1000) {
    ms = 0;
    ++tt;
  }
  std::tm tm{};
  gmtime_r(&tt, &tm);
  char buf[64];
  std::snprintf(buf, sizeof buf, "%04d-%02d-%02d %02d:%02d:%02d.%03d UTC", tm.tm_year + 1900, tm.tm_mon + 1,
                tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec, ms);
  return buf;
}

}  // namespace ptda::cli
