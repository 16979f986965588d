// The daemon's externally visible state: a plain StatusSnapshot (filled by the supervisor from the
// stages' counters) rendered as `status.json` and as a Prometheus text-format file for the
// node_exporter textfile collector, into fixed buffers, and replaced atomically (temporary file in the
// same directory + rename, so a reader never sees a partial file).
//
// JSON layout (keys in this order; times are seconds as decimals, feature values %.9g, strings escaped
// per RFC 8259 with \" \\ \b \f \n \r \t and \u00XX for other control characters, NUL included, and
// each ill-formed UTF-8 sequence replaced by U+FFFD: status/text_escape.hpp):
//   {"version":1,"state":..,"phase":..,"reason":..,"uptime_s":..,"now_s":..,"now_utc":..,
//    "wall_time_unix_ns":..,"method":..,"baseline":{"loaded":..,"path":..,"fs_hz":..,"window_len":..,"source":..,"classes":[{...}]},
//    "last_window":{...}|null,"alarm":{...},"coverage":{...}|null,"training":{...}|null,
//    "acquisition":{...},"can":{...},"slicer":{...},"pipeline":{...},"state_files":{...}}
// Prometheus (text exposition format 0.0.4): `# HELP` and `# TYPE` for every metric family, names
// `ptda_*`, `_total` for counters, units in names (`_seconds`, `_hertz`, `_radians_per_second`),
// label values escaped (\\ \" \n; ill-formed UTF-8 and NUL become U+FFFD). docs/systemd.md ("Status
// files") lists every metric.
// Times: every `*_s` time is on the daemon's status timeline (now_s; see StatusSnapshot::now_s), every
// age/duration is now_s minus such a time (never negative), every `*_utc` is RFC 3339 UTC text with
// milliseconds ("2026-11-25T04:31:07.250Z"), null when unknown.
#pragma once

#include <sys/types.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "ptda/drivers/alarm_output.hpp"
#include "ptda/drivers/can_channel.hpp"
#include "ptda/dsp/coverage.hpp"

