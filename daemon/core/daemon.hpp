// ptdad's lifecycle and supervisor (the main thread).
//
//   constructed ──configure()──▶ configured ──activate()──▶ running ──(SIGTERM/SIGINT, request_stop)──▶
//   stopping ──deactivate()──▶ deactivated
//
//   configured  the configuration files were read and validated, the Pipeline was configured (devices
//               opened, baseline read: a bad baseline means "refused", not an error), the status
//               writer and the sd_notify socket exist, SIGTERM/SIGINT/SIGHUP are blocked in this
//               thread (and so in every thread started later) and read through a signalfd.
//   running     the pipeline threads run; run() is the supervisor: it waits in poll() on the signalfd
//               and an eventfd, and every [daemon] status_period_s writes status.json/metrics, sends
//               STATUS=, logs state and counter changes; every WatchdogSec/2 it sends WATCHDOG=1 only
//               when every stage's heartbeat advanced since the previous ping. READY=1 is sent by
//               activate(). SIGHUP reloads (see reload()). In the running state the supervisor does
//               not allocate (fixed buffers; spdlog formats short lines in place), except while
//               reloading or in training mode (progress and the final training allocate).
//   stopping    STOPPING=1 was sent; deactivate() joins the threads (they re-check their stop flag
//               every kStageWaitNs) and drives the outputs fail-safe.
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "core/daemon_config.hpp"
#include "core/pipeline.hpp"
#include "mqtt/mqtt_publisher.hpp"
#include "ptda/drivers/clock.hpp"
#include "rt/sd_notify.hpp"
#include "status/history_log.hpp"
#include "status/status_writer.hpp"

namespace ptda::daemon {

struct DaemonOptions {
  std::filesystem::path config_file = "/etc/ptda/ptda.toml";
  /// Drop-in directory; unset = "<directory of config_file>/conf.d"; an empty path = none.
  std::optional<std::filesystem::path> config_dir;
  bool train = false;                ///< field training mode (--train)
  std::filesystem::path status_dir;  ///< non-empty: overrides [daemon] status_dir
  std::string joint;                 ///< non-empty: overrides [daemon] joint (ptdad@.service: the instance)
  std::string notify_socket;         ///< $NOTIFY_SOCKET ("" = not under systemd)
  WatchdogSettings watchdog;         ///< from $WATCHDOG_USEC / $WATCHDOG_PID
  bool exit_at_end = false;          ///< stop (exit 0) once a replay ended and was processed
  // Test-only hooks (documented as such in docs/daemon.md and `ptdad --help`).
  std::uint64_t exit_after_windows = 0;    ///< stop after this many processed windows (0 = never)
  double stall_processing_after_s = -1.0;  ///< stall the processing thread after this long (< 0 = never)
};

/// What tests and tools can observe from another thread. Fixed size; copying never allocates.
struct DaemonView {
  DaemonState state = DaemonState::kConfigured;
  Phase phase = Phase::kStarting;
  FixedString<kStatusTextBytes> reason;
  PipelineStatus pipeline;
  PipelineCounters counters;
  StageHeartbeats heartbeats;
  WakeSchedule wake;                  ///< how the stages schedule their wake-ups (real-time pace)
  std::uint64_t reloads = 0;          ///< successful reloads
  std::uint64_t reload_failures = 0;  ///< rejected reloads (old configuration kept)
  std::uint64_t watchdog_pings = 0;
  std::uint64_t watchdog_skipped = 0;  ///< pings withheld because a stage made no progress
  std::uint64_t status_writes = 0;
  std::uint64_t status_write_failures = 0;  ///< failed status.json write attempts (StateFileHealth)
  std::uint64_t local_clears = 0;           ///< local clear commands (SIGUSR1, request_clear())
  std::uint32_t window_len = 0;             ///< of the configuration in use
  double min_hold_s = 0.0;                  ///< of the configuration in use
};

class Daemon {
 public:
  /// `clock` must outlive the daemon (MonotonicClock in ptdad). Thread: main. Allocates.
  Daemon(DaemonOptions options, drivers::Clock& clock);
  ~Daemon();
  Daemon(const Daemon&) = delete;
  Daemon& operator=(const Daemon&) = delete;

