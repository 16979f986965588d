// Constant-speed window extraction (paper section 3.1), streaming and allocation-free after
// construction. Speed samples and vibration samples may arrive interleaved in any order relative to
// each other (each stream in time order): a window's content depends only on the two timelines, so
// the daemon's threads and the offline tool cut exactly the same windows.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "ptda/dsp/types.hpp"

namespace ptda::dsp {

struct ExtractionConfig {
  std::uint32_t window_len = 0;  ///< N samples per window (a RealFft length)
  std::uint32_t hop = 0;         ///< samples between window starts in one region; 0 = window_len
  double speed_tol_rel = 0.02;   ///< constant while | v - mean | <= max(rel * |mean|, abs)
  double speed_tol_abs_rad_s = 0.005;
  double min_speed_rad_s = 0.05;  ///< |v| below this is standstill: never a region
  double max_speed_rad_s = 1e9;   ///< |v| above this is out of the configured range: breaks a region
  double min_duration_s = 0.1;    ///< a region must have lasted this long before windows are cut
  double guard_s = 0.0;           ///< skipped after the region start (settling after the blend)
  double max_speed_gap_s = 0.05;  ///< speed samples further apart break the region (CAN silence)
  std::uint32_t max_windows_per_region = 0;  ///< 0 = unlimited
  double clip_abs = 0.0;                     ///< |x| >= this counts as clipped (0 = no clip check)
};

/// A completed or ongoing constant-speed region.
struct RegionInfo {
  std::uint64_t seq = 0;
  std::int64_t t_begin_ns = 0;
  std::int64_t t_end_ns = 0;      ///< time of the last speed sample in the region
  double mean_speed_rad_s = 0.0;  ///< signed
  std::int8_t direction = 1;
};

/// Where a cut window lies.
struct WindowRef {
  std::uint64_t seq = 0;  ///< windows cut so far (0-based), counted when the speed timeline
                          ///< confirms the window, so discarded windows leave gaps
  std::uint64_t region_seq = 0;
  std::uint32_t index_in_region = 0;
  std::int64_t first_sample = 0;  ///< absolute index of x[0] in the sample stream
  std::int64_t t_start_ns = 0;    ///< time of x[0]
  std::int64_t t_end_ns = 0;      ///< time of x[N-1] + 1/fs
  double speed_rad_s = 0.0;       ///< region mean speed (signed) over the region's speed samples up
                                  ///< to the one that confirmed the window's end (a function of the
                                  ///< speed timeline only, whatever the interleaving of pushes)
};

struct SlicerCounters {
  std::uint64_t speed_samples = 0;
  std::uint64_t speed_out_of_order = 0;  ///< dropped: timestamp not after the previous one
  std::uint64_t speed_gaps = 0;          ///< open runs broken by CAN silence (> max_speed_gap_s)
  std::uint64_t speed_out_of_range = 0;  ///< samples above max_speed_rad_s or not finite
  std::uint64_t regions = 0;             ///< regions that reached min_duration
  std::uint64_t windows = 0;             ///< windows handed out by pop()
  std::uint64_t windows_invalid = 0;     ///< discarded: NaN/Inf, clipped or missing samples inside
  std::uint64_t windows_lost = 0;        ///< discarded: samples already overwritten in the history
  std::uint64_t windows_overflow = 0;    ///< discarded: too many cut windows still waiting for samples
  std::uint64_t regions_dropped = 0;     ///< ended regions overwritten because nobody popped them
  std::uint64_t samples = 0;
  std::uint64_t samples_nonfinite = 0;
  std::uint64_t samples_clipped = 0;
  std::uint64_t samples_missing = 0;  ///< declared by mark_gap()
};

class WindowSlicer {
 public:
  /// fs_hz: nominal sample rate, a multiple of 0.001 Hz up to 1 MHz (sample times are then exact
  /// integers: sample i is at t0_ns + ceil(i * 1e9 / fs) ns); t0_ns: time of sample 0.
  /// history_len: samples kept for windows whose speed confirmation arrives late
  /// (0 = 4 windows + 1 s; must be >= window_len). Up to 2 * history_len / hop + 64 cut windows may
  /// wait for their samples (speed ahead of the vibration stream); more are counted as
  /// windows_overflow. Thread: any (setup). Allocates.
  /// Throws ptda::Error on an invalid configuration (names the TOML key, e.g. extraction.window_len).
  WindowSlicer(const ExtractionConfig& cfg, double fs_hz, std::int64_t t0_ns, std::size_t history_len = 0);

