// Field training mode: collects healthy constant-speed windows and regions from the live inputs,
// reports per-class progress, and finally trains and writes the baseline (dsp::train_baseline_streamed
// + formats::write_baseline, as `ptda train`), so a technician can commission a robot without an
// offline step.
//
// Memory does not hold the windows. They go to a spill file on disk (created in `spill_dir` and
// unlinked at once, so nothing is left behind after a stop or a crash): the processing thread copies
// each window into one of kSpillSlots preallocated slots and queues it (lock-free SPSC); the trainer's
// own writer thread appends it to the file and then publishes it. finish() streams the file twice
// into the training. In memory: kSpillSlots windows, and per window only its place (dsp::WindowRef).
//
// Threads: the processing thread feeds windows and regions (add_window/add_region: noexcept, no
// allocation, lock-free, never blocks). The writer thread (start/stop) is the only one that writes the
// file and publishes windows. The supervisor (not real-time) calls progress() and finish(), which
// allocate and may block. Entries are published with a release store of the count and are immutable
// afterwards, so the supervisor can read them while the other threads keep adding.
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <thread>
#include <vector>

#include "ptda/drivers/counter.hpp"
#include "ptda/dsp/baseline.hpp"
#include "ptda/dsp/baseline_training.hpp"
#include "ptda/dsp/monitor_engine.hpp"
#include "ptda/dsp/window_slicer.hpp"
#include "rt/spsc_ring.hpp"
#include "rt/wake_signal.hpp"

namespace ptda::daemon {

struct FieldTrainerConfig {
  double fs_hz = 0.0;
  std::uint32_t window_len = 0;
  std::uint32_t max_windows = 4096;  ///< windows kept at most (on disk: max_windows * window_len floats)
  std::uint32_t max_regions = 4096;
  std::filesystem::path spill_dir;   ///< where the (unlinked) spill file lives; must exist
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
  std::uint64_t windows = 0;  ///< collected (written to the spill file)
  std::uint64_t window_capacity = 0;
  std::uint64_t windows_queued = 0;  ///< handed over by the processing thread, not written yet
  std::uint64_t regions = 0;
  std::uint64_t windows_unmatched = 0;  ///< pooled windows matching no class seen so far
  std::uint64_t windows_dropped = 0;    ///< max_windows reached, the queue full or a failed write
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
  std::uint64_t windows = 0;  ///< written to the spill file
  std::uint64_t regions = 0;
  std::uint64_t windows_dropped = 0;       ///< all drops: max_windows, queue full, write failed
  std::uint64_t windows_queue_full = 0;    ///< of those: the writer was behind (a slow disk)
  std::uint64_t windows_write_failed = 0;  ///< of those: the spill file's write failed
  int last_write_errno = 0;                ///< of the last failed write (0: none)
  std::uint64_t regions_dropped = 0;
  std::uint64_t windows_rejected = 0;
};

class FieldTrainer {
 public:
  /// Windows queued between the processing thread and the writer (the RAM the windows take).
  static constexpr std::size_t kSpillSlots = 32;

  /// Validates, preallocates the queue and the window places, and creates the spill file in
  /// cfg.spill_dir (unlinked at once). Throws ptda::Error ("training.<key>: ..." / "classes.<key>")
  /// for fs_hz <= 0, window_len 0, max_windows/max_regions 0, target_cycles 0 or < classes.min_regions,
  /// an invalid [classes] table, more than 64 GiB of windows, or a spill file that cannot be created
  /// (naming the directory and the system error). Thread: the main thread (configure). Allocates.
  explicit FieldTrainer(const FieldTrainerConfig& cfg);
  /// Stops the writer (what is queued is written first) and closes the spill file (gone with it).
  ~FieldTrainer();
  FieldTrainer(const FieldTrainer&) = delete;
  FieldTrainer& operator=(const FieldTrainer&) = delete;

  /// Starts the writer thread; `on_space` (may be null) is rung after the writer freed slots, for a
  /// fast replay that waits for room (free_slots()). Thread: the main thread (activate). Allocates
  /// (the thread).
  void start(WakeSignal* on_space);
  /// Stops the writer thread after it has written every queued window. Thread: the main thread
  /// (deactivate), after the processing thread stopped adding. Blocks (joins). Idempotent.
  void stop() noexcept;
  /// Writes every queued window on the calling thread: for a trainer whose writer is not started
  /// (tests, tools). Thread: not concurrently with a running writer. Blocks (file writes).
  void flush() noexcept;

  /// Copies one healthy window into a free slot and queues it for the writer. Returns false (and
  /// counts) when max_windows windows were taken already or the queue is full (windows_dropped;
  /// windows_queue_full), or the window has the wrong length or a non-finite sample
  /// (windows_rejected). Thread: the processing thread only. Never allocates, blocks or throws.
  bool add_window(const dsp::WindowRef& ref, std::span<const float> samples) noexcept;
  /// Free queue slots now (for the processing thread: at least this many add_window() calls will find
  /// room). Thread: any. Never blocks or allocates.
  [[nodiscard]] std::size_t free_slots() const noexcept { return kSpillSlots - queue_.size_approx(); }
  /// Windows queued and not yet written. Thread: any. Never blocks or allocates.
  [[nodiscard]] std::size_t queued() const noexcept { return queue_.size_approx(); }
  /// Records one ended constant-speed region (a cycle of its segment class). Returns false when the
  /// region pool is full (regions_dropped) or its mean speed is not finite (windows_rejected). Thread: the
  /// processing thread only. Never allocates or blocks.
  bool add_region(const dsp::RegionInfo& region) noexcept;

