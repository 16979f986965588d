// Log-time smoothing of a periodic CAN frame for the order domain (issue 16, docs/method.md §9). The
// controller samples the joint angle on its own clock every period_s; the frame's *log* time adds the
// bus arbitration and receive jitter. At the order domain's mesh orders that jitter is a large phase
// error: 29 us rms (the simulator's default, uniform 0..0.1 ms) at an 18.7 Hz shaft is 1.1 rad at order
// 336. FrameClock replaces each log time by frame index x period + a smoothed offset, so only the
// smoothed jitter remains (rms jitter x sqrt(alpha / (2 - alpha)), alpha = 1 / smoothing_frames).
#pragma once

#include <cstdint>

namespace ptda::dsp {

struct FrameClockCounters {
  std::uint64_t frames = 0;   ///< frames smoothed
  std::uint64_t resyncs = 0;  ///< restarts: a log time more than period/4 off the smoothed clock
};

/// Streaming, allocation-free. A log time more than a quarter period off the smoothed clock (a lost
/// frame is fine: the index is rounded; a controller restart or a frame out of order is not) restarts the
/// clock at that frame, which is then passed unchanged. Clock drift: the offset follows it with a lag of
/// smoothing_frames frames, i.e. a constant time shift (a latency), which the order domain ignores.
class FrameClock {
 public:
  /// period_s > 0 ([can.speed_frame] period_s); smoothing_frames >= 1 (1 = no smoothing). Thread: any.
  /// Never allocates or throws.
  FrameClock(double period_s, double smoothing_frames) noexcept;
  /// The smoothed time of the frame logged at t_ns. Thread: the owner's. Never allocates or blocks.
  [[nodiscard]] std::int64_t smooth(std::int64_t t_ns) noexcept;
  [[nodiscard]] const FrameClockCounters& counters() const noexcept { return counters_; }

 private:
  double period_ns_;
  double alpha_;
  bool have_ = false;
  std::int64_t origin_ns_ = 0;  ///< log time that frame index 0 would have had
  std::int64_t k_ = 0;          ///< index of the last frame
  double off_ns_ = 0.0;         ///< smoothed offset of the frames from origin_ns_ + k period
  FrameClockCounters counters_;
};

}  // namespace ptda::dsp
