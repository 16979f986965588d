// libFuzzer target: the simulator's scenario TOML (sim parse_scenario). Bad text must throw ptda::Error.
#include <cstddef>
#include <cstdint>

#include "fuzz_support.hpp"
#include "ptda/common/error.hpp"
#include "ptda/sim/simulator.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    (void)ptda::sim::parse_scenario(ptda::fuzz::as_text(data, size), "fuzz.toml");
  } catch (const ptda::Error&) {
  }
  return 0;
}