  /// Classes seen so far (dsp::learn_segment_classes over the pooled regions with min_regions = 1),
  /// cycles and windows per class against the target. Thread: the supervisor (concurrently with the
  /// adders is fine). Allocates (O(regions + windows)); never blocks. Throws only std::bad_alloc.
  [[nodiscard]] TrainingProgress progress() const;

  /// Trains on the windows written so far and writes the baseline atomically to `path` (CRC'd store).
  /// Baseline::source = "<cfg.source>: <regions> regions, <windows> windows". Returns the baseline.
  /// Throws ptda::Error ("field training: ...") when mode is kRequireReady and not ready, when no class
  /// has enough data (saying, per class, cycles/windows vs needed), when the spill file cannot be read
  /// back, or when writing fails. Thread: the supervisor. Allocates (the training's class sums and
  /// one window) and blocks (reads the spill file twice, fsync).
  dsp::Baseline finish(const std::filesystem::path& path, FinishMode mode = FinishMode::kRequireReady) const;

  /// Takes the collected windows of `previous` (the trainer of the pipeline a reload replaces, its
  /// writer stopped) into this fresh one so a reload does not lose them: possible when the sample rate
  /// and the window length are the same (the windows are samples at that rate and length); the
  /// maximum counts, class, threshold and target settings may differ (they apply at finish; entries
  /// beyond a smaller maximum are counted as lost). The places and regions are copied; the spill file
  /// is shared (a dup of its descriptor: `previous` stays valid, so a reload that fails can hand the
  /// same windows to the restart), and this trainer's own empty file is closed. Windows and regions
  /// added afterwards get region and sample numbers after the copied ones, so the two slicers'
  /// numbering cannot merge windows into one overlap group. The file stays in previous's spill_dir
  /// (config().spill_dir says so afterwards). Call before start(): it sets counters that the writer and
  /// the processing thread own once running. Thread: the main thread (configure). Throws ptda::Error
  /// when the descriptor cannot be duplicated.
  TrainingCarryOver take_over(const FieldTrainer& previous);

  [[nodiscard]] const FieldTrainerConfig& config() const noexcept { return cfg_; }
  /// Thread: any. Never allocates or blocks.
  [[nodiscard]] FieldTrainerCounters counters() const noexcept;
  [[nodiscard]] std::uint64_t window_capacity() const noexcept { return cfg_.max_windows; }
  /// The warning to log when the spill file's file system has less room than the file may need
  /// (max_spill_bytes()), else "". Thread: the main thread (after configure). Never throws; one fstatvfs.
  [[nodiscard]] std::string spill_space_warning() const;
  /// The text of that warning for `need_bytes` against `free_bytes` in `dir` ("" when it fits).
  [[nodiscard]] static std::string spill_space_text(const std::filesystem::path& dir,
                                                    std::uint64_t need_bytes, std::uint64_t free_bytes);
  /// Test hook: the spill file's descriptor (a test swaps in /dev/full to see a failing disk).
  [[nodiscard]] int spill_fd_for_test() const noexcept { return fd_; }
  /// Test hook: `hook(ctx)` runs on the writer each time it found the queue empty, before it decides
  /// whether to stop (a test holds it there to force the add/stop race). Set before start().
  void set_idle_hook_for_test(void (*hook)(void*), void* ctx) noexcept {
    idle_hook_ = hook;
    idle_ctx_ = ctx;
  }
  /// Whether stop() has been asked for (test hook). Thread: any.
  [[nodiscard]] bool stop_requested_for_test() const noexcept {
    return stop_.load(std::memory_order_acquire);
  }
  /// Bytes one window takes in the spill file, and the most the file can grow to.
  [[nodiscard]] std::uint64_t window_bytes() const noexcept { return std::uint64_t{cfg_.window_len} * 4; }
  [[nodiscard]] std::uint64_t max_spill_bytes() const noexcept { return cfg_.max_windows * window_bytes(); }

 private:
  struct Queued {
    dsp::WindowRef ref;  ///< offsets applied; its samples are in slot (queue index % kSpillSlots)
  };
  struct Snapshot {
    std::uint64_t windows = 0;
    std::uint64_t regions = 0;
  };
  [[nodiscard]] Snapshot published() const noexcept;
  /// Writes what is queued; returns how many entries it took. Thread: the writer (or flush()).
  std::size_t write_queued() noexcept;
  void writer_loop() noexcept;

  FieldTrainerConfig cfg_;
  int fd_ = -1;                           ///< the spill file (unlinked): window i at i * window_bytes()
  std::vector<float> slots_;              ///< kSpillSlots * window_len
  SpscRing<Queued, kSpillSlots> queue_;   ///< processing thread -> writer
  std::vector<dsp::WindowRef> refs_;      ///< max_windows, written by the writer
  std::vector<dsp::RegionInfo> regions_;  ///< max_regions
  std::uint64_t region_seq_offset_ = 0;   ///< added to the slicer's region numbers (after take_over)
  std::int64_t sample_offset_ = 0;        ///< added to the slicer's sample indices (after take_over)
  std::uint64_t taken_ = 0;               ///< windows queued so far (processing thread: the max_windows cap)
  std::atomic<std::uint64_t> window_count_{0};  ///< written and published (writer)
  std::atomic<std::uint64_t> region_count_{0};
  std::atomic<int> last_write_errno_{0};
  WakeSignal work_;  ///< rung by add_window for the writer
  WakeSignal* on_space_ = nullptr;
  std::atomic<bool> stop_{false};
  void (*idle_hook_)(void*) = nullptr;
  void* idle_ctx_ = nullptr;
  std::thread writer_;
  // windows_ and write_failed_ belong to the writer; the others to the processing thread.
  drivers::Counter windows_, regions_added_, windows_dropped_, queue_full_, write_failed_, regions_dropped_,
      windows_rejected_;
};

}  // namespace ptda::daemon
