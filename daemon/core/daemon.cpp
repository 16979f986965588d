#include "core/daemon.hpp"

#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <spdlog/spdlog.h>
#include <sys/eventfd.h>
#include <sys/signalfd.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <system_error>

#include "core/logging.hpp"
#include "ptda/common/atomic_file.hpp"
#include "ptda/common/error.hpp"
#include "ptda/common/time.hpp"
#include "ptda/dsp/training.hpp"

namespace ptda::daemon {

namespace fs = std::filesystem;

namespace {

std::int64_t wall_time_ns() noexcept {
  timespec ts{};
  ::clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * kNsPerS + ts.tv_nsec;
}

DaemonState state_of(Phase phase) noexcept {
  switch (phase) {
    case Phase::kRefused:
      return DaemonState::kRefused;
    case Phase::kTraining:
      return DaemonState::kTraining;
    case Phase::kPausedSpeed:
    case Phase::kPausedSensor:
      return DaemonState::kPaused;
    case Phase::kEnded:
      return DaemonState::kEnded;
    case Phase::kStarting:
    case Phase::kMonitoring:
    case Phase::kNotJudging:  // running, its own phase and fault cause say it is blind
      return DaemonState::kRunning;
  }
  return DaemonState::kRunning;
}

/// Appends " name +delta" to a fixed buffer when a counter moved. Never allocates.
class DeltaLine {
 public:
  void add(const char* name, std::uint64_t now, std::uint64_t before) noexcept {
    if (now == before || len_ >= sizeof(buf_) - 1) return;
    const int n =
        std::snprintf(buf_ + len_, sizeof(buf_) - len_, "%s%s +%llu (%llu)", len_ == 0 ? "" : ", ", name,
                      static_cast<unsigned long long>(now - before), static_cast<unsigned long long>(now));
    if (n > 0) len_ = std::min(sizeof(buf_) - 1, len_ + static_cast<std::size_t>(n));
  }
  [[nodiscard]] bool empty() const noexcept { return len_ == 0; }
  [[nodiscard]] std::string_view view() const noexcept { return {buf_, len_}; }

