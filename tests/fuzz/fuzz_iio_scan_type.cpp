// libFuzzer target: the IIO `_type` string (drivers/adc/iio_scan_type.cpp). An accepted string must
// format to the canonical text, which parses back to the same type.
#include <cstddef>
#include <cstdint>

#include "adc/iio_scan_type.hpp"
#include "fuzz_support.hpp"
#include "ptda/common/error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    const auto t = ptda::drivers::parse_iio_scan_type(ptda::fuzz::as_text(data, size), "fuzz");
    const auto t2 =
        ptda::drivers::parse_iio_scan_type(ptda::drivers::format_iio_scan_type(t), "fuzz-roundtrip");
    if (!(t == t2)) __builtin_trap();
  } catch (const ptda::Error&) {
  }
  return 0;
}
