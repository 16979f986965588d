// Per-window residuals: raw, TDA (eq. 5) and PTDA (eqs. 8-9 / 12-13), then features (eqs. 14-16).
#include "ptda/dsp/analyzer.hpp"

#include <cmath>
#include <limits>

#include "ptda/dsp/features.hpp"

namespace ptda::dsp {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

}  // namespace

WindowAnalyzer::WindowAnalyzer(std::size_t n)
    : n_(n), fft_(n), d_(n, 0.0F), r_(n, 0.0F), X_(n / 2 + 1), D_(n / 2 + 1), R_(n / 2 + 1) {}

Features WindowAnalyzer::analyze(std::span<const float> x, const ClassBaseline& cls, Method method) noexcept {
  return analyze_with(x, cls.mean_magnitude, cls.tda_mean, method);
}

Features WindowAnalyzer::analyze_with(std::span<const float> x, std::span<const float> mean_magnitude,
                                      std::span<const float> tda_mean, Method method) noexcept {
  const std::size_t bins = n_ / 2 + 1;
  // Cheap guard: a size mismatch is a caller bug, but on a real-time path it must not become UB.
  // NaN features are never inside a band, so such a window is judged abnormal, never silently normal.
  const bool sizes_ok =
      x.size() == n_ && (method == Method::kRaw || (method == Method::kTda && tda_mean.size() == n_) ||
                         (method == Method::kPtda && mean_magnitude.size() == bins));
  if (!sizes_ok) return Features{kNaN, kNaN};

  fft_.forward(x, X_);
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
      for (std::size_t k = 0; k < bins; ++k) {
        // D[k] = |D_avg[k]| e^{j theta_x[k]}; a zero bin has no phase, take 0.
        const double re = X_[k].real();
        const double im = X_[k].imag();
        const double mag = std::sqrt(re * re + im * im);
        const double a = mean_magnitude[k];
        if (mag > 0.0) {
          D_[k] = {static_cast<float>(a * re / mag), static_cast<float>(a * im / mag)};
        } else {
          D_[k] = {static_cast<float>(a), 0.0F};
        }
      }
      fft_.inverse(D_, d_);
      for (std::size_t n = 0; n < n_; ++n) r_[n] = x[n] - d_[n];
      // The features are those of the time-domain residual r itself, so transform it.
      fft_.forward(r_, R_);
      break;
  }
  return Features{rms(r_), spectral_entropy(R_)};
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
