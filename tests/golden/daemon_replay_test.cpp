// End-to-end: the daemon's real threads give the same windows as `ptda monitor`.
//   For each paper job: `ptda simulate` a healthy (seed 1001) and a faulty (seed 3003) recording,
//   `ptda train` on the healthy one, `ptda monitor --jsonl` the faulty one; then run ptdad's Daemon
//   in-process (configure -> activate -> run, acquisition/CAN/processing/supervisor threads) on the
//   faulty recording with the WAV replay and candump replay backends at "fast" pace, collect every
//   WindowResult on the processing thread and print each with the CLI's window_json(): every line
//   must equal the JSONL line (window times, class, features to the last printed digit, bands,
//   verdict, k-of-n alarm). Times are mapped back from the daemon clock with the recording's t0.
// The order domain (issue 16, docs/method.md §9): the same comparison on the joint-rotation job of
// tests/golden/order_domain_test.cpp (same seeds, same order configuration), the daemon's resampler and
// window cutter against `ptda monitor`'s: a healthy run stays normal, the spur-tooth run alarms.
// A second test runs the built `ptdad` binary on the same replay (--exit-at-end) and checks its
// status.json counts, and --check-config's exit codes and located error message.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "core/daemon.hpp"
#include "core/daemon_config.hpp"
#include "core/pipeline.hpp"
#include "golden_support.hpp"
#include "ptda/cli/monitor_output.hpp"
#include "ptda/cli/pipeline_runner.hpp"
#include "ptda/common/time.hpp"
#include "ptda/drivers/clock.hpp"
#include "ptda/formats/recording.hpp"

