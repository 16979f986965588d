#include "training/field_trainer.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <string>

#include "ptda/common/error.hpp"
#include "ptda/formats/baseline_file.hpp"

namespace ptda::daemon {
namespace {

constexpr std::uint64_t kMaxSpillBytes = std::uint64_t{64} << 30;
constexpr std::int64_t kWriterIdleWaitNs = 100'000'000;

/// Creates an anonymous file in `dir`: O_TMPFILE where the file system has it, else a named file
/// unlinked at once. Either way nothing is left in `dir` once the descriptor is closed.
int create_spill_file(const std::filesystem::path& dir) {
  int fd = ::open(dir.c_str(), O_TMPFILE | O_RDWR | O_CLOEXEC, 0600);
  if (fd >= 0) return fd;
  if (errno != EOPNOTSUPP && errno != EISDIR && errno != EINVAL) {
    throw Error("training.spill_dir: cannot create the field-training spill file in " + dir.string() + ": " +
                std::strerror(errno));
  }
  std::string name = (dir / ".ptdad-training-XXXXXX").string();
  fd = ::mkostemp(name.data(), O_CLOEXEC);
  if (fd < 0) {
    throw Error("training.spill_dir: cannot create the field-training spill file " + name + ": " +
                std::strerror(errno));
  }
  ::unlink(name.c_str());
  return fd;
}

/// pwrite/pread of exactly `n` bytes at `off` (retried on EINTR and short transfers); errno on failure.
int write_all(int fd, const void* data, std::size_t n, std::uint64_t off) noexcept {
  const auto* p = static_cast<const char*>(data);
  while (n > 0) {
    const ssize_t w = ::pwrite(fd, p, n, static_cast<off_t>(off));
    if (w < 0) {
      if (errno == EINTR) continue;
      return errno;
    }
    p += w;
    n -= static_cast<std::size_t>(w);
    off += static_cast<std::uint64_t>(w);
  }
  return 0;
}

int read_all(int fd, void* data, std::size_t n, std::uint64_t off) noexcept {
  auto* p = static_cast<char*>(data);
  while (n > 0) {
    const ssize_t r = ::pread(fd, p, n, static_cast<off_t>(off));
    if (r < 0) {
      if (errno == EINTR) continue;
      return errno;
    }
    if (r == 0) return EIO;  // the file is shorter than the windows it published: never expected
    p += r;
    n -= static_cast<std::size_t>(r);
    off += static_cast<std::uint64_t>(r);
  }
  return 0;
}

std::string fmt_speed(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.4g", v);
  return buf;
}

/// Groups of overlapping windows (as dsp::train_baseline forms them) among `idx`.
std::uint32_t count_groups(std::vector<std::size_t> idx, const std::vector<dsp::WindowRef>& refs,
                           std::int64_t window_len) {
  std::sort(idx.begin(), idx.end(), [&](std::size_t a, std::size_t b) {
    const dsp::WindowRef& p = refs[a];
    const dsp::WindowRef& q = refs[b];
    return p.region_seq != q.region_seq ? p.region_seq < q.region_seq : p.first_sample < q.first_sample;
  });
  std::uint32_t groups = 0;
  std::int64_t reach = 0;
  for (std::size_t k = 0; k < idx.size(); ++k) {
    const dsp::WindowRef& r = refs[idx[k]];
    const bool same_region = k > 0 && refs[idx[k - 1]].region_seq == r.region_seq;
    if (!(same_region && r.first_sample < reach)) {
      ++groups;
      reach = r.first_sample;
    }
    reach = std::max(reach, r.first_sample + window_len);
  }
  return groups;
}

}  // namespace

FieldTrainer::FieldTrainer(const FieldTrainerConfig& cfg) : cfg_(cfg) {
  if (!(std::isfinite(cfg.fs_hz) && cfg.fs_hz > 0.0)) {
    throw Error("training.fs_hz: must be > 0, got " + std::to_string(cfg.fs_hz));
  }
  if (cfg.window_len == 0) throw Error("training.window_len: must be > 0");
  if (cfg.max_windows == 0) throw Error("training.max_windows: must be > 0");
  if (cfg.max_regions == 0) throw Error("training.max_regions: must be > 0");
  if (cfg.classes.min_regions == 0) throw Error("classes.min_regions: must be >= 1");
  if (cfg.target_cycles == 0 || cfg.target_cycles < cfg.classes.min_regions) {
    throw Error("training.target_cycles: must be >= classes.min_regions (" +
                std::to_string(cfg.classes.min_regions) + "), got " + std::to_string(cfg.target_cycles));
  }
  (void)dsp::learn_segment_classes({}, cfg.classes);  // throws on a bad [classes] table, naming the key
  const std::uint64_t bytes = std::uint64_t{cfg.max_windows} * cfg.window_len * sizeof(float);
  if (bytes > kMaxSpillBytes) {
    throw Error("training.max_windows: " + std::to_string(cfg.max_windows) + " windows of " +
                std::to_string(cfg.window_len) + " samples need " + std::to_string(bytes >> 20) +
                " MiB of disk, more than the 65536 MiB limit");
  }
  slots_.assign(kSpillSlots * cfg.window_len, 0.0F);
  refs_.assign(cfg.max_windows, dsp::WindowRef{});
  regions_.assign(cfg.max_regions, dsp::RegionInfo{});
  fd_ = create_spill_file(cfg.spill_dir.empty() ? std::filesystem::path(".") : cfg.spill_dir);
}

std::string FieldTrainer::spill_space_text(const std::filesystem::path& dir, std::uint64_t need_bytes,
                                           std::uint64_t free_bytes) {
  if (free_bytes >= need_bytes) return {};
  return "field training: the spill file in " + dir.string() + " may grow to " +
         std::to_string(need_bytes >> 20) + " MiB ([training] max_windows x window_len x 4 bytes) but " +
         std::to_string(free_bytes >> 20) +
         " MiB are free there: windows that do not fit will be dropped (training.dropped); lower "
         "[training] max_windows or set [training] spill_dir";
}

std::string FieldTrainer::spill_space_warning() const {
  struct statvfs st {};
  if (fd_ < 0 || ::fstatvfs(fd_, &st) != 0) return {};
  const std::uint64_t free_bytes = std::uint64_t{st.f_bavail} * st.f_frsize;
  const std::uint64_t written = window_count_.load(std::memory_order_acquire) * window_bytes();
  return spill_space_text(cfg_.spill_dir, max_spill_bytes() - std::min(written, max_spill_bytes()),
                          free_bytes);
}

FieldTrainer::~FieldTrainer() {
  stop();
  if (fd_ >= 0) ::close(fd_);
}

void FieldTrainer::start(WakeSignal* on_space) {
  if (writer_.joinable()) return;
  on_space_ = on_space;
  stop_.store(false, std::memory_order_relaxed);
  writer_ = std::thread([this] { writer_loop(); });
  pthread_setname_np(writer_.native_handle(), "ptdad-train");
}

void FieldTrainer::stop() noexcept {
  if (!writer_.joinable()) return;
  stop_.store(true, std::memory_order_release);
  work_.ring();
  writer_.join();
  on_space_ = nullptr;  // it belongs to the pipeline, which may go before this trainer (a reload)
}

void FieldTrainer::flush() noexcept {
  while (write_queued() > 0) {
  }
}

void FieldTrainer::writer_loop() noexcept {
  for (;;) {
    const std::uint32_t ticket = work_.ticket();
    // Read the stop before draining: the processing thread adds nothing after stop(), so a drain
    // that follows a stop seen here writes every window. Reading it after an empty drain lost the
    // windows queued in between (seen under qemu on aarch64).
    const bool stopping = stop_.load(std::memory_order_acquire);
    if (write_queued() > 0) {
      if (on_space_ != nullptr) on_space_->ring();
      continue;
    }
    if (idle_hook_ != nullptr) idle_hook_(idle_ctx_);
    if (stopping) return;
    work_.wait(ticket, kWriterIdleWaitNs);
  }
}

std::size_t FieldTrainer::write_queued() noexcept {
  std::size_t taken = 0;
  const std::uint64_t bytes = window_bytes();
  for (;;) {
    const std::uint64_t index = queue_.popped_index();
    const bool got = queue_.pop_with([&](const Queued& q) noexcept {
      const float* x = slots_.data() + (index % kSpillSlots) * cfg_.window_len;
      const std::uint64_t n = window_count_.load(std::memory_order_relaxed);  // only this thread writes it
      const int err = write_all(fd_, x, bytes, n * bytes);
      if (err != 0) {
        last_write_errno_.store(err, std::memory_order_relaxed);
        write_failed_.add();
        return;
      }
      refs_[n] = q.ref;
      window_count_.store(n + 1, std::memory_order_release);
      windows_.add();
    });
    if (!got) return taken;
    ++taken;
  }
}

bool FieldTrainer::add_window(const dsp::WindowRef& ref, std::span<const float> samples) noexcept {
  if (samples.size() != cfg_.window_len) {
    windows_rejected_.add();
    return false;
  }
  for (const float x : samples) {
    if (!std::isfinite(x)) {
      windows_rejected_.add();
      return false;
    }
  }
  // Windows whose write failed do not count against max_windows (the writer's counter only grows).
  if (taken_ - write_failed_.get() >= cfg_.max_windows) {
    windows_dropped_.add();
    return false;
  }
  // The slot of the next queue index is free while the queue has room (the writer frees a slot only
  // after it wrote the window).
  Queued* const q = queue_.claim();
  if (q == nullptr) {
    queue_full_.add();
    return false;
  }
  const std::uint64_t index = queue_.pushed_index();
  std::copy(samples.begin(), samples.end(),
            slots_.begin() + static_cast<std::ptrdiff_t>((index % kSpillSlots) * cfg_.window_len));
  q->ref = ref;
  q->ref.region_seq += region_seq_offset_;
  q->ref.first_sample += sample_offset_;
  queue_.commit();
  ++taken_;
  work_.ring();
  return true;
}

bool FieldTrainer::add_region(const dsp::RegionInfo& region) noexcept {
  if (!std::isfinite(region.mean_speed_rad_s)) {
    windows_rejected_.add();
    return false;
  }
  const std::uint64_t n = region_count_.load(std::memory_order_relaxed);
  if (n >= cfg_.max_regions) {
    regions_dropped_.add();
    return false;
  }
  regions_[n] = region;
  regions_[n].seq += region_seq_offset_;
  region_count_.store(n + 1, std::memory_order_release);
  regions_added_.add();
  return true;
}

FieldTrainer::Snapshot FieldTrainer::published() const noexcept {
  return {window_count_.load(std::memory_order_acquire), region_count_.load(std::memory_order_acquire)};
}

TrainingProgress FieldTrainer::progress() const {
  const Snapshot snap = published();
  TrainingProgress p;
  p.target_cycles = cfg_.target_cycles;
  p.windows = snap.windows;
  p.window_capacity = cfg_.max_windows;
  p.regions = snap.regions;
  const FieldTrainerCounters counts = counters();
  p.windows_dropped = counts.windows_dropped;
  p.windows_queued = queued();
  p.regions_dropped = counts.regions_dropped;
  p.windows_rejected = counts.windows_rejected;

  const std::vector<dsp::RegionInfo> regions(regions_.begin(),
                                             regions_.begin() + static_cast<std::ptrdiff_t>(snap.regions));
  dsp::ClassLearningConfig all = cfg_.classes;
  all.min_regions = 1;
  dsp::Baseline seen;
  for (const dsp::SegmentClass& c : dsp::learn_segment_classes(regions, all)) {
    dsp::ClassBaseline cb;
    cb.segment = c;
    seen.classes.push_back(std::move(cb));
  }
  std::vector<std::vector<std::size_t>> members(seen.classes.size());
  for (std::size_t i = 0; i < snap.windows; ++i) {
    const dsp::ClassBaseline* c = seen.match(refs_[i].speed_rad_s);
    if (c == nullptr) {
      ++p.windows_unmatched;
      continue;
    }
    members[static_cast<std::size_t>(c - seen.classes.data())].push_back(i);
  }
  for (std::size_t k = 0; k < seen.classes.size(); ++k) {
    ClassProgress cp;
    cp.segment = seen.classes[k].segment;
    cp.cycles = cp.segment.regions;
    cp.windows = static_cast<std::uint32_t>(members[k].size());
    cp.groups = count_groups(members[k], refs_, cfg_.window_len);
    cp.trainable = cp.cycles >= cfg_.classes.min_regions && cp.groups >= 3;
    cp.complete = cp.trainable && cp.cycles >= cfg_.target_cycles;
    if (cp.trainable) ++p.classes_trainable;
    if (cp.complete) ++p.classes_complete;
    p.classes.push_back(cp);
  }
  p.ready = !p.classes.empty() && p.classes_complete == p.classes.size();
  p.can_finish = p.classes_trainable > 0;
  return p;
}

dsp::Baseline FieldTrainer::finish(const std::filesystem::path& path, FinishMode mode) const {
  const TrainingProgress p = progress();
  std::string summary = std::to_string(p.regions) + " regions, " + std::to_string(p.windows) + " windows";
  std::string per_class;
  for (const ClassProgress& c : p.classes) {
    per_class += "; class " + std::to_string(c.segment.id) + " (" + (c.segment.direction < 0 ? "-" : "+") +
                 fmt_speed(c.segment.speed_rad_s) + " rad/s): " + std::to_string(c.cycles) + "/" +
                 std::to_string(p.target_cycles) + " cycles, " + std::to_string(c.windows) + " windows in " +
                 std::to_string(c.groups) + " groups";
  }
  const std::string needs = " (a class needs >= " + std::to_string(cfg_.classes.min_regions) +
                            " cycles and >= 3 non-overlapping windows to train, " +
                            std::to_string(p.target_cycles) + " cycles to be complete)";
  if (p.classes.empty()) {
    throw Error("field training: no constant-speed cycle seen yet (" + summary + ")");
  }
  if (mode == FinishMode::kRequireReady && !p.ready) {
    throw Error("field training: not ready: " + std::to_string(p.classes_complete) + " of " +
                std::to_string(p.classes.size()) + " classes complete" + needs + per_class);
  }
  if (!p.can_finish) {
    throw Error("field training: not enough data: no class has enough" + needs + per_class);
  }

  // The published entries [0, count) are immutable: copy their places, and stream their samples from
  // the spill file (each pass reads it in order, one window at a time, as `ptda train` reads a
  // recording).
  const Snapshot snap{p.windows, p.regions};
  // The training's own per-window lists spill to the same directory as the windows (beyond 32 KiB
  // per list), so a hardened service needs one writable place.
  dsp::SpillConfig spill;
  spill.dir = (cfg_.spill_dir.empty() ? std::filesystem::path(".") : cfg_.spill_dir).string();
  dsp::TrainingIndex index(spill);
  for (std::size_t i = 0; i < snap.windows; ++i) {
    index.refs.push_back(refs_[i]);
    index.recording.push_back(0U);
  }
  for (std::size_t i = 0; i < snap.regions; ++i) index.regions.push_back(regions_[i]);
  std::vector<float> x(cfg_.window_len);
  const dsp::TrainingWindowPass pass = [&](const dsp::TrainingWindowVisitor& visit) {
    for (std::size_t i = 0; i < snap.windows; ++i) {
      const int err = read_all(fd_, x.data(), window_bytes(), i * window_bytes());
      if (err != 0) {
        throw Error("field training: reading window " + std::to_string(i) + " back from the spill file in " +
                    cfg_.spill_dir.string() + " failed: " + std::strerror(err));
      }
      visit(i, x);
    }
  };
  dsp::Baseline b;
  try {
    b = dsp::train_baseline_streamed(index, cfg_.window_len, pass, cfg_.classes, cfg_.thresholds, cfg_.fs_hz,
                                     cfg_.gearbox);
  } catch (const Error& e) {
    const std::string what = e.what();
    throw Error(what.rfind("field training: ", 0) == 0 ? what : "field training: " + what);
  }
  b.source = cfg_.source + ": " + summary;
  formats::write_baseline(path, b);
  return b;
}

TrainingCarryOver FieldTrainer::take_over(const FieldTrainer& previous) {
  TrainingCarryOver r;
  const Snapshot old = previous.published();
  const FieldTrainerConfig& pc = previous.cfg_;
  if (pc.window_len != cfg_.window_len) {
    r.why =
        "window_len " + std::to_string(pc.window_len) + " -> " + std::to_string(cfg_.window_len) + " samples";
  } else if (std::fabs(pc.fs_hz - cfg_.fs_hz) > 1e-9 * std::max(pc.fs_hz, cfg_.fs_hz)) {
    r.why = "sample rate " + fmt_speed(pc.fs_hz) + " -> " + fmt_speed(cfg_.fs_hz) + " Hz";
  }
  if (!r.why.empty()) {
    r.windows_lost = old.windows;
    r.regions_lost = old.regions;
    return r;
  }
  const int shared = ::fcntl(previous.fd_, F_DUPFD_CLOEXEC, 0);
  if (shared < 0) {
    throw Error("field training: cannot share the spill file with the reloaded pipeline: " +
                std::string(std::strerror(errno)));
  }
  ::close(fd_);
  fd_ = shared;
  cfg_.spill_dir = pc.spill_dir;  // the file stays where it was created: a reload cannot move it
  r.kept = true;
  r.windows = std::min<std::uint64_t>(old.windows, cfg_.max_windows);
  r.regions = std::min<std::uint64_t>(old.regions, cfg_.max_regions);
  r.windows_lost = old.windows - r.windows;
  r.regions_lost = old.regions - r.regions;
  std::copy_n(previous.refs_.begin(), static_cast<std::ptrdiff_t>(r.windows), refs_.begin());
  std::copy_n(previous.regions_.begin(), static_cast<std::ptrdiff_t>(r.regions), regions_.begin());
  // The new slicer numbers regions and samples from 0 again: continue after the copied ones.
  std::uint64_t next_seq = previous.region_seq_offset_;
  std::int64_t next_sample = previous.sample_offset_;
  for (std::uint64_t i = 0; i < old.windows; ++i) {
    next_seq = std::max(next_seq, previous.refs_[i].region_seq + 1);
    next_sample = std::max(next_sample, previous.refs_[i].first_sample + std::int64_t{cfg_.window_len});
  }
  for (std::uint64_t i = 0; i < old.regions; ++i) next_seq = std::max(next_seq, previous.regions_[i].seq + 1);
  region_seq_offset_ = next_seq;
  sample_offset_ = next_sample;
  const FieldTrainerCounters c = previous.counters();
  windows_.set(r.windows);
  regions_added_.set(r.regions);
  taken_ = r.windows;
  queue_full_.set(c.windows_queue_full);
  write_failed_.set(c.windows_write_failed);
  last_write_errno_.store(c.last_write_errno, std::memory_order_relaxed);
  windows_dropped_.set(c.windows_dropped - c.windows_queue_full - c.windows_write_failed + r.windows_lost);
  regions_dropped_.set(c.regions_dropped + r.regions_lost);
  windows_rejected_.set(c.windows_rejected);
  window_count_.store(r.windows, std::memory_order_release);
  region_count_.store(r.regions, std::memory_order_release);
  return r;
}

FieldTrainerCounters FieldTrainer::counters() const noexcept {
  FieldTrainerCounters c;
  c.windows = windows_.get();
  c.regions = regions_added_.get();
  c.windows_queue_full = queue_full_.get();
  c.windows_write_failed = write_failed_.get();
  c.windows_dropped = windows_dropped_.get() + c.windows_queue_full + c.windows_write_failed;
  c.last_write_errno = last_write_errno_.load(std::memory_order_relaxed);
  c.regions_dropped = regions_dropped_.get();
  c.windows_rejected = windows_rejected_.get();
  return c;
}

}  // namespace ptda::daemon
