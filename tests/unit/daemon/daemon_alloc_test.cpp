// After warm-up, a long run through the daemon's real threads (acquisition, CAN, processing and the
// supervisor writing status.json + metrics and pinging the watchdog) makes no heap allocation.
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <memory>
#include <thread>

#include "alloc_counter.hpp"
#include "daemon_test_support.hpp"

namespace ptda::daemon::test {
namespace {

TEST(DaemonAlloc, SteadyStateMakesNoAllocations) {
  block_daemon_signals();
  const fs::path dir = scratch("alloc");
  write_sim_baseline(dir / "baseline.bin");
  // The simulator at fast pace, looping: ~60 s of job per pass, as fast as the engine goes.
  write_text(
      dir / "ptdad.toml",
      sim_config(
          dir / "baseline.bin", dir / "status", "fast",
          "metrics_path = \"" + (dir / "metrics" / "ptda.prom").string() + "\"\njoint = \"j4\"\n",
          "[alarm]\nmin_hold_s = 0.5\nlatch = false\n[alarm.can]\nenabled = true\nperiod_s = 0.05\n"
          // The event history, small files: the two passes below write and rotate it.
          "[history]\ndir = \"" +
              (dir / "history").string() +
              "\"\nmax_file_mib = 0.05\nfiles = 3\n"
              // MQTT on, towards a port nobody listens on: the supervisor hands every event and
              // summary to the publisher thread (which queues them on disk and is not counted: it is
              // no real-time thread, tests/support/alloc_counter.cpp).
              "[mqtt]\nenabled = true\nhost = \"127.0.0.1\"\nport = 9\ntopic_prefix = \"ptda/t/{joint}\"\n"
              "queue_dir = \"" +
              (dir / "mqtt").string() + "\"\nwindow_summary_interval_s = 0.5\n"));
  // A datagram socket for sd_notify (nobody reads it; a full queue is counted, not fatal).
  const fs::path sock = dir / "notify.sock";
  const int fd = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::snprintf(addr.sun_path, sizeof addr.sun_path, "%s", sock.c_str());
  ASSERT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);

  drivers::MonotonicClock clock;
  DaemonOptions opt;
  opt.config_file = dir / "ptdad.toml";
  opt.config_dir = fs::path();
  opt.notify_socket = sock.string();
  opt.watchdog = parse_watchdog_settings("100000", nullptr, ::getpid());
  auto daemon = std::make_unique<Daemon>(opt, clock);
  Daemon& d = *daemon;
  d.configure();
  d.activate();
  std::thread runner([&] { EXPECT_EQ(d.run(), 0); });