 private:
  char buf_[480] = {};
  std::size_t len_ = 0;
};

// Where a replay starts on the wall clock, to line it up with other records of the same run (a bus
// capture, a live bus fed from the recording's CAN log): sample 0 of the WAV maps to this instant.
void log_replay_origin(const Pipeline& p, const drivers::Clock& clock) {
  const std::optional<std::int64_t> origin = p.replay_origin_mono_ns();
  if (!origin) return;
  const std::int64_t real = *origin + drivers::realtime_offset_ns(clock);
  spdlog::info("replay timeline: sample 0 at {}.{:09} (CLOCK_REALTIME), {} ns on the daemon clock",
               real / 1'000'000'000, real % 1'000'000'000, *origin);
}

// Temporary files of `target` that a killed run left behind (common/atomic_file.hpp): the old
// "<name>.tmp" / "<name>.tmp.<pid>" and the current "<name>.tmp-<random>", regular files we own only.
void remove_stale_temp_files_of(const fs::path& target) {
  if (target.empty()) return;
  const fs::path dir = target.parent_path();
  const std::size_t n = remove_stale_temp_files(dir.empty() ? "." : dir.c_str(), target.filename().native());
  if (n > 0) spdlog::info("removed {} stale temporary file(s) of {}", n, target.string());
}

/// "rms+entropy", "coverage", "none": the AlarmCause bits. Never allocates.
void cause_text(std::uint8_t causes, char* out, std::size_t cap) noexcept {
  static constexpr std::pair<std::uint8_t, const char*> kNames[] = {
      {drivers::kCauseRms, "rms"},           {drivers::kCauseEntropy, "entropy"},
      {drivers::kCauseSensor, "sensor"},     {drivers::kCauseSpeed, "speed"},
      {drivers::kCauseBaseline, "baseline"}, {drivers::kCauseInternal, "internal"},
      {drivers::kCauseCoverage, "coverage"}, {drivers::kCauseBand, "band"}};
  std::size_t n = 0;
  out[0] = '\0';
  for (const auto& [bit, name] : kNames) {
    if ((causes & bit) == 0) continue;
    const int k = std::snprintf(out + n, cap - n, "%s%s", n == 0 ? "" : "+", name);
    if (k < 0 || static_cast<std::size_t>(k) >= cap - n) break;
    n += static_cast<std::size_t>(k);
  }
  if (n == 0) std::snprintf(out, cap, "none");
}

/// "rms_res 0.0123 out of [0.001, 0.01]". Never allocates.
int feature_text(char* out, std::size_t cap, const char* name, double v, const dsp::Band& band) noexcept {
  const bool in = v >= band.lo && v <= band.hi;
  return std::snprintf(out, cap, "%s %.4g %s [%.4g, %.4g]", name, v, in ? "in" : "out of", band.lo, band.hi);
}

}  // namespace

Daemon::Daemon(DaemonOptions options, drivers::Clock& clock) : options_(std::move(options)), clock_(clock) {}

Daemon::~Daemon() {
  deactivate();
  if (signal_fd_ >= 0) ::close(signal_fd_);
  if (event_fd_ >= 0) ::close(event_fd_);
}

DaemonConfig Daemon::load_config() const {
  const fs::path dir =
      options_.config_dir ? *options_.config_dir : options_.config_file.parent_path() / "conf.d";
  DaemonConfig cfg = load_daemon_config(options_.config_file, list_dropins(dir));
  if (!options_.status_dir.empty()) cfg.daemon.status_dir = options_.status_dir;
  if (!options_.joint.empty()) cfg.daemon.joint = options_.joint;
  for (const std::string& w : cfg.pipeline.warnings) spdlog::warn("{}", w);
  return cfg;
}

void Daemon::build_history() {
  history_.reset();
  if (cfg_.history.dir.empty()) return;
  HistoryConfig hc;
  hc.dir = cfg_.history.dir;
  hc.max_file_bytes = static_cast<std::uint64_t>(cfg_.history.max_file_mib * 1024.0 * 1024.0);
  hc.files = cfg_.history.files;
  hc.joint = cfg_.daemon.joint;
  hc.method = std::string(dsp::method_name(cfg_.pipeline.method));
  history_ = std::make_unique<HistoryLog>(hc);
}

void Daemon::history_state(const PipelineStatus& ps, const char* reason) noexcept {
  history_state(ps, reason, ps.alarm.level, ps.report.causes);
}

void Daemon::history_state(const PipelineStatus& ps, const char* reason, drivers::AlarmLevel level,
                           std::uint8_t cause_bits) noexcept {
  char causes[64];
  cause_text(cause_bits, causes, sizeof causes);
  const DaemonState st = state_.load(std::memory_order_relaxed);
  history_->state(clock_.now_ns() + drivers::realtime_offset_ns(clock_), daemon_state_name(st),
                  phase_name(ps.phase), drivers::alarm_level_name(level), causes, reason);
}

void Daemon::build_mqtt() {
  if (!cfg_.mqtt.enabled) {
    if (mqtt_) spdlog::info("mqtt: disabled");
    mqtt_.reset();
    return;
  }
  MqttSettings s = resolve_mqtt_settings(cfg_.mqtt, cfg_.daemon.joint, std::getenv("CREDENTIALS_DIRECTORY"));
  if (mqtt_) {
    const MqttSettings& old = mqtt_->settings();
    if (old.cfg == s.cfg && old.joint == s.joint && old.password == s.password) return;  // unchanged
    mqtt_.reset();  // disconnects and closes the queue before the new one opens it
  }
  mqtt_ = std::make_unique<MqttPublisher>(std::move(s));
  mqtt_state_sent_ = false;
  mqtt_next_summary_ns_ = INT64_MIN;
}

// The windows the processing thread handed over: history lines, and (rate-limited by the window's end
// time) MQTT window summaries. Never allocates.
void Daemon::drain_windows(Pipeline& p) noexcept {
  const std::int64_t offset = drivers::realtime_offset_ns(clock_);
  const double every_s = mqtt_ ? cfg_.mqtt.window_summary_interval_s : 0.0;
  while (p.pop_window_log(history_window_)) {
    const dsp::WindowResult& w = history_window_;
    if (history_) history_->window(w, w.ref.t_end_ns + offset);
    if (every_s > 0.0 && w.ref.t_end_ns >= mqtt_next_summary_ns_) {
      mqtt_next_summary_ns_ = w.ref.t_end_ns + seconds_to_ns(every_s);
      MqttEvent& e = mqtt_event_;
      e = MqttEvent{};
      e.kind = EventKind::kSummary;
      e.t_mono_ns = w.ref.t_end_ns;
      e.t_unix_ns = w.ref.t_end_ns + offset;
      e.window_n = w.ref.seq;
      e.speed_rad_s = w.ref.speed_rad_s;
      const bool scored = w.status == dsp::WindowStatus::kScored;
      e.status.assign(scored ? "scored" : "no_class");
      e.have_features = scored;
      e.class_id = w.class_id;
      e.rms_res = w.features.rms_res;
      e.entropy_res = w.features.entropy_res;
      e.rms_lo = w.thresholds.rms.lo;
      e.rms_hi = w.thresholds.rms.hi;
      e.entropy_lo = w.thresholds.entropy.lo;
      e.entropy_hi = w.thresholds.entropy.hi;
      e.abnormal = w.verdict.abnormal();
      (void)mqtt_->post(e);
    }
  }
  if (history_) history_->counters().ring_dropped = p.status().window_log_dropped;
}

void Daemon::mqtt_state(const PipelineStatus& ps) noexcept {
  const DaemonState st = state_.load(std::memory_order_relaxed);
  if (mqtt_state_sent_ && st == mqtt_last_state_ && ps.phase == mqtt_last_phase_ &&
      ps.alarm.level == mqtt_last_level_)
    return;
  mqtt_state_sent_ = true;
  mqtt_last_state_ = st;
  mqtt_last_phase_ = ps.phase;
  mqtt_last_level_ = ps.alarm.level;
  MqttEvent& e = mqtt_event_;
  e = MqttEvent{};
  e.kind = EventKind::kState;
  e.t_mono_ns = clock_.now_ns();
  e.t_unix_ns = e.t_mono_ns + drivers::realtime_offset_ns(clock_);
  e.state.assign(daemon_state_name(st));
  e.phase.assign(phase_name(ps.phase));
  e.level.assign(drivers::alarm_level_name(ps.alarm.level));
  char causes[64];
  cause_text(ps.report.causes, causes, sizeof causes);
  e.causes.assign(causes);
  (void)mqtt_->post(e);
}

void Daemon::mqtt_alarm(const LevelChange& c, const char* causes) noexcept {
  MqttEvent& e = mqtt_event_;
  e = MqttEvent{};
  e.kind = c.to == drivers::AlarmLevel::kFault ? EventKind::kFault : EventKind::kAlarm;
  e.level.assign(drivers::alarm_level_name(c.to));
  e.causes.assign(causes);
  if (c.have_window) {  // warning/alarm: the window that raised it; normal: the last judged window
    e.have_features = true;
    e.t_mono_ns = c.window.t_ns;
    e.class_id = c.window.class_id;
    e.rms_res = c.window.rms_res;
    e.entropy_res = c.window.entropy_res;
    e.rms_lo = c.window.thresholds.rms.lo;
    e.rms_hi = c.window.thresholds.rms.hi;
    e.entropy_lo = c.window.thresholds.entropy.lo;
    e.entropy_hi = c.window.thresholds.entropy.hi;
    e.abnormal_in_last_n = c.window.abnormal_in_last_n;
  } else {
    e.t_mono_ns = c.t_ns;
  }
  e.t_unix_ns = e.t_mono_ns + drivers::realtime_offset_ns(clock_);
  e.recorded_mono_ns = c.recorded_mono_ns;
  (void)mqtt_->post(e);
}

void Daemon::build_status_writer() {
  StatusWriterConfig wc;
  if (!cfg_.daemon.status_dir.empty()) {
    std::error_code ec;
    fs::create_directories(cfg_.daemon.status_dir, ec);
    if (ec) {
      throw Error("[daemon] status_dir " + cfg_.daemon.status_dir.string() +
                  ": cannot create: " + ec.message());
    }
    wc.json_path = cfg_.daemon.status_dir / "status.json";
  }
  if (!cfg_.daemon.metrics_path.empty()) {
    std::error_code ec;
    fs::create_directories(cfg_.daemon.metrics_path.parent_path(), ec);
    wc.prom_path = cfg_.daemon.metrics_path;
  }
  wc.joint = cfg_.daemon.joint;
  for (const fs::path& p : {wc.json_path, wc.prom_path}) remove_stale_temp_files_of(p);
  writer_.reset();
  status_failing_logged_[0] = status_failing_logged_[1] = false;
  if (!wc.json_path.empty() || !wc.prom_path.empty()) writer_ = std::make_unique<StatusWriter>(wc);
}

void Daemon::configure() {
  // Signals are read through a signalfd: block them here, before any thread exists, so every thread
  // inherits the mask and a signal is never delivered asynchronously.
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGTERM);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGHUP);
  sigaddset(&set, SIGUSR1);  // local operator clear of a latched alarm
  if (pthread_sigmask(SIG_BLOCK, &set, nullptr) != 0) throw Error("ptdad: pthread_sigmask failed");
  if (signal_fd_ < 0) {
    signal_fd_ = ::signalfd(-1, &set, SFD_NONBLOCK | SFD_CLOEXEC);
    if (signal_fd_ < 0) throw Error(std::string("ptdad: signalfd: ") + std::strerror(errno));
  }
  if (event_fd_ < 0) {
    event_fd_ = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
    if (event_fd_ < 0) throw Error(std::string("ptdad: eventfd: ") + std::strerror(errno));
  }

  cfg_ = load_config();
  set_log_level(cfg_.daemon.log_level);
  notifier_ = SdNotifier(options_.notify_socket);
  mode_ = options_.train ? PipelineMode::kTrain : PipelineMode::kMonitor;
  remove_stale_temp_files_of(cfg_.daemon.baseline);
  if (mode_ == PipelineMode::kTrain) remove_stale_temp_files_of(cfg_.training.output);
  build_status_writer();
  build_history();
  build_mqtt();

  auto p = std::make_unique<Pipeline>(cfg_, mode_, clock_);
  p->set_window_sink(sink_);
  p->enable_window_log(history_ != nullptr || mqtt_ != nullptr);
  p->set_wake_fd(event_fd_);
  p->set_device_factory(factory_);
  p->set_probe(probe_);
  // Every stage beats between two watchdog pings (check_watchdog): sleep at most half a ping period.
  p->set_liveness_period_ns(options_.watchdog.enabled ? options_.watchdog.ping_period_ns / 2 : 0);
  p->configure();
  spdlog::info("configured from {} file(s) ({}{}); inputs: {}; fs {} Hz, window {} samples, method {}",
               cfg_.files.size(), cfg_.files.front().string(), cfg_.files.size() > 1 ? " + drop-ins" : "",
               p->inputs_text(), p->fs_hz(), cfg_.pipeline.extraction.window_len,
               dsp::method_name(cfg_.pipeline.method));
  if (p->refused()) {
    spdlog::error("monitoring refused: {}", p->refusal());
  } else if (p->baseline() != nullptr && p->baseline()->domain == dsp::Domain::kOrder) {
    const dsp::Baseline& b = *p->baseline();
    spdlog::info(
        "baseline {}: {} segment class(es), order domain: windows of {} input-shaft revolutions of {} "
        "samples",
        cfg_.daemon.baseline.string(), b.classes.size(), b.revolutions, b.samples_per_rev);
  } else if (p->baseline() != nullptr) {
    spdlog::info("baseline {}: {} segment class(es), trained at {} Hz", cfg_.daemon.baseline.string(),
                 p->baseline()->classes.size(), p->baseline()->fs_hz);
  }
  if (const std::string why = p->band_off_reason(); !why.empty()) {
    spdlog::warn("band detector off: {} (k-of-n and the feature CUSUM still judge)", why);
  }
  if (!cfg_.pipeline.mesh_off_reason.empty()) {
    spdlog::info("mesh detector off: {}", cfg_.pipeline.mesh_off_reason);
  } else if (const std::string why = p->mesh_off_reason(); !why.empty()) {
    spdlog::warn("mesh detector off: {} (the other detectors still judge)", why);
  }
  std::lock_guard lock(pipeline_mutex_);
  pipeline_ = std::move(p);
}