  /// Speed samples in time order. A sample not after the latest accepted one is dropped and counted
  /// (speed_out_of_order) and ends the open run. Thread: the owner's. Never allocates or blocks.
  void push_speed(const SpeedSample& s) noexcept;
  /// The next consecutive vibration samples. Non-finite or clipped samples invalidate the windows
  /// that contain them. Thread: the owner's. Never allocates or blocks.
  void push_samples(std::span<const float> block) noexcept;
  /// `count` samples were lost (ADC overrun): they are filled as invalid. Thread: the owner's.
  /// Never allocates or blocks.
  void mark_gap(std::uint64_t count) noexcept;
  /// End of input: the open region ends at the last speed sample. Windows already cut stay
  /// poppable. Thread: the owner's. Never allocates or blocks.
  void finish() noexcept;

  /// The next valid window, oldest first: fills ref and out (out.size() must equal window_len, else
  /// returns false and consumes nothing). Windows with invalid samples or samples already overwritten
  /// in the history are skipped and counted. Returns false when none is complete yet.
  /// Thread: the owner's. Never allocates or blocks.
  bool pop(WindowRef& ref, std::span<float> out) noexcept;
  /// Whether pop() has a window to consider now (the oldest cut window has all its samples; pop() may
  /// still skip it as invalid or lost). Thread: the owner's. Never allocates or blocks.
  [[nodiscard]] bool has_window() const noexcept {
    return !pending_.empty() &&
           pending_.front().first_sample + static_cast<std::int64_t>(cfg_.window_len) <= samples_total_;
  }
  /// The next region that ended (and reached min_duration), oldest first; the last 256 are kept.
  /// Thread: the owner's. Never allocates or blocks.
  bool pop_region(RegionInfo& region) noexcept;

  /// The earliest speed-timeline time (on this slicer's clock, t0_ns-based) at which the next window
  /// can be cut: a lower bound, so no window is handed out for a speed timeline that ends before it.
  /// It is exact for the next window of an open region (its t_end_ns), the later of the first window's
  /// end and the region's min_duration for a candidate run, a cut window's t_end_ns while it waits for
  /// its samples, and for any run not yet begun (standstill, speed changing, no speed yet) one
  /// new_run_close_ns() after the newest speed sample. The open run may still break, so the time is
  /// when a window may close, not when one will. The
  /// daemon sleeps until then (docs/daemon.md, "Sleeping until a window can close").
  /// Thread: the owner's. Never allocates or blocks.
  [[nodiscard]] std::int64_t next_close_ns() const noexcept;
  /// The shortest time from a speed sample that starts a run to the first window that run can close:
  /// max(min_duration_s, guard_s + window_len / fs), less 1 ns of rounding. Thread: any.
  [[nodiscard]] std::int64_t new_run_close_ns() const noexcept { return new_run_close_ns_; }
  /// Samples between window starts in one region (hop, or window_len when hop = 0). Thread: any.
  [[nodiscard]] std::int64_t hop_samples() const noexcept { return hop_; }

  [[nodiscard]] const SlicerCounters& counters() const noexcept { return counters_; }
  [[nodiscard]] double fs_hz() const noexcept { return fs_hz_; }
  [[nodiscard]] const ExtractionConfig& config() const noexcept { return cfg_; }

