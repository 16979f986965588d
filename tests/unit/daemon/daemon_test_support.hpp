// Helpers shared by the daemon core tests (tests/unit/daemon/daemon_*_test.cpp): scratch directories,
// configuration text for the arc-welding job on the simulator backends, and a baseline trained
// in-process from the simulator (the same slicer + dsp::train_baseline that `ptda train` uses).
#pragma once

#include <gtest/gtest.h>
#include <signal.h>
#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <thread>

#include "core/daemon.hpp"
#include "core/daemon_config.hpp"
#include "core/sim_backends.hpp"
#include "ptda/common/time.hpp"
#include "ptda/config/pipeline_config.hpp"
#include "ptda/config/speed_codec.hpp"
#include "ptda/dsp/angle_resampler.hpp"
#include "ptda/dsp/baseline_training.hpp"
#include "ptda/dsp/frame_clock.hpp"
#include "ptda/dsp/monitor_engine.hpp"
#include "ptda/dsp/order_windows.hpp"
#include "ptda/formats/baseline_file.hpp"

namespace ptda::daemon::test {

namespace fs = std::filesystem;

/// Captures every log line of the default logger for the life of the object.
class LogCapture {
 public:
  LogCapture() : previous_(spdlog::default_logger()) {
    auto sink = std::make_shared<spdlog::sinks::ostream_sink_mt>(out_);
    auto logger = std::make_shared<spdlog::logger>("capture", sink);
    logger->set_pattern("%l: %v");
    logger->set_level(spdlog::level::trace);
    spdlog::set_default_logger(logger);
  }
  ~LogCapture() { spdlog::set_default_logger(previous_); }
  LogCapture(const LogCapture&) = delete;
  LogCapture& operator=(const LogCapture&) = delete;
  [[nodiscard]] std::string text() {
    spdlog::default_logger()->flush();
    return out_.str();
  }

 private:
  std::shared_ptr<spdlog::logger> previous_;
  std::ostringstream out_;
};

inline fs::path source_dir() {
  return fs::path(PTDA_SOURCE_DIR);
}
inline fs::path arc_scenario() {
  return source_dir() / "config" / "scenarios" / "arc_welding_healthy.toml";
}

/// A fresh scratch directory PTDA_TEST_TMP/daemon/<name>.
inline fs::path scratch(const std::string& name) {
  const char* env = std::getenv("PTDA_TEST_TMP");
  const fs::path base = env != nullptr ? fs::path(env) : fs::temp_directory_path() / "ptda-test-tmp";
  const fs::path dir = base / "daemon" / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

inline void write_text(const fs::path& p, const std::string& text) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out << text;
}

/// The arc-welding job's pipeline (config/examples/arc_welding.toml) without its [can] table.
/// band: with `band_cusum = true` in its [decision] table (the band CUSUM, session 12); mesh: with
/// `mesh_cusum = true` (the mesh detector, session 19).
inline std::string arc_pipeline(bool band = false, bool mesh = false) {
  std::ifstream in(source_dir() / "config" / "examples" / "arc_welding.toml");
  std::string line, out;
  bool skip = false;
  while (std::getline(in, line)) {
    if (!line.empty() && line[0] == '[') skip = line.rfind("[can", 0) == 0;
    if (!skip) out += line + "\n";
    if (band && line == "[decision]") out += "band_cusum = true\n";
    if (mesh && line == "[decision]") out += "mesh_cusum = true\n";
  }
  return out;
}

/// A daemon configuration whose devices come from the DeviceFactory (daemon_fakes.hpp; the [adc]/[can]
/// backends named here are never opened), fast pace, status period 50 ms. `extra` goes after [can]
/// (tables such as [training]), `extra_daemon` into [daemon]; `pipeline_edit` replaces the pipeline's
/// "clip_abs = 0.0" line.
inline std::string fake_config(const fs::path& dir, const std::string& extra = "",
                               const std::string& pipeline_edit = "", const std::string& extra_daemon = "") {
  std::string pipe = arc_pipeline();
  if (!pipeline_edit.empty()) pipe.replace(pipe.find("clip_abs = 0.0"), 14, pipeline_edit);
  return "[daemon]\nbaseline = \"" + (dir / "baseline.bin").string() + "\"\nstatus_dir = \"" +
         (dir / "status").string() + "\"\nstatus_period_s = 0.05\n" + extra_daemon +
         "\n[adc]\nbackend = \"wav\"\nrecording = \"" + (dir / "not-opened").string() +
         "\"\npace = \"fast\"\n\n[can]\nbackend = \"candump\"\npace = \"fast\"\n\n" + extra + "\n" + pipe;
}

/// The unsigned value after "key": inside status.json's "training" object (0 when absent).
inline std::uint64_t training_u64(const std::string& text, const std::string& key) {
  const auto obj = text.find("\"training\":{");
  if (obj == std::string::npos) return 0;
  const auto at = text.find("\"" + key + "\":", obj);
  if (at == std::string::npos) return 0;
  return std::strtoull(text.c_str() + at + key.size() + 3, nullptr, 10);
}

/// The string value of status.json's "reason".
inline std::string json_reason(const std::string& text) {
  const auto at = text.find("\"reason\":\"");
  if (at == std::string::npos) return "";
  const auto from = at + 10;
  return text.substr(from, text.find('"', from) - from);
}

/// The object text of `file` ("status", "metrics", "baseline") inside status.json's "state_files" (""
/// when absent).
inline std::string state_file_json(const std::string& status, const std::string& file) {
  const auto obj = status.find("\"state_files\":{");
  if (obj == std::string::npos) return "";
  const auto at = status.find("\"" + file + "\":{", obj);
  if (at == std::string::npos) return "";
  return status.substr(at, status.find('}', at) - at + 1);
}

/// How many "*.tmp*" entries `dir` holds.
inline std::size_t temp_files(const fs::path& dir) {
  std::size_t n = 0;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (e.path().filename().string().find(".tmp") != std::string::npos) ++n;
  }
  return n;
}

