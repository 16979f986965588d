#include "status/status_writer.hpp"

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "alloc_counter.hpp"
#include "ptda/common/error.hpp"
#include "status/text_escape.hpp"
#include "status_text.hpp"

namespace fs = std::filesystem;

namespace ptda::daemon {
namespace {

using test::JsonChecker;

TEST(JsonChecker, RejectsBrokenJson) {  // the checker itself must be able to fail
  EXPECT_TRUE(JsonChecker(R"({"a":[1,-2.5e3,true,null,"x\"\u001f"]})").valid());
  EXPECT_FALSE(JsonChecker(R"({"a":1,})").valid());
  EXPECT_FALSE(JsonChecker("{\"a\":\"\x01\"}").valid());
  EXPECT_FALSE(JsonChecker(R"({"a":01})").valid());
  EXPECT_FALSE(JsonChecker(R"({"a":nan})").valid());
  EXPECT_FALSE(JsonChecker(R"({"a":"\q"})").valid());
  EXPECT_FALSE(JsonChecker(R"({"a":1} x)").valid());
}

fs::path scratch(const std::string& name) {
  const char* base = std::getenv("PTDA_TEST_TMP");
  fs::path dir = fs::path(base != nullptr ? base : "/tmp") / "status_writer_test" / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

StatusSnapshot known_snapshot() {
  StatusSnapshot s;
  s.state = DaemonState::kRunning;
  s.phase.assign("monitoring");
  s.reason.assign("");
  s.method.assign("ptda");
  s.uptime_s = 3600.25;
  s.now_s = 5000.5;
  s.wall_time_unix_ns = 1700000000123456789;
  s.baseline_loaded = true;
  s.baseline_path.assign("/var/lib/ptda/baseline.bin");
  s.baseline_source.assign("ptda train rec/2024-05-01");
  s.baseline_fs_hz = 25600.0;
  s.baseline_window_len = 4096;
  s.class_count = 2;
  s.classes_listed = 2;
  s.classes[0] = StatusClass{0, 1, 0.5, 1.5, 12, 48, 0.01, 0.02, 0.8, 0.9};
  s.classes[1] = StatusClass{1, -1, 0.25, 2.0, 12, 60, 0.011, 0.021, 0.81, 0.91};
  s.have_window = true;
  s.window_t_s = 4999.125;
  s.window_wall_ns = 1700000000123456789 - 1'375'000'000;  // 1.375 s before the snapshot, as window_t_s
  s.window_class = 1;
  s.window_speed_rad_s = -0.25;
  s.window_rms = 0.025;
  s.window_entropy = 0.85;
  s.window_rms_lo = 0.011;
  s.window_rms_hi = 0.021;
  s.window_entropy_lo = 0.81;
  s.window_entropy_hi = 0.91;
  s.window_rms_out = true;
  s.window_abnormal_in_last_n = 3;
  s.alarm_level = drivers::AlarmLevel::kAlarm;
  s.alarm_since_s = 4990.0;
  s.alarm_since_wall_ns = 1700000000123456789 - 10'500'000'000;
  s.alarm_latched = true;
  s.alarm_causes = drivers::kCauseRms | drivers::kCauseSpeed;
  s.trip_class = 1;
  s.trip_t_s = 4990.0;
  s.trip_wall_ns = 1700000000123456789 - 10'500'000'000;
  s.trip_rms = 0.03;
  s.trip_entropy = 0.86;
  s.trip_detector = "k_of_n+sequential";
  s.trip_cusum = 7.5;
  s.acq_blocks = 100;
  s.acq_samples = 102400;
  s.acq_gaps = 1;
  s.acq_lost_samples = 64;
  s.can_frames = 5000;
  s.can_speed_frames = 4990;
  s.can_other_ids = 10;
  s.can_remote_frames = 2;
  s.can_bus_state = drivers::CanBusState::kErrorPassive;
  s.slicer_regions = 24;
  s.slicer_windows = 108;
  s.windows_scored = 107;
  s.windows_abnormal = 4;
  s.alarms_raised = 1;
  s.level_changes_dropped = 2;
  s.watchdog_pings = 7200;
  // Coverage: class 1 judged (last window), class 0 never in 3000 s of motion: partial.
  s.coverage_known = true;
  s.coverage_timeout_s = 60.0;
  dsp::CoverageState& c = s.coverage;
  c.level = dsp::CoverageLevel::kPartial;
  c.judged = 107;
  c.unmatched = {1, 0, 0};
  c.class_count = 2;
  c.classes[1] = dsp::ClassCoverage{107, true, 4'999'125'000'000, 2'999'500'000'000};
  c.speeds[0] = dsp::UnmatchedSpeed{0.75, 1, 4'998'000'000'000};
  c.speed_bins = 1;
  c.have_judged = true;
  c.last_judged_t_ns = 4'999'125'000'000;
  c.have_time = true;
  c.first_t_ns = 1'000'000'000'000;
  c.latest_t_ns = 5'000'000'000'000;
  c.moving_ns = 3'000'000'000'000;
  c.moving_at_last_judged_ns = 2'999'500'000'000;
  // Field training's baseline write failed 3 times on a full disk and still fails.
  s.state_files[2] = StateFileHealth{3, ENOSPC, "write", true};
  return s;
}

constexpr std::string_view kKnownJson =
    R"({"version":1,"state":"running","phase":"monitoring","reason":"","uptime_s":3600.250,"now_s":5000.500,)"
    R"("now_utc":"2023-11-14T22:13:20.123Z","wall_time_unix_ns":1700000000123456789,"method":"ptda",)"
    R"("baseline":{"loaded":true,"path":"/var/lib/ptda/baseline.bin","source":"ptda train rec/2024-05-01",)"
    R"("fs_hz":25600,"window_len":4096,"class_count":2,"classes":[)"
    R"({"id":0,"direction":1,"speed_rad_s":0.5,"duration_s":1.5,"regions":12,"n_windows":48,)"
    R"("rms_band":[0.01,0.02],"entropy_band":[0.8,0.9]},)"
    R"({"id":1,"direction":-1,"speed_rad_s":0.25,"duration_s":2,"regions":12,"n_windows":60,)"
    R"("rms_band":[0.011,0.021],"entropy_band":[0.81,0.91]}]},)"
    R"("last_window":{"t_s":4999.125,"t_utc":"2023-11-14T22:13:18.748Z","age_s":1.375,"class":1,"speed_rad_s":-0.25,"rms":0.025,"entropy":0.85,)"
    R"("rms_band":[0.011,0.021],"entropy_band":[0.81,0.91],"rms_out":true,"entropy_out":false,)"
    R"("abnormal":true,"abnormal_in_last_n":3},)"
    R"("alarm":{"level":"alarm","since_s":4990.000,"since_utc":"2023-11-14T22:13:09.623Z","duration_s":10.500,)"
    R"("latched":true,"causes":["rms","speed"],)"
    R"("trip":{"class":1,"t_s":4990.000,"t_utc":"2023-11-14T22:13:09.623Z","rms":0.03,"entropy":0.86,)"
    R"("detector":"k_of_n+sequential","cusum":7.5}},)"
    R"("coverage":{"state":"partial","timeout_s":60,"judged":107,)"
    R"("unmatched":{"speed":1,"direction":0,"invalid":0},"last_judged_age_s":0.875,)"
    R"("motion_since_judged_s":0.500,"classes":[{"id":0,"judged":0,"last_judged_age_s":null,"current":false},)"
    R"({"id":1,"judged":107,"last_judged_age_s":0.875,"current":true}],)"
    R"("unmatched_speeds":[{"speed_rad_s":0.75,"windows":1}]},"training":null,)"
    R"("acquisition":{"blocks":100,"samples":102400,"gaps":1,"lost_samples":64,"short_reads":0,)"
    R"("time_back":0,"timeouts":0,"read_errors":0},)"
    R"("can":{"frames":5000,"speed_frames":4990,"other_ids":10,"wrong_dlc":0,"remote_frames":2,"error_frames":0,)"
    R"("rx_overflow_drops":0,"bus_off":0,"bus_state":"error_passive"},)"
    R"("slicer":{"regions":24,"windows":108,"windows_invalid":0,"windows_lost":0},)"
    R"("pipeline":{"ring_overflows":0,"windows_scored":107,"windows_abnormal":4,"alarms_raised":1,)"
    R"("level_changes_dropped":2,"watchdog_pings":7200},)"
    R"("history":null,"mqtt":null,)"
    R"("state_files":{"status":{"failing":false,"failures":0,"last_errno":0,"last_error":""},)"
    R"("metrics":{"failing":false,"failures":0,"last_errno":0,"last_error":""},)"
    R"("baseline":{"failing":true,"failures":3,"last_errno":28,)"
    R"x("last_error":"write: ENOSPC (No space left on device)"}}})x"
    "\n";

StatusWriterConfig json_only(const fs::path& dir, std::size_t bytes = 64 * 1024) {
  StatusWriterConfig c;
  c.json_path = dir / "status.json";
  c.buffer_bytes = bytes;
  return c;
}

TEST(StatusWriter, JsonTextOfAKnownSnapshot) {
  StatusWriter w(json_only(scratch("json")));
  const std::string_view text = w.render_json(known_snapshot());
  EXPECT_EQ(text, kKnownJson);
  EXPECT_TRUE(JsonChecker(text).valid());
}

TEST(StatusWriter, JsonForEmptyAndTrainingSnapshots) {
  StatusWriter w(json_only(scratch("json2")));
  StatusSnapshot s;
  std::string text(w.render_json(s));
  EXPECT_TRUE(JsonChecker(text).valid()) << text;
  EXPECT_NE(text.find(R"("state":"configured")"), std::string::npos);
  EXPECT_NE(text.find(R"("classes":[])"), std::string::npos);
  EXPECT_NE(text.find(R"("last_window":null)"), std::string::npos);
  EXPECT_NE(
      text.find(
          R"("alarm":{"level":"fault","since_s":0.000,"since_utc":null,"duration_s":0.000,"latched":false,)"
          R"("causes":[],"trip":null})"),
      std::string::npos)
      << text;

  s.state = DaemonState::kTraining;
  s.training_windows = 10;
  s.training_capacity = 4096;
  s.training_regions = 3;
  s.training_classes = 2;
  s.training_classes_complete = 1;
  s.training_target_cycles = 10;
  s.have_window = true;
  s.window_rms = std::numeric_limits<double>::quiet_NaN();
  s.window_entropy = std::numeric_limits<double>::infinity();
  text = w.render_json(s);
  EXPECT_TRUE(JsonChecker(text).valid()) << text;
  EXPECT_NE(
      text.find(R"("training":{"windows":10,"capacity":4096,"regions":3,"classes":2,"classes_complete":1,)"
                R"("target_cycles":10,"dropped":0,"spill_write_failed":0,"spill_queue_full":0,)"
                R"("spill_last_error":null})"),
      std::string::npos)
      << text;
  // A refused spill write says why (a full disk is not a full pool).
  s.training_dropped = 7;
  s.training_spill_write_failed = 5;
  s.training_spill_queue_full = 2;
  s.training_spill_errno = ENOSPC;
  text = w.render_json(s);
  EXPECT_TRUE(JsonChecker(text).valid()) << text;
  EXPECT_NE(text.find(R"("dropped":7,"spill_write_failed":5,"spill_queue_full":2,)"
                      R"("spill_last_error":"No space left on device"})"),
            std::string::npos)
      << text;
  const std::string prom(w.render_prometheus(s));
  EXPECT_EQ(test::prom_samples(prom, "ptda_training_dropped_total"),
            std::vector<std::string>{"ptda_training_dropped_total 7"});
  EXPECT_EQ(test::prom_samples(prom, "ptda_training_spill_write_failed_total"),
            std::vector<std::string>{"ptda_training_spill_write_failed_total 5"});
  EXPECT_EQ(test::prom_samples(prom, "ptda_training_spill_queue_full_total"),
            std::vector<std::string>{"ptda_training_spill_queue_full_total 2"});
  EXPECT_NE(text.find(R"("rms":null,"entropy":null)"), std::string::npos) << text;
}

TEST(StatusWriter, EscapesStrings) {
  StatusWriter w(json_only(scratch("esc")));
  StatusSnapshot s;
  s.state = DaemonState::kRefused;
  s.reason.assign("bad \"baseline\" C:\\x\n\ttab\x01\x1f end");
  const std::string text(w.render_json(s));
  EXPECT_NE(text.find(R"("reason":"bad \"baseline\" C:\\x\n\ttab\u0001\u001f end")"), std::string::npos)
      << text;
  EXPECT_TRUE(JsonChecker(text).valid()) << text;

  char buf[64];
  TextBuffer b(buf, sizeof buf);
  b.append_label_value("a\"b\\c\nd\te");
  EXPECT_EQ(b.view(), "a\\\"b\\\\c\\nd\te");
  b.clear();
  b.append_json_string(std::string_view("\b\f\r\x7f/", 5));
  EXPECT_EQ(b.view(), "\"\\b\\f\\r\x7f/\"");
}

// Ill-formed UTF-8 and NUL bytes (a baseline path, a reason from a file) must not reach either file
// raw: the JSON must stay valid UTF-8 and the Prometheus label values too (status/text_escape.hpp).
TEST(StatusWriter, EscapesIllFormedUtf8AndNul) {
  StatusWriterConfig c = json_only(scratch("utf8"));
  c.prom_path = c.json_path.parent_path() / "ptda.prom";
  StatusWriter w(c);
  StatusSnapshot s;
  s.reason.assign(
      std::string_view("a\0b\xC0\x80"
                       "c\xED\xA0\x80"
                       "d\xE2\x82",
                       12));
  s.baseline_path.assign(
      "/var/lib/ptda/\xE2\x82\xAC"
      ".bin");
  const std::string text(w.render_json(s));
  EXPECT_NE(text.find("\"reason\":\"a\\u0000b\xEF\xBF\xBD\xEF\xBF\xBD"
                      "c"
                      "\xEF\xBF\xBD\xEF\xBF\xBD\xEF\xBF\xBD"
                      "d\xEF\xBF\xBD\""),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("\"path\":\"/var/lib/ptda/\xE2\x82\xAC"
                      ".bin\""),
            std::string::npos)
      << text;
  EXPECT_TRUE(JsonChecker(text).valid()) << text;
  EXPECT_TRUE(is_valid_utf8(text));
  const std::string prom(w.render_prometheus(s));
  EXPECT_NE(prom.find("reason=\"a\xEF\xBF\xBD"
                      "b\xEF\xBF\xBD\xEF\xBF\xBD"
                      "c"
                      "\xEF\xBF\xBD\xEF\xBF\xBD\xEF\xBF\xBD"
                      "d\xEF\xBF\xBD\""),
            std::string::npos)
      << prom;
  EXPECT_TRUE(is_valid_utf8(prom));
  EXPECT_EQ(prom.find('\0'), std::string::npos);
}

TEST(StatusWriter, JointNameLabelsEveryMetricAndNamesTheStatus) {
  // Several daemons of one cabinet share node_exporter's textfile directory: without a label of their
  // own their samples would collide.
  StatusWriterConfig c;
  c.json_path = scratch("joint") / "status.json";
  c.prom_path = scratch("joint") / "ptda.prom";
  c.joint = "joint4";
  StatusWriter w(c);
  const StatusSnapshot s = known_snapshot();
  const std::string prom(w.render_prometheus(s));
  std::istringstream lines(prom);
  std::size_t samples = 0;
  for (std::string line; std::getline(lines, line);) {
    if (line.empty() || line[0] == '#') continue;
    ++samples;
    const auto brace = line.find('{');
    ASSERT_NE(brace, std::string::npos) << line;
    EXPECT_EQ(line.compare(brace, 15, "{joint=\"joint4\""), 0) << line;
  }
  EXPECT_GT(samples, 50U);
  EXPECT_EQ(test::prom_samples(prom, "ptda_uptime_seconds"),
            std::vector<std::string>{R"(ptda_uptime_seconds{joint="joint4"} 3600.25)"});
  EXPECT_EQ(test::prom_samples(prom, "ptda_state").at(1), R"(ptda_state{joint="joint4",state="running"} 1)");
  const std::string json(w.render_json(s));
  EXPECT_EQ(json.rfind("{\"version\":1,\"joint\":\"joint4\",", 0), 0U) << json.substr(0, 80);
  EXPECT_TRUE(JsonChecker(json).valid());
  // Without a name, neither appears (one joint per cabinet, the files as before).
  StatusWriterConfig unnamed = c;
  unnamed.joint.clear();
  StatusWriter plain(unnamed);
  EXPECT_EQ(std::string(plain.render_prometheus(s)).find("joint="), std::string::npos);
  EXPECT_EQ(std::string(plain.render_json(s)).find("\"joint\""), std::string::npos);
}

// --- The fleet files (issue 15 item 5): alerting rules and dashboard use only metrics the daemon writes.

/// Every "ptda_<name>" token of `text` (lower-case letters, digits, '_'), e.g. the metric names of a
/// PromQL expression. File names ("ptda-alerts.yml") and label values are not tokens of this form.
std::set<std::string> ptda_tokens(const std::string& text) {
  std::set<std::string> out;
  const auto word = [](char c) { return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_'; };
  for (std::size_t at = text.find("ptda_"); at != std::string::npos; at = text.find("ptda_", at + 1)) {
    if (at > 0 && (word(text[at - 1]) || (text[at - 1] >= 'A' && text[at - 1] <= 'Z'))) continue;
    std::size_t end = at + 5;
    while (end < text.size() && word(text[end])) ++end;
    out.insert(text.substr(at, end - at));
  }
  return out;
}

/// The metric families ("# TYPE name ...") of a rendered textfile.
std::set<std::string> families(const std::string& prom) {
  std::set<std::string> out;
  std::istringstream lines(prom);
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind("# TYPE ", 0) == 0) out.insert(line.substr(7, line.find(' ', 7) - 7));
  }
  return out;
}

std::string read_source_file(const std::string& relative) {
  std::ifstream in(fs::path(PTDA_SOURCE_DIR) / relative);
  EXPECT_TRUE(in.good()) << relative;
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

TEST(FleetFiles, RulesAndDashboardUseOnlyMetricsTheDaemonWrites) {
  StatusWriterConfig c;
  const fs::path dir = scratch("fleet");
  c.prom_path = dir / "ptda.prom";
  c.joint = "joint4";
  StatusWriter w(c);
  // Monitoring with a window, an alarm and partial coverage; then field training (its own families).
  StatusSnapshot monitoring = known_snapshot();
  monitoring.mqtt.enabled = true;  // [mqtt] on: the ptda_mqtt_* families (PtdaMqttQueueDropping)
  StatusSnapshot training = known_snapshot();
  training.state = DaemonState::kTraining;
  training.training_windows = 120;
  training.training_capacity = 4096;
  const std::string prom_monitoring(w.render_prometheus(monitoring));
  const std::string prom_training(w.render_prometheus(training));
  ASSERT_FALSE(prom_monitoring.empty());
  ASSERT_FALSE(prom_training.empty());
  // Kept for `promtool check metrics` (tests/fleet/prometheus_check.sh runs this test for them).
  std::ofstream(dir / "monitoring.prom") << prom_monitoring;
  std::ofstream(dir / "training.prom") << prom_training;
  std::set<std::string> written = families(prom_monitoring);
  for (const std::string& f : families(prom_training)) written.insert(f);
  ASSERT_GT(written.size(), 50U);

  const auto missing = [&](const std::set<std::string>& used) {
    std::vector<std::string> out;
    for (const std::string& m : used) {
      if (written.count(m) == 0) out.push_back(m);
    }
    return out;
  };
  // The check itself can fail: a misspelt metric is reported.
  EXPECT_EQ(missing(ptda_tokens("rate(ptda_windows_judged_totl[5m]) and ptda_alarm_level")),
            std::vector<std::string>{"ptda_windows_judged_totl"});

  const std::string dashboard = read_source_file("packaging/grafana/ptda-joint.json");
  EXPECT_TRUE(test::JsonChecker(dashboard).valid()) << "packaging/grafana/ptda-joint.json is not valid JSON";
  const std::set<std::string> dash_metrics = ptda_tokens(dashboard);
  EXPECT_GE(dash_metrics.size(), 15U);  // state, verdict, features and bands, coverage, counters
  EXPECT_EQ(missing(dash_metrics), std::vector<std::string>{})
      << "ptda-joint.json uses metrics ptdad never writes";
  // Per joint: the dashboard selects by the label the daemon writes with [daemon] joint.
  EXPECT_NE(dashboard.find("joint=~\\\"$joint\\\""), std::string::npos);

  for (const char* rules :
       {"packaging/prometheus/ptda-alerts.yml", "packaging/prometheus/ptda-alerts.test.yml"}) {
    const std::set<std::string> used = ptda_tokens(read_source_file(rules));
    EXPECT_GE(used.size(), 8U) << rules;
    EXPECT_EQ(missing(used), std::vector<std::string>{}) << rules << " uses metrics ptdad never writes";
  }
}

TEST(StatusWriter, MqttFieldsAndMetrics) {
  StatusWriterConfig c = json_only(scratch("mqtt"));
  c.prom_path = c.json_path.parent_path() / "ptda.prom";
  StatusWriter w(c);
  StatusSnapshot s = known_snapshot();
  // Off: null in status.json, no ptda_mqtt_* family.
  EXPECT_NE(std::string(w.render_json(s)).find(R"("mqtt":null)"), std::string::npos);
  EXPECT_EQ(std::string(w.render_prometheus(s)).find("ptda_mqtt_"), std::string::npos);
  s.mqtt.enabled = true;
  s.mqtt.connected = false;
  s.mqtt.queue_bytes = 2963;
  s.mqtt.queue_pending = 5;
  s.mqtt.summary_queue_pending = 9;
  s.mqtt.dropped_event = 1;
  s.mqtt.dropped_summary = 4;
  s.mqtt.published = 13;
  s.mqtt.connect_failures = 7;
  s.mqtt.alarm_durable_us_last = 1612;  // microseconds, as the publisher measures them
  s.mqtt.alarm_durable_us_max = 27305;
  s.mqtt.last_error.assign("broker refused the connection: Connection Refused: not authorised.");
  const std::string json(w.render_json(s));
  EXPECT_TRUE(JsonChecker(json).valid());
  EXPECT_NE(
      json.find(R"("mqtt":{"connected":false,"queue_bytes":2963,"queue_pending":5,"summary_queue_pending":9,)"
                R"("dropped":{"event":1,"summary":4,"handoff":0,"io":0},"published":13,"connect_failures":7,)"
                R"("alarm_durable_us_last":1612,"alarm_durable_us_max":27305,)"
                R"("last_error":"broker refused the connection: Connection Refused: not authorised."})"),
      std::string::npos)
      << json;
  const std::string prom(w.render_prometheus(s));
  EXPECT_EQ(test::prom_samples(prom, "ptda_mqtt_connected"),
            std::vector<std::string>{"ptda_mqtt_connected 0"});
  EXPECT_EQ(test::prom_samples(prom, "ptda_mqtt_queue_bytes"),
            std::vector<std::string>{"ptda_mqtt_queue_bytes 2963"});
  EXPECT_EQ(test::prom_samples(prom, "ptda_mqtt_queue_pending"),
            std::vector<std::string>{"ptda_mqtt_queue_pending 5"});
  EXPECT_EQ(test::prom_samples(prom, "ptda_mqtt_summaries_queue_pending"),
            std::vector<std::string>{"ptda_mqtt_summaries_queue_pending 9"});
  // Seconds in Prometheus (1612 us, 27305 us).
  EXPECT_EQ(test::prom_samples(prom, "ptda_mqtt_alarm_durable_seconds"),
            (std::vector<std::string>{R"(ptda_mqtt_alarm_durable_seconds{stat="last"} 0.001612)",
                                      R"(ptda_mqtt_alarm_durable_seconds{stat="max"} 0.027305)"}));
  EXPECT_EQ(test::prom_samples(prom, "ptda_mqtt_queue_dropped_total"),
            (std::vector<std::string>{R"(ptda_mqtt_queue_dropped_total{kind="event"} 1)",
                                      R"(ptda_mqtt_queue_dropped_total{kind="summary"} 4)",
                                      R"(ptda_mqtt_queue_dropped_total{kind="handoff"} 0)",
                                      R"(ptda_mqtt_queue_dropped_total{kind="io"} 0)"}));
  EXPECT_EQ(test::prom_samples(prom, "ptda_mqtt_published_total"),
            std::vector<std::string>{"ptda_mqtt_published_total 13"});
  EXPECT_EQ(test::prom_samples(prom, "ptda_mqtt_connect_failures_total"),
            std::vector<std::string>{"ptda_mqtt_connect_failures_total 7"});
}

TEST(StatusWriter, FixedStringTruncates) {
  FixedString<8> f;
  f.assign("0123456789");
  EXPECT_EQ(f.view(), "0123456");
  EXPECT_EQ(f.text[7], '\0');
  f.assign("ab");
  EXPECT_EQ(f.view(), "ab");
}

TEST(StatusWriter, PrometheusLines) {
  StatusWriterConfig c;
  c.prom_path = scratch("prom") / "ptda.prom";
  StatusWriter w(c);
  StatusSnapshot s = known_snapshot();
  s.reason.assign("operator \"jo\"\\n\nnext");
  s.baseline_path.assign("/var/lib/ptda/base\\line.bin");
  const std::string text(w.render_prometheus(s));

  EXPECT_EQ(test::prom_samples(text, "ptda_info"),
            std::vector<std::string>{
                R"(ptda_info{method="ptda",phase="monitoring",reason="operator \"jo\"\\n\nnext",)"
                R"(baseline_path="/var/lib/ptda/base\\line.bin",)"
                R"(baseline_source="ptda train rec/2024-05-01"} 1)"});
  EXPECT_EQ(
      test::prom_samples(text, "ptda_state"),
      (std::vector<std::string>{R"(ptda_state{state="configured"} 0)", R"(ptda_state{state="running"} 1)",
                                R"(ptda_state{state="paused"} 0)", R"(ptda_state{state="refused"} 0)",
                                R"(ptda_state{state="training"} 0)", R"(ptda_state{state="stopping"} 0)",
                                R"(ptda_state{state="ended"} 0)"}));
  EXPECT_EQ(test::prom_samples(text, "ptda_rms_threshold"),
            (std::vector<std::string>{R"(ptda_rms_threshold{class="0",bound="low"} 0.01)",
                                      R"(ptda_rms_threshold{class="0",bound="high"} 0.02)",
                                      R"(ptda_rms_threshold{class="1",bound="low"} 0.011)",
                                      R"(ptda_rms_threshold{class="1",bound="high"} 0.021)"}));
  EXPECT_EQ(test::prom_samples(text, "ptda_class_speed_radians_per_second"),
            (std::vector<std::string>{R"(ptda_class_speed_radians_per_second{class="0"} 0.5)",
                                      R"(ptda_class_speed_radians_per_second{class="1"} -0.25)"}));
  EXPECT_EQ(test::prom_samples(text, "ptda_window_rms"),
            std::vector<std::string>{R"(ptda_window_rms{class="1"} 0.025)"});
  EXPECT_EQ(test::prom_samples(text, "ptda_window_age_seconds"),
            std::vector<std::string>{"ptda_window_age_seconds 1.375"});
  EXPECT_EQ(test::prom_samples(text, "ptda_alarm_level"), std::vector<std::string>{"ptda_alarm_level 2"});
  EXPECT_EQ(test::prom_samples(text, "ptda_alarm_level_duration_seconds"),
            std::vector<std::string>{"ptda_alarm_level_duration_seconds 10.5"});
  EXPECT_EQ(test::prom_samples(text, "ptda_alarm_cause"),
            (std::vector<std::string>{
                R"(ptda_alarm_cause{cause="rms"} 1)", R"(ptda_alarm_cause{cause="entropy"} 0)",
                R"(ptda_alarm_cause{cause="sensor"} 0)", R"(ptda_alarm_cause{cause="speed"} 1)",
                R"(ptda_alarm_cause{cause="baseline"} 0)", R"(ptda_alarm_cause{cause="internal"} 0)",
                R"(ptda_alarm_cause{cause="coverage"} 0)", R"(ptda_alarm_cause{cause="band"} 0)"}));
  EXPECT_EQ(
      test::prom_samples(text, "ptda_coverage_state"),
      (std::vector<std::string>{
          R"(ptda_coverage_state{state="waiting"} 0)", R"(ptda_coverage_state{state="full"} 0)",
          R"(ptda_coverage_state{state="partial"} 1)", R"(ptda_coverage_state{state="not judging"} 0)"}));
  EXPECT_EQ(test::prom_samples(text, "ptda_windows_judged_total"),
            std::vector<std::string>{"ptda_windows_judged_total 107"});
  EXPECT_EQ(test::prom_samples(text, "ptda_windows_unmatched_total"),
            (std::vector<std::string>{R"(ptda_windows_unmatched_total{reason="speed"} 1)",
                                      R"(ptda_windows_unmatched_total{reason="direction"} 0)",
                                      R"(ptda_windows_unmatched_total{reason="invalid"} 0)"}));
  EXPECT_EQ(test::prom_samples(text, "ptda_last_judged_window_age_seconds"),
            std::vector<std::string>{"ptda_last_judged_window_age_seconds 0.875"});
  EXPECT_EQ(test::prom_samples(text, "ptda_motion_since_judged_seconds"),
            std::vector<std::string>{"ptda_motion_since_judged_seconds 0.5"});
  EXPECT_EQ(test::prom_samples(text, "ptda_class_windows_judged_total"),
            (std::vector<std::string>{R"(ptda_class_windows_judged_total{class="0"} 0)",
                                      R"(ptda_class_windows_judged_total{class="1"} 107)"}));
  EXPECT_EQ(test::prom_samples(text, "ptda_class_last_judged_window_age_seconds"),
            std::vector<std::string>{R"(ptda_class_last_judged_window_age_seconds{class="1"} 0.875)"});
  EXPECT_EQ(test::prom_samples(text, "ptda_uptime_seconds"),
            std::vector<std::string>{"ptda_uptime_seconds 3600.25"});
  EXPECT_EQ(test::prom_samples(text, "ptda_acquisition_samples_total"),
            std::vector<std::string>{"ptda_acquisition_samples_total 102400"});
  EXPECT_EQ(test::prom_samples(text, "ptda_watchdog_pings_total"),
            std::vector<std::string>{"ptda_watchdog_pings_total 7200"});
  EXPECT_EQ(test::prom_samples(text, "ptda_alarm_level_changes_dropped_total"),
            std::vector<std::string>{"ptda_alarm_level_changes_dropped_total 2"});
  EXPECT_EQ(test::prom_samples(text, "ptda_can_bus_state")[2],
            R"(ptda_can_bus_state{state="error_passive"} 1)");
  EXPECT_EQ(test::prom_samples(text, "ptda_can_remote_frames_total"),
            std::vector<std::string>{"ptda_can_remote_frames_total 2"});
  EXPECT_TRUE(test::prom_samples(text, "ptda_training_windows").empty());  // only while training

  EXPECT_NE(text.find("# HELP ptda_acquisition_samples_total Vibration samples read.\n"
                      "# TYPE ptda_acquisition_samples_total counter\n"
                      "ptda_acquisition_samples_total 102400\n"),
            std::string::npos);
  EXPECT_NE(text.find("# TYPE ptda_rms_threshold gauge\n"), std::string::npos);

  // Format rules for every line: comments are HELP/TYPE; each family has exactly one of each, before
  // its samples; counters end in _total; names are ptda_[a-z_]+.
  std::istringstream in(text);
  std::string line;
  std::string family;
  std::vector<std::string> families;
  int lines = 0;
  while (std::getline(in, line)) {
    ++lines;
    ASSERT_FALSE(line.empty());
    if (line[0] == '#') {
      std::istringstream ls(line);
      std::string hash, kind, name, type;
      ls >> hash >> kind >> name;
      ASSERT_TRUE(kind == "HELP" || kind == "TYPE") << line;
      ASSERT_EQ(name.rfind("ptda_", 0), 0U) << line;
      ASSERT_EQ(name.find_first_not_of("abcdefghijklmnopqrstuvwxyz_"), std::string::npos) << line;
      if (kind == "HELP") {
        ASSERT_EQ(std::count(families.begin(), families.end(), name), 0) << "duplicate " << name;
        families.push_back(name);
        family = name;
      } else {
        ASSERT_EQ(name, family) << line;
        ls >> type;
        ASSERT_TRUE(type == "gauge" || type == "counter") << line;
        const bool total = name.size() > 6 && name.compare(name.size() - 6, 6, "_total") == 0;
        ASSERT_EQ(type == "counter", total) << line;
      }
    } else {
      ASSERT_EQ(line.rfind(family, 0), 0U) << line << " outside its family " << family;
    }
  }
  EXPECT_GT(lines, 100);
  EXPECT_EQ(text.back(), '\n');
}

TEST(StatusWriter, WritesBothFilesAtomically) {
  const fs::path dir = scratch("write");
  StatusWriterConfig c;
  c.json_path = dir / "status.json";
  c.prom_path = dir / "ptda.prom";
  StatusWriter w(c);
  ASSERT_EQ(w.write(known_snapshot()), StatusWriteResult::kOk);
  EXPECT_EQ(test::read_text(c.json_path), kKnownJson);
  const std::string prom = test::read_text(c.prom_path);
  EXPECT_NE(prom.find("ptda_alarm_level 2\n"), std::string::npos);
  for (const auto& e : fs::directory_iterator(dir)) {
    EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos) << e.path();
  }
  EXPECT_EQ(fs::status(c.prom_path).permissions() & fs::perms::all,
            fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read | fs::perms::others_read);
  // Rewriting replaces the content.
  StatusSnapshot s = known_snapshot();
  s.alarm_level = drivers::AlarmLevel::kNormal;
  ASSERT_EQ(w.write(s), StatusWriteResult::kOk);
  EXPECT_NE(test::read_text(c.prom_path).find("ptda_alarm_level 0\n"), std::string::npos);
  EXPECT_EQ(w.counters().writes, 2U);
  EXPECT_EQ(w.counters().io_errors, 0U);
}

TEST(StatusWriter, WriteMakesNoAllocations) {
  const fs::path dir = scratch("alloc");
  StatusWriterConfig c;
  c.json_path = dir / "status.json";
  c.prom_path = dir / "ptda.prom";
  StatusWriter w(c);
  const StatusSnapshot s = known_snapshot();
  StatusWriteResult r = StatusWriteResult::kOk;
  {
    test::AllocScope scope;
    for (int i = 0; i < 20; ++i) {
      if (w.write(s) != StatusWriteResult::kOk) r = StatusWriteResult::kIoError;
    }
    EXPECT_EQ(scope.count(), 0U);
  }
  EXPECT_EQ(r, StatusWriteResult::kOk);
}

TEST(StatusWriter, TooSmallBufferIsCountedNotOverflowed) {
  const fs::path dir = scratch("small");
  StatusWriterConfig c = json_only(dir, 1024);
  StatusWriter w(c);
  StatusSnapshot s = known_snapshot();
  s.classes_listed = kStatusMaxClasses;  // ~16 * 190 bytes: does not fit 1 KiB
  EXPECT_EQ(w.render_json(s), std::string_view{});
  EXPECT_EQ(w.counters().overflows, 1U);
  EXPECT_EQ(w.write(s), StatusWriteResult::kOverflow);
  EXPECT_EQ(w.counters().overflows, 2U);
  EXPECT_FALSE(fs::exists(c.json_path));  // nothing half-written

  char buf[8];
  buf[7] = 'Z';
  TextBuffer b(buf, 7);
  b.append("abcdef");
  b.append("gh");  // does not fit: dropped whole, flagged
  EXPECT_TRUE(b.overflow());
  EXPECT_EQ(b.view(), "abcdef");
  b.append("x");  // nothing after an overflow
  EXPECT_EQ(b.view(), "abcdef");
  EXPECT_EQ(buf[7], 'Z');
}

TEST(StatusWriter, IoErrorIsReported) {
  StatusWriterConfig c;
  c.json_path = scratch("io") / "missing-dir" / "status.json";
  c.recreate_dir_mode = 0;  // a missing directory is not created again
  StatusWriter w(c);
  EXPECT_EQ(w.write(known_snapshot()), StatusWriteResult::kIoError);
  EXPECT_EQ(w.last_errno(), ENOENT);
  EXPECT_EQ(w.counters().io_errors, 1U);
}

TEST(StatusWriter, RejectsBadConfiguration) {
  StatusWriterConfig c;
  EXPECT_THROW(StatusWriter{c}, Error);
  c.prom_path = "/run/ptda/ptda.txt";
  try {
    StatusWriter w(c);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(".prom"), std::string::npos) << e.what();
  }
  c.prom_path = "/run/ptda/ptda.prom";
  c.buffer_bytes = 100;
  EXPECT_THROW(StatusWriter{c}, Error);
}

}  // namespace
}  // namespace ptda::daemon

