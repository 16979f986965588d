// Replacing a state file (status.json, the Prometheus textfile, the baseline) without trusting the
// directory it lives in (issue 14 item 2). The old writers opened "<name>.tmp" / "<name>.tmp.<pid>"
// with O_CREAT|O_TRUNC and no O_NOFOLLOW: with a directory writable by another user, a symlink planted
// at that predictable name made the daemon (root) truncate, overwrite and chmod a file of the
// attacker's choice. write_file_atomic() instead creates "<name>.tmp-<12 random characters>" in the
// target's directory with O_CREAT|O_EXCL|O_NOFOLLOW|O_CLOEXEC (an existing entry of any kind, a
// symlink included, makes the open fail and another name is drawn), sets the mode on the descriptor
// (fchmod, never chmod by path), writes, optionally fsyncs, renames over the target (rename replaces a
// symlink at the target itself, it never follows it) and optionally fsyncs the directory.
// remove_stale_temp_files() removes what a `kill -9` left behind. Header-only like the rest of common/.
#pragma once

#include <dirent.h>
#include <fcntl.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>

#include "ptda/common/error.hpp"

namespace ptda {

/// A failed write of a file, with the errno of the failing step (e.g. to report it in status.json).
class WriteError : public Error {
 public:
  WriteError(const std::string& what, int err) : Error(what), err_(err) {}
  [[nodiscard]] int err() const noexcept { return err_; }

