// WindowAnalyzer against closed forms: bin-centred tones with a random phase per window.
#include "ptda/dsp/analyzer.hpp"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <bit>
#include <cmath>
#include <complex>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <numbers>
#include <random>
#include <vector>

#include "alloc_counter.hpp"
#include "ptda/common/error.hpp"
#include "ptda/dsp/features.hpp"
#include "ptda/dsp/real_fft.hpp"

namespace ptda::dsp {
namespace {

constexpr std::size_t kN = 3200;
constexpr std::size_t kBins = kN / 2 + 1;
const std::vector<std::size_t> kToneBins = {40, 97, 250, 801};
const std::vector<double> kToneAmps = {1.0, 0.5, 2.0, 0.7};

struct Draw {
  std::vector<std::vector<double>> phase;  // [window][tone], radians
  std::vector<std::vector<float>> x;       // [window][sample]
};

// Windows of the same bin-centred tones, each tone with a fresh uniform phase per window, plus white
// Gaussian noise of stddev noise_sd.
Draw draw_windows(std::size_t m, double noise_sd, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0.0, 2.0 * std::numbers::pi);
  std::normal_distribution<double> g(0.0, 1.0);
  Draw d;
  for (std::size_t i = 0; i < m; ++i) {
    std::vector<double> ph(kToneBins.size());
    for (double& p : ph) p = u(rng);
    std::vector<float> x(kN);
    for (std::size_t t = 0; t < kN; ++t) {
      double v = noise_sd * g(rng);
      for (std::size_t h = 0; h < kToneBins.size(); ++h) {
        v += kToneAmps[h] *
             std::cos(2.0 * std::numbers::pi * static_cast<double>((kToneBins[h] * t) % kN) / kN + ph[h]);
      }
      x[t] = static_cast<float>(v);
    }
    d.phase.push_back(ph);
    d.x.push_back(x);
  }
  return d;
}

// mean |X_i| and mean x_i, computed directly (eqs. 5 and 7).
ClassBaseline means_of(const std::vector<std::vector<float>>& xs) {
  WindowAnalyzer a(kN);
  ClassBaseline cls;
  std::vector<double> mag_sum(kBins, 0.0), x_sum(kN, 0.0);
  std::vector<float> mag(kBins);
  for (const auto& x : xs) {
    a.magnitude(x, mag);
    for (std::size_t k = 0; k < kBins; ++k) mag_sum[k] += mag[k];
    for (std::size_t t = 0; t < kN; ++t) x_sum[t] += x[t];
  }
  const auto m = static_cast<double>(xs.size());
  for (const double v : mag_sum) cls.mean_magnitude.push_back(static_cast<float>(v / m));
  for (const double v : x_sum) cls.tda_mean.push_back(static_cast<float>(v / m));
  cls.n_windows = static_cast<std::uint32_t>(xs.size());
  return cls;
}

// Amplitude of the bin-centred tone at bin k of a real signal: |X[k]| / (N/2).
double tone_amplitude(std::span<const float> x, std::size_t k) {
  RealFft fft(x.size());
  std::vector<std::complex<float>> X(fft.bins());
  fft.forward(x, X);
  return std::abs(X[k]) / (static_cast<double>(x.size()) / 2.0);
}

TEST(WindowAnalyzer, TdaKeepsTheMeanPhasorPtdaKeepsTheWholeAmplitude) {
  std::mt19937 rng(20240501);
  const std::size_t m = 10;
  const Draw d = draw_windows(m, 0.0, rng);
  const ClassBaseline cls = means_of(d.x);
  WindowAnalyzer a(kN);

  (void)a.analyze(d.x[0], cls, Method::kTda);
  const std::vector<float> tda_d(a.deterministic().begin(), a.deterministic().end());
  for (std::size_t h = 0; h < kToneBins.size(); ++h) {
    std::complex<double> phasor = 0.0;
    for (std::size_t i = 0; i < m; ++i) phasor += std::polar(1.0, d.phase[i][h]);
    const double kept = std::abs(phasor) / static_cast<double>(m);  // |mean_i e^{j phi_i}|
    // Float round-off only (no noise): 1e-5 absolute on amplitudes of order 1.
    EXPECT_NEAR(tone_amplitude(tda_d, kToneBins[h]), kToneAmps[h] * kept, 1e-5) << "tone " << h;
    EXPECT_LT(kept, 0.8) << "the drawn phases must actually differ for this test to mean anything";
  }

  for (std::size_t i = 0; i < m; ++i) {
    const Features f = a.analyze(d.x[i], cls, Method::kPtda);
    for (std::size_t h = 0; h < kToneBins.size(); ++h) {
      EXPECT_NEAR(tone_amplitude(a.deterministic(), kToneBins[h]), kToneAmps[h], 1e-5) << "window " << i;
    }
    // Without noise |D_avg| == |X_i| at the tones, so d_i is x_i itself and nothing is left over.
    double max_diff = 0.0;
    for (std::size_t t = 0; t < kN; ++t)
      max_diff = std::max(max_diff, std::abs(static_cast<double>(a.deterministic()[t] - d.x[i][t])));
    EXPECT_LT(max_diff, 1e-5) << "window " << i;
    EXPECT_LT(f.rms_res, 1e-5) << "window " << i;
  }
}

// A healthy window scored against a baseline of M other windows of the same tones + noise (stddev s).
// PTDA replaces |X[k]| by the baseline's mean magnitude, so at noise-only bins the residual is
// (|X| - mean|X_j|) e^{j theta}: with Rayleigh |X|, E|R|^2 = Var|X| (1 + 1/M) = s_k^2 (1 - pi/4)(1 + 1/M).
// Hence RMS_res(PTDA) = s sqrt((1 - pi/4)(1 + 1/M)) ~= 0.47 s: close to (below) the noise RMS, with
// no tone left. TDA leaves A_h^2/2 |e^{j phi} - mean_j e^{j phi_j}|^2 of every tone in the residual.
TEST(WindowAnalyzer, HealthyResidualPtdaIsNoiseTdaKeepsTheTones) {
  std::mt19937 rng(77);
  const std::size_t m = 30;
  const double s = 0.5;
  const Draw base = draw_windows(m, s, rng);
  const ClassBaseline cls = means_of(base.x);
  const Draw test = draw_windows(8, s, rng);
  WindowAnalyzer a(kN);

  double ptda_rms_sum = 0.0;
  const double ptda_expected = s * std::sqrt((1.0 - std::numbers::pi / 4.0) * (1.0 + 1.0 / m));
  for (std::size_t i = 0; i < test.x.size(); ++i) {
    const Features f = a.analyze(test.x[i], cls, Method::kPtda);
    ptda_rms_sum += f.rms_res;
    // No tone survives in the PTDA residual: what is left at a tone bin is noise-sized (s sqrt(N/2) ~= 20).
    for (const std::size_t k : kToneBins) {
      EXPECT_LT(std::abs(a.residual_spectrum()[k]), 5.0 * s * std::sqrt(kN / 2.0)) << "bin " << k;
    }

    const Features ft = a.analyze(test.x[i], cls, Method::kTda);
    double tone_power = 0.0;
    for (std::size_t h = 0; h < kToneBins.size(); ++h) {
      std::complex<double> mean_phasor = 0.0;
      for (std::size_t j = 0; j < m; ++j) mean_phasor += std::polar(1.0, base.phase[j][h]);
      mean_phasor /= static_cast<double>(m);
      const double left = kToneAmps[h] * std::abs(std::polar(1.0, test.phase[i][h]) - mean_phasor);
      tone_power += 0.5 * left * left;
      // The tone's remainder in the TDA residual spectrum, +- 5 noise standard deviations of one bin.
      EXPECT_NEAR(std::abs(a.residual_spectrum()[kToneBins[h]]) / (kN / 2.0), left,
                  5.0 * s * std::sqrt((1.0 + 1.0 / m) / (kN / 2.0)))
          << "window " << i << " tone " << h;
    }
    const double tda_expected = std::sqrt(s * s * (1.0 + 1.0 / m) + tone_power);
    // RMS over 3200 samples: relative spread ~ 1/sqrt(N) ~= 2 %; 6 % is 3 spreads.
    EXPECT_NEAR(ft.rms_res / tda_expected, 1.0, 0.06) << "window " << i;
    EXPECT_GT(ft.rms_res, 2.0 * f.rms_res) << "window " << i;
  }
  // Mean over 8 windows of an RMS whose per-window spread is ~2.5 % (|R|^2 at 1600 bins, each with
  // relative spread ~1): ~1 % for the mean; 4 % is 4 spreads.
  const double ratio = ptda_rms_sum / test.x.size() / ptda_expected;
  std::printf("PTDA healthy RMS_res / (s sqrt((1 - pi/4)(1 + 1/M))) = %.4f\n", ratio);
  EXPECT_NEAR(ratio, 1.0, 0.04);
}

TEST(WindowAnalyzer, RawResidualIsTheWindow) {
  std::mt19937 rng(5);
  const Draw d = draw_windows(1, 0.3, rng);
  WindowAnalyzer a(kN);
  const Features f = a.analyze_with(d.x[0], {}, {}, Method::kRaw);
  for (std::size_t t = 0; t < kN; ++t) {
    ASSERT_EQ(a.residual()[t], d.x[0][t]);
    ASSERT_EQ(a.deterministic()[t], 0.0F);
  }
  // The features come from the spectrum (rms by Parseval, entropy with a float log): equal to the
  // time-domain definitions within the analyzer's contract of 1e-6 relative (issue 13).
  EXPECT_NEAR(f.rms_res, rms(d.x[0]), 1e-6 * rms(d.x[0]));
  RealFft fft(kN);
  std::vector<std::complex<float>> X(kBins);
  fft.forward(d.x[0], X);
  EXPECT_NEAR(f.entropy_res, spectral_entropy(X), 1e-6 * spectral_entropy(X));
}

// The entropy's vectorised log (Eigen's float log) against std::log in double over the floats the
// entropy feeds it, p in [FLT_MIN, 1]: |error| <= fast_log_error() * max(1, |ln p|).
TEST(WindowAnalyzer, FastLogMeetsItsStatedAccuracy) {
  std::vector<float> p;
  for (float v = std::numeric_limits<float>::min(); v <= 1.0F; v *= 1.0001F) p.push_back(v);
  p.push_back(1.0F);
  Eigen::ArrayXf logs = Eigen::Map<const Eigen::ArrayXf>(p.data(), static_cast<Eigen::Index>(p.size())).log();
  double worst = 0.0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    const double exact = std::log(static_cast<double>(p[i]));
    const double err = std::abs(static_cast<double>(logs[static_cast<Eigen::Index>(i)]) - exact);
    worst = std::max(worst, err / std::max(1.0, std::abs(exact)));
  }
  std::printf("Eigen float log: max |error| / max(1, |ln p|) %.3g over %zu values in [FLT_MIN, 1]\n", worst,
              p.size());
  EXPECT_LE(worst, WindowAnalyzer::fast_log_error());
}