  /// Reads the configuration and configures everything (see the header comment). Throws ptda::Error
  /// "<file>:<line>:<column>: <what>" or "<device>: <what>". Thread: main. Blocks and allocates.
  void configure();
  /// Starts the pipeline threads, sends READY=1 and a first STATUS=. Throws ptda::Error.
  /// Thread: the thread that called configure().
  void activate();
  /// The supervisor loop until a stop (signal, request_stop, exit hooks). Returns the exit code:
  /// 0 after a requested stop, 1 when a reload left no working pipeline. Sends STOPPING=1 and
  /// deactivates before returning. Thread: the thread that called configure(). Blocks.
  int run();
  /// Stops the pipeline (idempotent). Thread: main. Never throws.
  void deactivate() noexcept;

  /// Thread: any (signal-safe: one atomic store and one write()). Never blocks or allocates.
  void request_stop() noexcept;
  /// Asks the supervisor to reload the configuration (as SIGHUP). Thread: any. Never blocks.
  void request_reload() noexcept;

  /// Test hook: receives every processed window of this and every later pipeline (processing thread).
  /// Set before configure(). Thread: main.
  void set_window_sink(WindowSink* sink) noexcept { sink_ = sink; }
  /// Benchmark hook: the latency probe of this and every later pipeline (see PipelineProbe). Set
  /// before configure(). Thread: main.
  void set_probe(PipelineProbe* probe) noexcept { probe_ = probe; }
  /// Test-only hook: the devices of this and every later pipeline (see DeviceFactory). Set before
  /// configure(). Thread: main.
  void set_device_factory(DeviceFactory* f) noexcept { factory_ = f; }
  /// Test-only hook: called by the supervisor right before field training writes the baseline (e.g. to
  /// send SIGTERM at that moment). Set before activate(). Thread: main.
  void set_before_baseline_write(void (*hook)(void*), void* arg) noexcept {
    before_write_ = hook;
    before_write_arg_ = arg;
  }
  /// Local operator clear of a latched alarm (as SIGUSR1): posted to the alarm manager, which accepts
  /// it only when the hold time passed and the condition is gone. Thread: any. Never blocks or allocates.
  void request_clear() noexcept;
  /// Test-only fault injection (see Pipeline::set_processing_stall). Thread: any.
  void set_processing_stall(bool stall) noexcept;

  /// A consistent-enough snapshot for tests and tools. Thread: any. Never allocates; takes a mutex
  /// only to pin the current pipeline against a concurrent reload.
  [[nodiscard]] DaemonView view() const noexcept;
  /// The configuration in use. Thread: main (the supervisor), or any while run() is not running.
  [[nodiscard]] const DaemonConfig& config() const noexcept { return cfg_; }

 private:
  [[nodiscard]] DaemonConfig load_config() const;
  void build_status_writer();
  void reload();
  void supervise(std::int64_t now) noexcept;
  void check_watchdog(std::int64_t now) noexcept;
  void check_training(std::int64_t now);
  void fill_snapshot(std::int64_t now) noexcept;
  void update_state_and_reason(std::int64_t now) noexcept;
  void log_counter_changes() noexcept;
  void log_status_write_changes() noexcept;
  void build_history();  ///< history_ from cfg_ ([history])
  void history_state(const PipelineStatus& ps, const char* reason) noexcept;  ///< a state line
  void history_state(const PipelineStatus& ps, const char* reason, drivers::AlarmLevel level,
                     std::uint8_t causes) noexcept;
  /// Every level change `p` recorded since the last call: log line, history line, MQTT event each.
  void log_alarm_changes(Pipeline& p) noexcept;
  void report_level_change(const LevelChange& c, const PipelineStatus& ps, std::uint64_t missed) noexcept;
  void build_mqtt();                                   ///< mqtt_ from cfg_ ([mqtt]); keeps an unchanged one
  void drain_windows(Pipeline& p) noexcept;            ///< the window log into history and MQTT
  void mqtt_state(const PipelineStatus& ps) noexcept;  ///< a state event when state/phase/level changed
  void mqtt_alarm(const LevelChange& c, const char* causes) noexcept;  ///< an alarm/fault event
  void restart_pipeline(const DaemonConfig& cfg, PipelineMode mode);

