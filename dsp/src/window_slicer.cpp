// Constant-speed region detection and window cutting (paper section 3.1). See docs/windows.md.
#include "ptda/dsp/window_slicer.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>

#include "number_text.hpp"
#include "ptda/common/error.hpp"
#include "ptda/common/time.hpp"
#include "ptda/dsp/real_fft.hpp"

namespace ptda::dsp {
namespace {

constexpr std::int64_t kNsPerSecond = 1'000'000'000;
constexpr std::int64_t kPsPerSecondMilli = 1'000'000'000'000;  // 1e12 = ns per s * mHz per Hz
constexpr std::size_t kRunSampleCapacity = 1024;
constexpr std::size_t kRegionCapacity = 256;
constexpr double kMaxFsHz = 1e6;

std::int64_t floor_div(std::int64_t a, std::int64_t b) noexcept {  // b > 0
  std::int64_t q = a / b;
  if (a % b != 0 && a < 0) --q;
  return q;
}
std::int64_t ceil_div_nonneg(std::int64_t a, std::int64_t b) noexcept {  // a >= 0, b > 0
  return a / b + (a % b != 0 ? 1 : 0);
}

void require(bool ok, const char* key, const std::string& what) {
  if (!ok) throw Error(std::string(key) + ": " + what);
}

using detail::num;

}  // namespace

WindowSlicer::WindowSlicer(const ExtractionConfig& cfg, double fs_hz, std::int64_t t0_ns,
                           std::size_t history_len)
    : cfg_(cfg), fs_hz_(fs_hz), t0_ns_(t0_ns) {
  require(RealFft::supported_length(cfg.window_len), "extraction.window_len",
          std::to_string(cfg.window_len) +
              " is not a supported FFT length (even, >= 4, prime factors 2, 3, 5 only)");
  auto finite_nonneg = [](double v) { return std::isfinite(v) && v >= 0.0; };
  require(finite_nonneg(cfg.speed_tol_rel), "extraction.speed_tol_rel",
          "must be finite and >= 0, got " + num(cfg.speed_tol_rel));
  require(finite_nonneg(cfg.speed_tol_abs_rad_s), "extraction.speed_tol_abs_rad_s",
          "must be finite and >= 0, got " + num(cfg.speed_tol_abs_rad_s));
  require(finite_nonneg(cfg.min_speed_rad_s), "extraction.min_speed_rad_s",
          "must be finite and >= 0, got " + num(cfg.min_speed_rad_s));
  require(!std::isnan(cfg.max_speed_rad_s) && cfg.max_speed_rad_s > cfg.min_speed_rad_s,
          "extraction.max_speed_rad_s",
          "must be greater than extraction.min_speed_rad_s (" + num(cfg.min_speed_rad_s) + "), got " +
              num(cfg.max_speed_rad_s));
  require(finite_nonneg(cfg.min_duration_s), "extraction.min_duration_s",
          "must be finite and >= 0, got " + num(cfg.min_duration_s));
  require(finite_nonneg(cfg.guard_s), "extraction.guard_s",
          "must be finite and >= 0, got " + num(cfg.guard_s));
  require(std::isfinite(cfg.max_speed_gap_s) && cfg.max_speed_gap_s > 0.0, "extraction.max_speed_gap_s",
          "must be finite and > 0, got " + num(cfg.max_speed_gap_s));
  require(finite_nonneg(cfg.clip_abs), "extraction.clip_abs",
          "must be finite and >= 0 (0 = off), got " + num(cfg.clip_abs));
  require(std::isfinite(fs_hz) && fs_hz > 0.0 && fs_hz <= kMaxFsHz, "fs_hz",
          "sample rate must be in (0, 1e6] Hz, got " + num(fs_hz));
  // Sample times are computed in exact integer arithmetic from fs in millihertz, so every platform
  // cuts the same windows; a rate that is not a multiple of 1 mHz would be silently changed.
  fs_mhz_ = static_cast<std::int64_t>(std::llround(fs_hz * 1000.0));
  require(fs_mhz_ >= 1 && std::fabs(fs_hz * 1000.0 - static_cast<double>(fs_mhz_)) <= 1e-6, "fs_hz",
          "sample rate " + num(fs_hz) + " Hz is not a multiple of 0.001 Hz");

  const auto n = static_cast<std::int64_t>(cfg.window_len);
  hop_ = cfg.hop == 0 ? n : static_cast<std::int64_t>(cfg.hop);
  min_duration_ns_ = seconds_to_ns(cfg.min_duration_s);
  guard_ns_ = seconds_to_ns(cfg.guard_s);
  max_gap_ns_ = seconds_to_ns(cfg.max_speed_gap_s);
  // A run starting at t cuts its first window at first0 = ceil_index(t + guard) and closes it when the
  // speed reaches offset(first0 + n) >= t + guard + offset(n) - 1 ns, and not before t + min_duration.
  new_run_close_ns_ = std::max(min_duration_ns_, guard_ns_ + offset_ns(n) - 1);

  const std::size_t history =
      history_len == 0 ? 4 * static_cast<std::size_t>(n) + static_cast<std::size_t>(std::ceil(fs_hz))
                       : history_len;
  require(
      history >= static_cast<std::size_t>(n), "history_len",
      std::to_string(history) + " samples is shorter than extraction.window_len (" + std::to_string(n) + ")");
  history_.assign(history, 0.0F);
  history_valid_.assign(history, 0);
  run_samples_.reserve(kRunSampleCapacity);
  pending_.reserve(2 * history / static_cast<std::size_t>(hop_) + 64);
  regions_.reserve(kRegionCapacity);
}

std::int64_t WindowSlicer::ceil_index(std::int64_t d_ns) const noexcept {
  // d * F / 1e12 with d = s * 1e9 + r and s * F = a * 1000 + b: a + (b * 1e9 + r * F) / 1e12.
  const std::int64_t s = floor_div(d_ns, kNsPerSecond);
  const std::int64_t r = d_ns - s * kNsPerSecond;
  const std::int64_t sf = s * fs_mhz_;
  const std::int64_t a = floor_div(sf, 1000);
  const std::int64_t b = sf - a * 1000;
  return a + ceil_div_nonneg(b * kNsPerSecond + r * fs_mhz_, kPsPerSecondMilli);
}

std::int64_t WindowSlicer::offset_ns(std::int64_t i) const noexcept {
  // i * 1e12 / F with i = q * F + m and m * 1e9 = c * F + e: q * 1e12 + c * 1000 + e * 1000 / F.
  const std::int64_t q = floor_div(i, fs_mhz_);
  const std::int64_t m = i - q * fs_mhz_;
  const std::int64_t c = m * kNsPerSecond / fs_mhz_;
  const std::int64_t e = m * kNsPerSecond - c * fs_mhz_;
  return q * kPsPerSecondMilli + c * 1000 + ceil_div_nonneg(e * 1000, fs_mhz_);
}

bool WindowSlicer::fits(double sum_dev_rad_s, double min_rad_s, double max_rad_s,
                        std::uint32_t n) const noexcept {
  const double mean = run_.ref_rad_s + sum_dev_rad_s / static_cast<double>(n);
  const double tol = std::max(cfg_.speed_tol_rel * std::fabs(mean), cfg_.speed_tol_abs_rad_s);
  return max_rad_s - mean <= tol && mean - min_rad_s <= tol;
}

void WindowSlicer::start_run(const SpeedSample& s, std::int8_t direction) noexcept {
  run_ = Run{};
  run_.open = true;
  run_.direction = direction;
  run_.n = 1;
  run_.ref_rad_s = s.speed_rad_s;
  run_.sum_dev_rad_s = 0.0;
  run_.min_rad_s = s.speed_rad_s;
  run_.max_rad_s = s.speed_rad_s;
  run_.t_first_ns = s.t_ns;
  run_.t_last_ns = s.t_ns;
  run_samples_.clear();
  run_samples_.push(RunSample{s.t_ns, s.speed_rad_s});
}

void WindowSlicer::join_run(const SpeedSample& s) noexcept {
  ++run_.n;
  run_.sum_dev_rad_s += s.speed_rad_s - run_.ref_rad_s;
  run_.min_rad_s = std::min(run_.min_rad_s, s.speed_rad_s);
  run_.max_rad_s = std::max(run_.max_rad_s, s.speed_rad_s);
  run_.t_last_ns = s.t_ns;
  if (!run_.is_region && run_.trimmable) {
    if (run_samples_.full()) {
      run_.trimmable = false;
    } else {
      run_samples_.push(RunSample{s.t_ns, s.speed_rad_s});
    }
  }
}

// A candidate run (not yet a region: nothing was cut from it) that the new sample does not fit keeps
// its longest tail the sample fits with. Without this a run that began on the end of a ramp would
// break inside the plateau and restart late; with it the region starts within a speed period of the
// plateau. Scans from the newest sample back so the cost is linear in the run length.
bool WindowSlicer::trim_run_for(double v_rad_s) noexcept {
  const std::size_t count = run_samples_.size();
  double sum = v_rad_s - run_.ref_rad_s;
  double lo = v_rad_s;
  double hi = v_rad_s;
  std::size_t best = count;  // index of the oldest kept sample; count = none fits
  double best_sum = 0.0;
  double best_lo = 0.0;
  double best_hi = 0.0;
  for (std::size_t k = count; k-- > 1;) {  // k = 0 would keep the whole run, which did not fit
    const double v = run_samples_.at(k).speed_rad_s;
    sum += v - run_.ref_rad_s;
    lo = std::min(lo, v);
    hi = std::max(hi, v);
    if (fits(sum, lo, hi, static_cast<std::uint32_t>(count - k + 1))) {
      best = k;
      best_sum = sum - (v_rad_s - run_.ref_rad_s);
      best_lo = lo;
      best_hi = hi;
    }
  }
  if (best == count) return false;
  // best_lo / best_hi include v; join_run() folds v in again, which min/max tolerate.
  for (std::size_t k = 0; k < best; ++k) run_samples_.pop();
  run_.n = static_cast<std::uint32_t>(count - best);
  run_.sum_dev_rad_s = best_sum;
  run_.min_rad_s = best_lo;
  run_.max_rad_s = best_hi;
  run_.t_first_ns = run_samples_.front().t_ns;
  return true;
}

void WindowSlicer::end_run() noexcept {
  if (run_.open && run_.is_region) {
    if (regions_.full()) {
      regions_.pop();
      ++counters_.regions_dropped;
    }
    regions_.push(
        RegionInfo{run_.region_seq, run_.t_first_ns, run_.t_last_ns, run_.mean_rad_s(), run_.direction});
  }
  run_ = Run{};
  run_samples_.clear();
}

std::int64_t WindowSlicer::next_close_ns() const noexcept {
  const auto n = static_cast<std::int64_t>(cfg_.window_len);
  // A run that has not begun starts at a speed sample after the newest one.
  std::int64_t close = (have_last_speed_ ? last_speed_t_ns_ : t0_ns_) + 1 + new_run_close_ns_;
  // A cut window waiting for its samples closes when they arrive (speed ahead of the vibration).
  if (!pending_.empty()) close = std::min(close, pending_.front().t_end_ns);
  if (run_.open) {
    if (run_.is_region) {
      if (cfg_.max_windows_per_region == 0 || run_.windows_cut < cfg_.max_windows_per_region) {
        const std::int64_t first = run_.first_sample0 + static_cast<std::int64_t>(run_.windows_cut) * hop_;
        close = std::min(close, t0_ns_ + offset_ns(first + n));
      }
    } else {
      // As cut_windows() once the candidate becomes a region; trimming only moves t_first_ns later.
      const std::int64_t first = ceil_index(run_.t_first_ns + guard_ns_ - t0_ns_);
      close = std::min(close, std::max(t0_ns_ + offset_ns(first + n), run_.t_first_ns + min_duration_ns_));
    }
  }
  return close;
}

void WindowSlicer::cut_windows() noexcept {
  if (!run_.open) return;
  if (!run_.is_region) {
    if (run_.t_last_ns - run_.t_first_ns < min_duration_ns_) return;
    run_.is_region = true;
    run_.region_seq = counters_.regions++;
    run_.first_sample0 = ceil_index(run_.t_first_ns + guard_ns_ - t0_ns_);
    run_samples_.clear();
  }
  const auto n = static_cast<std::int64_t>(cfg_.window_len);
  while (cfg_.max_windows_per_region == 0 || run_.windows_cut < cfg_.max_windows_per_region) {
    const std::int64_t first = run_.first_sample0 + static_cast<std::int64_t>(run_.windows_cut) * hop_;
    const std::int64_t t_end = t0_ns_ + offset_ns(first + n);
    if (t_end > run_.t_last_ns) break;  // the region is not confirmed up to the window's end yet
    WindowRef ref;
    ref.seq = windows_cut_++;
    ref.region_seq = run_.region_seq;
    ref.index_in_region = run_.windows_cut;
    ref.first_sample = first;
    ref.t_start_ns = t0_ns_ + offset_ns(first);
    ref.t_end_ns = t_end;
    ref.speed_rad_s = run_.mean_rad_s();
    if (pending_.full()) {
      ++counters_.windows_overflow;
    } else {
      pending_.push(ref);
    }
    ++run_.windows_cut;
  }
}

void WindowSlicer::push_speed(const SpeedSample& s) noexcept {
  ++counters_.speed_samples;
  if (have_last_speed_ && s.t_ns <= last_speed_t_ns_) {
    ++counters_.speed_out_of_order;
    end_run();
    return;
  }
  if (have_last_speed_ && s.t_ns - last_speed_t_ns_ > max_gap_ns_ && run_.open) {
    ++counters_.speed_gaps;
    end_run();
  }
  have_last_speed_ = true;
  last_speed_t_ns_ = s.t_ns;

  const double v = s.speed_rad_s;
  const double mag = std::fabs(v);
  if (!std::isfinite(v) || mag > cfg_.max_speed_rad_s) {
    ++counters_.speed_out_of_range;
    end_run();
    return;
  }
  if (mag < cfg_.min_speed_rad_s || mag == 0.0) {  // standstill (or no direction when min_speed is 0)
    end_run();
    return;
  }
  const std::int8_t dir = v < 0.0 ? -1 : 1;
  if (!run_.open) {
    start_run(s, dir);
  } else if (dir != run_.direction) {
    end_run();
    start_run(s, dir);
  } else if (fits(run_.sum_dev_rad_s + (v - run_.ref_rad_s), std::min(run_.min_rad_s, v),
                  std::max(run_.max_rad_s, v), run_.n + 1)) {
    join_run(s);
  } else if (!run_.is_region && run_.trimmable && trim_run_for(v)) {
    join_run(s);
  } else {
    end_run();
    start_run(s, dir);
  }
  cut_windows();
}

void WindowSlicer::store_sample(float x, bool valid) noexcept {
  const auto idx = static_cast<std::size_t>(samples_total_ % static_cast<std::int64_t>(history_.size()));
  history_[idx] = x;
  history_valid_[idx] = valid ? 1 : 0;
  ++samples_total_;
}

void WindowSlicer::push_samples(std::span<const float> block) noexcept {
  // Bulk copy into the ring (at most two contiguous pieces), then one branch-free validity pass per
  // piece that the compiler vectorises: the per-sample store_sample() loop with its branches was 10 %
  // of `ptda monitor` (issue 13). A sample is invalid when it is not finite or when clip_abs > 0 and
  // |x| >= clip_abs; the counters are the same as per-sample checking gives.
  const std::size_t h = history_.size();
  std::size_t idx = static_cast<std::size_t>(samples_total_ % static_cast<std::int64_t>(h));
  const bool clip = cfg_.clip_abs > 0.0;
  const double clip_abs = cfg_.clip_abs;
  std::uint64_t nonfinite = 0;
  std::uint64_t clipped = 0;
  std::size_t done = 0;
  while (done < block.size()) {
    const std::size_t n = std::min(block.size() - done, h - idx);
    const float* const src = block.data() + done;
    std::memcpy(history_.data() + idx, src, n * sizeof(float));
    std::uint8_t* const valid = history_valid_.data() + idx;
    if (clip) {
      for (std::size_t i = 0; i < n; ++i) {
        std::uint32_t bits = 0;
        std::memcpy(&bits, src + i, sizeof bits);
        const bool bad = (bits & 0x7F800000U) == 0x7F800000U;  // Inf or NaN
        const bool big = !bad && std::fabs(static_cast<double>(src[i])) >= clip_abs;
        nonfinite += bad ? 1U : 0U;
        clipped += big ? 1U : 0U;
        valid[i] = (bad || big) ? 0 : 1;
      }
    } else {
      // bad = 1 when every exponent bit is set (Inf or NaN): the masked exponent plus one exponent
      // step carries into bit 31 exactly then. Branch-free, so it vectorises (dsp/CMakeLists.txt).
      const auto bad_bit = [](const float* x) noexcept {
        std::uint32_t bits = 0;
        std::memcpy(&bits, x, sizeof bits);
        return ((bits & 0x7F800000U) + 0x00800000U) >> 31;
      };
      std::size_t bad_count = 0;
      for (std::size_t i = 0; i < n; ++i) {
        const std::uint32_t bad = bad_bit(src + i);
        bad_count += bad;
        valid[i] = static_cast<std::uint8_t>(bad ^ 1U);
      }
      nonfinite += bad_count;
    }
    done += n;
    idx += n;
    if (idx == h) idx = 0;
  }
  counters_.samples_nonfinite += nonfinite;
  counters_.samples_clipped += clipped;
  samples_total_ += static_cast<std::int64_t>(block.size());
  counters_.samples += block.size();
}

void WindowSlicer::mark_gap(std::uint64_t count) noexcept {
  counters_.samples_missing += count;
  const std::uint64_t fill = std::min<std::uint64_t>(count, history_.size());
  samples_total_ += static_cast<std::int64_t>(count - fill);  // older ones would be overwritten anyway
  for (std::uint64_t i = 0; i < fill; ++i) store_sample(0.0F, false);
}

void WindowSlicer::finish() noexcept {
  end_run();
}

bool WindowSlicer::pop(WindowRef& ref, std::span<float> out) noexcept {
  const auto n = static_cast<std::int64_t>(cfg_.window_len);
  if (out.size() != cfg_.window_len) return false;
  const auto h = static_cast<std::int64_t>(history_.size());
  while (!pending_.empty()) {
    const WindowRef w = pending_.front();
    if (w.first_sample < 0) {  // the region began before sample 0: samples never existed
      pending_.pop();
      ++counters_.windows_invalid;
      continue;
    }
    if (w.first_sample + n > samples_total_) return false;  // samples not all here yet
    if (w.first_sample < samples_total_ - h) {
      pending_.pop();
      ++counters_.windows_lost;
      continue;
    }
    const auto start = static_cast<std::size_t>(w.first_sample % h);
    const auto len = static_cast<std::size_t>(n);
    const std::size_t first_part = std::min(len, history_.size() - start);
    // Every flag of the range is 1: no 0 byte in it. memchr is glibc's vectorised scan; a byte-wise
    // std::all_of over the 12800 flags of a window was 2.3 % of `ptda monitor` (issue 13).
    const auto valid = [&](std::size_t from, std::size_t count) {
      return count == 0 || std::memchr(history_valid_.data() + from, 0, count) == nullptr;
    };
    pending_.pop();
    if (!valid(start, first_part) || !valid(0, len - first_part)) {
      ++counters_.windows_invalid;
      continue;
    }
    std::copy_n(history_.data() + start, first_part, out.data());
    std::copy_n(history_.data(), len - first_part, out.data() + first_part);
    ref = w;
    ++counters_.windows;
    return true;
  }
  return false;
}

bool WindowSlicer::pop_region(RegionInfo& region) noexcept {
  if (regions_.empty()) return false;
  region = regions_.front();
  regions_.pop();
  return true;
}

}  // namespace ptda::dsp
