// The spill containers' file (dsp/include/ptda/dsp/spill.hpp): an anonymous file, appended to and
// read with pwrite/pread. Offline code: throws ptda::Error.
#include "ptda/dsp/spill.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <string>

#include "ptda/common/error.hpp"

namespace ptda::dsp::detail {

SpillFile::~SpillFile() {
  if (fd_ >= 0) ::close(fd_);
}

SpillFile::SpillFile(SpillFile&& o) noexcept : dir_(std::move(o.dir_)), fd_(o.fd_), size_(o.size_) {
  o.fd_ = -1;
  o.size_ = 0;
}

SpillFile& SpillFile::operator=(SpillFile&& o) noexcept {
  if (this != &o) {
    if (fd_ >= 0) ::close(fd_);
    dir_ = std::move(o.dir_);
    fd_ = o.fd_;
    size_ = o.size_;
    o.fd_ = -1;
    o.size_ = 0;
  }
  return *this;
}

std::string SpillFile::directory() const {
  if (!dir_.empty()) return dir_;
  const char* t = std::getenv("TMPDIR");
  return t != nullptr && *t != '\0' ? std::string(t) : std::string("/tmp");
}

void SpillFile::append(const void* data, std::size_t n) {
  if (n == 0) return;
  if (fd_ < 0) {
    const std::string dir = directory();
    // Anonymous where the file system allows it; else a named file unlinked at once.
    int fd = ::open(dir.c_str(), O_TMPFILE | O_RDWR | O_CLOEXEC, 0600);
    if (fd < 0) {
      if (errno != EOPNOTSUPP && errno != EISDIR && errno != EINVAL) {
        throw Error("spill file: cannot create a spill file in " + dir + ": " + std::strerror(errno) +
                    " (set TMPDIR to a writable directory)");
      }
      std::string name = dir + "/.ptda-spill-XXXXXX";
      fd = ::mkostemp(name.data(), O_CLOEXEC);
      if (fd < 0) {
        throw Error("spill file: cannot create the spill file " + name + ": " + std::strerror(errno) +
                    " (set TMPDIR to a writable directory)");
      }
      ::unlink(name.c_str());
    }
    fd_ = fd;
  }
  const auto* p = static_cast<const char*>(data);
  std::uint64_t off = size_;
  while (n > 0) {
    const ssize_t w = ::pwrite(fd_, p, n, static_cast<off_t>(off));
    if (w < 0) {
      if (errno == EINTR) continue;
      throw Error("spill file: writing " + std::to_string(n) + " bytes at offset " + std::to_string(off) +
                  " of a spill file in " + directory() + " failed: " + std::strerror(errno));
    }
    p += w;
    n -= static_cast<std::size_t>(w);
    off += static_cast<std::uint64_t>(w);
  }
  size_ = off;
}

void SpillFile::read(std::uint64_t off, void* data, std::size_t n) const {
  if (off + n > size_) {
    throw Error("spill file: read of " + std::to_string(n) + " bytes at offset " + std::to_string(off) +
                " beyond the file's " + std::to_string(size_) + " bytes");
  }
  auto* p = static_cast<char*>(data);
  while (n > 0) {
    const ssize_t r = ::pread(fd_, p, n, static_cast<off_t>(off));
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) {
      throw Error("spill file: reading " + std::to_string(n) + " bytes at offset " + std::to_string(off) +
                  " of a spill file in " + directory() + " failed: " +
                  (r < 0 ? std::string(std::strerror(errno)) : std::string("unexpected end of file")));
    }
    p += r;
    n -= static_cast<std::size_t>(r);
    off += static_cast<std::uint64_t>(r);
  }
}

}  // namespace ptda::dsp::detail
