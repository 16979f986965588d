// The monitoring configuration shared by `ptda train/monitor` and ptdad (TOML; see config/README.md).
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "ptda/config/speed_codec.hpp"
#include "ptda/dsp/baseline.hpp"
#include "ptda/dsp/baseline_training.hpp"
#include "ptda/dsp/monitor_engine.hpp"
#include "ptda/dsp/window_slicer.hpp"

namespace ptda::config {

struct PipelineConfig {
  double fs_hz = 0.0;                       ///< [acquisition] fs_hz: 0 = take the recording's rate
  SpeedFrameSpec speed_frame;               ///< [can.speed_frame]
  double speed_latency_s = 0.0;             ///< [can] speed_latency_s: subtracted from CAN timestamps
  dsp::ExtractionConfig extraction;         ///< [extraction]
  dsp::ClassLearningConfig classes;         ///< [classes]
  dsp::ThresholdPolicy thresholds;          ///< [thresholds]
  dsp::DecisionConfig decision;             ///< [decision]
  dsp::Method method = dsp::Method::kPtda;  ///< [monitor] method
  dsp::GearboxInfo gearbox;                 ///< [gearbox]
  /// Accepted but deprecated spellings, one "file:line:col: what to write instead" each (the tools
  /// print them as warnings; see little_endian_deprecation()).
  std::vector<std::string> warnings;
};

/// The message for the pre-issue-17 spelling `little_endian = true|false` of a CAN signal's byte order
/// (scenarios used it, pipeline configurations `byte_order`): "<where>: <key> = true is deprecated
/// (...): write byte_order = \"little\" instead ...". Shared by the pipeline and scenario parsers.
/// Thread: any. Allocates.
[[nodiscard]] std::string little_endian_deprecation(const std::string& where, const std::string& key,
                                                    bool little);

/// Parses TOML text. Unknown keys and tables, wrong types and out-of-range values are errors; absent
/// keys keep the defaults above ([extraction] window_len is required). Throws ptda::Error
/// "<source>:<line>:<column>: <what>" (TOML syntax errors included). Thread: any. Allocates.
[[nodiscard]] PipelineConfig parse_pipeline_config(std::string_view toml_text, const std::string& source);
/// As above, but the tables named in ignored_tables (e.g. the daemon's "daemon", "adc", "alarm") are
/// skipped instead of reported as unknown; a dotted name ("can.interface") skips one key or
/// sub-table of a pipeline table. Thread: any. Allocates.
[[nodiscard]] PipelineConfig parse_pipeline_config(std::string_view toml_text, const std::string& source,
                                                   const std::vector<std::string>& ignored_tables);
/// Reads the file, then (when given) each drop-in in order, later keys overriding earlier ones key by
/// key. Each file is parsed on its own, so errors name the file they are in. Thread: any. Allocates,
/// reads files (blocks).
[[nodiscard]] PipelineConfig load_pipeline_config(const std::filesystem::path& path,
                                                  const std::vector<std::filesystem::path>& dropins = {});
/// As above with top-level tables to skip (see parse_pipeline_config()).
[[nodiscard]] PipelineConfig load_pipeline_config(const std::filesystem::path& path,
                                                  const std::vector<std::filesystem::path>& dropins,
                                                  const std::vector<std::string>& ignored_tables);

/// The effective configuration as TOML text with every key (a valid cfg parses back to equal values).
/// For `--check-config` style output and reports. Thread: any. Allocates.
[[nodiscard]] std::string format_pipeline_config(const PipelineConfig& cfg);

/// eq. (1) of the paper: R = 1 + z_spur / z_in * z_pin (input shaft speed / output speed); 0 when
/// z_in is 0. Thread: any. Never allocates.
[[nodiscard]] constexpr double cycloidal_ratio(std::uint32_t z_in, std::uint32_t z_spur,
                                               std::uint32_t z_pin) noexcept {
  return z_in == 0 ? 0.0 : 1.0 + static_cast<double>(z_spur) / static_cast<double>(z_in) * z_pin;
}

/// Names used in the configuration for the enumerations ("gaussian", "cycloidal", ...).
/// Thread: any. Never allocates or throws.
[[nodiscard]] std::string_view threshold_kind_name(dsp::ThresholdPolicy::Kind kind) noexcept;
[[nodiscard]] std::string_view gearbox_kind_name(dsp::GearboxInfo::Kind kind) noexcept;

}  // namespace ptda::config
