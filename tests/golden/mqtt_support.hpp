// A real Mosquitto broker for the golden tests (ctest label `mqtt`): a free local port, the broker
// process with its own configuration, and fork/exec helpers (tests/golden/mqtt_broker_test.cpp,
// tests/golden/fleet_cli_test.cpp). Test code only.
#pragma once

#include <arpa/inet.h>
#include <fcntl.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <functional>
#include <string>
#include <thread>
#include <vector>

#include "golden_support.hpp"

namespace ptda::golden {

using namespace std::chrono_literals;

inline int free_port() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = 0;
  socklen_t len = sizeof a;
  if (::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 ||
      ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len) != 0) {
    ::close(fd);
    return -1;
  }
  ::close(fd);
  return ntohs(a.sin_port);
}

inline bool port_open(int port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = htons(static_cast<std::uint16_t>(port));
  const bool ok = ::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
  ::close(fd);
  return ok;
}

inline bool wait_until(const std::function<bool()>& pred, std::chrono::milliseconds timeout) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < end) {
    if (pred()) return true;
    std::this_thread::sleep_for(50ms);
  }
  return pred();
}

/// fork/exec with stdout and stderr appended to files. Returns the child's pid.
inline pid_t spawn(const std::vector<std::string>& argv, const fs::path& out, const fs::path& err) {
  const pid_t pid = ::fork();
  if (pid == 0) {
    const int o = ::open(out.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
    const int e = ::open(err.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
    const int n = ::open("/dev/null", O_RDONLY);
    ::dup2(n, 0);
    ::dup2(o, 1);
    ::dup2(e, 2);
    std::vector<char*> args;
    for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    ::execvp(args[0], args.data());
    ::_exit(127);
  }
  return pid;
}

inline int stop(pid_t& pid, int sig) {
  if (pid <= 0) return -1;
  ::kill(pid, sig);
  int status = 0;
  ::waitpid(pid, &status, 0);
  pid = -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : -WTERMSIG(status);
}

/// Kills (SIGKILL) and reaps the children still running when a test ends early (a failed ASSERT):
/// a daemon left behind would write into the next run's scratch directory.
struct Reaper {
  std::vector<pid_t*> pids;
  ~Reaper() {
    for (pid_t* p : pids) stop(*p, SIGKILL);
  }
};

class Broker {
 public:
  Broker(fs::path dir, int port, const std::string& extra) : dir_(std::move(dir)), port_(port) {
    fs::create_directories(dir_ / "db");
    std::ofstream conf(dir_ / "mosquitto.conf");
    conf << "listener " << port_ << " 127.0.0.1\npersistence true\npersistence_location "
         << (dir_ / "db").string() << "/\nlog_dest file " << (dir_ / "mosquitto.log").string() << "\n"
         << (::geteuid() == 0 ? "user root\n" : "") << extra;
  }
  ~Broker() { stop(pid_, SIGTERM); }
  void start() {
    pid_ = spawn({"mosquitto", "-c", (dir_ / "mosquitto.conf").string()}, dir_ / "broker.out",
                 dir_ / "broker.err");
    ASSERT_TRUE(wait_until([&] { return port_open(port_); }, 5s)) << read_file(dir_ / "broker.err");
  }
  void halt() { stop(pid_, SIGTERM); }

 private:
  fs::path dir_;
  int port_;
  pid_t pid_ = -1;
};

}  // namespace ptda::golden
