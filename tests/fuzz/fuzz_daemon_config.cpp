// libFuzzer target: the daemon configuration with drop-ins (daemon/core/daemon_config.cpp and the
// pipeline parser under it). The input is split at lines "#---" into the main file and drop-ins.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "core/daemon_config.hpp"
#include "fuzz_support.hpp"
#include "ptda/common/error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text = ptda::fuzz::as_text(data, size);
  const std::vector<std::string_view> parts = ptda::fuzz::split_parts(text, 4);
  const auto main = ptda::fuzz::write_scratch("ptdad.toml", parts[0]);
  std::vector<std::filesystem::path> dropins;
  for (std::size_t i = 1; i < parts.size(); ++i)
    dropins.push_back(ptda::fuzz::write_scratch("dropin" + std::to_string(i) + ".toml", parts[i]));
  try {
    (void)ptda::daemon::load_daemon_config(main, dropins);
  } catch (const ptda::Error&) {
  }
  return 0;
}
