// Per-window path: deterministic part, residual and features of one window against its class
// baseline. Everything is allocated in the constructor; analyze() is allocation-free and
// deterministic, so the daemon's processing thread and `ptda monitor` give identical numbers.
#pragma once

#include <complex>
#include <cstddef>
#include <span>
#include <vector>

#include "ptda/dsp/baseline.hpp"
#include "ptda/dsp/real_fft.hpp"
#include "ptda/dsp/types.hpp"

namespace ptda::dsp {

class WindowAnalyzer {
 public:
  /// Thread: any (setup). Allocates. Throws ptda::Error when n is not a RealFft length.
  explicit WindowAnalyzer(std::size_t n);

  [[nodiscard]] std::size_t size() const noexcept { return n_; }

  /// Residual r = x - d and its features, with d by `method`:
  ///   raw : d = 0
  ///   tda : d = cls.tda_mean                                      (eq. 5)
  ///   ptda: d = IDFT(|D_avg[k]| e^{j theta_x[k]})                 (eqs. 8-9, 12-13)
  /// x.size() must equal size(); the cls vector the method uses must be sized for size()
  /// (tda_mean: N, mean_magnitude: N/2+1). On a size mismatch nothing is computed and both features
  /// are NaN (NaN is outside every band, so such a window counts as abnormal, never as healthy).
  /// Features: rms(r) and spectral_entropy(R) with R = FFT(r). Thread: the owner's (one analyzer per
  /// thread). Never allocates, throws or blocks.
  Features analyze(std::span<const float> x, const ClassBaseline& cls, Method method) noexcept;

  /// Like analyze() but with an explicit mean magnitude / TDA mean (used for leave-one-out training).
  /// line_groups (PTDA only; empty = the paper's PTDA): each group's deterministic magnitude is the
  /// mean magnitude times the window's own least-squares gain g = sum(a |X|) / sum(a^2) over the
  /// group, so D[k] = g a[k] e^{j theta_x[k]}. Groups outside [1, N/2] are ignored.
  /// floor_gain (PTDA only): every bin k >= 1 outside the groups gets D[k] = g_f a[k] e^{j theta_x[k]}
  /// with g_f the median of |X[k]| / a[k] over those bins (a[k] > 0), and both features are those of
  /// the level-referred residual spectrum: R[k] divided by the gain of its part (its group's g, or g_f;
  /// DC by 1) clamped to [1/2, 2] (level changes beyond 6 dB count), rms_res by Parseval. residual() stays
  /// the physical residual; residual_spectrum() is the referred one. g_f that is not > 0 (a dead channel) is
  /// taken as 1, so a silent sensor still shows as a low residual. Same size rule, thread and allocation
  /// contract as analyze().
  Features analyze_with(std::span<const float> x, std::span<const float> mean_magnitude,
                        std::span<const float> tda_mean, Method method,
                        std::span<const LineGroup> line_groups = {}, bool floor_gain = false) noexcept;

  /// The floor gain g_f of the last PTDA window analysed with floor_gain (1 otherwise).
  [[nodiscard]] double floor_gain() const noexcept { return floor_gain_; }

  /// Buffers of the last analyze() call (valid until the next call), for reports and tests.
  [[nodiscard]] std::span<const float> deterministic() const noexcept { return d_; }
  [[nodiscard]] std::span<const float> residual() const noexcept { return r_; }
  [[nodiscard]] std::span<const std::complex<float>> spectrum() const noexcept { return X_; }
  [[nodiscard]] std::span<const std::complex<float>> residual_spectrum() const noexcept { return R_; }

  /// |DFT| of x into mag (bins = N/2+1), used by training (eq. 7). On a size mismatch mag is filled
  /// with NaN. Overwrites spectrum(). Thread: the owner's. Never allocates or blocks.
  void magnitude(std::span<const float> x, std::span<float> mag) noexcept;

 private:
  std::size_t n_;
  RealFft fft_;
  std::vector<float> d_, r_;
  std::vector<double> mag_;             ///< |X[k]| of the last PTDA window
  std::vector<double> ratio_;           ///< floor-gain scratch: |X[k]| / a[k] over the floor bins
  std::vector<unsigned char> in_line_;  ///< floor-gain scratch: bin k lies in a line group
  std::vector<double> refer_;           ///< floor gain: 1 / the gain of bin k's part (group or floor)
  double floor_gain_ = 1.0;
  std::vector<std::complex<float>> X_, D_, R_;
};

/// The spectral lines of a healthy mean magnitude spectrum a[k], k = 0..N/2: bins above 4 times
/// (12 dB) the local floor (the median of a over the 65 bins centred on k, clipped to 1..N/2), each
/// run of such bins widened by one bin on both sides (the leakage skirt of a line between bins), runs
/// that touch merged. Bin 0 (DC) is never part of a line. Deterministic. Thread: any. Allocates.
[[nodiscard]] std::vector<LineGroup> find_line_groups(std::span<const float> mean_magnitude);

/// Fills every class's line_groups from its mean_magnitude when baseline.policy.ptda_line_gain is
/// set, and clears them otherwise. Called by training and by the baseline reader. Thread: any.
/// Allocates.
void prepare_line_groups(Baseline& baseline);

}  // namespace ptda::dsp
