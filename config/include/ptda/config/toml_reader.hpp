// Strict, located reading of TOML tables, shared by the pipeline configuration and the daemon's own
// tables: every error is a ptda::Error "<source>:<line>:<column>: <what>", unknown keys are errors,
// integers never silently become floats the other way round. Configure-time only: every function
// here may be called from any thread (on its own objects), allocates, and throws ptda::Error.
#pragma once

#include <toml++/toml.h>

#include <cstdint>
#include <filesystem>
#include <initializer_list>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace ptda::config {

/// A place in a configuration file (line/column 0 when unknown).
struct SourceLocation {
  std::string source;
  long line = 0;
  long column = 0;
};

/// The location of a toml++ region; `fallback_source` is used when the region has no path.
[[nodiscard]] SourceLocation location_of(const toml::source_region& region,
                                         const std::string& fallback_source = {});

/// Throws ptda::Error "<source>:<line>:<column>: <what>".
[[noreturn]] void fail_at(const SourceLocation& where, const std::string& what);

/// Parses TOML text; a syntax error becomes ptda::Error with the line and column toml++ reports.
/// Thread: any. Allocates.
[[nodiscard]] toml::table parse_toml(std::string_view text, const std::string& source);

/// Reads a whole file and parses it (errors name the file). Thread: any. Allocates, blocks on I/O.
[[nodiscard]] toml::table read_toml_file(const std::filesystem::path& path);

/// Reads the keys of one table with type and range checks. Every key asked for is remembered, so
/// finish() can report the keys nobody asked for ("unknown key 'x' in [name] (known keys: ...)").
/// Each read_* returns false (leaving `out` untouched) when the key is absent. Thread: any.
class TableReader {
 public:
  /// `name` is the dotted table path used in messages ("" for the root); `source` names the file
  /// when the table's nodes carry no path.
  TableReader(const toml::table& table, std::string name, std::string source);

  /// A TOML float or integer, finite, within [lo, hi].
  bool read(std::string_view key, double& out, double lo, double hi);
  /// A TOML integer (decimal, hex 0x.., octal, binary) within [lo, hi].
  bool read(std::string_view key, std::uint32_t& out, std::uint32_t lo, std::uint32_t hi);
  bool read(std::string_view key, std::uint8_t& out, std::uint8_t lo, std::uint8_t hi);
  bool read(std::string_view key, bool& out);
  bool read(std::string_view key, std::string& out);
  /// A string that must be one of `choices` (the error lists them).
  template <typename Enum>
  bool read_choice(std::string_view key, Enum& out,
                   std::initializer_list<std::pair<std::string_view, Enum>> choices) {
    std::string text;
    if (!read(key, text)) return false;
    for (const auto& [name, value] : choices) {
      if (text == name) {
        out = value;
        return true;
      }
    }
    std::string list;
    for (const auto& [name, value] : choices)
      list += (list.empty() ? "\"" : ", \"") + std::string(name) + "\"";
    fail_value(key, "must be one of " + list + ", not \"" + text + "\"");
  }
  /// The sub-table at key, or nullptr when absent; an error when key holds something else.
  [[nodiscard]] const toml::table* table(std::string_view key);
  /// Marks key as known without reading it (e.g. a table another component reads).
  void ignore(std::string_view key);

  /// Throws on the first key of the table that was not read or ignored.
  void finish() const;

  /// Location of key's value (or of the key itself when value_location is false); the table's
  /// location when the key is absent.
  [[nodiscard]] SourceLocation location(std::string_view key, bool value_location = true) const;
  /// Throws "<location of key's value>: <table>.<key>: <what>".
  [[noreturn]] void fail_value(std::string_view key, const std::string& what) const;
  /// "[name] key" style name of a key for messages.
  [[nodiscard]] std::string qualified(std::string_view key) const;

  [[nodiscard]] const std::string& name() const noexcept { return name_; }
  [[nodiscard]] const std::string& source() const noexcept { return source_; }

 private:
  const toml::node* find(std::string_view key);
  const toml::table& table_;
  std::string name_;
  std::string source_;
  std::vector<std::string> known_;
};

/// Name of a TOML node type for messages ("integer", "string", "table", ...).
[[nodiscard]] std::string_view toml_type_name(toml::node_type type) noexcept;

}  // namespace ptda::config
