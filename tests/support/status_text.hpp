// Shared by the tests that read the daemon's status files (status.json, the Prometheus file): reading
// a file whole, a minimal RFC 8259 validator and the sample lines of a Prometheus metric family.
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace ptda::test {

/// The whole file as bytes ("" when it cannot be read).
[[nodiscard]] std::string read_text(const std::filesystem::path& p);

/// True when `needle` occurs in `text`.
[[nodiscard]] inline bool has(std::string_view text, std::string_view needle) {
  return text.find(needle) != std::string_view::npos;
}

/// A minimal JSON validator (RFC 8259): `JsonChecker(text).valid()` is true when the text is exactly
/// one JSON value plus whitespace (strings without raw control characters and with valid escapes).
class JsonChecker {
 public:
  explicit JsonChecker(std::string_view s) : s_(s) {}
  [[nodiscard]] bool valid();

 private:
  void ws();
  bool lit(std::string_view w);
  bool value();
  bool object();
  bool array();
  bool string();
  bool number();
  std::string_view s_;
  std::size_t i_ = 0;
};

/// The sample lines of the Prometheus metric family `name` in `text` (without # HELP / # TYPE).
[[nodiscard]] std::vector<std::string> prom_samples(std::string_view text, std::string_view name);

}  // namespace ptda::test