void Daemon::activate() {
  if (!pipeline_) throw Error("ptdad: activate() before configure()");
  pipeline_->activate();
  log_replay_origin(*pipeline_, clock_);
  if (!pipeline_->can_timer_text().empty())
    spdlog::info("CAN verdict frame: {}", pipeline_->can_timer_text());
  active_ = true;
  started_ns_ = clock_.now_ns();
  training_started_ns_ = started_ns_;
  for (auto& t : beat_changed_ns_) t = started_ns_;
  last_ping_beats_ = pipeline_->heartbeats();
  last_seen_beats_ = last_ping_beats_;
  update_state_and_reason(started_ns_);
  notifier_.ready();
  std::snprintf(status_text_, sizeof status_text_, "%s: %s", daemon_state_name(state_.load()).data(),
                mode_ == PipelineMode::kTrain ? "field training"
                                              : (pipeline_->refused() ? "no usable baseline" : "monitoring"));
  notifier_.status(status_text_);
  spdlog::info("running ({}); watchdog {}", mode_ == PipelineMode::kTrain ? "field training" : "monitoring",
               options_.watchdog.enabled ? "on" : "off");
}

void Daemon::deactivate() noexcept {
  {
    std::lock_guard lock(pipeline_mutex_);
    if (pipeline_) pipeline_->deactivate();
  }
  active_ = false;
}

void Daemon::request_stop() noexcept {
  stop_requested_.store(true, std::memory_order_release);
  if (event_fd_ >= 0) {
    const std::uint64_t one = 1;
    [[maybe_unused]] const auto n = ::write(event_fd_, &one, sizeof one);
  }
}

void Daemon::request_reload() noexcept {
  reload_requested_.store(true, std::memory_order_release);
  if (event_fd_ >= 0) {
    const std::uint64_t one = 1;
    [[maybe_unused]] const auto n = ::write(event_fd_, &one, sizeof one);
  }
}

void Daemon::request_clear() noexcept {
  local_clears_.fetch_add(1, std::memory_order_relaxed);
  std::lock_guard lock(pipeline_mutex_);
  if (pipeline_) pipeline_->post_clear();
}

void Daemon::set_processing_stall(bool stall) noexcept {
  stall_.store(stall, std::memory_order_relaxed);
  std::lock_guard lock(pipeline_mutex_);
  if (pipeline_) pipeline_->set_processing_stall(stall);
}

DaemonView Daemon::view() const noexcept {
  DaemonView v;
  {
    std::lock_guard lock(pipeline_mutex_);
    if (pipeline_) {
      v.pipeline = pipeline_->status();
      v.counters = pipeline_->counters();
      v.heartbeats = pipeline_->heartbeats();
      v.wake = pipeline_->wake_schedule();
      v.window_len = pipeline_->config().pipeline.extraction.window_len;
      v.min_hold_s = pipeline_->config().alarm.min_hold_s;
    }
  }
  v.phase = v.pipeline.phase;
  v.state = state_.load(std::memory_order_acquire);
  {
    std::lock_guard lock(reason_mutex_);
    v.reason = reason_;
  }
  v.reloads = reloads_.load();
  v.reload_failures = reload_failures_.load();
  v.watchdog_pings = pings_.load();
  v.watchdog_skipped = pings_skipped_.load();
  v.status_writes = status_writes_.load();
  v.status_write_failures = status_write_failures_.load();
  v.local_clears = local_clears_.load();
  return v;
}

void Daemon::restart_pipeline(const DaemonConfig& cfg, PipelineMode mode) {
  auto fresh = std::make_unique<Pipeline>(cfg, mode, clock_);
  fresh->set_window_sink(sink_);
  fresh->enable_window_log(history_ != nullptr || mqtt_ != nullptr);
  fresh->set_wake_fd(event_fd_);
  fresh->set_device_factory(factory_);
  fresh->set_probe(probe_);
  // Every stage beats between two watchdog pings (check_watchdog): sleep at most half a ping period.
  fresh->set_liveness_period_ns(options_.watchdog.enabled ? options_.watchdog.ping_period_ns / 2 : 0);
  {
    // Stop the old pipeline first: a device (IIO buffer, GPIO line) has one user at a time.
    std::lock_guard lock(pipeline_mutex_);
    if (pipeline_) {
      pipeline_->deactivate();
      if (history_ || mqtt_) drain_windows(*pipeline_);  // its last windows, before it goes
      log_alarm_changes(*pipeline_);                     // and its last level changes
      last_level_changes_ = 0;                           // the next pipeline numbers its changes from 1
      // Field training goes on: keep the collected windows for the new pipeline (held here until it
      // started, so a reload that fails keeps them for the restart with the previous configuration).
      if (mode == PipelineMode::kTrain && pipeline_->mode() == PipelineMode::kTrain) {
        carried_trainer_ = pipeline_->release_trainer();
      }
    }
    pipeline_.reset();
  }
  training_end_seen_ = false;
  if (mode == PipelineMode::kTrain) fresh->set_previous_trainer(carried_trainer_.get());
  fresh->configure();
  if (fresh->trainer() != nullptr) {
    const std::string room = fresh->trainer()->spill_space_warning();
    if (!room.empty()) spdlog::warn("{}", room);
  }
  fresh->activate();
  if (mode != PipelineMode::kTrain) {
    carried_trainer_.reset();
  } else if (fresh->training_carry()) {
    const TrainingCarryOver& c = *fresh->training_carry();
    char note[kStatusTextBytes];
    if (c.kept) {
      std::snprintf(note, sizeof note, "reload kept %llu collected windows and %llu cycles%s",
                    static_cast<unsigned long long>(c.windows), static_cast<unsigned long long>(c.regions),
                    c.windows_lost + c.regions_lost > 0 ? " (the rest did not fit the new pool size)" : "");
      spdlog::info("field training: {}", note);
    } else {
      std::snprintf(note, sizeof note,
                    "training restarted: the reload changed %s; %llu windows and %llu cycles discarded",
                    c.why.c_str(), static_cast<unsigned long long>(c.windows_lost),
                    static_cast<unsigned long long>(c.regions_lost));
      spdlog::warn("field training: {} (windows of another length or rate cannot train one baseline)", note);
    }
    training_note_.assign(note);
    carried_trainer_.reset();
  }
  log_replay_origin(*fresh, clock_);
  if (stall_.load(std::memory_order_relaxed)) fresh->set_processing_stall(true);
  if (fresh->refused()) spdlog::error("monitoring refused: {}", fresh->refusal());
  std::lock_guard lock(pipeline_mutex_);
  pipeline_ = std::move(fresh);
  last_ping_beats_ = StageHeartbeats{};
  last_seen_beats_ = StageHeartbeats{};
  last_counters_ = PipelineCounters{};
  last_source_ = drivers::SampleSourceCounters{};
  last_slicer_ = dsp::SlicerCounters{};
}

