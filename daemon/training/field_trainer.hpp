// Field training mode: collects healthy constant-speed windows and regions from the live inputs into
// a pool preallocated at configure time, reports per-class progress, and finally trains and writes
// the baseline (dsp::train_baseline + formats::write_baseline), so a technician can commission a robot
// without an offline step.
//
// Threads: the processing thread feeds windows and regions (add_window/add_region: noexcept, no
// allocation, lock-free). The supervisor (not real-time) calls progress() and finish(), which allocate
// and may block. Entries are published with a release store of the count and are immutable
// afterwards, so the supervisor can read them while the processing thread keeps adding.
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "ptda/drivers/counter.hpp"
#include "ptda/dsp/baseline.hpp"
#include "ptda/dsp/baseline_training.hpp"
#include "ptda/dsp/monitor_engine.hpp"
#include "ptda/dsp/window_slicer.hpp"

namespace ptda::daemon {

struct FieldTrainerConfig {
  double fs_hz = 0.0;
  std::uint32_t window_len = 0;
  std::uint32_t max_windows = 4096;  ///< pool size (max_windows * window_len floats)
  std::uint32_t max_regions = 4096;
  std::uint32_t target_cycles = 10;  ///< regions (cycles) wanted per class; >= classes.min_regions
  dsp::ClassLearningConfig classes;  ///< classes.min_regions: the least a class needs at finish
  dsp::ThresholdPolicy thresholds;
  dsp::GearboxInfo gearbox;
  std::string source = "ptdad field training";  ///< Baseline::source prefix
};

struct ClassProgress {
  dsp::SegmentClass segment;  ///< learned with min_regions = 1 (every class seen so far)
  std::uint32_t cycles = 0;   ///< regions in the class (= segment.regions)
  std::uint32_t windows = 0;  ///< collected windows whose speed matches the class
  std::uint32_t groups = 0;   ///< of those, groups of overlapping windows (training needs >= 3)
  bool trainable = false;     ///< cycles >= classes.min_regions and groups >= 3
  bool complete = false;      ///< trainable and cycles >= target_cycles
};

struct TrainingProgress {
  std::vector<ClassProgress> classes;
  std::uint32_t target_cycles = 0;
  std::uint64_t windows = 0;  ///< in the pool
  std::uint64_t window_capacity = 0;
  std::uint64_t regions = 0;
  std::uint64_t windows_unmatched = 0;  ///< pooled windows matching no class seen so far
  std::uint64_t windows_dropped = 0;    ///< pool full
  std::uint64_t regions_dropped = 0;
  std::uint64_t windows_rejected = 0;  ///< wrong length or non-finite samples
  std::uint32_t classes_complete = 0;
  std::uint32_t classes_trainable = 0;
  bool ready = false;       ///< at least one class, and every class complete
  bool can_finish = false;  ///< at least one class trainable (finish with kWhatIsThere may work)
};

/// What take_over() kept of a previous trainer's pool (a reload during field training).
struct TrainingCarryOver {
  bool kept = false;               ///< false: the pool was incompatible, nothing was copied (see why)
  std::uint64_t windows = 0;       ///< windows copied
  std::uint64_t regions = 0;       ///< regions (cycles) copied
  std::uint64_t windows_lost = 0;  ///< beyond the new pool size (or all, when not kept)
  std::uint64_t regions_lost = 0;
  std::string why;  ///< when not kept: "window_len 4096 -> 2048 samples", "sample rate ... Hz"
};

enum class FinishMode : std::uint8_t {
  kRequireReady = 0,  ///< refuse unless progress().ready
  kWhatIsThere = 1,   ///< timeout / technician's explicit finish: train the classes that have enough
};

struct FieldTrainerCounters {
  std::uint64_t windows = 0;
  std::uint64_t regions = 0;
  std::uint64_t windows_dropped = 0;
  std::uint64_t regions_dropped = 0;
  std::uint64_t windows_rejected = 0;
};

class FieldTrainer {
 public:
  /// Validates and preallocates the pool. Throws ptda::Error ("training.<key>: ..." / "classes.<key>")
  /// for fs_hz <= 0, window_len 0, max_windows/max_regions 0, target_cycles 0 or < classes.min_regions,
  /// an invalid [classes] table, or a pool above 2 GiB. Thread: the main thread (configure). Allocates.
  explicit FieldTrainer(const FieldTrainerConfig& cfg);

