// At real-time pace the daemon reads its sources in bursts (docs/daemon.md, "Bursts"): the acquisition
// and CAN threads wake once per burst period (kBurstPeriodNs) and the processing thread once per CAN
// burst, instead of once per 256-sample block (100/s), per CAN frame (250/s) and per 5 ms idle check.
// Every sample and frame still arrives, and the run state makes no allocation.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <thread>

#include "alloc_counter.hpp"
#include "daemon_test_support.hpp"

namespace ptda::daemon::test {
namespace {

struct Rates {
  double acquisition = 0, can = 0, processing = 0, samples = 0, speeds = 0;
};

Rates rates(const DaemonView& a, const DaemonView& b, double wall_s) {
  return {static_cast<double>(b.heartbeats.acquisition - a.heartbeats.acquisition) / wall_s,
          static_cast<double>(b.heartbeats.can - a.heartbeats.can) / wall_s,
          static_cast<double>(b.heartbeats.processing - a.heartbeats.processing) / wall_s,
          static_cast<double>(b.pipeline.samples - a.pipeline.samples) / wall_s,
          static_cast<double>(b.pipeline.speeds - a.pipeline.speeds) / wall_s};
}

TEST(DaemonBurst, RealTimeStagesWakeOncePerBurstAndAllocateNothing) {
  block_daemon_signals();
  const fs::path dir = scratch("burst");
  write_sim_baseline(dir / "baseline.bin");
  // The simulator at real-time pace (25.6 kHz, 256-sample blocks, a speed frame every 4 ms).
  write_text(
      dir / "ptdad.toml",
      sim_config(dir / "baseline.bin", dir / "status", "realtime", "",
                 "[alarm]\nmin_hold_s = 0.5\nlatch = false\n[alarm.can]\nenabled = true\nperiod_s = 0.1\n"));
  drivers::MonotonicClock clock;
  DaemonOptions opt;
  opt.config_file = dir / "ptdad.toml";
  opt.config_dir = fs::path();
  Daemon d(opt, clock);
  d.configure();
  d.activate();
  std::thread runner([&] { EXPECT_EQ(d.run(), 0); });

  // Warm-up: data flows and the first window was judged (every path of the run state was taken once).
  ASSERT_TRUE(wait_for([&] { return d.view().pipeline.scored > 0; }, std::chrono::seconds(60)));
  const DaemonView before = d.view();
  const auto t0 = std::chrono::steady_clock::now();
  std::uint64_t allocations = 0;
  {
    ptda::test::AllocScope scope;
    std::this_thread::sleep_for(std::chrono::seconds(3));
    allocations = scope.count();
  }
  const DaemonView after = d.view();
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  d.request_stop();
  runner.join();

  const Rates r = rates(before, after, wall_s);
  std::printf(
      "wake-ups per second: acquisition %.1f, can %.1f, processing %.1f; %.0f samples/s, %.0f speeds/s\n",
      r.acquisition, r.can, r.processing, r.samples, r.speeds);
  const double bursts_per_s = 1e9 / static_cast<double>(kBurstPeriodNs);  // 50
  // Per burst: one wait each. (Without bursts: 100 blocks/s, ~250 frames/s, processing > 300/s.)
  EXPECT_LE(r.acquisition, 1.2 * bursts_per_s);
  EXPECT_LE(r.can, 1.2 * bursts_per_s);
  // Processing: woken by each CAN burst, one pass with work and one that finds none.
  EXPECT_LE(r.processing, 2.4 * bursts_per_s);
  // Nothing is lost: the samples keep up with the clock (25.6 kHz; a loaded machine delays, not drops).
  EXPECT_GT(r.samples, 0.8 * 25600.0);
  EXPECT_GT(r.speeds, 0.8 * 250.0);
  EXPECT_EQ(after.counters.acq_ring_full_blocks, 0U);
  EXPECT_EQ(after.counters.can_ring_full, 0U);
  EXPECT_EQ(after.pipeline.gap_samples, 0U);
  EXPECT_EQ(allocations, 0U);
}

}  // namespace
}  // namespace ptda::daemon::test
