// The background noise's spectral tilt ([vibration] noise_tilt_db_per_decade, ptda/sim/noise_tilt.hpp):
// the power law of the made noise's spectrum, its variance at every sample, the pivot.
#include "ptda/sim/noise_tilt.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <numbers>
#include <vector>

#include "ptda/dsp/real_fft.hpp"
#include "ptda/sim/random.hpp"

namespace ptda::sim {
namespace {

TEST(NoiseTilt, PivotIsTheGeometricCentreOfTheProbeBands) {
  EXPECT_NEAR(noise_tilt_pivot_hz(64500.0), std::sqrt(20.0 * 0.45 * 64500.0), 1e-9);  // 761.9 Hz
  EXPECT_NEAR(noise_tilt_pivot_hz(25600.0), 480.0, 1e-9);
}

TEST(NoiseTilt, GainIsThePowerLawFlatBelowTenHertz) {
  const TiltedNoise n(8.0, 25600.0);
  EXPECT_NEAR(n.gain_at(480.0), 1.0, 1e-12);
  EXPECT_NEAR(20.0 * std::log10(n.gain_at(4800.0)), 8.0, 1e-9);  // one decade up: +8 dB
  EXPECT_NEAR(20.0 * std::log10(n.gain_at(48.0)), -8.0, 1e-9);
  EXPECT_EQ(n.gain_at(3.0), n.gain_at(10.0));
  EXPECT_EQ(n.block(), 8192U);  // >= fs / 4
  EXPECT_EQ(TiltedNoise(8.0, 64500.0).block(), 16384U);
}

/// Welch estimate (Hann, 4096, no overlap) of `blocks` x 4096 samples of the noise; per bin.
std::vector<double> psd_of(TiltedNoise& n, Rng& rng, std::size_t blocks) {
  const std::size_t len = 4096;
  dsp::RealFft fft(len);
  std::vector<float> x(len);
  std::vector<std::complex<float>> s(len / 2 + 1);
  std::vector<double> p(len / 2 + 1, 0.0);
  for (std::size_t b = 0; b < blocks; ++b) {
    for (std::size_t t = 0; t < len; ++t) {
      const double w = 0.5 - 0.5 * std::cos(2.0 * std::numbers::pi * static_cast<double>(t) / len);
      x[t] = static_cast<float>(w * n.next(rng));
    }
    fft.forward(x, s);
    for (std::size_t k = 0; k < s.size(); ++k) p[k] += std::norm(s[k]);
  }
  return p;
}

TEST(NoiseTilt, MadeNoiseFollowsThePowerLawInThirdOctaves) {
  for (const double tilt : {-12.0, 6.0, 14.0}) {
    const double fs = 25600.0;
    TiltedNoise n(tilt, fs);
    Rng rng(11, 3);
    const std::vector<double> p = psd_of(n, rng, 160);
    const double df = fs / 4096.0, pivot = noise_tilt_pivot_hz(fs);
    // Third-octave band means of the PSD against the law, relative to the band holding the pivot.
    std::vector<std::pair<double, double>> bands;  // (centre, measured dB - law dB)
    for (double lo = 40.0; lo * 1.26 < 0.45 * fs; lo *= 1.26) {
      double sum = 0.0, law = 0.0;
      int m = 0;
      for (std::size_t k = 0; k < p.size(); ++k) {
        const double f = static_cast<double>(k) * df;
        if (f < lo || f >= lo * 1.26) continue;
        sum += p[k];
        law += std::pow(f / pivot, tilt / 10.0);
        ++m;
      }
      if (m >= 3) bands.push_back({lo * 1.12, 10.0 * std::log10(sum / law)});
    }
    double mean = 0.0;
    for (const auto& b : bands) mean += b.second;
    mean /= static_cast<double>(bands.size());
    for (const auto& [f, d] : bands) EXPECT_NEAR(d, mean, 0.6) << "tilt " << tilt << " at " << f << " Hz";
  }
}

TEST(NoiseTilt, KnownFloorShapeIsInterpolatedInLogFrequencyAndReferredToThePivot) {
  // Shape 0 dB at 100 Hz rising to 20 dB at 1 kHz, tilt 0, fs 25.6 kHz: pivot 480 Hz, where the shape is
  // 20 log10(4.8) = 13.62 dB; every gain is referred to it.
  const TiltedNoise n(0.0, 25600.0, {100.0, 1000.0}, {0.0, 20.0});
  const double at_pivot = 20.0 * std::log10(4.8);
  EXPECT_NEAR(n.gain_at(480.0), 1.0, 1e-12);
  EXPECT_NEAR(20.0 * std::log10(n.gain_at(1000.0)), 20.0 - at_pivot, 1e-9);
  EXPECT_NEAR(20.0 * std::log10(n.gain_at(std::sqrt(1e5))), 10.0 - at_pivot, 1e-9);  // log midpoint
  EXPECT_EQ(n.gain_at(5000.0), n.gain_at(1000.0));                                   // flat beyond the ends
  EXPECT_EQ(n.gain_at(50.0), n.gain_at(100.0));
  // With a tilt the two multiply: +6 dB per decade from the pivot on top of the shape.
  const TiltedNoise t(6.0, 25600.0, {100.0, 1000.0}, {0.0, 20.0});
  EXPECT_NEAR(20.0 * std::log10(t.gain_at(4800.0)), 6.0 + 20.0 - at_pivot, 1e-9);
  // No shape: the plain tilted law.
  EXPECT_EQ(TiltedNoise(6.0, 25600.0, {}, {}).gain_at(4800.0), TiltedNoise(6.0, 25600.0).gain_at(4800.0));
}

TEST(NoiseTilt, MadeNoiseFollowsTheKnownShape) {
  // A 20 dB step between 300 Hz and 3 kHz (flat outside): the made noise's band levels below 200 Hz and
  // above 4 kHz differ by 20 dB (Welch, 160 x 4096 samples: the band means are within a few tenths).
  const double fs = 25600.0;
  TiltedNoise n(0.0, fs, {300.0, 3000.0}, {0.0, 20.0});
  Rng rng(12, 4);
  const std::vector<double> p = psd_of(n, rng, 160);
  const double df = fs / 4096.0;
  auto band_db = [&](double lo, double hi) {
    double sum = 0.0;
    int m = 0;
    for (std::size_t k = 0; k < p.size(); ++k) {
      const double f = static_cast<double>(k) * df;
      if (f >= lo && f < hi) sum += p[k], ++m;
    }
    return 10.0 * std::log10(sum / m);
  };
  EXPECT_NEAR(band_db(4000.0, 11000.0) - band_db(60.0, 200.0), 20.0, 0.6);
  EXPECT_NEAR(band_db(900.0, 1100.0) - band_db(60.0, 200.0), 20.0 * std::log10(1000.0 / 300.0), 0.8);
}

TEST(NoiseTilt, VarianceIsTheSameAtEverySampleOfTheOverlap) {
  // White shaping (tilt 0) gives unit variance; the sine-window overlap-add keeps it at block edges.
  TiltedNoise n(0.0, 20480.0);
  Rng rng(5, 2);
  const std::size_t hop = n.block() / 2, hops = 400;
  double edge = 0.0, middle = 0.0, all = 0.0;
  for (std::size_t h = 0; h < hops; ++h) {
    for (std::size_t t = 0; t < hop; ++t) {
      const double v = n.next(rng);
      all += v * v;
      if (t < 16) edge += v * v;
      if (t >= hop / 2 - 8 && t < hop / 2 + 8) middle += v * v;
    }
  }
  const double n_edge = 16.0 * hops;
  EXPECT_NEAR(all / static_cast<double>(hop * hops), 1.0, 0.01);
  // 6400 samples each (correlated only within a few samples for white): sd of the mean ~ 0.018.
  EXPECT_NEAR(edge / n_edge, 1.0, 0.08);
  EXPECT_NEAR(middle / n_edge, 1.0, 0.08);
}

}  // namespace
}  // namespace ptda::sim
