// The alarm seam: tell the outside world the monitor's verdict. Backends: a GPIO line (gpiod_output),
// a CAN frame (can_alarm_output), a recording fake (recording_alarm_output).
//
// Fail-safe meaning. Only kNormal says "the gearbox was judged healthy and the monitor is working".
// Every other level, and an output that is not driven at all (daemon dead, line released, power lost,
// no alarm frame within its period), must be treated by the receiver as "not healthy":
//   kWarning - a feature left its band but the k-of-n debouncer has not confirmed it (informational);
//   kAlarm   - the debouncer confirmed an abnormal gearbox;
//   kFault   - the monitor cannot judge: sensor, CAN speed or baseline missing/invalid, internal overrun,
//              no window matching a trained class (coverage), or nothing judged yet (no cause bit).
// A GPIO output is therefore energised (logically active) only for levels below its trip level and is
// de-energised on trip, on deactivate() and by the hardware when nobody drives it.
#pragma once

#include <cstdint>
#include <cstring>
#include <string_view>

#include "ptda/drivers/counter.hpp"

namespace ptda::drivers {

enum class AlarmLevel : std::uint8_t { kNormal = 0, kWarning = 1, kAlarm = 2, kFault = 3 };

[[nodiscard]] constexpr std::string_view alarm_level_name(AlarmLevel l) noexcept {
  switch (l) {
    case AlarmLevel::kNormal:
      return "normal";
    case AlarmLevel::kWarning:
      return "warning";
    case AlarmLevel::kAlarm:
      return "alarm";
    case AlarmLevel::kFault:
      return "fault";
  }
  return "?";
}

/// Why the level is what it is (bits of AlarmReport::causes).
enum AlarmCause : std::uint8_t {
  kCauseRms = 1U << 0,       ///< rms_res left its band
  kCauseEntropy = 1U << 1,   ///< entropy_res left its band
  kCauseSensor = 1U << 2,    ///< vibration input missing, gaps or overruns
  kCauseSpeed = 1U << 3,     ///< speed frames stale or CAN bus-off
  kCauseBaseline = 1U << 4,  ///< no baseline for the current segment class
  kCauseInternal = 1U << 5,  ///< ring overrun, stage stalled, watchdog
  kCauseCoverage = 1U << 6,  ///< running, but no window judged for [daemon] coverage_timeout_s of motion
  kCauseBand = 1U << 7,      ///< the band CUSUM is above its h (energy grew in one band of the residual)
};

inline constexpr std::uint8_t kNoSegmentClass = 0xFF;

/// The verdict to publish. Plain struct: built by the decision stage, copied to every output.
struct AlarmReport {
  AlarmLevel level = AlarmLevel::kFault;
  std::uint8_t causes = 0;                       ///< AlarmCause bits
  std::uint8_t segment_class = kNoSegmentClass;  ///< class of the last judged window
  std::uint8_t abnormal_windows = 0;             ///< k-of-n: abnormal windows among the last n
  float rms = 0.0F;                              ///< rms_res of the last judged window (recording unit)
  float entropy = 0.0F;                          ///< entropy_res of the last judged window, [0, 1]
};

/// Whether two verdicts would give the same outputs (every field; the values bit for bit, so NaN equals
/// NaN). Thread: any. Pure.
[[nodiscard]] inline bool same_report(const AlarmReport& a, const AlarmReport& b) noexcept {
  return a.level == b.level && a.causes == b.causes && a.segment_class == b.segment_class &&
         a.abnormal_windows == b.abnormal_windows && std::memcmp(&a.rms, &b.rms, sizeof a.rms) == 0 &&
         std::memcmp(&a.entropy, &b.entropy, sizeof a.entropy) == 0;
}

enum class OutputStatus : std::uint8_t { kOk = 0, kError, kNotActive };

struct AlarmOutputCounters {
  std::uint64_t sets = 0;
  std::uint64_t errors = 0;
  std::uint64_t level_changes = 0;
};

class AlarmOutput {
 public:
  virtual ~AlarmOutput() = default;
  AlarmOutput(const AlarmOutput&) = delete;
  AlarmOutput& operator=(const AlarmOutput&) = delete;

  /// Opens and validates (chip and line exist, CAN channel configured...). Throws ptda::Error.
  /// Thread: the main thread at start-up. Blocks and allocates.
  virtual void configure() = 0;
  /// Takes the output and drives it to the fail-safe (tripped) state: kFault until the first set().
  /// Throws ptda::Error. Thread: the main thread. Never allocates after configure().
  virtual void activate() = 0;
  /// Drives the fail-safe state, then releases the output. Safe in any state and twice. Never throws.
  /// Thread: the main thread after set() stopped.
  virtual void deactivate() noexcept = 0;

  /// Publishes a verdict. Thread: the one alarm thread. Never allocates, throws or logs; may make one
  /// non-blocking system call.
  OutputStatus set(const AlarmReport& report) noexcept {
    const OutputStatus s = write(report);
    sets_.add();
    if (s != OutputStatus::kOk) errors_.add();
    if (report.level != last_level_) level_changes_.add();
    last_level_ = report.level;
    return s;
  }
  /// set() with only a level (causes and values zero).
  OutputStatus set(AlarmLevel level) noexcept {
    AlarmReport r;
    r.level = level;
    return set(r);
  }

  /// Last level passed to set() (kFault before any). Thread: the alarm thread.
  [[nodiscard]] AlarmLevel last_level() const noexcept { return last_level_; }
  /// Thread: any. Never blocks or allocates.
  [[nodiscard]] AlarmOutputCounters counters() const noexcept {
    return {sets_.get(), errors_.get(), level_changes_.get()};
  }

 protected:
  AlarmOutput() = default;

 private:
  /// The backend's part of set(). Same thread and allocation rules as set().
  virtual OutputStatus write(const AlarmReport& report) noexcept = 0;

  AlarmLevel last_level_ = AlarmLevel::kFault;
  Counter sets_, errors_, level_changes_;
};

}  // namespace ptda::drivers
