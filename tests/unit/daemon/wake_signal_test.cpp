#include "rt/wake_signal.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <thread>

#include "rt/spsc_ring.hpp"

namespace ptda::daemon {
namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

// A long timeout turns a lost wake-up into a stall the test can see without timing anything tight:
// a correct doorbell returns in microseconds, a broken one only after kLongNs.
constexpr std::int64_t kLongNs = 20'000'000'000;

TEST(WakeSignal, StaleTicketReturnsAtOnce) {
  WakeSignal s;
  const std::uint32_t t = s.ticket();
  s.ring();  // work published after the ticket was taken
  const auto t0 = Clock::now();
  s.wait(t, kLongNs);
  EXPECT_LT(seconds_since(t0), 5.0);
  EXPECT_EQ(s.ticket(), t + 1);
}

TEST(WakeSignal, TimesOutWhenNobodyRings) {
  WakeSignal s;
  const auto t0 = Clock::now();
  s.wait(s.ticket(), 30'000'000);
  EXPECT_GE(seconds_since(t0), 0.029);  // a lower bound only: the machine may be slow, never early
}

TEST(WakeSignal, RingFromAnotherThreadWakesTheSleeper) {
  WakeSignal s;
  std::atomic<bool> sleeping{false};
  const std::uint32_t t = s.ticket();
  std::thread producer([&] {
    while (!sleeping.load()) std::this_thread::yield();
    std::this_thread::sleep_for(std::chrono::milliseconds(20));  // most likely inside the futex by now
    s.ring();
  });
  const auto t0 = Clock::now();
  sleeping.store(true);
  s.wait(t, kLongNs);
  producer.join();
  EXPECT_LT(seconds_since(t0), 5.0);
}

// The pipeline's pattern: one producer pushes into an SPSC ring and rings; the consumer takes a ticket,
// drains the ring and sleeps only when it found nothing. Every item must arrive with no wait stalled.
TEST(WakeSignal, NoLostWakeUpsWithARing) {
  constexpr std::uint32_t kItems = 100'000;
  SpscRing<std::uint32_t, 64> ring;
  WakeSignal s;
  std::thread producer([&] {
    for (std::uint32_t i = 0; i < kItems; ++i) {
      while (!ring.try_push(i)) std::this_thread::yield();
      s.ring();
    }
  });
  std::uint32_t expected = 0;
  double longest_wait_s = 0.0;
  while (expected < kItems) {
    const std::uint32_t t = s.ticket();
    std::uint32_t v = 0;
    bool got = false;
    while (ring.try_pop(v)) {
      ASSERT_EQ(v, expected);
      ++expected;
      got = true;
    }
    if (!got) {
      const auto w0 = Clock::now();
      s.wait(t, kLongNs);
      const double w = seconds_since(w0);
      if (w > longest_wait_s) longest_wait_s = w;
    }
  }
  producer.join();
  EXPECT_EQ(expected, kItems);
  EXPECT_LT(longest_wait_s, 5.0);
}

}  // namespace
}  // namespace ptda::daemon
