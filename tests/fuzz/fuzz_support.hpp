// Shared by the libFuzzer harnesses (docs/reliability.md): the readers under test take paths, so an
// input is written to a file in a per-process scratch directory first.
#pragma once

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>
#include <vector>

namespace ptda::fuzz {

/// A scratch directory unique to this process (libFuzzer -jobs/-workers run several), made once.
inline const std::filesystem::path& scratch_dir() {
  static const std::filesystem::path dir = [] {
    std::filesystem::path d = std::filesystem::temp_directory_path() /
                              ("ptda-fuzz-" + std::to_string(static_cast<long>(::getpid())));
    std::filesystem::create_directories(d);
    return d;
  }();
  return dir;
}

/// Writes `bytes` to scratch_dir()/name (truncating) and returns the path.
inline std::filesystem::path write_scratch(const std::string& name, std::string_view bytes) {
  const std::filesystem::path p = scratch_dir() / name;
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  return p;
}

inline std::string_view as_text(const std::uint8_t* data, std::size_t size) {
  return {reinterpret_cast<const char*>(data), size};
}

/// Splits `text` at lines "#---" (the separator line is dropped, each part keeps its last newline)
/// into at most `max_parts` parts; the last part takes the rest.
inline std::vector<std::string_view> split_parts(std::string_view text, std::size_t max_parts) {
  std::vector<std::string_view> parts;
  std::size_t start = 0;
  for (;;) {
    const std::size_t cut = text.find("\n#---\n", start);
    if (cut == std::string_view::npos || parts.size() + 1 == max_parts) {
      parts.push_back(text.substr(start));
      return parts;
    }
    parts.push_back(text.substr(start, cut + 1 - start));
    start = cut + 6;
  }
}

}  // namespace ptda::fuzz
