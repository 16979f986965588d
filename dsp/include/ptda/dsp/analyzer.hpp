// Per-window path: deterministic part, residual and features of one window against its class
// baseline. Everything is allocated in the constructor; analyze() is allocation-free and
// deterministic, so the daemon's processing thread and `ptda monitor` give identical numbers.
#pragma once

#include <array>
#include <complex>
#include <cstddef>
#include <cstdint>
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
  /// Features: rms(r) and spectral_entropy(R) with R = DFT(r), computed from one forward transform X
  /// of x (docs/method.md section 7): R[k] = X[k] - D[k] in the spectrum (for PTDA |R[k]| =
  /// ||X[k]| - |D[k]||, same phase), rms by Parseval, the entropy from |R[k]|^2 with a vectorised float
  /// log (fast_log_error()). They agree with the time-domain definitions within 1e-6 relative
  /// (tests/golden/one_fft_test.cpp). TDA uses cls.tda_spectrum when it is sized N/2+1
  /// (prepare_line_groups() fills it), else one more transform of cls.tda_mean. Thread: the owner's (one
  /// analyzer per thread). Never allocates, throws or blocks.
  Features analyze(std::span<const float> x, const ClassBaseline& cls, Method method) noexcept;

  /// Like analyze() but with an explicit mean magnitude / TDA mean (used for leave-one-out training).
  /// line_groups (PTDA only; empty = the paper's PTDA): each group's deterministic magnitude is the
  /// mean magnitude times the window's own least-squares gain g = sum(a |X|) / sum(a^2) over the
  /// group, so D[k] = g a[k] e^{j theta_x[k]}. Groups outside [1, N/2] are ignored. TDA transforms
  /// tda_mean (two forward transforms).
  /// floor_gain (PTDA only): every bin k >= 1 outside the groups gets D[k] = g_f a[k] e^{j theta_x[k]}
  /// with g_f the median of |X[k]| / a[k] over those bins (a[k] > 0), and both features are those of
  /// the level-referred residual spectrum: R[k] divided by the gain of its part (its group's g, or g_f;
  /// DC by 1) clamped to [1/2, 2] (level changes beyond 6 dB count), rms_res by Parseval. The views
  /// (residual(), residual_spectrum()) stay the physical residual. g_f that is not > 0 (a dead
  /// channel) is taken as 1, so a silent sensor still shows as a low residual.
  /// Same size rule, thread and allocation contract as analyze().
  Features analyze_with(std::span<const float> x, std::span<const float> mean_magnitude,
                        std::span<const float> tda_mean, Method method,
                        std::span<const LineGroup> line_groups = {}, bool floor_gain = false) noexcept;

  /// The one-sided energies |R[k]|^2, k = 0..N/2, of the residual whose features the last analyze*()
  /// call returned (PTDA with floor gain: the level-referred residual), for the band CUSUM
  /// (band_energy.hpp). Valid until the next call. Thread: the owner's. Never allocates.
  [[nodiscard]] std::span<const float> residual_energy() const noexcept { return e_; }

  /// The floor gain g_f of the last PTDA window analysed with floor_gain (1 otherwise).
  [[nodiscard]] double floor_gain() const noexcept { return floor_gain_; }

  /// All three methods from one forward transform of x (training): out[Method] = the features
  /// analyze_with() gives, with the TDA mean given by its spectrum tda_spectrum = DFT(tda_mean)
  /// (N/2+1 bins). reuse_spectrum: x is the window of the last magnitude() call, whose transform is
  /// reused (no transform at all). floor_gain: as analyze_with(). Size mismatches give NaN features for
  /// the methods they concern. The time-domain views below then describe PTDA. Thread: the owner's.
  /// Never allocates or blocks.
  void analyze_all(std::span<const float> x, std::span<const float> mean_magnitude,
                   std::span<const std::complex<float>> tda_spectrum, std::span<const LineGroup> line_groups,
                   std::array<Features, kMethodCount>& out, bool reuse_spectrum = false,
                   bool floor_gain = false) noexcept;

  /// Views of the last analyze() call, for reports and tests. deterministic(), residual() and
  /// residual_spectrum() are built on first access after the call (PTDA: one inverse transform), from
  /// the spectrum and the inputs of that call, which must still be alive and unchanged. Valid until the
  /// next call. Thread: the owner's. Never allocate or block.
  [[nodiscard]] std::span<const float> deterministic() const noexcept;
  [[nodiscard]] std::span<const float> residual() const noexcept;
  [[nodiscard]] std::span<const std::complex<float>> spectrum() const noexcept { return X_; }
  [[nodiscard]] std::span<const std::complex<float>> residual_spectrum() const noexcept;

  /// |DFT| of x into mag (bins = N/2+1), used by training (eq. 7). On a size mismatch mag is filled
  /// with NaN. Overwrites spectrum(). Thread: the owner's. Never allocates or blocks.
  void magnitude(std::span<const float> x, std::span<float> mag) noexcept;

  /// Error bound of the vectorised natural log the entropy uses (Eigen's float log, a Cephes
  /// polynomial): |log(p) - ln p| <= fast_log_error() * max(1, |ln p|) for the normal floats p in (0, 1]
  /// (tests/unit/dsp/analyzer_test.cpp measures it). The entropy -sum p ln p therefore carries at most
  /// this relative error from the log. Thread: any.
  [[nodiscard]] static constexpr double fast_log_error() noexcept { return 2.5e-7; }

 private:
  enum class Last : std::uint8_t { kNone, kRaw, kTda, kPtda };

  std::size_t n_;
  double inv_log_half_;                          ///< 1 / ln(N/2): the entropy's normalisation
  mutable RealFft fft_;                          ///< mutable: the lazy views run the inverse transform
  std::vector<std::complex<float>> X_;           ///< DFT of the last window
  std::vector<std::complex<float>> M_;           ///< DFT of tda_mean when the caller has no spectrum for it
  std::vector<float> mag_;                       ///< |X[k]|
  std::vector<float> res_;                       ///< PTDA: |R[k]| with sign, |X[k]| - |D[k]|
  std::vector<float> refer_;                     ///< floor gain: 1 / the (clamped) gain of bin k's part
  std::vector<double> ratio_;                    ///< floor gain scratch: |X[k]| / a[k] over the floor bins
  std::vector<double> select_scratch_;           ///< select_nth()'s candidates
  std::vector<std::uint32_t> select_histogram_;  ///< floor_median()'s two histograms, select_nth()'s
  std::vector<std::uint16_t> floor_bucket_;      ///< floor_median(): each bin's bucket
  std::vector<std::uint32_t> in_line_;           ///< floor gain scratch: bin k lies in a line group
  double floor_gain_ = 1.0;
  std::vector<float> e_;        ///< |R[k]|^2
  std::vector<float> scratch_;  ///< p ln p of the entropy
  // Inputs of the last call (for the lazy views) and the views themselves.
  Last last_ = Last::kNone;
  std::span<const float> last_x_;
  std::span<const float> last_tda_mean_;
  const std::complex<float>* last_tda_spectrum_ = nullptr;
  mutable bool views_ready_ = true;
  mutable std::vector<float> d_, r_;
  mutable std::vector<std::complex<float>> D_, R_;

  bool transform(std::span<const float> x) noexcept;
  Features raw_features() noexcept;
  Features tda_features(const std::complex<float>* tda_spectrum) noexcept;
  Features ptda_features(std::span<const float> mean_magnitude, std::span<const LineGroup> line_groups,
                         bool floor_gain) noexcept;
  Features features_from_energy() noexcept;
  double floor_median(std::span<const float> mean_magnitude) noexcept;
  void floor_pass(const float* mean_magnitude, double gain, float floor_refer) noexcept;
  void build_views() const noexcept;
};