namespace ptda::daemon {

/// A NUL-terminated string in a fixed array; assign() truncates (at a byte boundary) instead of
/// allocating. Trivially copyable.
template <std::size_t N>
struct FixedString {
  static_assert(N >= 1);
  std::array<char, N> text{};
  std::uint32_t len = 0;
  /// Thread: any. Never allocates.
  void assign(std::string_view s) noexcept {
    const std::size_t n = s.size() < N - 1 ? s.size() : N - 1;
    for (std::size_t i = 0; i < n; ++i) text[i] = s[i];
    text[n] = '\0';
    len = static_cast<std::uint32_t>(n);
  }
  [[nodiscard]] std::string_view view() const noexcept { return {text.data(), len}; }
};

/// The MQTT publisher's state for status.json and the metrics (mqtt/mqtt_publisher.hpp). Trivially copyable.
struct MqttStats {
  bool enabled = false;
  bool connected = false;
  std::uint64_t queue_bytes = 0;
  std::uint64_t queue_pending = 0;          ///< alarms, faults, states not yet acknowledged
  std::uint64_t summary_queue_pending = 0;  ///< window summaries not yet acknowledged (own queue)
  std::uint64_t dropped_event = 0;    ///< undelivered alarms, faults, states removed from the full queue
  std::uint64_t dropped_summary = 0;  ///< oldest undelivered window summaries removed from their full queue
  std::uint64_t dropped_handoff = 0;  ///< events the hand-over ring could not hold
  std::uint64_t dropped_io = 0;       ///< events the queue could not append (I/O error)
  std::uint64_t published = 0;        ///< PUBACKed queued events and summaries
  std::uint64_t connect_failures = 0;
  std::uint64_t alarm_durable_us_last = 0;  ///< level change recorded -> its queue record fsync'ed
  std::uint64_t alarm_durable_us_max = 0;   ///< the largest since the publisher started
  FixedString<256> last_error;
};

enum class DaemonState : std::uint8_t {
  kConfigured = 0,  ///< configured, not yet running
  kRunning = 1,     ///< monitoring
  kPaused = 2,      ///< inputs held (e.g. robot in maintenance), outputs in fault
  kRefused = 3,     ///< cannot monitor: baseline refused / missing, see reason
  kTraining = 4,    ///< field training mode
  kStopping = 5,
  kEnded = 6,  ///< a replay ended and every window was processed (not a fault of the input)
};

[[nodiscard]] constexpr std::string_view daemon_state_name(DaemonState s) noexcept {
  switch (s) {
    case DaemonState::kConfigured:
      return "configured";
    case DaemonState::kRunning:
      return "running";
    case DaemonState::kPaused:
      return "paused";
    case DaemonState::kRefused:
      return "refused";
    case DaemonState::kTraining:
      return "training";
    case DaemonState::kStopping:
      return "stopping";
    case DaemonState::kEnded:
      return "ended";
  }
  return "?";
}

[[nodiscard]] constexpr std::string_view can_bus_state_name(drivers::CanBusState s) noexcept {
  switch (s) {
    case drivers::CanBusState::kErrorActive:
      return "error_active";
    case drivers::CanBusState::kErrorWarning:
      return "error_warning";
    case drivers::CanBusState::kErrorPassive:
      return "error_passive";
    case drivers::CanBusState::kBusOff:
      return "bus_off";
  }
  return "?";
}

/// The files the daemon writes: status.json, the Prometheus textfile, the baseline (field training).
enum class StateFile : std::uint8_t { kStatus = 0, kMetrics = 1, kBaseline = 2 };
inline constexpr std::size_t kStateFileCount = 3;

[[nodiscard]] constexpr std::string_view state_file_name(StateFile f) noexcept {
  switch (f) {
    case StateFile::kStatus:
      return "status";
    case StateFile::kMetrics:
      return "metrics";
    case StateFile::kBaseline:
      return "baseline";
  }
  return "?";
}

/// Write failures of one state file (status.json "state_files", ptda_state_write_* metrics).
struct StateFileHealth {
  std::uint64_t failures = 0;   ///< failed write attempts (retries the backoff skips are not attempts)
  std::int32_t last_errno = 0;  ///< errno of the latest failure (0: never failed)
  const char* last_step = "";   ///< its step ("open of the temporary file", "write", "rename", ...)
  bool failing = false;         ///< the latest attempt failed (retried with backoff)
};

inline constexpr std::size_t kStatusMaxClasses = 16;  ///< classes beyond this are not listed
inline constexpr std::size_t kStatusTextBytes = 256;  ///< room for the coverage text and a suffix
inline constexpr std::size_t kStatusPathBytes = 256;

struct StatusClass {
  std::uint32_t id = 0;
  std::int8_t direction = 1;
  double speed_rad_s = 0.0;
  double duration_s = 0.0;
  std::uint32_t regions = 0;
  std::uint32_t n_windows = 0;
  double rms_lo = 0.0, rms_hi = 0.0;  ///< band of the method in use
  double entropy_lo = 0.0, entropy_hi = 0.0;
};

struct StatusSnapshot {
  // Daemon.
  DaemonState state = DaemonState::kConfigured;
  FixedString<kStatusTextBytes> reason;  ///< why (refused: which check; paused: by whom); may be empty
  FixedString<16> method;                ///< "ptda" / "tda" / "raw"
  FixedString<32> phase;  ///< what the processing stage is doing ("monitoring", "replay ended", ...)
  double uptime_s = 0.0;
  /// Seconds on the status timeline when the snapshot was taken: the daemon's monotonic clock, or the
  /// newest data time when the data runs ahead of it (a fast replay stamps data at the replay's pace:
  /// the window and alarm times below are then data times). Every age is now_s minus a time.
  double now_s = 0.0;
  std::int64_t wall_time_unix_ns = 0;  ///< CLOCK_REALTIME when the snapshot was taken (0 = unknown)

  // Baseline.
  bool baseline_loaded = false;
  FixedString<kStatusPathBytes> baseline_path;
  FixedString<kStatusTextBytes> baseline_source;
  double baseline_fs_hz = 0.0;
  std::uint32_t baseline_window_len = 0;
  std::uint32_t class_count = 0;  ///< classes in the baseline (may exceed classes.size())
  std::array<StatusClass, kStatusMaxClasses> classes{};
  std::uint32_t classes_listed = 0;  ///< valid entries of `classes`

  // Last scored window.
  bool have_window = false;
  double window_t_s = 0.0;          ///< its end, status-timeline seconds
  std::int64_t window_wall_ns = 0;  ///< the same instant, unix ns (0 = unknown)
  std::int32_t window_class = -1;
  double window_speed_rad_s = 0.0;
  double window_rms = 0.0, window_entropy = 0.0;
  double window_rms_lo = 0.0, window_rms_hi = 0.0;
  double window_entropy_lo = 0.0, window_entropy_hi = 0.0;
  bool window_rms_out = false, window_entropy_out = false;
  std::uint32_t window_abnormal_in_last_n = 0;

