// libFuzzer target: one candump log line (formats/src/candump.cpp). A bad line must throw
// ptda::Error (or be skipped as a comment/blank); anything else (crash, UB, other exception) is a bug.
#include <cstddef>
#include <cstdint>

#include "fuzz_support.hpp"
#include "ptda/common/error.hpp"
#include "ptda/formats/candump.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view line = ptda::fuzz::as_text(data, size);
  try {
    const auto rec = ptda::formats::parse_candump_line(line, "fuzz", 1);
    if (rec) {
      // A parsed record must format to a line that parses back to the same frame. The log format
      // keeps microseconds, so a 7..9 digit fraction comes back truncated to the microsecond.
      const std::string again = ptda::formats::format_candump_line(*rec);
      const auto rec2 = ptda::formats::parse_candump_line(again, "fuzz-roundtrip", 1);
      if (!rec2 || rec2->frame.id != rec->frame.id || rec2->frame.len != rec->frame.len ||
          rec2->frame.t_ns != rec->frame.t_ns / 1000 * 1000)
        __builtin_trap();
    }
  } catch (const ptda::Error&) {
  }
  return 0;
}