// A zero-magnitude bin has no phase; the rule is phase 0, so D[k] = |D_avg[k]| (real, positive).
TEST(WindowAnalyzer, ZeroBinsTakePhaseZero) {
  const std::vector<float> x(kN, 0.0F);
  std::vector<float> mean_mag(kBins, 0.0F);
  mean_mag[0] = 3.0F;
  mean_mag[5] = 1.0F;
  WindowAnalyzer a(kN);
  const Features f = a.analyze_with(x, mean_mag, {}, Method::kPtda);
  for (std::size_t t = 0; t < kN; ++t) {
    // d = IDFT: 3/N from DC, (2/N) cos(2 pi 5 t / N) from bin 5 and its mirror.
    const double expected =
        3.0 / kN + 2.0 / kN * std::cos(2.0 * std::numbers::pi * static_cast<double>((5 * t) % kN) / kN);
    ASSERT_NEAR(a.deterministic()[t], expected, 1e-9) << t;
    ASSERT_EQ(a.residual()[t], -a.deterministic()[t]);
  }
  EXPECT_NEAR(f.rms_res, std::sqrt(9.0 / kN / kN + 2.0 / kN / kN), 1e-9);
}

// A fault tone the baseline never saw passes through PTDA untouched (|D_avg| ~ 0 there).
TEST(WindowAnalyzer, PtdaKeepsAnUnseenFaultTone) {
  std::mt19937 rng(9);
  const Draw base = draw_windows(10, 0.0, rng);
  const ClassBaseline cls = means_of(base.x);
  const Draw test = draw_windows(1, 0.0, rng);
  std::vector<float> x = test.x[0];
  for (std::size_t t = 0; t < kN; ++t) {
    x[t] += static_cast<float>(0.8 *
                               std::sin(2.0 * std::numbers::pi * static_cast<double>((1200 * t) % kN) / kN));
  }
  WindowAnalyzer a(kN);
  const Features f = a.analyze(x, cls, Method::kPtda);
  EXPECT_NEAR(f.rms_res, 0.8 / std::numbers::sqrt2, 1e-4);
  EXPECT_NEAR(std::abs(a.residual_spectrum()[1200]) / (kN / 2.0), 0.8, 1e-4);
  EXPECT_LT(f.entropy_res, 1e-3);  // one tone: entropy ~ 0
}

