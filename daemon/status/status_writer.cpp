#include "status/status_writer.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <span>
#include <string_view>

#include "ptda/common/atomic_file.hpp"
#include "ptda/common/error.hpp"
#include "status/text_escape.hpp"

namespace ptda::daemon {

// ---------------------------------------------------------------------------------------------------
// TextBuffer

void TextBuffer::append(std::string_view s) noexcept {
  if (overflow_) return;
  if (s.size() > cap_ - len_) {
    overflow_ = true;
    return;
  }
  for (const char c : s) data_[len_++] = c;
}

void TextBuffer::append_char(char c) noexcept {
  append(std::string_view(&c, 1));
}

void TextBuffer::append_u64(std::uint64_t v) noexcept {
  char buf[24];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  append(std::string_view(buf, static_cast<std::size_t>(r.ptr - buf)));
}

void TextBuffer::append_i64(std::int64_t v) noexcept {
  char buf[24];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  append(std::string_view(buf, static_cast<std::size_t>(r.ptr - buf)));
}

void TextBuffer::append_double(double v, std::string_view null_text) noexcept {
  if (!std::isfinite(v)) {
    if (!null_text.empty()) {
      append(null_text);
    } else if (std::isnan(v)) {
      append("NaN");
    } else {
      append(v > 0 ? "+Inf" : "-Inf");
    }
    return;
  }
  char buf[40];
  const int n = std::snprintf(buf, sizeof buf, "%.9g", v);
  if (n <= 0 || static_cast<std::size_t>(n) >= sizeof buf) {
    overflow_ = true;
    return;
  }
  append(std::string_view(buf, static_cast<std::size_t>(n)));
}

void TextBuffer::append_escaped(EscapeFn escape, std::string_view s) noexcept {
  if (overflow_) return;
  const std::size_t n = escape(s, data_ + len_, cap_ - len_);
  if (n == kEscapeOverflow) {
    overflow_ = true;
  } else {
    len_ += n;
  }
}

void TextBuffer::append_json_string(std::string_view s) noexcept {
  append_char('"');
  append_escaped(escape_json_body, s);
  append_char('"');
}

void TextBuffer::append_label_value(std::string_view s) noexcept {
  append_escaped(escape_prom_label_value, s);
}

void append_seconds(TextBuffer& b, double s) noexcept {
  if (!std::isfinite(s)) {
    b.append("null");
    return;
  }
  char buf[48];
  const int n = std::snprintf(buf, sizeof buf, "%.3f", s);
  if (n <= 0 || static_cast<std::size_t>(n) >= sizeof buf) {
    b.append("null");
    return;
  }
  b.append(std::string_view(buf, static_cast<std::size_t>(n)));
}

std::size_t format_rfc3339_utc(std::int64_t unix_ns, char* out, std::size_t cap) noexcept {
  // 253402300799 s = 9999-12-31T23:59:59Z: four-digit years only.
  if (cap < 25 || unix_ns < 0 || unix_ns / 1'000'000'000 > 253'402'300'799) return 0;
  const std::time_t secs = static_cast<std::time_t>(unix_ns / 1'000'000'000);
  const int ms = static_cast<int>((unix_ns % 1'000'000'000) / 1'000'000);
  std::tm tm{};
  if (::gmtime_r(&secs, &tm) == nullptr) return 0;
  const int n = std::snprintf(out, cap, "%04d-%02d-%02dT%02d:%02d:%02d.%03dZ", tm.tm_year + 1900,
                              tm.tm_mon + 1, tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec, ms);
  return n == 24 ? 24 : 0;
}

namespace {

using drivers::AlarmLevel;

constexpr std::array<std::pair<std::uint8_t, std::string_view>, 8> kCauseNames{{
    {drivers::kCauseRms, "rms"},
    {drivers::kCauseEntropy, "entropy"},
    {drivers::kCauseSensor, "sensor"},
    {drivers::kCauseSpeed, "speed"},
    {drivers::kCauseBaseline, "baseline"},
    {drivers::kCauseInternal, "internal"},
    {drivers::kCauseCoverage, "coverage"},
    {drivers::kCauseBand, "band"},
}};

constexpr std::array<dsp::UnmatchedReason, dsp::kUnmatchedReasonCount> kUnmatchedReasons{
    dsp::UnmatchedReason::kSpeed, dsp::UnmatchedReason::kDirection, dsp::UnmatchedReason::kInvalid};

// The counters of status.json and the Prometheus file, from one table so the two cannot drift apart:
// status.json groups them ({"acquisition": {...}, "can": {...}, ...}), Prometheus prints each as a
// `counter` family in the same order.
struct CounterDesc {
  std::string_view json_key;
  std::string_view prom_name;
  std::string_view help;
  std::uint64_t StatusSnapshot::*field;
};
// The event history's counters ([history]; only while it is on, so not one of kCounterGroups).
constexpr CounterDesc kHistoryCounters[] = {
    {"lines", "ptda_history_lines_total", "Lines written to the event history.",
     &StatusSnapshot::history_lines},
    {"write_failures", "ptda_history_write_failures_total",
     "Event history lines lost to a failed open, write or rotation (counted, not retried).",
     &StatusSnapshot::history_write_failures},
    {"rotation_failures", "ptda_history_rotation_failures_total",
     "Rotations that could not move the current history file aside (the history stopped at its bound).",
     &StatusSnapshot::history_rotation_failures},
    {"windows_dropped", "ptda_history_windows_dropped_total",
     "Windows the history's hand-over ring could not hold (the supervisor was late).",
     &StatusSnapshot::history_windows_dropped},
};
// The order domain's front end (docs/method.md §9; only in the order domain, so not one of
// kCounterGroups).
constexpr CounterDesc kOrderCounters[] = {
    {"frames", "ptda_order_frames_total", "Speed frames the angle resampler accepted.",
     &StatusSnapshot::order_frames},
    {"frames_no_angle", "ptda_order_frames_no_angle_total", "Speed frames without an angle (a break).",
     &StatusSnapshot::order_frames_no_angle},
    {"frames_out_of_order", "ptda_order_frames_out_of_order_total",
     "Speed frames not after the previous one (dropped).", &StatusSnapshot::order_frames_out_of_order},
    {"frames_overflow", "ptda_order_frames_overflow_total",
     "Speed frames dropped: the vibration lagged too far behind.", &StatusSnapshot::order_frames_overflow},
    {"angle_inconsistent", "ptda_order_angle_inconsistent_total",
     "Frame intervals whose angle step disagreed with the speeds (speed integral used).",
     &StatusSnapshot::order_angle_inconsistent},
    {"breaks", "ptda_order_breaks_total", "Resampler segments ended (standstill, reversal, gap, bad frame).",
     &StatusSnapshot::order_breaks},
    {"samples_unused", "ptda_order_samples_unused_total",
     "Vibration samples with no angle (before the first frame, in a break, not finite, gaps).",
     &StatusSnapshot::order_samples_unused},
    {"samples_overrun", "ptda_order_samples_overrun_total",
     "Vibration samples lost: the speed frames lagged more than max_lead_s.",
     &StatusSnapshot::order_samples_overrun},
    {"outputs", "ptda_order_outputs_total", "Angle samples produced.", &StatusSnapshot::order_outputs},
    {"outputs_dropped", "ptda_order_outputs_dropped_total", "Angle samples dropped on a full output queue.",
     &StatusSnapshot::order_outputs_dropped},
    {"windows", "ptda_order_windows_total", "Order windows cut (R revolutions each).",
     &StatusSnapshot::order_windows},
};

struct CounterGroup {
  std::string_view json_key;
  std::span<const CounterDesc> counters;
  bool with_bus_state;  ///< status.json adds "bus_state" after the counters (Prometheus: a gauge family)
};

constexpr CounterDesc kAcquisitionCounters[] = {
    {"blocks", "ptda_acquisition_blocks_total", "Sample blocks read.", &StatusSnapshot::acq_blocks},
    {"samples", "ptda_acquisition_samples_total", "Vibration samples read.", &StatusSnapshot::acq_samples},
    {"gaps", "ptda_acquisition_gaps_total", "Discontinuities in the sample stream.",
     &StatusSnapshot::acq_gaps},
    {"lost_samples", "ptda_acquisition_lost_samples_total", "Samples estimated lost in gaps.",
     &StatusSnapshot::acq_lost_samples},
    {"short_reads", "ptda_acquisition_short_reads_total", "Reads that ended inside a scan.",
     &StatusSnapshot::acq_short_reads},
    {"time_back", "ptda_acquisition_time_back_total", "Device timestamps that went backwards.",
     &StatusSnapshot::acq_time_back},
    {"timeouts", "ptda_acquisition_timeouts_total", "Reads that timed out.", &StatusSnapshot::acq_timeouts},
    {"read_errors", "ptda_acquisition_read_errors_total", "Failed reads.", &StatusSnapshot::acq_read_errors},
};
constexpr CounterDesc kCanCounters[] = {
    {"frames", "ptda_can_frames_total", "CAN frames received (error frames included).",
     &StatusSnapshot::can_frames},
    {"speed_frames", "ptda_can_speed_frames_total", "Speed frames decoded.",
     &StatusSnapshot::can_speed_frames},
    {"other_ids", "ptda_can_other_id_frames_total", "Frames with another id.",
     &StatusSnapshot::can_other_ids},
    {"wrong_dlc", "ptda_can_wrong_dlc_frames_total", "Speed frames with a wrong length.",
     &StatusSnapshot::can_wrong_dlc},
    {"remote_frames", "ptda_can_remote_frames_total", "Remote (RTR) frames with the speed id (no data).",
     &StatusSnapshot::can_remote_frames},
    {"error_frames", "ptda_can_error_frames_total", "CAN error frames.", &StatusSnapshot::can_error_frames},
    {"rx_overflow_drops", "ptda_can_rx_overflow_drops_total",
     "Frames dropped by the kernel on a full socket queue.", &StatusSnapshot::can_rx_overflow_drops},
    {"bus_off", "ptda_can_bus_off_total", "Transitions into bus-off.", &StatusSnapshot::can_bus_off},
};
constexpr CounterDesc kSlicerCounters[] = {
    {"regions", "ptda_slicer_regions_total", "Constant-speed regions found.",
     &StatusSnapshot::slicer_regions},
    {"windows", "ptda_slicer_windows_total", "Windows cut.", &StatusSnapshot::slicer_windows},
    {"windows_invalid", "ptda_slicer_windows_invalid_total", "Windows discarded: invalid samples inside.",
     &StatusSnapshot::slicer_windows_invalid},
    {"windows_lost", "ptda_slicer_windows_lost_total", "Windows discarded: samples already overwritten.",
     &StatusSnapshot::slicer_windows_lost},
};
constexpr CounterDesc kPipelineCounters[] = {
    {"ring_overflows", "ptda_ring_overflows_total", "Items dropped on full inter-thread rings.",
     &StatusSnapshot::ring_overflows},
    {"windows_scored", "ptda_windows_scored_total", "Windows judged against the baseline.",
     &StatusSnapshot::windows_scored},
    {"windows_abnormal", "ptda_windows_abnormal_total", "Judged windows outside a band.",
     &StatusSnapshot::windows_abnormal},
    {"alarms_raised", "ptda_alarms_raised_total", "Alarms raised (k-of-n confirmed).",
     &StatusSnapshot::alarms_raised},
    {"level_changes_dropped", "ptda_alarm_level_changes_dropped_total",
     "Alarm level changes the full change ring could not hold (no own log, history line or MQTT event).",
     &StatusSnapshot::level_changes_dropped},
    {"watchdog_pings", "ptda_watchdog_pings_total", "systemd watchdog pings sent.",
     &StatusSnapshot::watchdog_pings},
};
constexpr CounterGroup kCounterGroups[] = {
    {"acquisition", kAcquisitionCounters, false},
    {"can", kCanCounters, true},
    {"slicer", kSlicerCounters, false},
    {"pipeline", kPipelineCounters, false},
};

constexpr StateFile kStateFiles[kStateFileCount] = {StateFile::kStatus, StateFile::kMetrics,
                                                    StateFile::kBaseline};

/// "state_files":{"status":{"failing":..,"failures":..,"last_errno":..,"last_error":".."},...}
void render_state_files_json(JsonWriter& j, const StateFileHealth* files) noexcept {
  j.key("state_files");
  j.open('{');
  for (const StateFile f : kStateFiles) {
    const StateFileHealth& h = files[static_cast<std::size_t>(f)];
    j.key(state_file_name(f));
    j.open('{');
    j.boolean("failing", h.failing);
    j.u64("failures", h.failures);
    j.i64("last_errno", h.last_errno);
    // "rename: ENOENT (No such file or directory)"; "" when it never failed.
    char text[160] = "";
    if (h.last_errno != 0) {
      std::snprintf(text, sizeof text, "%s: %s (%s)", h.last_step, errno_name(h.last_errno),
                    errno_text(h.last_errno));
    }
    j.str("last_error", text);
    j.close('}');
  }
  j.close('}');
}

/// `files`: the kStateFileCount entries of "state_files" (write() passes its live health).
void render_json_into(TextBuffer& b, const StatusSnapshot& s, const StateFileHealth* files,
                      std::string_view joint) noexcept {
  JsonWriter j(b);
  j.open('{');
  j.u64("version", 1);
  if (!joint.empty()) j.str("joint", joint);
  j.str("state", daemon_state_name(s.state));
  j.str("phase", s.phase.view());
  j.str("reason", s.reason.view());
  j.secs("uptime_s", s.uptime_s);
  j.secs("now_s", s.now_s);
  j.utc("now_utc", s.wall_time_unix_ns);
  j.i64("wall_time_unix_ns", s.wall_time_unix_ns);
  j.str("method", s.method.view());

  j.key("baseline");
  j.open('{');
  j.boolean("loaded", s.baseline_loaded);
  j.str("path", s.baseline_path.view());
  j.str("source", s.baseline_source.view());
  j.num("fs_hz", s.baseline_fs_hz);
  j.u64("window_len", s.baseline_window_len);
  j.u64("class_count", s.class_count);
  j.key("classes");
  j.open('[');
  const std::uint32_t listed = s.classes_listed < kStatusMaxClasses ? s.classes_listed : kStatusMaxClasses;
  for (std::uint32_t i = 0; i < listed; ++i) {
    const StatusClass& c = s.classes[i];
    j.item();
    j.open('{');
    j.u64("id", c.id);
    j.i64("direction", c.direction);
    j.num("speed_rad_s", c.speed_rad_s);
    j.num("duration_s", c.duration_s);
    j.u64("regions", c.regions);
    j.u64("n_windows", c.n_windows);
    j.band("rms_band", c.rms_lo, c.rms_hi);
    j.band("entropy_band", c.entropy_lo, c.entropy_hi);
    j.close('}');
  }
  j.close(']');
  j.close('}');

  if (s.have_window) {
    j.key("last_window");
    j.open('{');
    j.secs("t_s", s.window_t_s);
    j.utc("t_utc", s.window_wall_ns);
    j.secs("age_s", s.now_s - s.window_t_s);
    j.i64("class", s.window_class);
    j.num("speed_rad_s", s.window_speed_rad_s);
    j.num("rms", s.window_rms);
    j.num("entropy", s.window_entropy);
    j.band("rms_band", s.window_rms_lo, s.window_rms_hi);
    j.band("entropy_band", s.window_entropy_lo, s.window_entropy_hi);
    j.boolean("rms_out", s.window_rms_out);
    j.boolean("entropy_out", s.window_entropy_out);
    j.boolean("abnormal", s.window_rms_out || s.window_entropy_out);
    j.u64("abnormal_in_last_n", s.window_abnormal_in_last_n);
    j.close('}');
  } else {
    j.null("last_window");
  }

  j.key("alarm");
  j.open('{');
  j.str("level", drivers::alarm_level_name(s.alarm_level));
  j.secs("since_s", s.alarm_since_s);
  j.utc("since_utc", s.alarm_since_wall_ns);
  j.secs("duration_s", s.now_s - s.alarm_since_s);
  j.boolean("latched", s.alarm_latched);
  j.key("causes");
  j.open('[');
  for (const auto& [bit, name] : kCauseNames) {
    if ((s.alarm_causes & bit) == 0) continue;
    j.item();
    b.append_json_string(name);
  }
  j.close(']');
  if (s.trip_class >= 0) {
    j.key("trip");
    j.open('{');
    j.i64("class", s.trip_class);
    j.secs("t_s", s.trip_t_s);
    j.utc("t_utc", s.trip_wall_ns);
    j.num("rms", s.trip_rms);
    j.num("entropy", s.trip_entropy);
    j.str("detector", s.trip_detector);
    j.num("cusum", s.trip_cusum);
    if (s.trip_band_on) {
      j.num("band_cusum", s.trip_band_cusum);
      if (s.trip_band >= 0) {
        j.i64("band", s.trip_band);
        j.band("band_hz", s.trip_band_lo_hz, s.trip_band_hi_hz);
      } else {
        j.null("band");
        j.null("band_hz");
      }
    }
    if (s.trip_mesh_on) {  // as the history log and `ptda monitor --jsonl` name them
      j.num("mesh_cusum", s.trip_mesh_cusum);
      j.str("mesh_cusum_feature", s.trip_mesh_feature);
    }
    j.close('}');
  } else {
    j.null("trip");
  }
  j.close('}');

  if (s.coverage_known) {
    const dsp::CoverageState& c = s.coverage;
    j.key("coverage");
    j.open('{');
    j.str("state", dsp::coverage_level_name(c.level));
    j.num("timeout_s", s.coverage_timeout_s);
    j.u64("judged", c.judged);
    j.key("unmatched");
    j.open('{');
    for (const dsp::UnmatchedReason r : kUnmatchedReasons) {
      j.u64(dsp::unmatched_reason_name(r), c.unmatched[static_cast<std::size_t>(r)]);
    }
    j.close('}');
    j.secs("last_judged_age_s", c.last_judged_age_s());
    j.secs("motion_since_judged_s", c.moving_since_judged_s());
    j.key("classes");
    j.open('[');
    const std::uint32_t n = c.class_count < dsp::kCoverageMaxClasses
                                ? c.class_count
                                : static_cast<std::uint32_t>(dsp::kCoverageMaxClasses);
    for (std::uint32_t i = 0; i < n; ++i) {
      const dsp::ClassCoverage& k = c.classes[i];
      j.item();
      j.open('{');
      j.u64("id", i);
      j.u64("judged", k.judged);
      if (k.have) {
        j.secs("last_judged_age_s", static_cast<double>(c.latest_t_ns - k.last_t_ns) * 1e-9);
      } else {
        j.null("last_judged_age_s");
      }
      j.boolean("current", c.class_current(i, s.coverage_timeout_s));
      j.close('}');
    }
    j.close(']');
    j.key("unmatched_speeds");
    j.open('[');
    for (std::uint32_t i = 0; i < c.speed_bins && i < dsp::kCoverageSpeedBins; ++i) {
      j.item();
      j.open('{');
      j.num("speed_rad_s", c.speeds[i].speed_rad_s);
      j.u64("windows", c.speeds[i].count);
      j.close('}');
    }
    j.close(']');
    j.close('}');
  } else {
    j.null("coverage");
  }

  if (s.state == DaemonState::kTraining) {
    j.key("training");
    j.open('{');
    j.u64("windows", s.training_windows);
    j.u64("capacity", s.training_capacity);
    j.u64("regions", s.training_regions);
    j.u64("classes", s.training_classes);
    j.u64("classes_complete", s.training_classes_complete);
    j.u64("target_cycles", s.training_target_cycles);
    j.u64("dropped", s.training_dropped);
    // Why windows were dropped, so a full disk is told apart from a full pool.
    j.u64("spill_write_failed", s.training_spill_write_failed);
    j.u64("spill_queue_full", s.training_spill_queue_full);
    if (s.training_spill_errno != 0) {
      j.str("spill_last_error", errno_text(s.training_spill_errno));
    } else {
      j.null("spill_last_error");
    }
    j.close('}');
  } else {
    j.null("training");
  }

  for (const CounterGroup& g : kCounterGroups) {
    j.key(g.json_key);
    j.open('{');
    for (const CounterDesc& c : g.counters) j.u64(c.json_key, s.*c.field);
    if (g.with_bus_state) j.str("bus_state", can_bus_state_name(s.can_bus_state));
    j.close('}');
  }
  if (s.order_domain) {
    j.key("order");
    j.open('{');
    for (const CounterDesc& c : kOrderCounters) j.u64(c.json_key, s.*c.field);
    j.close('}');
  }
  if (s.history_enabled) {
    j.key("history");
    j.open('{');
    for (const CounterDesc& c : kHistoryCounters) j.u64(c.json_key, s.*c.field);
    j.i64("last_errno", s.history_last_errno);
    j.close('}');
  } else {
    j.null("history");
  }
  if (s.mqtt.enabled) {
    const MqttStats& m = s.mqtt;
    j.key("mqtt");
    j.open('{');
    j.boolean("connected", m.connected);
    j.u64("queue_bytes", m.queue_bytes);
    j.u64("queue_pending", m.queue_pending);
    j.u64("summary_queue_pending", m.summary_queue_pending);
    j.key("dropped");
    j.open('{');
    j.u64("event", m.dropped_event);
    j.u64("summary", m.dropped_summary);
    j.u64("handoff", m.dropped_handoff);
    j.u64("io", m.dropped_io);
    j.close('}');
    j.u64("published", m.published);
    j.u64("connect_failures", m.connect_failures);
    j.u64("alarm_durable_us_last", m.alarm_durable_us_last);
    j.u64("alarm_durable_us_max", m.alarm_durable_us_max);
    if (m.last_error.len > 0) {
      j.str("last_error", m.last_error.view());
    } else {
      j.null("last_error");
    }
    j.close('}');
  } else {
    j.null("mqtt");
  }
  render_state_files_json(j, files);
  j.close('}');
  b.append_char('\n');
}

// ----------------------------------------------------------------------------------------- Prometheus
class Prom {
 public:
  Prom(TextBuffer& b, std::string_view joint) noexcept : b_(b), joint_(joint) {}
  /// "# HELP name help\n# TYPE name type\n"
  void family(std::string_view name, std::string_view type, std::string_view help) noexcept {
    b_.append("# HELP ");
    b_.append(name);
    b_.append_char(' ');
    b_.append(help);
    b_.append("\n# TYPE ");
    b_.append(name);
    b_.append_char(' ');
    b_.append(type);
    b_.append_char('\n');
  }
  /// `name{labels} ` - labels is a list of key/value pairs.
  void begin(std::string_view name,
             std::initializer_list<std::pair<std::string_view, std::string_view>> labels) noexcept {
    b_.append(name);
    if (labels.size() != 0 || !joint_.empty()) {
      b_.append_char('{');
      bool first = true;
      if (!joint_.empty()) {  // the same label on every sample (several joints per textfile directory)
        b_.append("joint=\"");
        b_.append_label_value(joint_);
        b_.append_char('"');
        first = false;
      }
      for (const auto& [k, v] : labels) {
        if (!first) b_.append_char(',');
        first = false;
        b_.append(k);
        b_.append("=\"");
        b_.append_label_value(v);
        b_.append_char('"');
      }
      b_.append_char('}');
    }
    b_.append_char(' ');
  }
  void sample(std::string_view name,
              std::initializer_list<std::pair<std::string_view, std::string_view>> labels,
              double v) noexcept {
    begin(name, labels);
    b_.append_double(v, {});
    b_.append_char('\n');
  }
  /// A unix time in ns as seconds with milliseconds ("%.3f": %.9g would round it to 10 s).
  void sample_unix(std::string_view name, std::int64_t unix_ns) noexcept {
    begin(name, {});
    b_.append_i64(unix_ns / 1'000'000'000);
    char ms[8];
    const int n =
        std::snprintf(ms, sizeof ms, ".%03d", static_cast<int>((unix_ns % 1'000'000'000) / 1'000'000));
    if (n == 4) b_.append(std::string_view(ms, 4));
    b_.append_char('\n');
  }
  void sample_u64(std::string_view name,
                  std::initializer_list<std::pair<std::string_view, std::string_view>> labels,
                  std::uint64_t v) noexcept {
    begin(name, labels);
    b_.append_u64(v);
    b_.append_char('\n');
  }
  void gauge(std::string_view name, std::string_view help, double v) noexcept {
    family(name, "gauge", help);
    sample(name, {}, v);
  }
  void counter(std::string_view name, std::string_view help, std::uint64_t v) noexcept {
    family(name, "counter", help);
    sample_u64(name, {}, v);
  }

 private:
  TextBuffer& b_;
  std::string_view joint_;
};

/// Decimal text of a small integer in a caller's buffer (label values).
std::string_view small_int(char (&buf)[16], std::int64_t v) noexcept {
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return {buf, static_cast<std::size_t>(r.ptr - buf)};
}

void render_state_files_prom(Prom& p, const StateFileHealth* files) noexcept {
  const auto health = [files](StateFile f) -> const StateFileHealth& {
    return files[static_cast<std::size_t>(f)];
  };
  p.family("ptda_state_write_failures_total", "counter",
           "Failed writes of the daemon's files (status, metrics, baseline).");
  for (const StateFile f : kStateFiles) {
    p.sample_u64("ptda_state_write_failures_total", {{"file", state_file_name(f)}}, health(f).failures);
  }
  p.family("ptda_state_write_failing", "gauge", "1 while the latest write of the file failed (retried).");
  for (const StateFile f : kStateFiles) {
    p.sample("ptda_state_write_failing", {{"file", state_file_name(f)}}, health(f).failing ? 1.0 : 0.0);
  }
  p.family("ptda_state_write_last_errno", "gauge", "errno of the file's latest failed write (0: none).");
  for (const StateFile f : kStateFiles) {
    p.sample("ptda_state_write_last_errno", {{"file", state_file_name(f)}}, health(f).last_errno);
  }
}

void render_prom_into(TextBuffer& b, const StatusSnapshot& s, const StateFileHealth* files,
                      std::string_view joint) noexcept {
  Prom p(b, joint);
  p.family("ptda_info", "gauge",
           "Constant 1; labels: monitoring method, phase, state reason, baseline path and source.");
  p.sample("ptda_info",
           {{"method", s.method.view()},
            {"phase", s.phase.view()},
            {"reason", s.reason.view()},
            {"baseline_path", s.baseline_path.view()},
            {"baseline_source", s.baseline_source.view()}},
           1.0);
  p.family("ptda_state", "gauge", "1 for the daemon's current state, 0 for the others.");
  for (const DaemonState st :
       {DaemonState::kConfigured, DaemonState::kRunning, DaemonState::kPaused, DaemonState::kRefused,
        DaemonState::kTraining, DaemonState::kStopping, DaemonState::kEnded}) {
    p.sample("ptda_state", {{"state", daemon_state_name(st)}}, st == s.state ? 1.0 : 0.0);
  }
  p.gauge("ptda_uptime_seconds", "Seconds since the daemon started.", s.uptime_s);
  if (s.wall_time_unix_ns > 0) {
    p.family("ptda_status_timestamp_seconds", "gauge", "Unix time (UTC) when this file was written.");
    p.sample_unix("ptda_status_timestamp_seconds", s.wall_time_unix_ns);
  }

  p.gauge("ptda_baseline_loaded", "1 when a baseline is loaded and accepted.", s.baseline_loaded ? 1.0 : 0.0);
  p.gauge("ptda_baseline_sample_rate_hertz", "Sample rate the baseline was trained at.", s.baseline_fs_hz);
  p.gauge("ptda_baseline_window_samples", "Samples per window in the baseline.", s.baseline_window_len);
  p.gauge("ptda_baseline_classes", "Segment classes in the baseline.", s.class_count);

  const std::uint32_t listed = s.classes_listed < kStatusMaxClasses ? s.classes_listed : kStatusMaxClasses;
  char idb[16];
  p.family("ptda_class_speed_radians_per_second", "gauge", "Signed joint speed of each segment class.");
  for (std::uint32_t i = 0; i < listed; ++i) {
    const StatusClass& c = s.classes[i];
    p.sample("ptda_class_speed_radians_per_second", {{"class", small_int(idb, c.id)}},
             c.direction < 0 ? -c.speed_rad_s : c.speed_rad_s);
  }
  p.family("ptda_rms_threshold", "gauge",
           "Band of rms_res per class for the method in use (recording unit).");
  for (std::uint32_t i = 0; i < listed; ++i) {
    const StatusClass& c = s.classes[i];
    p.sample("ptda_rms_threshold", {{"class", small_int(idb, c.id)}, {"bound", "low"}}, c.rms_lo);
    p.sample("ptda_rms_threshold", {{"class", small_int(idb, c.id)}, {"bound", "high"}}, c.rms_hi);
  }
  p.family("ptda_entropy_threshold", "gauge", "Band of entropy_res per class for the method in use.");
  for (std::uint32_t i = 0; i < listed; ++i) {
    const StatusClass& c = s.classes[i];
    p.sample("ptda_entropy_threshold", {{"class", small_int(idb, c.id)}, {"bound", "low"}}, c.entropy_lo);
    p.sample("ptda_entropy_threshold", {{"class", small_int(idb, c.id)}, {"bound", "high"}}, c.entropy_hi);
  }

  p.family("ptda_window_rms", "gauge", "rms_res of the last scored window (recording unit).");
  if (s.have_window) p.sample("ptda_window_rms", {{"class", small_int(idb, s.window_class)}}, s.window_rms);
  p.family("ptda_window_entropy", "gauge", "entropy_res of the last scored window, [0, 1].");
  if (s.have_window) {
    p.sample("ptda_window_entropy", {{"class", small_int(idb, s.window_class)}}, s.window_entropy);
  }
  p.family("ptda_window_abnormal", "gauge", "1 when the last scored window was outside a band.");
  if (s.have_window) {
    p.sample("ptda_window_abnormal", {{"class", small_int(idb, s.window_class)}},
             s.window_rms_out || s.window_entropy_out ? 1.0 : 0.0);
  }
  p.family("ptda_window_age_seconds", "gauge", "Seconds since the end of the last scored window.");
  if (s.have_window) p.sample("ptda_window_age_seconds", {}, s.now_s - s.window_t_s);
  p.family("ptda_window_end_timestamp_seconds", "gauge", "Unix time (UTC) of the last scored window's end.");
  if (s.have_window && s.window_wall_ns > 0) {
    p.sample_unix("ptda_window_end_timestamp_seconds", s.window_wall_ns);
  }
  p.gauge("ptda_abnormal_windows", "Abnormal windows among the debouncer's last n.",
          s.window_abnormal_in_last_n);

  p.gauge("ptda_alarm_level", "Published level: 0 normal, 1 warning, 2 alarm, 3 fault.",
          static_cast<double>(s.alarm_level));
  p.family("ptda_alarm_cause", "gauge", "1 for each cause bit of the published verdict.");
  for (const auto& [bit, name] : kCauseNames) {
    p.sample("ptda_alarm_cause", {{"cause", name}}, (s.alarm_causes & bit) != 0 ? 1.0 : 0.0);
  }
  p.gauge("ptda_alarm_latched", "1 while an alarm waits for an accepted clear.", s.alarm_latched ? 1.0 : 0.0);
  p.gauge("ptda_alarm_level_duration_seconds", "Seconds since the level was entered.",
          s.now_s - s.alarm_since_s);
  p.family("ptda_alarm_level_since_timestamp_seconds", "gauge",
           "Unix time (UTC) when the level was entered.");
  if (s.alarm_since_wall_ns > 0) {
    p.sample_unix("ptda_alarm_level_since_timestamp_seconds", s.alarm_since_wall_ns);
  }

  if (s.coverage_known) {
    const dsp::CoverageState& c = s.coverage;
    p.family("ptda_coverage_state", "gauge",
             "1 for the current coverage state (waiting, full, partial, not judging), 0 for the others.");
    for (const dsp::CoverageLevel l : {dsp::CoverageLevel::kWaiting, dsp::CoverageLevel::kFull,
                                       dsp::CoverageLevel::kPartial, dsp::CoverageLevel::kNotJudging}) {
      p.sample("ptda_coverage_state", {{"state", dsp::coverage_level_name(l)}}, l == c.level ? 1.0 : 0.0);
    }
    p.counter("ptda_windows_judged_total", "Windows judged against a class of the baseline.", c.judged);
    p.family("ptda_windows_unmatched_total", "counter",
             "Windows cut but not judged, by reason: speed (no class at that speed), direction (no class in "
             "that direction), invalid (discarded samples).");
    for (const dsp::UnmatchedReason r : kUnmatchedReasons) {
      p.sample_u64("ptda_windows_unmatched_total", {{"reason", dsp::unmatched_reason_name(r)}},
                   c.unmatched[static_cast<std::size_t>(r)]);
    }
    p.gauge("ptda_last_judged_window_age_seconds",
            "Data seconds since the last judged window ended (since the first data before one).",
            c.last_judged_age_s());
    p.gauge(
        "ptda_motion_since_judged_seconds",
        "Seconds of joint motion since the last judged window; coverage_timeout_s of it means not judging.",
        c.moving_since_judged_s());
    const std::uint32_t n = c.class_count < dsp::kCoverageMaxClasses
                                ? c.class_count
                                : static_cast<std::uint32_t>(dsp::kCoverageMaxClasses);
    p.family("ptda_class_windows_judged_total", "counter", "Windows judged per segment class.");
    for (std::uint32_t i = 0; i < n; ++i) {
      p.sample_u64("ptda_class_windows_judged_total", {{"class", small_int(idb, i)}}, c.classes[i].judged);
    }
    p.family("ptda_class_last_judged_window_age_seconds", "gauge",
             "Data seconds since the class's last judged window ended (classes judged at least once).");
    for (std::uint32_t i = 0; i < n; ++i) {
      if (!c.classes[i].have) continue;
      p.sample("ptda_class_last_judged_window_age_seconds", {{"class", small_int(idb, i)}},
               static_cast<double>(c.latest_t_ns - c.classes[i].last_t_ns) * 1e-9);
    }
  }

  if (s.state == DaemonState::kTraining) {
    p.gauge("ptda_training_windows", "Healthy windows collected by field training.", s.training_windows);
    p.gauge("ptda_training_window_capacity", "Windows the training pool holds.", s.training_capacity);
    p.gauge("ptda_training_regions", "Constant-speed cycles collected.", s.training_regions);
    p.gauge("ptda_training_classes", "Segment classes seen so far.", s.training_classes);
    p.gauge("ptda_training_classes_complete", "Classes with the target number of cycles.",
            s.training_classes_complete);
    p.gauge("ptda_training_target_cycles", "Cycles wanted per class.", s.training_target_cycles);
    p.counter(
        "ptda_training_dropped_total",
        "Windows and regions not kept: the pool full, the spill file refusing a write or its writer behind.",
        s.training_dropped);
    p.counter("ptda_training_spill_write_failed_total", "Windows the spill file refused (part of dropped).",
              s.training_spill_write_failed);
    p.counter("ptda_training_spill_queue_full_total",
              "Windows dropped while the spill writer was behind (part of dropped).",
              s.training_spill_queue_full);
  }

  for (const CounterGroup& g : kCounterGroups) {
    for (const CounterDesc& c : g.counters) p.counter(c.prom_name, c.help, s.*c.field);
  }
  p.family("ptda_can_bus_state", "gauge", "1 for the CAN controller's current state.");
  for (const drivers::CanBusState st :
       {drivers::CanBusState::kErrorActive, drivers::CanBusState::kErrorWarning,
        drivers::CanBusState::kErrorPassive, drivers::CanBusState::kBusOff}) {
    p.sample("ptda_can_bus_state", {{"state", can_bus_state_name(st)}}, st == s.can_bus_state ? 1.0 : 0.0);
  }
  if (s.order_domain) {
    for (const CounterDesc& c : kOrderCounters) p.counter(c.prom_name, c.help, s.*c.field);
  }
  if (s.history_enabled) {
    for (const CounterDesc& c : kHistoryCounters) p.counter(c.prom_name, c.help, s.*c.field);
  }
  if (s.mqtt.enabled) {
    const MqttStats& m = s.mqtt;
    p.gauge("ptda_mqtt_connected", "1 while the MQTT publisher is connected to its broker.",
            m.connected ? 1.0 : 0.0);
    p.gauge("ptda_mqtt_queue_bytes", "Bytes in the MQTT store-and-forward queue.",
            static_cast<double>(m.queue_bytes));
    p.gauge("ptda_mqtt_queue_pending", "Events in the MQTT queue not yet acknowledged by the broker.",
            static_cast<double>(m.queue_pending));
    p.gauge("ptda_mqtt_summaries_queue_pending",
            "Window summaries in their MQTT queue not yet acknowledged by the broker.",
            static_cast<double>(m.summary_queue_pending));
    p.family("ptda_mqtt_queue_dropped_total", "counter",
             "MQTT events dropped: event (alarm/fault/state removed from the full queue), summary (window "
             "summary while offline or from the full queue), handoff (supervisor ring full), io (queue write "
             "failed).");
    p.sample("ptda_mqtt_queue_dropped_total", {{"kind", "event"}}, static_cast<double>(m.dropped_event));
    p.sample("ptda_mqtt_queue_dropped_total", {{"kind", "summary"}}, static_cast<double>(m.dropped_summary));
    p.sample("ptda_mqtt_queue_dropped_total", {{"kind", "handoff"}}, static_cast<double>(m.dropped_handoff));
    p.sample("ptda_mqtt_queue_dropped_total", {{"kind", "io"}}, static_cast<double>(m.dropped_io));
    p.counter("ptda_mqtt_published_total",
              "MQTT messages the broker acknowledged (queued events) or took (summaries).", m.published);
    p.counter("ptda_mqtt_connect_failures_total",
              "Failed MQTT connection attempts (refused, unreachable, TLS).", m.connect_failures);
    p.family("ptda_mqtt_alarm_durable_seconds", "gauge",
             "Alarm level change recorded -> its MQTT queue record fsync'ed: the latest (stat=last) and the "
             "largest since the publisher started (stat=max); 0 before the first.");
    p.sample("ptda_mqtt_alarm_durable_seconds", {{"stat", "last"}},
             static_cast<double>(m.alarm_durable_us_last) / 1e6);
    p.sample("ptda_mqtt_alarm_durable_seconds", {{"stat", "max"}},
             static_cast<double>(m.alarm_durable_us_max) / 1e6);
  }
  render_state_files_prom(p, files);
}

}  // namespace

// ---------------------------------------------------------------------------------------------------
// StatusWriter

StatusWriter::StatusWriter(const StatusWriterConfig& cfg) {
  if (cfg.json_path.empty() && cfg.prom_path.empty()) {
    throw Error("status: neither a JSON path nor a Prometheus path is configured");
  }
  if (!cfg.prom_path.empty() && cfg.prom_path.extension() != ".prom") {
    throw Error("status.prom_path: " + cfg.prom_path.string() +
                ": must end in \".prom\" (the node_exporter textfile collector reads only *.prom)");
  }
  if (cfg.buffer_bytes < 1024) {
    throw Error("status.buffer_bytes: must be >= 1024, got " + std::to_string(cfg.buffer_bytes));
  }
  json_buf_.assign(cfg.buffer_bytes, '\0');
  prom_buf_.assign(cfg.buffer_bytes, '\0');
  recreate_dir_mode_ = cfg.recreate_dir_mode;
  joint_ = cfg.joint;
  const auto target = [](Target& t, const std::filesystem::path& p) {
    if (p.empty()) return;
    t.path = p.string();
    t.dir = p.parent_path().string();
    t.name = p.filename().string();
  };
  target(json_, cfg.json_path);
  target(prom_, cfg.prom_path);
}

std::string_view StatusWriter::render_json(const StatusSnapshot& s) noexcept {
  TextBuffer b(json_buf_.data(), json_buf_.size());
  render_json_into(b, s, s.state_files.data(), joint_);
  if (b.overflow()) {
    ++counters_.overflows;
    return {};
  }
  return b.view();
}

std::string_view StatusWriter::render_prometheus(const StatusSnapshot& s) noexcept {
  TextBuffer b(prom_buf_.data(), prom_buf_.size());
  render_prom_into(b, s, s.state_files.data(), joint_);
  if (b.overflow()) {
    ++counters_.overflows;
    return {};
  }
  return b.view();
}

StateFileHealth StatusWriter::health(StateFile f) const noexcept {
  if (f == StateFile::kStatus) return json_.health;
  if (f == StateFile::kMetrics) return prom_.health;
  return {};
}

StatusWriteResult StatusWriter::replace_file(Target& t, std::string_view text) noexcept {
  if (t.skip > 0) {  // backoff after repeated failures: not an attempt
    --t.skip;
    return StatusWriteResult::kIoError;
  }
  AtomicWriteOptions opt;
  opt.mode = 0644;  // readable by a node_exporter running as another user, whatever the service's UMask
  opt.exact_mode = true;
  opt.durable = false;
  AtomicWriteResult r = write_file_atomic(t.path.c_str(), text.data(), text.size(), opt);
  if (r.err == ENOENT && std::string_view(r.step) == kStepOpenTemp && recreate_dir_mode_ != 0 &&
      !t.dir.empty()) {
    // The directory was removed under us (e.g. /run/ptda by hand): create it again, then retry once.
    if (::mkdir(t.dir.c_str(), 0700) == 0) {
      const int dfd = ::open(t.dir.c_str(), O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
      if (dfd >= 0) {
        (void)::fchmod(dfd, recreate_dir_mode_);
        ::close(dfd);
      }
      ++counters_.dirs_recreated;
      r = write_file_atomic(t.path.c_str(), text.data(), text.size(), opt);
    }
  }
  if (!r.ok()) {
    last_errno_ = r.err;
    ++counters_.io_errors;
    ++t.health.failures;
    t.health.last_errno = r.err;
    t.health.last_step = r.step;
    // 1st failure: retry at the next call; then skip 1, 3, 7, ... calls (at most the cap).
    const std::uint64_t consecutive = t.health.failing ? ++t.consecutive : (t.consecutive = 1);
    t.health.failing = true;
    const std::uint64_t skip = consecutive >= 5 ? kStatusMaxSkippedWrites : (1ULL << (consecutive - 1)) - 1;
    t.skip = static_cast<std::uint32_t>(std::min<std::uint64_t>(skip, kStatusMaxSkippedWrites));
    return StatusWriteResult::kIoError;
  }
  t.health.failing = false;
  t.consecutive = 0;
  return StatusWriteResult::kOk;
}

StatusWriteResult StatusWriter::write(const StatusSnapshot& s) noexcept {
  ++counters_.writes;
  StatusWriteResult worst = StatusWriteResult::kOk;
  const auto merge = [&worst](StatusWriteResult r) {
    if (static_cast<int>(r) > static_cast<int>(worst)) worst = r;
  };
  // "state_files": the writer's own health for status and metrics (the snapshot's baseline entry). A
  // file a reader sees was written, so its own entry says "not failing"; the other shows its latest
  // attempt.
  std::array<StateFileHealth, kStateFileCount> files = s.state_files;
  constexpr auto kStatus = static_cast<std::size_t>(StateFile::kStatus);
  constexpr auto kMetrics = static_cast<std::size_t>(StateFile::kMetrics);
  if (!json_.path.empty()) {
    files[kStatus] = json_.health;
    files[kStatus].failing = false;
    files[kMetrics] = prom_.health;
    TextBuffer b(json_buf_.data(), json_buf_.size());
    render_json_into(b, s, files.data(), joint_);
    if (b.overflow()) ++counters_.overflows;
    merge(b.overflow() ? StatusWriteResult::kOverflow : replace_file(json_, b.view()));
  }
  if (!prom_.path.empty()) {
    files[kStatus] = json_.health;
    files[kMetrics] = prom_.health;
    files[kMetrics].failing = false;
    TextBuffer b(prom_buf_.data(), prom_buf_.size());
    render_prom_into(b, s, files.data(), joint_);
    if (b.overflow()) ++counters_.overflows;
    merge(b.overflow() ? StatusWriteResult::kOverflow : replace_file(prom_, b.view()));
  }
  return worst;
}

}  // namespace ptda::daemon