  DaemonOptions options_;
  drivers::Clock& clock_;
  DaemonConfig cfg_;
  WindowSink* sink_ = nullptr;
  PipelineProbe* probe_ = nullptr;
  DeviceFactory* factory_ = nullptr;
  void (*before_write_)(void*) = nullptr;
  void* before_write_arg_ = nullptr;
  std::atomic<std::uint64_t> local_clears_{0};  ///< SIGUSR1 / request_clear() calls
  PipelineMode mode_ = PipelineMode::kMonitor;

  mutable std::mutex pipeline_mutex_;  ///< guards the pipeline_ pointer (swapped by reloads)
  std::unique_ptr<Pipeline> pipeline_;
  std::unique_ptr<StatusWriter> writer_;
  std::unique_ptr<HistoryLog> history_;  ///< [history] dir set; written by the supervisor
  dsp::WindowResult history_window_;     ///< drain_windows()'s buffer (not on the stack: ~300 bytes)
  std::unique_ptr<MqttPublisher> mqtt_;  ///< [mqtt] enabled; events posted by the supervisor
  MqttEvent mqtt_event_;                 ///< the supervisor's event buffer (not on the stack)
  std::int64_t mqtt_next_summary_ns_ = INT64_MIN;  ///< window end (daemon clock) of the next summary
  DaemonState mqtt_last_state_ = DaemonState::kConfigured;
  Phase mqtt_last_phase_ = Phase::kStarting;
  drivers::AlarmLevel mqtt_last_level_ = drivers::AlarmLevel::kFault;
  bool mqtt_state_sent_ = false;
  SdNotifier notifier_;
  int signal_fd_ = -1;
  int event_fd_ = -1;
  std::atomic<bool> stop_requested_{false};
  std::atomic<bool> reload_requested_{false};
  std::atomic<bool> stall_{false};
  bool active_ = false;
  int exit_code_ = 0;

  // Supervisor state (main thread).
  std::int64_t started_ns_ = 0;
  StageHeartbeats last_ping_beats_{};
  StageHeartbeats last_seen_beats_{};
  std::int64_t beat_changed_ns_[3] = {0, 0, 0};
  bool stalled_logged_ = false;
  std::int64_t training_started_ns_ = 0;
  bool training_end_seen_ = false;  ///< check_training saw the replay's end with every window written
  std::uint64_t training_spill_problems_ = 0;  ///< spill write failures and queue-full drops logged so far
  std::unique_ptr<FieldTrainer> carried_trainer_;   ///< the pool across a reload during training
  FixedString<kStatusTextBytes> training_note_;     ///< what the last reload did to the pool
  StateFileHealth baseline_health_;                 ///< field training's baseline writes
  std::uint32_t baseline_consecutive_ = 0;          ///< failed baseline writes in a row
  std::int64_t baseline_retry_ns_ = 0;              ///< no new attempt before (backoff)
  bool status_failing_logged_[2] = {false, false};  ///< StateFile::kStatus, kMetrics
  StatusSnapshot snapshot_;
  PipelineCounters last_counters_{};
  drivers::SampleSourceCounters last_source_{};
  dsp::SlicerCounters last_slicer_{};
  Phase last_phase_ = Phase::kStarting;
  drivers::AlarmLevel last_level_ = drivers::AlarmLevel::kFault;  ///< the last level change reported
  std::uint64_t last_level_changes_ = 0;  ///< its LevelChange::number (0: none of this pipeline yet)
  LevelChange level_change_;              ///< log_alarm_changes()'s buffer (not on the stack)
  DaemonState last_state_ = DaemonState::kConfigured;
  FixedString<kStatusTextBytes> reason_;
  FixedString<kStatusTextBytes> last_reload_error_;
  std::atomic<DaemonState> state_{DaemonState::kConfigured};
  std::atomic<std::uint64_t> reloads_{0}, reload_failures_{0}, pings_{0}, pings_skipped_{0},
      status_writes_{0}, status_write_failures_{0};
  mutable std::mutex reason_mutex_;  ///< guards reason_ for view()
  char status_text_[kStatusTextBytes + 160] = {};
};

}  // namespace ptda::daemon