void Daemon::reload() {
  notifier_.reloading();
  spdlog::info("reload requested: reading {}", options_.config_file.string());
  DaemonConfig next;
  try {
    next = load_config();
  } catch (const Error& e) {
    reload_failures_.fetch_add(1);
    last_reload_error_.assign(e.what());
    spdlog::error("reload rejected, keeping the previous configuration: {}", e.what());
    notifier_.ready();
    return;
  }
  try {
    restart_pipeline(next, mode_);
    cfg_ = std::move(next);
    set_log_level(cfg_.daemon.log_level);
    try {
      build_status_writer();
    } catch (const Error& e) {
      spdlog::error("reload: status files disabled: {}", e.what());
      writer_.reset();
    }
    try {
      build_history();
    } catch (const Error& e) {
      spdlog::error("reload: event history disabled: {}", e.what());
      history_.reset();
    }
    try {
      build_mqtt();
    } catch (const Error& e) {
      spdlog::error("reload: mqtt disabled: {}", e.what());
      mqtt_.reset();
    }
    pipeline_->enable_window_log(history_ != nullptr || mqtt_ != nullptr);
    reloads_.fetch_add(1);
    spdlog::info("reload: new configuration active ({})", pipeline_->inputs_text());
  } catch (const Error& e) {
    reload_failures_.fetch_add(1);
    last_reload_error_.assign(e.what());
    spdlog::error("reload failed, restarting with the previous configuration: {}", e.what());
    try {
      restart_pipeline(cfg_, mode_);
    } catch (const Error& e2) {
      spdlog::critical("the previous configuration no longer starts either: {}; exiting", e2.what());
      exit_code_ = 1;
      stop_requested_.store(true);
    }
  }
  notifier_.ready();
}

void Daemon::check_watchdog(std::int64_t now) noexcept {
  std::lock_guard lock(pipeline_mutex_);
  if (!pipeline_) return;
  const StageHeartbeats b = pipeline_->heartbeats();
  const bool advanced = b.acquisition != last_ping_beats_.acquisition && b.can != last_ping_beats_.can &&
                        b.processing != last_ping_beats_.processing;
  if (advanced) {
    notifier_.watchdog();
    pings_.fetch_add(1, std::memory_order_relaxed);
    last_ping_beats_ = b;
  } else {
    pings_skipped_.fetch_add(1, std::memory_order_relaxed);
    spdlog::warn("watchdog ping withheld: heartbeats acquisition {} can {} processing {} did not all advance",
                 b.acquisition, b.can, b.processing);
  }
  (void)now;
}

void Daemon::update_state_and_reason(std::int64_t now) noexcept {
  Pipeline* p = pipeline_.get();
  if (p == nullptr) return;
  const PipelineStatus ps = p->status();
  const StageHeartbeats b = p->heartbeats();
  const std::uint64_t beats[3] = {b.acquisition, b.can, b.processing};
  const std::uint64_t last[3] = {last_seen_beats_.acquisition, last_seen_beats_.can,
                                 last_seen_beats_.processing};
  static constexpr const char* kStage[3] = {"acquisition", "can", "processing"};
  int stalled = -1;
  for (int i = 0; i < 3; ++i) {
    if (beats[i] != last[i]) beat_changed_ns_[i] = now;
    if (now - beat_changed_ns_[i] > seconds_to_ns(cfg_.daemon.stage_stall_s)) stalled = i;
  }
  last_seen_beats_ = b;

  DaemonState state = state_of(ps.phase);
  char reason[kStatusTextBytes] = {};
  switch (ps.phase) {
    case Phase::kRefused:
      std::snprintf(reason, sizeof reason, "%s", p->refusal().c_str());
      break;
    case Phase::kPausedSpeed:
      std::snprintf(reason, sizeof reason, "no joint speed (CAN id 0x%X) for more than %.3g s%s",
                    static_cast<unsigned>(cfg_.pipeline.speed_frame.id),
                    cfg_.daemon.speed_stale_periods * cfg_.pipeline.speed_frame.period_s,
                    p->can_bus_state() == drivers::CanBusState::kBusOff ? " (bus-off)" : "");
      break;
    case Phase::kPausedSensor:
      std::snprintf(reason, sizeof reason, "no vibration data for more than %.3g s",
                    cfg_.daemon.sensor_stale_s);
      break;
    case Phase::kEnded: {
      const int n = std::snprintf(reason, sizeof reason, "replay ended; %llu windows processed",
                                  static_cast<unsigned long long>(ps.windows));
      // How well the replay was covered ("partial coverage: class 1 ..."); nothing when fully.
      if (p->baseline() != nullptr && n > 0 && static_cast<std::size_t>(n) + 3 < sizeof reason &&
          ps.coverage.level != dsp::CoverageLevel::kFull) {
        const auto at = static_cast<std::size_t>(n);
        reason[at] = ';';
        reason[at + 1] = ' ';
        if (dsp::describe_coverage(ps.coverage, *p->baseline(), cfg_.daemon.coverage_timeout_s,
                                   reason + at + 2, sizeof reason - at - 2) == 0) {
          reason[at] = '\0';
        }
      }
      break;
    }
    case Phase::kNotJudging:
      if (p->baseline() != nullptr) {
        const std::size_t n = dsp::describe_coverage(ps.coverage, *p->baseline(),
                                                     cfg_.daemon.coverage_timeout_s, reason, sizeof reason);
        if (ps.ended && n + 1 < sizeof reason) {
          // Whole or not at all (a cut would end the text mid-word).
          const int k = std::snprintf(reason + n, sizeof reason - n, "; replay ended; %llu windows processed",
                                      static_cast<unsigned long long>(ps.windows));
          if (k < 0 || static_cast<std::size_t>(k) >= sizeof reason - n) reason[n] = '\0';
        }
      }
      break;
    case Phase::kStarting:
      std::snprintf(reason, sizeof reason, "waiting for the first vibration block");
      break;
    case Phase::kTraining:
      std::snprintf(reason, sizeof reason, "%s", training_note_.text.data());  // a reload's effect
      break;
    case Phase::kMonitoring:
      // "not judged yet" before the first judged window, "partial coverage: ..." when a class is missing.
      if (p->baseline() != nullptr) {
        (void)dsp::describe_coverage(ps.coverage, *p->baseline(), cfg_.daemon.coverage_timeout_s, reason,
                                     sizeof reason);
      }
      break;
  }
  if (stalled >= 0) {
    std::snprintf(reason, sizeof reason, "stage %s made no progress for more than %.3g s", kStage[stalled],
                  cfg_.daemon.stage_stall_s);
    if (!stalled_logged_) spdlog::error("{}", reason);
    stalled_logged_ = true;
  } else {
    stalled_logged_ = false;
  }
  if (stop_requested_.load(std::memory_order_relaxed)) state = DaemonState::kStopping;
  {
    std::lock_guard lock(reason_mutex_);
    reason_.assign(reason);
  }
  state_.store(state, std::memory_order_release);
  if (ps.phase != last_phase_ || state != last_state_) {
    if (history_) history_state(ps, reason);
    if (ps.phase == Phase::kRefused || ps.phase == Phase::kPausedSpeed || ps.phase == Phase::kPausedSensor ||
        ps.phase == Phase::kNotJudging) {
      spdlog::warn("state {} ({}): {}", daemon_state_name(state), phase_name(ps.phase), reason);
    } else {
      spdlog::info("state {} ({}){}{}", daemon_state_name(state), phase_name(ps.phase), reason[0] ? ": " : "",
                   reason);
    }
    last_phase_ = ps.phase;
    last_state_ = state;
  }
}

