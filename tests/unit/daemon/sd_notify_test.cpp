#include "rt/sd_notify.hpp"

#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cstddef>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>

#include "alloc_counter.hpp"
#include "ptda/common/error.hpp"

namespace fs = std::filesystem;

namespace ptda::daemon {
namespace {

/// A service manager stand-in: a bound AF_UNIX datagram socket (path or abstract name).
class FakeManager {
 public:
  explicit FakeManager(const std::string& address) {
    fd_ = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_un a{};
    a.sun_family = AF_UNIX;
    std::string raw = address;
    if (raw[0] == '@') raw[0] = '\0';
    std::memcpy(a.sun_path, raw.data(), raw.size());
    const auto len = static_cast<socklen_t>(offsetof(sockaddr_un, sun_path) + raw.size());
    ok_ = fd_ >= 0 && ::bind(fd_, reinterpret_cast<const sockaddr*>(&a), len) == 0;
  }
  ~FakeManager() {
    if (fd_ >= 0) ::close(fd_);
  }
  [[nodiscard]] bool ok() const { return ok_; }
  /// Next datagram, or "<none>" when nothing is queued.
  std::string next() {
    char buf[4096];
    const ssize_t n = ::recv(fd_, buf, sizeof buf, MSG_DONTWAIT);
    return n < 0 ? std::string("<none>") : std::string(buf, static_cast<std::size_t>(n));
  }

