// ptdad under a fake service manager: a bound AF_UNIX datagram socket as $NOTIFY_SOCKET with the
// watchdog on. It must see READY=1, STATUS=..., WATCHDOG=1 pings while every stage makes progress,
// no ping once the processing thread stalls (test-only fault injection), and STOPPING=1.
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include "daemon_test_support.hpp"
#include "fake_service_manager.hpp"

namespace ptda::daemon::test {
namespace {

using namespace std::chrono_literals;

TEST(DaemonNotify, ReadyStatusWatchdogOnlyWhileProgressingAndStopping) {
  block_daemon_signals();
  const fs::path dir = scratch("notify");
  write_sim_baseline(dir / "baseline.bin");
  write_text(dir / "ptdad.toml", sim_config(dir / "baseline.bin", dir / "status", "realtime"));
  FakeManager manager(dir / "notify.sock");
  ASSERT_TRUE(manager.bound());

  drivers::MonotonicClock clock;
  DaemonOptions opt;
  opt.config_file = dir / "ptdad.toml";
  opt.config_dir = fs::path();
  opt.notify_socket = (dir / "notify.sock").string();
  opt.watchdog =
      parse_watchdog_settings("200000", nullptr, ::getpid());  // WatchdogSec=0.2s: ping every 0.1 s
  ASSERT_TRUE(opt.watchdog.enabled);
  ASSERT_EQ(opt.watchdog.ping_period_ns, 100'000'000);
  Daemon d(opt, clock);
  d.configure();
  d.activate();
  std::thread runner([&] { EXPECT_EQ(d.run(), 0); });

  ASSERT_TRUE(wait_for([&] { return manager.count("WATCHDOG=1") >= 4; }));
  ASSERT_TRUE(wait_for([&] { return manager.count("STATUS=") >= 2; }));
  {
    const auto msgs = manager.messages();
    ASSERT_FALSE(msgs.empty());
    EXPECT_EQ(msgs.front(), "READY=1");  // nothing before READY
    bool monitoring = false;
    for (const auto& m : msgs) monitoring = monitoring || m.find("STATUS=running (monitoring)") == 0;
    EXPECT_TRUE(monitoring);
  }
  EXPECT_EQ(d.view().watchdog_skipped, 0U);

  // Stall the processing thread: the supervisor withholds the pings (systemd would then kill and
  // restart the service). With both inputs at real-time pace that thread also reads them (docs/daemon.md,
  // "One thread at real-time pace"): the acquisition and CAN heartbeats stop with it.
  ASSERT_TRUE(d.view().wake.single_thread);
  d.set_processing_stall(true);
  ASSERT_TRUE(wait_for([&] { return d.view().watchdog_skipped >= 1; }));
  const std::size_t pings_at_stall = manager.count("WATCHDOG=1");
  const std::uint64_t can_beats = d.view().heartbeats.can;
  ASSERT_TRUE(wait_for([&] { return d.view().watchdog_skipped >= 5; }));
  EXPECT_EQ(manager.count("WATCHDOG=1"), pings_at_stall);
  EXPECT_EQ(d.view().heartbeats.can, can_beats);
  ASSERT_TRUE(
      wait_for([&] { return d.view().reason.view().find("stage processing made no progress") == 0; }));

  // Progress again: pings resume.
  d.set_processing_stall(false);
  ASSERT_TRUE(wait_for([&] { return manager.count("WATCHDOG=1") >= pings_at_stall + 2; }));

  d.request_stop();
  runner.join();
  ASSERT_TRUE(wait_for([&] { return manager.count("STOPPING=1") == 1; }));
  EXPECT_EQ(manager.messages().back(), "STOPPING=1");
}

}  // namespace
}  // namespace ptda::daemon::test