void Daemon::fill_snapshot(std::int64_t now) noexcept {
  Pipeline* p = pipeline_.get();
  StatusSnapshot& s = snapshot_;
  s.state = state_.load();
  {
    std::lock_guard lock(reason_mutex_);
    s.reason = reason_;
  }
  s.method.assign(dsp::method_name(cfg_.pipeline.method));
  s.uptime_s = ns_to_seconds(now - started_ns_);
  s.wall_time_unix_ns = wall_time_ns();
  s.now_s = ns_to_seconds(now);
  if (p == nullptr) return;
  const PipelineStatus ps = p->status();
  s.phase.assign(phase_name(ps.phase));
  // The status timeline: window and alarm times are on the alarm manager's time base, which in a fast
  // replay is data time and runs ahead of the daemon clock (a 60 s recording is replayed in ~2 s). Ages
  // are taken against the latest instant of that timeline, so they are never negative; in real time it
  // is the daemon clock (the data lags it by the ring's latency).
  const std::int64_t timeline_ns = std::max({now, ps.clock_ns, ps.data_time_ns});
  s.now_s = ns_to_seconds(timeline_ns);
  // Wall-clock time of a timeline instant: the daemon clock's offset to CLOCK_REALTIME. For a fast
  // replay that is the replay's own timeline (sample 0 at activation, as logged at start).
  const std::int64_t to_wall_ns = drivers::realtime_offset_ns(clock_);
  const auto wall = [to_wall_ns](std::int64_t t_ns) noexcept { return t_ns + to_wall_ns; };
  const dsp::Baseline* b = p->baseline();
  s.baseline_loaded = b != nullptr;
  s.baseline_path.assign(cfg_.daemon.baseline.native());
  const auto m = static_cast<std::size_t>(cfg_.pipeline.method);
  if (b != nullptr) {
    s.baseline_source.assign(b->source);
    s.baseline_fs_hz = b->fs_hz;
    s.baseline_window_len = b->window_len;
    s.class_count = static_cast<std::uint32_t>(b->classes.size());
    s.classes_listed = static_cast<std::uint32_t>(std::min(b->classes.size(), kStatusMaxClasses));
    for (std::uint32_t i = 0; i < s.classes_listed; ++i) {
      const dsp::ClassBaseline& c = b->classes[i];
      StatusClass& sc = s.classes[i];
      sc.id = c.segment.id;
      sc.direction = c.segment.direction;
      sc.speed_rad_s = c.segment.speed_rad_s;
      sc.duration_s = c.segment.duration_s;
      sc.regions = c.segment.regions;
      sc.n_windows = c.n_windows;
      sc.rms_lo = c.thresholds[m].rms.lo;
      sc.rms_hi = c.thresholds[m].rms.hi;
      sc.entropy_lo = c.thresholds[m].entropy.lo;
      sc.entropy_hi = c.thresholds[m].entropy.hi;
    }
  } else {
    s.baseline_source.assign("");
    s.class_count = 0;
    s.classes_listed = 0;
  }
  s.have_window = ps.have_window;
  if (ps.have_window) {
    const dsp::WindowResult& w = ps.last_window;
    s.window_t_s = ns_to_seconds(w.ref.t_end_ns);
    s.window_wall_ns = wall(w.ref.t_end_ns);
    s.window_class = w.class_id;
    s.window_speed_rad_s = w.ref.speed_rad_s;
    s.window_rms = w.features.rms_res;
    s.window_entropy = w.features.entropy_res;
    s.window_rms_lo = w.thresholds.rms.lo;
    s.window_rms_hi = w.thresholds.rms.hi;
    s.window_entropy_lo = w.thresholds.entropy.lo;
    s.window_entropy_hi = w.thresholds.entropy.hi;
    s.window_rms_out = w.verdict.rms_out;
    s.window_entropy_out = w.verdict.entropy_out;
    s.window_abnormal_in_last_n = w.abnormal_in_last_n;
  }
  s.alarm_level = ps.report.level;
  s.alarm_since_s = ns_to_seconds(ps.alarm.since_ns);
  s.alarm_since_wall_ns = wall(ps.alarm.since_ns);
  s.alarm_latched = ps.alarm.latched;
  s.alarm_causes = ps.report.causes;
  s.trip_class = ps.alarm.alarm_active ? ps.alarm.trip.class_id : -1;
  s.trip_rms = ps.alarm.trip.rms_res;
  s.trip_entropy = ps.alarm.trip.entropy_res;
  s.trip_t_s = ns_to_seconds(ps.alarm.trip.t_ns);
  s.trip_detector = dsp::alarm_detector_name(ps.alarm.trip.detector);
  s.trip_cusum = ps.alarm.trip.seq_statistic;
  s.trip_band_on = ps.alarm.trip.band_on;
  s.trip_band_cusum = ps.alarm.trip.band_statistic;
  s.trip_band = ps.alarm.trip.band_index;
  s.trip_band_lo_hz = ps.alarm.trip.band_lo_hz;
  s.trip_band_hi_hz = ps.alarm.trip.band_hi_hz;
  s.trip_mesh_on = ps.alarm.trip.mesh_on;
  s.trip_mesh_cusum = ps.alarm.trip.mesh_statistic;
  s.trip_mesh_feature = dsp::mesh_feature_label(ps.alarm.trip.mesh_feature);
  s.trip_wall_ns = wall(ps.alarm.trip.t_ns);

  const drivers::SampleSourceCounters a = p->source_counters();
  const PipelineCounters c = p->counters();
  const drivers::CanCounters cc = p->can_counters();
  s.acq_blocks = a.blocks;
  s.acq_samples = a.samples;
  s.acq_gaps = a.gaps;
  s.acq_lost_samples = a.lost_samples + c.acq_ring_full_samples;
  s.acq_short_reads = a.short_reads;
  s.acq_time_back = a.time_back;
  s.acq_timeouts = a.timeouts;
  s.acq_read_errors = a.read_errors;
  s.can_frames = c.can_frames;
  s.can_speed_frames = c.can_speed;
  s.can_other_ids = c.can_other_id;
  s.can_wrong_dlc = c.can_wrong_dlc;
  s.can_remote_frames = c.can_rtr;
  s.can_error_frames = c.can_error_frames;
  s.can_rx_overflow_drops = cc.rx_overflow_drops;
  s.can_bus_off = cc.bus_off;
  s.can_bus_state = p->can_bus_state();
  s.slicer_regions = ps.slicer.regions;
  s.slicer_windows = ps.slicer.windows;
  s.slicer_windows_invalid = ps.slicer.windows_invalid;
  s.slicer_windows_lost = ps.slicer.windows_lost;
  s.order_domain = ps.order_domain;
  s.order_frames = ps.resampler.frames;
  s.order_frames_no_angle = ps.resampler.frames_no_angle;
  s.order_frames_out_of_order = ps.resampler.frames_out_of_order;
  s.order_frames_overflow = ps.resampler.frames_overflow;
  s.order_angle_inconsistent = ps.resampler.angle_inconsistent;
  s.order_breaks = ps.resampler.breaks;
  s.order_samples_unused = ps.resampler.samples_unused;
  s.order_samples_overrun = ps.resampler.samples_overrun;
  s.order_outputs = ps.resampler.outputs;
  s.order_outputs_dropped = ps.resampler.outputs_dropped;
  s.order_windows = ps.order_windows_cut;
  s.ring_overflows = c.acq_ring_full_blocks + c.can_ring_full;
  s.windows_scored = ps.scored;
  s.windows_abnormal = ps.abnormal;
  s.alarms_raised = ps.alarm_counters.alarms_raised;
  s.level_changes_dropped = ps.alarm_counters.level_changes_dropped;
  s.coverage = ps.coverage;
  s.coverage_timeout_s = cfg_.daemon.coverage_timeout_s;
  s.coverage_known = b != nullptr && p->mode() == PipelineMode::kMonitor;
  s.watchdog_pings = pings_.load(std::memory_order_relaxed);
}

