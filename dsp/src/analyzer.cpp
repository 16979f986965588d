// Per-window residuals: raw, TDA (eq. 5) and PTDA (eqs. 8-9 / 12-13), then features (eqs. 14-16).
#include "ptda/dsp/analyzer.hpp"

#include <Eigen/Core>
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>

#include "ptda/dsp/features.hpp"

namespace ptda::dsp {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Level referral absorbs level changes up to this factor (6 dB) either way; beyond it the excess counts,
// so a vibration four times the training level still raises rms_res (docs/method.md §2, "Floor gain").
constexpr double kLevelAllowance = 2.0;

double referral(double gain) noexcept {
  if (!(gain > 0.0) || !std::isfinite(gain)) return 1.0;
  return 1.0 / std::clamp(gain, 1.0 / kLevelAllowance, kLevelAllowance);
}

// select_nth()'s bucket of a value: 2^7 buckets per octave over [2^-8, 2^8) (the bits of a positive
// double are in the order of its value; 7 mantissa bits below the exponent), bucket 0 for everything
// below (negative values, zero, small values, a NaN with the sign bit), the last bucket for everything
// above (infinity, NaN). Monotone in the value for non-NaN values.
constexpr int kSelectShift = 45;
constexpr std::uint64_t kSelectLowBits = 0x3F70000000000000ULL;  // 2^-8
std::size_t select_bucket(double x) noexcept {
  const auto bits = std::bit_cast<std::uint64_t>(x);
  const auto rel = static_cast<std::int64_t>(bits >> kSelectShift) -
                   static_cast<std::int64_t>(kSelectLowBits >> kSelectShift) + 1;
  // A negative value has the sign bit set: its bits are above every positive value's; map it to 0.
  const std::int64_t neg = -static_cast<std::int64_t>(bits >> 63);  // all ones when negative
  const std::int64_t clamped = std::clamp<std::int64_t>(rel & ~neg, 0, kSelectBuckets - 1);
  return static_cast<std::size_t>(clamped);
}

using ArrayMap = Eigen::Map<Eigen::ArrayXf>;
using ConstArrayMap = Eigen::Map<const Eigen::ArrayXf>;

// Sum of n floats in double with four independent accumulators (the adds do not wait on each other;
// one double chain would be latency-bound).
double sum_f64(const float* v, std::size_t n) noexcept {
  double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0;
  std::size_t i = 0;
  for (; i + 4 <= n; i += 4) {
    s0 += static_cast<double>(v[i]);
    s1 += static_cast<double>(v[i + 1]);
    s2 += static_cast<double>(v[i + 2]);
    s3 += static_cast<double>(v[i + 3]);
  }
  for (; i < n; ++i) s0 += static_cast<double>(v[i]);
  return (s0 + s1) + (s2 + s3);
}

// e[k] = |z[k]|^2 in float. A complex<float> is an array of two floats ([complex.numbers]).
void energies(const std::complex<float>* z, float* e, std::size_t n) noexcept {
  const auto* f = reinterpret_cast<const float*>(z);
  for (std::size_t k = 0; k < n; ++k) e[k] = f[2 * k] * f[2 * k] + f[2 * k + 1] * f[2 * k + 1];
}

// e[k] = |a[k] - b[k]|^2 in float.
void difference_energies(const std::complex<float>* a, const std::complex<float>* b, float* e,
                         std::size_t n) noexcept {
  const auto* fa = reinterpret_cast<const float*>(a);
  const auto* fb = reinterpret_cast<const float*>(b);
  for (std::size_t k = 0; k < n; ++k) {
    const float re = fa[2 * k] - fb[2 * k];
    const float im = fa[2 * k + 1] - fb[2 * k + 1];
    e[k] = re * re + im * im;
  }
}

// The float logarithm of Eigen 3.4's plog_impl_float (Cephes: frexp, a shift to [sqrt(1/2), sqrt(2)),
// a degree-8 polynomial) for a normal positive float, operation by operation in the same order, without
// fused multiply-adds (pmadd is a multiply and an add on SSE and AVX2 without FMA), so it returns the
// same bits as Eigen's SSE packet log. Written as plain float code so the compiler vectorises the loop
// for the widest unit at hand (p_log_p_kernel's target clones).
inline float cephes_log(float v) noexcept {
  const auto bits = std::bit_cast<std::uint32_t>(v);
  float e = static_cast<float>(static_cast<std::int32_t>(bits >> 23) - 126);
  float x = std::bit_cast<float>((bits & 0x807FFFFFU) | 0x3F000000U);  // in [0.5, 1)
  // Branch-free masks (what the packet code does; a conditional would keep the loop scalar).
  const std::uint32_t below = 0U - static_cast<std::uint32_t>(x < 0.707106781186547524F);
  const float tmp = std::bit_cast<float>(std::bit_cast<std::uint32_t>(x) & below);
  x = x - 1.0F;
  e = e - std::bit_cast<float>(std::bit_cast<std::uint32_t>(1.0F) & below);
  x = x + tmp;
  const float x2 = x * x;
  const float x3 = x2 * x;
  float y = 7.0376836292E-2F * x + -1.1514610310E-1F;
  float y1 = -1.2420140846E-1F * x + +1.4249322787E-1F;
  float y2 = +2.0000714765E-1F * x + -2.4999993993E-1F;
  y = y * x + 1.1676998740E-1F;
  y1 = y1 * x + -1.6668057665E-1F;
  y2 = y2 * x + +3.3333331174E-1F;
  y = y * x3 + y1;
  y = y * x3 + y2;
  y = y * x3;
  y = -0.5F * x2 + y;
  x = x + y;
  return e * static_cast<float>(0.693147180559945309417232121458176568L) + x;
}

}  // namespace