TEST(WindowAnalyzer, SizeMismatchGivesNaNNotUb) {
  WindowAnalyzer a(kN);
  const std::vector<float> x(kN, 1.0F), short_x(kN - 2, 1.0F), mag(kBins, 1.0F), mean(kN, 0.5F);
  auto is_nan = [](const Features& f) { return std::isnan(f.rms_res) && std::isnan(f.entropy_res); };
  EXPECT_TRUE(is_nan(a.analyze_with(short_x, mag, mean, Method::kPtda)));
  EXPECT_TRUE(is_nan(a.analyze_with(short_x, mag, mean, Method::kRaw)));
  EXPECT_TRUE(is_nan(a.analyze_with(x, std::span<const float>(mag).first(kBins - 1), mean, Method::kPtda)));
  EXPECT_TRUE(is_nan(a.analyze_with(x, mag, std::span<const float>(mean).first(kN - 1), Method::kTda)));
  // Each method only checks what it uses.
  EXPECT_FALSE(is_nan(a.analyze_with(x, {}, mean, Method::kTda)));
  EXPECT_FALSE(is_nan(a.analyze_with(x, mag, {}, Method::kPtda)));
  std::vector<float> out(kBins - 1, 0.0F);
  a.magnitude(x, out);
  EXPECT_TRUE(std::isnan(out[0]));
}

