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
/// As above; an order-domain window carries "domain": "order" after "method" (time: no key, as above).
[[nodiscard]] std::string window_json(const dsp::WindowResult& w, dsp::Method method, dsp::Domain domain);

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
/// Adds one window to a running summary (summarize() is this over the windows, with s.t0_ns set).
void summarize_add(MonitorSummary& s, const dsp::WindowResult& w);
void print_summary(std::ostream& out, const MonitorSummary& s, const dsp::SlicerCounters& slicer,
                   const CanCounters& can, dsp::Method method);

/// The coverage block of the summary: per class judged windows and the age of the last one, unmatched
/// windows by reason with the speeds seen, the coverage state. t0_ns: the recording's sample 0.
void print_coverage(std::ostream& out, const dsp::CoverageState& c, const dsp::Baseline& baseline,
                    double timeout_s, std::int64_t t0_ns);
/// Warnings about the coverage ("warning: ..." lines; none when every class was judged recently and at
/// least half of the cut windows were judged). Returns how many were printed.
std::size_t print_coverage_warnings(std::ostream& out, const dsp::CoverageState& c,
                                    const dsp::Baseline& baseline, double timeout_s);

/// Compares the judged recording with the baseline's training recordings (dsp::Baseline::training):
/// "warning: in-sample: ..." when it is one of them (same recording id) and the windows judged overlap
/// the windows trained on; a note when it is one of them but the windows are disjoint (a held-out
/// part), or when the baseline does not list its training recordings. `windows` are the judged windows
/// (UNIX times); t0_ns: the recording's sample 0 (times are printed from it). Returns true when it
/// warned. Thread: any. Allocates.
bool print_training_overlap(std::ostream& out, const dsp::Baseline& baseline, const std::string& recording_id,
                            const std::vector<dsp::WindowResult>& windows, std::int64_t t0_ns);

/// The time span of the judged windows, gathered window by window (for print_training_overlap without
/// keeping the windows).
struct WindowSpan {
  bool any = false;
  std::int64_t from_ns = 0;  ///< earliest t_start_ns
  std::int64_t to_ns = 0;    ///< latest t_end_ns
  void add(const dsp::WindowResult& w) noexcept;
};
bool print_training_overlap(std::ostream& out, const dsp::Baseline& baseline, const std::string& recording_id,
                            const WindowSpan& span, std::int64_t t0_ns);

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