// Loops compiled twice on x86-64 (SSE2 and AVX2, chosen at load time by the CPU; AVX2 without FMA, so
// both give the same bits: no multiply-add is fused) and vectorised by GCC's dynamic cost model
// (dsp/CMakeLists.txt). They have external linkage (target_clones needs it) but no header.
// Not under ThreadSanitizer: GCC instruments the clone's IFUNC resolver, which the dynamic loader runs
// during relocation, before the TSan runtime is up, so every binary linking the DSP crashed at load.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(__SANITIZE_THREAD__)
#define PTDA_SIMD_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define PTDA_SIMD_CLONES
#endif

// The floor gain's last pass over the bins k = 1..N/2 (out of line, for the vectoriser): a floor bin
// (in_line[k] == 0) gets res[k] = |X[k]| - g a[k] (in double, as a float) and refer[k] = floor_refer,
// a group bin keeps both; e[k] = (res[k] refer[k])^2.
PTDA_SIMD_CLONES
void floor_residual_energies(const float* mag, const float* a, const std::uint32_t* in_line, double gain,
                             float floor_refer, float* res, float* refer, float* e, std::size_t n) noexcept {
  for (std::size_t k = 1; k < n; ++k) {
    const std::uint32_t keep = 0U - static_cast<std::uint32_t>(in_line[k] != 0U);
    const auto floor_res = static_cast<float>(static_cast<double>(mag[k]) - gain * a[k]);
    const float r = std::bit_cast<float>((std::bit_cast<std::uint32_t>(res[k]) & keep) |
                                         (std::bit_cast<std::uint32_t>(floor_res) & ~keep));
    const float f = std::bit_cast<float>((std::bit_cast<std::uint32_t>(refer[k]) & keep) |
                                         (std::bit_cast<std::uint32_t>(floor_refer) & ~keep));
    res[k] = r;
    refer[k] = f;
    e[k] = (r * f) * (r * f);
  }
}

// bucket[k], k = 1..n-1: select_bucket()'s bucket of the float quotient mag[k] / a[k] (7 mantissa bits
// below the exponent: bits >> 16; 2^-8 is 0x3B800000; monotone in the value for non-NaN floats) for a
// floor bin (in_line[k] == 0 and a[k] > 0), kSelectBuckets (one past the histogram) for any other bin.
PTDA_SIMD_CLONES
void floor_buckets(const float* mag, const float* a, const std::uint32_t* in_line, std::uint16_t* bucket,
                   std::size_t n) noexcept {
  for (std::size_t k = 1; k < n; ++k) {
    const auto bits = std::bit_cast<std::uint32_t>(mag[k] / a[k]);
    std::int32_t rel =
        static_cast<std::int32_t>(bits >> 16) - static_cast<std::int32_t>(0x3B800000U >> 16) + 1;
    rel &= ~(-static_cast<std::int32_t>(bits >> 31));  // sign bit (a NaN with it): bucket 0
    rel = std::max(rel, 0);
    rel = std::min(rel, static_cast<std::int32_t>(kSelectBuckets - 1));
    const std::uint32_t other =
        0U - (static_cast<std::uint32_t>(in_line[k] != 0U) | static_cast<std::uint32_t>(!(a[k] > 0.0F)));
    bucket[k] = static_cast<std::uint16_t>((static_cast<std::uint32_t>(rel) & ~other) |
                                           (static_cast<std::uint32_t>(kSelectBuckets) & other));
  }
}

