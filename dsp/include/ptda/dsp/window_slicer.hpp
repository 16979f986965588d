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
  std::uint32_t window_len = 0;          ///< N samples per window (a RealFft length)
  std::uint32_t hop = 0;                 ///< samples between window starts in one region; 0 = window_len
  double speed_tol_rel = 0.02;           ///< constant while | v - mean | <= max(rel * |mean|, abs)
  double speed_tol_abs_rad_s = 0.005;
  double min_speed_rad_s = 0.05;         ///< |v| below this is standstill: never a region
  double max_speed_rad_s = 1e9;          ///< |v| above this is out of the configured range: breaks a region
  double min_duration_s = 0.1;           ///< a region must have lasted this long before windows are cut
  double guard_s = 0.0;                  ///< skipped after the region start (settling after the blend)
  double max_speed_gap_s = 0.05;         ///< speed samples further apart break the region (CAN silence)
  std::uint32_t max_windows_per_region = 0;  ///< 0 = unlimited
  double clip_abs = 0.0;                 ///< |x| >= this counts as clipped (0 = no clip check)
};

/// A completed or ongoing constant-speed region.
struct RegionInfo {
  std::uint64_t seq = 0;
  std::int64_t t_begin_ns = 0;
  std::int64_t t_end_ns = 0;       ///< time of the last speed sample in the region
  double mean_speed_rad_s = 0.0;   ///< signed
  std::int8_t direction = 1;
};

/// Where a cut window lies.
struct WindowRef {
  std::uint64_t seq = 0;            ///< windows cut so far (0-based)
  std::uint64_t region_seq = 0;
  std::uint32_t index_in_region = 0;
  std::int64_t first_sample = 0;    ///< absolute index of x[0] in the sample stream
  std::int64_t t_start_ns = 0;      ///< time of x[0]
  std::int64_t t_end_ns = 0;        ///< time of x[N-1] + 1/fs
  double speed_rad_s = 0.0;         ///< region mean speed (signed) when the window was cut
};

struct SlicerCounters {
  std::uint64_t speed_samples = 0;
  std::uint64_t speed_out_of_order = 0;  ///< dropped: timestamp not after the previous one
  std::uint64_t speed_gaps = 0;          ///< regions broken by CAN silence
  std::uint64_t speed_out_of_range = 0;  ///< samples above max_speed_rad_s
  std::uint64_t regions = 0;             ///< regions that reached min_duration
  std::uint64_t windows = 0;             ///< windows handed out by pop()
  std::uint64_t windows_invalid = 0;     ///< discarded: NaN/Inf, clipped or missing samples inside
  std::uint64_t windows_lost = 0;        ///< discarded: samples already overwritten in the history
  std::uint64_t samples = 0;
  std::uint64_t samples_nonfinite = 0;
  std::uint64_t samples_clipped = 0;
  std::uint64_t samples_missing = 0;     ///< declared by mark_gap()
};

class WindowSlicer {
 public:
  /// fs_hz: nominal sample rate; t0_ns: time of sample 0. history_len: samples kept for windows whose
  /// speed confirmation arrives late (0 = 4 windows + 1 s). Thread: any (setup). Allocates.
  /// Throws ptda::Error on an invalid configuration (says which key).
  WindowSlicer(const ExtractionConfig& cfg, double fs_hz, std::int64_t t0_ns, std::size_t history_len = 0);

  /// Speed samples in time order. Thread: the owner's. Never allocates.
  void push_speed(const SpeedSample& s) noexcept;
  /// The next consecutive vibration samples. Non-finite or clipped samples invalidate the windows
  /// that contain them. Thread: the owner's. Never allocates.
  void push_samples(std::span<const float> block) noexcept;
  /// `count` samples were lost (ADC overrun): they are filled as invalid. Never allocates.
  void mark_gap(std::uint64_t count) noexcept;
  /// End of input: the open region ends at the last speed sample. Never allocates.
  void finish() noexcept;

  /// The next valid window, oldest first: fills ref and out (out.size() == window_len).
  /// Returns false when none is complete yet. Thread: the owner's. Never allocates.
  bool pop(WindowRef& ref, std::span<float> out) noexcept;
  /// The next region that ended (and reached min_duration), oldest first. Never allocates.
  bool pop_region(RegionInfo& region) noexcept;

  [[nodiscard]] const SlicerCounters& counters() const noexcept { return counters_; }
  [[nodiscard]] double fs_hz() const noexcept { return fs_hz_; }
  [[nodiscard]] const ExtractionConfig& config() const noexcept { return cfg_; }

 private:
  // Implementation state is the dsp-windows owner's to define.
  ExtractionConfig cfg_;
  double fs_hz_;
  std::int64_t t0_ns_;
  SlicerCounters counters_;
  struct State;
  std::vector<unsigned char> state_storage_;  // placeholder; replace freely
};

}  // namespace ptda::dsp