/// A daemon configuration for the simulator backends (arc-welding healthy scenario).
inline std::string sim_config(const fs::path& baseline, const fs::path& status_dir, const std::string& pace,
                              const std::string& extra_daemon = "", const std::string& extra = "",
                              bool band = false, bool mesh = false) {
  std::ostringstream s;
  s << "[daemon]\nbaseline = \"" << baseline.string() << "\"\nstatus_dir = \"" << status_dir.string()
    << "\"\nstatus_period_s = 0.05\n"
    << extra_daemon << "\n[adc]\nbackend = \"sim\"\nscenario = \"" << arc_scenario().string()
    << "\"\nseed = 7\npace = \"" << pace << "\"\n\n[can]\nbackend = \"sim\"\npace = \"" << pace << "\"\n\n"
    << extra << "\n"
    << arc_pipeline(band, mesh);
  return s.str();
}

/// Trains a baseline on the simulated healthy arc-welding job (seed 7) and writes it to `path`, once
/// per process (later calls copy the first file). Allocates; takes ~1 s.
/// band: trained with `[decision] band_cusum = true` said (required); without it the default (on since
/// session 13) also stores band statistics (format 7).
/// mesh: trained with `[decision] mesh_cusum = true` (format 8).
inline void write_sim_baseline(const fs::path& path, bool band = false, bool mesh = false) {
  static fs::path first[4];
  const int slot = (band ? 1 : 0) + (mesh ? 2 : 0);
  if (!first[slot].empty()) {
    fs::copy_file(first[slot], path, fs::copy_options::overwrite_existing);
    return;
  }
  const DaemonConfig cfg =
      parse_daemon_config(sim_config(path, "", "fast", "", "", band, mesh), "baseline.toml");
  const config::PipelineConfig& pc = cfg.pipeline;
  const auto rec = make_sim_recording(arc_scenario(), 7);
  dsp::WindowSlicer slicer(pc.extraction, rec->fs_hz, 0);
  dsp::CollectedWindows data;
  std::vector<float> buf(pc.extraction.window_len);
  const auto drain = [&] {
    dsp::WindowRef ref;
    while (slicer.pop(ref, buf)) {
      data.refs.push_back(ref);
      data.windows.push_back(buf);
    }
    dsp::RegionInfo region;
    while (slicer.pop_region(region)) data.regions.push_back(region);
  };
  std::size_t f = 0;
  const std::size_t n = rec->samples.size();
  for (std::size_t pos = 0; pos < n; pos += 4096) {
    const std::size_t count = std::min<std::size_t>(4096, n - pos);
    const std::int64_t t_end = rec->sample_offset_ns(pos + count);
    for (; f < rec->frames.size() && rec->frames[f].t_ns < t_end; ++f) {
      config::DecodedSpeed d;
      if (config::decode_speed(rec->frames[f], pc.speed_frame, d) == config::DecodeResult::kOk) {
        slicer.push_speed({rec->frames[f].t_ns, d.speed_rad_s, d.angle_rad, d.has_angle});
      }
    }
    slicer.push_samples(std::span<const float>(rec->samples.data() + pos, count));
    drain();
  }
  slicer.finish();
  drain();
  dsp::Baseline b = dsp::train_baseline(data, pc.classes, pc.thresholds, rec->fs_hz, pc.gearbox);
  b.source = "daemon tests: simulated arc welding, seed 7";
  formats::write_baseline(path, b);
  first[slot] = path;
}