#if defined(__x86_64__)
// The loop of p_log_p() on x86-64.
PTDA_SIMD_CLONES
void p_log_p_kernel(const float* e, float scale, float* out, std::size_t n) noexcept {
  constexpr float kMinNormal = std::numeric_limits<float>::min();
  for (std::size_t k = 0; k < n; ++k) {
    const float p = e[k] * scale;
    // max(p, FLT_MIN) without a branch: p < FLT_MIN selects FLT_MIN's bits.
    const std::uint32_t small = 0U - static_cast<std::uint32_t>(p < kMinNormal);
    const std::uint32_t clamped =
        (std::bit_cast<std::uint32_t>(p) & ~small) | (std::bit_cast<std::uint32_t>(kMinNormal) & small);
    out[k] = p * cephes_log(std::bit_cast<float>(clamped));
  }
}
#endif

void p_log_p(std::span<const float> e, float scale, std::span<float> out) noexcept {
  const std::size_t n = std::min(e.size(), out.size());
#if defined(__x86_64__)
  // Eigen's array log ran its packet log on whole packets of 4 and std::log on the remainder.
  const std::size_t packets = n - n % 4;
  p_log_p_kernel(e.data(), scale, out.data(), packets);
  for (std::size_t k = packets; k < n; ++k) {
    const float p = e[k] * scale;
    out[k] = p * std::log(std::max(p, std::numeric_limits<float>::min()));
  }
#else
  // Elsewhere (NEON) Eigen's packet log fuses its multiply-adds, which the plain code above would
  // only match as far as the compiler's contraction does: keep Eigen's expression itself.
  const ConstArrayMap ev(e.data(), static_cast<Eigen::Index>(n));
  ArrayMap plnp(out.data(), static_cast<Eigen::Index>(n));
  plnp = (ev * scale) * (ev * scale).max(std::numeric_limits<float>::min()).log();
#endif
}

WindowAnalyzer::WindowAnalyzer(std::size_t n)
    : n_(n),
      inv_log_half_(n >= 4 ? 1.0 / std::log(static_cast<double>(n / 2)) : 0.0),
      fft_(n),
      X_(n / 2 + 1),
      M_(n / 2 + 1),
      mag_(n / 2 + 1, 0.0F),
      res_(n / 2 + 1, 0.0F),
      refer_(n / 2 + 1, 1.0F),
      ratio_(n / 2 + 1, 0.0),
      select_scratch_(n / 2 + 1, 0.0),
      select_histogram_(2 * (kSelectBuckets + 1), 0U),
      floor_bucket_(n / 2 + 1, 0U),
      in_line_(n / 2 + 1, 0U),
      e_(n / 2 + 1, 0.0F),
      scratch_(n / 2 + 1, 0.0F),
      d_(n, 0.0F),
      r_(n, 0.0F),
      D_(n / 2 + 1),
      R_(n / 2 + 1) {}

bool WindowAnalyzer::transform(std::span<const float> x) noexcept {
  if (x.size() != n_) return false;
  fft_.forward(x, X_);
  return true;
}

// Features of the residual whose one-sided energies |R[k]|^2, k = 0..N/2, are in e_ (N even):
//   sum_n r[n]^2 = (1/N) (|R[0]|^2 + 2 sum_{k=1}^{N/2-1} |R[k]|^2 + |R[N/2]|^2)      (Parseval)
//   entropy = -sum p ln p / ln(N/2), p[k] = |R[k]|^2 / sum_{k=1}^{N/2} |R[k]|^2       (spectral_entropy())
Features WindowAnalyzer::features_from_energy() noexcept {
  const std::size_t half = n_ / 2;
  const float* e = e_.data();
  const double mid = sum_f64(e + 1, half - 1);
  const double total = mid + static_cast<double>(e[half]);
  const double sum_sq =
      (static_cast<double>(e[0]) + 2.0 * mid + static_cast<double>(e[half])) / static_cast<double>(n_);
  Features f;
  f.rms_res = std::sqrt(sum_sq / static_cast<double>(n_));
  if (total == 0.0) {
    f.entropy_res = 0.0;
  } else if (!std::isfinite(total)) {
    f.entropy_res = kNaN;
  } else if (total > 1e-30 && total < 1e30) {
    // p in float (1 / total is a normal float here); p ln p with Eigen's vectorised log. p below the
    // smallest normal float is clamped inside the log only: its term is < 1.2e-38 * 88 either way.
    const auto inv_total = static_cast<float>(1.0 / total);
    p_log_p(std::span<const float>(e + 1, half), inv_total, std::span<float>(scratch_.data(), half));
    f.entropy_res = -sum_f64(scratch_.data(), half) * inv_log_half_;
  } else {
    // Extreme scales (never a real accelerometer): the reference definition in double.
    double h = 0.0;
    for (std::size_t k = 1; k <= half; ++k) {
      const double p = static_cast<double>(e[k]) / total;
      if (p > 0.0) h -= p * std::log(p);
    }
    f.entropy_res = h * inv_log_half_;
  }
  return f;
}