TEST(WindowAnalyzer, AnalyzeDoesNotAllocate) {
  std::mt19937 rng(3);
  const Draw d = draw_windows(4, 0.2, rng);
  const ClassBaseline cls = means_of(d.x);
  WindowAnalyzer a(kN);
  std::vector<float> mag(kBins);
  double sink = 0.0;
  test::AllocScope scope;
  for (const Method m : {Method::kRaw, Method::kTda, Method::kPtda}) {
    const Features f = a.analyze(d.x[1], cls, m);
    sink += f.rms_res + f.entropy_res;
  }
  a.magnitude(d.x[2], mag);
  EXPECT_EQ(scope.count(), 0U);
  EXPECT_TRUE(std::isfinite(sink));
}

TEST(WindowAnalyzer, MagnitudeIsAbsOfTheDft) {
  std::mt19937 rng(4);
  const Draw d = draw_windows(1, 0.2, rng);
  WindowAnalyzer a(kN);
  std::vector<float> mag(kBins);
  a.magnitude(d.x[0], mag);
  RealFft fft(kN);
  std::vector<std::complex<float>> X(kBins);
  fft.forward(d.x[0], X);
  for (std::size_t k = 0; k < kBins; ++k) ASSERT_NEAR(mag[k], std::abs(X[k]), 1e-5 * (1.0 + std::abs(X[k])));
}