 private:
  int fd_ = -1;
  bool ok_ = false;
};

fs::path temp_dir() {
  const char* base = std::getenv("PTDA_TEST_TMP");
  const fs::path root = base != nullptr ? fs::path(base) : fs::temp_directory_path();
  const fs::path d = root / ("sdnotify_" + std::to_string(::getpid()));
  fs::create_directories(d);
  return d;
}

TEST(SdNotify, PathSocketReceivesEachStateAsOneDatagram) {
  const fs::path dir = temp_dir();
  const std::string path = (dir / "notify.sock").string();
  fs::remove(path);
  FakeManager mgr(path);
  ASSERT_TRUE(mgr.ok());
  SdNotifier n(path);
  ASSERT_TRUE(n.enabled());
  EXPECT_TRUE(n.ready());
  EXPECT_TRUE(n.status("monitoring: 12 windows, 0 alarms"));
  EXPECT_TRUE(n.watchdog());
  EXPECT_TRUE(n.notify("READY=1\nSTATUS=both"));
  EXPECT_TRUE(n.stopping());
  EXPECT_EQ(mgr.next(), "READY=1");
  EXPECT_EQ(mgr.next(), "STATUS=monitoring: 12 windows, 0 alarms");
  EXPECT_EQ(mgr.next(), "WATCHDOG=1");
  EXPECT_EQ(mgr.next(), "READY=1\nSTATUS=both");
  EXPECT_EQ(mgr.next(), "STOPPING=1");
  EXPECT_EQ(mgr.next(), "<none>");
  EXPECT_EQ(n.sent(), 5u);
  EXPECT_EQ(n.send_errors(), 0u);
  fs::remove_all(dir);
}

TEST(SdNotify, AbstractNamespaceSocketFromTheEnvironment) {
  const std::string name = "@ptda-sd-notify-test-" + std::to_string(::getpid());
  FakeManager mgr(name);
  ASSERT_TRUE(mgr.ok());
  ASSERT_EQ(::setenv("NOTIFY_SOCKET", name.c_str(), 1), 0);
  SdNotifier n = SdNotifier::from_environment();
  ::unsetenv("NOTIFY_SOCKET");
  ASSERT_TRUE(n.enabled());
  EXPECT_TRUE(n.ready());
  EXPECT_TRUE(n.watchdog());
  EXPECT_EQ(mgr.next(), "READY=1");
  EXPECT_EQ(mgr.next(), "WATCHDOG=1");
}

TEST(SdNotify, WithoutNotifySocketEverythingIsANoOp) {
  ::unsetenv("NOTIFY_SOCKET");
  SdNotifier n = SdNotifier::from_environment();
  EXPECT_FALSE(n.enabled());
  EXPECT_TRUE(n.ready());
  EXPECT_TRUE(n.status("x"));
  EXPECT_EQ(n.sent(), 0u);
}

TEST(SdNotify, UnreachableManagerIsCountedNotFatal) {
  SdNotifier n("/nonexistent-dir/notify.sock");
  EXPECT_FALSE(n.ready());
  EXPECT_FALSE(n.watchdog());
  EXPECT_EQ(n.send_errors(), 2u);
}

TEST(SdNotify, BadAddressesAreRejected) {
  EXPECT_THROW(SdNotifier("run/notify"), Error);
  EXPECT_THROW(SdNotifier("@"), Error);
  EXPECT_THROW(SdNotifier("/" + std::string(200, 'x')), Error);
  EXPECT_THROW(SdNotifier("vsock:2:1234"), Error);
}

TEST(SdNotify, SendingNeverAllocates) {
  const std::string name = "@ptda-sd-notify-alloc-" + std::to_string(::getpid());
  FakeManager mgr(name);
  ASSERT_TRUE(mgr.ok());
  SdNotifier n(name);
  test::AllocScope scope;
  for (int i = 0; i < 10; ++i) {
    (void)n.watchdog();
    (void)n.status("steady");
    (void)mgr.next();  // drain: the receive queue of a datagram socket is short (max_dgram_qlen)
    (void)mgr.next();
  }
  EXPECT_EQ(scope.count(), 0u);
  EXPECT_EQ(n.sent(), 20u);
}

TEST(SdNotify, AFullManagerQueueIsCountedInsteadOfBlocking) {
  const std::string name = "@ptda-sd-notify-full-" + std::to_string(::getpid());
  FakeManager mgr(name);  // never read until the end
  ASSERT_TRUE(mgr.ok());
  SdNotifier n(name);
  int ok = 0;
  for (int i = 0; i < 1000; ++i) ok += n.watchdog() ? 1 : 0;
  EXPECT_EQ(n.sent(), static_cast<std::uint64_t>(ok));
  EXPECT_EQ(n.sent() + n.send_errors(), 1000u);
  EXPECT_GE(n.send_errors(), 1u);  // the queue holds max_dgram_qlen (10 by default) datagrams
  EXPECT_EQ(mgr.next(), "WATCHDOG=1");
}

TEST(WatchdogSettings, ParsedLikeSdWatchdogEnabled) {
  const WatchdogSettings w = parse_watchdog_settings("5000000", nullptr, 42);
  EXPECT_TRUE(w.enabled);
  EXPECT_EQ(w.timeout_ns, 5'000'000'000);
  EXPECT_EQ(w.ping_period_ns, 2'500'000'000);
  EXPECT_TRUE(parse_watchdog_settings("3000000", "42", 42).enabled);
  EXPECT_FALSE(parse_watchdog_settings("3000000", "43", 42).enabled);  // meant for another process
  EXPECT_FALSE(parse_watchdog_settings(nullptr, "42", 42).enabled);
  EXPECT_FALSE(parse_watchdog_settings(nullptr, nullptr, 42).enabled);
  for (const char* bad : {"", "abc", "0", "-5", "5s", " 5", "99999999999999999999"}) {
    EXPECT_THROW((void)parse_watchdog_settings(bad, nullptr, 42), Error) << "'" << bad << "'";
  }
  EXPECT_THROW((void)parse_watchdog_settings("1000", "x", 42), Error);
  try {
    (void)parse_watchdog_settings("5s", nullptr, 1);
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("WATCHDOG_USEC"), std::string::npos) << e.what();
  }
}

TEST(WatchdogSettings, FromTheEnvironment) {
  ASSERT_EQ(::setenv("WATCHDOG_USEC", "2000000", 1), 0);
  ASSERT_EQ(::setenv("WATCHDOG_PID", std::to_string(::getpid()).c_str(), 1), 0);
  const WatchdogSettings w = watchdog_settings_from_environment();
  ::unsetenv("WATCHDOG_USEC");
  ::unsetenv("WATCHDOG_PID");
  EXPECT_TRUE(w.enabled);
  EXPECT_EQ(w.ping_period_ns, 1'000'000'000);
  EXPECT_FALSE(watchdog_settings_from_environment().enabled);
}

}  // namespace
}  // namespace ptda::daemon
