// Training: normal quantiles, bands, statistics and the leave-one-group-out class baseline.
#include "ptda/dsp/training.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <map>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "ptda/common/error.hpp"
#include "ptda/dsp/analyzer.hpp"
#include "ptda/dsp/features.hpp"

namespace ptda::dsp {
namespace {

void expect_error_containing(const std::function<void()>& f, const std::string& needle) {
  try {
    f();
    ADD_FAILURE() << "no ptda::Error (expected one containing '" << needle << "')";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
  }
}

TEST(InverseNormalCdf, KnownQuantiles) {
  // Standard table values of Phi^{-1}: 0.975 -> 1.959963984540054, 0.9995 -> 3.290526731491926.
  EXPECT_NEAR(inverse_normal_cdf(0.975), 1.959963984540054, 1e-12);
  EXPECT_NEAR(inverse_normal_cdf(1.0 - 0.0005), 3.290526731491926, 1e-9);  // 1 - p rounds at 1e-13
  EXPECT_NEAR(inverse_normal_cdf(0.0005), -3.290526731491926, 1e-12);
  EXPECT_NEAR(inverse_normal_cdf(0.5), 0.0, 1e-15);
  EXPECT_NEAR(inverse_normal_cdf(0.8413447460685429), 1.0, 1e-12);  // Phi(1)
}

TEST(InverseNormalCdf, RoundTripsThroughErfcDeepIntoTheTail) {
  for (const double p : {1e-200, 1e-30, 1e-12, 1e-5, 0.01, 0.2, 0.49, 0.7, 0.99}) {
    const double z = inverse_normal_cdf(p);
    const double back = 0.5 * std::erfc(-z / std::numbers::sqrt2);
    EXPECT_NEAR(back / p, 1.0, 1e-12) << "p = " << p;
  }
}

TEST(InverseNormalCdf, RejectsProbabilitiesOutsideOpenUnitInterval) {
  for (const double p : {0.0, 1.0, -0.1, 1.5, std::numeric_limits<double>::quiet_NaN()}) {
    EXPECT_THROW((void)inverse_normal_cdf(p), Error) << p;
  }
}

TEST(FitBand, GaussianUsesTheTwoSidedZ) {
  const std::vector<double> v = {1.0, 2.0, 3.0, 4.0, 5.0};  // mean 3, stddev sqrt(2.5)
  const double sd = std::sqrt(2.5);
  ThresholdPolicy p;
  p.kind = ThresholdPolicy::Kind::kGaussian;
  p.false_alarm_rate = 0.05;
  Band b = fit_band(v, p);
  EXPECT_NEAR((b.hi - 3.0) / sd, 1.959964, 1e-6);
  EXPECT_NEAR((3.0 - b.lo) / sd, 1.959964, 1e-6);
  p.false_alarm_rate = 1e-3;
  b = fit_band(v, p);
  EXPECT_NEAR((b.hi - 3.0) / sd, 3.290527, 1e-6);
  // margin widens both ends by margin * width.
  p.margin = 0.1;
  const Band w = fit_band(v, p);
  const double width = b.hi - b.lo;
  EXPECT_NEAR(w.lo, b.lo - 0.1 * width, 1e-12);
  EXPECT_NEAR(w.hi, b.hi + 0.1 * width, 1e-12);
}

TEST(FitBand, QuantileInterpolatesLinearly) {
  // 0..100 shuffled: quantiles q are exactly 100 q.
  std::vector<double> v(101);
  for (std::size_t i = 0; i < v.size(); ++i) v[i] = static_cast<double>(i);
  std::mt19937 rng(1);
  std::shuffle(v.begin(), v.end(), rng);
  ThresholdPolicy p;
  p.kind = ThresholdPolicy::Kind::kQuantile;
  p.false_alarm_rate = 0.1;
  Band b = fit_band(v, p);
  EXPECT_NEAR(b.lo, 5.0, 1e-12);
  EXPECT_NEAR(b.hi, 95.0, 1e-12);
  // Between order statistics: {10, 20, 30, 40}, q = 0.25 -> h = 0.75 -> 17.5; q = 0.75 -> h = 2.25 -> 32.5.
  const std::vector<double> w = {40.0, 10.0, 30.0, 20.0};
  p.false_alarm_rate = 0.5;
  b = fit_band(w, p);
  EXPECT_NEAR(b.lo, 17.5, 1e-12);
  EXPECT_NEAR(b.hi, 32.5, 1e-12);
  p.margin = 0.2;  // width 15 -> 3 each side
  b = fit_band(w, p);
  EXPECT_NEAR(b.lo, 14.5, 1e-12);
  EXPECT_NEAR(b.hi, 35.5, 1e-12);
}

TEST(FitBand, BadInputIsAnError) {
  ThresholdPolicy p;
  expect_error_containing([&] { (void)fit_band(std::vector<double>{1.0}, p); }, "at least 2");
  expect_error_containing([&] { (void)fit_band(std::vector<double>{1.0, std::nan(""), 2.0}, p); }, "value 1");
  p.false_alarm_rate = 0.0;
  expect_error_containing([&] { (void)fit_band(std::vector<double>{1.0, 2.0}, p); }, "false_alarm_rate");
  p.false_alarm_rate = 0.01;
  p.margin = -0.5;
  expect_error_containing([&] { (void)fit_band(std::vector<double>{1.0, 2.0}, p); }, "margin");
}

TEST(FeatureStats, KnownData) {
  const std::vector<double> v = {2.0, 4.0, 4.0, 4.0, 5.0, 5.0, 7.0, 9.0};  // mean 5, sum sq dev 32
  const FeatureStats s = feature_stats(v);
  EXPECT_EQ(s.n, 8U);
  EXPECT_DOUBLE_EQ(s.mean, 5.0);
  EXPECT_NEAR(s.stddev, std::sqrt(32.0 / 7.0), 1e-12);
  EXPECT_EQ(s.min, 2.0);
  EXPECT_EQ(s.max, 9.0);
  EXPECT_EQ(feature_stats(std::vector<double>{}).n, 0U);
  EXPECT_EQ(feature_stats(std::vector<double>{3.0}).stddev, 0.0);
}

// ---- build_class_baseline --------------------------------------------------------------------

constexpr std::size_t kN = 3200;
constexpr std::size_t kBins = kN / 2 + 1;

// Windows of bin-centred tones (random phase per window) plus white noise of stddev 0.5.
std::vector<std::vector<float>> tone_windows(std::size_t m, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 2.0 * std::numbers::pi);
  std::normal_distribution<double> g(0.0, 0.5);
  const std::vector<std::size_t> bins = {64, 130, 400};
  const std::vector<double> amps = {1.0, 2.0, 0.6};
  std::vector<std::vector<float>> w(m, std::vector<float>(kN));
  for (auto& x : w) {
    std::vector<double> ph(bins.size());
    for (double& p : ph) p = u(rng);
    for (std::size_t t = 0; t < kN; ++t) {
      double v = g(rng);
      for (std::size_t h = 0; h < bins.size(); ++h) {
        v +=
            amps[h] * std::cos(2.0 * std::numbers::pi * static_cast<double>((bins[h] * t) % kN) / kN + ph[h]);
      }
      x[t] = static_cast<float>(v);
    }
  }
  return w;
}

struct Scored {
  std::array<std::vector<double>, kMethodCount> rms, entropy;
};

// Reference scoring written the slow, obvious way: for window i, average |X_j| and x_j over the
// windows j the predicate admits, then analyze. PTDA uses `lines`: training's line groups, which come
// from the mean of all the class's windows (the default policy has the line gain on), and the class's
// floor gain (on by default).
template <typename Admit>
Scored score_brute_force(const std::vector<std::vector<float>>& w, Admit admit,
                         const std::vector<LineGroup>& lines, bool floor_gain) {
  WindowAnalyzer a(kN);
  std::vector<std::vector<float>> mags(w.size(), std::vector<float>(kBins));
  for (std::size_t j = 0; j < w.size(); ++j) a.magnitude(w[j], mags[j]);
  Scored s;
  for (std::size_t i = 0; i < w.size(); ++i) {
    std::vector<double> ms(kBins, 0.0), xs(kN, 0.0);
    double cnt = 0.0;
    for (std::size_t j = 0; j < w.size(); ++j) {
      if (!admit(i, j)) continue;
      for (std::size_t k = 0; k < kBins; ++k) ms[k] += mags[j][k];
      for (std::size_t t = 0; t < kN; ++t) xs[t] += w[j][t];
      cnt += 1.0;
    }
    std::vector<float> mf(kBins), xf(kN);
    for (std::size_t k = 0; k < kBins; ++k) mf[k] = static_cast<float>(ms[k] / cnt);
    for (std::size_t t = 0; t < kN; ++t) xf[t] = static_cast<float>(xs[t] / cnt);
    for (std::size_t m = 0; m < kMethodCount; ++m) {
      const Features f = a.analyze_with(w[i], mf, xf, static_cast<Method>(m), lines, floor_gain);
      s.rms[m].push_back(f.rms_res);
      s.entropy[m].push_back(f.entropy_res);
    }
  }
  return s;
}

void expect_stats_match(const FeatureStats& got, const std::vector<double>& values, const char* what) {
  const FeatureStats want = feature_stats(values);
  // The baseline forms (total - group) / count in double and rounds to float, the reference sums the
  // admitted windows directly: the float means differ in the last bit, features by ~1e-7 relative.
  const double tol = 1e-6 * std::abs(want.mean);
  EXPECT_EQ(got.n, want.n) << what;
  EXPECT_NEAR(got.mean, want.mean, tol) << what;
  EXPECT_NEAR(got.stddev, want.stddev, tol) << what;
  EXPECT_NEAR(got.min, want.min, tol) << what;
  EXPECT_NEAR(got.max, want.max, tol) << what;
}

TEST(BuildClassBaseline, MeansAreOverAllWindows) {
  const auto w = tone_windows(6, 10);
  SegmentClass seg;
  seg.id = 4;
  seg.speed_rad_s = 1.5;
  const ClassBaseline cls = build_class_baseline(seg, w, {}, ThresholdPolicy{});
  EXPECT_EQ(cls.segment.id, 4U);
  EXPECT_EQ(cls.segment.speed_rad_s, 1.5);
  EXPECT_EQ(cls.n_windows, 6U);
  ASSERT_EQ(cls.mean_magnitude.size(), kBins);
  ASSERT_EQ(cls.tda_mean.size(), kN);
  WindowAnalyzer a(kN);
  std::vector<double> ms(kBins, 0.0);
  std::vector<float> mag(kBins);
  for (const auto& x : w) {
    a.magnitude(x, mag);
    for (std::size_t k = 0; k < kBins; ++k) ms[k] += mag[k];
  }
  for (std::size_t k = 0; k < kBins; ++k)
    ASSERT_NEAR(cls.mean_magnitude[k], ms[k] / 6.0, 1e-6 * (1.0 + ms[k] / 6.0)) << k;
  for (std::size_t t = 0; t < kN; ++t) {
    double s = 0.0;
    for (const auto& x : w) s += x[t];
    ASSERT_NEAR(cls.tda_mean[t], s / 6.0, 1e-6) << t;
  }
}

// Each window is scored against the other windows only: the learned statistics and bands are those of
// the leave-one-out features, and differ from in-sample scoring in the predicted way.
TEST(BuildClassBaseline, ThresholdsComeFromLeaveOneOutFeatures) {
  const std::size_t m = 8;
  const auto w = tone_windows(m, 11);
  ThresholdPolicy policy;
  policy.kind = ThresholdPolicy::Kind::kGaussian;
  policy.false_alarm_rate = 0.01;
  // The closed form below holds for a residual linear in the mean: the floor gain's median is not.
  // BuildClassBaseline.LeavesTheWholeGroupOut checks leave-one-out scoring with the floor gain on.
  policy.ptda_floor_gain = false;
  // No between-day prior: the bands are compared with fit_band() of the values alone (the widening
  // has its own test, BuildClassBaseline.DaySpreadFromSeveralRecordings).
  policy.day_sd_floor = 0.0;
  const ClassBaseline cls = build_class_baseline(SegmentClass{}, w, {}, policy);

  ASSERT_FALSE(cls.line_groups.empty());  // the tones are lines: the default line gain is exercised
  ASSERT_FALSE(cls.floor_gain);
  const Scored loo = score_brute_force(
      w, [](std::size_t i, std::size_t j) { return i != j; }, cls.line_groups, false);
  const Scored in_sample = score_brute_force(
      w, [](std::size_t, std::size_t) { return true; }, cls.line_groups, false);
  for (std::size_t mi = 0; mi < kMethodCount; ++mi) {
    const std::string what(method_name(static_cast<Method>(mi)));
    expect_stats_match(cls.rms_stats[mi], loo.rms[mi], what.c_str());
    expect_stats_match(cls.entropy_stats[mi], loo.entropy[mi], what.c_str());
    const Band rb = fit_band(loo.rms[mi], policy);
    EXPECT_NEAR(cls.thresholds[mi].rms.hi, rb.hi, 1e-5 * rb.hi) << what;
    EXPECT_NEAR(cls.thresholds[mi].rms.lo, std::max(0.0, rb.lo), 1e-5 * rb.hi) << what;
  }

  // Including the scored window in its own |D_avg| pulls the estimate towards it. Per bin the PTDA
  // residual is (|X_i| - mean) e^{j theta_i}, and |X_i| - mean_all = (M-1)/M (|X_i| - mean_others)
  // exactly, so the in-sample residual is the leave-one-out one scaled by (M-1)/M = 0.875: in-sample
  // bands would be 12.5 % too narrow and raise false alarms.
  const auto ptda = static_cast<std::size_t>(Method::kPtda);
  const double ratio = feature_stats(in_sample.rms[ptda]).mean / cls.rms_stats[ptda].mean;
  std::printf("PTDA RMS_res in-sample / leave-one-out = %.4f (closed form %.4f)\n", ratio, (m - 1.0) / m);
  // Exact up to float round-off of the means (~1e-7 relative).
  EXPECT_NEAR(ratio, (m - 1.0) / m, 1e-5);
  EXPECT_LT(fit_band(in_sample.rms[ptda], policy).hi, cls.thresholds[ptda].rms.hi);

  // Raw features do not depend on any average: they are the windows' own RMS.
  const auto raw = static_cast<std::size_t>(Method::kRaw);
  std::vector<double> raw_rms;
  for (const auto& x : w) raw_rms.push_back(rms(x));
  expect_stats_match(cls.rms_stats[raw], raw_rms, "raw");
}

// Windows of one group (one constant-speed region) never enter each other's average. Make each group
// two identical copies: leave-one-window-out would then subtract a perfect copy, leave-one-group-out not.
TEST(BuildClassBaseline, LeavesTheWholeGroupOut) {
  const auto base = tone_windows(5, 12);
  std::vector<std::vector<float>> w;
  std::vector<std::uint64_t> groups;
  for (std::size_t g = 0; g < base.size(); ++g) {
    for (int copy = 0; copy < 2; ++copy) {
      w.push_back(base[g]);
      groups.push_back(100 + 7 * g);  // arbitrary ids
    }
  }
  const ClassBaseline cls = build_class_baseline(SegmentClass{}, w, groups, ThresholdPolicy{});
  ASSERT_TRUE(cls.floor_gain);  // the default: leave-one-group-out scoring with the floor gain
  const Scored logo = score_brute_force(
      w, [&](std::size_t i, std::size_t j) { return groups[i] != groups[j]; }, cls.line_groups, true);
  const Scored lowo = score_brute_force(
      w, [](std::size_t i, std::size_t j) { return i != j; }, cls.line_groups, true);
  const auto ptda = static_cast<std::size_t>(Method::kPtda);
  expect_stats_match(cls.rms_stats[ptda], logo.rms[ptda], "ptda");
  expect_stats_match(cls.entropy_stats[ptda], logo.entropy[ptda], "ptda");
  expect_stats_match(cls.rms_stats[static_cast<std::size_t>(Method::kTda)], logo.rms[1], "tda");
  // With the copy inside the average (1 of 9 windows) the residual shrinks markedly.
  EXPECT_LT(feature_stats(lowo.rms[ptda]).mean, 0.95 * cls.rms_stats[ptda].mean);
}

TEST(BuildClassBaseline, BandsContainTheirTrainingFeaturesAndAreNonNegative) {
  const auto w = tone_windows(12, 13);
  ThresholdPolicy policy;
  policy.kind = ThresholdPolicy::Kind::kQuantile;
  policy.false_alarm_rate = 1e-3;
  policy.day_sd_floor = 0.0;  // the sample quantiles themselves (the widening: day_spread_test.cpp)
  const ClassBaseline cls = build_class_baseline(SegmentClass{}, w, {}, policy);
  for (std::size_t mi = 0; mi < kMethodCount; ++mi) {
    // Quantiles at 0.0005 / 0.9995 of 12 values are within 0.0055 of the min / max order statistic.
    EXPECT_NEAR(cls.thresholds[mi].rms.lo, cls.rms_stats[mi].min,
                0.01 * (cls.rms_stats[mi].max - cls.rms_stats[mi].min));
    EXPECT_NEAR(cls.thresholds[mi].rms.hi, cls.rms_stats[mi].max,
                0.01 * (cls.rms_stats[mi].max - cls.rms_stats[mi].min));
    EXPECT_GE(cls.thresholds[mi].entropy.lo, 0.0);
    EXPECT_GT(cls.thresholds[mi].entropy.hi, cls.thresholds[mi].entropy.lo);
  }
}

TEST(BuildClassBaseline, BadInputNamesTheProblem) {
  const auto w = tone_windows(4, 14);
  const SegmentClass seg{};
  const ThresholdPolicy p{};
  expect_error_containing([&] { (void)build_class_baseline(seg, {}, {}, p); }, "no training windows");
  const std::vector<std::uint64_t> two_groups = {1, 1, 2, 2};
  expect_error_containing([&] { (void)build_class_baseline(seg, w, two_groups, p); }, "at least 3 groups");
  const std::vector<std::uint64_t> wrong_count = {1, 2, 3};
  expect_error_containing([&] { (void)build_class_baseline(seg, w, wrong_count, p); },
                          "3 group ids for 4 windows");
  auto short_w = w;
  short_w[2].resize(kN - 10);
  expect_error_containing([&] { (void)build_class_baseline(seg, short_w, {}, p); },
                          "window 2 has 3190 samples");
  auto nan_w = w;
  nan_w[1][5] = std::numeric_limits<float>::quiet_NaN();
  expect_error_containing([&] { (void)build_class_baseline(seg, nan_w, {}, p); },
                          "window 1 sample 5 is not finite");
  const std::vector<std::vector<float>> odd(4, std::vector<float>(14, 0.0F));
  expect_error_containing([&] { (void)build_class_baseline(seg, odd, {}, p); }, "window length 14");
}

}  // namespace
}  // namespace ptda::dsp