TEST(WindowAnalyzer, UnsupportedLengthThrows) {
  EXPECT_THROW(WindowAnalyzer a(3201), Error);
  EXPECT_THROW(WindowAnalyzer a(14), Error);
}

// select_nth() (the floor gain's median, issue 13) must return what std::nth_element leaves at the
// rank, for every rank class, distribution and size, including ties, infinities, NaN (fallback), values
// outside the histogram's range and inputs too short for it; and it must not allocate.
double reference_nth(std::vector<double> v, std::size_t rank) {
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(rank), v.end());
  return v[rank];
}

TEST(SelectNth, EqualsNthElement) {
  std::mt19937 rng(2026);
  std::normal_distribution<double> normal(1.0, 0.3);
  std::exponential_distribution<double> expo(2.0);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<double> candidates(20000);
  std::vector<std::uint32_t> histogram(kSelectBuckets);
  int checked = 0;
  constexpr int kKinds = 11;
  for (int trial = 0; trial < 1100; ++trial) {
    const std::size_t m = trial % 7 == 0 ? 1 + rng() % 1100 : 1000 + rng() % 12000;
    std::vector<double> v(m);
    const int kind = trial % kKinds;
    // One bucket is 1/128 octave wide: values inside [1, 1 + 2^-10) all share the bucket of 1.
    const double one_bucket_base = 1.0;
    for (std::size_t i = 0; i < m; ++i) {
      switch (kind) {
        case 0:
          v[i] = std::fabs(normal(rng));
          break;
        case 1:
          v[i] = expo(rng);
          break;
        case 2:
          v[i] = static_cast<double>(rng() % 5);  // heavy ties, zeros (bucket 0)
          break;
        case 3:
          v[i] = 1.0 + static_cast<double>(rng() % 7) * 0x1p-20;  // ties, all in one bucket
          break;
        case 4:
          v[i] = static_cast<double>(i);  // sorted, most above 2^8 (last bucket)
          break;
        case 5:
          v[i] = static_cast<double>(m - i) * 1e-3;  // reversed
          break;
        case 6:
          v[i] = one_bucket_base + unit(rng) * 0x1p-11;  // adversarial: every value in one bucket
          break;
        case 7:
          v[i] = normal(rng) - 1.0;  // about half negative
          break;
        case 8:
          v[i] = std::ldexp(unit(rng) + 0.5, static_cast<int>(rng() % 40) - 20);  // wide range
          break;
        case 9:  // adversarial: bucket boundaries (powers of two and their neighbours)
          v[i] =
              std::nextafter(std::ldexp(1.0, static_cast<int>(rng() % 5) - 2), rng() % 2 == 0 ? 0.0 : 10.0);
          break;
        default:
          v[i] = rng() % 50 == 0 ? std::numeric_limits<double>::infinity() : normal(rng);
          break;
      }
    }
    if (trial % 25 == 0) v[rng() % m] = std::numeric_limits<double>::quiet_NaN();  // fallback path
    const std::size_t rank = trial % 3 == 0 ? m / 2 : rng() % m;
    const double want = reference_nth(v, rank);
    std::vector<double> got = v;
    const double x = select_nth(got, rank, candidates, histogram);
    if (std::isnan(want)) {
      EXPECT_TRUE(std::isnan(x)) << "trial " << trial;
    } else {
      EXPECT_EQ(x, want) << "trial " << trial << " kind " << kind << " m " << m << " rank " << rank;
    }
    ++checked;
  }
  EXPECT_EQ(checked, 1100);

  // Every rank of one tie-heavy input around 1 (the histogram path for all but the edge buckets).
  std::vector<double> ties(3000);
  for (std::size_t i = 0; i < ties.size(); ++i) ties[i] = 0.5 + static_cast<double>((i * 7919) % 37) / 32.0;
  for (std::size_t rank = 0; rank < ties.size(); ++rank) {
    std::vector<double> got = ties;
    ASSERT_EQ(select_nth(got, rank, candidates, histogram), reference_nth(ties, rank)) << "rank " << rank;
  }

  // Too little scratch or an out-of-range rank: nth_element, or NaN for the rank.
  std::vector<double> v(5000);
  for (std::size_t i = 0; i < v.size(); ++i) v[i] = static_cast<double>((i * 7919) % 5000);
  std::vector<double> small(10);
  std::vector<std::uint32_t> small_hist(10);
  std::vector<double> copy = v;
  EXPECT_EQ(select_nth(copy, 2500, small, histogram), 2500.0);
  copy = v;
  EXPECT_EQ(select_nth(copy, 2500, candidates, small_hist), 2500.0);
  EXPECT_TRUE(std::isnan(select_nth(copy, 5000, candidates, histogram)));

  // The histogram path leaves the input in its order (only the fallback reorders it).
  std::vector<double> ratios(6400);
  for (std::size_t i = 0; i < ratios.size(); ++i) ratios[i] = std::fabs(normal(rng));
  copy = ratios;
  const double want = reference_nth(ratios, 3200);
  ptda::test::AllocScope scope;
  const double med = select_nth(copy, 3200, candidates, histogram);
  EXPECT_EQ(scope.count(), 0U);
  EXPECT_EQ(med, want);
  EXPECT_EQ(copy, ratios);
}

