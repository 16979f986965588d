#include "alarm/alarm_manager.hpp"

#include <time.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "ptda/common/error.hpp"

namespace ptda::daemon {
namespace {

using drivers::AlarmLevel;

std::int64_t seconds_to_ns(double s) noexcept {
  return static_cast<std::int64_t>(std::llround(s * 1e9));
}

void check_hold(double v, const char* key) {
  // 1e6 s (11.6 days) keeps the ns value far from int64 overflow.
  if (!(std::isfinite(v) && v >= 0.0 && v <= 1e6)) {
    throw Error(std::string("alarm.") + key + ": must be a finite number of seconds in [0, 1e6], got " +
                std::to_string(v));
  }
}

std::uint8_t verdict_causes(const dsp::WindowResult& w) noexcept {
  std::uint8_t c = 0;
  if (w.verdict.rms_out) c |= drivers::kCauseRms;
  if (w.verdict.entropy_out) c |= drivers::kCauseEntropy;
  // A band alarm can come with both features in their bands: without this bit it would read "alarm,
  // no cause" on the CAN frame and in status.json.
  if (w.band_alarm) c |= drivers::kCauseBand;
  return c;
}

}  // namespace

AlarmManager::AlarmManager(const AlarmManagerConfig& cfg, std::int64_t t_start_ns) : cfg_(cfg) {
  if (cfg.warning_k == 0) throw Error("alarm.warning_k: must be >= 1 (1 = warn on any abnormal window)");
  check_hold(cfg.min_hold_s, "min_hold_s");
  check_hold(cfg.warning_hold_s, "warning_hold_s");
  min_hold_ns_ = seconds_to_ns(cfg.min_hold_s);
  warning_hold_ns_ = seconds_to_ns(cfg.warning_hold_s);
  state_.level = AlarmLevel::kFault;
  state_.since_ns = t_start_ns;
}

AlarmLevel AlarmManager::on_window(const dsp::WindowResult& w, std::int64_t t_mono_ns) noexcept {
  if (w.status != dsp::WindowStatus::kScored) {
    windows_unclassified_.add();
    apply_posted_clears(t_mono_ns);
    evaluate(t_mono_ns);
    return state_.level;
  }
  const bool abnormal = w.verdict.abnormal();
  const std::uint8_t causes = verdict_causes(w);
  windows_scored_.add();
  if (abnormal) windows_abnormal_.add();

  judged_ = true;
  state_.have_window = true;
  state_.last_window_t_ns = w.ref.t_end_ns;
  state_.last_class_id = w.class_id;
  state_.last_rms_res = w.features.rms_res;
  state_.last_entropy_res = w.features.entropy_res;
  state_.last_abnormal_in_last_n = w.abnormal_in_last_n;
  state_.last_abnormal = abnormal;
  last_thresholds_ = w.thresholds;
  state_.condition = w.alarm;
  // The sequential detector's warning level (docs/method.md, "Decision") warns as well.
  warning_condition_ = cfg_.warning_enabled && (w.abnormal_in_last_n >= cfg_.warning_k || w.seq_warn);
  state_.feature_causes |= causes;

  TripInfo info;
  info.t_ns = w.ref.t_end_ns;
  info.class_id = w.class_id;
  info.causes = causes;
  info.abnormal_in_last_n = w.abnormal_in_last_n;
  info.rms_res = w.features.rms_res;
  info.entropy_res = w.features.entropy_res;
  info.thresholds = w.thresholds;
  info.detector = w.detector;
  info.seq_statistic = w.seq_max_statistic;
  info.band_on = w.band_on;
  info.band_statistic = w.band_max_statistic;
  info.band_index = w.band_max_index;
  info.band_lo_hz = w.band_lo_hz;
  info.band_hi_hz = w.band_hi_hz;
  info.mesh_on = w.mesh_on;
  info.mesh_alarm = w.mesh_alarm;
  info.mesh_statistic = w.mesh_max_statistic;
  info.mesh_feature = w.mesh_max_feature;
  info.mesh_class = w.mesh_max_class;

  if (w.alarm && !state_.alarm_active) {
    state_.alarm_active = true;
    state_.alarm_raised_ns = t_mono_ns;
    state_.trip = info;
    alarms_raised_.add();
  }
  if (warning_condition_ && !warning_active_) {
    warning_active_ = true;
    warning_raised_ns_ = t_mono_ns;
    if (!state_.alarm_active) state_.trip = info;
  }
  apply_posted_clears(t_mono_ns);
  evaluate(t_mono_ns);
  return state_.level;
}

AlarmLevel AlarmManager::set_faults(std::uint8_t fault_causes, std::int64_t t_mono_ns) noexcept {
  const std::uint8_t mask = fault_causes & kFaultCauseMask;
  if (state_.fault_causes == 0 && mask != 0) faults_entered_.add();
  state_.fault_causes = mask;
  apply_posted_clears(t_mono_ns);
  evaluate(t_mono_ns);
  return state_.level;
}

AlarmLevel AlarmManager::set_input_ended(std::int64_t t_mono_ns) noexcept {
  ended_ = true;
  apply_posted_clears(t_mono_ns);
  evaluate(t_mono_ns);
  return state_.level;
}

AlarmLevel AlarmManager::tick(std::int64_t t_mono_ns) noexcept {
  apply_posted_clears(t_mono_ns);
  evaluate(t_mono_ns);
  return state_.level;
}

ClearResult AlarmManager::request_clear(ClearSource source, std::int64_t t_mono_ns) noexcept {
  state_.last_clear_ns = t_mono_ns;
  state_.last_clear_source = source;
  evaluate(t_mono_ns);  // an unlatched alarm whose hold just expired ends first
  last_clear_ = clear_now(t_mono_ns);
  evaluate(t_mono_ns);
  return last_clear_;
}

void AlarmManager::post_clear_request(ClearSource source) noexcept {
  posted_source_.store(static_cast<std::uint8_t>(source), std::memory_order_relaxed);
  posted_clears_.fetch_add(1, std::memory_order_release);
}

void AlarmManager::apply_posted_clears(std::int64_t t_ns) noexcept {
  if (posted_clears_.load(std::memory_order_relaxed) == 0) return;
  if (posted_clears_.exchange(0, std::memory_order_acquire) == 0) return;
  const auto source = static_cast<ClearSource>(posted_source_.load(std::memory_order_relaxed));
  state_.last_clear_ns = t_ns;
  state_.last_clear_source = source;
  evaluate(t_ns);
  last_clear_ = clear_now(t_ns);
}

ClearResult AlarmManager::clear_now(std::int64_t t_ns) noexcept {
  ClearResult r;
  if (!state_.alarm_active || !cfg_.latch) {
    r = ClearResult::kNothingToClear;
    clears_nothing_.add();
  } else if (t_ns - state_.alarm_raised_ns < min_hold_ns_) {
    r = ClearResult::kRefusedHold;
    clears_refused_.add();
  } else if (state_.condition) {
    r = ClearResult::kRefusedCondition;
    clears_refused_.add();
  } else {
    state_.alarm_active = false;
    r = ClearResult::kCleared;
    clears_accepted_.add();
  }
  return r;
}

void AlarmManager::evaluate(std::int64_t t_ns) noexcept {
  if (state_.alarm_active && !cfg_.latch && !state_.condition &&
      t_ns - state_.alarm_raised_ns >= min_hold_ns_) {
    state_.alarm_active = false;
  }
  if (warning_active_ && !warning_condition_ && t_ns - warning_raised_ns_ >= warning_hold_ns_) {
    warning_active_ = false;
  }
  state_.latched = state_.alarm_active && cfg_.latch;

  AlarmLevel level = AlarmLevel::kNormal;
  if (state_.alarm_active) {
    level = AlarmLevel::kAlarm;
  } else if (!judged_ || ended_ || state_.fault_causes != 0) {  // not judged yet, ended, or cannot judge
    level = AlarmLevel::kFault;
  } else if (warning_active_) {
    level = AlarmLevel::kWarning;
  }
  // The features of the abnormal windows since the debouncer last held none: the run-up counts.
  if (!state_.alarm_active && !warning_active_ && state_.last_abnormal_in_last_n == 0) {
    state_.feature_causes = 0;
  }
  set_level(level, t_ns);
}

void AlarmManager::set_level(AlarmLevel level, std::int64_t t_ns) noexcept {
  if (level == state_.level) return;
  const AlarmLevel from = state_.level;
  state_.level = level;
  state_.since_ns = t_ns;
  level_changes_.add();
  if (level == AlarmLevel::kWarning) warnings_raised_.add();
  if (change_ring_ == nullptr) return;
  LevelChange c;
  c.from = from;
  c.to = level;
  c.causes = report().causes;
  c.t_ns = t_ns;
  c.number = level_changes_.get();
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);  // vDSO: no system call, never blocks
  c.recorded_mono_ns = static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
  if (level == AlarmLevel::kAlarm || level == AlarmLevel::kWarning) {
    c.have_window = true;
    c.window = state_.trip;
  } else if (level == AlarmLevel::kNormal && state_.have_window) {
    c.have_window = true;
    c.window.t_ns = state_.last_window_t_ns;
    c.window.class_id = state_.last_class_id;
    c.window.abnormal_in_last_n = state_.last_abnormal_in_last_n;
    c.window.rms_res = state_.last_rms_res;
    c.window.entropy_res = state_.last_entropy_res;
    c.window.thresholds = last_thresholds_;
  }
  if (!change_ring_->try_push(c)) level_changes_dropped_.add();
}