// ---- order domain (issue 16) ----------------------------------------------------------------------

inline fs::path joint_scenario() {
  return source_dir() / "config" / "scenarios" / "joint_rotation_healthy.toml";
}

/// The joint-rotation job's pipeline (config/examples/joint_rotation.toml) without its [can] tables, in
/// the order domain with windows of R = 4 revolutions (as tests/golden/order_domain_test.cpp).
inline std::string order_pipeline() {
  std::ifstream in(source_dir() / "config" / "examples" / "joint_rotation.toml");
  std::string line, out;
  bool skip = false;
  while (std::getline(in, line)) {
    if (!line.empty() && line[0] == '[') skip = line.rfind("[can", 0) == 0;
    if (skip) continue;
    if (line.rfind("window_len = 12800", 0) == 0) line = "domain = \"order\"\nrevolutions = 4";
    out += line + "\n";
  }
  return out;
}

/// Trains the order baseline in-process on one pass of the simulated healthy joint rotation (seed 101):
/// the front end `ptda train` runs in the order domain (FrameClock, AngleResampler, OrderWindowCutter)
/// and dsp::train_order_baseline. Allocates.
inline void write_sim_order_baseline(const fs::path& path, const std::string& config_text) {
  const DaemonConfig cfg = parse_daemon_config(config_text, "order.toml");
  const config::PipelineConfig& pc = cfg.pipeline;
  const auto rec = make_sim_recording(joint_scenario(), 101);
  dsp::AngleResampler res(config::angle_resampler_config(pc), rec->fs_hz, 0);
  const dsp::OrderWindowConfig oc = config::order_window_config(pc, res.pass_order());
  dsp::OrderWindowCutter cut(oc);
  dsp::FrameClock frame_clock(pc.speed_frame.period_s, pc.order.can_time_smoothing_frames);
  const std::int64_t latency_ns = seconds_to_ns(pc.speed_latency_s);
  dsp::OrderWindows data;
  std::vector<float> buf(cut.window_len());
  std::size_t f = 0;
  const std::size_t n = rec->samples.size();
  for (std::size_t pos = 0; pos < n; pos += 4096) {
    const std::size_t count = std::min<std::size_t>(4096, n - pos);
    const std::int64_t t_end = rec->sample_offset_ns(pos + count);
    for (; f < rec->frames.size() && rec->frames[f].t_ns - latency_ns < t_end; ++f) {
      config::DecodedSpeed d;
      if (config::decode_speed(rec->frames[f], pc.speed_frame, d) == config::DecodeResult::kOk) {
        res.push_speed(
            {frame_clock.smooth(rec->frames[f].t_ns - latency_ns), d.speed_rad_s, d.angle_rad, d.has_angle});
      }
    }
    res.push_samples(std::span<const float>(rec->samples.data() + pos, count));
    dsp::OrderSample o;
    dsp::OrderWindowRef ref;
    while (res.pop(o)) {
      if (!cut.push(o, ref, buf)) continue;
      data.refs.push_back(ref);
      data.windows.push_back(buf);
    }
  }
  dsp::Baseline b = dsp::train_order_baseline(data, oc, pc.order.speed_band_rel, pc.thresholds, pc.gearbox);
  b.domain = dsp::Domain::kOrder;
  b.samples_per_rev = pc.order.samples_per_rev;
  b.revolutions = pc.order.revolutions;
  b.source = "daemon tests: simulated joint rotation, seed 101, order domain";
  formats::write_baseline(path, b);
}