namespace ptda::daemon {
namespace {

std::size_t dir_entries(const fs::path& dir) {
  std::size_t n = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir)) ++n;
  return n;
}

// Issue 14 item 2. The old writer opened "<path>.tmp" with O_CREAT|O_TRUNC (following a symlink) and
// fchmod'ed it 0644: with the status directory writable by another user, a symlink planted there made
// ptdad (root) overwrite a file of the attacker's choice and make it world-readable.
TEST(StatusWriter, PlantedSymlinksAreNotFollowed) {
  const fs::path dir = scratch("symlink");
  const fs::path victim = scratch("symlink_victim") / "shadow";
  {
    std::ofstream out(victim);
    out << "root:secret\n";
  }
  fs::permissions(victim, fs::perms::owner_read | fs::perms::owner_write);
  fs::create_symlink(victim, dir / "status.json.tmp");  // the old predictable names
  fs::create_symlink(victim, dir / "ptda.prom.tmp");
  fs::create_symlink(victim, dir / "ptda.prom");  // and the target itself
  StatusWriterConfig c;
  c.json_path = dir / "status.json";
  c.prom_path = dir / "ptda.prom";
  StatusWriter w(c);
  ASSERT_EQ(w.write(known_snapshot()), StatusWriteResult::kOk);
  EXPECT_EQ(test::read_text(victim), "root:secret\n");
  EXPECT_EQ(fs::status(victim).permissions() & fs::perms::all,
            fs::perms::owner_read | fs::perms::owner_write);
  EXPECT_EQ(test::read_text(c.json_path), kKnownJson);
  EXPECT_FALSE(fs::is_symlink(c.prom_path));
  EXPECT_NE(test::read_text(c.prom_path).find("ptda_alarm_level 2\n"), std::string::npos);
}

