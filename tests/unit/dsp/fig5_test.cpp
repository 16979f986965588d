// The paper's Fig. 5 experiment (section 3.2): 10 cycles of eq. 10 with Table 1 amplitudes, GMF 520 Hz,
// a random phase per harmonic per cycle and SNR -10 dB. TDA (eq. 5) loses the harmonics because the
// cycles are not phase-aligned; PTDA (eqs. 7-9) keeps their amplitudes.
//
// Reading of eq. 10: x[n] = sum_k A_k sin(2 pi k f_GMF n / fs + 2 pi theta_k) + w[n], theta_k drawn
// uniformly in [0, 1) per harmonic and per cycle, i.e. theta_k is a fraction of a full turn of the
// k-th harmonic. (Read literally as a time shift "n + theta_k" with theta_k in seconds, the phase
// 2 pi k f_GMF theta_k is also uniform over whole turns, so both readings give the same experiment.)
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <complex>
#include <cstdio>
#include <numbers>
#include <random>
#include <vector>

#include "ptda/dsp/analyzer.hpp"

namespace ptda::dsp {
namespace {

constexpr double kFsHz = 25600.0;  // holds the 12th harmonic (6240 Hz) well below Nyquist
constexpr std::size_t kN = 12800;  // 0.5 s per cycle
constexpr double kGmfHz = 520.0;
constexpr std::size_t kCycles = 10;
constexpr std::array<int, 6> kHarmonics = {1, 4, 5, 7, 8, 12};
constexpr std::array<double, 6> kAmps = {0.43, 0.48, 1.40, 1.10, 1.60, 0.94};  // Table 1

// Least-squares amplitude of a sinusoid of known frequency in y: fit a cos + b sin (2x2 normal
// equations, no orthogonality assumed, so leakage of a non-bin-centred frequency would not matter).
double ls_amplitude(std::span<const float> y, double f_hz) {
  double cc = 0.0, ss = 0.0, cs = 0.0, yc = 0.0, ys = 0.0;
  for (std::size_t n = 0; n < y.size(); ++n) {
    const double ph = 2.0 * std::numbers::pi * f_hz * static_cast<double>(n) / kFsHz;
    const double c = std::cos(ph);
    const double s = std::sin(ph);
    cc += c * c;
    ss += s * s;
    cs += c * s;
    yc += y[n] * c;
    ys += y[n] * s;
  }
  const double det = cc * ss - cs * cs;
  const double a = (yc * ss - ys * cs) / det;
  const double b = (ys * cc - yc * cs) / det;
  return std::hypot(a, b);
}

TEST(Fig5, PtdaRecoversHarmonicAmplitudesTdaLosesThem) {
  std::mt19937 rng(5);  // fixed seed: the pinned numbers below are for this draw (libstdc++)
  std::uniform_real_distribution<double> unit(0.0, 1.0);

  double signal_power = 0.0;
  for (const double a : kAmps) signal_power += 0.5 * a * a;
  const double noise_sd = std::sqrt(10.0 * signal_power);  // SNR -10 dB: noise power = 10 x signal power
  std::normal_distribution<double> noise(0.0, noise_sd);

  std::vector<std::vector<float>> x(kCycles, std::vector<float>(kN));
  std::array<std::array<double, 6>, kCycles> theta{};
  for (std::size_t i = 0; i < kCycles; ++i) {
    for (double& t : theta[i]) t = unit(rng);
    for (std::size_t n = 0; n < kN; ++n) {
      double v = noise(rng);
      for (std::size_t h = 0; h < kHarmonics.size(); ++h) {
        v += kAmps[h] * std::sin(2.0 * std::numbers::pi *
                                 (kHarmonics[h] * kGmfHz * static_cast<double>(n) / kFsHz + theta[i][h]));
      }
      x[i][n] = static_cast<float>(v);
    }
  }

  // eq. 5 and eq. 7 over the 10 cycles.
  WindowAnalyzer a(kN);
  std::vector<float> tda_mean(kN, 0.0F), mean_mag(kN / 2 + 1, 0.0F), mag(kN / 2 + 1);
  {
    std::vector<double> xs(kN, 0.0), ms(kN / 2 + 1, 0.0);
    for (const auto& xi : x) {
      a.magnitude(xi, mag);
      for (std::size_t k = 0; k < ms.size(); ++k) ms[k] += mag[k];
      for (std::size_t n = 0; n < kN; ++n) xs[n] += xi[n];
    }
    for (std::size_t k = 0; k < ms.size(); ++k) mean_mag[k] = static_cast<float>(ms[k] / kCycles);
    for (std::size_t n = 0; n < kN; ++n) tda_mean[n] = static_cast<float>(xs[n] / kCycles);
  }

  (void)a.analyze_with(x[0], mean_mag, tda_mean, Method::kTda);
  const std::vector<float> d_tda(a.deterministic().begin(), a.deterministic().end());

  double tda_ratio_sum = 0.0, ptda_rel_err_sum = 0.0;
  std::printf("harmonic  f_Hz   A_true  TDA_est  A*|mean phasor|  PTDA_est(mean of 10)  PTDA_rel_err\n");
  for (std::size_t h = 0; h < kHarmonics.size(); ++h) {
    const double f = kHarmonics[h] * kGmfHz;
    const double tda_est = ls_amplitude(d_tda, f);
    std::complex<double> phasor = 0.0;
    for (std::size_t i = 0; i < kCycles; ++i) phasor += std::polar(1.0, 2.0 * std::numbers::pi * theta[i][h]);
    const double tda_expected = kAmps[h] * std::abs(phasor) / kCycles;
    // TDA keeps A |mean_i e^{j phi_i}|, plus averaged noise: its LS amplitude error has a standard
    // deviation of noise_sd sqrt(2 / (N M)) = 0.0236 per component; 0.1 is > 4 of them.
    EXPECT_NEAR(tda_est, tda_expected, 0.1) << "harmonic " << kHarmonics[h];

    double ptda_est = 0.0, rel_err = 0.0;
    for (std::size_t i = 0; i < kCycles; ++i) {
      (void)a.analyze_with(x[i], mean_mag, tda_mean, Method::kPtda);  // d_i from eqs. 8-9
      const double e = ls_amplitude(a.deterministic(), f);
      ptda_est += e / kCycles;
      rel_err += std::abs(e - kAmps[h]) / kAmps[h] / kCycles;
    }
    std::printf("%8d %6.0f %7.2f %8.3f %16.3f %21.3f %13.4f\n", kHarmonics[h], f, kAmps[h], tda_est,
                tda_expected, ptda_est, rel_err);
    tda_ratio_sum += tda_est / kAmps[h];
    ptda_rel_err_sum += rel_err;
  }
  const double tda_mean_ratio = tda_ratio_sum / kHarmonics.size();
  const double ptda_mean_rel_err = ptda_rel_err_sum / kHarmonics.size();
  std::printf("TDA mean estimated/true = %.4f, PTDA mean relative error = %.4f\n", tda_mean_ratio,
              ptda_mean_rel_err);

  // The paper's claim (Fig. 5): PTDA keeps the harmonics' amplitudes, TDA loses most of them.
  // PTDA's error is the per-bin noise: |X_i[k]| scatters by noise_sd sqrt(N/2) / sqrt(2) ~= 335 around
  // A N/2 (2752 for A1 = 0.43), i.e. ~12 % for the weakest harmonic, ~4 % after averaging 10 cycles.
  // TDA's expected ratio is E|mean of 10 unit phasors| ~= sqrt(pi / 40) ~= 0.28.
  EXPECT_LT(ptda_mean_rel_err, 0.10);
  EXPECT_LT(tda_mean_ratio, 0.5);
  // Pinned: measured with this seed. The draw is fixed, so only float round-off in the FFTs and sums
  // can move these (~1e-6); 1e-4 catches any change to the method or the signal.
  EXPECT_NEAR(tda_mean_ratio, 0.39198, 1e-4);
  EXPECT_NEAR(ptda_mean_rel_err, 0.02300, 1e-4);
}

}  // namespace
}  // namespace ptda::dsp
