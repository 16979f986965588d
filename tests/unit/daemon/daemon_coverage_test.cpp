// Coverage through ptdad's real threads (docs/daemon.md, "Coverage"): the simulated healthy arc-welding
// job is replayed from memory (daemon_fakes.hpp) with its speed frames re-encoded, so the vibration is
// the one the baseline was trained on but the speeds the daemon sees are not. Checked in every output:
// the phase, status.json, the Prometheus file, STATUS=, the recorded output and the CAN verdict frames.
// Every expected count comes from a run of the same input (the sink's windows), never from the preset.
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <atomic>
#include <functional>
#include <limits>
#include <mutex>
#include <thread>

#include "alarm/can_alarm_output.hpp"
#include "daemon_fakes.hpp"
#include "daemon_test_support.hpp"
#include "fake_service_manager.hpp"
#include "ptda/config/speed_codec.hpp"
#include "status_text.hpp"

namespace ptda::daemon::test {
namespace {

using drivers::AlarmLevel;

std::shared_ptr<const SimRecording> healthy() {
  static const auto rec = make_sim_recording(arc_scenario(), 7);
  return rec;
}

struct Sink final : WindowSink {
  Sink() { w.resize(8192); }
  void on_window(const dsp::WindowResult& r) noexcept override {
    if (n < w.size()) w[n++] = r;
  }
  [[nodiscard]] std::vector<dsp::WindowResult> windows() const {
    return {w.begin(), w.begin() + static_cast<std::ptrdiff_t>(n)};
  }
  std::vector<dsp::WindowResult> w;
  std::size_t n = 0;
};

constexpr double kTimeoutS = 5.0;

std::string coverage_config(const fs::path& dir) {
  return "[daemon]\nbaseline = \"" + (dir / "baseline.bin").string() + "\"\nstatus_dir = \"" +
         (dir / "status").string() + "\"\nmetrics_path = \"" + (dir / "ptda.prom").string() +
         "\"\nstatus_period_s = 0.05\ncoverage_timeout_s = " + std::to_string(kTimeoutS) +
         "\n\n[adc]\nbackend = \"wav\"\nrecording = \"" + (dir / "not-opened").string() +
         "\"\npace = \"fast\"\n\n[can]\nbackend = \"candump\"\npace = \"fast\"\n\n[alarm.can]\nenabled = "
         "true\nid = 0x3A0\n\n" +
         arc_pipeline();
}

/// The healthy job's frames with every decoded speed passed through f(t_ns, speed) and re-encoded.
template <typename F>
std::shared_ptr<ChannelPlan> frames_with(const config::SpeedFrameSpec& spec, F f) {
  auto p = std::make_shared<ChannelPlan>();
  for (const CanFrame& c : healthy()->frames) {
    config::DecodedSpeed d;
    if (config::decode_speed(c, spec, d) != config::DecodeResult::kOk) {
      p->frames.push_back(c);
      continue;
    }
    CanFrame g =
        config::encode_speed(spec, c.t_ns, f(c.t_ns, d.speed_rad_s), d.has_angle ? d.angle_rad : 0.0);
    g.t_ns = c.t_ns;
    p->frames.push_back(g);
  }
  return p;
}

using ptda::test::has;
using ptda::test::read_text;

struct RunOutcome {
  std::vector<dsp::WindowResult> windows;
  DaemonView view;
  std::string status_json, metrics;
  std::vector<drivers::AlarmReport> shown;  ///< every verdict the recording output got
  std::vector<drivers::AlarmReport> can;    ///< every verdict frame on the bus
  std::vector<std::string> notify;
  int code = -1;
};

/// Runs the replay to its end. With a gate, only data up to gate_ns (stream time) is released until
/// `during` returned (it runs while the daemon does), so a test can look at an intermediate state.
RunOutcome run(const fs::path& dir, const std::shared_ptr<ChannelPlan>& frames,
               std::int64_t gate_ns = std::numeric_limits<std::int64_t>::max(),
               const std::function<void(Daemon&, FakeManager&)>& during = {}) {
  write_text(dir / "ptdad.toml", coverage_config(dir));
  const auto source = std::make_shared<SourcePlan>(plan_blocks(*healthy(), 512));
  FakeDevices dev(source, frames, /*recording_output=*/true);
  FakeManager manager(dir / "notify.sock");
  EXPECT_TRUE(manager.bound());
  DaemonOptions opt;
  opt.config_file = dir / "ptdad.toml";
  opt.config_dir = fs::path();
  opt.exit_at_end = true;
  opt.notify_socket = (dir / "notify.sock").string();
  drivers::MonotonicClock clock;
  Sink sink;
  Daemon d(opt, clock);
  d.set_window_sink(&sink);
  d.set_device_factory(&dev);
  dev.gate.t_ns = gate_ns;
  d.configure();
  d.activate();
  RunOutcome r;
  std::thread runner([&] { r.code = d.run(); });
  if (during) during(d, manager);
  dev.gate.t_ns = std::numeric_limits<std::int64_t>::max();
  runner.join();
  r.view = d.view();
  r.windows = sink.windows();
  r.status_json = read_text(dir / "status" / "status.json");
  r.metrics = read_text(dir / "ptda.prom");
  for (const auto& rep : dev.last_output->reports()) r.shown.push_back(rep);
  drivers::CanAlarmConfig ac;
  ac.id = 0x3A0;
  for (const CanFrame& f : dev.last_channel->sent()) {
    drivers::AlarmReport rep;
    std::uint8_t alive = 0;
    if (drivers::decode_alarm_frame(f, ac, rep, alive)) r.can.push_back(rep);
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(50));  // the last datagrams
  r.notify = manager.messages();
  return r;
}

std::size_t scored(const std::vector<dsp::WindowResult>& ws, std::int32_t cls = -1) {
  std::size_t n = 0;
  for (const auto& w : ws)
    n += w.status == dsp::WindowStatus::kScored && (cls < 0 || w.class_id == cls) ? 1 : 0;
  return n;
}

/// No verdict says normal before a window was judged: until then the report has no segment class.
void expect_no_normal_before_judged(const std::vector<drivers::AlarmReport>& reports) {
  for (std::size_t i = 0; i < reports.size(); ++i) {
    if (reports[i].segment_class != drivers::kNoSegmentClass) break;
    EXPECT_NE(reports[i].level, AlarmLevel::kNormal) << "verdict " << i << " before the first judged window";
  }
}

class Coverage : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { block_daemon_signals(); }
};

config::SpeedFrameSpec spec_of(const fs::path& dir) {
  return parse_daemon_config(coverage_config(dir), "spec.toml").pipeline.speed_frame;
}

// The arc job's classes are +4.10, +1.00, +0.50, -2.50 and -1.20 rad/s: 1.5 times each matches none.
TEST_F(Coverage, SpeedsMatchingNoClassEndNotJudgingInEveryOutput) {
  const fs::path dir = scratch("coverage_none");
  write_sim_baseline(dir / "baseline.bin");
  const RunOutcome r = run(dir, frames_with(spec_of(dir), [](std::int64_t, double v) { return 1.5 * v; }));
  ASSERT_EQ(r.code, 0);
  ASSERT_GT(r.windows.size(), 20U);
  ASSERT_EQ(scored(r.windows), 0U);  // the premise: nothing matches

  EXPECT_EQ(r.view.phase, Phase::kNotJudging) << phase_name(r.view.phase);
  EXPECT_EQ(r.view.pipeline.report.level, AlarmLevel::kFault);
  EXPECT_NE(r.view.pipeline.report.causes & drivers::kCauseCoverage, 0);
  const dsp::CoverageState& c = r.view.pipeline.coverage;
  EXPECT_EQ(c.level, dsp::CoverageLevel::kNotJudging);
  EXPECT_EQ(c.judged, 0U);
  EXPECT_EQ(c.unmatched[static_cast<std::size_t>(dsp::UnmatchedReason::kSpeed)], r.windows.size());
  EXPECT_GT(c.moving_since_judged_s(), kTimeoutS);
  EXPECT_TRUE(has(std::string(r.view.reason.view()), "not judging: no window matches a trained class (seen "))
      << r.view.reason.view();

  // status.json: reason, cause and the coverage object.
  EXPECT_TRUE(has(r.status_json, "\"reason\":\"not judging: no window matches a trained class (seen "))
      << r.status_json;
  // The end of the replay adds no cause of its own (it used to show as a sensor fault).
  EXPECT_TRUE(has(r.status_json, "\"causes\":[\"coverage\"]")) << r.status_json;
  EXPECT_TRUE(has(r.status_json,
                  "\"coverage\":{\"state\":\"not judging\",\"timeout_s\":5,\"judged\":0,"
                  "\"unmatched\":{\"speed\":" +
                      std::to_string(r.windows.size()) + ",\"direction\":0,\"invalid\":0}"))
      << r.status_json;
  // Metrics.
  EXPECT_TRUE(has(r.metrics, "\nptda_windows_judged_total 0\n")) << r.metrics;
  EXPECT_TRUE(has(r.metrics, "\nptda_windows_unmatched_total{reason=\"speed\"} " +
                                 std::to_string(r.windows.size()) + "\n"));
  EXPECT_TRUE(has(r.metrics, "\nptda_coverage_state{state=\"not judging\"} 1\n"));
  EXPECT_TRUE(has(r.metrics, "\nptda_alarm_cause{cause=\"coverage\"} 1\n"));
  EXPECT_TRUE(has(r.metrics, "\nptda_last_judged_window_age_seconds "));
  // Outputs: never normal; the CAN frame carries cause bit 6 (coverage).
  ASSERT_FALSE(r.shown.empty());
  bool coverage_frame = false;
  for (const auto& rep : r.shown) EXPECT_NE(rep.level, AlarmLevel::kNormal);
  for (const auto& rep : r.can) {
    EXPECT_NE(rep.level, AlarmLevel::kNormal);
    coverage_frame = coverage_frame || (rep.level == AlarmLevel::kFault && (rep.causes & 0x40) != 0);
  }
  EXPECT_TRUE(coverage_frame);
  // STATUS=.
  bool status_seen = false;
  for (const auto& m : r.notify) {
    status_seen = status_seen || (m.rfind("STATUS=running (not judging): ", 0) == 0 && has(m, "0 judged") &&
                                  has(m, "alarm fault; not judging: no window matches"));
  }
  EXPECT_TRUE(status_seen);
}

// Class 1 (+1.00 rad/s) runs at 1.5 rad/s from half-time on: the other classes go on being judged,
// class 1 stops, and the coverage ends partial without a fault.
TEST_F(Coverage, AClassThatDisappearsMidRunIsReportedPartial) {
  const fs::path dir = scratch("coverage_partial");
  write_sim_baseline(dir / "baseline.bin");
  const config::SpeedFrameSpec spec = spec_of(dir);
  const RunOutcome clean = run(dir, frames_with(spec, [](std::int64_t, double v) { return v; }));
  ASSERT_EQ(clean.code, 0);
  const auto half_ns =
      static_cast<std::int64_t>(0.5e9 * static_cast<double>(healthy()->samples.size()) / healthy()->fs_hz);
  const RunOutcome r = run(dir, frames_with(spec, [&](std::int64_t t, double v) {
                             return t >= half_ns && v > 0.9 && v < 1.1 ? 1.5 * v : v;
                           }));
  ASSERT_EQ(r.code, 0);

  // Which class is +1.00 rad/s: the clean run judged it (class ids are by speed, forward first).
  std::int32_t cls = -1;
  for (const auto& w : clean.windows) {
    if (w.status == dsp::WindowStatus::kScored && w.ref.speed_rad_s > 0.9 && w.ref.speed_rad_s < 1.1)
      cls = w.class_id;
  }
  ASSERT_GE(cls, 0);
  const dsp::CoverageState& c = r.view.pipeline.coverage;
  const auto k = static_cast<std::size_t>(cls);
  EXPECT_GT(c.classes[k].judged, 0U);
  EXPECT_LT(c.classes[k].judged, scored(clean.windows, cls));
  EXPECT_EQ(c.classes[k].judged, scored(r.windows, cls));
  EXPECT_GT(c.unmatched[static_cast<std::size_t>(dsp::UnmatchedReason::kSpeed)], 0U);
  for (std::uint32_t i = 0; i < c.class_count; ++i) {
    if (i == k) continue;
    EXPECT_EQ(c.classes[i].judged, scored(clean.windows, static_cast<std::int32_t>(i))) << "class " << i;
    EXPECT_TRUE(c.class_current(i, kTimeoutS)) << "class " << i;
  }
  EXPECT_FALSE(c.class_current(static_cast<std::uint32_t>(cls), kTimeoutS));
  EXPECT_EQ(c.level, dsp::CoverageLevel::kPartial);
  EXPECT_EQ(r.view.phase, Phase::kEnded) << phase_name(r.view.phase);
  EXPECT_EQ(r.view.pipeline.report.causes & drivers::kCauseCoverage, 0);
  for (const auto& rep : r.shown) EXPECT_EQ(rep.causes & drivers::kCauseCoverage, 0);
  // The unmatched speed bin is the moved class: 1.5 rad/s.
  bool bin = false;
  for (std::uint32_t i = 0; i < c.speed_bins; ++i)
    bin = bin || std::abs(c.speeds[i].speed_rad_s - 1.5) < 0.05;
  EXPECT_TRUE(bin);
  EXPECT_TRUE(has(r.status_json, "\"coverage\":{\"state\":\"partial\"")) << r.status_json;
  EXPECT_TRUE(has(r.status_json,
                  "{\"id\":" + std::to_string(cls) + ",\"judged\":" + std::to_string(c.classes[k].judged)));
  EXPECT_TRUE(has(r.metrics, "\nptda_coverage_state{state=\"partial\"} 1\n"));
  EXPECT_TRUE(has(r.metrics, "\nptda_class_windows_judged_total{class=\"" + std::to_string(cls) + "\"} " +
                                 std::to_string(c.classes[k].judged) + "\n"));
  // The end of the replay says so: status.json's reason and the last STATUS=.
  const std::string partial =
      "partial coverage: class " + std::to_string(cls) + " (+1.00 rad/s) not judged for ";
  EXPECT_TRUE(has(r.status_json, partial)) << r.status_json;
  std::string last_status;
  for (const auto& m : r.notify)
    if (m.rfind("STATUS=", 0) == 0) last_status = m;
  EXPECT_TRUE(has(last_status, partial)) << last_status;
  // The clean run: full coverage, and no normal before the first judged window.
  EXPECT_EQ(clean.view.pipeline.coverage.level, dsp::CoverageLevel::kFull);
  expect_no_normal_before_judged(clean.shown);
  expect_no_normal_before_judged(clean.can);
  EXPECT_EQ(clean.shown.front().level, AlarmLevel::kFault);
}

// The first ~25 s run at 1.5 times the speed (no class), the rest as trained: the daemon enters
// "not judging" (fault, cause coverage) and leaves it when judged windows come back.
TEST_F(Coverage, CoverageRecoversWhenJudgedWindowsComeBack) {
  const fs::path dir = scratch("coverage_recover");
  write_sim_baseline(dir / "baseline.bin");
  constexpr std::int64_t kBlindUntilNs = 25'000'000'000;
  // The data is held at the end of the blind stretch until the daemon shows it, then released.
  bool held_not_judging = false, held_status = false;
  const RunOutcome r =
      run(dir,
          frames_with(spec_of(dir), [](std::int64_t t, double v) { return t < kBlindUntilNs ? 1.5 * v : v; }),
          kBlindUntilNs, [&](Daemon& d, FakeManager& m) {
            held_not_judging = wait_for([&] { return d.view().phase == Phase::kNotJudging; });
            held_status = wait_for([&] {
              for (const auto& msg : m.messages())
                if (has(msg, "STATUS=running (not judging): ")) return true;
              return false;
            });
          });
  EXPECT_TRUE(held_not_judging);
  EXPECT_TRUE(held_status);
  ASSERT_EQ(r.code, 0);
  ASSERT_GT(scored(r.windows), 0U);
  // The verdicts in order: fault (not judged yet, no cause), then fault with cause coverage, then normal.
  std::size_t first_coverage = r.shown.size(), first_normal = r.shown.size();
  for (std::size_t i = 0; i < r.shown.size(); ++i) {
    if (first_coverage == r.shown.size() && (r.shown[i].causes & drivers::kCauseCoverage) != 0)
      first_coverage = i;
    if (first_normal == r.shown.size() && r.shown[i].level == AlarmLevel::kNormal) first_normal = i;
  }
  ASSERT_LT(first_coverage, r.shown.size());
  ASSERT_LT(first_normal, r.shown.size());
  EXPECT_LT(first_coverage, first_normal);
  EXPECT_EQ(r.shown[first_coverage].level, AlarmLevel::kFault);
  EXPECT_EQ(r.shown.front().level, AlarmLevel::kFault);
  EXPECT_EQ(r.shown.front().causes, 0);  // "not judged yet"
  expect_no_normal_before_judged(r.shown);
  expect_no_normal_before_judged(r.can);
  // Once judged windows are back the coverage cause is gone and stays gone.
  for (std::size_t i = first_normal; i < r.shown.size(); ++i)
    EXPECT_EQ(r.shown[i].causes & drivers::kCauseCoverage, 0) << "verdict " << i;
  const dsp::CoverageState& c = r.view.pipeline.coverage;
  EXPECT_NE(c.level, dsp::CoverageLevel::kNotJudging);
  EXPECT_EQ(c.judged, scored(r.windows));
  EXPECT_EQ(c.judged + c.unmatched[0] + c.unmatched[1], r.windows.size());
  EXPECT_EQ(r.view.phase, Phase::kEnded) << phase_name(r.view.phase);
  bool entered = false, left = false;
  for (const auto& m : r.notify) {
    if (has(m, "STATUS=running (not judging)")) entered = true;
    if (entered && (has(m, "STATUS=running (monitoring)") || has(m, "(replay ended)"))) left = true;
  }
  EXPECT_TRUE(entered);
  EXPECT_TRUE(left);
}

}  // namespace
}  // namespace ptda::daemon::test