namespace ptda::golden {
namespace {

/// Collects every processed window (processing thread); the vector is reserved up front.
class Collector final : public daemon::WindowSink {
 public:
  Collector() { windows.reserve(100000); }
  void on_window(const dsp::WindowResult& w) noexcept override {
    if (windows.size() < windows.capacity()) windows.push_back(w);
  }
  std::vector<dsp::WindowResult> windows;
};

// The job's example configuration, with `decision` (e.g. "band_cusum = true\n") added to its [decision]
// table.
std::string job_config_text(const std::string& job, const std::string& decision) {
  std::ifstream in(source_dir() / "config" / "examples" / (job + ".toml"));
  std::string line, out;
  while (std::getline(in, line)) {
    out += line + "\n";
    if (line == "[decision]") out += decision;
  }
  return out;
}

std::string job_pipeline(const std::string& job, const std::string& decision = "") {
  // The job's pipeline tables without [can] (the daemon file has its own [can] table below).
  std::istringstream in(job_config_text(job, decision));
  std::string line, out;
  bool skip = false;
  while (std::getline(in, line)) {
    if (!line.empty() && line[0] == '[') skip = line == "[can]";
    if (!skip) out += line + "\n";
  }
  return out;
}

fs::path write_daemon_config(const fs::path& dir, const std::string& job, const fs::path& recording,
                             const fs::path& baseline, const std::string& decision = "") {
  const fs::path path = dir / "ptdad.toml";
  std::ofstream out(path);
  out << "[daemon]\nbaseline = \"" << baseline.string() << "\"\nstatus_dir = \"" << (dir / "status").string()
      << "\"\nstatus_period_s = 0.05\n\n[adc]\nbackend = \"wav\"\nrecording = \"" << recording.string()
      << "\"\npace = \"fast\"\nblock_len = 1000\n\n[can]\nbackend = \"candump\"\npace = \"fast\"\n"
      << "speed_latency_s = 0.0\n\n[alarm]\nmin_hold_s = 0.0\nlatch = false\n\n"
      << job_pipeline(job, decision);
  return path;
}

struct Prepared {
  fs::path dir, faulty, baseline, jsonl, config;
  std::vector<std::string> lines;
};

// `tag` keeps each test's scratch directory its own: ctest runs the tests of this binary as separate
// processes in parallel, and a shared directory would be wiped by the other test mid-run.
Prepared prepare(const std::string& job, const std::string& tag = "threads",
                 const std::string& decision = "") {
  Prepared p;
  p.dir = scratch_dir("daemon_replay_" + tag + "_" + job);
  const std::string scen = (source_dir() / "config" / "scenarios").string() + "/" + job;
  std::string cfg = (source_dir() / "config" / "examples" / (job + ".toml")).string();
  if (!decision.empty()) {
    cfg = (p.dir / (job + "_" + tag + ".toml")).string();
    std::ofstream(cfg) << job_config_text(job, decision);
  }
  p.faulty = p.dir / "faulty";
  p.baseline = p.dir / "baseline.bin";
  p.jsonl = p.dir / "faulty.jsonl";
  EXPECT_EQ(run_ptda({"simulate", "--scenario", scen + "_healthy.toml", "--out", (p.dir / "train").string(),
                      "--seed", "1001"},
                     p.dir, "sim_train")
                .exit_code,
            0);
  EXPECT_EQ(run_ptda({"simulate", "--scenario", scen + "_faulty.toml", "--out", p.faulty.string(), "--seed",
                      "3003"},
                     p.dir, "sim_faulty")
                .exit_code,
            0);
  EXPECT_EQ(run_ptda({"train", "--recording", (p.dir / "train").string(), "--config", cfg, "--out",
                      p.baseline.string()},
                     p.dir, "train")
                .exit_code,
            0);
  const RunResult m = run_ptda({"monitor", "--recording", p.faulty.string(), "--config", cfg, "--baseline",
                                p.baseline.string(), "--jsonl", p.jsonl.string(), "--quiet"},
                               p.dir, "monitor");
  EXPECT_EQ(m.exit_code, 0) << m.err;
  std::ifstream in(p.jsonl);
  std::string line;
  while (std::getline(in, line)) p.lines.push_back(line);
  p.config = write_daemon_config(p.dir, job, p.faulty, p.baseline, decision);
  return p;
}

struct Pinned {
  const char* job;
  std::size_t windows;  ///< windows in the faulty recording's JSONL
  std::size_t alarm_windows;
};

// Measured with the seeds above (and equal to tests/golden/paper_jobs_test.cpp's window counts); arc
// welding re-measured after its example config moved to k = 4 of n = 10 and the presets gained
// cycle-to-cycle variation. Re-pinned for issue 12 (CUSUM beside k-of-n, tolerance bands): the CUSUM
// holds the alarm from the first faulty window on (k-of-n alone: 38, 89, 18). Session 38 (the feature
// CUSUM's step cap of 2.5 per window): arc welding's alarm starts at window 5, so 96 of its 101 windows
// (docs/method.md §6 "Step cap"); the other two are held by the uncapped band CUSUM from window 0.
// The band CUSUM on spot welding's faulty recording (full severity; measured with the seeds above): it
// alarms from the first window, in band 7 of 32 (bins 1121..1280 of 2.5 Hz: 2802.5-3200 Hz).
constexpr std::size_t kBandFirstAlarm = 0;
constexpr std::int32_t kBandFirstAlarmBand = 7;

constexpr Pinned kJobs[] = {{"joint_rotation", 40, 40}, {"arc_welding", 101, 96}, {"spot_welding", 20, 20}};

/// The daemon's coverage tracker reached the state `ptda monitor`'s did (same windows, same speed
/// samples, same motion time).
void expect_same_coverage(const dsp::CoverageState& dc, const dsp::CoverageState& mc) {
  EXPECT_EQ(dc.judged, mc.judged);
  EXPECT_EQ(dc.unmatched, mc.unmatched);
  EXPECT_EQ(dc.moving_ns, mc.moving_ns);
  EXPECT_EQ(dc.level, mc.level);
  for (std::size_t k = 0; k < dsp::kCoverageMaxClasses; ++k)
    EXPECT_EQ(dc.classes[k].judged, mc.classes[k].judged);
}

class DaemonReplay : public ::testing::TestWithParam<Pinned> {};

// Replays p's faulty recording through ptdad's threads and expects every window to give the JSONL line
// `ptda monitor` wrote, and the same coverage. Returns the daemon's windows.
std::vector<dsp::WindowResult> expect_daemon_equals_monitor(const Prepared& p, const std::string& job,
                                                            const std::string& cfg) {
  Collector collector;
  drivers::MonotonicClock clock;
  daemon::DaemonOptions opt;
  opt.config_file = p.config;
  opt.config_dir = fs::path();
  opt.exit_at_end = true;
  daemon::Daemon d(opt, clock);
  d.set_window_sink(&collector);
  d.configure();
  d.activate();
  EXPECT_EQ(d.run(), 0);
  const daemon::DaemonView v = d.view();
  EXPECT_TRUE(v.pipeline.ended);
  EXPECT_EQ(v.pipeline.phase, daemon::Phase::kEnded);
  EXPECT_EQ(v.counters.acq_ring_full_blocks, 0U);  // fast replay: back-pressure, never a drop
  EXPECT_EQ(v.counters.can_ring_full, 0U);
  EXPECT_EQ(v.pipeline.gap_samples, 0U);

  const formats::RecordingMeta meta = formats::read_recording_meta(p.faulty);
  const std::int64_t shift = seconds_to_ns(meta.start_time_s) - v.pipeline.t0_mono_ns;
  EXPECT_EQ(collector.windows.size(), p.lines.size());
  for (std::size_t i = 0; i < std::min(p.lines.size(), collector.windows.size()); ++i) {
    dsp::WindowResult& w = collector.windows[i];
    w.ref.t_start_ns += shift;
    w.ref.t_end_ns += shift;
    EXPECT_EQ(cli::window_json(w, dsp::Method::kPtda), p.lines[i]) << job << " window " << i;
  }

  // Coverage: the daemon's tracker reaches the state `ptda monitor`'s does (same windows, same speed
  // samples, same motion time), and every window of a paper job's faulty recording is judged.
  const cli::MonitorInputs in = cli::load_monitor_inputs(p.faulty.string(), cfg, p.baseline.string());
  cli::RunOptions ro;
  ro.progress = false;
  const cli::MonitorResult m =
      cli::monitor_recording(in.rec, in.cfg, in.baseline, dsp::Method::kPtda, in.fs_hz, {}, ro);
  const dsp::CoverageState& dc = v.pipeline.coverage;
  expect_same_coverage(dc, m.coverage);
  EXPECT_EQ(dc.judged, p.lines.size());
  EXPECT_EQ(dc.level, dsp::CoverageLevel::kFull);
  return collector.windows;
}

TEST_P(DaemonReplay, ThreadsReproduceMonitorJsonlExactly) {
  const Pinned pin = GetParam();
  const Prepared p = prepare(pin.job);
  ASSERT_FALSE(p.lines.empty());
  const std::string cfg = (source_dir() / "config" / "examples" / (std::string(pin.job) + ".toml")).string();
  const std::vector<dsp::WindowResult> windows = expect_daemon_equals_monitor(p, pin.job, cfg);
  std::size_t alarm_windows = 0;
  for (const dsp::WindowResult& w : windows) alarm_windows += w.alarm ? 1 : 0;
  EXPECT_EQ(windows.size(), pin.windows) << "pinned window count";
  EXPECT_EQ(alarm_windows, pin.alarm_windows) << "pinned alarm windows";
}

INSTANTIATE_TEST_SUITE_P(PaperJobs, DaemonReplay, ::testing::ValuesIn(kJobs),
                         [](const auto& param_info) { return std::string(param_info.param.job); });

// The band CUSUM on (`[decision] band_cusum = true`, session 12): trained and monitored with it, the
// daemon's windows still give `ptda monitor`'s JSONL line for line, band evidence included. Pinned from
// this run (seeds 1001 / 3003): spot welding's 20 faulty windows, the band detector's first alarm.
TEST(DaemonReplayBandCusum, ThreadsReproduceMonitorJsonlWithBandCusum) {
  const Prepared p = prepare("spot_welding", "band", "band_cusum = true\n");
  ASSERT_FALSE(p.lines.empty());
  const std::string cfg = (p.dir / "spot_welding_band.toml").string();
  const std::vector<dsp::WindowResult> windows = expect_daemon_equals_monitor(p, "spot_welding", cfg);
  ASSERT_EQ(windows.size(), 20U);
  std::size_t first_band_alarm = windows.size();
  for (std::size_t i = 0; i < windows.size(); ++i) {
    EXPECT_TRUE(windows[i].band_on) << i;
    EXPECT_NE(p.lines[i].find("\"band_cusum_max\":"), std::string::npos) << p.lines[i];
    if (windows[i].band_alarm && first_band_alarm == windows.size()) first_band_alarm = i;
  }
  ASSERT_EQ(first_band_alarm, kBandFirstAlarm) << "pinned first band alarm";
  EXPECT_EQ(windows[first_band_alarm].band_max_index, kBandFirstAlarmBand);
  // k-of-n needs 3 windows, and since session 38 the feature CUSUM too (its step cap 2.5 against
  // cusum_alarm 7; before: sequential+band at window 0).
  EXPECT_EQ(windows[first_band_alarm].detector, dsp::AlarmDetector::kBand);
  EXPECT_NE(p.lines[first_band_alarm].find("\"detector\":\"band\""), std::string::npos)
      << p.lines[first_band_alarm];
}

// The mesh CUSUM on (`[decision] mesh_cusum = true`, session 19): trained and monitored with it, the
// daemon's windows give `ptda monitor`'s JSONL line for line, mesh evidence included. Spot welding's
// plateau holds 2.8 input-shaft revolutions per window (1.29 rad/s x 33.86 / 2 pi = 6.96 Hz, 0.4 s), so
// every scored window has am and pm.
TEST(DaemonReplayMeshCusum, ThreadsReproduceMonitorJsonlWithMeshCusum) {
  const Prepared p = prepare("spot_welding", "mesh", "mesh_cusum = true\n");
  ASSERT_FALSE(p.lines.empty());
  const std::string cfg = (p.dir / "spot_welding_mesh.toml").string();
  const std::vector<dsp::WindowResult> windows = expect_daemon_equals_monitor(p, "spot_welding", cfg);
  ASSERT_EQ(windows.size(), 20U);
  std::size_t first_mesh_alarm = windows.size();
  double top = 0.0;
  for (std::size_t i = 0; i < windows.size(); ++i) {
    top = std::max(top, windows[i].mesh_max_statistic);
    EXPECT_TRUE(windows[i].mesh_on) << i;
    EXPECT_TRUE(std::isfinite(windows[i].mesh_value[0])) << i;
    EXPECT_TRUE(std::isfinite(windows[i].mesh_value[1])) << i;
    EXPECT_NE(p.lines[i].find("\"mesh_cusum_max\":"), std::string::npos) << p.lines[i];
    if (windows[i].mesh_alarm && first_mesh_alarm == windows.size()) first_mesh_alarm = i;
  }
  // Pinned from this run (seeds 1001 / 3003): the project simulator's spot-welding fault is not a
  // once-per-revolution modulation of the mesh, and the mesh CUSUM stays low (largest 0.719 of h = 10
  // with mesh_cusum_k 0.75 since session 38, 0.219 with k 1; with the one-day allowance: one training
  // recording; 1.03 without it at k 1) while the other detectors hold the alarm.
  EXPECT_EQ(first_mesh_alarm, windows.size());
  EXPECT_NEAR(top, 0.719, 0.02);
  EXPECT_EQ(windows.back().detector, dsp::AlarmDetector::kAll);
}

// ---- order domain ----------------------------------------------------------------------------------

struct OrderPrepared {
  fs::path dir, baseline, config;
};

/// joint_rotation.toml with domain = "order", R = 4, S = 1024 (default), as order_domain_test.cpp.
std::string order_pipeline() {
  std::string text = job_pipeline("joint_rotation");
  const std::string len = "window_len = 12800";
  const std::size_t at = text.find(len);
  EXPECT_NE(at, std::string::npos) << "the joint-rotation configuration changed";
  if (at != std::string::npos) text.replace(at, len.size(), "domain = \"order\"\nrevolutions = 4");
  return text;
}

const OrderPrepared& order_prepared() {
  static const OrderPrepared p = [] {
    OrderPrepared q;
    // Per process: ctest runs the order tests of this binary in parallel, and scratch_dir() empties the
    // directory it returns (a shared one was wiped under a running test: seen once in a -j2 run).
    q.dir = scratch_dir("daemon_replay_order_" + std::to_string(::getpid()));
    const fs::path scen = source_dir() / "config" / "scenarios";
    // The offline configuration: the order pipeline with the simulator's 0.5 ms transport delay in [can].
    const fs::path offline = q.dir / "order.toml";
    std::ofstream(offline) << "[can]\nspeed_latency_s = 0.0005\n\n" << order_pipeline();
    q.config = offline;
    q.baseline = q.dir / "order.bin";
    EXPECT_EQ(run_ptda({"simulate", "--scenario", (scen / "joint_rotation_healthy.toml").string(), "--out",
                        (q.dir / "train").string()},
                       q.dir, "sim_train")
                  .exit_code,
              0);
    EXPECT_EQ(run_ptda({"train", "--recording", (q.dir / "train").string(), "--config", offline.string(),
                        "--out", q.baseline.string()},
                       q.dir, "train")
                  .exit_code,
              0);
    return q;
  }();
  return p;
}

struct OrderPinned {
  const char* name;
  const char* scenario;
  const char* seed;  ///< "" = the scenario's own (order_domain_test.cpp's runs)
  std::size_t windows, scored, alarm_windows;
  bool alarm;
};

// The runs of tests/golden/order_domain_test.cpp (pinned there from `ptda monitor`, session 10): healthy
// seed 201: 109 windows, 103 scored, no alarm; spur-tooth fault: 109 windows, 102 scored, alarm from the
// third scored window on (the first up to session 37: the feature CUSUM's step cap, session 38).
constexpr OrderPinned kOrderRuns[] = {{"healthy", "joint_rotation_healthy.toml", "201", 109, 103, 0, false},
                                      {"faulty", "joint_rotation_faulty.toml", "", 109, 102, 100, true}};

class DaemonReplayOrder : public ::testing::TestWithParam<OrderPinned> {};

TEST_P(DaemonReplayOrder, ThreadsReproduceOrderMonitorJsonlExactly) {
  const OrderPinned pin = GetParam();
  const OrderPrepared& p = order_prepared();
  ASSERT_TRUE(fs::exists(p.baseline));
  const fs::path dir = p.dir / pin.name;
  fs::create_directories(dir);
  const fs::path rec = dir / "recording";
  std::vector<std::string> sim{"simulate", "--scenario",
                               (source_dir() / "config" / "scenarios" / pin.scenario).string(), "--out",
                               rec.string()};
  if (*pin.seed != '\0') {
    sim.emplace_back("--seed");
    sim.emplace_back(pin.seed);
  }
  ASSERT_EQ(run_ptda(sim, dir, "sim").exit_code, 0);
  const fs::path jsonl = dir / "monitor.jsonl";
  const RunResult m = run_ptda({"monitor", "--recording", rec.string(), "--config", p.config.string(),
                                "--baseline", p.baseline.string(), "--jsonl", jsonl.string(), "--quiet"},
                               dir, "monitor");
  ASSERT_EQ(m.exit_code, 0) << m.err;
  std::vector<std::string> lines;
  {
    std::ifstream in(jsonl);
    for (std::string line; std::getline(in, line);) lines.push_back(line);
  }
  ASSERT_FALSE(lines.empty());

  // The daemon: WAV + candump replays at fast pace, the CAN latency in the daemon's [can] table.
  const fs::path config = dir / "ptdad.toml";
  std::ofstream(config) << "[daemon]\nbaseline = \"" << p.baseline.string() << "\"\nstatus_dir = \""
                        << (dir / "status").string()
                        << "\"\nstatus_period_s = 0.05\n\n[adc]\nbackend = \"wav\"\nrecording = \""
                        << rec.string() << "\"\npace = \"fast\"\nblock_len = 1000\n\n[can]\nbackend = "
                        << "\"candump\"\npace = \"fast\"\nspeed_latency_s = 0.0005\n\n[alarm]\n"
                        << "min_hold_s = 0.0\nlatch = false\n\n"
                        << order_pipeline();
  Collector collector;
  drivers::MonotonicClock clock;
  daemon::DaemonOptions opt;
  opt.config_file = config;
  opt.config_dir = fs::path();
  opt.exit_at_end = true;
  daemon::Daemon d(opt, clock);
  d.set_window_sink(&collector);
  d.configure();
  d.activate();
  ASSERT_EQ(d.run(), 0);
  const daemon::DaemonView v = d.view();
  EXPECT_TRUE(v.pipeline.ended);
  EXPECT_EQ(v.pipeline.phase, daemon::Phase::kEnded);
  EXPECT_EQ(v.counters.acq_ring_full_blocks, 0U);
  EXPECT_EQ(v.counters.can_ring_full, 0U);
  EXPECT_EQ(v.pipeline.gap_samples, 0U);
  EXPECT_TRUE(v.pipeline.order_domain);
  EXPECT_EQ(v.pipeline.slicer.windows, 0U);  // the time-domain slicer is not used
  EXPECT_EQ(v.pipeline.order_windows_cut, lines.size());
  EXPECT_EQ(v.pipeline.resampler.samples_overrun, 0U);
  EXPECT_EQ(v.pipeline.resampler.frames_overflow, 0U);
  EXPECT_EQ(v.pipeline.resampler.outputs_dropped, 0U);

  const formats::RecordingMeta meta = formats::read_recording_meta(rec);
  const std::int64_t shift = seconds_to_ns(meta.start_time_s) - v.pipeline.t0_mono_ns;
  ASSERT_EQ(collector.windows.size(), lines.size());
  std::size_t alarm_windows = 0, scored = 0;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    dsp::WindowResult w = collector.windows[i];
    w.ref.t_start_ns += shift;
    w.ref.t_end_ns += shift;
    // Window times, segment, class, features to the last printed digit, bands, verdict, detectors.
    EXPECT_EQ(cli::window_json(w, dsp::Method::kPtda, dsp::Domain::kOrder), lines[i])
        << pin.name << " window " << i;
    if (w.status != dsp::WindowStatus::kScored) continue;
    ++scored;
    if (w.alarm) ++alarm_windows;  // counted on scored windows, as order_domain_test.cpp pins them
  }
  EXPECT_EQ(collector.windows.size(), pin.windows) << "pinned window count";
  EXPECT_EQ(scored, pin.scored) << "pinned scored windows";
  EXPECT_EQ(alarm_windows, pin.alarm_windows) << "pinned alarm windows";
  // The alarm manager (what drives the GPIO/CAN outputs and status.json): raised on the faulty run only.
  EXPECT_EQ(v.pipeline.alarm_counters.alarms_raised > 0, pin.alarm)
      << v.pipeline.alarm_counters.alarms_raised;
  EXPECT_EQ(v.pipeline.alarm_counters.windows_scored, pin.scored);

