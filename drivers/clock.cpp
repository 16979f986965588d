#include "ptda/drivers/clock.hpp"

#include <time.h>

#include <cerrno>

namespace ptda::drivers {

std::int64_t MonotonicClock::now_ns() const noexcept {
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

std::int64_t realtime_offset_ns(const Clock& clock) noexcept {
  constexpr std::int64_t kGoodBracketNs = 100'000;
  std::int64_t best_offset = 0;
  std::int64_t best_bracket = -1;
  for (int attempt = 0; attempt < 3; ++attempt) {
    const std::int64_t before = clock.now_ns();
    timespec ts{};
    ::clock_gettime(CLOCK_REALTIME, &ts);
    const std::int64_t after = clock.now_ns();
    const std::int64_t real = static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
    const std::int64_t bracket = after - before;
    if (best_bracket < 0 || bracket < best_bracket) {
      best_bracket = bracket;
      best_offset = real - (before + bracket / 2);
    }
    if (bracket <= kGoodBracketNs) break;
  }
  return best_offset;
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
