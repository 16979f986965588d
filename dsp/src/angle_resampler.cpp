// Angle-domain resampling: cubic Hermite angle law between CAN frames, anti-alias convolution in the
// angle domain (docs/method.md §9).
#include "ptda/dsp/angle_resampler.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include "ptda/common/error.hpp"

namespace ptda::dsp {

namespace {

constexpr double kKaiserBeta = 7.857;     // 0.1102 (A - 8.7) for A = 80 dB (Kaiser's formula)
constexpr double kKaiserWidth = 2.51;     // (A - 7.95) / 14.36 / 2: transition = kKaiserWidth / Q cycles
constexpr std::size_t kTableStep = 1024;  // kernel table entries per output sample

double bessel_i0(double x) noexcept {
  double sum = 1.0;
  double term = 1.0;
  for (int k = 1; k < 200; ++k) {
    const double f = x / (2.0 * k);
    term *= f * f;
    sum += term;
    if (term < 1e-17 * sum) break;
  }
  return sum;
}

[[noreturn]] void bad(const std::string& key, const std::string& what) {
  throw Error("angle_resampler." + key + " " + what);
}

}  // namespace

double AngleResampler::pass_order_of(const AngleResamplerConfig& cfg) noexcept {
  const double half_width = kKaiserWidth / static_cast<double>(cfg.half_taps) / 2.0;
  return (cfg.cutoff / 2.0 - half_width) * static_cast<double>(cfg.samples_per_rev);
}

AngleResampler::AngleResampler(const AngleResamplerConfig& cfg, double fs_hz, std::int64_t t0_ns)
    : cfg_(cfg), fs_hz_(fs_hz), t0_ns_(t0_ns), latency_ns_(std::llround(cfg.speed_latency_s * 1e9)) {
  const std::uint32_t s = cfg.samples_per_rev;
  if (s < 16 || s % 2 != 0) bad("samples_per_rev", "must be even and >= 16 (got " + std::to_string(s) + ")");
  if (!(cfg.ratio > 0.0) || !std::isfinite(cfg.ratio)) bad("ratio", "must be > 0");
  if (cfg.half_taps < 4 || cfg.half_taps > 256) bad("half_taps", "must be in [4, 256]");
  if (!(cfg.cutoff > 0.0 && cfg.cutoff < 1.0)) bad("cutoff", "must be in (0, 1)");
  if (!(fs_hz > 0.0) || !std::isfinite(fs_hz)) bad("fs_hz", "must be > 0");
  if (!(cfg.max_speed_gap_s > 0.0) || !(cfg.max_lead_s > 0.0) || cfg.max_lead_s > 60.0)
    bad("max_speed_gap_s/max_lead_s", "must be > 0 (max_lead_s <= 60 s)");
  if (!std::isfinite(cfg.speed_latency_s)) bad("speed_latency_s", "must be finite");
  const double q = cfg.half_taps;
  const double half_width = kKaiserWidth / q / 2.0;  // half the transition band, cycles per sample
  pass_order_ = (cfg.cutoff / 2.0 - half_width) * s;
  stop_order_ = (cfg.cutoff / 2.0 + half_width) * s;
  if (pass_order_ <= 0.0 || stop_order_ >= 0.5 * s * 1.2)
    bad("half_taps", "too small for cutoff " + std::to_string(cfg.cutoff) + ": transition band does not fit");
  max_shaft_hz_ = fs_hz / (2.0 * stop_order_);
  if (!(cfg.min_shaft_hz > 0.0) || cfg.min_shaft_hz >= max_shaft_hz_) {
    bad("min_shaft_hz", "must be in (0, " + std::to_string(max_shaft_hz_) +
                            ") Hz: above it the kernel does not fit below fs/2 for samples_per_rev " +
                            std::to_string(s));
  }
  sigma_per_rad_ = s / (2.0 * std::numbers::pi);

  // h(u) = c sinc(c u) w(u / Q), u in output samples (the integral over u is 1).
  const std::size_t entries = cfg.half_taps * kTableStep;
  table_.assign(entries + 2, 0.0);
  const double i0b = bessel_i0(kKaiserBeta);
  for (std::size_t i = 0; i <= entries; ++i) {
    const double u = static_cast<double>(i) / kTableStep;
    const double x = u / q;
    const double w = x >= 1.0 ? 0.0 : bessel_i0(kKaiserBeta * std::sqrt(1.0 - x * x)) / i0b;
    const double a = std::numbers::pi * cfg.cutoff * u;
    const double sinc = i == 0 ? 1.0 : std::sin(a) / a;
    table_[i] = cfg.cutoff * sinc * w;
  }

  const auto lead = static_cast<std::size_t>(std::ceil((cfg.max_lead_s + cfg.max_speed_gap_s) * fs_hz));
  raw_.assign(lead + 1024, 0.0F);
  frames_.resize(static_cast<std::size_t>(std::ceil(cfg.max_lead_s * 1000.0)) + 64);
  // The kernel span at the slowest accepted speed, plus margin.
  const auto span =
      static_cast<std::size_t>(std::ceil(2.0 * (q + 2.0) * fs_hz / (s * cfg.min_shaft_hz))) + 64;
  a_sigma_.assign(span, 0.0);
  a_g_.assign(span, 0.0);
  a_t_.assign(span, 0.0);
  a_w_.assign(span, 0.0);
  out_.resize(2 * raw_.size() + 64);
}

double AngleResampler::kernel(double u) const noexcept {
  const double x = u * static_cast<double>(kTableStep);
  const auto i = static_cast<std::size_t>(x);
  if (i >= table_.size() - 1) return 0.0;
  const double f = x - static_cast<double>(i);
  return table_[i] + f * (table_[i + 1] - table_[i]);
}

void AngleResampler::push_speed(const SpeedSample& s) noexcept {
  const double t_s = static_cast<double>(s.t_ns - latency_ns_ - t0_ns_) * 1e-9;
  const double last_t = frame_count_ > 0 ? frames_[(frame_head_ + frame_count_ - 1) % frames_.size()].t_s
                                         : (have_prev_ ? prev_.t_s : -1e300);
  if (!(t_s > last_t)) {
    ++counters_.frames_out_of_order;
    return;
  }
  if (frame_count_ == frames_.size()) {
    ++counters_.frames_overflow;
    return;
  }
  ++counters_.frames;
  if (!s.has_angle) ++counters_.frames_no_angle;
  frames_[(frame_head_ + frame_count_) % frames_.size()] =
      Frame{t_s, cfg_.ratio * s.angle_rad, cfg_.ratio * s.speed_rad_s, s.has_angle};
  ++frame_count_;
  process();
}

void AngleResampler::push_samples(std::span<const float> block) noexcept {
  for (const float x : block) {
    if (raw_next_ - angled_next_ >= static_cast<std::int64_t>(raw_.size())) {
      // The speed frames lag too far: the oldest waiting sample is lost.
      ++angled_next_;
      ++counters_.samples_overrun;
      break_segment();
    }
    raw_[static_cast<std::size_t>(raw_next_ % static_cast<std::int64_t>(raw_.size()))] = x;
    ++raw_next_;
    ++counters_.samples;
  }
  process();
}

bool AngleResampler::pop(OrderSample& out) noexcept {
  if (out_count_ == 0) return false;
  out = out_[out_head_];
  out_head_ = (out_head_ + 1) % out_.size();
  --out_count_;
  return true;
}

void AngleResampler::break_segment() noexcept {
  if (in_segment_) {
    in_segment_ = false;
    ++counters_.breaks;
    ++segment_;
  }
}

void AngleResampler::start_segment() noexcept {
  in_segment_ = true;
  const double ip = std::floor(sigma_);
  seg_base_ += static_cast<std::int64_t>(ip);
  sigma_ -= ip;
  a_head_ = a_count_ = 0;
  next_k_set_ = false;
}

void AngleResampler::process() noexcept {
  const auto t_of = [this](std::int64_t n) { return static_cast<double>(n) / fs_hz_; };
  for (;;) {
    if (!have_prev_) {
      if (frame_count_ == 0) break;
      prev_ = frames_[frame_head_];
      frame_head_ = (frame_head_ + 1) % frames_.size();
      --frame_count_;
      have_prev_ = true;
      if (!prev_.has_angle) {
        have_prev_ = false;  // an origin needs an angle
        continue;
      }
    }
    while (angled_next_ < raw_next_ && t_of(angled_next_) < prev_.t_s) {
      ++angled_next_;
      ++counters_.samples_unused;
    }
    if (frame_count_ == 0) break;
    const Frame& b = frames_[frame_head_];
    angle_interval(prev_, b);
    if (t_of(raw_next_) < b.t_s) break;  // more samples of this interval to come
    // Interval complete: b starts the next one.
    sigma_ += std::abs(interval_dphi_) * sigma_per_rad_;
    if (interval_inconsistent_) ++counters_.angle_inconsistent;
    if (!interval_valid_) break_segment();
    prev_ = b;
    frame_head_ = (frame_head_ + 1) % frames_.size();
    --frame_count_;
  }
}

void AngleResampler::angle_interval(const Frame& a, const Frame& b) noexcept {
  const double h = b.t_s - a.t_s;
  const double wa = a.w_rad_s;
  const double wb = b.w_rad_s;
  const double trap = 0.5 * h * (wa + wb);
  double dphi = a.has_angle && b.has_angle ? b.phi_rad - a.phi_rad : trap;
  interval_inconsistent_ = false;
  if (a.has_angle && b.has_angle && !(std::abs(dphi - trap) <= 0.5 * std::abs(trap) + 1e-12)) {
    interval_inconsistent_ = true;
    dphi = trap;
  }
  interval_dphi_ = dphi;
  const double w_min = 2.0 * std::numbers::pi * cfg_.min_shaft_hz;
  const double w_max = 2.0 * std::numbers::pi * max_shaft_hz_;
  const double dir = wa < 0.0 ? -1.0 : 1.0;
  bool ok = a.has_angle && b.has_angle && h <= cfg_.max_speed_gap_s && std::isfinite(wa) &&
            std::isfinite(wb) && std::isfinite(dphi) && wa * wb > 0.0 && std::abs(wa) >= w_min &&
            std::abs(wb) >= w_min && std::abs(wa) <= w_max && std::abs(wb) <= w_max;
  if (ok) {
    // h dphi/du = A u^2 + B u + C must keep the sign of the motion on [0, 1] (a monotone angle).
    const double qa = 3.0 * h * wa - 6.0 * dphi + 3.0 * h * wb;
    const double qb = -4.0 * h * wa + 6.0 * dphi - 2.0 * h * wb;
    if (qa != 0.0) {
      const double u = -qb / (2.0 * qa);
      if (u > 0.0 && u < 1.0 && dir * (qa * u * u + qb * u + h * wa) <= 0.0) ok = false;
    }
  }
  interval_valid_ = ok;
  const auto t_of = [this](std::int64_t n) { return static_cast<double>(n) / fs_hz_; };
  for (; angled_next_ < raw_next_ && t_of(angled_next_) < b.t_s; ++angled_next_) {
    if (!ok) {
      ++counters_.samples_unused;
      break_segment();
      continue;
    }
    const double u = (t_of(angled_next_) - a.t_s) / h;
    angle_sample(angled_next_, u, h, dphi, wa, wb, dir);
  }
}

void AngleResampler::angle_sample(std::int64_t n, double u, double h, double dphi, double wa, double wb,
                                  double dir) noexcept {
  const float x = raw_[static_cast<std::size_t>(n % static_cast<std::int64_t>(raw_.size()))];
  if (!std::isfinite(x)) {
    ++counters_.samples_unused;
    break_segment();
    return;
  }
  if (!in_segment_ || dir_ != static_cast<std::int8_t>(dir)) {
    break_segment();
    dir_ = static_cast<std::int8_t>(dir);
    start_segment();
  }
  if (a_count_ == a_sigma_.size()) {
    // Slower than min_shaft_hz inside an interval: the kernel no longer fits; restart.
    break_segment();
    start_segment();
  }
  const double u2 = u * u;
  const double u3 = u2 * u;
  // Cubic Hermite relative to the interval start: phi(0) = 0, phi(1) = dphi, slopes h wa, h wb.
  const double p = (u3 - 2.0 * u2 + u) * h * wa + (-2.0 * u3 + 3.0 * u2) * dphi + (u3 - u2) * h * wb;
  const double dp =
      ((3.0 * u2 - 4.0 * u + 1.0) * h * wa + (-6.0 * u2 + 6.0 * u) * dphi + (3.0 * u2 - 2.0 * u) * h * wb) /
      h;
  const double speed = std::abs(dp);
  const std::size_t i = (a_head_ + a_count_) % a_sigma_.size();
  a_sigma_[i] = sigma_ + dir * p * sigma_per_rad_;
  a_g_[i] = static_cast<double>(x) * speed * sigma_per_rad_ / fs_hz_;
  a_t_[i] = static_cast<double>(n) / fs_hz_;
  a_w_[i] = speed;
  ++a_count_;
  emit();
}

void AngleResampler::emit() noexcept {
  const auto q = static_cast<double>(cfg_.half_taps);
  const std::size_t cap = a_sigma_.size();
  while (in_segment_ && a_count_ > 0) {
    if (!next_k_set_) {
      next_k_ = static_cast<std::int64_t>(std::ceil(a_sigma_[a_head_] + q));
      next_k_set_ = true;
    }
    const auto k = static_cast<double>(next_k_);
    const double newest = a_sigma_[(a_head_ + a_count_ - 1) % cap];
    if (newest < k + q) return;
    while (a_count_ > 0 && a_sigma_[a_head_] <= k - q) {
      a_head_ = (a_head_ + 1) % cap;
      --a_count_;
    }
    double y = 0.0;
    double t = a_t_[a_head_];
    double w = a_w_[a_head_];
    for (std::size_t j = 0; j < a_count_; ++j) {
      const std::size_t i = (a_head_ + j) % cap;
      const double sg = a_sigma_[i];
      if (sg >= k + q) break;
      y += a_g_[i] * kernel(std::abs(sg - k));
      if (sg <= k && j + 1 < a_count_) {
        const std::size_t i1 = (i + 1) % cap;
        const double s1 = a_sigma_[i1];
        if (s1 > k) {
          const double f = (k - sg) / (s1 - sg);
          t = a_t_[i] + f * (a_t_[i1] - a_t_[i]);
          w = a_w_[i] + f * (a_w_[i1] - a_w_[i]);
        }
      }
    }
    OrderSample o;
    o.k = seg_base_ + next_k_;
    o.segment = segment_;
    o.direction = dir_;
    o.value = static_cast<float>(y);
    o.t_ns = t0_ns_ + std::llround(t * 1e9);
    o.shaft_speed_rad_s = w;
    ++counters_.outputs;
    if (out_count_ == out_.size()) {
      ++counters_.outputs_dropped;
    } else {
      out_[(out_head_ + out_count_) % out_.size()] = o;
      ++out_count_;
    }
    ++next_k_;
  }
}

}  // namespace ptda::dsp
