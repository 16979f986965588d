// Input files must be regular files of bounded size (issue 14 item 3): a FIFO hung `configure`,
// /dev/zero exhausted memory. Every reader calls require_regular_file() (or read_regular_file())
// before reading. Configuration and baseline files must not be writable by others when running as
// root, and configuration strings must be usable as paths and names (item 8). Header-only like the
// rest of common/.
#pragma once

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

#include "ptda/common/error.hpp"

namespace ptda {

/// Size limits of the files read whole (generous: 100x the largest real file).
inline constexpr std::uint64_t kMaxConfigFileBytes = 16ULL << 20U;   ///< TOML: config, drop-in, scenario
inline constexpr std::uint64_t kMaxBaselineFileBytes = 1ULL << 30U;  ///< a baseline
inline constexpr std::uint64_t kNoSizeLimit = ~std::uint64_t{0};     ///< streamed files (WAV, CAN log)

/// Longest string value accepted from a configuration file (PATH_MAX): paths and names beyond it are
/// mistakes, and a 200 KB interface name once produced an 836 MB can.log.
inline constexpr std::size_t kMaxConfigStringBytes = 4096;
/// Longest network interface name (IFNAMSIZ 16 including the terminating NUL).
inline constexpr std::size_t kMaxInterfaceNameBytes = 15;

/// Why a string from a configuration cannot be used as a path or name, or "" when it can: a NUL byte
/// (TOML allows "\u0000"; every system call would cut the path there) or more than max_bytes.
/// Thread: any. Allocates only for a non-empty answer.
[[nodiscard]] inline std::string string_value_problem(std::string_view s,
                                                      std::size_t max_bytes = kMaxConfigStringBytes) {
  const std::size_t nul = s.find('\0');
  if (nul != std::string_view::npos)
    return "contains a NUL byte (\\u0000) at byte " + std::to_string(nul) + "; paths and names cannot";
  if (s.size() > max_bytes)
    return "is " + std::to_string(s.size()) + " bytes long, at most " + std::to_string(max_bytes) +
           " allowed";
  return {};
}

namespace detail {
inline std::string file_kind(mode_t mode) {
  if (S_ISDIR(mode)) return "a directory";
  if (S_ISFIFO(mode)) return "a FIFO";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISSOCK(mode)) return "a socket";
  return "a special file";
}

inline void check_stat(const std::string& name, const struct stat& st, std::uint64_t max_bytes,
                       std::string_view what) {
  if (!S_ISREG(st.st_mode))
    throw Error(name + ": is " + file_kind(st.st_mode) + ", not a " + std::string(what));
  const auto size = static_cast<std::uint64_t>(st.st_size);
  if (size > max_bytes)
    throw Error(name + ": " + std::string(what) + " is too large (" + std::to_string(size) +
                " bytes, at most " + std::to_string(max_bytes) + ")");
}
}  // namespace detail

/// Issue 14 item 8: when the process runs as root (euid 0), a configuration or baseline file that
/// group or other users may write lets them steer (or blind) a root daemon. Throws ptda::Error
/// "<name>: <what> is group- or world-writable (mode 0664) ... fix: chmod go-w <name>" when euid is 0
/// and st has S_IWGRP or S_IWOTH; otherwise returns. `euid` is a parameter so tests can pose as root
/// or not. Thread: any. Allocates only to throw.
inline void require_not_writable_by_others(const std::string& name, const struct stat& st,
                                           std::string_view what, uid_t euid) {
  if (euid != 0 || (st.st_mode & (S_IWGRP | S_IWOTH)) == 0) return;
  char mode[8];
  std::snprintf(mode, sizeof mode, "%04o", static_cast<unsigned>(st.st_mode & 07777U));
  const char* who = (st.st_mode & S_IWOTH) != 0 ? "world-writable" : "group-writable";
  throw Error(name + ": " + std::string(what) + " is " + who + " (mode " + mode +
              ") and ptda runs as root: another user could change what it does. Fix: chmod go-w " + name);
}

