#include "ptda/drivers/clock.hpp"

#include <time.h>

#include <cerrno>

namespace ptda::drivers {

std::int64_t MonotonicClock::now_ns() const noexcept {
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

void MonotonicClock::sleep_until_ns(std::int64_t t_ns) noexcept {
  if (t_ns <= 0) return;
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(t_ns / 1'000'000'000);
  ts.tv_nsec = static_cast<long>(t_ns % 1'000'000'000);
  // EINTR: return early (the contract lets callers re-check); any other error means "already past".
  (void)::clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr);
}

}  // namespace ptda::drivers