/// Blocks the daemon's signals in this thread (before any thread is started) so that a signal sent
/// to the process stays pending for the daemon's signalfd instead of killing the test.
// Voluntary context switches (a sleep that blocked: one wake-up each) of this process's threads, by
// thread name (/proc/self/task/<tid>/status). Allocates: call it outside an AllocScope.
inline std::map<std::string, std::uint64_t> sleeps_by_thread() {
  std::map<std::string, std::uint64_t> out;
  for (const auto& t : fs::directory_iterator("/proc/self/task")) {
    std::ifstream comm(t.path() / "comm");
    std::string name;
    std::getline(comm, name);
    std::ifstream status(t.path() / "status");
    std::string line;
    while (std::getline(status, line)) {
      if (line.rfind("voluntary_ctxt_switches:", 0) == 0) {
        std::istringstream in(line.substr(24));
        std::uint64_t v = 0;
        in >> v;
        out[name] += v;
      }
    }
  }
  return out;
}

inline void block_daemon_signals() {
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGTERM);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGHUP);
  pthread_sigmask(SIG_BLOCK, &set, nullptr);
}

/// Runs Daemon::run() on its own thread and expects exit code 0. join() waits for a run that ends by
/// itself (--exit-at-end) or after a request_stop(); the destructor requests the stop and joins, so a
/// failed ASSERT in the test cannot leave the thread running (or hang the test).
class DaemonRunThread {
 public:
  explicit DaemonRunThread(Daemon& d) : d_(d), t_([this] { EXPECT_EQ(d_.run(), 0); }) {}
  DaemonRunThread(const DaemonRunThread&) = delete;
  DaemonRunThread& operator=(const DaemonRunThread&) = delete;
  ~DaemonRunThread() {
    d_.request_stop();
    join();
  }
  void join() {
    if (t_.joinable()) t_.join();
  }

 private:
  Daemon& d_;
  std::thread t_;
};

/// Deletes a directory a running daemon writes into, as at once as a file system allows: rename, then
/// delete the renamed tree. A plain remove_all() races with the daemon's next temporary file and throws
/// "Directory not empty" (seen under qemu-user on a loaded machine).
inline void remove_dir_under_daemon(const fs::path& dir) {
  const fs::path gone = dir.parent_path() / (dir.filename().string() + ".gone");
  fs::remove_all(gone);
  fs::rename(dir, gone);
  fs::remove_all(gone);
}

/// Multiplier for failure-guard deadlines: PTDA_TEST_TIME_SCALE, which the cross test presets set
/// (CMakePresets.json) because everything runs 5-20x slower under qemu-user; 1 when unset.
inline double test_time_scale() {
  const char* env = std::getenv("PTDA_TEST_TIME_SCALE");
  const double scale = env != nullptr ? std::atof(env) : 1.0;
  return scale > 1.0 ? scale : 1.0;
}

/// Polls `pred` every 5 ms until it holds or `limit` (times test_time_scale()) passed: a failure
/// guard, not a timing claim.
template <typename Pred>
bool wait_for(Pred pred, std::chrono::milliseconds limit = std::chrono::milliseconds(10000)) {
  const auto deadline =
      std::chrono::steady_clock::now() +
      std::chrono::duration_cast<std::chrono::steady_clock::duration>(limit * test_time_scale());
  while (!pred()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return true;
}

}  // namespace ptda::daemon::test
