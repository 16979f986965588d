// libFuzzer target: the baseline file parser (formats/src/baseline_file.cpp). The trailing CRC-32 is
// recomputed over the mutated bytes so the fuzzer reaches the header and payload checks behind it.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <vector>

#include "fuzz_support.hpp"
#include "ptda/common/error.hpp"
#include "ptda/formats/baseline_file.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::vector<std::uint8_t> bytes(data, data + size);
  if (bytes.size() >= 5 && (bytes[0] & 1U) == 0U) {
    // Even first byte ('P' of the magic is even): fix the CRC; odd: leave it (tests the CRC check).
    const std::uint32_t crc = ptda::formats::crc32(bytes.data(), bytes.size() - 4);
    for (int i = 0; i < 4; ++i) bytes[bytes.size() - 4 + i] = static_cast<std::uint8_t>(crc >> (8 * i));
  }
  try {
    const auto b = ptda::formats::parse_baseline(bytes, "fuzz.ptdab");
    // An accepted baseline must serialise again (it is consistent).
    (void)ptda::formats::serialize_baseline(b);
  } catch (const ptda::Error&) {
  }
  return 0;
}