// docs/systemd.md: status.json and *.prom are 0644 whatever the service's UMask (0077).
TEST(StatusWriter, FilesAre0644UnderAStrictUmask) {
  const fs::path dir = scratch("umask");
  StatusWriterConfig c;
  c.json_path = dir / "status.json";
  c.prom_path = dir / "ptda.prom";
  StatusWriter w(c);
  const mode_t old = ::umask(077);
  const StatusWriteResult r = w.write(known_snapshot());
  ::umask(old);
  ASSERT_EQ(r, StatusWriteResult::kOk);
  constexpr fs::perms k0644 =
      fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read | fs::perms::others_read;
  EXPECT_EQ(fs::status(c.json_path).permissions() & fs::perms::all, k0644);
  EXPECT_EQ(fs::status(c.prom_path).permissions() & fs::perms::all, k0644);
}

// Issue 14 item 6: a status directory deleted under the running daemon is created again (0755, as
// systemd's RuntimeDirectory), and writing goes on. Before: every write failed with ENOENT, silently.
TEST(StatusWriter, DeletedDirectoryIsCreatedAgain) {
  const fs::path dir = scratch("recreate") / "run-ptda";
  fs::create_directories(dir);
  StatusWriter w(json_only(dir));
  ASSERT_EQ(w.write(known_snapshot()), StatusWriteResult::kOk);
  fs::remove_all(dir);
  const mode_t old = ::umask(077);
  const StatusWriteResult r = w.write(known_snapshot());
  ::umask(old);
  ASSERT_EQ(r, StatusWriteResult::kOk);
  EXPECT_EQ(test::read_text(dir / "status.json"), kKnownJson);
  EXPECT_EQ(fs::status(dir).permissions() & fs::perms::all,
            fs::perms::owner_all | fs::perms::group_read | fs::perms::group_exec | fs::perms::others_read |
                fs::perms::others_exec);
  EXPECT_EQ(w.counters().dirs_recreated, 1U);
  EXPECT_FALSE(w.health(StateFile::kStatus).failing);
  EXPECT_EQ(w.health(StateFile::kStatus).failures, 0U);
}