Features WindowAnalyzer::raw_features() noexcept {
  energies(X_.data(), e_.data(), X_.size());
  return features_from_energy();
}

Features WindowAnalyzer::tda_features(const std::complex<float>* tda_spectrum) noexcept {
  // R = DFT(x - d) = X - DFT(d): the transform is linear.
  difference_energies(X_.data(), tda_spectrum, e_.data(), X_.size());
  return features_from_energy();
}

Features WindowAnalyzer::ptda_features(std::span<const float> mean_magnitude,
                                       std::span<const LineGroup> line_groups, bool floor_gain) noexcept {
  // D[k] = |D[k]| e^{j theta_x[k]} has the phase of X[k], so R[k] = X[k] - D[k] = (|X[k]| - |D[k]|)
  // e^{j theta_x[k]}: |R[k]| = | |X[k]| - |D[k]| |. A zero bin takes phase 0: R[k] = -|D[k]|, the same
  // magnitude. No inverse transform, no second forward transform.
  const auto bins = static_cast<Eigen::Index>(X_.size());
  energies(X_.data(), e_.data(), X_.size());
  ArrayMap mag(mag_.data(), bins);
  ArrayMap res(res_.data(), bins);
  ArrayMap e(e_.data(), bins);
  const ConstArrayMap a(mean_magnitude.data(), bins);
  mag = e.sqrt();
  floor_gain_ = 1.0;
  if (floor_gain) {
    // Every bin k >= 1 gets its residual and referral from a group or from the floor below.
    res_[0] = mag_[0] - mean_magnitude[0];
    refer_[0] = 1.0F;
  } else {
    res = mag - a;
  }
  for (const LineGroup& g : line_groups) {
    const std::size_t lo = std::max<std::size_t>(g.begin, 1);
    const std::size_t hi = std::min<std::size_t>(g.end, X_.size());
    double num = 0.0;
    double den = 0.0;
    for (std::size_t k = lo; k < hi; ++k) {
      num += static_cast<double>(mean_magnitude[k]) * mag_[k];
      den += static_cast<double>(mean_magnitude[k]) * mean_magnitude[k];
    }
    const double gain = den > 0.0 ? num / den : 1.0;
    for (std::size_t k = lo; k < hi; ++k) {
      res_[k] = static_cast<float>(static_cast<double>(mag_[k]) - gain * mean_magnitude[k]);
    }
    if (floor_gain) {
      const auto r = static_cast<float>(referral(gain));
      for (std::size_t k = lo; k < hi; ++k) refer_[k] = r;
    }
  }
  if (!floor_gain) {
    e = res.square();
    return features_from_energy();
  }
  // Floor gain (docs/method.md §2): the median of |X[k]| / a[k] over the bins k >= 1 outside every
  // group. The median, not a least-squares gain: a defect's sidebands and impact combs fill a minority
  // of the floor bins and must not be absorbed into the floor level.
  std::fill(in_line_.begin(), in_line_.end(), 0U);
  for (const LineGroup& g : line_groups) {
    const std::size_t hi = std::min<std::size_t>(g.end, X_.size());
    for (std::size_t k = g.begin; k < hi; ++k) in_line_[k] = 1U;
  }
  const double mid = floor_median(mean_magnitude);
  if (mid > 0.0 && std::isfinite(mid)) floor_gain_ = mid;
  const auto floor_refer = static_cast<float>(referral(floor_gain_));
  // res_ stays the physical residual (the views rebuild D from it); the features are those of the
  // level-referred one: each part divided by its own gain, within the allowance. One pass, the group
  // bins kept by a mask (no branch, so it vectorises).
  floor_pass(mean_magnitude.data(), floor_gain_, floor_refer);
  e_[0] = (res_[0] * refer_[0]) * (res_[0] * refer_[0]);
  return features_from_energy();
}

