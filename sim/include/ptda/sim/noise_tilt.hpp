// Spectral tilt of the background noise ([vibration] noise_tilt_db_per_decade): Gaussian noise whose
// power spectral density changes by a constant number of dB per decade of frequency. Real floors are
// not white (the GFD rig's rises by about 11-14 dB per decade, docs/gap.md), and the gap diagnosis
// calibrates this slope with the level (docs/gap.md, step 4).
#pragma once

#include <complex>
#include <cstddef>
#include <vector>

#include "ptda/dsp/real_fft.hpp"
#include "ptda/sim/random.hpp"

namespace ptda::sim {

/// Frequency where the tilted floor keeps the white floor's density (noise_rms): the geometric centre of
/// the band range the gap probes use, sqrt(20 Hz * 0.45 fs), so that a slope change leaves the median
/// band level where it was. Any thread; no allocation.
[[nodiscard]] double noise_tilt_pivot_hz(double fs_hz) noexcept;

/// Tilted Gaussian noise, unit density at the pivot. Made in the frequency domain, so the power law is
/// exact and not an approximation by sections: blocks of B samples (a power of two >= fs / 4, so bins
/// are <= 4 Hz wide) get a Gaussian spectrum times (f / pivot)^(tilt / 20) (flat below 10 Hz), are
/// transformed back, weighted by a sine window and overlap-added at hop B/2 (sin^2 + cos^2 = 1: the
/// variance is the same at every sample). Draws B normals from the caller's Rng per B/2 samples.
/// One instance per signal; not thread-safe. Allocates at construction only.
class TiltedNoise {
 public:
  static constexpr double kMaxTiltDbPerDecade = 18.0;

  /// |tilt| must be <= kMaxTiltDbPerDecade and fs > 0 (the scenario reader checks both).
  TiltedNoise(double tilt_db_per_decade, double fs_hz);
  /// With a known floor shape on top of the tilt ([vibration] noise_shape_hz/_db, same length, increasing
  /// frequencies; the scenario reader checks): the gain at f is also multiplied by 10^((S(f) - S(pivot)) /
  /// 20), S interpolated linearly in log f and flat beyond the ends.
  TiltedNoise(double tilt_db_per_decade, double fs_hz, std::vector<double> shape_hz,
              std::vector<double> shape_db);

  /// The next sample (unit density at the pivot). No allocation.
  double next(Rng& rng) noexcept;
  /// The amplitude gain the shaping applies at f_hz (1 at the pivot). Any thread; no allocation.
  [[nodiscard]] double gain_at(double f_hz) const noexcept;
  [[nodiscard]] std::size_t block() const noexcept { return n_; }

 private:
  void refill(Rng& rng) noexcept;  // one new block: out_ = tail_ + head of the block

  [[nodiscard]] double shape_db(double f_hz) const noexcept;
  double tilt_;
  double fs_hz_;
  std::vector<double> shape_hz_;
  std::vector<double> shape_db_;
  std::size_t n_;
  dsp::RealFft fft_;
  std::vector<float> gain_;  // per bin
  std::vector<float> window_;
  std::vector<std::complex<float>> spec_;
  std::vector<float> block_;
  std::vector<float> tail_;  // second half of the previous windowed block
  std::vector<float> out_;   // the samples being handed out
  std::size_t pos_ = 0;
  bool primed_ = false;
};

}  // namespace ptda::sim
