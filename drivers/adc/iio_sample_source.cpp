#include "adc/iio_sample_source.hpp"

#include <fcntl.h>
#include <poll.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>
#include <utility>

#include "adc/iio_sysfs_value.hpp"
#include "ptda/common/error.hpp"

namespace fs = std::filesystem;

namespace ptda::drivers {
namespace {

std::string read_attr(const fs::path& p) {
  std::ifstream in(p);
  if (!in) throw Error(p.string(), 0, 0, "cannot read (missing IIO attribute?)");
  std::stringstream ss;
  ss << in.rdbuf();
  std::string s = ss.str();
  while (!s.empty() && (s.back() == '\n' || s.back() == ' ')) s.pop_back();
  return s;
}

/// Writes like `echo value > attr`: the attribute must exist (sysfs never creates files).
void write_attr(const fs::path& p, const std::string& value) {
  const int fd = ::open(p.c_str(), O_WRONLY | O_TRUNC | O_CLOEXEC);
  if (fd < 0) throw Error(p.string(), 0, 0, std::string("cannot open for writing: ") + std::strerror(errno));
  const std::string line = value + "\n";
  const ssize_t n = ::write(fd, line.data(), line.size());
  const int e = errno;
  ::close(fd);
  if (n != static_cast<ssize_t>(line.size()))
    throw Error(p.string(), 0, 0,
                "cannot write '" + value + "': " + (n < 0 ? std::strerror(e) : "short write"));
}

/// Shortest decimal text that reads back as v ("25600", "1600.5").
std::string number_text(double v) {
  char buf[64];
  for (int prec = 6; prec <= 17; ++prec) {
    std::snprintf(buf, sizeof buf, "%.*g", prec, v);
    if (std::strtod(buf, nullptr) == v) break;
  }
  return buf;
}

bool write_enable(const std::string& path, bool on) noexcept {
  const int fd = ::open(path.c_str(), O_WRONLY | O_TRUNC | O_CLOEXEC);
  if (fd < 0) return false;
  const char* text = on ? "1\n" : "0\n";
  const ssize_t n = ::write(fd, text, 2);
  ::close(fd);
  return n == 2;
}

timespec to_timespec(std::int64_t ns) noexcept {
  if (ns < 0) ns = 0;
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(ns / 1'000'000'000);
  ts.tv_nsec = static_cast<long>(ns % 1'000'000'000);
  return ts;
}

}  // namespace

IioSampleSource::IioSampleSource(IioSourceConfig config, const Clock& clock)
    : config_(std::move(config)), clock_(clock) {}

IioSampleSource::~IioSampleSource() {
  deactivate();
  if (fd_ >= 0) ::close(fd_);
}

fs::path IioSampleSource::buffer_attr(const char* name) const {
  return buffer_dir_ / name;
}

void IioSampleSource::configure() {
  const fs::path& dir = config_.sysfs_dir;
  if (!fs::is_directory(dir)) throw Error(dir.string(), 0, 0, "no such IIO device directory");
  if (config_.block_len == 0 || config_.block_len > kMaxBlock)
    throw Error(dir.string(), 0, 0, "block_len must be 1.." + std::to_string(kMaxBlock));
  if (!(config_.gap_tolerance > 0.0)) throw Error(dir.string(), 0, 0, "gap_tolerance must be > 0");
  // Since Linux 5.11 each buffer has bufferN/; buffer/ stays as the first one's alias.
  buffer_dir_ = fs::is_directory(dir / "buffer") ? dir / "buffer" : dir / "buffer0";
  if (!fs::is_directory(buffer_dir_))
    throw Error(dir.string(), 0, 0, "no buffer/ directory: not a buffered device");
  enable_path_ = buffer_attr("enable").string();

  // 1. Stop a capture a previous run may have left on: scan elements cannot change while enabled.
  write_attr(enable_path_, "0");
  // 2. Rate, read back: drivers round to what the hardware supports.
  const fs::path freq = dir / "sampling_frequency";
  if (config_.fs_hz > 0.0) write_attr(freq, number_text(config_.fs_hz));
  fs_hz_ = parse_sysfs_rate_hz(read_attr(freq), freq.string());
  period_ns_ = 1e9 / fs_hz_;
  // 3. Timestamps on CLOCK_MONOTONIC (the default is CLOCK_REALTIME, which jumps with NTP).
  if (fs::exists(dir / "current_timestamp_clock")) write_attr(dir / "current_timestamp_clock", "monotonic");

  // 4. Enable exactly the wanted scan elements.
  const fs::path se = dir / "scan_elements";
  if (!fs::is_directory(se)) throw Error(se.string(), 0, 0, "missing (not a buffered IIO device)");
  std::vector<std::string> available;
  for (const auto& entry : fs::directory_iterator(se)) {
    const std::string f = entry.path().filename().string();
    if (f.size() > 6 && f.rfind("in_", 0) == 0 && f.compare(f.size() - 3, 3, "_en") == 0)
      available.push_back(f.substr(3, f.size() - 6));
  }
  std::sort(available.begin(), available.end());
  std::vector<std::string> wanted{config_.channel};
  for (const auto& c : config_.extra_channels) wanted.push_back(c);
  const bool has_ts = std::find(available.begin(), available.end(), "timestamp") != available.end();
  if (config_.timestamp && has_ts) wanted.emplace_back("timestamp");
  for (const auto& w : wanted) {
    if (std::find(available.begin(), available.end(), w) == available.end()) {
      std::string list;
      for (const auto& a : available) list += (list.empty() ? "" : ", ") + a;
      throw Error(se.string(), 0, 0, "no channel '" + w + "' (available: " + list + ")");
    }
  }
  std::vector<IioChannelSpec> specs;
  for (const auto& a : available) {
    const bool on = std::find(wanted.begin(), wanted.end(), a) != wanted.end();
    write_attr(se / ("in_" + a + "_en"), on ? "1" : "0");
    if (!on) continue;
    IioChannelSpec spec;
    spec.name = a;
    const fs::path index_path = se / ("in_" + a + "_index");
    spec.index = parse_sysfs_index(read_attr(index_path), index_path.string());
    const fs::path type_path = se / ("in_" + a + "_type");
    spec.type = parse_iio_scan_type(read_attr(type_path), type_path.string());
    specs.push_back(std::move(spec));
  }
  layout_ = compute_iio_scan_layout(specs);
  value_element_ = layout_.find(config_.channel);
  if (layout_.elements[static_cast<std::size_t>(value_element_)].type.repeat != 1)
    throw Error(se.string(), 0, 0, "channel '" + config_.channel + "' has repeat > 1 (not a scalar sample)");

  // 5. Trigger and buffer geometry.
  if (!config_.trigger.empty()) write_attr(dir / "trigger" / "current_trigger", config_.trigger);
  if (config_.buffer_length > 0) write_attr(buffer_attr("length"), std::to_string(config_.buffer_length));
  if (config_.watermark > 0 && fs::exists(buffer_attr("watermark")))
    write_attr(buffer_attr("watermark"), std::to_string(config_.watermark));

  // 6. Buffers, then the character device (non-blocking: read() waits only in poll()).
  buf_.assign(static_cast<std::size_t>(config_.block_len) * layout_.scan_bytes + layout_.scan_bytes, 0);
  have_ = 0;
  if (fd_ >= 0) ::close(fd_);
  fd_ = ::open(config_.dev_path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd_ < 0)
    throw Error(config_.dev_path.string(), 0, 0, std::string("cannot open: ") + std::strerror(errno));
}

void IioSampleSource::activate() {
  if (fd_ < 0) throw Error(config_.sysfs_dir.string(), 0, 0, "activate() before configure()");
  write_attr(enable_path_, "1");
  have_ = 0;
  short_read_pending_ = false;
  next_index_ = 0;
  have_last_ts_ = false;
  active_ = true;
}

void IioSampleSource::deactivate() noexcept {
  if (!active_) return;
  active_ = false;
  (void)write_enable(enable_path_, false);
}

SourceStatus IioSampleSource::read(SampleBlock& out, std::int64_t timeout_ns) noexcept {
  if (!active_) return SourceStatus::kNotActive;
  const std::size_t scan = layout_.scan_bytes;

  // Wait only when not even one whole scan is buffered; otherwise just top the buffer up.
  if (have_ < scan) {
    pollfd p{fd_, POLLIN, 0};
    const timespec ts = to_timespec(timeout_ns);
    const int r = ::ppoll(&p, 1, &ts, nullptr);
    if (r == 0 || (r < 0 && errno == EINTR)) {
      if (timeout_ns > 0) stats_.timeouts.add();  // a poll (burst read, timeout 0) is not a timeout
      return SourceStatus::kTimeout;
    }
    if (r < 0 || (p.revents & (POLLERR | POLLNVAL)) != 0) {
      stats_.read_errors.add();
      return SourceStatus::kError;
    }
  }
  if (have_ < static_cast<std::size_t>(config_.block_len) * scan) {
    // buf_ holds block_len + 1 scans, so a read that returns all it was asked for ends on a scan
    // boundary; ending inside a scan means the producer handed out a partial one.
    const ssize_t n = ::read(fd_, buf_.data() + have_, buf_.size() - have_);
    if (n < 0) {
      if (errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) {
        stats_.read_errors.add();
        return SourceStatus::kError;
      }
    } else if (n == 0) {
      if (have_ < scan) {
        stats_.end_of_stream.add();
        return SourceStatus::kEndOfStream;
      }
    } else {
      have_ += static_cast<std::size_t>(n);
      if (have_ % scan != 0) {
        stats_.short_reads.add();
        short_read_pending_ = true;
      }
    }
    if (have_ < scan) {
      if (timeout_ns > 0) stats_.timeouts.add();
      return SourceStatus::kTimeout;
    }
  }

  const std::size_t scans = std::min<std::size_t>(have_ / scan, config_.block_len);
  const IioScanElement& value_el = layout_.elements[static_cast<std::size_t>(value_element_)];
  const IioScanElement* ts_el = layout_.timestamp_element >= 0
                                    ? &layout_.elements[static_cast<std::size_t>(layout_.timestamp_element)]
                                    : nullptr;
  const double gap_limit_ns = (1.0 + config_.gap_tolerance) * period_ns_;

  std::uint32_t flags = 0;
  std::uint32_t gap_samples = 0;
  std::size_t count = 0;
  std::int64_t t_first = 0;
  for (std::size_t k = 0; k < scans; ++k) {
    const std::uint8_t* s = buf_.data() + k * scan;
    if (ts_el != nullptr) {
      const std::int64_t t = decode_iio_value(s, *ts_el);
      if (have_last_ts_) {
        // Saturated: a garbage timestamp (any 64-bit value) must not overflow (UB) into a step
        // backwards; it is a huge gap or a step back by its sign.
        std::int64_t dt = 0;
        if (__builtin_sub_overflow(t, last_ts_, &dt)) {
          dt = t < last_ts_ ? std::numeric_limits<std::int64_t>::min()
                            : std::numeric_limits<std::int64_t>::max();
        }
        const bool back = dt <= 0;
        const bool gap = static_cast<double>(dt) > gap_limit_ns;
        if ((back || gap) && k > 0) break;  // a discontinuity always starts a new block
        if (back) {
          flags |= kBlockTimeBack;
          stats_.time_back.add();
        } else if (gap) {
          const double lost = std::round(static_cast<double>(dt) / period_ns_) - 1.0;
          gap_samples = lost > 0.0 ? static_cast<std::uint32_t>(std::min(lost, 4.0e9)) : 0U;
          flags |= kBlockGap;
          stats_.gaps.add();
          stats_.lost_samples.add(gap_samples);
        }
      }
      if (k == 0) t_first = t;
      last_ts_ = t;
      have_last_ts_ = true;
    }
    out.samples[k] = static_cast<float>(decode_iio_value(s, value_el)) * config_.scale;
    ++count;
  }
  if (ts_el == nullptr) {
    flags |= kBlockClockTime;
    t_first =
        clock_.now_ns() - static_cast<std::int64_t>(std::llround(static_cast<double>(count) * period_ns_));
  }
  if (short_read_pending_) {  // a read that went into this block ended inside a scan
    flags |= kBlockShortRead;
    short_read_pending_ = false;
  }

  out.t_mono_ns = t_first;
  out.first_index = next_index_ + gap_samples;
  out.count = static_cast<std::uint32_t>(count);
  out.flags = flags;
  out.gap_samples = gap_samples;
  next_index_ = out.first_index + count;

  const std::size_t used = count * scan;
  std::memmove(buf_.data(), buf_.data() + used, have_ - used);
  have_ -= used;
  stats_.blocks.add();
  stats_.samples.add(count);
  return SourceStatus::kOk;
}

}  // namespace ptda::drivers
