// Per-window residuals: raw, TDA (eq. 5) and PTDA (eqs. 8-9 / 12-13), then features (eqs. 14-16).
#include "ptda/dsp/analyzer.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

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

}  // namespace

WindowAnalyzer::WindowAnalyzer(std::size_t n)
    : n_(n),
      fft_(n),
      d_(n, 0.0F),
      r_(n, 0.0F),
      mag_(n / 2 + 1, 0.0),
      ratio_(n / 2 + 1, 0.0),
      in_line_(n / 2 + 1, 0),
      refer_(n / 2 + 1, 1.0),
      X_(n / 2 + 1),
      D_(n / 2 + 1),
      R_(n / 2 + 1) {}

Features WindowAnalyzer::analyze(std::span<const float> x, const ClassBaseline& cls, Method method) noexcept {
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
  if (!sizes_ok) return Features{kNaN, kNaN};

  fft_.forward(x, X_);
  floor_gain_ = 1.0;
  switch (method) {
    case Method::kRaw:
      for (std::size_t n = 0; n < n_; ++n) {
        d_[n] = 0.0F;
        r_[n] = x[n];
      }
      for (std::size_t k = 0; k < bins; ++k) {
        D_[k] = {0.0F, 0.0F};
        R_[k] = X_[k];
      }
      break;
    case Method::kTda:
      for (std::size_t n = 0; n < n_; ++n) {
        d_[n] = tda_mean[n];
        r_[n] = x[n] - tda_mean[n];
      }
      fft_.forward(r_, R_);
      break;
    case Method::kPtda:
      // |X[k]| once per bin (double: the paper's PTDA stays bit-identical with or without groups); the
      // deterministic magnitude goes to d_ until the inverse transform overwrites it: the healthy mean
      // a[k], or g a[k] inside a line group.
      for (std::size_t k = 0; k < bins; ++k) {
        const double re = X_[k].real();
        const double im = X_[k].imag();
        mag_[k] = std::sqrt(re * re + im * im);
        d_[k] = mean_magnitude[k];
      }
      for (const LineGroup& g : line_groups) {
        const std::size_t lo = std::max<std::size_t>(g.begin, 1);
        const std::size_t hi = std::min<std::size_t>(g.end, bins);
        double num = 0.0;
        double den = 0.0;
        for (std::size_t k = lo; k < hi; ++k) {
          num += static_cast<double>(mean_magnitude[k]) * mag_[k];
          den += static_cast<double>(mean_magnitude[k]) * mean_magnitude[k];
        }
        const double gain = den > 0.0 ? num / den : 1.0;
        for (std::size_t k = lo; k < hi; ++k) {
          d_[k] = static_cast<float>(gain * mean_magnitude[k]);
          refer_[k] = referral(gain);
        }
      }
      if (floor_gain) {
        // The median, not a least-squares gain: sidebands and impact combs of a defect fill a minority
        // of the floor bins and must not be absorbed into the floor level.
        std::fill(in_line_.begin(), in_line_.end(), static_cast<unsigned char>(0));
        refer_[0] = 1.0;  // DC: a sensor offset, neither line nor floor
        for (const LineGroup& g : line_groups) {
          const std::size_t hi = std::min<std::size_t>(g.end, bins);
          for (std::size_t k = g.begin; k < hi; ++k) in_line_[k] = 1;
        }
        std::size_t m = 0;
        for (std::size_t k = 1; k < bins; ++k) {
          if (in_line_[k] == 0 && mean_magnitude[k] > 0.0F) ratio_[m++] = mag_[k] / mean_magnitude[k];
        }
        if (m > 0) {
          const auto mid = ratio_.begin() + static_cast<std::ptrdiff_t>(m / 2);
          std::nth_element(ratio_.begin(), mid, ratio_.begin() + static_cast<std::ptrdiff_t>(m));
          if (*mid > 0.0 && std::isfinite(*mid)) floor_gain_ = *mid;
        }
        for (std::size_t k = 1; k < bins; ++k) {
          if (in_line_[k] == 0) {
            d_[k] = static_cast<float>(floor_gain_ * mean_magnitude[k]);
            refer_[k] = referral(floor_gain_);
          }
        }
      }
      for (std::size_t k = 0; k < bins; ++k) {
        // D[k] = |D[k]| e^{j theta_x[k]}; a zero bin has no phase, take 0.
        const double mag = mag_[k];
        const double a = d_[k];
        if (mag > 0.0) {
          D_[k] = {static_cast<float>(a * X_[k].real() / mag), static_cast<float>(a * X_[k].imag() / mag)};
        } else {
          D_[k] = {static_cast<float>(a), 0.0F};
        }
      }
      fft_.inverse(D_, d_);
      for (std::size_t n = 0; n < n_; ++n) r_[n] = x[n] - d_[n];
      // The features are those of the time-domain residual r itself, so transform it.
      fft_.forward(r_, R_);
      if (floor_gain) {
        // Level referral: each part of the residual back to the level it had in training (a line
        // group's by its gain, the floor's by g_f), so a day with other levels leaves the features
        // where they were. RMS by Parseval over the referred one-sided spectrum.
        double sum_sq = 0.0;
        for (std::size_t k = 0; k < bins; ++k) {
          R_[k] *= static_cast<float>(refer_[k]);
          const double p = std::norm(R_[k]);
          sum_sq += (k == 0 || 2 * k == n_) ? p : 2.0 * p;
        }
        return Features{std::sqrt(sum_sq) / static_cast<double>(n_), spectral_entropy(R_)};
      }
      break;
  }
  return Features{rms(r_), spectral_entropy(R_)};
}

std::vector<LineGroup> find_line_groups(std::span<const float> mean_magnitude) {
  std::vector<LineGroup> out;
  const std::size_t bins = mean_magnitude.size();
  if (bins < 3) return out;
  constexpr std::size_t kHalf = 32;       // floor: median of 65 bins around k
  constexpr double kLineOverFloor = 4.0;  // 12 dB
  std::vector<float> win;
  win.reserve(2 * kHalf + 1);
  std::vector<bool> line(bins, false);
  for (std::size_t k = 1; k < bins; ++k) {
    const std::size_t lo = k > kHalf + 1 ? k - kHalf : 1;
    const std::size_t hi = std::min(bins, k + kHalf + 1);
    win.assign(mean_magnitude.begin() + static_cast<std::ptrdiff_t>(lo),
               mean_magnitude.begin() + static_cast<std::ptrdiff_t>(hi));
    const auto mid = win.begin() + static_cast<std::ptrdiff_t>(win.size() / 2);
    std::nth_element(win.begin(), mid, win.end());
    line[k] = static_cast<double>(mean_magnitude[k]) > kLineOverFloor * static_cast<double>(*mid);
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

void prepare_line_groups(Baseline& baseline) {
  for (ClassBaseline& c : baseline.classes) {
    c.floor_gain = baseline.policy.ptda_floor_gain;
    if (baseline.policy.ptda_line_gain) {
      c.line_groups = find_line_groups(c.mean_magnitude);
    } else {
      c.line_groups.clear();
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
