// What `ptda monitor` prints and writes per window, shared with `ptda report` and the tests.
// Thread: any. Allocates.
#pragma once

#include <cstdint>
#include <iosfwd>
#include <optional>
#include <string>
#include <vector>

#include "ptda/cli/pipeline_runner.hpp"
#include "ptda/config/pipeline_config.hpp"
#include "ptda/dsp/baseline.hpp"
#include "ptda/dsp/monitor_engine.hpp"

namespace ptda::cli {

/// One JSONL line (no newline): n, t_start, t_end (UNIX s), segment (class id or null), region,
/// speed_rad_s, status ("scored"|"no_class"), method, rms_res, entropy_res, rms_band [lo,hi],
/// entropy_band [lo,hi] (null when not scored), rms_out, entropy_out, abnormal, alarm, abnormal_in_last_n.
[[nodiscard]] std::string window_json(const dsp::WindowResult& w, dsp::Method method);

[[nodiscard]] std::string window_table_header();
/// One table row; times relative to t0_ns (the recording's sample 0); decision_n: the alarm's n.
[[nodiscard]] std::string window_table_row(const dsp::WindowResult& w, std::int64_t t0_ns,
                                           std::uint32_t decision_n);

struct MonitorSummary {
  std::uint64_t windows = 0, scored = 0, no_class = 0;
  std::uint64_t abnormal = 0, rms_out = 0, entropy_out = 0, alarm_windows = 0;
  std::uint64_t rms_low = 0;  ///< scored windows with the residual below its band (not abnormal)
  double rms_sum = 0.0, entropy_sum = 0.0;  ///< over scored windows
  std::optional<dsp::WindowResult> first_abnormal, first_alarm;
  std::int64_t t0_ns = 0;
};
[[nodiscard]] MonitorSummary summarize(const std::vector<dsp::WindowResult>& windows, std::int64_t t0_ns);
void print_summary(std::ostream& out, const MonitorSummary& s, const dsp::SlicerCounters& slicer,
                   const CanCounters& can, dsp::Method method);

/// Configuration, baseline and recording of a monitor/report run, checked against each other.
struct MonitorInputs {
  std::string config_path, baseline_path;
  config::PipelineConfig cfg;
  dsp::Baseline baseline;
  RecordingInfo rec;
  double fs_hz = 0.0;
};
/// Loads all three; throws ptda::Error naming the file at fault (missing, corrupt, mismatching).
[[nodiscard]] MonitorInputs load_monitor_inputs(const std::string& recording, const std::string& config_path,
                                                const std::string& baseline_path);

}  // namespace ptda::cli
