// From scored windows to the published verdict: warning level, minimum hold, latching, operator
// clear, and the "monitoring not possible" fault state (docs/drivers.md, alarm outputs).
//
// Levels (drivers::AlarmLevel), highest priority first:
//   kAlarm   - the k-of-n condition (dsp::WindowResult::alarm) held at some window and the alarm is
//              still active: it stays for at least min_hold_s after it was raised, and then
//                - unlatched: until a scored window arrives with the condition off;
//                - latched: until a clear request is accepted (request_clear / post_clear_request).
//              An accepted clear needs: the hold time over, and the condition off at the last scored
//              window. Otherwise the clear is refused (and counted) and the alarm stays.
//   kFault   - no alarm active and the monitor cannot judge: fault causes set with set_faults()
//              (sensor, speed, baseline, internal, coverage), or no window has been scored yet ("not
//              judged yet": kFault with no cause; set_faults(0) alone never makes the level kNormal). A fault
//              never raises, holds or latches kAlarm; a latched alarm stays kAlarm through a fault (the
//              receiver keeps the confirmed verdict) and the report's causes then carry the fault bits as
//              well. The end of a replay (set_input_ended()) is kFault with no cause of its own: the
//              verdict stops, nothing failed.
//   kWarning - warning enabled and at least warning_k of the debouncer's last n windows were abnormal
//              (warning_k = 1: any abnormal window), kept for at least warning_hold_s.
//   kNormal  - otherwise.
// Only scored windows (WindowStatus::kScored) are judged; kNoClass windows are counted and ignored.
//
// Threads: every member function except post_clear_request() and counters() belongs to one owner
// thread (the daemon's decision/alarm thread). All are noexcept and allocation-free after
// construction; time is injected (t_mono_ns on the daemon's monotonic clock), so tests are
// deterministic.
#pragma once

#include <atomic>
#include <cstdint>

#include "ptda/drivers/alarm_output.hpp"
#include "ptda/drivers/counter.hpp"
#include "ptda/dsp/monitor_engine.hpp"
#include "rt/spsc_ring.hpp"

