#include "status/history_log.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <system_error>

#include "ptda/common/error.hpp"
#include "ptda/dsp/decision.hpp"
#include "status/status_writer.hpp"

namespace ptda::daemon {
namespace {

constexpr std::size_t kLineBytes = 4096;  // a window line is ~700 bytes, a state line < 1 KiB

double seconds(std::int64_t ns) noexcept {
  return static_cast<double>(ns) * 1e-9;
}

}  // namespace

HistoryLog::HistoryLog(HistoryConfig cfg) : cfg_(std::move(cfg)), line_(kLineBytes) {
  if (cfg_.dir.empty()) throw Error("[history] dir: empty path");
  if (cfg_.files < 2) throw Error("[history] files: at least 2 (the current file and one rotation)");
  std::error_code ec;
  if (!std::filesystem::is_directory(cfg_.dir, ec)) {
    std::filesystem::create_directories(cfg_.dir, ec);
    if (ec) throw Error("[history] dir " + cfg_.dir.string() + ": cannot create: " + ec.message());
    std::filesystem::permissions(cfg_.dir, std::filesystem::perms(0750), ec);
  }
  path_ = file(0);
  rotated_.reserve(cfg_.files);
  for (std::uint32_t k = 0; k < cfg_.files; ++k) rotated_.push_back(file(k).string());
  if (!open_current()) {
    throw Error("[history] " + path_.string() + ": cannot open for appending: " +
                std::error_code(counters_.last_errno, std::generic_category()).message());
  }
}

HistoryLog::~HistoryLog() {
  if (fd_ >= 0) {
    ::fsync(fd_);  // the history survives a power cut up to the daemon's stop
    ::close(fd_);
  }
}

std::filesystem::path HistoryLog::file(std::uint32_t k) const {
  return cfg_.dir / (k == 0 ? std::string("history.jsonl") : "history." + std::to_string(k) + ".jsonl");
}

bool HistoryLog::open_current() noexcept {
  fd_ = ::open(rotated_[0].c_str(), O_RDWR | O_CREAT | O_APPEND | O_CLOEXEC | O_NOFOLLOW, 0640);
  if (fd_ < 0) {
    counters_.last_errno = errno;
    return false;
  }
  struct stat st {};
  size_ = ::fstat(fd_, &st) == 0 ? static_cast<std::uint64_t>(st.st_size) : 0;
  // A line cut by a power loss (no '\n' at the end): cut the file back to its last whole line, so the
  // next line does not glue onto the fragment.
  if (size_ > 0) {
    char last = '\n';
    if (::pread(fd_, &last, 1, static_cast<off_t>(size_ - 1)) == 1 && last != '\n') {
      std::uint64_t end = size_;
      char buf[4096];
      while (end > 0) {
        const std::uint64_t from = end > sizeof buf ? end - sizeof buf : 0;
        const ssize_t n = ::pread(fd_, buf, end - from, static_cast<off_t>(from));
        if (n <= 0) break;
        std::uint64_t i = static_cast<std::uint64_t>(n);
        while (i > 0 && buf[i - 1] != '\n') --i;
        if (i > 0) {
          end = from + i;
          break;
        }
        end = from;
      }
      if (::ftruncate(fd_, static_cast<off_t>(end)) == 0) {
        counters_.cut_bytes += size_ - end;
        size_ = end;
      }
    }
  }
  return true;
}

void HistoryLog::rotate() noexcept {
  if (fd_ >= 0) {
    ::fsync(fd_);  // a rotated file is complete on disk before its name moves
    ::close(fd_);
    fd_ = -1;
  }
  // history.<n-2> -> history.<n-1> (replacing the oldest), ..., history -> history.1
  bool current_moved = true;
  for (std::uint32_t k = cfg_.files - 1; k >= 1; --k) {
    if (::rename(rotated_[k - 1].c_str(), rotated_[k].c_str()) != 0 && errno != ENOENT) {
      counters_.last_errno = errno;
      if (k == 1) current_moved = false;
    }
  }
  // The renames are durable before the new file takes lines (a power cut must not leave two files
  // with one name's history).
  const int dfd = ::open(cfg_.dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd >= 0) {
    ::fsync(dfd);
    ::close(dfd);
  }
  if (!current_moved) {
    // The full current file could not be moved aside: rotating again on the next line would shift the
    // older files once more and lose them. The history stops at its size bound instead; every line
    // from here on is counted as a write failure (the supervisor reports it) until a restart.
    rotation_failed_ = true;
    ++counters_.rotation_failures;
  } else {
    ++counters_.rotations;
  }
  open_current();
}

void HistoryLog::write_line(std::size_t len) noexcept {
  if (size_ > 0 && size_ + len > cfg_.max_file_bytes) {
    if (rotation_failed_) {
      ++counters_.write_failures;
      return;
    }
    rotate();
    if (rotation_failed_) {
      ++counters_.write_failures;
      return;
    }
  }
  if (fd_ < 0 && !open_current()) {
    ++counters_.write_failures;
    return;
  }
  const char* p = line_.data();
  std::size_t left = len;
  while (left > 0) {
    const ssize_t n = ::write(fd_, p, left);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      counters_.last_errno = n < 0 ? errno : EIO;
      ++counters_.write_failures;
      // A partial line would break the JSON Lines: cut the file back to the last whole line.
      if (left != len && ::ftruncate(fd_, static_cast<off_t>(size_)) != 0) {
        ::close(fd_);
        fd_ = -1;
      }
      return;
    }
    p += n;
    left -= static_cast<std::size_t>(n);
  }
  size_ += len;
  ++counters_.lines;
  counters_.bytes += len;
}

