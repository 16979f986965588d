// FrameClock (issue 16): CAN log times of a periodic frame with one-sided jitter are regularised. With a
// known clock (period 4 ms, 50 ppm drift, uniform 0..100 us jitter, a lost frame) the smoothed times'
// deviation from the true send times + a constant must shrink by the factor sqrt(alpha / (2 - alpha))
// of an exponential average; a jump restarts the clock.
#include "ptda/dsp/frame_clock.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

namespace ptda::dsp {
namespace {

TEST(FrameClock, SmoothsOneSidedJitter) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> jitter(0.0, 100e3);  // ns
  const double period_ns = 4e6 * (1.0 + 50e-6);
  FrameClock clock(0.004, 32.0);
  std::vector<double> raw_err, smooth_err;
  const std::int64_t t0 = 1'700'000'000'000'000'000;
  for (int k = 0; k < 5000; ++k) {
    if (k == 2000) continue;  // a lost frame
    const double truth = static_cast<double>(k) * period_ns;
    const auto logged = t0 + static_cast<std::int64_t>(std::llround(truth + 500e3 + jitter(rng)));
    const std::int64_t s = clock.smooth(logged);
    if (k >= 500) {  // after the start-up transient (~5 / alpha frames)
      raw_err.push_back(static_cast<double>(logged - t0) - truth);
      smooth_err.push_back(static_cast<double>(s - t0) - truth);
    }
  }
  const auto sd = [](const std::vector<double>& v) {
    double m = 0.0, q = 0.0;
    for (const double x : v) m += x;
    m /= static_cast<double>(v.size());
    for (const double x : v) q += (x - m) * (x - m);
    return std::sqrt(q / static_cast<double>(v.size() - 1));
  };
  // Uniform 0..100 us: sd 28.9 us. Exponential average over 32 frames: x sqrt(1/63) = 3.6 us, plus the
  // 1-ns rounding; bound 5 us (the drift's lag is a constant, not a spread).
  EXPECT_NEAR(sd(raw_err), 28.9e3, 1.5e3);
  EXPECT_LT(sd(smooth_err), 5e3);
  EXPECT_EQ(clock.counters().resyncs, 0U);
  EXPECT_EQ(clock.counters().frames, 4999U);
}

TEST(FrameClock, JumpRestartsAndOneFrameSmoothingPassesTimesThrough) {
  FrameClock clock(0.004, 32.0);
  std::int64_t t = 1'000'000'000;
  for (int k = 0; k < 10; ++k, t += 4'000'000) (void)clock.smooth(t);
  // 1.5 ms off the 4 ms grid: more than a quarter period -> restart, passed unchanged.
  t += 1'500'000;
  EXPECT_EQ(clock.smooth(t), t);
  EXPECT_EQ(clock.counters().resyncs, 1U);
  // Out of order: restart too.
  EXPECT_EQ(clock.smooth(t - 4'000'000), t - 4'000'000);
  EXPECT_EQ(clock.counters().resyncs, 2U);

  FrameClock none(0.004, 1.0);
  for (std::int64_t u : {0LL, 4'010'000LL, 8'050'000LL, 11'990'000LL}) EXPECT_EQ(none.smooth(u), u);
}

}  // namespace
}  // namespace ptda::dsp