namespace ptda::daemon {

struct AlarmManagerConfig {
  bool warning_enabled = true;  ///< publish kWarning before k-of-n confirms
  std::uint32_t warning_k = 1;  ///< abnormal windows among the debouncer's last n that warn (>= 1)
  double warning_hold_s = 0.0;  ///< a warning stays at least this long
  double min_hold_s = 10.0;     ///< an alarm stays at least this long after it was raised
  bool latch = true;            ///< an alarm needs an accepted clear request to end
};

/// Mask of the AlarmCause bits that mean "monitoring not possible".
inline constexpr std::uint8_t kFaultCauseMask = drivers::kCauseSensor | drivers::kCauseSpeed |
                                                drivers::kCauseBaseline | drivers::kCauseInternal |
                                                drivers::kCauseCoverage;
/// Mask of the AlarmCause bits a window's verdict can set.
inline constexpr std::uint8_t kFeatureCauseMask =
    drivers::kCauseRms | drivers::kCauseEntropy | drivers::kCauseBand;

enum class ClearSource : std::uint8_t { kCan = 0, kLocal = 1 };

enum class ClearResult : std::uint8_t {
  kCleared = 0,           ///< the latched alarm ended
  kNothingToClear = 1,    ///< no alarm active (or not latched and already ending by itself)
  kRefusedCondition = 2,  ///< the k-of-n condition still holds at the last scored window
  kRefusedHold = 3,       ///< min_hold_s has not passed since the alarm was raised
};

/// What tripped: copied from the scored window that raised the alarm (or the warning).
struct TripInfo {
  std::int64_t t_ns = 0;  ///< the window's t_end_ns
  std::int32_t class_id = -1;
  std::uint8_t causes = 0;  ///< kCauseRms / kCauseEntropy of that window
  std::uint32_t abnormal_in_last_n = 0;
  double rms_res = 0.0;
  double entropy_res = 0.0;
  dsp::FeatureThresholds thresholds;
  dsp::AlarmDetector detector = dsp::AlarmDetector::kNone;  ///< which detector held the alarm
  double seq_statistic = 0.0;  ///< largest class CUSUM at that window (the sequential evidence)
  // The band CUSUM's evidence at that window (band_on: [decision] band_cusum is on).
  bool band_on = false;
  double band_statistic = 0.0;   ///< largest band CUSUM over classes and bands
  std::int32_t band_index = -1;  ///< its band (-1: none)
  double band_lo_hz = 0.0;       ///< its frequency range
  double band_hi_hz = 0.0;
  // The mesh CUSUM's evidence at that window (mesh_on: [decision] mesh_cusum is on).
  bool mesh_on = false;
  bool mesh_alarm = false;
  double mesh_statistic = 0.0;     ///< largest mesh CUSUM over classes and features
  std::int32_t mesh_feature = -1;  ///< its feature (0 am, 1 pm; -1: none)
  std::int32_t mesh_class = -1;    ///< its class (the decision's class index)
};

/// The manager's state, trivially copyable (the owner may hand copies to the status writer).
struct AlarmState {
  drivers::AlarmLevel level = drivers::AlarmLevel::kFault;
  std::int64_t since_ns = 0;         ///< when `level` was entered
  bool alarm_active = false;         ///< an alarm is raised (held, latched or condition on)
  bool latched = false;              ///< alarm active and waiting for an accepted clear
  bool condition = false;            ///< k-of-n state at the last scored window
  std::int64_t alarm_raised_ns = 0;  ///< when the active alarm was raised (valid if alarm_active)
  std::uint8_t fault_causes = 0;     ///< set_faults() mask
  std::uint8_t feature_causes = 0;   ///< rms/entropy bits of the abnormal windows since the debouncer
                                     ///< last held none (kept while a warning/alarm is active)
  TripInfo trip;                     ///< the window that raised the alarm, else the one that warned
  bool have_window = false;          ///< a scored window was seen
  std::int64_t last_window_t_ns = 0;
  std::int32_t last_class_id = -1;
  double last_rms_res = 0.0;
  double last_entropy_res = 0.0;
  std::uint32_t last_abnormal_in_last_n = 0;
  bool last_abnormal = false;
  std::int64_t last_clear_ns = 0;  ///< time of the last applied clear request (0 = none)
  ClearSource last_clear_source = ClearSource::kLocal;
};

/// Thread-safe event counters (writer: the owner thread; readers: any).
struct AlarmCounters {
  std::uint64_t windows_scored = 0;
  std::uint64_t windows_abnormal = 0;
  std::uint64_t windows_unclassified = 0;
  std::uint64_t alarms_raised = 0;
  std::uint64_t warnings_raised = 0;
  std::uint64_t faults_entered = 0;  ///< transitions of the fault mask from 0 to non-zero
  std::uint64_t clears_accepted = 0;
  std::uint64_t clears_refused = 0;
  std::uint64_t clears_nothing = 0;
  std::uint64_t level_changes = 0;
  std::uint64_t level_changes_dropped = 0;  ///< changes the LevelChangeRing could not hold
};

/// One change of the alarm level, recorded where it happens (AlarmManager::set_level) so that two
/// changes between two looks of the supervisor stay two events. Trivially copyable (SpscRing).
struct LevelChange {
  drivers::AlarmLevel from = drivers::AlarmLevel::kFault;
  drivers::AlarmLevel to = drivers::AlarmLevel::kFault;
  std::uint8_t causes = 0;   ///< report().causes right after the change
  std::int64_t t_ns = 0;     ///< when (the manager's time base, as AlarmState::since_ns)
  std::uint64_t number = 0;  ///< AlarmCounters::level_changes counting this one (a gap = ring overflow)
  std::int64_t recorded_mono_ns = 0;  ///< CLOCK_MONOTONIC when recorded (the durability latency's start)
  bool have_window = false;           ///< `window` is valid
  TripInfo window;  ///< warning/alarm: the window that raised it; normal: the last scored window
};
/// Processing thread (producer) -> supervisor (consumer). 64 changes: far more than the debouncer lets
/// happen within one status period.
using LevelChangeRing = SpscRing<LevelChange, 64>;

class AlarmManager {
 public:
  /// Starts in kFault with no causes ("not judged yet", as drivers' activate()) until the first scored
  /// window. Throws ptda::Error ("alarm: ...", naming the key) when
  /// warning_k is 0, or a hold time is negative or not finite. Thread: any (setup). Never allocates
  /// except for the exception.
  AlarmManager(const AlarmManagerConfig& cfg, std::int64_t t_start_ns);

  /// One processed window from dsp::MonitorEngine::poll(). Scored windows update the condition, the
  /// warning and the alarm; kNoClass windows are only counted. Returns the current level.
  /// Thread: the owner. Never allocates, blocks or throws.
  drivers::AlarmLevel on_window(const dsp::WindowResult& w, std::int64_t t_mono_ns) noexcept;

