// The monitoring pipeline after the inputs: window slicer -> PTDA/TDA/raw -> features -> thresholds ->
// k-of-n decision. The daemon's processing thread and `ptda monitor` both drive this one class.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "ptda/dsp/analyzer.hpp"
#include "ptda/dsp/baseline.hpp"
#include "ptda/dsp/decision.hpp"
#include "ptda/dsp/window_slicer.hpp"

namespace ptda::dsp {

struct DecisionConfig {
  std::uint32_t k = 3;  ///< abnormal windows ...
  std::uint32_t n = 5;  ///< ... out of the last n scored windows raise the alarm
};

enum class WindowStatus : std::uint8_t {
  kScored = 0,   ///< features computed and judged
  kNoClass = 1,  ///< no segment class of the baseline matches its speed/direction: not scored
};

struct WindowResult {
  WindowRef ref;
  WindowStatus status = WindowStatus::kScored;
  std::int32_t class_id = -1;
  Features features;
  FeatureThresholds thresholds;  ///< of the class and method used
  Verdict verdict;
  bool alarm = false;  ///< k-of-n state after this window
  std::uint32_t abnormal_in_last_n = 0;
};

class MonitorEngine {
 public:
  /// Copies what it needs of baseline (the caller may drop it). Throws ptda::Error when the baseline's
  /// sample rate or window length disagree with fs_hz / cfg.window_len (says which).
  /// Thread: any (setup). Allocates.
  MonitorEngine(const Baseline& baseline, const ExtractionConfig& cfg, const DecisionConfig& decision,
                Method method, double fs_hz, std::int64_t t0_ns);

  /// Forwarded to the WindowSlicer (see window_slicer.hpp). Thread: the owner's (the daemon's
  /// processing thread). Never allocate or block.
  void push_speed(const SpeedSample& s) noexcept;
  void push_samples(std::span<const float> block) noexcept;
  void mark_gap(std::uint64_t count) noexcept;
  void finish() noexcept;
  /// Next processed window (scored or kNoClass), oldest first. A kNoClass window is not judged and
  /// does not enter the k-of-n decision (its alarm fields repeat the current state). The slicer's
  /// ended regions are drained and dropped here. Thread: the owner's. Never allocates or blocks.
  bool poll(WindowResult& out) noexcept;

  /// The last polled window's samples and the analyzer's buffers for it (reports).
  [[nodiscard]] std::span<const float> last_window() const noexcept { return window_; }
  [[nodiscard]] const WindowAnalyzer& analyzer() const noexcept { return analyzer_; }
  [[nodiscard]] const WindowSlicer& slicer() const noexcept { return slicer_; }
  [[nodiscard]] const Baseline& baseline() const noexcept { return baseline_; }

 private:
  Baseline baseline_;
  Method method_;
  WindowSlicer slicer_;
  WindowAnalyzer analyzer_;
  KOfNDebouncer debouncer_;
  std::vector<float> window_;
};

/// Offline training input: every window of a healthy recording with its region (allocates).
struct CollectedWindows {
  std::vector<WindowRef> refs;
  std::vector<std::vector<float>> windows;
  std::vector<RegionInfo> regions;
};

struct ClassLearningConfig {
  double speed_tol_rel = 0.05;  ///< regions within this relative speed of each other share a class
  double speed_tol_abs_rad_s = 0.02;
  std::uint32_t min_regions = 3;  ///< a class needs at least this many training regions (cycles)
};

/// Groups regions into segment classes by direction and speed (the class's duration is the median
/// region length). Classes with fewer than min_regions regions are dropped. Ids 0.. in order:
/// forward classes by speed, then backward classes by speed (docs/windows.md).
/// Thread: any (offline). Allocates. Throws ptda::Error on a bad configuration (names the key).
[[nodiscard]] std::vector<SegmentClass> learn_segment_classes(const std::vector<RegionInfo>& regions,
                                                              const ClassLearningConfig& cfg);

/// Builds the baseline: classes from the regions, then build_class_baseline() per class with the
/// window's overlap group as leave-out group (windows of one region whose sample ranges overlap share
/// a group). Classes with fewer than 3 groups are left out; kept classes are renumbered 0.. in order.
/// source is left empty for the caller. Thread: any (offline). Allocates.
/// Throws ptda::Error when no class has enough windows (says how many regions/windows per class).
[[nodiscard]] Baseline train_baseline(const CollectedWindows& data, const ClassLearningConfig& classes,
                                      const ThresholdPolicy& policy, double fs_hz,
                                      const GearboxInfo& gearbox);

}  // namespace ptda::dsp
