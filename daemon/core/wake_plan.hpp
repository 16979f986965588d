// When the acquisition and CAN threads wake at real-time pace (docs/daemon.md, "Sleeping until a
// window can close"): the processing thread publishes the earliest daemon-clock time at which the next
// window can close (WindowSlicer::next_close_ns() + t0); each thread sleeps until that time plus its
// own offset (the block that holds the window's last sample is complete; then the speed frame that
// follows that block has arrived), and never longer than a maximum sleep that the rings, the device
// buffers, the staleness checks and the watchdog allow. An unchanged CAN verdict frame rides on a
// processing pass that happens anyway once half its period has passed (resend_due), so its own timed
// wake-up at the full period is seldom needed.
#pragma once

#include <cstdint>
#include <limits>

namespace ptda::daemon {

/// No window can close that the pipeline knows of (no t0 yet, refused, training, replay ended).
inline constexpr std::int64_t kNoDue = std::numeric_limits<std::int64_t>::max();

/// The next wake-up of a stage: `due_ns + offset_ns` when that is in the future; when it is not (the
/// stage has just served it and the processing thread has not yet published the next), the first
/// `due_ns + offset_ns + k * spacing_ns` after now (no window closes sooner than spacing_ns after the
/// previous one: WindowSlicer hop and new_run_close_ns()). Never more than max_sleep_ns from now: a
/// time further away is brought forward by whole max_sleep_ns steps, so the stages that see one due
/// time stay that due time's offsets apart. With kNoDue, the first point of the grid
/// `origin_ns + offset_ns + k * max_sleep_ns` after now: the stages share it, so the CAN thread still
/// drains after the acquisition thread by the difference of their offsets. `late`: the processing
/// thread found the due window still open after both stages had served it (a speed frame or a block
/// later than the offsets allow); the stages then retry every `retry_ns` (one speed frame period)
/// instead of every spacing_ns. spacing_ns, retry_ns and max_sleep_ns must be > 0. Thread: any. Pure.
[[nodiscard]] constexpr std::int64_t plan_wake(std::int64_t now_ns, std::int64_t due_ns,
                                               std::int64_t offset_ns, std::int64_t spacing_ns,
                                               std::int64_t max_sleep_ns, std::int64_t origin_ns,
                                               bool late = false, std::int64_t retry_ns = 1) noexcept {
  std::int64_t t = (due_ns == kNoDue ? origin_ns : due_ns) + offset_ns;
  const std::int64_t step = due_ns == kNoDue ? max_sleep_ns : late ? retry_ns : spacing_ns;
  if (t <= now_ns) t += ((now_ns - t) / step + 1) * step;
  const std::int64_t cap = now_ns + max_sleep_ns;
  if (t > cap) t -= ((t - cap + max_sleep_ns - 1) / max_sleep_ns) * max_sleep_ns;
  return t;
}

/// Whether an unchanged verdict frame last sent at `last_sent_ns` goes out again on a processing pass
/// at `now_ns` (`[alarm.can] period_s` = `period_ns`, > 0): once at least half the period (rounded up)
/// has passed. The processing thread still wakes on its own at `last_sent_ns + period_ns`, where this
/// holds too, so a frame comes at most every period/2 and at least every period (docs/daemon.md).
/// Thread: any. Pure.
[[nodiscard]] constexpr bool resend_due(std::int64_t now_ns, std::int64_t last_sent_ns,
                                        std::int64_t period_ns) noexcept {
  return now_ns - last_sent_ns >= period_ns - period_ns / 2;
}

}  // namespace ptda::daemon
