#include "rt/sd_notify.hpp"

#include <sys/socket.h>
#include <sys/uio.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cstddef>
#include <cstdlib>
#include <cstring>
#include <utility>

#include "ptda/common/error.hpp"

namespace ptda::daemon {
namespace {

/// Strict decimal parse of a positive integer (no sign, no spaces, no trailing junk).
bool parse_positive(const char* text, std::uint64_t& out) {
  const std::string_view s(text);
  if (s.empty()) return false;
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
  return ec == std::errc() && ptr == s.data() + s.size() && out > 0;
}

}  // namespace

WatchdogSettings parse_watchdog_settings(const char* watchdog_usec, const char* watchdog_pid,
                                         pid_t self_pid) {
  WatchdogSettings w;
  if (watchdog_usec == nullptr) return w;
  std::uint64_t usec = 0;
  if (!parse_positive(watchdog_usec, usec)) {
    throw Error("WATCHDOG_USEC", 0, 0, std::string("not a positive integer: '") + watchdog_usec + "'");
  }
  // ns must fit in int64: 9.2e12 s is far beyond any WatchdogSec, but a garbage value must not overflow.
  if (usec > static_cast<std::uint64_t>(INT64_MAX / 1000)) {
    throw Error("WATCHDOG_USEC", 0, 0, std::string("out of range: '") + watchdog_usec + "'");
  }
  if (watchdog_pid != nullptr) {
    std::uint64_t pid = 0;
    if (!parse_positive(watchdog_pid, pid)) {
      throw Error("WATCHDOG_PID", 0, 0, std::string("not a positive integer: '") + watchdog_pid + "'");
    }
    if (pid != static_cast<std::uint64_t>(self_pid)) return w;  // meant for another process
  }
  w.enabled = true;
  w.timeout_ns = static_cast<std::int64_t>(usec) * 1000;
  w.ping_period_ns = w.timeout_ns / 2;
  return w;
}

WatchdogSettings watchdog_settings_from_environment() {
  return parse_watchdog_settings(std::getenv("WATCHDOG_USEC"), std::getenv("WATCHDOG_PID"), ::getpid());
}

SdNotifier::SdNotifier(std::string_view notify_socket) {
  if (notify_socket.empty()) return;
  if (notify_socket[0] != '/' && notify_socket[0] != '@') {
    throw Error("NOTIFY_SOCKET", 0, 0,
                "'" + std::string(notify_socket) + "' is neither an absolute path nor an '@' abstract name");
  }
  if (notify_socket.size() < 2) throw Error("NOTIFY_SOCKET", 0, 0, "empty socket name");
  if (notify_socket.size() > sizeof(sockaddr_un::sun_path)) {
    throw Error("NOTIFY_SOCKET", 0, 0,
                "'" + std::string(notify_socket) + "' is longer than " +
                    std::to_string(sizeof(sockaddr_un::sun_path)) + " bytes");
  }
  address_.assign(notify_socket);
  if (address_[0] == '@') address_[0] = '\0';
  fd_ = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd_ < 0) {
    throw Error("NOTIFY_SOCKET", 0, 0, std::string("socket(AF_UNIX, SOCK_DGRAM): ") + std::strerror(errno));
  }
}

SdNotifier SdNotifier::from_environment() {
  const char* s = std::getenv("NOTIFY_SOCKET");
  return SdNotifier(s == nullptr ? std::string_view() : std::string_view(s));
}

SdNotifier::~SdNotifier() {
  if (fd_ >= 0) ::close(fd_);
}

SdNotifier::SdNotifier(SdNotifier&& other) noexcept
    : fd_(std::exchange(other.fd_, -1)),
      address_(std::move(other.address_)),
      send_errors_(other.send_errors_.load(std::memory_order_relaxed)),
      sent_(other.sent_.load(std::memory_order_relaxed)) {}

SdNotifier& SdNotifier::operator=(SdNotifier&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = std::exchange(other.fd_, -1);
    address_ = std::move(other.address_);
    send_errors_.store(other.send_errors_.load(std::memory_order_relaxed), std::memory_order_relaxed);
    sent_.store(other.sent_.load(std::memory_order_relaxed), std::memory_order_relaxed);
  }
  return *this;
}

bool SdNotifier::notify(std::string_view state) noexcept {
  return notify_pair(state, {});
}

bool SdNotifier::notify_pair(std::string_view key, std::string_view value) noexcept {
  if (fd_ < 0) return true;
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::memcpy(addr.sun_path, address_.data(), address_.size());
  // Abstract names are exactly address_.size() bytes long (no terminator); paths may omit it too.
  const auto addr_len = static_cast<socklen_t>(offsetof(sockaddr_un, sun_path) + address_.size());

  iovec iov[2];
  iov[0].iov_base = const_cast<char*>(key.data());  // sendmsg does not write through it
  iov[0].iov_len = key.size();
  iov[1].iov_base = const_cast<char*>(value.data());
  iov[1].iov_len = value.size();
  msghdr msg{};
  msg.msg_name = &addr;
  msg.msg_namelen = addr_len;
  msg.msg_iov = iov;
  msg.msg_iovlen = value.empty() ? 1 : 2;

  const std::size_t total = key.size() + value.size();
  ssize_t n = -1;
  do {
    n = ::sendmsg(fd_, &msg, MSG_NOSIGNAL | MSG_DONTWAIT);
  } while (n < 0 && errno == EINTR);
  if (n != static_cast<ssize_t>(total)) {
    send_errors_.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  sent_.fetch_add(1, std::memory_order_relaxed);
  return true;
}

}  // namespace ptda::daemon