void WindowAnalyzer::floor_pass(const float* mean_magnitude, double gain, float floor_refer) noexcept {
  floor_residual_energies(mag_.data(), mean_magnitude, in_line_.data(), gain, floor_refer, res_.data(),
                          refer_.data(), e_.data(), X_.size());
}

// The median (rank m / 2 of m) of the double ratios q[k] = |X[k]| / a[k] over the floor bins (k >= 1,
// outside every group, a[k] > 0); NaN when there are none. The histogram select of select_nth() fused
// with the bin loop, on the float quotient: round-to-float is monotone in the exact quotient, and so is
// the double one, so a bucket of the float quotients holds a contiguous run of the double ratios in
// sorted order. A vectorised pass gives every bin its bucket, a second counts them, then the double
// ratios are computed for the bins of the median's bucket only. A NaN or a median outside [2^-8, 2^8): the
// double ratios of every floor bin and select_nth() (whose fallback is std::nth_element), as before.
double WindowAnalyzer::floor_median(std::span<const float> a) noexcept {
  const std::size_t bins = X_.size();
  std::uint16_t* const bucket = floor_bucket_.data();
  floor_buckets(mag_.data(), a.data(), in_line_.data(), bucket, bins);
  // Two histograms (even and odd bins), so that neighbouring bins of one bucket do not wait on each
  // other's increment; the last entry of each counts the bins that are not floor bins.
  std::uint32_t* const h0 = select_histogram_.data();
  std::uint32_t* const h1 = h0 + kSelectBuckets + 1;
  std::fill(h0, h0 + 2 * (kSelectBuckets + 1), 0U);
  std::size_t k = 1;
  for (; k + 1 < bins; k += 2) {
    ++h0[bucket[k]];
    ++h1[bucket[k + 1]];
  }
  for (; k < bins; ++k) ++h0[bucket[k]];
  const std::size_t m = bins - 1 - h0[kSelectBuckets] - h1[kSelectBuckets];
  if (m == 0) return kNaN;
  const std::size_t rank = m / 2;
  std::size_t below = 0;
  std::size_t b = 0;
  // Terminates: the counts of buckets 0..kSelectBuckets-1 add up to m > rank.
  while (below + h0[b] + h1[b] <= rank) {
    below += h0[b] + h1[b];
    ++b;
  }
  constexpr std::size_t kLast = kSelectBuckets - 1;
  bool edge = b == 0 || b == kLast;
  if (!edge && (h0[0] + h1[0] + h0[kLast] + h1[kLast]) != 0) {
    for (std::size_t j = 1; j < bins; ++j)
      edge = edge || (bucket[j] != kSelectBuckets && std::isnan(mag_[j]));
  }
  if (edge) {
    std::size_t i = 0;
    for (std::size_t j = 1; j < bins; ++j) {
      if (in_line_[j] == 0U && a[j] > 0.0F) ratio_[i++] = static_cast<double>(mag_[j]) / a[j];
    }
    return select_nth(std::span<double>(ratio_.data(), m), rank, select_scratch_,
                      std::span<std::uint32_t>(h0, kSelectBuckets));
  }
  double* const cand = select_scratch_.data();
  std::size_t c = 0;
  // The median's bucket holds a small share of the bins: 16 buckets are compared at once (an OR over a
  // fixed-length inner loop, which the compiler vectorises) and only a block with a match is walked.
  const auto want = static_cast<std::uint16_t>(b);
  constexpr std::size_t kScan = 16;
  for (std::size_t j = 1; j < bins; j += kScan) {
    const std::size_t end = std::min(j + kScan, bins);
    if (end - j == kScan) {  // a whole block (the last, shorter one is always walked)
      unsigned any = 0;
      for (std::size_t t = 0; t < kScan; ++t) any |= static_cast<unsigned>(bucket[j + t] == want);
      if (any == 0) continue;
    }
    for (std::size_t t = j; t < end; ++t) {
      if (bucket[t] == want) cand[c++] = static_cast<double>(mag_[t]) / a[t];
    }
  }
  std::nth_element(cand, cand + (rank - below), cand + c);
  return cand[rank - below];
}

Features WindowAnalyzer::analyze(std::span<const float> x, const ClassBaseline& cls, Method method) noexcept {
  if (method == Method::kTda && cls.tda_spectrum.size() == n_ / 2 + 1 && cls.tda_mean.size() == n_ &&
      x.size() == n_) {
    transform(x);
    last_ = Last::kTda;
    last_x_ = x;
    last_tda_mean_ = cls.tda_mean;
    last_tda_spectrum_ = cls.tda_spectrum.data();
    views_ready_ = false;
    return tda_features(cls.tda_spectrum.data());
  }
  return analyze_with(x, cls.mean_magnitude, cls.tda_mean, method, cls.line_groups, cls.floor_gain);
}