// Issue 14 item 6: a failing file is visible (health: failures, errno, step), retried with backoff
// (attempts after 1, 2, 4, 8, 16 calls, then every 16), and written again once the cause is gone.
// Root ignores permission bits, so the failure is a path component that is a regular file (ENOTDIR),
// which also defeats the directory re-creation.
TEST(StatusWriter, FailuresAreCountedWithErrnoRetriedWithBackoffAndRecover) {
  const fs::path dir = scratch("backoff");
  const fs::path blocker = dir / "status";
  { std::ofstream out(blocker); }
  StatusWriterConfig c;
  c.json_path = blocker / "status.json";
  c.prom_path = dir / "ptda.prom";
  StatusWriter w(c);
  std::vector<std::uint64_t> failures;
  for (int i = 0; i < 40; ++i) {
    EXPECT_EQ(w.write(known_snapshot()), StatusWriteResult::kIoError);
    failures.push_back(w.health(StateFile::kStatus).failures);
  }
  // Attempts at calls 1, 2, 4, 8, 16, 32 (1-based): skip 0, 1, 3, 7, 15, 15 calls after them.
  EXPECT_EQ(failures[0], 1U);
  EXPECT_EQ(failures[1], 2U);
  EXPECT_EQ(failures[2], 2U);
  EXPECT_EQ(failures[3], 3U);
  EXPECT_EQ(failures[6], 3U);
  EXPECT_EQ(failures[7], 4U);
  EXPECT_EQ(failures[15], 5U);
  EXPECT_EQ(failures[31], 6U);
  EXPECT_EQ(failures[39], 6U);
  const StateFileHealth h = w.health(StateFile::kStatus);
  EXPECT_TRUE(h.failing);
  EXPECT_EQ(h.last_errno, ENOTDIR);
  EXPECT_STREQ(h.last_step, "open of the temporary file");
  EXPECT_EQ(w.last_errno(), ENOTDIR);
  // The metrics file is written all along and carries the status file's failure.
  ASSERT_EQ(w.write(known_snapshot()), StatusWriteResult::kIoError);
  const std::string prom = test::read_text(c.prom_path);
  EXPECT_NE(prom.find("ptda_state_write_failures_total{file=\"status\"} 6\n"), std::string::npos) << prom;
  EXPECT_NE(prom.find("ptda_state_write_failing{file=\"status\"} 1\n"), std::string::npos);
  EXPECT_NE(prom.find("ptda_state_write_last_errno{file=\"status\"} 20\n"), std::string::npos);
  EXPECT_NE(prom.find("ptda_state_write_failing{file=\"metrics\"} 0\n"), std::string::npos);
  EXPECT_NE(prom.find("ptda_state_write_failures_total{file=\"baseline\"} 3\n"), std::string::npos);
  EXPECT_FALSE(w.health(StateFile::kMetrics).failing);

  // The cause removed: written again within the backoff (at most 16 calls), the count kept.
  fs::remove(blocker);
  fs::create_directory(blocker);
  int calls = 0;
  while (w.write(known_snapshot()) != StatusWriteResult::kOk && calls < 40) ++calls;
  EXPECT_LE(calls, 16);
  EXPECT_FALSE(w.health(StateFile::kStatus).failing);
  EXPECT_EQ(w.health(StateFile::kStatus).failures, 6U);
  // status.json itself: not failing (it was written), the past failures and their errno.
  const std::string json = test::read_text(c.json_path);
  EXPECT_NE(json.find(R"x("state_files":{"status":{"failing":false,"failures":6,"last_errno":20,)x"
                      R"x("last_error":"open of the temporary file: ENOTDIR (Not a directory)"},)x"
                      R"x("metrics":{"failing":false,"failures":0,"last_errno":0,"last_error":""},)x"),
            std::string::npos)
      << json;
  EXPECT_TRUE(JsonChecker(json).valid());
  EXPECT_EQ(dir_entries(blocker), 1U);  // no temporary file left
  // After a success the next failure is attempted at once again.
  fs::remove_all(blocker);
  { std::ofstream out(blocker); }
  EXPECT_EQ(w.write(known_snapshot()), StatusWriteResult::kIoError);
  EXPECT_EQ(w.health(StateFile::kStatus).failures, 7U);
}

}  // namespace
}  // namespace ptda::daemon