  // Alarm.
  drivers::AlarmLevel alarm_level = drivers::AlarmLevel::kFault;
  double alarm_since_s = 0.0;            ///< when the level was entered, status-timeline seconds
  std::int64_t alarm_since_wall_ns = 0;  ///< the same instant, unix ns (0 = unknown)
  bool alarm_latched = false;
  std::uint8_t alarm_causes = 0;  ///< AlarmCause bits
  std::int32_t trip_class = -1;   ///< the window that raised the alarm (-1: none)
  double trip_rms = 0.0, trip_entropy = 0.0;
  double trip_t_s = 0.0;
  const char* trip_detector = "none";  ///< dsp::alarm_detector_name of the trip window
  double trip_cusum = 0.0;             ///< largest class CUSUM at the trip window
  bool trip_band_on = false;           ///< the band CUSUM runs: the three fields below are written
  double trip_band_cusum = 0.0;        ///< largest band CUSUM at the trip window
  std::int32_t trip_band = -1;         ///< its band (-1: none)
  double trip_band_lo_hz = 0.0, trip_band_hi_hz = 0.0;  ///< its frequency range
  bool trip_mesh_on = false;               ///< the mesh CUSUM runs: the two fields below are written
  double trip_mesh_cusum = 0.0;            ///< largest mesh CUSUM at the trip window
  const char* trip_mesh_feature = "none";  ///< its feature (dsp::mesh_feature_label: "am", "pm", "none")
  std::int64_t trip_wall_ns = 0;           ///< unix ns (0 = unknown)

  // Field training (state == kTraining).
  std::uint64_t training_windows = 0;
  std::uint64_t training_capacity = 0;
  std::uint64_t training_regions = 0;
  std::uint32_t training_classes = 0;
  std::uint32_t training_classes_complete = 0;
  std::uint32_t training_target_cycles = 0;
  std::uint64_t training_dropped = 0;             ///< windows/regions beyond the pool
  std::uint64_t training_spill_write_failed = 0;  ///< windows the spill file refused (in training_dropped)
  std::uint64_t training_spill_queue_full = 0;    ///< windows dropped while the writer was behind (ditto)
  std::int32_t training_spill_errno = 0;          ///< the last failed spill write's errno (0: none)

  // Acquisition.
  std::uint64_t acq_blocks = 0, acq_samples = 0, acq_gaps = 0, acq_lost_samples = 0;
  std::uint64_t acq_short_reads = 0, acq_time_back = 0, acq_timeouts = 0, acq_read_errors = 0;
  // CAN.
  std::uint64_t can_frames = 0, can_speed_frames = 0, can_other_ids = 0, can_wrong_dlc = 0;
  std::uint64_t can_remote_frames = 0;  ///< RTR frames with the speed id
  std::uint64_t can_error_frames = 0, can_rx_overflow_drops = 0, can_bus_off = 0;
  drivers::CanBusState can_bus_state = drivers::CanBusState::kErrorActive;
  // Slicer.
  std::uint64_t slicer_regions = 0, slicer_windows = 0, slicer_windows_invalid = 0;
  std::uint64_t slicer_windows_lost = 0;
  // Pipeline.
  std::uint64_t ring_overflows = 0;
  std::uint64_t windows_scored = 0, windows_abnormal = 0;
  std::uint64_t alarms_raised = 0;
  std::uint64_t level_changes_dropped = 0;  ///< AlarmCounters::level_changes_dropped (LevelChangeRing full)
  std::uint64_t watchdog_pings = 0;

  // Coverage (monitoring with a baseline): judged and unmatched windows, motion since the last judgement.
  bool coverage_known = false;  ///< false: "coverage" is null and its metrics are left out
  double coverage_timeout_s = 0.0;
  dsp::CoverageState coverage;

  // Event history ([history], docs/fleet.md): false when off ("history" is null, no metrics).
  /// Order domain ([extraction] domain = "order"): the angle resampler's and window cutter's counters,
  /// status.json "order" and ptda_order_* metrics. Absent (not null) in the time domain, whose files
  /// stay as they were.
  bool order_domain = false;
  std::uint64_t order_frames = 0, order_frames_no_angle = 0, order_frames_out_of_order = 0;
  std::uint64_t order_frames_overflow = 0, order_angle_inconsistent = 0, order_breaks = 0;
  std::uint64_t order_samples_unused = 0, order_samples_overrun = 0, order_outputs = 0;
  std::uint64_t order_outputs_dropped = 0, order_windows = 0;
  bool history_enabled = false;
  std::uint64_t history_lines = 0;              ///< lines written
  std::uint64_t history_write_failures = 0;     ///< lines lost to failed opens/writes (counted)
  std::uint64_t history_rotation_failures = 0;  ///< the current file could not be moved aside
  std::uint64_t history_windows_dropped = 0;    ///< windows the hand-over ring could not hold
  std::int32_t history_last_errno = 0;
  // MQTT ([mqtt] enabled): "mqtt" is null and no ptda_mqtt_* metrics when off.
  MqttStats mqtt;