 private:
  int err_;
};

/// AtomicWriteResult::step when the temporary file could not be created (compare with strcmp).
inline constexpr const char* kStepOpenTemp = "open of the temporary file";

/// Characters of the random part of a temporary name ("<name>.tmp-" + these).
inline constexpr std::size_t kTempSuffixChars = 12;

/// What write_file_atomic() did: err == 0 on success, else the errno of the failing step (named by
/// `step`, a string literal such as "write" or "rename"). The temporary file is gone either way.
struct AtomicWriteResult {
  int err = 0;
  const char* step = "";
  [[nodiscard]] bool ok() const noexcept { return err == 0; }
};

struct AtomicWriteOptions {
  mode_t mode = 0644;
  /// true: fchmod(mode) on the descriptor, so the service's UMask does not apply (files another user
  /// must read); false: the mode given to open(), minus the umask.
  bool exact_mode = false;
  /// true: fsync the file before the rename and the directory after it (a file that must survive a
  /// power cut, e.g. the baseline); false for files rewritten every few seconds in /run.
  bool durable = true;
};

namespace detail {

/// 12 characters of [0-9a-z] from getrandom() (falling back to the clock, the pid and a counter when
/// getrandom is not available). Never allocates or blocks (GRND_NONBLOCK).
inline void random_suffix(char* out) noexcept {
  static constexpr char kAlphabet[] = "0123456789abcdefghijklmnopqrstuvwxyz";
  std::uint8_t bytes[kTempSuffixChars] = {};
  if (::getrandom(bytes, sizeof bytes, GRND_NONBLOCK) != static_cast<ssize_t>(sizeof bytes)) {
    static std::atomic<std::uint64_t> counter{0};
    timespec ts{};
    ::clock_gettime(CLOCK_MONOTONIC, &ts);
    std::uint64_t x = static_cast<std::uint64_t>(ts.tv_nsec) ^
                      (static_cast<std::uint64_t>(ts.tv_sec) << 30U) ^
                      (static_cast<std::uint64_t>(::getpid()) << 20U) ^
                      ((counter.fetch_add(1, std::memory_order_relaxed) + 1) * 0x9E3779B97F4A7C15ULL);
    for (std::uint8_t& b : bytes) {
      x ^= x >> 33U;
      x *= 0xFF51AFD7ED558CCDULL;
      x ^= x >> 29U;
      b = static_cast<std::uint8_t>(x);
    }
  }
  for (std::size_t i = 0; i < kTempSuffixChars; ++i) out[i] = kAlphabet[bytes[i] % 36U];
}

inline bool write_all_fd(int fd, const char* data, std::size_t size) noexcept {
  std::size_t done = 0;
  while (done < size) {
    const ssize_t n = ::write(fd, data + done, size - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    if (n == 0) {
      errno = EIO;
      return false;
    }
    done += static_cast<std::size_t>(n);
  }
  return true;
}

/// True when `name` is a temporary file of the target `base`: "<base>.tmp" (the old status writer),
/// "<base>.tmp.<digits>" (the old baseline writer: the pid) or "<base>.tmp-" + kTempSuffixChars of
/// [0-9a-z] (write_file_atomic).
inline bool is_temp_name_of(std::string_view name, std::string_view base) noexcept {
  if (name.size() < base.size() + 4 || name.substr(0, base.size()) != base) return false;
  name.remove_prefix(base.size());
  if (name.substr(0, 4) != ".tmp") return false;
  name.remove_prefix(4);
  if (name.empty()) return true;
  const char kind = name.front();
  name.remove_prefix(1);
  if (kind == '.') {
    if (name.empty()) return false;
    for (const char c : name) {
      if (c < '0' || c > '9') return false;
    }
    return true;
  }
  if (kind != '-' || name.size() != kTempSuffixChars) return false;
  for (const char c : name) {
    if (!((c >= '0' && c <= '9') || (c >= 'a' && c <= 'z'))) return false;
  }
  return true;
}

}  // namespace detail

/// Longest path write_file_atomic() accepts (longer: ENAMETOOLONG); the names live on the stack.
inline constexpr std::size_t kAtomicPathMax = 4096;

/// Replaces `path` with `size` bytes at `data` (see the header comment). The temporary file is
/// "<path>.tmp-XXXXXXXXXXXX" in the same directory (so the rename stays on one file system; for a
/// "*.prom" target it never ends in ".prom", so node_exporter never reads it). Returns the failing
/// step and its errno; on failure the temporary file is removed and `path` is untouched.
/// Thread: any. Never allocates or throws; blocks on file I/O (and on fsync when durable).
inline AtomicWriteResult write_file_atomic(const char* path, const void* data, std::size_t size,
                                           const AtomicWriteOptions& opt = {}) noexcept {
  const std::size_t len = std::strlen(path);
  constexpr std::size_t kExtra = 5 + kTempSuffixChars;  // ".tmp-" + suffix
  if (len == 0 || len + kExtra + 1 > kAtomicPathMax) return {ENAMETOOLONG, "temporary file name"};
  if (path[len - 1] == '/') return {EISDIR, "temporary file name"};
  char tmp[kAtomicPathMax];
  std::memcpy(tmp, path, len);
  std::memcpy(tmp + len, ".tmp-", 5);
  tmp[len + kExtra] = '\0';
  int fd = -1;
  for (int attempt = 0; attempt < 16 && fd < 0; ++attempt) {
    detail::random_suffix(tmp + len + 5);
    fd = ::open(tmp, O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, opt.exact_mode ? 0600 : opt.mode);
    if (fd < 0 && errno != EEXIST) return {errno, kStepOpenTemp};
  }
  if (fd < 0) return {EEXIST, kStepOpenTemp};
  const auto fail = [&](const char* step, int err) noexcept {
    if (fd >= 0) ::close(fd);
    ::unlink(tmp);
    return AtomicWriteResult{err, step};
  };
  if (opt.exact_mode && ::fchmod(fd, opt.mode) != 0) return fail("fchmod", errno);
  if (!detail::write_all_fd(fd, static_cast<const char*>(data), size)) return fail("write", errno);
  if (opt.durable && ::fsync(fd) != 0) return fail("fsync", errno);
  const int closed = ::close(fd);
  fd = -1;
  if (closed != 0) return fail("close", errno);
  if (::rename(tmp, path) != 0) return fail("rename", errno);
  if (!opt.durable) return {};
  // Make the rename itself durable: fsync the directory.
  const char* slash = std::strrchr(path, '/');
  int dfd = -1;
  if (slash == nullptr) {
    dfd = ::open(".", O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  } else {
    const auto dir_len = static_cast<std::size_t>(slash - path);
    char dir[kAtomicPathMax];
    std::memcpy(dir, path, dir_len == 0 ? 1 : dir_len);  // "/name": the root directory
    dir[dir_len == 0 ? 1 : dir_len] = '\0';
    dfd = ::open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  }
  if (dfd < 0) return {errno, "open of the directory for fsync"};
  if (::fsync(dfd) != 0) {
    const int err = errno;
    ::close(dfd);
    return {err, "fsync of the directory"};
  }
  ::close(dfd);
  return {};
}

/// Removes the temporary files of the target `target_name` that an earlier run left in `dir` (killed
/// between create and rename): regular files owned by the effective user whose name is one of the
/// patterns of detail::is_temp_name_of. Never follows a symlink, never removes anything else. Returns
/// how many were removed (a missing or unreadable directory: 0). Thread: any (configure time).
/// Allocates nothing beyond what readdir does; never throws.
inline std::size_t remove_stale_temp_files(const char* dir, std::string_view target_name) noexcept {
  const int dfd = ::open(dir[0] == '\0' ? "." : dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd < 0) return 0;
  DIR* d = ::fdopendir(dfd);
  if (d == nullptr) {
    ::close(dfd);
    return 0;
  }
  std::size_t removed = 0;
  const uid_t me = ::geteuid();
  while (const dirent* e = ::readdir(d)) {
    if (!detail::is_temp_name_of(e->d_name, target_name)) continue;
    struct stat st {};
    if (::fstatat(dfd, e->d_name, &st, AT_SYMLINK_NOFOLLOW) != 0) continue;
    if (!S_ISREG(st.st_mode) || st.st_uid != me) continue;
    if (::unlinkat(dfd, e->d_name, 0) == 0) ++removed;
  }
  ::closedir(d);
  return removed;
}

/// "ENOENT" for an errno value ("" for 0, "E?" when unknown). Thread: any. Never allocates.
[[nodiscard]] inline const char* errno_name(int err) noexcept {
  if (err == 0) return "";
  const char* n = ::strerrorname_np(err);
  return n != nullptr ? n : "E?";
}

/// "No such file or directory" for an errno value ("" for 0). Thread: any. Never allocates.
[[nodiscard]] inline const char* errno_text(int err) noexcept {
  if (err == 0) return "";
  const char* t = ::strerrordesc_np(err);
  return t != nullptr ? t : "unknown error";
}

}  // namespace ptda
