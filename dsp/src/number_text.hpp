// Short "%g" text of a number for the error messages of dsp/ (one copy instead of one per file).
#pragma once

#include <cstdio>
#include <string>

namespace ptda::dsp::detail {

/// Thread: any. Allocates (the returned string).
inline std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

}  // namespace ptda::dsp::detail
