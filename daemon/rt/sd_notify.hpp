// Minimal client of systemd's service notification protocol (sd_notify(3)): datagrams of
// newline-separated "KEY=value" assignments sent to the AF_UNIX socket named by $NOTIFY_SOCKET
// (a path, or "@name" for the abstract namespace). Written here instead of linking libsystemd so the
// daemon has no extra runtime dependency and so sending never allocates.
#pragma once

#include <sys/types.h>

#include <atomic>
#include <cstdint>
#include <string>
#include <string_view>

namespace ptda::daemon {

/// The service manager's watchdog settings ($WATCHDOG_USEC, $WATCHDOG_PID), as sd_watchdog_enabled(3).
struct WatchdogSettings {
  bool enabled = false;
  std::int64_t timeout_ns = 0;      ///< WatchdogSec= as passed in WATCHDOG_USEC
  std::int64_t ping_period_ns = 0;  ///< timeout / 2, the period sd_watchdog_enabled(3) recommends
};

/// Parses the two variables (nullptr = unset). Disabled when WATCHDOG_USEC is unset, or when
/// WATCHDOG_PID is set and names another process (the watchdog is meant for the main PID only).
/// Throws ptda::Error naming the variable when a value is set but is not a positive decimal integer
/// (sd_watchdog_enabled returns -EINVAL there; a unit file typo must not silently disable the watchdog).
/// Thread: any, at start-up. Allocates only to build the error message.
[[nodiscard]] WatchdogSettings parse_watchdog_settings(const char* watchdog_usec, const char* watchdog_pid,
                                                       pid_t self_pid);

/// parse_watchdog_settings(getenv("WATCHDOG_USEC"), getenv("WATCHDOG_PID"), getpid()).
/// Thread: the main thread at start-up (getenv is not safe against concurrent setenv). Throws ptda::Error.
[[nodiscard]] WatchdogSettings watchdog_settings_from_environment();

/// One open datagram socket towards the service manager. When no socket is configured the notifier is
/// disabled and every send is a successful no-op, so the daemon runs the same outside systemd.
class SdNotifier {
 public:
  /// Disabled notifier. Thread: any. Never allocates.
  SdNotifier() noexcept = default;
  /// Opens a socket for `notify_socket` ("/run/systemd/notify", "@abstract/name"; "" = disabled).
  /// Throws ptda::Error for an address that is neither absolute nor abstract, too long for sockaddr_un,
  /// or when socket() fails. Thread: the main thread at start-up.
  explicit SdNotifier(std::string_view notify_socket);
  /// SdNotifier(getenv("NOTIFY_SOCKET") or ""). Thread: the main thread at start-up. Throws ptda::Error.
  [[nodiscard]] static SdNotifier from_environment();

  ~SdNotifier();
  SdNotifier(SdNotifier&& other) noexcept;
  SdNotifier& operator=(SdNotifier&& other) noexcept;
  SdNotifier(const SdNotifier&) = delete;
  SdNotifier& operator=(const SdNotifier&) = delete;

  [[nodiscard]] bool enabled() const noexcept { return fd_ >= 0; }

  /// Sends `state` as one datagram (e.g. "READY=1\nSTATUS=running"). Returns false and counts a send
  /// error when the datagram could not be sent (true when disabled). Thread: any one thread at a time
  /// (the supervisor). Never allocates; never blocks (MSG_DONTWAIT: a full socket queue is an error).
  bool notify(std::string_view state) noexcept;
  /// Sends "<key><value>" (e.g. key "STATUS=") from two pieces without copying them together.
  /// Same contract as notify().
  bool notify_pair(std::string_view key, std::string_view value) noexcept;

  bool ready() noexcept { return notify("READY=1"); }
  bool stopping() noexcept { return notify("STOPPING=1"); }
  bool reloading() noexcept { return notify("RELOADING=1"); }
  bool watchdog() noexcept { return notify("WATCHDOG=1"); }
  bool status(std::string_view text) noexcept { return notify_pair("STATUS=", text); }

  /// Datagrams that failed to send since construction. Thread: any. Never allocates.
  [[nodiscard]] std::uint64_t send_errors() const noexcept {
    return send_errors_.load(std::memory_order_relaxed);
  }
  /// Datagrams sent since construction. Thread: any. Never allocates.
  [[nodiscard]] std::uint64_t sent() const noexcept { return sent_.load(std::memory_order_relaxed); }

 private:
  int fd_ = -1;
  std::string address_;  ///< sun_path bytes ('\0' first for the abstract namespace), no terminator
  std::atomic<std::uint64_t> send_errors_{0};
  std::atomic<std::uint64_t> sent_{0};
};

}  // namespace ptda::daemon