Features WindowAnalyzer::analyze_with(std::span<const float> x, std::span<const float> mean_magnitude,
                                      std::span<const float> tda_mean, Method method,
                                      std::span<const LineGroup> line_groups, bool floor_gain) noexcept {
  const std::size_t bins = n_ / 2 + 1;
  // Cheap guard: a size mismatch is a caller bug, but on a real-time path it must not become UB.
  // NaN features are never inside a band, so such a window is judged abnormal, never silently normal.
  const bool sizes_ok =
      x.size() == n_ && (method == Method::kRaw || (method == Method::kTda && tda_mean.size() == n_) ||
                         (method == Method::kPtda && mean_magnitude.size() == bins));
  last_ = Last::kNone;
  views_ready_ = true;
  if (!sizes_ok) return Features{kNaN, kNaN};

  transform(x);
  last_x_ = x;
  views_ready_ = false;
  switch (method) {
    case Method::kRaw:
      last_ = Last::kRaw;
      return raw_features();
    case Method::kTda:
      fft_.forward(tda_mean, M_);
      last_ = Last::kTda;
      last_tda_mean_ = tda_mean;
      last_tda_spectrum_ = M_.data();
      return tda_features(M_.data());
    case Method::kPtda:
      last_ = Last::kPtda;
      return ptda_features(mean_magnitude, line_groups, floor_gain);
  }
  return Features{kNaN, kNaN};
}

void WindowAnalyzer::analyze_all(std::span<const float> x, std::span<const float> mean_magnitude,
                                 std::span<const std::complex<float>> tda_spectrum,
                                 std::span<const LineGroup> line_groups,
                                 std::array<Features, kMethodCount>& out, bool reuse_spectrum,
                                 bool floor_gain) noexcept {
  const std::size_t bins = n_ / 2 + 1;
  out.fill(Features{kNaN, kNaN});
  last_ = Last::kNone;
  views_ready_ = true;
  if (x.size() != n_) return;
  if (!reuse_spectrum) transform(x);
  last_x_ = x;
  out[static_cast<std::size_t>(Method::kRaw)] = raw_features();
  if (tda_spectrum.size() == bins)
    out[static_cast<std::size_t>(Method::kTda)] = tda_features(tda_spectrum.data());
  if (mean_magnitude.size() == bins) {
    out[static_cast<std::size_t>(Method::kPtda)] = ptda_features(mean_magnitude, line_groups, floor_gain);
    last_ = Last::kPtda;
    views_ready_ = false;
  }
}

void WindowAnalyzer::build_views() const noexcept {
  if (views_ready_) return;
  views_ready_ = true;
  const std::size_t bins = X_.size();
  switch (last_) {
    case Last::kNone:
      return;
    case Last::kRaw:
      std::fill(d_.begin(), d_.end(), 0.0F);
      std::copy(last_x_.begin(), last_x_.end(), r_.begin());
      std::copy(X_.begin(), X_.end(), R_.begin());
      return;
    case Last::kTda:
      for (std::size_t n = 0; n < n_; ++n) {
        d_[n] = last_tda_mean_[n];
        r_[n] = last_x_[n] - last_tda_mean_[n];
      }
      for (std::size_t k = 0; k < bins; ++k) R_[k] = X_[k] - last_tda_spectrum_[k];
      return;
    case Last::kPtda:
      for (std::size_t k = 0; k < bins; ++k) {
        // D[k] = |D[k]| e^{j theta_x[k]} with |D[k]| = |X[k]| - res[k]; a zero bin has phase 0.
        const double mag = mag_[k];
        const double dmag = mag - static_cast<double>(res_[k]);
        if (mag > 0.0) {
          D_[k] = {static_cast<float>(dmag * X_[k].real() / mag),
                   static_cast<float>(dmag * X_[k].imag() / mag)};
        } else {
          D_[k] = {static_cast<float>(dmag), 0.0F};
        }
        R_[k] = X_[k] - D_[k];
      }
      fft_.inverse(D_, d_);
      for (std::size_t n = 0; n < n_; ++n) r_[n] = last_x_[n] - d_[n];
      return;
  }
}

std::span<const float> WindowAnalyzer::deterministic() const noexcept {
  build_views();
  return d_;
}

std::span<const float> WindowAnalyzer::residual() const noexcept {
  build_views();
  return r_;
}

std::span<const std::complex<float>> WindowAnalyzer::residual_spectrum() const noexcept {
  build_views();
  return R_;
}