drivers::AlarmReport AlarmManager::report() const noexcept {
  drivers::AlarmReport r;
  r.level = state_.level;
  const bool episode = state_.alarm_active || warning_active_;
  r.causes = static_cast<std::uint8_t>((episode ? state_.feature_causes : 0) | state_.fault_causes);
  if (state_.have_window) {
    r.segment_class = state_.last_class_id >= 0 && state_.last_class_id < drivers::kNoSegmentClass
                          ? static_cast<std::uint8_t>(state_.last_class_id)
                          : drivers::kNoSegmentClass;
    r.abnormal_windows =
        static_cast<std::uint8_t>(std::min<std::uint32_t>(state_.last_abnormal_in_last_n, 255U));
    r.rms = static_cast<float>(state_.last_rms_res);
    r.entropy = static_cast<float>(state_.last_entropy_res);
  }
  return r;
}

AlarmCounters AlarmManager::counters() const noexcept {
  AlarmCounters c;
  c.windows_scored = windows_scored_.get();
  c.windows_abnormal = windows_abnormal_.get();
  c.windows_unclassified = windows_unclassified_.get();
  c.alarms_raised = alarms_raised_.get();
  c.warnings_raised = warnings_raised_.get();
  c.faults_entered = faults_entered_.get();
  c.clears_accepted = clears_accepted_.get();
  c.clears_refused = clears_refused_.get();
  c.clears_nothing = clears_nothing_.get();
  c.level_changes = level_changes_.get();
  c.level_changes_dropped = level_changes_dropped_.get();
  return c;
}

}  // namespace ptda::daemon
