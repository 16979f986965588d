// Status for people (issue 17, item 3): every time in status.json and the metrics is non-negative and
// has its wall-clock (RFC 3339) twin, alarm level changes are logged by the supervisor with their
// evidence, and the end of a replay is its own phase (state "ended"), not a sensor fault.
//
// The replays run at fast pace: data time then runs far ahead of the daemon clock (the arc job's ~60 s
// of data in a few seconds), which is what made window_age and alarm_level_duration negative.
// The texts are parsed by the small Cursor below (the project's tests do not use std::regex).
#include <gtest/gtest.h>
#include <time.h>

#include <atomic>
#include <cstdlib>
#include <ctime>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "daemon_test_support.hpp"
#include "ptda/formats/baseline_file.hpp"
#include "status/status_writer.hpp"
#include "status_text.hpp"

namespace ptda::daemon::test {
namespace {

using ptda::test::has;
using ptda::test::read_text;

/// A left-to-right matcher over a text: each step consumes what it matches and fails otherwise.
struct Cursor {
  const std::string& s;
  std::size_t i = 0;
  [[nodiscard]] bool at_end() const { return i >= s.size(); }
  bool lit(std::string_view t) {
    if (s.compare(i, t.size(), t) != 0) return false;
    i += t.size();
    return true;
  }
  /// One or more characters for which `ok` holds.
  template <typename F>
  bool run(F ok) {
    const std::size_t start = i;
    while (i < s.size() && ok(s[i])) ++i;
    return i > start;
  }
  bool digits(std::size_t n) {  // exactly n digits
    for (std::size_t k = 0; k < n; ++k)
      if (i + k >= s.size() || s[i + k] < '0' || s[i + k] > '9') return false;
    i += n;
    return true;
  }
  bool digits() {
    return run([](char c) { return c >= '0' && c <= '9'; });
  }
  bool lower() {
    return run([](char c) { return (c >= 'a' && c <= 'z') || c == '_'; });
  }
  bool nonspace() {
    return run([](char c) { return c != ' ' && c != '\n' && c != '\t'; });
  }
};

/// Unix seconds of RFC 3339 UTC text as the status writer writes it ("2026-11-25T04:31:07.250Z"); -1 when
/// it does not parse.
double parse_rfc3339_utc(const std::string& s) {
  Cursor c{s};
  if (!(c.digits(4) && c.lit("-") && c.digits(2) && c.lit("-") && c.digits(2) && c.lit("T") && c.digits(2) &&
        c.lit(":") && c.digits(2) && c.lit(":") && c.digits(2) && c.lit(".") && c.digits(3) && c.lit("Z") &&
        c.at_end()))
    return -1.0;
  const auto field = [&](std::size_t at, std::size_t n) { return std::stoi(s.substr(at, n)); };
  std::tm tm{};
  tm.tm_year = field(0, 4) - 1900;
  tm.tm_mon = field(5, 2) - 1;
  tm.tm_mday = field(8, 2);
  tm.tm_hour = field(11, 2);
  tm.tm_min = field(14, 2);
  tm.tm_sec = field(17, 2);
  if (tm.tm_mon > 11 || tm.tm_mday < 1 || tm.tm_mday > 31 || tm.tm_hour > 23 || tm.tm_min > 59 ||
      tm.tm_sec > 60) {
    return -1.0;
  }
  return static_cast<double>(::timegm(&tm)) + field(20, 3) * 1e-3;
}

/// Every `"key":value` of a JSON text whose key is lower case and whose value is null, a string or a
/// number (objects, arrays and booleans are skipped), in text order.
std::vector<std::pair<std::string, std::string>> json_scalars(const std::string& json) {
  std::vector<std::pair<std::string, std::string>> out;
  for (std::size_t at = json.find('"'); at != std::string::npos; at = json.find('"', at + 1)) {
    Cursor c{json, at + 1};
    const std::size_t key_at = c.i;
    if (!c.lower()) continue;
    const std::size_t key_end = c.i;
    if (!c.lit("\":")) continue;
    const std::size_t v = c.i;
    if (c.lit("null")) {
    } else if (c.lit("\"")) {
      const std::size_t close = json.find('"', c.i);
      if (close == std::string::npos) continue;
      c.i = close + 1;
    } else if (c.run([](char ch) {
                 return (ch >= '0' && ch <= '9') || ch == '-' || ch == '.' || ch == 'e' || ch == 'E' ||
                        ch == '+';
               })) {
    } else {
      continue;
    }
    out.emplace_back(json.substr(key_at, key_end - key_at), json.substr(v, c.i - v));
    at = c.i - 1;
  }
  return out;
}

/// The alarm line the supervisor logs when the level becomes alarm, with its evidence: one line, or two
/// when it would be longer than spdlog's inline buffer (docs/daemon.md). True when `log` has one.
bool has_alarm_line_with_evidence(const std::string& log) {
  const std::string head = "warning: alarm level alarm (was ";
  for (std::size_t at = log.find(head); at != std::string::npos; at = log.find(head, at + 1)) {
    Cursor c{log, at + head.size()};
    if (!c.lower()) continue;
    const std::size_t close = log.find(')', c.i);
    if (close == std::string::npos || log.find('\n', c.i) < close) continue;
    c.i = close + 1;
    if (!c.lit(" at ") || parse_rfc3339_utc(log.substr(c.i, 24)) < 0.0) continue;
    c.i += 24;
    if (!c.lit(": ")) {
      if (!c.lit(" (evidence on the next line)\n")) continue;
      const std::size_t eol = log.find('\n', c.i);
      const std::string ev = "warning: alarm level alarm evidence: ";
      const std::size_t e = log.find(ev, c.i);
      if (e == std::string::npos || (eol != std::string::npos && e > eol)) continue;
      c.i = e + ev.size();
    }
    const auto band = [&] {
      return c.nonspace() && c.lit(" ") && (c.lit("in") || c.lit("out of")) && c.lit(" [") && c.nonspace() &&
             c.lit(" ") && c.nonspace();
    };
    if (c.lit("class ") && c.digits() && c.lit(", rms_res ") && band() && c.lit(" entropy_res ") && band() &&
        c.lit(" ") && c.digits() && c.lit(" of 10 abnormal (warn 1, alarm 4); cause ") &&
        (c.lit("rms+entropy") || c.lit("rms") || c.lit("entropy")))
      return true;
  }
  return false;
}

/// Checks one status.json text: every time (`*_s` except speeds) is >= 0, every `*_utc` parses and lies
/// within a day of the test's wall clock, and the named wall-clock fields are present and not null.
/// Returns the number of time fields checked.
int check_status_json(const std::string& json, const std::vector<std::string>& required_utc) {
  const double wall_now = static_cast<double>(std::time(nullptr));
  int times = 0;
  std::vector<std::string> seen_utc;
  for (const auto& [key, value] : json_scalars(json)) {
    const bool speed = key.size() >= 6 && key.compare(key.size() - 6, 6, "_rad_s") == 0;
    if (!speed && key.size() > 2 && key.compare(key.size() - 2, 2, "_s") == 0 && value != "null") {
      ++times;
      EXPECT_GE(std::strtod(value.c_str(), nullptr), 0.0) << key << " = " << value << " in " << json;
    }
    if (key.size() > 4 && key.compare(key.size() - 4, 4, "_utc") == 0) {
      if (value == "null" || value.size() < 2) {
        EXPECT_EQ(value, "null") << key;
        continue;
      }
      const double t = parse_rfc3339_utc(value.substr(1, value.size() - 2));
      EXPECT_GT(t, wall_now - 86400.0) << key << " = " << value;
      EXPECT_LT(t, wall_now + 86400.0) << key << " = " << value;
      seen_utc.push_back(key);
    }
  }
  for (const std::string& k : required_utc) {
    EXPECT_NE(std::find(seen_utc.begin(), seen_utc.end(), k), seen_utc.end()) << k << " missing in " << json;
  }
  return times;
}

/// Every `*_seconds` sample of the Prometheus text is >= 0; `*_timestamp_seconds` are unix times within a
/// day of now. Returns the number checked.
int check_metrics(const std::string& prom) {
  const double wall_now = static_cast<double>(std::time(nullptr));
  std::istringstream in(prom);
  std::string line;
  int n = 0;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    const std::size_t sp = line.rfind(' ');
    std::string name = line.substr(0, line.find_first_of("{ "));
    if (name.size() < 8 || name.compare(name.size() - 8, 8, "_seconds") != 0) continue;
    const double v = std::strtod(line.c_str() + sp + 1, nullptr);
    ++n;
    EXPECT_GE(v, 0.0) << line;
    if (name.find("_timestamp_seconds") != std::string::npos) {
      EXPECT_GT(v, wall_now - 86400.0) << line;
      EXPECT_LT(v, wall_now + 86400.0) << line;
    }
  }
  return n;
}

struct Outcome {
  DaemonView view;
  std::string status_json, metrics, log;
  std::vector<std::string> snapshots;  ///< status.json texts read while the daemon ran
};

/// Replays `scenario` (seed 7) at fast pace against the healthy arc baseline until the end.
Outcome replay(const std::string& name, const std::string& scenario) {
  const fs::path dir = scratch(name);
  write_sim_baseline(dir / "baseline.bin");
  std::string cfg = sim_config(dir / "baseline.bin", dir / "status", "fast",
                               "metrics_path = \"" + (dir / "ptda.prom").string() + "\"\n");
  const std::string healthy = arc_scenario().string();
  cfg.replace(cfg.find(healthy), healthy.size(), (arc_scenario().parent_path() / scenario).string());
  const std::string pace = "pace = \"fast\"\n";  // the first one is [adc]'s: one pass, then the end
  cfg.insert(cfg.find(pace) + pace.size(), "loop = false\n");
  write_text(dir / "ptdad.toml", cfg);
  LogCapture log;
  DaemonOptions opt;
  opt.config_file = dir / "ptdad.toml";
  opt.config_dir = fs::path();
  drivers::MonotonicClock clock;
  Daemon d(opt, clock);
  d.configure();
  d.activate();
  Outcome r;
  {
    DaemonRunThread runner(d);
    // Until the replay ended and the supervisor wrote that state, then stop (not --exit-at-end: its
    // last status.json says "stopping").
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
    while (std::chrono::steady_clock::now() < deadline) {
      std::string s = read_text(dir / "status" / "status.json");
      if (!s.empty() && s.back() == '\n') {
        if (r.snapshots.empty() || r.snapshots.back() != s) r.snapshots.push_back(s);
        const DaemonView v = d.view();
        // status.json is replaced before the metrics file: wait for both to show the end.
        if ((v.phase == Phase::kEnded || v.phase == Phase::kNotJudging) && has(s, "\"state\":\"ended\"") &&
            has(read_text(dir / "ptda.prom"), "\nptda_state{state=\"ended\"} 1\n")) {
          break;
        }
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    r.view = d.view();
    r.status_json = read_text(dir / "status" / "status.json");
    r.metrics = read_text(dir / "ptda.prom");
  }
  r.log = log.text();
  return r;
}

class StatusTimes : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { block_daemon_signals(); }
};

TEST(StatusTimesFormat, Rfc3339Utc) {
  char buf[32];
  ASSERT_EQ(format_rfc3339_utc(0, buf, sizeof buf), 24U);
  EXPECT_STREQ(buf, "1970-01-01T00:00:00.000Z");
  // 1795581067.250999 s: `date -u -d @1795581067` = Wed Nov 25 04:31:07 UTC 2026; ms truncated.
  ASSERT_EQ(format_rfc3339_utc(1'795'581'067'250'999'000, buf, sizeof buf), 24U);
  EXPECT_STREQ(buf, "2026-11-25T04:31:07.250Z");
  EXPECT_DOUBLE_EQ(parse_rfc3339_utc(buf), 1795581067.25);
  EXPECT_EQ(format_rfc3339_utc(-1, buf, sizeof buf), 0U);
  EXPECT_EQ(format_rfc3339_utc(0, buf, 24), 0U);  // no room for the NUL
}

// The parsers above, on texts whose answer is known (they must be able to say no).
TEST(StatusTimesParsers, RecogniseWhatTheyShouldAndNothingElse) {
  EXPECT_DOUBLE_EQ(parse_rfc3339_utc("2026-11-25T04:31:07.250Z"), 1795581067.25);
  EXPECT_EQ(parse_rfc3339_utc("2026-11-25 04:31:07.250Z"), -1.0);
  EXPECT_EQ(parse_rfc3339_utc("2026-13-25T04:31:07.250Z"), -1.0);
  EXPECT_EQ(parse_rfc3339_utc("2026-11-25T04:31:07.250Zx"), -1.0);
  const auto f = json_scalars(R"({"a_s":1.5,"b":{"c_utc":"2026"},"d":null,"ok":true,"e":-2e-3,"F":3})");
  ASSERT_EQ(f.size(), 4U);
  EXPECT_EQ(f[0], (std::pair<std::string, std::string>{"a_s", "1.5"}));
  EXPECT_EQ(f[1], (std::pair<std::string, std::string>{"c_utc", "\"2026\""}));
  EXPECT_EQ(f[2], (std::pair<std::string, std::string>{"d", "null"}));
  EXPECT_EQ(f[3], (std::pair<std::string, std::string>{"e", "-2e-3"}));
  const std::string one =
      "x warning: alarm level alarm (was warning, 3 more) at 2026-11-25T04:31:07.250Z: class 0, rms_res 1.2 "
      "out "
      "of [0.1, 0.9], entropy_res 0.7 in [0.5, 0.8], 4 of 10 abnormal (warn 1, alarm 4); cause rms\n";
  EXPECT_TRUE(has_alarm_line_with_evidence(one));
  const std::string two =
      "x warning: alarm level alarm (was normal) at 2026-11-25T04:31:07.250Z (evidence on the next line)\n"
      "y warning: alarm level alarm evidence: class 2, rms_res 1.2 in [0.1, 1.9], entropy_res 0.3 out of "
      "[0.5, "
      "0.8], 5 of 10 abnormal (warn 1, alarm 4); cause entropy\n";
  EXPECT_TRUE(has_alarm_line_with_evidence(two));
  std::string bad = one;
  bad.replace(bad.find("(warn 1"), 7, "(warn 2");
  EXPECT_FALSE(has_alarm_line_with_evidence(bad));
  EXPECT_FALSE(has_alarm_line_with_evidence("warning: alarm level alarm (was normal) at yesterday: class 0"));
}

TEST_F(StatusTimes, HealthyReplayHasNoNegativeTimeAndWallClockTimes) {
  const Outcome r = replay("status_times_healthy", "arc_welding_healthy.toml");
  ASSERT_GT(r.view.pipeline.scored, 10U);
  // Final files: the last window, the alarm level and the snapshot itself carry UTC times.
  EXPECT_GE(check_status_json(r.status_json, {"now_utc", "t_utc", "since_utc"}), 8) << r.status_json;
  const std::size_t now_at = r.status_json.find("\"now_s\":");
  ASSERT_NE(now_at, std::string::npos) << r.status_json;
  EXPECT_GT(std::strtod(r.status_json.c_str() + now_at + 8, nullptr), 0.0);  // was always 0
  EXPECT_GE(check_metrics(r.metrics), 6) << r.metrics;
  EXPECT_TRUE(has(r.metrics, "\nptda_window_age_seconds ")) << r.metrics;
  EXPECT_TRUE(has(r.metrics, "\nptda_alarm_level_duration_seconds ")) << r.metrics;
  EXPECT_TRUE(has(r.metrics, "\nptda_alarm_level_since_timestamp_seconds ")) << r.metrics;
  EXPECT_TRUE(has(r.metrics, "\nptda_window_end_timestamp_seconds ")) << r.metrics;
  EXPECT_TRUE(has(r.metrics, "\nptda_status_timestamp_seconds ")) << r.metrics;
  // Every status.json written during the replay as well (the data ran ahead of the clock then).
  ASSERT_GE(r.snapshots.size(), 1U);
  for (const std::string& s : r.snapshots) check_status_json(s, {"now_utc"});
}

TEST_F(StatusTimes, AlarmLevelChangesAreLoggedWithEvidence) {
  // The faulty arc job against the healthy baseline raises the alarm (k = 4 of n = 10,
  // config/examples/arc_welding.toml).
  const Outcome r = replay("status_times_faulty", "arc_welding_faulty.toml");
  ASSERT_GT(r.view.pipeline.alarm_counters.alarms_raised, 0U);
  // The first verdict after "not judged yet", and the alarm with the window that raised it.
  EXPECT_TRUE(has(r.log, "alarm level normal (was fault") || has(r.log, "alarm level warning (was fault") ||
              has(r.log, "alarm level alarm (was fault"))
      << r.log;
  EXPECT_TRUE(has_alarm_line_with_evidence(r.log)) << r.log;
  // The end of the replay ends the verdict: fault, no cause, phase "replay ended".
  EXPECT_TRUE(has(r.log, "no verdict (replay ended); cause none") || r.view.pipeline.alarm.alarm_active)
      << r.log;
}

TEST_F(StatusTimes, EndOfReplayIsItsOwnPhaseNotASensorFault) {
  const Outcome r = replay("status_times_end", "arc_welding_healthy.toml");
  EXPECT_EQ(r.view.phase, Phase::kEnded) << phase_name(r.view.phase);
  EXPECT_EQ(r.view.state, DaemonState::kEnded);
  EXPECT_EQ(r.view.pipeline.report.level, drivers::AlarmLevel::kFault);  // no verdict after the end
  EXPECT_EQ(r.view.pipeline.report.causes & drivers::kCauseSensor, 0);
  EXPECT_EQ(r.view.pipeline.fault_causes, 0);
  EXPECT_TRUE(
      has(r.status_json, "\"state\":\"ended\",\"phase\":\"replay ended\",\"reason\":\"replay ended; "))
      << r.status_json;
  EXPECT_FALSE(has(r.status_json, "\"sensor\"")) << r.status_json;
  EXPECT_TRUE(has(r.metrics, "\nptda_state{state=\"ended\"} 1\n")) << r.metrics;
  EXPECT_TRUE(has(r.metrics, "\nptda_alarm_cause{cause=\"sensor\"} 0\n")) << r.metrics;
  EXPECT_TRUE(has(r.log, "info: state ended (replay ended): replay ended; ")) << r.log;
}

// The band CUSUM is on by default (session 13). A baseline without band statistics (format <= 6, or
// trained with it off) still monitors; configure() logs at warning level why the band detector is off.
// With a baseline that has them, nothing is said.
TEST_F(StatusTimes, ABaselineWithoutBandStatisticsIsLoggedAsBandDetectorOff) {
  const fs::path dir = scratch("band_off_log");
  write_sim_baseline(dir / "with_bands.bin");
  dsp::Baseline b = formats::read_baseline(dir / "with_bands.bin");
  ASSERT_GT(b.policy.band_count, 0U) << "the default training stores band statistics";
  b.policy.band_count = 0;
  for (dsp::ClassBaseline& c : b.classes) c.band_stats.clear();
  formats::write_baseline(dir / "no_bands.bin", b);
  for (const bool bands : {false, true}) {
    const fs::path base = dir / (bands ? "with_bands.bin" : "no_bands.bin");
    write_text(dir / "ptdad.toml", sim_config(base, dir / "status", "fast"));
    LogCapture log;
    DaemonOptions opt;
    opt.config_file = dir / "ptdad.toml";
    opt.config_dir = fs::path();
    drivers::MonotonicClock clock;
    Daemon d(opt, clock);
    d.configure();
    const std::string text = log.text();
    EXPECT_EQ(has(text, "warning: band detector off: the baseline has no band statistics"), !bands) << text;
  }
}

}  // namespace
}  // namespace ptda::daemon::test
