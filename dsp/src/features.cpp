// Health features of a residual (paper eqs. 14-16). Accumulation in double: a window holds up to
// tens of thousands of samples, and float sums would lose the small residual energies.
#include "ptda/dsp/features.hpp"

#include <cmath>

namespace ptda::dsp {

double rms(std::span<const float> r) noexcept {
  if (r.empty()) return 0.0;
  double sum_sq = 0.0;
  for (const float v : r) sum_sq += static_cast<double>(v) * static_cast<double>(v);
  return std::sqrt(sum_sq / static_cast<double>(r.size()));
}

double spectral_entropy(std::span<const std::complex<float>> residual_spectrum) noexcept {
  // Bins 1..N/2 of a one-sided spectrum with N/2 + 1 bins; fewer than 2 bins has no spread to measure.
  if (residual_spectrum.size() < 3) return 0.0;
  const std::size_t half = residual_spectrum.size() - 1;
  double total = 0.0;
  for (std::size_t k = 1; k <= half; ++k) total += static_cast<double>(std::norm(residual_spectrum[k]));
  if (total == 0.0) return 0.0;
  if (!std::isfinite(total)) return std::nan("");
  double h = 0.0;
  for (std::size_t k = 1; k <= half; ++k) {
    const double p = static_cast<double>(std::norm(residual_spectrum[k])) / total;
    if (p > 0.0) h -= p * std::log(p);
  }
  return h / std::log(static_cast<double>(half));
}

}  // namespace ptda::dsp
