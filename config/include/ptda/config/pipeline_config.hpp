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
#include "ptda/dsp/order_windows.hpp"
#include "ptda/dsp/window_slicer.hpp"

namespace ptda::config {

/// The order domain's parameters (`[extraction] domain = "order"`, docs/method.md §9, docs/cli.md).
struct OrderDomainConfig {
  std::uint32_t samples_per_rev = 1024;  ///< S: angle samples per input-shaft revolution (even, >= 16)
  std::uint32_t revolutions = 8;         ///< R: input-shaft revolutions per window (window N = R S)
  /// Relative width of a speed class (learn_order_classes band_rel): windows whose |joint speed| is
  /// within band_rel of a class's slowest window share it; a window matches a class within +-band/2.
  double speed_band_rel = 0.1;
  std::uint32_t anti_alias_half_taps = 32;  ///< Q of AngleResamplerConfig::half_taps (4..256)
  double anti_alias_cutoff = 0.8;           ///< c of AngleResamplerConfig::cutoff, in (0, 1)
  double min_shaft_hz = 0.5;                ///< |input-shaft speed| below this breaks the stream
  /// CAN log times smoothed over about this many frames (dsp::FrameClock with [can.speed_frame]
  /// period_s) before the angle law is built; 0 = the log times as they are.
  std::uint32_t can_time_smoothing_frames = 32;
  /// Learn the amplitude's speed law in training (|x| proportional to |speed|^p within a class, p fitted
  /// on the healthy windows and applied only when significant; docs/method.md §9) and normalise every
  /// window to its class's speed with it. false: p = 0.
  bool speed_law = true;
};

struct PipelineConfig {
  double fs_hz = 0.0;                       ///< [acquisition] fs_hz: 0 = take the recording's rate
  SpeedFrameSpec speed_frame;               ///< [can.speed_frame]
  double speed_latency_s = 0.0;             ///< [can] speed_latency_s: subtracted from CAN timestamps
  dsp::ExtractionConfig extraction;         ///< [extraction]
  dsp::Domain domain = dsp::Domain::kTime;  ///< [extraction] domain: "time" (default) or "order"
  OrderDomainConfig order;                  ///< [extraction] order keys (used when domain = "order")
  dsp::ClassLearningConfig classes;         ///< [classes]
  dsp::ThresholdPolicy thresholds;          ///< [thresholds]
  dsp::DecisionConfig decision;             ///< [decision]
  dsp::Method method = dsp::Method::kPtda;  ///< [monitor] method
  dsp::GearboxInfo gearbox;                 ///< [gearbox]
  /// Why the default-on mesh detector is off for this configuration (no gearbox teeth, the order
  /// domain), for the tools' notice; empty when it runs or `mesh_cusum = false` was said.
  std::string mesh_off_reason;
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

/// The resampler configuration of the order domain: S, Q, c and min_shaft_hz from cfg.order, the
/// gearbox ratio, max_speed_gap_s from [extraction], speed_latency_s 0 (run_recording and the daemon
/// apply [can] speed_latency_s when they decode the frames). Thread: any. Never allocates.
[[nodiscard]] dsp::AngleResamplerConfig angle_resampler_config(const PipelineConfig& cfg) noexcept;
/// The checks of a baseline against the configuration that do not depend on the input: the same domain,
/// and in the order domain the same S, R and gearbox ratio (the windows are R revolutions of S samples
/// of the input shaft). Throws ptda::Error "<baseline_source>: baseline was trained in the order domain
/// but <config_source> sets [extraction] domain = \"time\": ..." (and the like for S, R and the ratio).
/// Used by `ptda monitor` and `ptdad`. Thread: any. Allocates only to throw.
void check_baseline_domain(const dsp::Baseline& baseline, const std::string& baseline_source,
                           const PipelineConfig& cfg, const std::string& config_source);

/// The order window cutter's configuration; max_order = the resampler's pass_order() (pass it).
/// Thread: any. Never allocates.
[[nodiscard]] dsp::OrderWindowConfig order_window_config(const PipelineConfig& cfg,
                                                         double pass_order) noexcept;

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