double select_nth(std::span<double> values, std::size_t rank, std::span<double> candidates,
                  std::span<std::uint32_t> histogram) noexcept {
  const std::size_t m = values.size();
  double* const v = values.data();
  const auto fallback = [&]() noexcept {
    std::nth_element(v, v + rank, v + m);
    return v[rank];
  };
  if (rank >= m) return kNaN;
  if (m < kSelectMinValues || candidates.size() < m || histogram.size() < kSelectBuckets) return fallback();
  // Pass 1: a histogram of the buckets (128 per octave from 2^-8 to 2^8; everything else, NaN included,
  // lands in the first or the last bucket).
  std::uint32_t* const hist = histogram.data();
  std::fill(hist, hist + kSelectBuckets, 0U);
  for (std::size_t i = 0; i < m; ++i) ++hist[select_bucket(v[i])];
  if (hist[0] != 0 || hist[kSelectBuckets - 1] != 0) {
    // A NaN has no order: std::nth_element decides (what the analyzer has always returned then).
    for (std::size_t i = 0; i < m; ++i) {
      if (std::isnan(v[i])) return fallback();
    }
  }
  std::size_t below = 0;
  std::size_t b = 0;
  while (below + hist[b] <= rank) below += hist[b++];        // terminates: the counts add up to m > rank
  if (b == 0 || b == kSelectBuckets - 1) return fallback();  // outside the bucketed range
  // Pass 2: gather the values of bucket b (the store is unconditional, the index moves only for a
  // candidate: no branch to mispredict). Every value of a lower bucket is smaller than each of them,
  // every value of a higher bucket larger.
  double* const cand = candidates.data();
  std::size_t c = 0;
  for (std::size_t i = 0; i < m; ++i) {
    const double x = v[i];
    cand[c] = x;
    c += static_cast<std::size_t>(select_bucket(x) == b);
  }
  std::nth_element(cand, cand + (rank - below), cand + c);
  return cand[rank - below];
}

float local_floor_median(std::span<const float> a, std::size_t k, std::vector<float>& scratch) {
  constexpr std::size_t kHalf = 32;  // 65 bins around k
  const std::size_t lo = k > kHalf + 1 ? k - kHalf : 1;
  const std::size_t hi = std::min(a.size(), k + kHalf + 1);
  scratch.assign(a.begin() + static_cast<std::ptrdiff_t>(lo), a.begin() + static_cast<std::ptrdiff_t>(hi));
  const auto mid = scratch.begin() + static_cast<std::ptrdiff_t>(scratch.size() / 2);
  std::nth_element(scratch.begin(), mid, scratch.end());
  return *mid;
}

std::vector<float> local_floor_medians(std::span<const float> a) {
  const std::size_t bins = a.size();
  std::vector<float> out(bins, 0.0F);
  if (bins < 2) return out;
  if (std::any_of(a.begin(), a.end(), [](float x) { return std::isnan(x); })) {
    std::vector<float> scratch;
    for (std::size_t k = 1; k < bins; ++k) out[k] = local_floor_median(a, k, scratch);
    return out;
  }
  // The window of bin k is [lo(k), hi(k)) with lo = max(1, k - 32) and hi = min(bins, k + 33) (as in
  // local_floor_median); both bounds move by at most one bin per step, so the sorted copy of the
  // window loses at most one value and gains at most one.
  constexpr std::size_t kHalf = 32;
  std::vector<float> win;
  win.reserve(2 * kHalf + 2);
  std::size_t lo = 1;
  std::size_t hi = 1;
  for (std::size_t k = 1; k < bins; ++k) {
    const std::size_t new_lo = k > kHalf + 1 ? k - kHalf : 1;
    const std::size_t new_hi = std::min(bins, k + kHalf + 1);
    // In the middle of the spectrum one value leaves and one enters: one shift of the values between
    // the two places instead of an erase and an insert (each moving the tail of the window).
    if (lo + 1 == new_lo && hi + 1 == new_hi && !win.empty()) {
      const float gone = a[lo++];
      const float come = a[hi++];
      auto at = std::lower_bound(win.begin(), win.end(), gone);
      if (come >= gone) {
        auto end = std::upper_bound(at, win.end(), come);
        std::move(at + 1, end, at);
        *(end - 1) = come;
      } else {
        auto begin = std::upper_bound(win.begin(), at, come);
        std::move_backward(begin, at, at + 1);
        *begin = come;
      }
    }
    for (; lo < new_lo; ++lo) win.erase(std::lower_bound(win.begin(), win.end(), a[lo]));
    for (; hi < new_hi; ++hi) win.insert(std::upper_bound(win.begin(), win.end(), a[hi]), a[hi]);
    out[k] = win[win.size() / 2];
  }
  return out;
}

