// Input files must be regular files of bounded size (issue 14 item 3): a FIFO hung `configure`,
// /dev/zero exhausted memory. Every reader calls require_regular_file() (or read_regular_file())
// before reading. Header-only like the rest of common/.
#pragma once

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string>
#include <string_view>

#include "ptda/common/error.hpp"

namespace ptda {

/// Size limits of the files read whole (generous: 100x the largest real file).
inline constexpr std::uint64_t kMaxConfigFileBytes = 16ULL << 20U;   ///< TOML: config, drop-in, scenario
inline constexpr std::uint64_t kMaxBaselineFileBytes = 1ULL << 30U;  ///< a baseline
inline constexpr std::uint64_t kNoSizeLimit = ~std::uint64_t{0};     ///< streamed files (WAV, CAN log)

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
inline std::string read_regular_file(const std::filesystem::path& path, std::uint64_t max_bytes,
                                     std::string_view what) {
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