  /// Copies one healthy window into the pool. Returns false (and counts) when the pool is full
  /// (windows_dropped) or the window has the wrong length or a non-finite sample (windows_rejected).
  /// Thread: the processing thread only. Never allocates, blocks or throws.
  bool add_window(const dsp::WindowRef& ref, std::span<const float> samples) noexcept;
  /// Records one ended constant-speed region (a cycle of its segment class). Returns false when the
  /// region pool is full (regions_dropped) or its mean speed is not finite (windows_rejected). Thread: the
  /// processing thread only. Never allocates or blocks.
  bool add_region(const dsp::RegionInfo& region) noexcept;

  /// Classes seen so far (dsp::learn_segment_classes over the pooled regions with min_regions = 1),
  /// cycles and windows per class against the target. Thread: the supervisor (concurrently with the
  /// adders is fine). Allocates (O(regions + windows)); never blocks. Throws only std::bad_alloc.
  [[nodiscard]] TrainingProgress progress() const;

  /// Trains on what is pooled now and writes the baseline atomically to `path` (CRC'd store).
  /// Baseline::source = "<cfg.source>: <regions> regions, <windows> windows". Returns the baseline.
  /// Throws ptda::Error ("field training: ...") when mode is kRequireReady and not ready, when no class
  /// has enough data (saying, per class, cycles/windows vs needed), or when writing fails.
  /// Thread: the supervisor. Allocates (a copy of the pooled windows) and blocks (fsync).
  dsp::Baseline finish(const std::filesystem::path& path, FinishMode mode = FinishMode::kRequireReady) const;

  /// Copies the pool of `previous` (the trainer of the pipeline a reload replaces) into this fresh one
  /// so a reload does not lose the collected windows: possible when the sample rate and the window
  /// length are the same (the windows are samples at that rate and length); pool size, class, threshold
  /// and target settings may differ (they apply at finish; entries beyond a smaller pool are counted as
  /// lost). Windows and regions added afterwards get region and sample numbers after the copied ones,
  /// so the two slicers' numbering cannot merge windows into one overlap group. Call before the
  /// processing thread starts. Thread: the main thread (configure). Allocates nothing; never throws
  /// except std::bad_alloc for `why`.
  TrainingCarryOver take_over(const FieldTrainer& previous);

  /// Empties the pool and the counters. Thread: the processing thread while the supervisor is not
  /// inside progress()/finish() (e.g. when training restarts). Never allocates.
  void reset() noexcept;

  [[nodiscard]] const FieldTrainerConfig& config() const noexcept { return cfg_; }
  /// Thread: any. Never allocates or blocks.
  [[nodiscard]] FieldTrainerCounters counters() const noexcept;
  [[nodiscard]] std::uint64_t window_capacity() const noexcept { return cfg_.max_windows; }

 private:
  struct Snapshot {
    std::uint64_t windows = 0;
    std::uint64_t regions = 0;
  };
  [[nodiscard]] Snapshot published() const noexcept;

  FieldTrainerConfig cfg_;
  std::vector<float> samples_;            ///< max_windows * window_len
  std::vector<dsp::WindowRef> refs_;      ///< max_windows
  std::vector<dsp::RegionInfo> regions_;  ///< max_regions
  std::uint64_t region_seq_offset_ = 0;   ///< added to the slicer's region numbers (after take_over)
  std::int64_t sample_offset_ = 0;        ///< added to the slicer's sample indices (after take_over)
  std::atomic<std::uint64_t> window_count_{0};
  std::atomic<std::uint64_t> region_count_{0};
  drivers::Counter windows_, regions_added_, windows_dropped_, regions_dropped_, windows_rejected_;
};

}  // namespace ptda::daemon
