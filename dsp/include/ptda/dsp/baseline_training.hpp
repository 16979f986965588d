// The training glue (dsp/src/baseline_training.cpp): segment classes from the regions of a healthy
// recording, then the baseline from its collected windows. Offline (`ptda train`) and the daemon's
// field training at finish: allocates and throws ptda::Error.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "ptda/dsp/baseline.hpp"
#include "ptda/dsp/spill.hpp"
#include "ptda/dsp/training.hpp"
#include "ptda/dsp/window_slicer.hpp"

namespace ptda::dsp {

/// Receives window `index` (into the training data's refs) with its samples.
using TrainingWindowVisitor = std::function<void(std::size_t index, std::span<const float> x)>;
/// One pass over the training windows: calls the visitor once for every window of the training data,
/// in cut order (index 0, 1, ...); the samples need only live for the call.
using TrainingWindowPass = std::function<void(const TrainingWindowVisitor&)>;

/// Offline training input: every window of a healthy recording with its region (allocates).
struct CollectedWindows {
  std::vector<WindowRef> refs;
  std::vector<std::vector<float>> windows;
  std::vector<RegionInfo> regions;
  /// Per window: the index of the training recording (day) it came from, for the between-day spread
  /// (docs/method.md §5). Empty = all windows come from one recording.
  std::vector<std::uint32_t> recording;
};

/// The index of a streamed training: each window's place and training recording (day, 0-based), in
/// cut order, and the regions, in spill vectors, so that its memory does not grow with the training
/// data (docs/cli.md, `ptda train`, "Memory"). `spill` is also where the training spills its own
/// per-window values.
struct TrainingIndex {
  explicit TrainingIndex(const SpillConfig& cfg = {});
  SpillConfig spill;
  SpillVector<WindowRef> refs;
  SpillVector<std::uint32_t> recording;  ///< one per ref
  SpillVector<RegionInfo> regions;
};

/// The index of in-memory training data (its refs, regions and recordings; recording 0 for every window
/// when data.recording is empty). Throws ptda::Error when data.recording has another size than refs.
[[nodiscard]] TrainingIndex make_training_index(const CollectedWindows& data, const SpillConfig& spill = {});

struct ClassLearningConfig {
  double speed_tol_rel = 0.05;  ///< regions within this relative speed of each other share a class
  double speed_tol_abs_rad_s = 0.02;
  std::uint32_t min_regions = 3;  ///< a class needs at least this many training regions (cycles)
};

/// Groups regions into segment classes by direction and speed (the class's duration is the median
/// region length). Classes with fewer than min_regions regions are dropped; when `dropped` is given,
/// one line per dropped speed group is appended to it ("speed +1.5 rad/s: 2 regions, fewer than
/// classes.min_regions = 3"). Ids 0.. in order: forward classes by speed, then backward classes by
/// speed (docs/windows.md).
/// Thread: any (offline). Allocates. Throws ptda::Error on a bad configuration (names the key).
[[nodiscard]] std::vector<SegmentClass> learn_segment_classes(const std::vector<RegionInfo>& regions,
                                                              const ClassLearningConfig& cfg,
                                                              std::vector<std::string>* dropped = nullptr);
/// learn_segment_classes() of regions in a spill vector (sorted in bounded memory; the same classes).
[[nodiscard]] std::vector<SegmentClass> learn_segment_classes_streamed(
    const SpillVector<RegionInfo>& regions, const ClassLearningConfig& cfg,
    std::vector<std::string>* dropped = nullptr);

/// Builds the baseline: classes from the regions, then build_class_baseline() per class with the
/// window's overlap group as leave-out group (windows of one region whose sample ranges overlap share
/// a group). Classes with fewer than 3 groups are left out; kept classes are renumbered 0.. in order.
/// source is left empty for the caller. Thread: any (offline). Allocates.
/// When `dropped` is given, one line per class (or speed group) left out is appended, saying which
/// (direction, speed) and why (too few regions, too few non-overlapping window groups).
/// Throws ptda::Error when no class has enough windows: the message lists every dropped class and why.
[[nodiscard]] Baseline train_baseline(const CollectedWindows& data, const ClassLearningConfig& classes,
                                      const ThresholdPolicy& policy, double fs_hz, const GearboxInfo& gearbox,
                                      std::vector<std::string>* dropped = nullptr);

/// train_baseline() without holding the windows: `index` holds the refs, regions and recording ids
/// and `pass` hands the windows over, one at a time; it is called twice (the class sums, then the
/// leave-one-group-out features and the hold-out's features), so a caller can stream a recording twice
/// instead of keeping it. Same result, byte for byte, as train_baseline() on the same windows (it is
/// built on this) as long as no per-window list spills (index.spill.memory_bytes per list); beyond, the
/// sums of the threshold statistics are formed chunk by chunk (equal up to rounding) and every order
/// statistic stays exact. Memory: O(N) per class, index.spill.memory_bytes per per-window list, and the
/// windows of one overlap group at a time (a group is scored when its last window in cut order has
/// come). Spill files go to index.spill.dir. Throws as train_baseline() does, when a pass does not
/// visit every window exactly once, in order, and when a spill file fails. Thread: any (offline).
/// Allocates.
[[nodiscard]] Baseline train_baseline_streamed(const TrainingIndex& index, std::size_t window_len,
                                               const TrainingWindowPass& pass,
                                               const ClassLearningConfig& classes,
                                               const ThresholdPolicy& policy, double fs_hz,
                                               const GearboxInfo& gearbox,
                                               std::vector<std::string>* dropped = nullptr);
/// The same with the index of in-memory data (make_training_index(index); its `windows` is ignored).
[[nodiscard]] Baseline train_baseline_streamed(const CollectedWindows& index, std::size_t window_len,
                                               const TrainingWindowPass& pass,
                                               const ClassLearningConfig& classes,
                                               const ThresholdPolicy& policy, double fs_hz,
                                               const GearboxInfo& gearbox,
                                               std::vector<std::string>* dropped = nullptr);

}  // namespace ptda::dsp