std::vector<LineGroup> find_line_groups(std::span<const float> mean_magnitude) {
  if (mean_magnitude.size() < 3) return {};
  return find_line_groups(mean_magnitude, local_floor_medians(mean_magnitude));
}

std::vector<LineGroup> find_line_groups(std::span<const float> mean_magnitude, std::span<const float> floor) {
  std::vector<LineGroup> out;
  const std::size_t bins = mean_magnitude.size();
  if (bins < 3 || floor.size() != bins) return out;
  constexpr double kLineOverFloor = 4.0;  // 12 dB over the local floor (median of 65 bins around k)
  std::vector<bool> line(bins, false);
  for (std::size_t k = 1; k < bins; ++k) {
    line[k] = static_cast<double>(mean_magnitude[k]) > kLineOverFloor * static_cast<double>(floor[k]);
  }
  for (std::size_t k = 1; k < bins; ++k) {
    if (!line[k]) continue;
    std::size_t e = k;
    while (e < bins && line[e]) ++e;
    const auto begin = static_cast<std::uint32_t>(std::max<std::size_t>(1, k - 1));
    const auto end = static_cast<std::uint32_t>(std::min(bins, e + 1));
    if (!out.empty() && begin <= out.back().end) {
      out.back().end = end;
    } else {
      out.push_back(LineGroup{begin, end});
    }
    k = e;
  }
  return out;
}

namespace {

// Fingerprint of the inputs of prepare_line_groups() for one class: a multiply-xorshift mix over the
// bytes of both vectors (their sizes included) and the two flags; never 0.
std::uint64_t prepare_key(const ClassBaseline& c, bool line_gain, bool floor_gain) noexcept {
  std::uint64_t h = 0x9E3779B97F4A7C15ULL ^ (line_gain ? 1U : 0U) ^ (floor_gain ? 2U : 0U);
  const auto mix = [&h](std::uint64_t w) noexcept {
    h = (h ^ w) * 0xBF58476D1CE4E5B9ULL;
    h ^= h >> 31;
  };
  for (const std::vector<float>* v : {&c.mean_magnitude, &c.tda_mean}) {
    mix(v->size());
    const auto* bytes = reinterpret_cast<const unsigned char*>(v->data());
    const std::size_t n = v->size() * sizeof(float);
    std::size_t i = 0;
    for (; i + 8 <= n; i += 8) {
      std::uint64_t w = 0;
      std::memcpy(&w, bytes + i, 8);
      mix(w);
    }
    if (i < n) {
      std::uint64_t w = 0;
      std::memcpy(&w, bytes + i, n - i);
      mix(w);
    }
  }
  return h == 0 ? 1 : h;
}

}  // namespace

void prepare_line_groups(Baseline& baseline) {
  std::optional<RealFft> fft;  // one plan for every class of the same length (its twiddles cost)
  for (ClassBaseline& c : baseline.classes) {
    const std::uint64_t key = prepare_key(c, baseline.policy.ptda_line_gain, baseline.policy.ptda_floor_gain);
    if (c.prepared_key == key) continue;  // derived from these very inputs already
    c.prepared_key = key;
    c.floor_gain = baseline.policy.ptda_floor_gain;
    if (baseline.policy.ptda_line_gain) {
      c.line_groups = find_line_groups(c.mean_magnitude);
    } else {
      c.line_groups.clear();
    }
    c.tda_spectrum.clear();
    if (RealFft::supported_length(c.tda_mean.size())) {
      if (!fft || fft->size() != c.tda_mean.size()) fft.emplace(c.tda_mean.size());
      c.tda_spectrum.resize(fft->bins());
      fft->forward(c.tda_mean, c.tda_spectrum);
    }
  }
}

void WindowAnalyzer::magnitude(std::span<const float> x, std::span<float> mag) noexcept {
  const std::size_t bins = n_ / 2 + 1;
  if (x.size() != n_ || mag.size() != bins) {
    for (float& m : mag) m = std::numeric_limits<float>::quiet_NaN();
    return;
  }
  fft_.forward(x, X_);
  for (std::size_t k = 0; k < bins; ++k) {
    const double re = X_[k].real();
    const double im = X_[k].imag();
    mag[k] = static_cast<float>(std::sqrt(re * re + im * im));
  }
}

}  // namespace ptda::dsp