  /// Replaces the fault mask (AlarmCause bits within kFaultCauseMask; other bits are ignored). 0 means
  /// monitoring is possible. Thread: the owner. Never allocates, blocks or throws.
  drivers::AlarmLevel set_faults(std::uint8_t fault_causes, std::int64_t t_mono_ns) noexcept;

  /// The input ended for good (a replay finished): from now on the level is kFault (no verdict) unless
  /// an alarm is active; no cause bit is added (an end is not a sensor fault). Thread: the owner. Never
  /// allocates, blocks or throws.
  drivers::AlarmLevel set_input_ended(std::int64_t t_mono_ns) noexcept;

  /// Time passes: ends holds that expired, applies posted clear requests. Call at least every few
  /// hundred ms (and before report()). Thread: the owner. Never allocates, blocks or throws.
  drivers::AlarmLevel tick(std::int64_t t_mono_ns) noexcept;

  /// An operator clear of a latched alarm (see the header comment for the rules). Warnings are never
  /// latched and need no clear. Thread: the owner. Never allocates, blocks or throws.
  ClearResult request_clear(ClearSource source, std::int64_t t_mono_ns) noexcept;

  /// Queues a clear request from another thread (the CAN receive thread, the supervisor's local
  /// command); the owner applies it at its next tick()/on_window()/set_faults() with that call's time.
  /// The last applied result is last_clear_result(). Thread: any. Lock-free, never allocates.
  void post_clear_request(ClearSource source) noexcept;

  /// The verdict for drivers::AlarmOutput::set(): level; causes = feature_causes while a warning or
  /// alarm is active (kept through a fault), | the fault bits; class, rms, entropy and abnormal count of the
  /// last scored window (kNoSegmentClass / 0 before one). Thread: the owner. Never allocates.
  [[nodiscard]] drivers::AlarmReport report() const noexcept;

  [[nodiscard]] drivers::AlarmLevel level() const noexcept { return state_.level; }
  /// Every later level change is also pushed into `ring` (nullptr: none); a full ring counts
  /// level_changes_dropped. Thread: the owner, before it runs. Never allocates.
  void set_change_ring(LevelChangeRing* ring) noexcept { change_ring_ = ring; }
  /// AlarmCounters::level_changes, cheaper. Thread: the owner. Never allocates.
  [[nodiscard]] std::uint64_t level_change_count() const noexcept { return level_changes_.get(); }
  /// Thread: the owner (copy it to publish elsewhere). Never allocates.
  [[nodiscard]] const AlarmState& state() const noexcept { return state_; }
  [[nodiscard]] const AlarmManagerConfig& config() const noexcept { return cfg_; }
  /// Result of the last applied clear request (kNothingToClear before any). Thread: the owner.
  [[nodiscard]] ClearResult last_clear_result() const noexcept { return last_clear_; }
  /// Thread: any. Never allocates or blocks.
  [[nodiscard]] AlarmCounters counters() const noexcept;

 private:
  void apply_posted_clears(std::int64_t t_ns) noexcept;
  void evaluate(std::int64_t t_ns) noexcept;
  void set_level(drivers::AlarmLevel level, std::int64_t t_ns) noexcept;
  ClearResult clear_now(std::int64_t t_ns) noexcept;

  AlarmManagerConfig cfg_;
  std::int64_t min_hold_ns_ = 0;
  std::int64_t warning_hold_ns_ = 0;
  AlarmState state_;
  bool warning_condition_ = false;
  bool warning_active_ = false;
  std::int64_t warning_raised_ns_ = 0;
  bool judged_ = false;  ///< a scored window was seen: kNormal/kWarning are possible from here on
  bool ended_ = false;   ///< set_input_ended(): no further verdict
  ClearResult last_clear_ = ClearResult::kNothingToClear;
  dsp::FeatureThresholds last_thresholds_;  ///< of the last scored window (a change to normal reports it)
  LevelChangeRing* change_ring_ = nullptr;
  std::atomic<std::uint32_t> posted_clears_{0};
  std::atomic<std::uint8_t> posted_source_{0};
  drivers::Counter windows_scored_, windows_abnormal_, windows_unclassified_, alarms_raised_,
      warnings_raised_, faults_entered_, clears_accepted_, clears_refused_, clears_nothing_, level_changes_,
      level_changes_dropped_;
};

}  // namespace ptda::daemon