 private:
  /// Fixed-capacity FIFO over a vector sized at construction (no allocation afterwards).
  template <typename T>
  class Fifo {
   public:
    void reserve(std::size_t capacity) { items_.assign(capacity, T{}); }
    [[nodiscard]] bool empty() const noexcept { return size_ == 0; }
    [[nodiscard]] bool full() const noexcept { return size_ == items_.size(); }
    [[nodiscard]] std::size_t size() const noexcept { return size_; }
    [[nodiscard]] const T& front() const noexcept { return items_[head_]; }
    [[nodiscard]] const T& at(std::size_t i) const noexcept { return items_[(head_ + i) % items_.size()]; }
    void push(const T& v) noexcept {
      items_[(head_ + size_) % items_.size()] = v;
      ++size_;
    }
    void pop() noexcept {
      head_ = (head_ + 1) % items_.size();
      --size_;
    }
    void clear() noexcept { head_ = size_ = 0; }

   private:
    std::vector<T> items_;
    std::size_t head_ = 0;
    std::size_t size_ = 0;
  };

  struct RunSample {
    std::int64_t t_ns;
    double speed_rad_s;
  };

  /// An open run of one-sign, in-range speed samples; a region once it lasted min_duration.
  struct Run {
    bool open = false;
    bool is_region = false;
    bool trimmable = true;  ///< all of the run's samples are in run_samples_ (only before it is a region)
    std::int8_t direction = 1;
    std::uint32_t n = 0;
    double ref_rad_s = 0.0;  ///< the run's first speed; sums are of v - ref (exact for constant speed)
    double sum_dev_rad_s = 0.0;
    double min_rad_s = 0.0;
    double max_rad_s = 0.0;
    std::int64_t t_first_ns = 0;
    std::int64_t t_last_ns = 0;
    std::uint64_t region_seq = 0;
    std::uint32_t windows_cut = 0;
    std::int64_t first_sample0 = 0;  ///< start of window 0 (valid once is_region)
    [[nodiscard]] double mean_rad_s() const noexcept {
      return ref_rad_s + sum_dev_rad_s / static_cast<double>(n);
    }
  };

  [[nodiscard]] bool fits(double sum_dev_rad_s, double min_rad_s, double max_rad_s,
                          std::uint32_t n) const noexcept;
  void start_run(const SpeedSample& s, std::int8_t direction) noexcept;
  void join_run(const SpeedSample& s) noexcept;
  bool trim_run_for(double v_rad_s) noexcept;
  void end_run() noexcept;
  void cut_windows() noexcept;
  void store_sample(float x, bool valid) noexcept;

  /// ceil(d_ns * fs / 1e9) in exact integer arithmetic (fs is kept in mHz).
  [[nodiscard]] std::int64_t ceil_index(std::int64_t d_ns) const noexcept;
  /// ceil(i * 1e9 / fs) ns: the time of sample i relative to t0 (exact integer arithmetic).
  [[nodiscard]] std::int64_t offset_ns(std::int64_t i) const noexcept;

  ExtractionConfig cfg_;
  double fs_hz_;
  std::int64_t t0_ns_;
  SlicerCounters counters_;

  std::int64_t fs_mhz_ = 0;  ///< fs in millihertz (exact)
  std::int64_t hop_ = 0;     ///< effective hop in samples
  std::int64_t min_duration_ns_ = 0;
  std::int64_t guard_ns_ = 0;
  std::int64_t max_gap_ns_ = 0;
  std::int64_t new_run_close_ns_ = 0;

  // Speed side.
  bool have_last_speed_ = false;
  std::int64_t last_speed_t_ns_ = 0;  ///< latest accepted speed timestamp
  Run run_;
  Fifo<RunSample> run_samples_;    ///< the open run's samples while it is only a candidate
  std::uint64_t windows_cut_ = 0;  ///< WindowRef::seq of the next cut window
  Fifo<WindowRef> pending_;        ///< cut windows waiting for (or holding) their samples
  Fifo<RegionInfo> regions_;       ///< ended regions for pop_region()

  // Sample side: history ring indexed by absolute sample index modulo its length.
  std::vector<float> history_;
  std::vector<std::uint8_t> history_valid_;
  std::int64_t samples_total_ = 0;  ///< absolute index of the next sample
};

}  // namespace ptda::dsp
