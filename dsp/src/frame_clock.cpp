// FrameClock: CAN log times regularised to frame index x period + a smoothed offset (frame_clock.hpp).
#include "ptda/dsp/frame_clock.hpp"

#include <cmath>

namespace ptda::dsp {

FrameClock::FrameClock(double period_s, double smoothing_frames) noexcept
    : period_ns_(period_s * 1e9), alpha_(smoothing_frames >= 1.0 ? 1.0 / smoothing_frames : 1.0) {}

std::int64_t FrameClock::smooth(std::int64_t t_ns) noexcept {
  ++counters_.frames;
  if (!(period_ns_ > 0.0)) return t_ns;
  const auto restart = [&] {
    have_ = true;
    origin_ns_ = t_ns;
    k_ = 0;
    off_ns_ = 0.0;
    return t_ns;
  };
  if (!have_) return restart();
  const double rel = static_cast<double>(t_ns - origin_ns_);
  const auto k = static_cast<std::int64_t>(std::llround(rel / period_ns_));
  const double off = rel - static_cast<double>(k) * period_ns_;
  if (k <= k_ || std::fabs(off - off_ns_) > 0.25 * period_ns_) {
    ++counters_.resyncs;
    return restart();
  }
  off_ns_ += alpha_ * (off - off_ns_);
  k_ = k;
  // Keep the offset small (clock drift): move the origin by it, the smoothed clock is unchanged.
  if (std::fabs(off_ns_) > 0.125 * period_ns_) {
    const auto shift = static_cast<std::int64_t>(std::llround(off_ns_));
    origin_ns_ += shift;
    off_ns_ -= static_cast<double>(shift);
  }
  return origin_ns_ + static_cast<std::int64_t>(std::llround(static_cast<double>(k) * period_ns_ + off_ns_));
}

}  // namespace ptda::dsp
