// Time source of the daemon: CLOCK_MONOTONIC in production, a manual clock in tests and fast replays.
// Every timestamp the drivers hand out (SampleBlock::t_mono_ns, CanFrame::t_ns) is on this clock.
#pragma once

#include <atomic>
#include <cstdint>
#include <optional>

namespace ptda::drivers {

class Clock {
 public:
  virtual ~Clock() = default;
  /// Current time in ns. Thread: any. Never blocks or allocates.
  [[nodiscard]] virtual std::int64_t now_ns() const noexcept = 0;
  /// Waits until now_ns() >= t_ns (returns at once when already there). Thread: any. Blocks (this is
  /// the caller's one wait); never allocates. May return early on a signal: callers re-check now_ns().
  virtual void sleep_until_ns(std::int64_t t_ns) noexcept = 0;

 protected:
  Clock() = default;
  Clock(const Clock&) = default;
  Clock& operator=(const Clock&) = default;
};

/// CLOCK_MONOTONIC (clock_gettime / clock_nanosleep TIMER_ABSTIME): immune to wall-clock steps.
class MonotonicClock final : public Clock {
 public:
  [[nodiscard]] std::int64_t now_ns() const noexcept override;
  void sleep_until_ns(std::int64_t t_ns) noexcept override;
};

/// CLOCK_REALTIME minus `clock`, in ns, for mapping kernel stamps (CLOCK_REALTIME) onto the daemon clock
/// and back: a realtime read bracketed by two reads of `clock`, the tightest of up to three brackets (one
/// within 100 us is taken at once). A thread preempted between two plain reads would be off by the whole
/// preemption (seen under emulation: tens of ms). Thread: any. Never blocks or allocates.
[[nodiscard]] std::int64_t realtime_offset_ns(const Clock& clock) noexcept;

/// A clock that only moves when told. sleep_until_ns() jumps the clock forward to the target instead
/// of waiting, so paced replays run instantly and deterministically in tests.
class ManualClock final : public Clock {
 public:
  explicit ManualClock(std::int64_t start_ns = 0) noexcept : t_ns_(start_ns) {}
  [[nodiscard]] std::int64_t now_ns() const noexcept override {
    return t_ns_.load(std::memory_order_acquire);
  }
  /// Jumps to t_ns when that is later than now (never goes back). Thread: any. Never blocks.
  void sleep_until_ns(std::int64_t t_ns) noexcept override {
    std::int64_t cur = t_ns_.load(std::memory_order_relaxed);
    while (cur < t_ns && !t_ns_.compare_exchange_weak(cur, t_ns, std::memory_order_acq_rel)) {
    }
    sleeps_.fetch_add(1, std::memory_order_relaxed);
  }
  /// Sets the time (may go back: tests of clock misbehaviour). Thread: any. Never blocks.
  void set_ns(std::int64_t t_ns) noexcept { t_ns_.store(t_ns, std::memory_order_release); }
  void advance_ns(std::int64_t dt_ns) noexcept { t_ns_.fetch_add(dt_ns, std::memory_order_acq_rel); }
  /// How many times sleep_until_ns() was called (tests check that pacing happened).
  [[nodiscard]] std::uint64_t sleeps() const noexcept { return sleeps_.load(std::memory_order_relaxed); }

 private:
  std::atomic<std::int64_t> t_ns_;
  std::atomic<std::uint64_t> sleeps_{0};
};

/// How a replay source releases data.
enum class ReplayPace : std::uint8_t {
  kRealTime = 0,          ///< each sample/frame is released when the clock reaches its mapped time
  kAsFastAsPossible = 1,  ///< everything is released at once; timestamps are still the mapped times
};

/// How a replay source maps the log's clock (UNIX ns, CanFrame::t_ns in a candump log, a recording's
/// start_time_s) onto the daemon's clock: t_mono_ns = origin_mono_ns + (t_unix_ns - origin_unix_ns).
/// Give the WAV and the candump replay of one recording the same timeline so they stay aligned.
struct ReplayTimeline {
  std::optional<std::int64_t> origin_unix_ns;  ///< unset: the source's own first sample/frame time
  std::optional<std::int64_t> origin_mono_ns;  ///< unset: Clock::now_ns() at activate()
};

}  // namespace ptda::drivers