void Daemon::log_counter_changes() noexcept {
  Pipeline* p = pipeline_.get();
  if (p == nullptr) return;
  const PipelineCounters c = p->counters();
  const drivers::SampleSourceCounters a = p->source_counters();
  const dsp::SlicerCounters sc = p->status().slicer;
  DeltaLine line;
  line.add("sample ring overruns", c.acq_ring_full_blocks, last_counters_.acq_ring_full_blocks);
  line.add("adc read errors", c.acq_read_errors, last_counters_.acq_read_errors);
  line.add("adc gaps", a.gaps, last_source_.gaps);
  line.add("adc short reads", a.short_reads, last_source_.short_reads);
  line.add("adc time back", a.time_back, last_source_.time_back);
  line.add("speed ring overruns", c.can_ring_full, last_counters_.can_ring_full);
  line.add("CAN wrong DLC", c.can_wrong_dlc, last_counters_.can_wrong_dlc);
  line.add("CAN remote", c.can_rtr, last_counters_.can_rtr);
  line.add("CAN error frames", c.can_error_frames, last_counters_.can_error_frames);
  line.add("CAN receive errors", c.can_receive_errors, last_counters_.can_receive_errors);
  line.add("CAN clear frames", c.can_clear_frames, last_counters_.can_clear_frames);
  line.add("alarm output errors", c.output_errors, last_counters_.output_errors);
  // Speed samples the slicer refused: each one ends the constant-speed run (a window may be lost).
  line.add("speed samples out of order", sc.speed_out_of_order, last_slicer_.speed_out_of_order);
  line.add("speed gaps", sc.speed_gaps, last_slicer_.speed_gaps);
  line.add("speed out of range", sc.speed_out_of_range, last_slicer_.speed_out_of_range);
  if (!line.empty()) spdlog::warn("counters: {}", line.view());
  if (c.acq_end && !last_counters_.acq_end) spdlog::info("vibration source: end of stream");
  if (c.can_end && !last_counters_.can_end) spdlog::info("CAN source: end of stream");
  last_counters_ = c;
  last_source_ = a;
  last_slicer_ = sc;
}

// Runs on the supervisor (the processing thread records each level change in the pipeline's
// LevelChangeRing; it never logs). Each change is its own log line, history line and MQTT event, also
// when several happened since the last look. A new pipeline starts at fault without a recorded change:
// when the previous one ended at another level, that start is reported from the new one's status.
void Daemon::log_alarm_changes(Pipeline& p) noexcept {
  const PipelineStatus ps = p.status();
  if (ps.alarm_counters.level_changes == 0 && ps.alarm.level != last_level_) {
    LevelChange& c = level_change_;
    c = LevelChange{};
    c.from = last_level_;
    c.to = ps.alarm.level;
    c.causes = ps.report.causes;
    c.t_ns = ps.alarm.since_ns;
    report_level_change(c, ps, 0);
  }
  while (p.pop_level_change(level_change_)) {
    const LevelChange& c = level_change_;
    const std::uint64_t missed = c.number > last_level_changes_ + 1 ? c.number - last_level_changes_ - 1 : 0;
    last_level_changes_ = c.number;
    report_level_change(c, ps, missed);
  }
}