// The floor gain's median (floor_median(): float-quotient buckets, double ratios for the median's
// bucket only) must be the median of the double ratios |X[k]| / a[k] over the floor bins that
// std::nth_element gives, on noise windows at several levels (the median inside [2^-8, 2^8) and far
// outside it: the fallback), with a NaN sample, with zero bins in a (excluded) and with line groups.
TEST(FloorGain, MedianEqualsNthElementOfDoubleRatios) {
  constexpr std::size_t kLen = 3200;
  constexpr std::size_t kHalfBins = kLen / 2 + 1;
  std::mt19937 rng(77);
  std::normal_distribution<float> noise(0.0F, 1.0F);
  std::uniform_real_distribution<float> level(0.5F, 2.0F);
  RealFft fft(kLen);
  WindowAnalyzer an(kLen);
  std::vector<std::complex<float>> spectrum(kHalfBins);
  const std::vector<LineGroup> groups{{0, 3}, {100, 112}, {400, 404}, {1500, kHalfBins + 10}};
  int fallback_checked = 0;
  for (int trial = 0; trial < 60; ++trial) {
    std::vector<float> a(kHalfBins);
    for (std::size_t k = 0; k < kHalfBins; ++k) a[k] = 30.0F * level(rng);
    if (trial % 4 == 1) {
      for (std::size_t k = 5; k < kHalfBins; k += 9) a[k] = 0.0F;  // no ratio for these bins
    }
    const float scale = trial % 5 == 2 ? 2000.0F : (trial % 5 == 3 ? 1e-4F : 1.0F);  // outside the range
    std::vector<float> x(kLen);
    for (float& v : x) v = scale * noise(rng);
    if (trial % 6 == 5) x[17] = std::numeric_limits<float>::quiet_NaN();
    fft.forward(x, spectrum);
    std::vector<double> ratios;
    std::vector<bool> in_line(kHalfBins, false);
    for (const LineGroup& g : groups) {
      for (std::size_t k = g.begin; k < std::min<std::size_t>(g.end, kHalfBins); ++k) in_line[k] = true;
    }
    // |X[k]| as the analyzer computes it: float energies, then Eigen's array sqrt over all bins (with
    // EIGEN_FAST_MATH its SSE packet sqrt is not std::sqrt's bits).
    std::vector<float> energy(kHalfBins);
    std::vector<float> mag(kHalfBins);
    for (std::size_t k = 0; k < kHalfBins; ++k) {
      const float re = spectrum[k].real();
      const float im = spectrum[k].imag();
      energy[k] = re * re + im * im;
    }
    Eigen::Map<Eigen::ArrayXf>(mag.data(), kHalfBins) =
        Eigen::Map<const Eigen::ArrayXf>(energy.data(), kHalfBins).sqrt();
    for (std::size_t k = 1; k < kHalfBins; ++k) {
      if (!in_line[k] && a[k] > 0.0F) ratios.push_back(static_cast<double>(mag[k]) / a[k]);
    }
    const double median = reference_nth(ratios, ratios.size() / 2);
    const Features f = an.analyze_with(x, a, {}, Method::kPtda, groups, true);
    if (median > 0.0 && std::isfinite(median)) {
      EXPECT_EQ(an.floor_gain(), median) << "trial " << trial;
      EXPECT_TRUE(std::isfinite(f.rms_res)) << "trial " << trial;
      if (scale != 1.0F) ++fallback_checked;
    } else {
      EXPECT_EQ(an.floor_gain(), 1.0) << "trial " << trial;  // NaN median: no floor gain
    }
  }
  EXPECT_GE(fallback_checked, 20);
}

