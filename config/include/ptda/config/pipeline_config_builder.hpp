// Building a PipelineConfig from parsed TOML tables, one file after the other (base file, then
// drop-ins). The daemon uses it to validate the pipeline part of its own configuration files with the
// same rules and messages as `ptda`. Configure-time only: allocates and throws ptda::Error.
#pragma once

#include <toml++/toml.h>

#include <map>
#include <string>
#include <vector>

#include "ptda/config/pipeline_config.hpp"
#include "ptda/config/toml_reader.hpp"

namespace ptda::config {

class PipelineConfigBuilder {
 public:
  /// ignored_tables: tables or keys that belong to someone else (skipped, not reported as unknown):
  /// "daemon" skips the top-level table [daemon]; a dotted name such as "can.interface" skips that
  /// key (or sub-table) inside a pipeline table. Thread: any. Allocates.
  explicit PipelineConfigBuilder(std::vector<std::string> ignored_tables = {});

  /// Applies one parsed file over what was applied before: every key present overrides, absent keys
  /// keep their value. Per-key type and range errors are thrown here; `source` names the file when
  /// the table carries no path. Thread: the caller's. Allocates.
  void apply(const toml::table& root, const std::string& source);

  /// Cross-key checks on the merged result (window_len given and a valid FFT length, k <= n,
  /// min_speed < max_speed, speed frame consistency, gearbox teeth vs. ratio), each error located at
  /// the key that was set last. Computes gearbox.ratio from the teeth when not given explicitly.
  /// Thread: the caller's. Allocates.
  [[nodiscard]] PipelineConfig finish() const;

 private:
  void note(const TableReader& reader, std::string_view key);
  void ignore_owned(TableReader& reader) const;
  [[noreturn]] void fail_key(const std::string& path, const std::string& what) const;

  PipelineConfig cfg_;
  std::vector<std::string> ignored_;
  /// Dotted key path -> where its value was set last (for cross-key errors after merging).
  std::map<std::string, SourceLocation, std::less<>> set_at_;
  bool ratio_given_ = false;
  SourceLocation main_source_;  ///< the first file applied: named when a required key is missing
};

}  // namespace ptda::config