// Lines stay under spdlog's 250-byte inline buffer, so logging them does not allocate.
void Daemon::report_level_change(const LevelChange& c, const PipelineStatus& ps,
                                 std::uint64_t missed) noexcept {
  const drivers::AlarmLevel level = c.to;
  const drivers::AlarmLevel was = c.from;
  last_level_ = level;

  char since[32] = "?";
  (void)format_rfc3339_utc(c.t_ns + drivers::realtime_offset_ns(clock_), since, sizeof since);
  char head[96];
  std::snprintf(head, sizeof head, "alarm level %s (was %s", drivers::alarm_level_name(level).data(),
                drivers::alarm_level_name(was).data());
  char extra[64] = "";
  if (missed > 0) {
    std::snprintf(extra, sizeof extra, "; %llu more not recorded: ring full",
                  static_cast<unsigned long long>(missed));
  }
  const dsp::DecisionConfig& dc = cfg_.pipeline.decision;
  char evidence[320] = "";
  char causes[64];
  cause_text(c.causes, causes, sizeof causes);
  if (c.have_window) {
    // Alarm/warning: the window that raised it; normal: the last judged window.
    char f1[64], f2[64];
    (void)feature_text(f1, sizeof f1, "rms_res", c.window.rms_res, c.window.thresholds.rms);
    (void)feature_text(f2, sizeof f2, "entropy_res", c.window.entropy_res, c.window.thresholds.entropy);
    std::snprintf(
        evidence, sizeof evidence, "class %d, %s, %s, %u of %u abnormal (warn %u, alarm %u); cause %s",
        static_cast<int>(c.window.class_id), f1, f2, static_cast<unsigned>(c.window.abnormal_in_last_n),
        static_cast<unsigned>(dc.n), static_cast<unsigned>(cfg_.alarm.warning ? cfg_.alarm.warning_k : 0),
        static_cast<unsigned>(dc.k), causes);
    const std::size_t used = std::strlen(evidence);
    const bool episode = level != drivers::AlarmLevel::kNormal;
    if (episode && c.window.band_on && c.window.band_index >= 0 && used < sizeof evidence) {
      // The band CUSUM's evidence (only with [decision] band_cusum on: other lines stay as before).
      std::snprintf(evidence + used, sizeof evidence - used, "; detector %s, band %d %.0f-%.0f Hz CUSUM %.3g",
                    dsp::alarm_detector_name(c.window.detector), static_cast<int>(c.window.band_index),
                    c.window.band_lo_hz, c.window.band_hi_hz, c.window.band_statistic);
    }
    const std::size_t used2 = std::strlen(evidence);
    if (episode && c.window.mesh_on && c.window.mesh_alarm && used2 < sizeof evidence) {
      // The mesh CUSUM's evidence (only with [decision] mesh_cusum on and its alarm held).
      std::snprintf(evidence + used2, sizeof evidence - used2, "; detector %s, mesh %s CUSUM %.3g (class %d)",
                    dsp::alarm_detector_name(c.window.detector),
                    dsp::mesh_feature_label(c.window.mesh_feature), c.window.mesh_statistic,
                    static_cast<int>(c.window.mesh_class));
    }
  } else {
    std::snprintf(evidence, sizeof evidence, "no verdict (%s); cause %s", phase_name(ps.phase), causes);
  }
  if (history_) history_state(ps, evidence, level, c.causes);
  if (mqtt_) mqtt_alarm(c, causes);
  // spdlog formats the message, then the sink's pattern ("[2026-11-27 16:53:47.995] [warning] ", 36
  // bytes, and the newline) around it, each in a 250-byte inline buffer: a longer line would allocate
  // on the supervisor. A line longer than kMaxLine is logged as two: the level change, then its
  // evidence (each well under the limit: evidence < 320 bytes only with absurd causes, then cut).
  constexpr std::size_t kMaxLine = 250 - 36 - 2;
  char line[kMaxLine + 1];
  const int len = std::snprintf(line, sizeof line, "%s%s) at %s: %s", head, extra, since, evidence);
  const bool split = len > static_cast<int>(kMaxLine);
  if (split) {
    std::snprintf(line, sizeof line, "%s%s) at %s (evidence on the next line)", head, extra, since);
  }
  const auto emit = [&](const char* text) {
    if (level == drivers::AlarmLevel::kNormal) {
      spdlog::info("{}", text);
    } else {
      spdlog::warn("{}", text);
    }
  };
  emit(line);
  if (split) {
    std::snprintf(line, sizeof line, "alarm level %s evidence: %s", drivers::alarm_level_name(level).data(),
                  evidence);
    emit(line);
  }
}

void Daemon::check_training(std::int64_t now) {
  if (mode_ != PipelineMode::kTrain || !pipeline_ || pipeline_->trainer() == nullptr) return;
  const FieldTrainer& trainer = *pipeline_->trainer();
  // The end first, then the progress: a window published in between is then counted, not missed. At
  // the end of a replay the last windows may still wait in the slicer or be on their way to the file.
  const bool ended = pipeline_->status().ended && !pipeline_->training_backlog() && trainer.queued() == 0;
  // The spill counters before the progress (whose dropped count includes them): they only grow, so
  // their sum never exceeds the dropped count shown beside them.
  const FieldTrainerCounters tk = trainer.counters();
  const TrainingProgress progress = trainer.progress();  // allocates: training mode only
  snapshot_.training_windows = progress.windows;
  snapshot_.training_capacity = progress.window_capacity;
  snapshot_.training_regions = progress.regions;
  snapshot_.training_classes = static_cast<std::uint32_t>(progress.classes.size());
  snapshot_.training_classes_complete = progress.classes_complete;
  snapshot_.training_target_cycles = progress.target_cycles;
  snapshot_.training_dropped = progress.windows_dropped + progress.regions_dropped;
  snapshot_.training_spill_write_failed = tk.windows_write_failed;
  snapshot_.training_spill_queue_full = tk.windows_queue_full;
  snapshot_.training_spill_errno = tk.last_write_errno;
  if (tk.windows_write_failed + tk.windows_queue_full < training_spill_problems_)
    training_spill_problems_ = 0;
  if (tk.windows_write_failed + tk.windows_queue_full > training_spill_problems_) {
    // Counted by the writer and the processing thread; reported here, once per status period at most.
    spdlog::warn(
        "field training: {} window(s) not kept: {} failed writes to the spill file in {} (last: {}), "
        "{} while the writer was behind",
        tk.windows_write_failed + tk.windows_queue_full - training_spill_problems_, tk.windows_write_failed,
        trainer.config().spill_dir.string(),
        tk.last_write_errno != 0 ? std::strerror(tk.last_write_errno) : "none", tk.windows_queue_full);
    training_spill_problems_ = tk.windows_write_failed + tk.windows_queue_full;
  }
  const bool timed_out = now - training_started_ns_ > seconds_to_ns(cfg_.training.max_duration_s);
  training_end_seen_ = ended;
  if (!progress.ready && !((timed_out || ended) && progress.can_finish)) return;
  if (baseline_health_.failing && now < baseline_retry_ns_) return;  // backoff after a failed write
  const fs::path out = cfg_.training.output.empty() ? cfg_.daemon.baseline : cfg_.training.output;
  if (before_write_ != nullptr) before_write_(before_write_arg_);  // test-only hook
  try {
    const dsp::Baseline b =
        trainer.finish(out, progress.ready ? FinishMode::kRequireReady : FinishMode::kWhatIsThere);
    spdlog::info(
        "field training: baseline written to {} ({} segment class(es), {} windows); monitoring starts",
        out.string(), b.classes.size(), progress.windows);
    // What the amount of data cannot promise (one run: the between-day spread is assumed), as `ptda train`
    // prints it; a maintenance engineer reads these in the journal before trusting the first alarm.
    for (const std::string& w : dsp::training_warnings(
             b, "with `ptda train --recording` once per day, then point [daemon] baseline at that file"))
      spdlog::warn("field training: {}", w);
    if (baseline_health_.failing) {
      spdlog::info("field training: writing {} works again after {} failed attempt(s)", out.string(),
                   baseline_consecutive_);
    }
    baseline_health_.failing = false;
    baseline_consecutive_ = 0;
    mode_ = PipelineMode::kMonitor;
    DaemonConfig next = cfg_;
    next.daemon.baseline = out;
    cfg_ = next;
    // A stop that arrived meanwhile (the write is atomic and was not interrupted): do not start the
    // monitoring pipeline only to stop it again.
    if (stop_requested_.load(std::memory_order_acquire)) return;
    restart_pipeline(next, mode_);
  } catch (const WriteError& e) {
    // Trained, but the file could not be written (full disk, EIO, read-only, a missing directory):
    // shown in status.json / the metrics, retried after 1, 2, 4, ... status periods (at most 64),
    // logged on the first failure and when it works again.
    ++baseline_health_.failures;
    baseline_health_.last_errno = e.err();
    baseline_health_.last_step = "write";
    if (!baseline_health_.failing) {
      spdlog::error("field training: {}; the collected windows are kept, retrying with backoff", e.what());
    }
    baseline_health_.failing = true;
    ++baseline_consecutive_;
    const std::int64_t period = seconds_to_ns(cfg_.daemon.status_period_s);
    baseline_retry_ns_ =
        now + period * (std::int64_t{1} << std::min<std::uint32_t>(baseline_consecutive_ - 1, 6));
  } catch (const Error& e) {
    spdlog::error("field training: {}", e.what());
    training_started_ns_ = now;  // try again after another max_duration_s
  }
}

