// Health features of a residual (paper section 3.4).
#pragma once

#include <complex>
#include <span>

namespace ptda::dsp {

/// eq. 14: sqrt(mean(r^2)); 0 for an empty span. Accumulates in double.
/// Thread: any. Never allocates or blocks.
[[nodiscard]] double rms(std::span<const float> r) noexcept;

/// eqs. 15-16 on the one-sided spectrum R[k] = residual_spectrum[k] of a real residual (k = 0..N/2 as from
/// RealFft): SR[k] = |R[k]|^2 / sum |R|^2 over bins k = 1..N/2 (DC left out: an accelerometer's DC is offset
/// and gravity, not vibration), entropy = -sum SR ln SR (natural log), divided by ln(N/2) so the result is in
/// [0, 1] whatever the window length (1 = flat white spectrum, 0 = a single tone). Returns 0 for an all-zero
/// spectrum or fewer than 3 bins, NaN when R holds a non-finite value. Thread: any. Never allocates or
/// blocks.
[[nodiscard]] double spectral_entropy(std::span<const std::complex<float>> residual_spectrum) noexcept;

}  // namespace ptda::dsp