namespace ptda::daemon {
namespace {

TEST(StatusWriter, EventHistoryCountersInStatusAndMetricsWhenItIsOn) {
  StatusWriterConfig c;
  c.prom_path = scratch("history_prom") / "ptda.prom";
  StatusWriter w(c);
  StatusSnapshot s = known_snapshot();
  std::string off(w.render_prometheus(s));
  EXPECT_EQ(off.find("ptda_history_"), std::string::npos);  // off: no history families
  s.history_enabled = true;
  s.history_lines = 1234;
  s.history_write_failures = 7;
  s.history_rotation_failures = 1;
  s.history_windows_dropped = 3;
  s.history_last_errno = 21;
  const std::string text(w.render_prometheus(s));
  EXPECT_EQ(test::prom_samples(text, "ptda_history_lines_total"),
            std::vector<std::string>{"ptda_history_lines_total 1234"});
  EXPECT_EQ(test::prom_samples(text, "ptda_history_write_failures_total"),
            std::vector<std::string>{"ptda_history_write_failures_total 7"});
  EXPECT_EQ(test::prom_samples(text, "ptda_history_windows_dropped_total"),
            std::vector<std::string>{"ptda_history_windows_dropped_total 3"});
  EXPECT_EQ(test::prom_samples(text, "ptda_history_rotation_failures_total"),
            std::vector<std::string>{"ptda_history_rotation_failures_total 1"});
  StatusWriter j(json_only(scratch("history_json")));
  const std::string json(j.render_json(s));
  EXPECT_NE(json.find(R"("history":{"lines":1234,"write_failures":7,"rotation_failures":1,)"
                      R"("windows_dropped":3,"last_errno":21})"),
            std::string::npos)
      << json;
  EXPECT_TRUE(JsonChecker(json).valid());
}

}  // namespace
}  // namespace ptda::daemon

namespace ptda::daemon {
namespace {

TEST(StatusWriter, TripNamesTheMeshStatisticWhenTheMeshDetectorRuns) {
  StatusWriter w(json_only(scratch("trip_mesh")));
  StatusSnapshot s = known_snapshot();
  const std::string off(w.render_json(s));
  EXPECT_EQ(off.find("mesh_cusum"), std::string::npos) << off;  // off: the trip has no mesh fields
  s.trip_detector = "mesh";
  s.trip_mesh_on = true;
  s.trip_mesh_cusum = 12.25;
  s.trip_mesh_feature = "pm";
  const std::string on(w.render_json(s));
  EXPECT_NE(on.find(R"("detector":"mesh","cusum":7.5,"mesh_cusum":12.25,"mesh_cusum_feature":"pm"}})"),
            std::string::npos)
      << on;
  EXPECT_TRUE(JsonChecker(on).valid());
}

}  // namespace
}  // namespace ptda::daemon