  // Write failures of the state files, indexed by StateFile. The daemon fills the baseline entry;
  // StatusWriter::write() fills status and metrics from its own health (render_* print these).
  std::array<StateFileHealth, kStateFileCount> state_files{};
};

/// RFC 3339 UTC text with milliseconds ("2026-11-25T04:31:07.250Z", 24 characters) of a unix time in
/// ns into `out`; returns the length, 0 when `cap` < 25 or the time is before 1970 or after 9999.
/// Thread: any. Never allocates (gmtime_r, no time zone lookup).
std::size_t format_rfc3339_utc(std::int64_t unix_ns, char* out, std::size_t cap) noexcept;

/// Appends text into a fixed char buffer; on overflow it stops writing and remembers it.
class TextBuffer {
 public:
  TextBuffer(char* data, std::size_t capacity) noexcept : data_(data), cap_(capacity) {}
  void append(std::string_view s) noexcept;
  void append_char(char c) noexcept;
  void append_u64(std::uint64_t v) noexcept;
  void append_i64(std::int64_t v) noexcept;
  /// %.9g; non-finite values are written as `null_text` (JSON: "null"; Prometheus: NaN/+Inf/-Inf when
  /// null_text is empty).
  void append_double(double v, std::string_view null_text) noexcept;
  /// A JSON string literal with quotes (RFC 8259 escaping, valid UTF-8: status/text_escape.hpp).
  void append_json_string(std::string_view s) noexcept;
  /// A Prometheus label value without quotes (escapes \\, \" and \n; valid UTF-8, NUL replaced:
  /// status/text_escape.hpp).
  void append_label_value(std::string_view s) noexcept;
  [[nodiscard]] bool overflow() const noexcept { return overflow_; }
  [[nodiscard]] std::size_t size() const noexcept { return len_; }
  [[nodiscard]] std::string_view view() const noexcept { return {data_, len_}; }
  void clear() noexcept {
    len_ = 0;
    overflow_ = false;
  }

 private:
  using EscapeFn = std::size_t (*)(std::string_view, char*, std::size_t) noexcept;
  void append_escaped(EscapeFn escape, std::string_view s) noexcept;
  char* data_;
  std::size_t cap_;
  std::size_t len_ = 0;
  bool overflow_ = false;
};

/// Seconds with millisecond resolution ("%.3f"); JSON null when not finite. Never allocates.
void append_seconds(TextBuffer& b, double s) noexcept;

/// Writes JSON into a TextBuffer: objects, arrays and typed members (status.json, the event history).
/// Thread: the buffer's owner. Never allocates.
class JsonWriter {
 public:
  explicit JsonWriter(TextBuffer& b) noexcept : b_(b) {}
  void open(char c) noexcept {
    b_.append_char(c);
    first_ = true;
  }
  void close(char c) noexcept {
    b_.append_char(c);
    first_ = false;
  }
  void key(std::string_view k) noexcept {
    if (!first_) b_.append_char(',');
    first_ = false;
    b_.append_json_string(k);
    b_.append_char(':');
  }
  void item() noexcept {
    if (!first_) b_.append_char(',');
    first_ = false;
  }
  void str(std::string_view k, std::string_view v) noexcept {
    key(k);
    b_.append_json_string(v);
  }
  void u64(std::string_view k, std::uint64_t v) noexcept {
    key(k);
    b_.append_u64(v);
  }
  void i64(std::string_view k, std::int64_t v) noexcept {
    key(k);
    b_.append_i64(v);
  }
  void num(std::string_view k, double v) noexcept {
    key(k);
    b_.append_double(v, "null");
  }
  void secs(std::string_view k, double v) noexcept {
    key(k);
    append_seconds(b_, v);
  }
  void boolean(std::string_view k, bool v) noexcept {
    key(k);
    b_.append(v ? "true" : "false");
  }
  void band(std::string_view k, double lo, double hi) noexcept {
    key(k);
    b_.append_char('[');
    b_.append_double(lo, "null");
    b_.append_char(',');
    b_.append_double(hi, "null");
    b_.append_char(']');
  }
  void null(std::string_view k) noexcept {
    key(k);
    b_.append("null");
  }
  /// RFC 3339 UTC text of a unix time in ns; null when unknown (0).
  void utc(std::string_view k, std::int64_t unix_ns) noexcept {
    char buf[32];
    const std::size_t n = unix_ns > 0 ? format_rfc3339_utc(unix_ns, buf, sizeof buf) : 0;
    if (n == 0) {
      null(k);
    } else {
      str(k, std::string_view(buf, n));
    }
  }

