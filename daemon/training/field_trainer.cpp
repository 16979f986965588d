#include "training/field_trainer.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "ptda/common/error.hpp"
#include "ptda/formats/baseline_file.hpp"

namespace ptda::daemon {
namespace {

constexpr std::uint64_t kMaxPoolBytes = std::uint64_t{2} << 30;

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
  if (bytes > kMaxPoolBytes) {
    throw Error("training.max_windows: " + std::to_string(cfg.max_windows) + " windows of " +
                std::to_string(cfg.window_len) + " samples need " + std::to_string(bytes >> 20) +
                " MiB, more than the 2048 MiB limit");
  }
  samples_.assign(static_cast<std::size_t>(cfg.max_windows) * cfg.window_len, 0.0F);
  refs_.assign(cfg.max_windows, dsp::WindowRef{});
  regions_.assign(cfg.max_regions, dsp::RegionInfo{});
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
  const std::uint64_t n = window_count_.load(std::memory_order_relaxed);  // single writer
  if (n >= cfg_.max_windows) {
    windows_dropped_.add();
    return false;
  }
  std::copy(samples.begin(), samples.end(),
            samples_.begin() + static_cast<std::ptrdiff_t>(n * cfg_.window_len));
  refs_[n] = ref;
  refs_[n].region_seq += region_seq_offset_;
  refs_[n].first_sample += sample_offset_;
  window_count_.store(n + 1, std::memory_order_release);
  windows_.add();
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
  p.windows_dropped = windows_dropped_.get();
  p.regions_dropped = regions_dropped_.get();
  p.windows_rejected = windows_rejected_.get();

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

  // The pooled entries [0, count) are immutable once published: copy them.
  const Snapshot snap{p.windows, p.regions};
  dsp::CollectedWindows data;
  data.refs.assign(refs_.begin(), refs_.begin() + static_cast<std::ptrdiff_t>(snap.windows));
  data.regions.assign(regions_.begin(), regions_.begin() + static_cast<std::ptrdiff_t>(snap.regions));
  data.windows.reserve(snap.windows);
  for (std::size_t i = 0; i < snap.windows; ++i) {
    const auto first = samples_.begin() + static_cast<std::ptrdiff_t>(i * cfg_.window_len);
    data.windows.emplace_back(first, first + cfg_.window_len);
  }
  dsp::Baseline b;
  try {
    b = dsp::train_baseline(data, cfg_.classes, cfg_.thresholds, cfg_.fs_hz, cfg_.gearbox);
  } catch (const Error& e) {
    throw Error(std::string("field training: ") + e.what());
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
  r.kept = true;
  r.windows = std::min<std::uint64_t>(old.windows, cfg_.max_windows);
  r.regions = std::min<std::uint64_t>(old.regions, cfg_.max_regions);
  r.windows_lost = old.windows - r.windows;
  r.regions_lost = old.regions - r.regions;
  std::copy_n(previous.samples_.begin(), static_cast<std::ptrdiff_t>(r.windows * cfg_.window_len),
              samples_.begin());
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
  windows_dropped_.set(c.windows_dropped + r.windows_lost);
  regions_dropped_.set(c.regions_dropped + r.regions_lost);
  windows_rejected_.set(c.windows_rejected);
  window_count_.store(r.windows, std::memory_order_release);
  region_count_.store(r.regions, std::memory_order_release);
  return r;
}

void FieldTrainer::reset() noexcept {
  window_count_.store(0, std::memory_order_release);
  region_count_.store(0, std::memory_order_release);
  windows_.set(0);
  regions_added_.set(0);
  windows_dropped_.set(0);
  regions_dropped_.set(0);
  windows_rejected_.set(0);
}

FieldTrainerCounters FieldTrainer::counters() const noexcept {
  return {windows_.get(), regions_added_.get(), windows_dropped_.get(), regions_dropped_.get(),
          windows_rejected_.get()};
}

}  // namespace ptda::daemon