// Logs a status/metrics file that starts failing and one that works again (not every failed period).
// Lines stay under spdlog's inline buffer: no allocation.
void Daemon::log_status_write_changes() noexcept {
  for (const StateFile f : {StateFile::kStatus, StateFile::kMetrics}) {
    const StateFileHealth h = writer_->health(f);
    bool& was = status_failing_logged_[static_cast<std::size_t>(f)];
    if (h.failing && !was) {
      spdlog::error("{} file {}: write failed at {}: {} ({}); retrying with backoff", state_file_name(f),
                    writer_->path(f), h.last_step, errno_text(h.last_errno), errno_name(h.last_errno));
    } else if (!h.failing && was) {
      spdlog::info("{} file {}: written again ({} failed attempt(s) in all)", state_file_name(f),
                   writer_->path(f), h.failures);
    }
    was = h.failing;
  }
}

void Daemon::supervise(std::int64_t now) noexcept {
  update_state_and_reason(now);
  try {
    check_training(now);
  } catch (const std::exception& e) {
    spdlog::error("field training: {}", e.what());
  }
  fill_snapshot(now);
  // The windows first, then the level change they caused: the history stays in time order.
  if ((history_ || mqtt_) && pipeline_) drain_windows(*pipeline_);
  snapshot_.history_enabled = history_ != nullptr;
  if (history_) {
    const HistoryCounters& hk = history_->counters();
    snapshot_.history_lines = hk.lines;
    snapshot_.history_write_failures = hk.write_failures;
    snapshot_.history_rotation_failures = hk.rotation_failures;
    snapshot_.history_windows_dropped = hk.ring_dropped;
    snapshot_.history_last_errno = hk.last_errno;
  }
  if (pipeline_) log_alarm_changes(*pipeline_);
  if (mqtt_ && pipeline_) mqtt_state(pipeline_->status());
  snapshot_.mqtt = mqtt_ ? mqtt_->stats() : MqttStats{};
  snapshot_.state_files[static_cast<std::size_t>(StateFile::kBaseline)] = baseline_health_;
  if (writer_) {
    if (writer_->write(snapshot_) == StatusWriteResult::kOk)
      status_writes_.fetch_add(1, std::memory_order_relaxed);
    status_write_failures_.store(writer_->health(StateFile::kStatus).failures, std::memory_order_relaxed);
    log_status_write_changes();
  }
  Pipeline* p = pipeline_.get();
  if (p != nullptr) {
    const PipelineStatus ps = p->status();
    std::snprintf(
        status_text_, sizeof status_text_, "%s (%s): %llu windows, %llu judged, %llu abnormal, alarm %s%s%s",
        daemon_state_name(snapshot_.state).data(), phase_name(ps.phase),
        static_cast<unsigned long long>(ps.windows), static_cast<unsigned long long>(ps.scored),
        static_cast<unsigned long long>(ps.abnormal), drivers::alarm_level_name(ps.report.level).data(),
        snapshot_.reason.len > 0 ? "; " : "", snapshot_.reason.text.data());
    notifier_.status(status_text_);
    // Field training: the last windows may still be on their way to the spill file; exit once
    // check_training has seen the end with all of them written (and trained, when it could).
    if (options_.exit_at_end && ps.ended && (p->trainer() == nullptr || training_end_seen_)) {
      spdlog::info("replay ended: {} windows processed, stopping (--exit-at-end)", ps.windows);
      stop_requested_.store(true);
    }
    if (options_.exit_after_windows > 0 && ps.windows >= options_.exit_after_windows) {
      spdlog::info("{} windows processed, stopping (--exit-after-windows)", ps.windows);
      stop_requested_.store(true);
    }
    if (options_.stall_processing_after_s >= 0.0 &&
        now - started_ns_ >= seconds_to_ns(options_.stall_processing_after_s) &&
        !stall_.load(std::memory_order_relaxed)) {
      spdlog::warn("test hook: stalling the processing thread");
      stall_.store(true);
      p->set_processing_stall(true);
    }
  }
  log_counter_changes();
}

int Daemon::run() {
  const std::int64_t status_period = seconds_to_ns(cfg_.daemon.status_period_s);
  const std::int64_t ping_period = options_.watchdog.enabled ? options_.watchdog.ping_period_ns : 0;
  std::int64_t now = clock_.now_ns();
  std::int64_t next_status = now + status_period;
  std::int64_t next_ping = ping_period > 0 ? now + ping_period : INT64_MAX;
  while (!stop_requested_.load(std::memory_order_acquire)) {
    now = clock_.now_ns();
    const std::int64_t wait_ns = std::max<std::int64_t>(0, std::min(next_status, next_ping) - now);
    pollfd fds[2] = {{signal_fd_, POLLIN, 0}, {event_fd_, POLLIN, 0}};
    const int rc = ::poll(fds, 2, static_cast<int>((wait_ns + 999'999) / 1'000'000));
    if (rc > 0 && (fds[0].revents & POLLIN) != 0) {
      signalfd_siginfo si{};
      while (::read(signal_fd_, &si, sizeof si) == static_cast<ssize_t>(sizeof si)) {
        if (si.ssi_signo == SIGHUP) {
          reload_requested_.store(true);
        } else if (si.ssi_signo == SIGUSR1) {
          spdlog::info("SIGUSR1 received: clear request for a latched alarm");
          request_clear();
        } else {
          spdlog::info("{} received: stopping", si.ssi_signo == SIGTERM ? "SIGTERM" : "SIGINT");
          stop_requested_.store(true);
        }
      }
    }
    if (rc > 0 && (fds[1].revents & POLLIN) != 0) {
      std::uint64_t v = 0;
      [[maybe_unused]] const auto n = ::read(event_fd_, &v, sizeof v);
      // Woken by the processing thread for a level change: its MQTT event goes to the publisher (and
      // from there to the disk queue) now, not at the next status period (docs/fleet.md, kill -9).
      if (pipeline_) {
        if (history_ || mqtt_) drain_windows(*pipeline_);
        log_alarm_changes(*pipeline_);
      }
    }
    if (stop_requested_.load(std::memory_order_acquire)) break;
    if (reload_requested_.exchange(false)) {
      reload();
      now = clock_.now_ns();
      next_status = now;
      if (ping_period > 0) next_ping = std::min(next_ping, now + ping_period);
    }
    now = clock_.now_ns();
    if (now >= next_ping) {
      check_watchdog(now);
      next_ping = std::max(next_ping + ping_period, now + ping_period / 2);
    }
    if (now >= next_status) {
      supervise(now);
      next_status = std::max(next_status + status_period, now + status_period / 2);
    }
  }
  notifier_.stopping();
  state_.store(DaemonState::kStopping);
  spdlog::info("stopping");
  deactivate();
  now = clock_.now_ns();
  update_state_and_reason(now);
  if ((history_ || mqtt_) && pipeline_) drain_windows(*pipeline_);
  if (pipeline_) log_alarm_changes(*pipeline_);  // the changes since the last status period
  if (mqtt_ && pipeline_) mqtt_state(pipeline_->status());
  state_.store(DaemonState::kStopping);
  fill_snapshot(now);
  if (writer_) writer_->write(snapshot_);
  spdlog::info("stopped");
  return exit_code_;
}

}  // namespace ptda::daemon