/// Issue 14 item 8, the directories: running as root, a file is only as safe as the directories that
/// hold it. Whoever may write a parent directory can rename the file away and put their own in its
/// place. Throws ptda::Error "<dir>: directory holding <name> is group- or world-writable (mode 0775)
/// ... Fix: chmod go-w <dir>" for the first such directory from the file's parent up to "/", both along
/// the path as given (made absolute) and along its canonical form (symlinks resolved). A sticky
/// directory (mode 1777, /tmp) is accepted: there only a file's owner may rename or remove it. Owners
/// are not checked. No check when euid is not 0. Thread: any (configure time). Allocates.
inline void require_parents_not_writable_by_others(const std::filesystem::path& path, std::string_view what,
                                                   uid_t euid) {
  if (euid != 0) return;
  const auto check_chain = [&](std::filesystem::path dir) {
    while (!dir.empty()) {
      struct stat st {};
      if (::stat(dir.c_str(), &st) == 0 && S_ISDIR(st.st_mode) && (st.st_mode & (S_IWGRP | S_IWOTH)) != 0 &&
          (st.st_mode & S_ISVTX) == 0) {
        char mode[8];
        std::snprintf(mode, sizeof mode, "%04o", static_cast<unsigned>(st.st_mode & 07777U));
        const char* who = (st.st_mode & S_IWOTH) != 0 ? "world-writable" : "group-writable";
        throw Error(dir.string() + ": directory holding the " + std::string(what) + " " + path.string() +
                    " is " + who + " (mode " + mode +
                    ") and ptda runs as root: another user could replace the file. Fix: chmod go-w " +
                    dir.string());
      }
      const std::filesystem::path up = dir.parent_path();
      if (up == dir) break;
      dir = up;
    }
  };
  std::error_code ec;
  const std::filesystem::path abs = std::filesystem::absolute(path, ec);
  if (!ec) check_chain(abs.lexically_normal().parent_path());
  const std::filesystem::path real = std::filesystem::canonical(path, ec);
  if (!ec) check_chain(real.parent_path());
}

/// Throws ptda::Error "<path>: ..." unless path (symlinks followed) is an existing regular file of at
/// most max_bytes. `what` names the file's role ("baseline", "configuration file"). Never opens the
/// file, so a FIFO cannot block it. Thread: any (configure time). Allocates only to throw.
inline void require_regular_file(const std::filesystem::path& path, std::uint64_t max_bytes,
                                 std::string_view what) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0)
    throw Error(path.string() + ": cannot open " + std::string(what) + ": " + std::strerror(errno));
  detail::check_stat(path.string(), st, max_bytes, what);
}

/// The whole content of a regular file of at most max_bytes. Opened non-blocking and checked with
/// fstat on the open descriptor, so a FIFO or device swapped in after a check cannot hang or flood
/// it. Throws ptda::Error naming the path. Thread: any (configure time). Blocks (reads); allocates.
/// As require_regular_file, then require_not_writable_by_others and
/// require_parents_not_writable_by_others (for configuration and baseline files).
inline void require_trusted_file(const std::filesystem::path& path, std::uint64_t max_bytes,
                                 std::string_view what, uid_t euid = ::geteuid()) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0)
    throw Error(path.string() + ": cannot open " + std::string(what) + ": " + std::strerror(errno));
  detail::check_stat(path.string(), st, max_bytes, what);
  require_not_writable_by_others(path.string(), st, what, euid);
  require_parents_not_writable_by_others(path, what, euid);
}

/// With `euid` given, the permission check of require_not_writable_by_others runs on the open file
/// too (configuration files: pass ::geteuid()).
inline std::string read_regular_file(const std::filesystem::path& path, std::uint64_t max_bytes,
                                     std::string_view what, std::optional<uid_t> euid = std::nullopt) {
  const std::string name = path.string();
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
  if (fd < 0) throw Error(name + ": cannot open " + std::string(what) + ": " + std::strerror(errno));
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  struct stat st {};
  if (::fstat(fd, &st) != 0)
    throw Error(name + ": cannot stat " + std::string(what) + ": " + std::strerror(errno));
  detail::check_stat(name, st, max_bytes, what);
  if (euid) {
    require_not_writable_by_others(name, st, what, *euid);
    require_parents_not_writable_by_others(path, what, *euid);
  }
  std::string text(static_cast<std::size_t>(st.st_size), '\0');
  std::size_t got = 0;
  while (got < text.size()) {
    const ssize_t n = ::read(fd, text.data() + got, text.size() - got);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw Error(name + ": cannot read " + std::string(what) + ": " + std::strerror(errno));
    if (n == 0) break;  // shrank while reading: parse what is there
    got += static_cast<std::size_t>(n);
  }
  text.resize(got);
  return text;
}

}  // namespace ptda
