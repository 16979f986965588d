// End-to-end cost of ptdad on a replay of a simulated paper job with a faulty gearbox.
//
// Set-up (once, cached in $PTDA_BENCH_DIR, default <build>/bench-data): for each paper job, the `ptda`
// tool simulates a healthy (seed 1001) and a faulty (seed 3003) recording and trains a baseline on
// the healthy one, as tests/golden/daemon_replay_test.cpp does.
//
// BM_DaemonLatency/<job>/<pace>: the daemon's real threads in-process (Daemon::configure, activate,
//   run: acquisition, CAN, processing and the supervisor) over the faulty recording (WAV + candump
//   replay, 256-sample blocks, [alarm.can] frames every 0.1 s, k-of-n without latch or hold). A
//   PipelineProbe and a WindowSink stamp CLOCK_MONOTONIC at four points; for each window, with B the
//   block that holds the window's last sample:
//     queue    = B popped from the sample ring        - B pushed by the acquisition thread
//     service  = window handed off (WindowSink)       - B popped (speed wait + slicer + DSP + k-of-n)
//     handoff  = window handed off                    - B pushed   (= queue + service)
//     output   = alarm outputs set()                  - B pushed, for the windows that changed the
//                published level or causes (the outputs are re-set only on a change or every period,
//                so they are not touched for every window; the hand-off is)
//     after_last_sample (realtime only) = handoff - acquisition time of the last sample (the replay
//                releases a block once its last sample is due, as an ADC FIFO would)
//   "fast" replays the whole recording as fast as the pipeline takes it (exit at the end); "realtime"
//   paces it like the devices and stops after $PTDA_BENCH_RT_WINDOWS windows (default 24, ~15 s).
//   cpu_s_per_signal_s = process CPU time (CLOCK_PROCESS_CPUTIME_ID) over activate()..run() divided
//   by the seconds of signal processed.
// BM_PtdadProcess/<job>/<method>: the real `ptdad` binary (--exit-at-end) on the fast replay; wait4()
//   gives its CPU time (user + system, start-up included), /proc/<pid>/status VmHWM its peak RSS.
// BM_PtdadDomain/<order>: `ptdad` on the joint-rotation faulty replay in the time domain (0) and the
//   order domain (1: [extraction] domain = "order", R = 4; its baseline trained by `ptda train`).
// BM_PtdadSim/<job>: `ptdad` on the simulator backend (faulty scenario synthesised in memory, fast,
//   looping) until 2 passes of windows; peak RSS and CPU time.
// Before the benchmarks, main() prints the fixed allocations of the pipeline for each job's
// configuration (rings, blocks, slicer history, FFT plans and buffers, baseline), computed from the
// configuration and the types' sizes.
#include <benchmark/benchmark.h>
#include <fcntl.h>
#include <kiss_fftr.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "core/daemon.hpp"
#include "core/daemon_config.hpp"
#include "ptda/common/error.hpp"
#include "ptda/drivers/clock.hpp"
#include "ptda/formats/baseline_file.hpp"
#include "ptda/formats/recording.hpp"
#include "ptda/formats/wav.hpp"

extern char** environ;

