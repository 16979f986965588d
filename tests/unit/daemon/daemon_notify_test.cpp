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

namespace ptda::daemon::test {
namespace {

using namespace std::chrono_literals;

/// The service manager's end: receives datagrams on a thread.
class FakeManager {
 public:
  explicit FakeManager(const fs::path& path) : path_(path) {
    fd_ = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    std::snprintf(addr.sun_path, sizeof addr.sun_path, "%s", path.c_str());
    ::unlink(path.c_str());
    bound_ = ::bind(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0;
    timeval tv{0, 20000};
    ::setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    thread_ = std::thread([this] {
      char buf[4096];
      while (!stop_.load()) {
        const ssize_t n = ::recv(fd_, buf, sizeof buf, 0);
        if (n > 0) {
          std::lock_guard lock(mutex_);
          messages_.emplace_back(buf, static_cast<std::size_t>(n));
        }
      }
    });
  }
  ~FakeManager() {
    stop_ = true;
    thread_.join();
    ::close(fd_);
  }
  [[nodiscard]] bool bound() const { return bound_; }
  std::vector<std::string> messages() {
    std::lock_guard lock(mutex_);
    return messages_;
  }
  std::size_t count(const std::string& prefix) {
    std::size_t n = 0;
    for (const auto& m : messages()) n += m.rfind(prefix, 0) == 0 ? 1 : 0;
    return n;
  }

 private:
  fs::path path_;
  int fd_ = -1;
  bool bound_ = false;
  std::atomic<bool> stop_{false};
  std::mutex mutex_;
  std::vector<std::string> messages_;
  std::thread thread_;
};

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
  // restart the service), while acquisition and CAN keep beating.
  d.set_processing_stall(true);
  ASSERT_TRUE(wait_for([&] { return d.view().watchdog_skipped >= 1; }));
  const std::size_t pings_at_stall = manager.count("WATCHDOG=1");
  const std::uint64_t can_beats = d.view().heartbeats.can;
  ASSERT_TRUE(wait_for([&] { return d.view().watchdog_skipped >= 5; }));
  EXPECT_EQ(manager.count("WATCHDOG=1"), pings_at_stall);
  EXPECT_GT(d.view().heartbeats.can, can_beats);
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