void HistoryLog::begin_line(JsonWriter& o, std::string_view type, std::int64_t unix_ns) const noexcept {
  o.open('{');
  o.str("type", type);
  if (!cfg_.joint.empty()) o.str("joint", cfg_.joint);
  o.utc("t_utc", unix_ns);
}

void HistoryLog::finish_line(TextBuffer& b, JsonWriter& o) noexcept {
  o.close('}');
  b.append_char('\n');
  if (b.overflow()) {
    ++counters_.write_failures;  // a line longer than the buffer: dropped, counted
    return;
  }
  write_line(b.size());
}

void HistoryLog::window(const dsp::WindowResult& w, std::int64_t end_unix_ns) noexcept {
  TextBuffer b(line_.data(), line_.size());
  JsonWriter o(b);
  begin_line(o, "window", end_unix_ns);
  o.u64("n", w.ref.seq);
  o.num("t_start", seconds(w.ref.t_start_ns));
  o.num("t_end", seconds(w.ref.t_end_ns));
  const bool scored = w.status == dsp::WindowStatus::kScored;
  if (w.class_id >= 0) {
    o.i64("segment", w.class_id);
  } else {
    o.null("segment");
  }
  o.u64("region", w.ref.region_seq);
  o.num("speed_rad_s", w.ref.speed_rad_s);
  o.str("status", scored ? "scored" : "no_class");
  o.str("method", cfg_.method);
  if (scored) {
    o.num("rms_res", w.features.rms_res);
    o.num("entropy_res", w.features.entropy_res);
    o.band("rms_band", w.thresholds.rms.lo, w.thresholds.rms.hi);
    o.band("entropy_band", w.thresholds.entropy.lo, w.thresholds.entropy.hi);
  } else {
    o.null("rms_res");
    o.null("entropy_res");
    o.null("rms_band");
    o.null("entropy_band");
  }
  o.boolean("rms_out", scored && w.verdict.rms_out);
  o.boolean("entropy_out", scored && w.verdict.entropy_out);
  o.boolean("abnormal", scored && w.verdict.abnormal());
  o.boolean("alarm", w.alarm);
  o.u64("abnormal_in_last_n", w.abnormal_in_last_n);
  o.boolean("rms_low", scored && w.verdict.rms_low);
  o.str("detector", dsp::alarm_detector_name(w.detector));
  o.boolean("kofn_alarm", w.kofn_alarm);
  o.boolean("seq_alarm", w.seq_alarm);
  o.boolean("seq_warn", w.seq_warn);
  if (scored) {
    o.num("z_rms", w.z_rms);
    o.num("z_entropy", w.z_entropy);
    o.num("cusum", w.seq_statistic);
    o.str("cusum_feature", dsp::seq_feature_name(w.seq_feature));
  } else {
    o.null("z_rms");
    o.null("z_entropy");
    o.null("cusum");
    o.null("cusum_feature");
  }
  o.num("cusum_max", w.seq_max_statistic);
  if (w.band_on) {  // as ptda monitor --jsonl writes them (only with [decision] band_cusum on)
    o.boolean("band_alarm", w.band_alarm);
    if (scored) {
      o.num("band_z_max", w.band_z_max);
      o.num("band_cusum", w.band_statistic);
      if (w.band_index >= 0) {
        o.i64("band_cusum_band", w.band_index);
      } else {
        o.null("band_cusum_band");
      }
    } else {
      o.null("band_z_max");
      o.null("band_cusum");
      o.null("band_cusum_band");
    }
    o.num("band_cusum_max", w.band_max_statistic);
    if (w.band_max_index >= 0) {
      o.i64("band", w.band_max_index);
      o.band("band_hz", w.band_lo_hz, w.band_hi_hz);
    } else {
      o.null("band");
      o.null("band_hz");
    }
  }
  if (w.mesh_on) {  // as ptda monitor --jsonl writes them (only with [decision] mesh_cusum on)
    o.boolean("mesh_alarm", w.mesh_alarm);
    o.num("mesh_am", w.mesh_value[0]);
    o.num("mesh_pm", w.mesh_value[1]);
    o.num("mesh_excess_am", w.mesh_excess[0]);
    o.num("mesh_excess_pm", w.mesh_excess[1]);
    if (scored) {
      o.num("mesh_cusum", w.mesh_statistic);
      o.str("mesh_cusum_feature", dsp::mesh_feature_label(w.mesh_feature));
    } else {
      o.null("mesh_cusum");
      o.null("mesh_cusum_feature");
    }
    o.num("mesh_cusum_max", w.mesh_max_statistic);
    o.str("mesh_feature", dsp::mesh_feature_label(w.mesh_max_feature));
  }
  finish_line(b, o);
}

void HistoryLog::state(std::int64_t unix_ns, std::string_view state, std::string_view phase,
                       std::string_view level, std::string_view causes, std::string_view reason) noexcept {
  TextBuffer b(line_.data(), line_.size());
  JsonWriter o(b);
  begin_line(o, "state", unix_ns);
  o.str("state", state);
  o.str("phase", phase);
  o.str("level", level);
  o.str("causes", causes);
  o.str("reason", reason);
  finish_line(b, o);
}

}  // namespace ptda::daemon