// p_log_p(): the bits of Eigen's array expression it replaced (the same packet log on whole packets of
// four, std::log on the rest), for p across [FLT_MIN, 1] and a few below, at lengths 1..67; and ln
// within 2e-7 relative of the double logarithm over that range (Cephes' float log).
TEST(PLogP, SameBitsAsEigenAndAccurate) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> exponent(-130.0F, 0.0F);
  for (std::size_t n = 1; n <= 67; ++n) {
    std::vector<float> e(n);
    for (float& v : e) v = std::exp2(exponent(rng));
    if (n > 3) e[2] = 0.0F;
    const float scale = 0.75F;
    std::vector<float> got(n);
    p_log_p(e, scale, got);
    std::vector<float> want(n);
    const Eigen::Map<const Eigen::ArrayXf> ev(e.data(), static_cast<Eigen::Index>(n));
    Eigen::Map<Eigen::ArrayXf> wv(want.data(), static_cast<Eigen::Index>(n));
    wv = (ev * scale) * (ev * scale).max(std::numeric_limits<float>::min()).log();
    for (std::size_t k = 0; k < n; ++k) {
      EXPECT_EQ(std::bit_cast<std::uint32_t>(got[k]), std::bit_cast<std::uint32_t>(want[k]))
          << "n " << n << " k " << k << " e " << e[k];
    }
  }
  // Accuracy over the range: p ln p / p against ln p in double, for normal p in (0, 1].
  double worst = 0.0;
  std::vector<float> p(4096);
  std::vector<float> out(p.size());
  for (int round = 0; round < 20; ++round) {
    for (float& v : p) v = std::max(std::exp2(exponent(rng)), std::numeric_limits<float>::min());
    p[0] = 1.0F;
    p[1] = std::numeric_limits<float>::min();
    p_log_p(p, 1.0F, out);
    for (std::size_t k = 0; k < p.size(); ++k) {
      const double ln = std::log(static_cast<double>(p[k]));
      if (ln == 0.0) {
        EXPECT_EQ(out[k], 0.0F);
        continue;
      }
      worst = std::max(worst, std::fabs(static_cast<double>(out[k]) / p[k] - ln) / std::fabs(ln));
    }
  }
  EXPECT_LT(worst, 2e-7);
}

}  // namespace
}  // namespace ptda::dsp