namespace {

namespace fs = std::filesystem;
using namespace ptda;

constexpr const char* kJobs[] = {"arc_welding", "joint_rotation", "spot_welding"};
constexpr const char* kMethods[] = {"raw", "tda", "ptda"};
constexpr std::uint32_t kBlockLen = 256;  // config/examples/ptdad.toml's block_len

std::int64_t mono_ns() {
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

double process_cpu_s() {
  timespec ts{};
  ::clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

fs::path data_dir() {
  const char* env = std::getenv("PTDA_BENCH_DIR");
  return env != nullptr && *env != '\0' ? fs::path(env) : fs::path(PTDA_BENCH_DEFAULT_DIR);
}

struct ProcessResult {
  int exit_code = -1;
  double wall_s = 0.0;
  double user_s = 0.0, sys_s = 0.0;
  double maxrss_mib = 0.0;  ///< ru_maxrss (includes the spawning process's RSS: see run_process)
  double hwm_mib = 0.0;     ///< VmHWM of the child's own mm, sampled every 2 ms
};

/// Runs argv (argv[0] is the executable path) with stdout and stderr appended to `log`, waits for it.
ProcessResult run_process(const std::vector<std::string>& argv, const fs::path& log) {
  std::vector<char*> args;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 1, log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
  posix_spawn_file_actions_adddup2(&fa, 1, 2);
  ProcessResult r;
  pid_t pid = 0;
  const std::int64_t t0 = mono_ns();
  const int rc = posix_spawn(&pid, args[0], &fa, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  if (rc != 0) throw Error(argv[0] + ": posix_spawn failed");
  // Peak RSS: ru_maxrss of a child also counts the parent's RSS at the spawn (the kernel keeps the
  // high-water mark of the mm that exec() replaced), so it would report this process's size. VmHWM
  // of /proc/<pid>/status is the high-water mark of ptdad's own mm: sample it every 2 ms until exit.
  const fs::path proc_status = fs::path("/proc") / std::to_string(pid) / "status";
  int status = 0;
  rusage ru{};
  for (;;) {
    const pid_t w = ::wait4(pid, &status, WNOHANG, &ru);
    if (w == pid) break;
    if (w < 0) throw Error(argv[0] + ": wait4 failed");
    std::ifstream in(proc_status);
    std::string line;
    while (std::getline(in, line)) {
      if (line.rfind("VmHWM:", 0) == 0) {
        r.hwm_mib = std::max(r.hwm_mib, std::strtod(line.c_str() + 6, nullptr) / 1024.0);  // kB
      }
    }
    ::usleep(2000);
  }
  r.wall_s = static_cast<double>(mono_ns() - t0) * 1e-9;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  r.user_s = static_cast<double>(ru.ru_utime.tv_sec) + static_cast<double>(ru.ru_utime.tv_usec) * 1e-6;
  r.sys_s = static_cast<double>(ru.ru_stime.tv_sec) + static_cast<double>(ru.ru_stime.tv_usec) * 1e-6;
  r.maxrss_mib = static_cast<double>(ru.ru_maxrss) / 1024.0;  // KiB on Linux
  return r;
}

struct Prepared {
  fs::path dir, faulty, baseline;
  double fs_hz = 0.0;
  double signal_s = 0.0;  ///< duration of the faulty recording
};

/// Simulates and trains once per job (cached on disk across runs).
const Prepared& prepare(const std::string& job) {
  static std::map<std::string, Prepared> cache;
  if (auto it = cache.find(job); it != cache.end()) return it->second;
  Prepared p;
  p.dir = data_dir() / job;
  p.faulty = p.dir / "faulty";
  p.baseline = p.dir / "baseline.bin";
  if (!fs::exists(p.baseline) || !fs::exists(p.faulty / "recording.toml")) {
    fs::create_directories(p.dir);
    const fs::path log = p.dir / "prepare.log";
    const std::string src = PTDA_SOURCE_DIR;
    const std::string scen = src + "/config/scenarios/" + job;
    const std::string cfg = src + "/config/examples/" + job + ".toml";
    const auto check = [&](const ProcessResult& r, const char* what) {
      if (r.exit_code != 0) throw Error(std::string("ptda ") + what + " failed; see " + log.string());
    };
    check(run_process({PTDA_BINARY, "simulate", "--scenario", scen + "_healthy.toml", "--out",
                       (p.dir / "train").string(), "--seed", "1001"},
                      log),
          "simulate");
    check(run_process({PTDA_BINARY, "simulate", "--scenario", scen + "_faulty.toml", "--out",
                       p.faulty.string(), "--seed", "3003"},
                      log),
          "simulate");
    check(run_process({PTDA_BINARY, "train", "--recording", (p.dir / "train").string(), "--config", cfg,
                       "--out", p.baseline.string()},
                      log),
          "train");
  }
  const formats::RecordingMeta meta = formats::read_recording_meta(p.faulty);
  const formats::WavReader wav(p.faulty / meta.vibration_file);
  p.fs_hz = static_cast<double>(wav.info().sample_rate_hz);
  p.signal_s = static_cast<double>(wav.info().frames) / p.fs_hz;
  return cache.emplace(job, p).first->second;
}

/// The job's pipeline tables (config/examples/<job>.toml) without [can] and [monitor].
std::string job_pipeline(const std::string& job) {
  std::ifstream in(fs::path(PTDA_SOURCE_DIR) / "config" / "examples" / (job + ".toml"));
  std::string line, out;
  bool skip = false;
  while (std::getline(in, line)) {
    if (!line.empty() && line[0] == '[') skip = line == "[can]" || line == "[monitor]";
    if (!skip) out += line + "\n";
  }
  return out;
}

/// The job's pipeline in the order domain (issue 16, docs/method.md §9): its window_len line replaced by
/// domain = "order" with R = 4 revolutions of S = 1024 samples (tests/golden/order_domain_test.cpp).
std::string order_pipeline(const std::string& job) {
  std::istringstream in(job_pipeline(job));
  std::string line, out;
  while (std::getline(in, line)) {
    if (line.rfind("window_len = ", 0) == 0) line = "domain = \"order\"\nrevolutions = 4";
    out += line + "\n";
  }
  return out;
}

/// Trains the order-domain baseline of the job on its healthy recording (cached on disk).
fs::path prepare_order_baseline(const Prepared& p, const std::string& job) {
  const fs::path baseline = p.dir / "baseline-order.bin";
  if (fs::exists(baseline)) return baseline;
  const fs::path cfg = p.dir / "order.toml";
  std::ofstream(cfg) << "[can]\nspeed_latency_s = 0.0005\n\n" << order_pipeline(job);
  const ProcessResult r = run_process({PTDA_BINARY, "train", "--recording", (p.dir / "train").string(),
                                       "--config", cfg.string(), "--out", baseline.string()},
                                      p.dir / "prepare.log");
  if (r.exit_code != 0)
    throw Error("ptda train (order domain) failed; see " + (p.dir / "prepare.log").string());
  return baseline;
}

/// A ptdad configuration for the replay of the job's faulty recording. Fast replays use a 50 ms status
/// period (as the daemon tests do): the supervisor notices the end of the replay within one period, and
/// the idle tail would otherwise add up to 1 s of idle threads to the measured CPU time.
fs::path write_replay_config(const Prepared& p, const std::string& job, const std::string& tag,
                             const std::string& pace, const std::string& method, bool order = false) {
  const fs::path dir = p.dir / tag;
  fs::create_directories(dir);
  const fs::path path = dir / "ptdad.toml";
  std::ofstream out(path);
  const fs::path baseline = order ? prepare_order_baseline(p, job) : p.baseline;
  // status.json where PTDA_BENCH_STATUS_ROOT says (scripts/bench_daemon.sh: a tmpfs, as the production
  // /run/ptda), else beside the configuration.
  const char* status_root = std::getenv("PTDA_BENCH_STATUS_ROOT");
  const fs::path status_dir = status_root != nullptr && *status_root != '\0'
                                  ? fs::path(status_root) / tag / "status"
                                  : dir / "status";
  out << "[daemon]\nbaseline = \"" << baseline.string() << "\"\nstatus_dir = \"" << status_dir.string()
      << "\"\nlog_level = \"warn\"\nstatus_period_s = " << (pace == "fast" ? "0.05" : "1.0")
      << "\n\n[adc]\nbackend = \"wav\"\nrecording = \"" << p.faulty.string() << "\"\npace = \"" << pace
      << "\"\nblock_len = " << kBlockLen << "\n\n[can]\nbackend = \"candump\"\npace = \"" << pace
      << "\"\nspeed_latency_s = " << (order ? "0.0005" : "0.0")
      << "\n\n[alarm]\nmin_hold_s = 0.0\nlatch = false\n\n"
      << "[alarm.can]\nenabled = true\nperiod_s = 0.1\n\n[monitor]\nmethod = \"" << method << "\"\n\n"
      << (order ? order_pipeline(job) : job_pipeline(job));
  return path;
}

// ---- latency instrumentation ------------------------------------------------------------------

struct BlockStamp {
  std::uint64_t first_index;
  std::uint32_t count;
  std::int64_t t_ns;
};
struct SetStamp {
  std::int64_t t_ns;
  drivers::AlarmLevel level;
  std::uint8_t causes;
};
struct WindowStamp {
  std::int64_t t_ns;         ///< hand-off
  std::int64_t last_sample;  ///< stream index of the window's last sample
  std::int64_t t_end_ns;     ///< daemon time of the last sample + 1/fs
  std::size_t sets_before;   ///< output sets made before the hand-off
};

/// The probe and the window sink: every container is reserved up front, so the hooks never allocate
/// (a full container drops the stamp; the counts are checked after the run).
class Recorder final : public daemon::PipelineProbe, public daemon::WindowSink {
 public:
  Recorder(std::size_t blocks, std::size_t windows, std::size_t sets) {
    pushed.reserve(blocks);
    popped.reserve(blocks);
    windows_.reserve(windows);
    sets_.reserve(sets);
  }
  void on_block_pushed(const drivers::SampleBlock& b) noexcept override { add(pushed, b); }
  void on_block_popped(const drivers::SampleBlock& b) noexcept override { add(popped, b); }
  void on_outputs_set(const drivers::AlarmReport& r) noexcept override {
    if (sets_.size() < sets_.capacity()) sets_.push_back({mono_ns(), r.level, r.causes});
  }
  void on_window(const dsp::WindowResult& w) noexcept override {
    if (windows_.size() < windows_.capacity()) {
      windows_.push_back({mono_ns(), w.ref.first_sample + static_cast<std::int64_t>(window_len) - 1,
                          w.ref.t_end_ns, sets_.size()});
    }
  }

  std::uint32_t window_len = 0;
  std::vector<BlockStamp> pushed, popped;
  std::vector<WindowStamp> windows_;
  std::vector<SetStamp> sets_;

 private:
  static void add(std::vector<BlockStamp>& v, const drivers::SampleBlock& b) noexcept {
    if (v.size() < v.capacity()) v.push_back({b.first_index, b.count, mono_ns()});
  }
};

/// The stamp of the block holding absolute sample index `index`, or nullptr.
const BlockStamp* find_block(const std::vector<BlockStamp>& v, std::uint64_t index) {
  auto it = std::upper_bound(v.begin(), v.end(), index,
                             [](std::uint64_t i, const BlockStamp& b) { return i < b.first_index; });
  if (it == v.begin()) return nullptr;
  --it;
  return index < it->first_index + it->count ? &*it : nullptr;
}

struct Stats {
  double p50 = 0, p99 = 0, max = 0;
  std::size_t n = 0;
};

Stats stats_us(std::vector<double> v) {
  Stats s;
  s.n = v.size();
  if (v.empty()) return s;
  std::sort(v.begin(), v.end());
  const auto rank = [&](double p) {
    const auto k = static_cast<std::size_t>(std::ceil(p * static_cast<double>(v.size())));
    return v[std::min(v.size(), std::max<std::size_t>(k, 1)) - 1];
  };
  s.p50 = rank(0.50);
  s.p99 = rank(0.99);
  s.max = v.back();
  return s;
}

void put(benchmark::State& state, const std::string& name, const Stats& s) {
  state.counters[name + "_p50_us"] = s.p50;
  state.counters[name + "_p99_us"] = s.p99;
  state.counters[name + "_max_us"] = s.max;
}

std::uint64_t realtime_windows() {
  const char* env = std::getenv("PTDA_BENCH_RT_WINDOWS");
  return env != nullptr ? std::strtoull(env, nullptr, 10) : 24;
}

void BM_DaemonLatency(benchmark::State& state) {
  const std::string job = kJobs[state.range(0)];
  const bool realtime = state.range(1) == 1;
  const Prepared& p = prepare(job);
  const fs::path config = write_replay_config(p, job, realtime ? "latency-rt" : "latency-fast",
                                              realtime ? "realtime" : "fast", "ptda");
  std::vector<double> queue, service, handoff, output, after_last;
  double cpu_s = 0.0, signal_s = 0.0;
  std::size_t windows = 0, missing = 0;
  for (auto _ : state) {
    const auto blocks = static_cast<std::size_t>(p.signal_s * p.fs_hz / kBlockLen) + 64;
    Recorder rec(blocks, 100'000, 1'000'000);
    drivers::MonotonicClock clock;
    daemon::DaemonOptions opt;
    opt.config_file = config;
    opt.config_dir = fs::path();
    opt.exit_at_end = !realtime;
    opt.exit_after_windows = realtime ? realtime_windows() : 0;
    daemon::Daemon d(opt, clock);
    d.set_window_sink(&rec);
    d.set_probe(&rec);
    d.configure();
    rec.window_len = d.config().pipeline.extraction.window_len;
    const double cpu0 = process_cpu_s();
    d.activate();
    if (d.run() != 0) state.SkipWithError("ptdad exited with an error");
    cpu_s += process_cpu_s() - cpu0;
    const daemon::DaemonView v = d.view();
    signal_s += static_cast<double>(v.pipeline.samples) / p.fs_hz;

    if (rec.pushed.empty() || rec.popped.empty()) {
      state.SkipWithError("no block was stamped");
      break;
    }
    const std::uint64_t base = rec.popped.front().first_index;  // the pipeline's sample 0
    const std::int64_t sample_ns = std::llround(1e9 / p.fs_hz);
    for (std::size_t i = 0; i < rec.windows_.size(); ++i) {
      const WindowStamp& w = rec.windows_[i];
      const auto index = base + static_cast<std::uint64_t>(w.last_sample);
      const BlockStamp* push = find_block(rec.pushed, index);
      const BlockStamp* pop = find_block(rec.popped, index);
      if (push == nullptr || pop == nullptr) {
        ++missing;
        continue;
      }
      ++windows;
      queue.push_back(static_cast<double>(pop->t_ns - push->t_ns) * 1e-3);
      service.push_back(static_cast<double>(w.t_ns - pop->t_ns) * 1e-3);
      handoff.push_back(static_cast<double>(w.t_ns - push->t_ns) * 1e-3);
      if (realtime) after_last.push_back(static_cast<double>(w.t_ns - (w.t_end_ns - sample_ns)) * 1e-3);
      // The first set() after this hand-off, when it published a change and this is the last window
      // handed off before it (the window whose verdict the change shows).
      const std::size_t s = w.sets_before;
      const bool last_before_set = i + 1 == rec.windows_.size() || rec.windows_[i + 1].sets_before > s;
      if (s < rec.sets_.size() && s > 0 && last_before_set &&
          (rec.sets_[s].level != rec.sets_[s - 1].level || rec.sets_[s].causes != rec.sets_[s - 1].causes)) {
        output.push_back(static_cast<double>(rec.sets_[s].t_ns - push->t_ns) * 1e-3);
      }
    }
    if (rec.pushed.size() == rec.pushed.capacity() || rec.windows_.size() == rec.windows_.capacity() ||
        rec.sets_.size() == rec.sets_.capacity()) {
      state.SkipWithError("a stamp buffer filled up");
    }
  }
  const std::string label = job + (realtime ? " realtime" : " fast");
  state.SetLabel(label);
  put(state, "queue", stats_us(queue));
  put(state, "service", stats_us(service));
  put(state, "handoff", stats_us(handoff));
  put(state, "output", stats_us(output));
  state.counters["output_n"] = static_cast<double>(output.size());
  if (realtime) put(state, "after_last_sample", stats_us(after_last));
  state.counters["windows"] = static_cast<double>(windows);
  state.counters["unmatched"] = static_cast<double>(missing);
  state.counters["signal_s"] = signal_s;
  state.counters["cpu_s_per_signal_s"] = signal_s > 0 ? cpu_s / signal_s : 0.0;
}

BENCHMARK(BM_DaemonLatency)
    ->ArgNames({"job", "realtime"})
    ->Args({0, 0})
    ->Args({1, 0})
    ->Args({2, 0})
    ->Iterations(1)
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_DaemonLatency)
    ->ArgNames({"job", "realtime"})
    ->Args({0, 1})
    ->Iterations(1)
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

void BM_PtdadProcess(benchmark::State& state) {
  const std::string job = kJobs[state.range(0)];
  const std::string method = kMethods[state.range(1)];
  const Prepared& p = prepare(job);
  const fs::path config = write_replay_config(p, job, "process-" + method, "fast", method);
  double cpu_s = 0.0, user_s = 0.0, sys_s = 0.0, rss = 0.0;
  std::int64_t runs = 0;
  for (auto _ : state) {
    const ProcessResult r = run_process(
        {PTDAD_BINARY, "--config", config.string(), "--config-dir", "", "--exit-at-end", "--foreground"},
        config.parent_path() / "ptdad.log");
    if (r.exit_code != 0) state.SkipWithError("ptdad failed; see ptdad.log next to the configuration");
    state.SetIterationTime(r.wall_s);
    cpu_s += r.user_s + r.sys_s;
    user_s += r.user_s;
    sys_s += r.sys_s;
    rss = std::max(rss, r.hwm_mib);
    ++runs;
  }
  const double signal_s = p.signal_s * static_cast<double>(runs);
  state.SetLabel(job + " " + method);
  state.counters["cpu_s_per_signal_s"] = cpu_s / signal_s;
  state.counters["user_s"] = user_s / static_cast<double>(runs);
  state.counters["sys_s"] = sys_s / static_cast<double>(runs);
  state.counters["signal_s"] = p.signal_s;
  state.counters["peak_rss_MiB"] = rss;
}

BENCHMARK(BM_PtdadProcess)
    ->ArgNames({"job", "method"})
    ->ArgsProduct({{0, 1, 2}, {0, 1, 2}})
    ->Iterations(1)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

// BM_PtdadDomain/<domain>: `ptdad` (PTDA) on the joint-rotation job's faulty replay in the time domain
// (windows of 12800 samples) and in the order domain (CAN angle -> AngleResampler, windows of 4
// input-shaft revolutions of 1024 samples); CPU time per second of signal, start-up included.
void BM_PtdadDomain(benchmark::State& state) {
  const bool order = state.range(0) == 1;
  const std::string job = "joint_rotation";
  const Prepared& p = prepare(job);
  const fs::path config =
      write_replay_config(p, job, order ? "domain-order" : "domain-time", "fast", "ptda", order);
  double cpu_s = 0.0, rss = 0.0;
  std::int64_t runs = 0;
  for (auto _ : state) {
    const ProcessResult r = run_process(
        {PTDAD_BINARY, "--config", config.string(), "--config-dir", "", "--exit-at-end", "--foreground"},
        config.parent_path() / "ptdad.log");
    if (r.exit_code != 0) state.SkipWithError("ptdad failed; see ptdad.log next to the configuration");
    state.SetIterationTime(r.wall_s);
    cpu_s += r.user_s + r.sys_s;
    rss = std::max(rss, r.hwm_mib);
    ++runs;
  }
  state.SetLabel(job + (order ? " order domain" : " time domain"));
  state.counters["cpu_s_per_signal_s"] = cpu_s / (p.signal_s * static_cast<double>(runs));
  state.counters["signal_s"] = p.signal_s;
  state.counters["peak_rss_MiB"] = rss;
}

BENCHMARK(BM_PtdadDomain)
    ->ArgNames({"order"})
    ->DenseRange(0, 1)
    ->Iterations(5)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

/// The status file's "samples" (vibration samples read), or 0.
double status_samples(const fs::path& status_json) {
  std::ifstream in(status_json);
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string text = ss.str();
  const auto pos = text.find("\"samples\":");
  return pos == std::string::npos ? 0.0 : std::strtod(text.c_str() + pos + 10, nullptr);
}

void BM_PtdadSim(benchmark::State& state) {
  const std::string job = kJobs[state.range(0)];
  const Prepared& p = prepare(job);
  const fs::path dir = p.dir / "sim";
  fs::create_directories(dir);
  const fs::path config = dir / "ptdad.toml";
  {
    std::ofstream out(config);
    out << "[daemon]\nbaseline = \"" << p.baseline.string() << "\"\nstatus_dir = \""
        << (dir / "status").string()
        << "\"\nstatus_period_s = 0.05\nlog_level = \"warn\"\n\n[adc]\nbackend = \"sim\"\nscenario = \""
        << PTDA_SOURCE_DIR << "/config/scenarios/" << job << "_faulty.toml\"\nseed = 3003\npace = \"fast\"\n"
        << "loop = true\nblock_len = " << kBlockLen << "\n\n[can]\nbackend = \"sim\"\npace = \"fast\"\n"
        << "speed_latency_s = 0.0\n\n[alarm]\nmin_hold_s = 0.0\nlatch = false\n\n[monitor]\nmethod = "
           "\"ptda\"\n\n"
        << job_pipeline(job);
  }
  double cpu_s = 0.0, rss = 0.0, samples = 0.0;
  for (auto _ : state) {
    const ProcessResult r =
        run_process({PTDAD_BINARY, "--config", config.string(), "--config-dir", "", "--foreground",
                     "--test-exit-after-windows", std::to_string(state.range(1))},
                    dir / "ptdad.log");
    if (r.exit_code != 0) state.SkipWithError("ptdad failed; see sim/ptdad.log");
    state.SetIterationTime(r.wall_s);
    cpu_s += r.user_s + r.sys_s;
    rss = std::max(rss, r.hwm_mib);
    samples += status_samples(dir / "status" / "status.json");
  }
  const double signal_s = samples / p.fs_hz;
  state.SetLabel(job + " sim");
  state.counters["signal_s"] = signal_s;  // from status.json (written every 50 ms: a lower bound)
  state.counters["cpu_s_per_signal_s"] = signal_s > 0 ? cpu_s / signal_s : 0.0;
  state.counters["peak_rss_MiB"] = rss;
}

// Two passes of each job's windows (101, 40 and 20 per pass; see tests/golden/daemon_replay_test.cpp).
BENCHMARK(BM_PtdadSim)
    ->ArgNames({"job", "windows"})
    ->Args({0, 202})
    ->Args({1, 80})
    ->Args({2, 40})
    ->Iterations(1)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

// ---- fixed allocations ---------------------------------------------------------------------------

std::size_t fft_plan_bytes(std::size_t n, int inverse) {
  std::size_t len = 0;
  kiss_fftr_alloc(static_cast<int>(n), inverse, nullptr, &len);
  return len;
}

void print_fixed_allocations() {
  std::printf("Fixed allocations of the ptdad pipeline (bytes, from the configuration and sizeof):\n");
  std::printf("%-15s %7s %10s %10s %10s %12s %10s %10s %10s %10s\n", "job", "N", "SampleRing", "SpeedRing",
              "2 blocks", "slicer hist", "pending", "FFT plans", "analyzer", "baseline");
  for (const char* job : kJobs) {
    const Prepared& p = prepare(job);
    const dsp::Baseline b = formats::read_baseline(p.baseline);
    const std::size_t n = b.window_len;
    const std::size_t bins = n / 2 + 1;
    const daemon::DaemonConfig cfg =
        daemon::load_daemon_config(write_replay_config(p, job, "latency-fast", "fast", "ptda"));
    const dsp::ExtractionConfig& ex = cfg.pipeline.extraction;
    const std::size_t hop = ex.hop == 0 ? n : ex.hop;
    const std::size_t history = 4 * n + static_cast<std::size_t>(std::ceil(p.fs_hz));
    const std::size_t slicer = history * (sizeof(float) + 1);
    const std::size_t pending =
        (2 * history / hop + 64) * sizeof(dsp::WindowRef) + 1024 * 16 + 256 * sizeof(dsp::RegionInfo);
    const std::size_t plans = fft_plan_bytes(n, 0) + fft_plan_bytes(n, 1);
    // WindowAnalyzer d_, r_ (N floats each), X_, D_, R_ (N/2+1 complex each); MonitorEngine window_.
    const std::size_t analyzer = 3 * n * sizeof(float) + 3 * bins * sizeof(std::complex<float>);
    std::size_t baseline = 0;
    for (const auto& c : b.classes) baseline += (c.mean_magnitude.size() + c.tda_mean.size()) * sizeof(float);
    std::printf("%-15s %7zu %10zu %10zu %10zu %12zu %10zu %10zu %10zu %10zu  (%zu classes)\n", job, n,
                sizeof(daemon::SampleRing), sizeof(daemon::SpeedRing), 2 * sizeof(drivers::SampleBlock),
                slicer, pending, plans, analyzer, baseline, b.classes.size());
  }
  std::printf("\n");
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  try {
    print_fixed_allocations();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "daemon_bench: set-up failed: %s\n", e.what());
    return 1;
  }
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
