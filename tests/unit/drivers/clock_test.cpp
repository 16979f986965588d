#include "ptda/drivers/clock.hpp"

#include <gtest/gtest.h>
#include <time.h>

namespace ptda::drivers {
namespace {

TEST(MonotonicClock, MatchesClockMonotonicAndNeverGoesBack) {
  MonotonicClock c;
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);
  const std::int64_t ref = static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
  const std::int64_t a = c.now_ns();
  EXPECT_GE(a, ref);
  std::int64_t prev = a;
  for (int i = 0; i < 1000; ++i) {
    const std::int64_t t = c.now_ns();
    ASSERT_GE(t, prev);
    prev = t;
  }
}

TEST(MonotonicClock, SleepUntilThePastReturnsAtOnceAndTheTargetIsReached) {
  MonotonicClock c;
  c.sleep_until_ns(0);
  c.sleep_until_ns(c.now_ns() - 1'000'000'000);
  const std::int64_t target = c.now_ns() + 1'000'000;  // 1 ms: checks the target, not the duration
  c.sleep_until_ns(target);
  EXPECT_GE(c.now_ns(), target);
}

TEST(RealtimeOffset, MapsTheDaemonClockOntoClockRealtime) {
  const auto realtime = [] {
    timespec ts{};
    ::clock_gettime(CLOCK_REALTIME, &ts);
    return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
  };
  // A clock that stands still: the bracket is 0, so the offset is realtime minus its reading exactly.
  ManualClock manual(5'000'000'000);
  const std::int64_t before = realtime();
  const std::int64_t offset = realtime_offset_ns(manual);
  const std::int64_t after = realtime();
  EXPECT_GE(offset, before - 5'000'000'000);
  EXPECT_LE(offset, after - 5'000'000'000);
  // The monotonic clock: realtime = monotonic + offset, within the reads' own spread.
  MonotonicClock mono;
  const std::int64_t r0 = realtime();
  const std::int64_t mapped = mono.now_ns() + realtime_offset_ns(mono);
  const std::int64_t r1 = realtime();
  EXPECT_GE(mapped, r0 - 1'000'000);
  EXPECT_LE(mapped, r1 + 1'000'000);
}

TEST(ManualClock, SleepJumpsForwardOnlyAndIsCounted) {
  ManualClock c(100);
  EXPECT_EQ(c.now_ns(), 100);
  c.sleep_until_ns(250);
  EXPECT_EQ(c.now_ns(), 250);
  c.sleep_until_ns(200);  // already past
  EXPECT_EQ(c.now_ns(), 250);
  c.advance_ns(50);
  EXPECT_EQ(c.now_ns(), 300);
  c.set_ns(10);  // tests may move it back deliberately
  EXPECT_EQ(c.now_ns(), 10);
  EXPECT_EQ(c.sleeps(), 2u);
}

}  // namespace
}  // namespace ptda::drivers