 private:
  TextBuffer& b_;
  bool first_ = true;
};

struct StatusWriterConfig {
  std::filesystem::path json_path;       ///< empty = no JSON file (e.g. /run/ptda/status.json)
  std::filesystem::path prom_path;       ///< empty = none; must end in ".prom" (e.g. .../ptda.prom)
  std::size_t buffer_bytes = 64 * 1024;  ///< per format
  /// When a file's directory is missing (deleted under the running daemon), it is created again with
  /// this mode (set with fchmod, whatever the umask); only the last path component. 0 = never.
  mode_t recreate_dir_mode = 0755;
  /// The monitored joint's name ([daemon] joint, e.g. "joint4"): "joint" in status.json and the label
  /// joint="..." on every metric sample, so several daemons of one cabinet can share node_exporter's
  /// textfile directory. "" = neither (one joint per cabinet).
  std::string joint;
};

/// Consecutive failures of a file make write() skip it for 2^(n-1) - 1 calls, at most this many.
inline constexpr std::uint32_t kStatusMaxSkippedWrites = 15;

enum class StatusWriteResult : std::uint8_t {
  kOk = 0,
  kOverflow = 1,  ///< a rendering did not fit its buffer: that file was not replaced
  kIoError = 2,   ///< open/write/rename failed or skipped by the backoff: that file was not replaced
};

struct StatusWriterCounters {
  std::uint64_t writes = 0;     ///< write() calls
  std::uint64_t overflows = 0;  ///< renderings that did not fit
  std::uint64_t io_errors = 0;
  std::uint64_t dirs_recreated = 0;  ///< missing directories created again
};

class StatusWriter {
 public:
  /// Allocates both buffers and the path strings. Throws ptda::Error ("status: ...") when a
  /// prom path does not end in ".prom", the buffer is smaller than 1 KiB, or both paths are empty.
  /// Does not touch the file system. Thread: any (setup). Allocates.
  explicit StatusWriter(const StatusWriterConfig& cfg);

  /// Renders into the fixed buffers; the returned view stays valid until the next render/write.
  /// An overflow returns an empty view and is counted. Thread: the one writer thread (supervisor).
  /// Never allocates or blocks.
  std::string_view render_json(const StatusSnapshot& s) noexcept;
  std::string_view render_prometheus(const StatusSnapshot& s) noexcept;

  /// Renders both and replaces each configured file with ptda::write_file_atomic (a temporary
  /// "<path>.tmp-<random>" created O_EXCL|O_NOFOLLOW, fchmod 0644, rename; no fsync: the files live in
  /// /run and are rewritten every few seconds). A missing directory is created again (see
  /// recreate_dir_mode); a file whose writes keep failing is retried with backoff (see
  /// kStatusMaxSkippedWrites). Returns the worst result. Thread: the supervisor. Blocks on file I/O;
  /// never allocates.
  StatusWriteResult write(const StatusSnapshot& s) noexcept;

  /// errno of the latest failed write of either file.
  [[nodiscard]] int last_errno() const noexcept { return last_errno_; }
  /// Thread: the writer thread.
  [[nodiscard]] StatusWriterCounters counters() const noexcept { return counters_; }
  /// Failures of status.json (StateFile::kStatus) or the metrics file (kMetrics); kBaseline: empty.
  /// Thread: the writer thread. Never allocates.
  [[nodiscard]] StateFileHealth health(StateFile f) const noexcept;
  /// The configured path of a file ("" when not configured). Thread: any.
  [[nodiscard]] const std::string& path(StateFile f) const noexcept {
    return f == StateFile::kStatus ? json_.path : prom_.path;
  }

 private:
  struct Target {
    std::string path, dir, name;  ///< dir "" = the current directory
    StateFileHealth health;
    std::uint64_t consecutive = 0;  ///< failed attempts in a row
    std::uint32_t skip = 0;         ///< write() calls still to skip (backoff)
  };
  StatusWriteResult replace_file(Target& t, std::string_view text) noexcept;

  std::vector<char> json_buf_;
  std::vector<char> prom_buf_;
  Target json_, prom_;
  mode_t recreate_dir_mode_ = 0755;
  std::string joint_;  ///< StatusWriterConfig::joint
  StatusWriterCounters counters_;
  int last_errno_ = 0;
};

}  // namespace ptda::daemon