/// out[k] = p ln p with p = e[k] * scale, for k < min(e.size(), out.size()): the entropy's terms.
/// ln is Eigen 3.4's float packet log (Cephes, relative error about 1e-7 for p in [FLT_MIN, 1]) with the
/// same bits, vectorised by the compiler (AVX2 when the CPU has it); p below FLT_MIN is clamped inside
/// the log only. The last n % 4 terms use std::log (as Eigen's array log did). On x86-64 a plain
/// auto-vectorised loop (SSE2 or AVX2 by the CPU); elsewhere Eigen's array log itself (NEON fuses the
/// multiply-adds). For finite e >= 0 with
/// p <= 1. Thread: any. Never allocates.
void p_log_p(std::span<const float> e, float scale, std::span<float> out) noexcept;

/// Buckets of select_nth()'s histogram (the size its `histogram` scratch needs).
inline constexpr std::size_t kSelectBuckets = 2048;
/// Below this many values select_nth() is std::nth_element.
inline constexpr std::size_t kSelectMinValues = 256;

/// The value of rank `rank` (0-based) in ascending order of `values`: what
/// `std::nth_element(values.begin(), values.begin() + rank, values.end())` leaves at that position
/// (the same value; only a zero may come back as -0.0 instead of +0.0 or the reverse). A histogram
/// select: one pass counts the values per bucket (128 buckets per octave of the value over
/// [2^-8, 2^8), from the bits of the double), a second gathers the values of the bucket that holds the
/// rank into `candidates`, and only those are selected. Fast when the values are positive and spread
/// around 1 (the floor gain's ratios |X[k]| / a[k]); exact for any input. A NaN (no order), a rank in
/// the first or the last bucket (values outside the range), fewer than kSelectMinValues values, or too
/// little scratch (candidates.size() < values.size(), histogram.size() < kSelectBuckets) fall back to
/// std::nth_element on `values` itself. rank >= values.size() gives NaN. `values` is reordered only by
/// the fallback. Thread: any. Never allocates.
[[nodiscard]] double select_nth(std::span<double> values, std::size_t rank, std::span<double> candidates,
                                std::span<std::uint32_t> histogram) noexcept;

