// The fault matrix (issue 14 item 3): every daemon fault of the issue, one row each, run through the
// daemon's real threads on in-memory replays of the simulated healthy arc-welding job (daemon_fakes.hpp),
// and for each the same three checks:
//   (a) a clear cause is visible: the exact status.json field, DaemonView counter or reason;
//   (b) no data lost: the baseline file is byte-identical when the fault is not about it, every sample
//       and window is counted (the ones the fault spoils are counted as such, nothing skipped silently);
//   (c) the daemon still serves: it judges windows and publishes status after the fault cleared, or
//       keeps its last good state (a stop leaves a complete baseline a new daemon monitors on).
// The rows reuse the existing injection points: the DeviceFactory fakes (CAN, ADC), the
// before-baseline-write hook, signals sent to the process, RLIMIT_FSIZE on the test process (a write
// past the limit fails with EFBIG, as a full file system fails with ENOSPC: same code path), and the
// file system itself (deleted directory, planted symlinks, forged bytes). docs/reliability.md, "Fault
// matrix", lists the rows.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <functional>
#include <optional>

#include "daemon_fakes.hpp"
#include "daemon_test_support.hpp"
#include "ptda/common/error.hpp"
#include "status_text.hpp"

namespace ptda::daemon::test {
namespace {

using namespace std::chrono_literals;
using ptda::test::read_text;
constexpr std::size_t kBlock = 512;

std::shared_ptr<const SimRecording> healthy() {
  static const auto rec = make_sim_recording(arc_scenario(), 7);
  return rec;
}
std::shared_ptr<const SourcePlan> clean_source() {
  static const auto plan = std::make_shared<const SourcePlan>(plan_blocks(*healthy(), kBlock));
  return plan;
}
std::shared_ptr<const ChannelPlan> clean_frames() {
  static const auto plan = [] {
    auto p = std::make_shared<ChannelPlan>();
    p->frames = healthy()->frames;
    return p;
  }();
  return plan;
}
std::uint64_t total_samples() {
  return healthy()->samples.size();
}

/// Stream start times of the processed windows (fixed capacity: never allocates on the processing thread).
struct Starts final : WindowSink {
  explicit Starts(const FakeDevices& dev) : dev_(dev) { t.resize(8192); }
  void on_window(const dsp::WindowResult& r) noexcept override {
    if (n < t.size()) t[n++] = r.ref.t_start_ns - dev_.origin();
  }
  [[nodiscard]] std::size_t after(std::int64_t t_ns) const {
    return static_cast<std::size_t>(std::count_if(t.begin(), t.begin() + static_cast<std::ptrdiff_t>(n),
                                                  [&](std::int64_t x) { return x >= t_ns; }));
  }
  const FakeDevices& dev_;
  std::vector<std::int64_t> t;
  std::size_t n = 0;
};

std::vector<char> bytes_of(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// One row's scratch directory: a baseline, the status directory with the metrics file in it.
struct Scene {
  explicit Scene(const std::string& name) : dir(scratch("fault_matrix_" + name)) {
    write_sim_baseline(dir / "baseline.bin");
    baseline_bytes = bytes_of(dir / "baseline.bin");
  }
  [[nodiscard]] fs::path status_dir() const { return dir / "status"; }
  [[nodiscard]] fs::path status() const { return dir / "status" / "status.json"; }
  [[nodiscard]] fs::path prom() const { return dir / "status" / "ptda.prom"; }
  [[nodiscard]] std::string config(const std::string& extra = "") const {
    // log_level "error": the rows check files and counters, not log lines, and a CI excerpt of this
    // test's output should show the failing row's message rather than the daemons' info lines.
    return fake_config(dir, extra, "", "metrics_path = \"" + prom().string() + "\"\nlog_level = \"error\"\n");
  }
  [[nodiscard]] std::string training_config(std::uint32_t target_cycles) const {
    return config("[training]\ntarget_cycles = " + std::to_string(target_cycles) + "\noutput = \"" +
                  (dir / "trained.bin").string() + "\"\n");
  }
  /// (b) for the faults that are not about the baseline: byte-identical, no temporary file beside it.
  void expect_baseline_kept() const {
    EXPECT_EQ(bytes_of(dir / "baseline.bin"), baseline_bytes) << "the baseline changed";
    EXPECT_EQ(temp_files(dir), 0U);
  }
  fs::path dir;
  std::vector<char> baseline_bytes;
};

/// A daemon on `dev` running on its own thread until the object goes (request_stop + join).
struct Live {
  Live(const Scene& s, const std::string& config_text, FakeDevices& dev, bool train = false,
       bool exit_at_end = false, WindowSink* sink = nullptr)
      : d(options(s, config_text, train, exit_at_end), clock) {
    d.set_device_factory(&dev);
    if (sink != nullptr) d.set_window_sink(sink);
    d.configure();
    d.activate();
    runner.emplace(d);
  }
  static DaemonOptions options(const Scene& s, const std::string& text, bool train, bool exit_at_end) {
    write_text(s.dir / "ptdad.toml", text);
    DaemonOptions o;
    o.config_file = s.dir / "ptdad.toml";
    o.config_dir = fs::path();
    o.train = train;
    o.exit_at_end = exit_at_end;
    return o;
  }
  /// Every block up to the gate processed (the last may wait for a later speed sample: 30 ms slack).
  bool reach(FakeDevices& dev, std::int64_t t_ns) {
    dev.gate.t_ns = t_ns;
    return wait_for([&] { return d.view().pipeline.data_time_ns - dev.origin() >= t_ns - 30'000'000; });
  }
  drivers::MonotonicClock clock;
  Daemon d;
  std::optional<DaemonRunThread> runner;
};

/// A whole replay (exit at its end); the daemon's final view, status text and CAN counters.
struct Replay {
  DaemonView view;
  std::string status;
  drivers::CanCounters can;
  std::size_t windows = 0;
  std::vector<std::int64_t> starts;  ///< stream start times of the windows (with a Starts sink)
};
Replay replay(const Scene& s, const std::string& config_text, FakeDevices& dev, Starts* starts = nullptr) {
  Replay r;
  {
    Live live(s, config_text, dev, false, true, starts);
    live.runner->join();
    r.view = live.d.view();
    r.can = dev.last_channel->counters();  // the daemon owns the channel: read before it goes
  }
  r.status = read_text(s.status());
  if (starts != nullptr) {
    r.windows = starts->n;
    r.starts.assign(starts->t.begin(), starts->t.begin() + static_cast<std::ptrdiff_t>(starts->n));
  }
  return r;
}

bool has(const std::string& text, const std::string& needle) {
  return text.find(needle) != std::string::npos;
}

/// RLIMIT_FSIZE of this process set to `bytes` (SIGXFSZ ignored, so a write past it fails with EFBIG)
/// until the object goes. The limit applies to every thread: the test writes nothing while it holds.
class FileSizeLimit {
 public:
  explicit FileSizeLimit(rlim_t bytes) {
    ::getrlimit(RLIMIT_FSIZE, &old_);
    old_handler_ = ::signal(SIGXFSZ, SIG_IGN);
    rlimit lim = old_;
    lim.rlim_cur = bytes;
    EXPECT_EQ(::setrlimit(RLIMIT_FSIZE, &lim), 0);
  }
  FileSizeLimit(const FileSizeLimit&) = delete;
  FileSizeLimit& operator=(const FileSizeLimit&) = delete;
  ~FileSizeLimit() { lift(); }
  void lift() {
    if (lifted_) return;
    lifted_ = true;
    ::setrlimit(RLIMIT_FSIZE, &old_);
    ::signal(SIGXFSZ, old_handler_);
  }

 private:
  rlimit old_{};
  sighandler_t old_handler_ = SIG_DFL;
  bool lifted_ = false;
};

/// The clean replay every row compares with (run once).
const Replay& reference() {
  static const Replay r = [] {
    const Scene s("reference");
    FakeDevices dev(clean_source(), clean_frames());
    Starts starts(dev);
    return replay(s, s.config(), dev, &starts);
  }();
  return r;
}

CanFrame error_frame(std::int64_t t_ns, std::uint32_t cls, std::uint8_t d1) {
  CanFrame f;
  f.t_ns = t_ns;
  f.id = cls;
  f.flags = kCanError;
  f.len = 8;
  f.data[1] = d1;
  return f;
}

// --- the rows --------------------------------------------------------------------------------------

void can_silence() {
  // No frame at all for 3 s (cable pulled, controller silent): paused with a fault, then resumed.
  const Scene s("can_silence");
  const std::int64_t a = 20'000'000'000, b = 23'000'000'000;
  auto plan = std::make_shared<ChannelPlan>();
  for (const CanFrame& f : healthy()->frames) {
    if (f.t_ns < a || f.t_ns >= b) plan->frames.push_back(f);
  }
  FakeDevices dev(clean_source(), plan);
  Starts starts(dev);
  const Replay r = replay(s, s.config(), dev, &starts);
  // (a)
  EXPECT_EQ(r.view.pipeline.pauses, 1U);
  EXPECT_EQ(r.view.pipeline.alarm_counters.faults_entered, 1U);
  EXPECT_EQ(r.view.pipeline.alarm_counters.alarms_raised,
            reference().view.pipeline.alarm_counters.alarms_raised);
  // (b) every sample and every frame counted; only windows overlapping the silence are missing.
  EXPECT_EQ(r.view.pipeline.samples, total_samples());
  EXPECT_EQ(r.view.counters.can_frames, plan->frames.size());
  std::size_t inside = 0;
  for (std::size_t i = 0; i < starts.n; ++i) inside += (starts.t[i] >= a && starts.t[i] < b) ? 1 : 0;
  EXPECT_EQ(inside, 0U);
  EXPECT_GE(r.windows + 8, reference().windows);
  s.expect_baseline_kept();
  // (c) windows judged after the silence.
  EXPECT_GT(starts.after(b), 10U);
  std::printf("  can silence 3 s: pauses %llu, faults %llu, windows %zu (clean %zu), %zu after\n",
              static_cast<unsigned long long>(r.view.pipeline.pauses),
              static_cast<unsigned long long>(r.view.pipeline.alarm_counters.faults_entered), r.windows,
              reference().windows, starts.after(b));
}

void can_bus_off() {
  // Error-passive at 1/4 of the frames, bus-off at 1/2, the controller restarted 500 frames later. The
  // gate holds the data inside each state (the bus state is read by the supervisor, on its period).
  const Scene s("can_bus_off");
  const auto& src = healthy()->frames;
  auto plan = std::make_shared<ChannelPlan>();
  const std::int64_t t_passive = src[src.size() / 4].t_ns + 500, t_off = src[src.size() / 2].t_ns + 500;
  const std::int64_t t_restart = src[src.size() / 2 + 500].t_ns + 500;
  for (std::size_t i = 0; i < src.size(); ++i) {
    plan->frames.push_back(src[i]);
    if (i == src.size() / 4)
      plan->frames.push_back(error_frame(t_passive, 0x004U /*CRTL*/, 0x10 /*RX_PASSIVE*/));
    if (i == src.size() / 2) plan->frames.push_back(error_frame(t_off, 0x040U /*BUSOFF*/, 0));
    if (i == src.size() / 2 + 500) plan->frames.push_back(error_frame(t_restart, 0x100U /*RESTARTED*/, 0));
  }
  FakeDevices dev(clean_source(), plan);
  Starts starts(dev);
  Live live(s, s.config(), dev, false, false, &starts);
  // (a) each state in status.json while it lasts; bus-off pauses monitoring with its reason and a fault.
  ASSERT_TRUE(live.reach(dev, t_passive + 100'000'000));
  ASSERT_TRUE(wait_for([&] { return has(read_text(s.status()), "\"bus_state\":\"error_passive\""); }));
  ASSERT_TRUE(live.reach(dev, t_off + 100'000'000));
  ASSERT_TRUE(wait_for([&] { return has(read_text(s.status()), "\"bus_state\":\"bus_off\""); }));
  ASSERT_TRUE(wait_for([&] { return has(std::string(live.d.view().reason.view()), "(bus-off)"); }));
  DaemonView v = live.d.view();
  EXPECT_EQ(v.phase, Phase::kPausedSpeed);
  EXPECT_NE(v.pipeline.report.level, drivers::AlarmLevel::kNormal);
  EXPECT_NE(v.pipeline.report.causes & drivers::kCauseSpeed, 0U);
  // (c) restarted: error-active again, monitoring resumes by itself.
  dev.gate.t_ns = std::numeric_limits<std::int64_t>::max();
  ASSERT_TRUE(wait_for([&] { return live.d.view().pipeline.ended; }));
  ASSERT_TRUE(wait_for([&] { return has(read_text(s.status()), "\"bus_state\":\"error_active\""); }));
  v = live.d.view();
  const drivers::CanCounters can = dev.last_channel->counters();
  EXPECT_EQ(can.error_passive, 1U);
  EXPECT_EQ(can.bus_off, 1U);
  EXPECT_EQ(can.restarts, 1U);
  EXPECT_EQ(v.pipeline.pauses, 1U);
  EXPECT_GT(starts.after(t_restart), 10U);
  // (b) every frame and sample counted, the three error frames as such.
  EXPECT_EQ(v.counters.can_error_frames, 3U);
  EXPECT_EQ(v.counters.can_frames, plan->frames.size());
  EXPECT_EQ(v.pipeline.samples, total_samples());
  s.expect_baseline_kept();
}

void adc_overrun() {
  // One block lost in the middle of a clean window; the next block keeps its index and carries the gap
  // flag.
  const Scene s("adc_overrun");
  auto plan = std::make_shared<SourcePlan>(*clean_source());
  const std::int64_t t_mid = reference().starts.at(reference().windows / 2) + 50'000'000;  // window: 125 ms
  const auto at = static_cast<std::size_t>(
      std::lower_bound(plan->blocks.begin(), plan->blocks.end(), t_mid,
                       [](const drivers::SampleBlock& b, std::int64_t t) { return b.t_mono_ns < t; }) -
      plan->blocks.begin());
  const std::int64_t t_gap = plan->blocks[at].t_mono_ns;
  plan->blocks[at + 1].flags |= drivers::kBlockGap;
  plan->blocks[at + 1].gap_samples = kBlock;
  plan->blocks.erase(plan->blocks.begin() + static_cast<std::ptrdiff_t>(at));
  FakeDevices dev(plan, clean_frames());
  Starts starts(dev);
  const Replay r = replay(s, s.config(), dev, &starts);
  // (a)
  EXPECT_TRUE(has(r.status, "\"gaps\":1,")) << r.status;
  EXPECT_TRUE(has(r.status, "\"lost_samples\":512,")) << r.status;
  EXPECT_EQ(r.view.pipeline.gap_samples, kBlock);
  // (b) the lost samples are counted as lost, the spoilt window as invalid: nothing else is missing.
  EXPECT_EQ(r.view.pipeline.samples + kBlock, total_samples());
  EXPECT_EQ(r.view.pipeline.slicer.windows_invalid, 1U);
  EXPECT_EQ(r.windows + r.view.pipeline.slicer.windows_invalid, reference().windows);
  s.expect_baseline_kept();
  // (c)
  EXPECT_GT(starts.after(t_gap), 10U);
}

void sigterm_during_baseline_write() {
  // SIGTERM arrives right before field training writes its baseline (the test hook): the atomic write
  // completes, the daemon stops at once with exit 0, and the baseline is complete and usable.
  const Scene s("sigterm_write");
  FakeDevices dev(clean_source(), clean_frames());
  DaemonOptions opt = Live::options(s, s.training_config(5), true, false);
  drivers::MonotonicClock clock;
  Daemon d(opt, clock);
  d.set_device_factory(&dev);
  int calls = 0;
  d.set_before_baseline_write(
      [](void* arg) {
        ++*static_cast<int*>(arg);
        ::kill(::getpid(), SIGTERM);
      },
      &calls);
  d.configure();
  d.activate();
  EXPECT_EQ(d.run(), 0);
  const DaemonView v = d.view();
  // (a) the stop was the signal's: exactly one write attempt, no failure recorded, status says stopped.
  EXPECT_EQ(calls, 1);
  const std::string status = read_text(s.status());
  EXPECT_TRUE(has(state_file_json(status, "baseline"), "\"failures\":0,")) << status;
  // (b) the trained baseline is whole (CRC and semantic checks) and nothing temporary is left.
  const dsp::Baseline b = formats::read_baseline(s.dir / "trained.bin");
  EXPECT_FALSE(b.classes.empty());
  EXPECT_EQ(temp_files(s.dir), 0U);
  s.expect_baseline_kept();
  // (c) the last good state serves: a new daemon monitors on the trained baseline.
  std::string cfg = s.config();
  cfg.replace(cfg.find("baseline.bin"), 12, "trained.bin");
  FakeDevices mdev(clean_source(), clean_frames());
  const Replay m = replay(s, cfg, mdev);
  EXPECT_GT(m.view.pipeline.scored, 0U);
  EXPECT_EQ(m.view.pipeline.samples, total_samples());
  std::printf(
      "  SIGTERM before the baseline write: state %s, trained %zu classes; then %llu windows scored\n",
      daemon_state_name(v.state).data(), b.classes.size(),
      static_cast<unsigned long long>(m.view.pipeline.scored));
}

void status_disk_full() {
  // The status directory's file system is full (RLIMIT_FSIZE 256 bytes: EFBIG at the write step) for
  // a while, then frees up.
  const Scene s("disk_full");
  FakeDevices dev(clean_source(), clean_frames());
  const std::int64_t loop = healthy()->loop_ns;
  Live live(s, s.config(), dev);
  ASSERT_TRUE(live.reach(dev, loop / 4));
  ASSERT_TRUE(wait_for([&] { return has(read_text(s.status()), "\"state\":"); }));
  const std::uint64_t windows_before = live.d.view().pipeline.windows;
  {
    FileSizeLimit full(256);
    const bool progressed = live.reach(dev, loop / 2);
    // At least the first attempt and its retry fail (counted, not timed: qemu under load is slow).
    const bool retried = wait_for([&] { return live.d.view().status_write_failures >= 2; });
    full.lift();
    ASSERT_TRUE(progressed);
    ASSERT_TRUE(retried);
  }
  // (a) once it can be written again, status.json shows the failures with their errno and step.
  std::string st;
  ASSERT_TRUE(wait_for([&] {
    st = state_file_json(read_text(s.status()), "status");
    return has(st, "\"failing\":false") && !has(st, "\"failures\":0,");
  })) << read_text(s.status());
  EXPECT_TRUE(has(st, "\"last_errno\":27,")) << st;
  EXPECT_TRUE(has(st, "\"last_error\":\"write: EFBIG (File too large)\"")) << st;
  const std::string mt = state_file_json(read_text(s.status()), "metrics");
  EXPECT_TRUE(has(mt, "\"last_errno\":27,")) << mt;
  ASSERT_TRUE(
      wait_for([&] { return has(read_text(s.prom()), "ptda_state_write_failing{file=\"status\"} 0\n"); }));
  // (b) judging went on while nothing could be written; no temporary file stays behind.
  EXPECT_GT(live.d.view().pipeline.windows, windows_before);
  // None stays behind: the writer's current temporary file exists for the moment of a write (long
  // under qemu on a loaded machine), so wait for a moment between writes rather than sample once.
  EXPECT_TRUE(wait_for([&] { return temp_files(s.status_dir()) == 0; }));
  s.expect_baseline_kept();
  // (c) to the end of the replay, every sample processed.
  dev.gate.t_ns = std::numeric_limits<std::int64_t>::max();
  ASSERT_TRUE(wait_for([&] { return live.d.view().pipeline.ended; }));
  EXPECT_EQ(live.d.view().pipeline.samples, total_samples());
  EXPECT_EQ(live.d.view().pipeline.windows, reference().view.pipeline.windows);
}

void status_dir_deleted() {
  const Scene s("dir_deleted");
  FakeDevices dev(clean_source(), clean_frames());
  const std::int64_t loop = healthy()->loop_ns;
  Live live(s, s.config(), dev);
  ASSERT_TRUE(live.reach(dev, loop / 4));
  ASSERT_TRUE(wait_for([&] { return has(read_text(s.status()), "\"state\":"); }));
  remove_dir_under_daemon(s.status_dir());
  ASSERT_TRUE(live.reach(dev, loop / 2));
  // (a) the directory is back (0755) with both files, and the status file reports itself healthy. A
  // deletion that lands between a write's open and its rename fails that one attempt (ENOENT); the
  // file written next still renders the health from before its own write, so the wait is for a
  // status.json that says "failing":false, not for the first file back.
  std::string st;
  ASSERT_TRUE(wait_for([&] {
    st = read_text(s.status());
    return has(st, "\"state\":") && fs::exists(s.prom()) &&
           has(state_file_json(st, "status"), "\"failing\":false");
  })) << st;
  EXPECT_EQ(fs::status(s.status_dir()).permissions() & fs::perms::all,
            fs::perms::owner_all | fs::perms::group_read | fs::perms::group_exec | fs::perms::others_read |
                fs::perms::others_exec);
  // (b)
  s.expect_baseline_kept();
  // (c) the windows written into the new status.json keep counting up to the end.
  dev.gate.t_ns = std::numeric_limits<std::int64_t>::max();
  ASSERT_TRUE(wait_for([&] { return live.d.view().pipeline.ended; }));
  EXPECT_EQ(live.d.view().pipeline.samples, total_samples());
  EXPECT_EQ(live.d.view().pipeline.windows, reference().view.pipeline.windows);
}

void baseline_write_failure() {
  // Field training's baseline write fails at its open step (the output's directory is a file:
  // ENOTDIR), then succeeds on a retry once the directory is there. The windows' spill file has its
  // own directory ([training] spill_dir), which works throughout.
  const Scene s("baseline_write");
  FakeDevices dev(clean_source(), clean_frames());
  const fs::path out_dir = s.dir / "out";
  fs::create_directories(s.dir / "spill");
  std::string cfg = s.training_config(5);
  cfg.replace(cfg.find((s.dir / "trained.bin").string()), (s.dir / "trained.bin").string().size(),
              (out_dir / "trained.bin").string());
  cfg.replace(cfg.find("[training]\n"), 11,
              "[training]\nspill_dir = \"" + (s.dir / "spill").string() + "\"\n");
  { std::ofstream blocker(out_dir); }
  dev.gate.t_ns = healthy()->loop_ns / 2;  // enough for 5 cycles per class; the stream does not end
  Live live(s, cfg, dev, true);
  std::string text, entry;
  ASSERT_TRUE(wait_for([&] {
    text = read_text(s.status());
    entry = state_file_json(text, "baseline");
    return has(entry, "\"failing\":true");
  })) << text;
  // (a)
  EXPECT_TRUE(has(entry, "\"last_errno\":20,")) << entry;
  EXPECT_TRUE(has(entry, "ENOTDIR (Not a directory)")) << entry;
  // (b) the collected windows are kept while the write fails.
  EXPECT_GT(training_u64(text, "windows"), 0U) << text;
  EXPECT_TRUE(has(text, "\"state\":\"training\"")) << text;
  // (c) retried: the baseline is written and monitoring starts on it; the failures stay counted.
  fs::remove(out_dir);
  fs::create_directory(out_dir);
  ASSERT_TRUE(wait_for([&] { return dev.pipelines == 2 && live.d.view().state != DaemonState::kTraining; }));
  EXPECT_FALSE(formats::read_baseline(out_dir / "trained.bin").classes.empty());
  EXPECT_EQ(temp_files(out_dir), 0U);
  ASSERT_TRUE(wait_for([&] {
    entry = state_file_json(read_text(s.status()), "baseline");
    return has(entry, "\"failing\":false");
  }));
  EXPECT_FALSE(has(entry, "\"failures\":0,")) << entry;
  dev.gate.t_ns = std::numeric_limits<std::int64_t>::max();
  ASSERT_TRUE(wait_for([&] { return live.d.view().pipeline.scored > 0; }));
  s.expect_baseline_kept();  // the configured baseline.bin: field training writes out/trained.bin
}

void spill_write_failure() {
  // The disk refuses field training's spill file (EFBIG from a file size limit that status.json and
  // the metrics file still fit in): the windows it refuses are counted as dropped (never held in RAM
  // instead), the windows before it stay, and training completes once the disk takes writes again.
  const Scene s("spill_write");
  FakeDevices dev(clean_source(), clean_frames());
  dev.gate.t_ns = healthy()->loop_ns / 20;  // too little for 5 cycles per class: no baseline yet
  Live live(s, s.training_config(5), dev, true);
  std::string text;
  ASSERT_TRUE(wait_for([&] {
    text = read_text(s.status());
    return has(text, "\"state\":\"training\"") && fs::exists(s.prom()) && training_u64(text, "windows") > 0 &&
           live.reach(dev, dev.gate.t_ns);
  })) << text;
  const std::uint64_t before = training_u64(text, "windows");
  const auto state_bytes = std::max(fs::file_size(s.status()), fs::file_size(s.prom()));
  {
    FileSizeLimit full(4 * state_bytes);
    dev.gate.t_ns = healthy()->loop_ns / 2;  // enough for 5 cycles per class, if the windows were kept
    // Every window the slicer cut is either collected or counted as dropped (none lost silently, none
    // held in RAM instead), once the replay reached the gate and the status caught up.
    const auto slicer_windows = [](const std::string& t) {
      const auto obj = t.find("\"slicer\":{");
      const auto at = obj == std::string::npos ? obj : t.find("\"windows\":", obj);
      return at == std::string::npos ? 0ULL : std::strtoull(t.c_str() + at + 10, nullptr, 10);
    };
    const bool accounted = wait_for([&] {
      text = read_text(s.status());
      const std::uint64_t w = training_u64(text, "windows");
      const std::uint64_t d = training_u64(text, "dropped");
      return live.reach(dev, dev.gate.t_ns) && d > 0 && w + d == slicer_windows(text);
    });
    // (a) counted as dropped, and why; (b) the windows written before stay.
    EXPECT_TRUE(accounted) << text;
    EXPECT_GT(training_u64(text, "spill_write_failed"), 0U) << text;
    EXPECT_TRUE(has(text, "\"spill_last_error\":\"File too large\"")) << text;
    EXPECT_GE(training_u64(text, "windows"), before) << text;
    EXPECT_LT(training_u64(text, "windows"), slicer_windows(text)) << text;
    EXPECT_TRUE(has(text, "\"state\":\"training\"")) << text;
    full.lift();
  }
  // (c) training goes on: with the disk back the baseline is written and monitoring starts on it.
  dev.gate.t_ns = std::numeric_limits<std::int64_t>::max();
  ASSERT_TRUE(wait_for([&] { return live.d.view().state != DaemonState::kTraining && dev.pipelines >= 2; }));
  EXPECT_FALSE(formats::read_baseline(s.dir / "trained.bin").classes.empty());
  EXPECT_EQ(temp_files(s.dir), 0U);
  s.expect_baseline_kept();
}

/// `bytes` with the first float equal to `find` replaced by `value` and the trailing CRC-32 recomputed.
std::vector<char> forge(std::vector<char> bytes, float find, float value) {
  std::uint32_t f = 0, v = 0;
  std::memcpy(&f, &find, 4);
  std::memcpy(&v, &value, 4);
  for (std::size_t i = 0; i + 8 <= bytes.size(); ++i) {
    std::uint32_t x = 0;
    std::memcpy(&x, bytes.data() + i, 4);
    if (x != f) continue;
    std::memcpy(bytes.data() + i, &v, 4);
    const std::uint32_t crc = formats::crc32(bytes.data(), bytes.size() - 4);
    for (int k = 0; k < 4; ++k)
      bytes[bytes.size() - 4 + static_cast<std::size_t>(k)] = static_cast<char>(crc >> (8 * k));
    return bytes;
  }
  ADD_FAILURE() << "float not found in the baseline";
  return bytes;
}

void bad_baseline(const std::string& name, bool crc_valid) {
  const Scene s(name);
  const fs::path path = s.dir / "baseline.bin";
  std::vector<char> bytes = s.baseline_bytes;
  if (crc_valid) {
    const dsp::Baseline good = formats::read_baseline(path);
    bytes = forge(bytes, good.classes.at(0).mean_magnitude.at(1), std::nanf(""));
  } else {
    bytes[bytes.size() / 2] = static_cast<char>(bytes[bytes.size() / 2] ^ 0x5a);
  }
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  }
  FakeDevices dev(clean_source(), clean_frames());
  dev.gate.t_ns = healthy()->loop_ns / 4;
  Live live(s, s.config(), dev);
  ASSERT_TRUE(live.reach(dev, dev.gate.t_ns));
  ASSERT_TRUE(wait_for([&] { return has(read_text(s.status()), "\"state\":\"refused\""); }));
  const DaemonView v = live.d.view();
  // (a) refused, with the file and what is wrong in it.
  EXPECT_EQ(v.state, DaemonState::kRefused);
  EXPECT_EQ(v.phase, Phase::kRefused);
  const std::string reason(v.reason.view());
  EXPECT_TRUE(has(reason, path.string())) << reason;
  EXPECT_TRUE(has(reason, crc_valid ? "class" : "CRC")) << reason;
  EXPECT_EQ(v.pipeline.report.causes, drivers::kCauseBaseline);
  // (b) the refused file is left as it was (for the operator to inspect); every sample is counted.
  EXPECT_EQ(bytes_of(path), bytes);
  EXPECT_GT(v.pipeline.samples, 0U);
  // (c) not blind: no window judged, the outputs at fault (never normal), status still published.
  EXPECT_EQ(v.pipeline.windows, 0U);
  EXPECT_EQ(v.pipeline.report.level, drivers::AlarmLevel::kFault);
  const std::uint64_t writes = v.status_writes;
  EXPECT_TRUE(wait_for([&] { return live.d.view().status_writes >= writes + 2; }));
  std::printf("  %s baseline: %s\n", name.c_str(), reason.c_str());
}

void symlink_at_temp_names() {
  // Another user planted symlinks at the old predictable temporary names, pointing at a file of theirs.
  const Scene s("symlinks");
  const fs::path victim = scratch("fault_matrix_symlink_victim") / "shadow";
  write_text(victim, "root:secret\n");
  fs::permissions(victim, fs::perms::owner_read | fs::perms::owner_write);
  fs::create_directories(s.status_dir());
  const std::vector<fs::path> planted = {s.status_dir() / "status.json.tmp", s.status_dir() / "ptda.prom.tmp",
                                         s.dir / ("baseline.bin.tmp." + std::to_string(::getpid()))};
  for (const fs::path& p : planted) fs::create_symlink(victim, p);
  FakeDevices dev(clean_source(), clean_frames());
  const Replay r = replay(s, s.config(), dev);
  // (a) nothing to see: the writes succeeded at names of their own.
  EXPECT_TRUE(has(state_file_json(r.status, "status"), "\"failures\":0,")) << r.status;
  EXPECT_TRUE(has(state_file_json(r.status, "metrics"), "\"failures\":0,")) << r.status;
  // (b) the victim unchanged (content and mode), the symlinks neither followed nor removed.
  EXPECT_EQ(read_text(victim), "root:secret\n");
  EXPECT_EQ(fs::status(victim).permissions() & fs::perms::all,
            fs::perms::owner_read | fs::perms::owner_write);
  for (const fs::path& p : planted) EXPECT_TRUE(fs::is_symlink(p)) << p;
  EXPECT_EQ(bytes_of(s.dir / "baseline.bin"), s.baseline_bytes);
  // (c)
  EXPECT_FALSE(fs::is_symlink(s.status()));
  EXPECT_EQ(r.view.pipeline.samples, total_samples());
  EXPECT_EQ(r.view.pipeline.windows, reference().view.pipeline.windows);
}

void sighup_during_training() {
  const Scene s("sighup_training");
  FakeDevices dev(clean_source(), clean_frames());
  dev.gate.t_ns = healthy()->loop_ns / 5;  // every pipeline replays the stream from its start up to here
  Live live(s, s.training_config(12), dev, true);
  std::string text;
  // Settled: everything up to the gate processed, the training counts caught up with the pipeline's
  // windows, and the regions unchanged for 0.3 s (a region is counted after its last window, when the
  // slicer sees it end: under qemu on a loaded machine that lagged the windows by a status period).
  const auto settled = [&](std::uint64_t carried) {
    std::uint64_t last_regions = ~0ULL;
    auto since = std::chrono::steady_clock::now();
    return wait_for([&] {
      text = read_text(s.status());
      const DaemonView v = live.d.view();
      const std::uint64_t r = training_u64(text, "regions");
      const auto now = std::chrono::steady_clock::now();
      if (r != last_regions) {
        last_regions = r;
        since = now;
      }
      return has(text, "\"state\":\"training\"") && v.pipeline.windows > 0 &&
             v.pipeline.data_time_ns - dev.origin() >= dev.gate.t_ns - 30'000'000 &&
             training_u64(text, "windows") == carried + v.pipeline.windows &&
             now - since >= std::chrono::milliseconds(300);
    });
  };
  ASSERT_TRUE(settled(0)) << text;
  const std::uint64_t windows = training_u64(text, "windows"), regions = training_u64(text, "regions");
  ASSERT_GT(regions, 0U);
  ASSERT_EQ(::kill(::getpid(), SIGHUP), 0);
  ASSERT_TRUE(wait_for([&] { return live.d.view().reloads == 1 && dev.pipelines == 2; }));
  ASSERT_TRUE(settled(windows)) << text;
  // (a)
  EXPECT_EQ(json_reason(text), "reload kept " + std::to_string(windows) + " collected windows and " +
                                   std::to_string(regions) + " cycles");
  // (b) the pool kept, the new pipeline's windows added to it.
  EXPECT_EQ(training_u64(text, "windows"), 2 * windows);
  EXPECT_EQ(training_u64(text, "regions"), 2 * regions);
  s.expect_baseline_kept();
  // (c) training goes on to its end: the baseline is written and monitoring starts on it.
  dev.gate.t_ns = std::numeric_limits<std::int64_t>::max();
  ASSERT_TRUE(wait_for([&] { return live.d.view().state != DaemonState::kTraining && dev.pipelines >= 3; }));
  EXPECT_FALSE(formats::read_baseline(s.dir / "trained.bin").classes.empty());
}

struct Row {
  const char* name;
  std::function<void()> run;
};

class FaultMatrix : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { block_daemon_signals(); }
};

TEST_F(FaultMatrix, ClearCauseNoDataLostStillServing) {
  ASSERT_GE(reference().windows, 40U);
  ASSERT_EQ(reference().view.pipeline.samples, total_samples());
  const std::vector<Row> rows = {
      {"CAN silence", can_silence},
      {"CAN error-passive and bus-off", can_bus_off},
      {"ADC overrun", adc_overrun},
      {"SIGTERM right before the baseline write", sigterm_during_baseline_write},
      {"status directory full (EFBIG)", status_disk_full},
      {"status directory deleted", status_dir_deleted},
      {"baseline write failure in field training", baseline_write_failure},
      {"spill write failure in field training (EFBIG)", spill_write_failure},
      {"corrupt baseline (CRC)", [] { bad_baseline("corrupt_baseline", false); }},
      {"forged CRC-valid baseline (NaN)", [] { bad_baseline("forged_baseline", true); }},
      {"symlinks at the temporary names", symlink_at_temp_names},
      {"SIGHUP during field training", sighup_during_training},
  };
  for (const Row& row : rows) {
    SCOPED_TRACE(row.name);
    const auto t0 = std::chrono::steady_clock::now();
    row.run();
    std::printf("row '%s': %.0f ms\n", row.name,
                std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
}

}  // namespace
}  // namespace ptda::daemon::test