  // status.json: the same pipeline counters as in the time domain, and the order front end's.
  const cli::JsonValue status = cli::parse_json(read_file(dir / "status" / "status.json"), "status.json");
  EXPECT_EQ(status.at("pipeline").at("windows_scored").as_number(), static_cast<double>(pin.scored));
  EXPECT_EQ(status.at("order").at("windows").as_number(), static_cast<double>(lines.size()));
  EXPECT_EQ(status.at("order").at("frames").as_number(), static_cast<double>(v.pipeline.resampler.frames));
  EXPECT_EQ(status.at("slicer").at("windows").as_number(), 0.0);

  // Coverage as `ptda monitor`'s in the order domain.
  const cli::MonitorInputs in =
      cli::load_monitor_inputs(rec.string(), p.config.string(), p.baseline.string());
  cli::RunOptions ro;
  ro.progress = false;
  const cli::MonitorResult mr =
      cli::monitor_recording(in.rec, in.cfg, in.baseline, dsp::Method::kPtda, in.fs_hz, {}, ro);
  const dsp::CoverageState& dc = v.pipeline.coverage;
  expect_same_coverage(dc, mr.coverage);
  EXPECT_EQ(dc.judged, pin.scored);
  EXPECT_EQ(dc.unmatched_total(), pin.windows - pin.scored);  // the windows no class matched, by reason
  // The resampler saw what the offline tool's saw.
  EXPECT_EQ(v.pipeline.resampler.frames, mr.resampler.frames);
  EXPECT_EQ(v.pipeline.resampler.outputs, mr.resampler.outputs);
  EXPECT_EQ(v.pipeline.resampler.breaks, mr.resampler.breaks);
  EXPECT_EQ(v.pipeline.order_windows_cut, mr.order_windows_cut);
}

INSTANTIATE_TEST_SUITE_P(JointRotation, DaemonReplayOrder, ::testing::ValuesIn(kOrderRuns),
                         [](const auto& param_info) { return std::string(param_info.param.name); });

// A baseline of the other domain is refused at configure (fault, cause baseline), naming both.
TEST(DaemonReplayOrderRefusal, BaselineOfTheOtherDomainIsRefused) {
  const OrderPrepared& p = order_prepared();
  ASSERT_TRUE(fs::exists(p.baseline));
  const fs::path dir = p.dir / "refusal";
  fs::create_directories(dir);
  const fs::path time_baseline = dir / "time.bin";
  const std::string time_cfg = (source_dir() / "config" / "examples" / "joint_rotation.toml").string();
  ASSERT_EQ(run_ptda({"train", "--recording", (p.dir / "train").string(), "--config", time_cfg, "--out",
                      time_baseline.string()},
                     dir, "train_time")
                .exit_code,
            0);
  const auto refusal = [&](const fs::path& baseline, const std::string& pipeline) {
    const std::string text =
        "[daemon]\nbaseline = \"" + baseline.string() + "\"\n[adc]\nbackend = \"wav\"\n" + "recording = \"" +
        (p.dir / "train").string() +
        "\"\npace = \"fast\"\n[can]\nbackend = \"candump\"\npace = \"fast\"\n\n" + pipeline;
    const daemon::DaemonConfig cfg = daemon::parse_daemon_config(text, "ptdad.toml");
    drivers::MonotonicClock clock;
    daemon::Pipeline pl(cfg, daemon::PipelineMode::kMonitor, clock);
    pl.configure();
    EXPECT_TRUE(pl.refused());
    // --check-config reports it too (one problem: the recording and its CAN log are fine).
    const std::vector<std::string> problems = daemon::check_config_paths(cfg, false);
    EXPECT_EQ(problems.size(), 1U) << (problems.empty() ? std::string() : problems.front());
    return pl.refusal();
  };
  EXPECT_EQ(refusal(time_baseline, order_pipeline()),
            time_baseline.string() +
                ": baseline was trained in the time domain but the configuration sets [extraction] domain = "
                "\"order\": use the configuration it was trained with, or retrain");
  EXPECT_EQ(refusal(p.baseline, job_pipeline("joint_rotation")),
            p.baseline.string() +
                ": baseline was trained in the order domain but the configuration sets [extraction] domain = "
                "\"time\": use the configuration it was trained with, or retrain");
  // Same domain, other revolutions: named with both values.
  std::string r8 = order_pipeline();
  r8.replace(r8.find("revolutions = 4"), 15, "revolutions = 8");
  EXPECT_EQ(refusal(p.baseline, r8),
            p.baseline.string() +
                ": order baseline has samples_per_rev = 1024, revolutions = 4 but the "
                "configuration sets [extraction] samples_per_rev = 1024, revolutions = 8");
}

RunResult run_ptdad(const std::vector<std::string>& args, const fs::path& dir, const std::string& tag) {
  std::string cmd = shell_quote(PTDAD_BINARY);
  for (const auto& a : args) cmd += " " + shell_quote(a);
  return run_captured(std::move(cmd), dir, tag);
}

TEST(DaemonBinary, ReplaysARecordingAndChecksConfigurations) {
  const Prepared p = prepare("arc_welding", "binary");
  const RunResult ok =
      run_ptdad({"--config", p.config.string(), "--config-dir", "", "--check-config"}, p.dir, "check");
  EXPECT_EQ(ok.exit_code, 0) << ok.err;
  EXPECT_NE(ok.out.find("configuration is valid"), std::string::npos) << ok.out;

  const fs::path bad = p.dir / "bad.toml";
  std::ofstream(bad) << "[daemon]\nstatus_period_s = 0.1\n\n[adc]\nbackend = \"wave\"\n";
  const RunResult ko =
      run_ptdad({"--config", bad.string(), "--config-dir", "", "--check-config"}, p.dir, "check_bad");
  EXPECT_EQ(ko.exit_code, 1);
  EXPECT_NE(
      ko.err.find(bad.string() + ":5:11: adc.backend must be one of \"iio\", \"wav\", \"sim\", not \"wave\""),
      std::string::npos)
      << ko.err;

  // A joint name unfit for a label or topic is a usage error (exit 2) naming the option.
  const RunResult bad_joint =
      run_ptdad({"--config", p.config.string(), "--joint", "robot 17/j4"}, p.dir, "joint");
  EXPECT_EQ(bad_joint.exit_code, 2);
  EXPECT_NE(bad_joint.err.find("--joint: 'robot 17/j4' is not a joint name"), std::string::npos)
      << bad_joint.err;

  // --joint (what ptdad@joint4.service passes) names the joint in status.json and the history; the
  // event history ([history], issue 15 item 3) gets every window.
  const fs::path history = p.dir / "history";
  fs::remove_all(history);
  const fs::path with_history = p.dir / "with_history.toml";
  {
    std::ifstream in(p.config);
    std::ofstream out(with_history);
    out << in.rdbuf() << "\n[history]\ndir = \"" << history.string() << "\"\n";
  }
  const RunResult run = run_ptdad({"--config", with_history.string(), "--config-dir", "", "--exit-at-end",
                                   "--foreground", "--joint", "joint4"},
                                  p.dir, "run");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  // The history's window lines are `ptda monitor`'s windows, one for one: same numbers, classes and
  // verdicts; the features as %.9g of the same doubles.
  std::vector<cli::JsonValue> windows, states;
  {
    std::ifstream in(history / "history.jsonl");
    for (std::string line; std::getline(in, line);) {
      cli::JsonValue v = cli::parse_json(line, "history.jsonl");
      (v.at("type").as_string() == "window" ? windows : states).push_back(std::move(v));
    }
  }
  ASSERT_EQ(windows.size(), p.lines.size());
  for (std::size_t i = 0; i < windows.size(); ++i) {
    const cli::JsonValue m = cli::parse_json(p.lines[i], "jsonl");
    const cli::JsonValue& h = windows[i];
    EXPECT_EQ(h.at("joint").as_string(), "joint4");
    EXPECT_EQ(h.at("n").as_number(), m.at("n").as_number()) << i;
    EXPECT_EQ(h.at("status").as_string(), m.at("status").as_string()) << i;
    EXPECT_EQ(h.at("abnormal").as_bool(), m.at("abnormal").as_bool()) << i;
    EXPECT_EQ(h.at("alarm").as_bool(), m.at("alarm").as_bool()) << i;
    EXPECT_EQ(h.at("detector").as_string(), m.at("detector").as_string()) << i;
    if (m.at("status").as_string() == "scored") {
      EXPECT_EQ(h.at("segment").as_number(), m.at("segment").as_number()) << i;
      EXPECT_NEAR(h.at("rms_res").as_number(), m.at("rms_res").as_number(),
                  1e-8 * m.at("rms_res").as_number());
      EXPECT_NEAR(h.at("entropy_res").as_number(), m.at("entropy_res").as_number(), 1e-8);
    }
  }
  // State lines: the start of monitoring and the end of the replay, each with its alarm level.
  ASSERT_GE(states.size(), 2U);
  EXPECT_EQ(states.front().at("state").as_string(), "running");
  bool ended = false;
  for (const auto& st : states) ended = ended || st.at("phase").as_string() == "replay ended";
  EXPECT_TRUE(ended);
  // `ptda report --history`: the trend report of that history.
  std::size_t judged = 0, alarmed = 0;
  for (const auto& w : windows) {
    judged += w.at("status").as_string() == "scored" ? 1 : 0;
    alarmed += w.at("alarm").as_bool() ? 1 : 0;
  }
  const fs::path html = p.dir / "history.html";
  const RunResult rep =
      run_ptda({"report", "--history", history.string(), "--html", html.string()}, p.dir, "history_report");
  ASSERT_EQ(rep.exit_code, 0) << rep.err;
  const std::string page = read_file(html);
  EXPECT_NE(page.find("<h1>PTDA event history of joint4</h1>"), std::string::npos);
  EXPECT_NE(page.find("<tr><th>judged</th><td>" + std::to_string(judged) + "</td></tr>"), std::string::npos);
  EXPECT_NE(page.find(alarmed > 0 ? "ALARM first at " : "no alarm in "), std::string::npos);
  EXPECT_NE(page.find("hours since "), std::string::npos);
  EXPECT_EQ(page.find("Example windows"), std::string::npos);
  // A partial last line (power cut while writing) is left out with a note.
  const fs::path cut = p.dir / "history_cut";
  fs::remove_all(cut);
  fs::create_directories(cut);
  fs::copy_file(history / "history.jsonl", cut / "history.1.jsonl");
  std::ofstream(cut / "history.jsonl") << "{\"type\":\"window\",\"joint\":\"joint4\",\"t_ut";
  const RunResult partial =
      run_ptda({"report", "--history", cut.string(), "--html", html.string()}, p.dir, "history_partial");
  ASSERT_EQ(partial.exit_code, 0) << partial.err;
  EXPECT_NE(read_file(html).find("left out a partial last line of " + (cut / "history.jsonl").string()),
            std::string::npos);
  // A broken line elsewhere is left out with a note naming the file and line (one glitch does not make
  // a week of history unreadable).
  std::ofstream(cut / "history.jsonl") << "{\"type\":\"window\"\n{\"type\":\"state\"}\n";
  const RunResult broken =
      run_ptda({"report", "--history", cut.string(), "--html", html.string()}, p.dir, "history_broken");
  ASSERT_EQ(broken.exit_code, 0) << broken.err;
  EXPECT_NE(read_file(html).find(
                "left out 2 unreadable line(s); the first: " + (cut / "history.jsonl").string() + ":1"),
            std::string::npos);
  const cli::JsonValue status = cli::parse_json(read_file(p.dir / "status" / "status.json"), "status.json");
  EXPECT_EQ(status.at("joint").as_string(), "joint4");
  std::size_t scored = 0, abnormal = 0;
  for (const auto& line : p.lines) {
    const cli::JsonValue w = cli::parse_json(line, "jsonl");
    if (w.at("status").as_string() == "scored") ++scored;
    if (w.at("abnormal").as_bool()) ++abnormal;
  }
  EXPECT_EQ(status.at("pipeline").at("windows_scored").as_number(), static_cast<double>(scored));
  EXPECT_EQ(status.at("pipeline").at("windows_abnormal").as_number(), static_cast<double>(abnormal));
  EXPECT_NE(run.err.find("replay ended: " + std::to_string(p.lines.size()) + " windows processed"),
            std::string::npos)
      << run.err;
}

}  // namespace
}  // namespace ptda::golden