/// The spectral lines of a healthy mean magnitude spectrum a[k], k = 0..N/2: bins above 4 times
/// (12 dB) the local floor (the median of a over the 65 bins centred on k, clipped to 1..N/2), each
/// run of such bins widened by one bin on both sides (the leakage skirt of a line between bins), runs
/// that touch merged. Bin 0 (DC) is never part of a line. Deterministic. Thread: any. Allocates.
[[nodiscard]] std::vector<LineGroup> find_line_groups(std::span<const float> mean_magnitude);
/// find_line_groups() with the local floor given (`floor` = local_floor_medians(mean_magnitude)), for a
/// caller that needs the floor too; empty when the sizes differ. Thread: any. Allocates.
[[nodiscard]] std::vector<LineGroup> find_line_groups(std::span<const float> mean_magnitude,
                                                      std::span<const float> floor);

/// The local floor of bin k (1 <= k < a.size()) that find_line_groups() compares lines with: the median
/// of a over the up to 65 bins centred on k (bins 1..a.size() - 1). `scratch` is reused between calls.
/// Thread: any. Allocates only when scratch grows (setup and training, never per window).
[[nodiscard]] float local_floor_median(std::span<const float> a, std::size_t k, std::vector<float>& scratch);

/// local_floor_median(a, k) of every bin at once: out[0] = 0 (DC has no floor), out[k] for 1 <= k <
/// a.size() the same value local_floor_median() returns (compared with ==; for a NaN in a, the per-bin
/// function is called for every bin). One sorted window of at most 65 values slides over a, one
/// removal and one insertion per bin, instead of one std::nth_element per bin (about 30x less at
/// N/2 = 6400 bins). Thread: any. Allocates (setup and training, never per window).
[[nodiscard]] std::vector<float> local_floor_medians(std::span<const float> a);

/// Fills every class's line_groups from its mean_magnitude when baseline.policy.ptda_line_gain is
/// set, and clears them otherwise; and every class's tda_spectrum = DFT(tda_mean) (left empty when
/// the length is not a RealFft length). Called by training and by the baseline reader. Thread: any.
/// Allocates.
void prepare_line_groups(Baseline& baseline);

}  // namespace ptda::dsp