  // Warm-up: a full pass over the simulated recording (the loop seam included) and a few windows.
  const std::uint64_t pass = 1'626'483;  // samples of one pass of the scenario (pinned below)
  ASSERT_TRUE(wait_for([&] { return d.view().pipeline.samples > pass + 200'000; }, std::chrono::seconds(60)));
  const DaemonView before = d.view();
  std::uint64_t allocations = 0;
  const auto t_start = std::chrono::steady_clock::now();
  {
    ptda::test::AllocScope scope;
    // Two more passes: every class, the loop seam twice, status writes and watchdog pings.
    // (and at least two status writes and a watchdog ping: at fast pace two passes take ~0.1 s, less
    // than two status periods on a loaded machine)
    wait_for(
        [&] {
          const DaemonView v = d.view();
          return v.pipeline.samples > before.pipeline.samples + 2 * pass &&
                 v.status_writes > before.status_writes + 1 && v.watchdog_pings > before.watchdog_pings;
        },
        std::chrono::seconds(120));
    allocations = scope.count();
  }
  const DaemonView after = d.view();
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  std::printf("steady state: %.1f s of data (%llu windows) in %.2f s wall, %llu allocations\n",
              static_cast<double>(after.pipeline.samples - before.pipeline.samples) / 25600.0,
              static_cast<unsigned long long>(after.pipeline.windows - before.pipeline.windows), wall_s,
              static_cast<unsigned long long>(allocations));
  d.request_stop();
  runner.join();
  // Destroyed here: the publisher thread moves what is left in its hand-over ring into the queue (at
  // fast pace the real-time threads may have kept it off the CPU for the whole run).
  daemon.reset();
  ::close(fd);

  EXPECT_EQ(allocations, 0U);
  EXPECT_GT(after.pipeline.samples, before.pipeline.samples + 2 * pass);
  EXPECT_GE(after.pipeline.scored - before.pipeline.scored, 190U);  // ~100 windows per pass
  EXPECT_GT(after.status_writes, before.status_writes);
  EXPECT_GT(after.watchdog_pings, before.watchdog_pings);
  EXPECT_EQ(after.counters.acq_ring_full_blocks, 0U);
  EXPECT_GT(after.counters.can_frames, 0U);
  // The history was written and rotated while the allocations were counted (~700 bytes a window line:
  // a 50 KiB file holds ~70 of the ~200 windows).
  EXPECT_TRUE(fs::exists(dir / "history" / "history.2.jsonl"));
  EXPECT_FALSE(fs::exists(dir / "history" / "history.3.jsonl"));
  // The events the supervisor handed over reached the queue (no broker: none delivered).
  std::uint64_t queued_bytes = 0;
  for (const auto& e : fs::recursive_directory_iterator(dir / "mqtt")) {
    if (e.is_regular_file()) queued_bytes += e.file_size();
  }
  EXPECT_GT(queued_bytes, 0U);
  std::ifstream in(dir / "status" / "status.json");
  const std::string status((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(status.find(R"("handoff":0,)"), std::string::npos) << status;
}

// Runs the daemon of dir/ptdad.toml (simulator backends, fast pace) past one pass of the scenario, then
// counts the heap allocations of every thread over two more passes and a status write.
struct SteadyRun {
  bool started = false;  // the first pass was reached
  std::uint64_t allocations = 0;
  DaemonView before;
  DaemonView after;
};
SteadyRun run_steady_state(const fs::path& dir) {
  SteadyRun r;
  drivers::MonotonicClock clock;
  DaemonOptions opt;
  opt.config_file = dir / "ptdad.toml";
  opt.config_dir = fs::path();
  auto daemon = std::make_unique<Daemon>(opt, clock);
  Daemon& d = *daemon;
  d.configure();
  d.activate();
  std::thread runner([&] { EXPECT_EQ(d.run(), 0); });
  const std::uint64_t pass = 1'626'483;  // samples of one pass of the scenario (as above)
  r.started = wait_for([&] { return d.view().pipeline.samples > pass + 200'000; }, std::chrono::seconds(60));
  if (r.started) {
    r.before = d.view();
    {
      ptda::test::AllocScope scope;
      wait_for(
          [&] {
            const DaemonView v = d.view();
            return v.pipeline.samples > r.before.pipeline.samples + 2 * pass &&
                   v.status_writes > r.before.status_writes + 1;
          },
          std::chrono::seconds(120));
      r.allocations = scope.count();
    }
    r.after = d.view();
  }
  d.request_stop();
  runner.join();
  daemon.reset();
  return r;
}

// The band CUSUM on (session 12): its per-class, per-band state is sized at configure, the band energies
// come from the analyzer's residual, and the history log writes the band evidence, all without a heap
// allocation on the real-time threads or the supervisor.
TEST(DaemonAlloc, BandCusumSteadyStateMakesNoAllocations) {
  block_daemon_signals();
  const fs::path dir = scratch("alloc_band");
  write_sim_baseline(dir / "baseline.bin", true);
  write_text(
      dir / "ptdad.toml",
      sim_config(dir / "baseline.bin", dir / "status", "fast",
                 "metrics_path = \"" + (dir / "metrics" / "ptda.prom").string() + "\"\njoint = \"j4\"\n",
                 "[alarm]\nmin_hold_s = 0.5\nlatch = false\n[history]\ndir = \"" +
                     (dir / "history").string() + "\"\nmax_file_mib = 0.05\nfiles = 3\n",
                 true));
  const SteadyRun run = run_steady_state(dir);
  ASSERT_TRUE(run.started);
  const std::uint64_t allocations = run.allocations;
  const DaemonView& before = run.before;
  const DaemonView& after = run.after;
  EXPECT_EQ(allocations, 0U);
  EXPECT_GE(after.pipeline.scored - before.pipeline.scored, 190U);
  EXPECT_TRUE(after.pipeline.last_window.band_on);  // the band CUSUM ran
  // The history's window lines carry the band evidence.
  std::ifstream in(dir / "history" / "history.jsonl");
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("\"band_cusum_max\":"), std::string::npos);
}

// The mesh detector on (session 19): its demodulators and CUSUM state are sized at configure, the
// features come from the analyzer's spectrum, and the history log writes the mesh evidence, all without
// a heap allocation. Arc welding's plateau holds enough input-shaft revolutions for every window.
TEST(DaemonAlloc, MeshCusumSteadyStateMakesNoAllocations) {
  block_daemon_signals();
  const fs::path dir = scratch("alloc_mesh");
  write_sim_baseline(dir / "baseline.bin", false, true);
  write_text(dir / "ptdad.toml",
             sim_config(dir / "baseline.bin", dir / "status", "fast", "joint = \"j4\"\n",
                        "[alarm]\nmin_hold_s = 0.5\nlatch = false\n[history]\ndir = \"" +
                            (dir / "history").string() + "\"\nmax_file_mib = 0.05\nfiles = 3\n",
                        false, true));
  const SteadyRun run = run_steady_state(dir);
  ASSERT_TRUE(run.started);
  const std::uint64_t allocations = run.allocations;
  const DaemonView& before = run.before;
  const DaemonView& after = run.after;
  EXPECT_EQ(allocations, 0U);
  EXPECT_GE(after.pipeline.scored - before.pipeline.scored, 190U);
  EXPECT_TRUE(after.pipeline.last_window.mesh_on);  // the mesh CUSUM ran
  std::ifstream in(dir / "history" / "history.jsonl");
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("\"mesh_cusum_max\":"), std::string::npos);
  // The 4.1 rad/s class (2.76 input-shaft revolutions per window) had a pm to judge; the slow classes
  // (0.34 and 0.67 revolutions) have none (null).
  std::size_t judged = 0;
  std::size_t none = 0;
  for (std::size_t at = text.find("\"mesh_pm\":"); at != std::string::npos;
       at = text.find("\"mesh_pm\":", at + 1))
    (text.compare(at + 10, 4, "null") == 0 ? none : judged) += 1;
  EXPECT_GT(judged, 0U);
  EXPECT_GT(none, 0U);
}

// ---- order domain (issue 16) ----------------------------------------------------------------------

/// The simulator backends on the joint-rotation job at fast pace, looping, order domain; the simulator's
/// 0.5 ms CAN transport delay corrected as in order_domain_test.cpp.
std::string order_sim_config(const fs::path& dir, const std::string& extra) {
  return "[daemon]\nbaseline = \"" + (dir / "baseline.bin").string() + "\"\nstatus_dir = \"" +
         (dir / "status").string() + "\"\nstatus_period_s = 0.05\nmetrics_path = \"" +
         (dir / "metrics" / "ptda.prom").string() +
         "\"\njoint = \"j4\"\n\n[adc]\nbackend = \"sim\"\nscenario = \"" + joint_scenario().string() +
         "\"\nseed = 101\npace = \"fast\"\n\n[can]\nbackend = \"sim\"\npace = \"fast\"\n" +
         "speed_latency_s = 0.0005\n\n" + extra + "\n" + order_pipeline();
}

// The order domain's run state (FrameClock, AngleResampler, OrderWindowCutter, MonitorEngine::
// judge_window on the processing thread) makes no heap allocation either: everything is sized in
// configure(). The loop seam of the simulator (the joint angle jumps back) breaks the resampler's
// segment, as a real restart of the job would.
TEST(DaemonAlloc, OrderDomainSteadyStateMakesNoAllocations) {
  block_daemon_signals();
  const fs::path dir = scratch("alloc_order");
  const std::string text =
      order_sim_config(dir,
                       "[alarm]\nmin_hold_s = 0.5\nlatch = false\n[alarm.can]\nenabled = true\n"
                       "period_s = 0.05\n[history]\ndir = \"" +
                           (dir / "history").string() + "\"\nmax_file_mib = 0.05\nfiles = 3\n");
  write_text(dir / "ptdad.toml", text);
  write_sim_order_baseline(dir / "baseline.bin", text);
  const std::uint64_t pass = make_sim_recording(joint_scenario(), 101)->samples.size();

  drivers::MonotonicClock clock;
  DaemonOptions opt;
  opt.config_file = dir / "ptdad.toml";
  opt.config_dir = fs::path();
  auto daemon = std::make_unique<Daemon>(opt, clock);
  Daemon& d = *daemon;
  d.configure();
  d.activate();
  std::thread runner([&] { EXPECT_EQ(d.run(), 0); });

  // Warm-up: a full pass (the loop seam included) and a few windows.
  ASSERT_TRUE(
      wait_for([&] { return d.view().pipeline.samples > pass + 200'000; }, std::chrono::seconds(120)));
  const DaemonView before = d.view();
  std::uint64_t allocations = 0;
  const auto t_start = std::chrono::steady_clock::now();
  {
    ptda::test::AllocScope scope;
    wait_for(
        [&] {
          const DaemonView v = d.view();
          return v.pipeline.samples > before.pipeline.samples + 2 * pass &&
                 v.status_writes > before.status_writes + 1;
        },
        std::chrono::seconds(240));
    allocations = scope.count();
  }
  const DaemonView after = d.view();
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  std::printf(
      "order steady state: %.1f s of data (%llu windows, %llu scored) in %.2f s wall, %llu allocations\n",
      static_cast<double>(after.pipeline.samples - before.pipeline.samples) / 25600.0,
      static_cast<unsigned long long>(after.pipeline.windows - before.pipeline.windows),
      static_cast<unsigned long long>(after.pipeline.scored - before.pipeline.scored), wall_s,
      static_cast<unsigned long long>(allocations));
  d.request_stop();
  runner.join();
  daemon.reset();

  EXPECT_EQ(allocations, 0U);
  EXPECT_TRUE(after.pipeline.order_domain);
  EXPECT_GT(after.pipeline.samples, before.pipeline.samples + 2 * pass);
  EXPECT_GE(after.pipeline.scored - before.pipeline.scored, 2U * 90U);
  EXPECT_GT(after.status_writes, before.status_writes);
  EXPECT_EQ(after.counters.acq_ring_full_blocks, 0U);
  EXPECT_EQ(after.pipeline.resampler.outputs_dropped, 0U);
  EXPECT_EQ(after.pipeline.resampler.samples_overrun, 0U);
  EXPECT_TRUE(fs::exists(dir / "history" / "history.1.jsonl"));
}

}  // namespace
}  // namespace ptda::daemon::test
