// The between-day (between-recording) spread: the random-effects decomposition, the bands widened by it,
// the CUSUM's allowance for it, and training on several recordings (docs/method.md §5, §6).
// Reference numbers: computed with python3 (Debian 12 python3-numpy 1.24.2) by the textbook formulas:
//  - groups {1, 2, 3}, {4, 6}, {5, 5, 8, 10}: grand mean 4.888888888888889, MSW = 3.6666666666666665,
//    MSB = 21.444444444444443, n0 = 2.888888888888889, between variance (MSB - MSW) / n0 =
//    6.153846153846153; one group {1, 2, 3, 4, 6}: sample variance 3.7.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "ptda/common/error.hpp"
#include "ptda/dsp/decision.hpp"
#include "ptda/dsp/training.hpp"

namespace ptda::dsp {
namespace {

// An unbalanced one-way layout and its closed-form components (pinned: the method-of-moments formulas
// of training.hpp worked by hand).
const std::vector<double> kUnbalancedValues = {1, 2, 3, 4, 6, 5, 5, 8, 10};
const std::vector<std::uint32_t> kUnbalancedGroups = {7, 7, 7, 2, 2, 9, 9, 9, 9};  // ids need not be dense

void expect_unbalanced_closed_form(const VarianceComponents& vc) {
  EXPECT_EQ(vc.groups, 3U);
  EXPECT_EQ(vc.n, 9U);
  EXPECT_NEAR(vc.mean, 4.888888888888889, 1e-14);
  EXPECT_NEAR(vc.within_var, 3.6666666666666665, 1e-13);
  EXPECT_NEAR(vc.msb, 21.444444444444443, 1e-12);
  EXPECT_NEAR(vc.n0, 2.888888888888889, 1e-14);
  EXPECT_NEAR(vc.between_var, 6.153846153846153, 1e-12);
}

TEST(VarianceComponents, UnbalancedOneWayClosedForm) {
  expect_unbalanced_closed_form(variance_components(kUnbalancedValues, kUnbalancedGroups));
}

// The training keeps no band values since session 21: it adds them to accumulators window by window.
// Same closed form as above (pinned there), groups interleaved as several recordings' windows are not.
TEST(VarianceComponents, TheAccumulatorGivesTheClosedFormWhateverTheOrderOfGroups) {
  for (const std::vector<std::size_t>& order : {std::vector<std::size_t>{0, 1, 2, 3, 4, 5, 6, 7, 8},
                                                std::vector<std::size_t>{5, 0, 3, 6, 1, 4, 7, 2, 8},
                                                std::vector<std::size_t>{8, 7, 6, 5, 4, 3, 2, 1, 0}}) {
    VarianceAccumulator acc;
    for (const std::size_t i : order) acc.add(kUnbalancedValues[i], kUnbalancedGroups[i]);
    EXPECT_EQ(acc.count(), 9U);
    expect_unbalanced_closed_form(acc.result());
  }
  // Large values with a small spread (ln band energies sit near a constant): Welford keeps the
  // within-group variance where a sum of squares would cancel. 1e8 + k * 1e-3, k = 0..3, two groups.
  VarianceAccumulator big;
  for (int k = 0; k < 4; ++k) big.add(1e8 + k * 1e-3, 0);
  for (int k = 0; k < 4; ++k) big.add(1e8 + k * 1e-3, 1);
  const VarianceComponents b = big.result();
  // Each group: squared deviations 2 x (1.5e-3^2 + 0.5e-3^2) = 5e-6; MSW = 1e-5 / (8 - 2). The inputs
  // themselves carry 1e8's rounding (ulp 1.5e-8), hence 1e-9; a sum of squares (~4e16) would lose it all.
  EXPECT_NEAR(b.within_var, 1e-5 / 6.0, 1e-9);
  EXPECT_EQ(b.between_var, 0.0);
  EXPECT_THROW((void)VarianceAccumulator{}.result(), Error);
}

TEST(VarianceComponents, OneGroupAndNoBetweenSpread) {
  const std::vector<double> v = {1, 2, 3, 4, 6};
  const VarianceComponents one = variance_components(v, {});
  EXPECT_EQ(one.groups, 1U);
  EXPECT_NEAR(one.within_var, 3.7, 1e-14);
  EXPECT_EQ(one.between_var, 0.0);
  // Two groups with equal means: MSB = 0 < MSW, the estimate is clamped at 0.
  const std::vector<double> w = {1, 3, 2, 2};
  const std::vector<std::uint32_t> g = {0, 0, 1, 1};
  const VarianceComponents eq = variance_components(w, g);
  EXPECT_EQ(eq.between_var, 0.0);
  EXPECT_NEAR(eq.within_var, 1.0, 1e-14);  // (1 + 1 + 0 + 0) / (4 - 2)
  // One value per group: within and between cannot be told apart.
  const VarianceComponents single = variance_components(w, std::vector<std::uint32_t>{0, 1, 2, 3});
  EXPECT_EQ(single.between_var, 0.0);
  EXPECT_NEAR(single.within_var, 2.0 / 3.0, 1e-14);
  EXPECT_THROW((void)variance_components(w, std::vector<std::uint32_t>{0, 1}), Error);
  EXPECT_THROW((void)variance_components(std::vector<double>{}, {}), Error);
}

TEST(FitBand, DayRatioWidensBySqrtOfOnePlusRatioSquared) {
  const std::vector<double> v = {std::exp(-1.0), 1.0, std::exp(1.0), 1.0, 1.0};  // ln: sd sqrt(0.5)
  ThresholdPolicy p;
  p.false_alarm_rate = 1e-2;
  const double k1 = tolerance_factor_one_sided(5, 0.99, 0.9);
  // ratio 0.75: sd x sqrt(1 + 0.5625) = 1.25 sd.
  const Band b = fit_band(v, p, FeatureScale::kLog, 0.75);
  EXPECT_NEAR(b.hi, std::exp(1.25 * k1 * std::sqrt(0.5)), 1e-12);
  EXPECT_NEAR(b.lo, std::exp(-1.25 * k1 * std::sqrt(0.5)), 1e-12);
  // within_ratio: the within-day sd is half the sample sd -> sd x 0.5 x 1.25.
  const Band h = fit_band(v, p, FeatureScale::kLog, 0.75, 0.5);
  EXPECT_NEAR(h.hi, std::exp(0.625 * k1 * std::sqrt(0.5)), 1e-12);
  // Ratio 0 is the session-6 band, bit for bit, whatever within_ratio says.
  const Band z0 = fit_band(v, p, FeatureScale::kLog);
  const Band z1 = fit_band(v, p, FeatureScale::kLog, 0.0, 0.5);
  EXPECT_EQ(z0.hi, z1.hi);
  EXPECT_EQ(z0.lo, z1.lo);
  // Gaussian on the values: mean +- z sd x 1.25.
  p.kind = ThresholdPolicy::Kind::kGaussian;
  const FeatureStats s = feature_stats(v);
  const double z = -inverse_normal_cdf(0.005);
  const Band g = fit_band(v, p, FeatureScale::kLinear, 0.75);
  EXPECT_NEAR(g.hi, s.mean + 1.25 * z * s.stddev, 1e-12);
  // Quantile: both quantiles move away from the median (1.0) by 1.25.
  p.kind = ThresholdPolicy::Kind::kQuantile;
  const Band q0 = fit_band(v, p, FeatureScale::kLinear);
  const Band q = fit_band(v, p, FeatureScale::kLinear, 0.75);
  EXPECT_NEAR(q.hi - 1.0, 1.25 * (q0.hi - 1.0), 1e-12);
  EXPECT_NEAR(1.0 - q.lo, 1.25 * (1.0 - q0.lo), 1e-12);
  EXPECT_THROW((void)fit_band(v, p, FeatureScale::kLinear, -0.1), Error);
  EXPECT_THROW((void)fit_band(v, p, FeatureScale::kLinear, 0.5, 0.0), Error);
}

TEST(SequentialScale, AllowanceIsQTimesBetweenOverWithin) {
  ClassBaseline c;
  const auto m = static_cast<std::size_t>(Method::kPtda);
  c.log_rms_stats[m] = FeatureStats{-2.0, 0.05, -2.2, -1.8, 20};
  c.entropy_stats[m] = FeatureStats{0.9, 0.004, 0.89, 0.91, 20};
  ThresholdPolicy p;                                        // alpha 1e-3, confidence 0.9
  const double cn = 3.962420485378056 / 3.090232306167813;  // small_sample_scale(20): see its test
  // Format <= 3 (no day spread): the session-6 standardisation, no allowance.
  const SeqScale old = sequential_scale(c, Method::kPtda, p, 3.0);
  EXPECT_NEAR(old.scale, cn, 1e-9);
  EXPECT_EQ(old.log_rms.stddev, 0.05);
  EXPECT_EQ(old.rms_allowance, 0.0);
  EXPECT_EQ(old.entropy_allowance, 0.0);
  // One recording, within 0.04 / 0.003, between (the prior 0.3 x within) 0.012 / 0.0009:
  // allowance 3 x 0.3 x sqrt(2) / c_n for both features.
  DaySpread& d = c.day_spread[m];
  d.recordings = 1;
  d.log_rms_within_sd = 0.04;
  d.log_rms_between_sd = 0.012;
  d.entropy_within_sd = 0.003;
  d.entropy_between_sd = 0.0009;
  const SeqScale one = sequential_scale(c, Method::kPtda, p, 3.0);
  EXPECT_EQ(one.log_rms.stddev, 0.04);  // z is standardised by the within-day sd
  EXPECT_EQ(one.entropy.stddev, 0.003);
  EXPECT_NEAR(one.rms_allowance, 0.9 * std::numbers::sqrt2 / cn, 1e-12);
  EXPECT_NEAR(one.entropy_allowance, 0.9 * std::numbers::sqrt2 / cn, 1e-12);
  // Three recordings: sqrt(1 + 1/3); day_allowance 0 switches it off.
  d.recordings = 3;
  EXPECT_NEAR(sequential_scale(c, Method::kPtda, p, 3.0).rms_allowance, 0.9 * std::sqrt(4.0 / 3.0) / cn,
              1e-12);
  EXPECT_EQ(sequential_scale(c, Method::kPtda, p, 0.0).rms_allowance, 0.0);
  // z against the within sd: ln rms = -2 + 0.04 c_n -> z_rms = 1.
  const StandardScores z = standardize(Features{std::exp(-2.0 + 0.04 * cn), 0.9}, one);
  EXPECT_NEAR(z.rms, 1.0, 1e-12);
  EXPECT_NEAR(z.entropy, 0.0, 1e-12);
}

TEST(Cusum, ExtraAllowancePerFeature) {
  Cusum c;
  c.update(3.0, -3.0, 1.0, 20.0, 0.5, 1.5);  // rms 3 - 1.5 = 1.5; entropy low 3 - 2.5 = 0.5
  EXPECT_DOUBLE_EQ(c.statistic(), 1.5);
  EXPECT_EQ(c.feature(), SeqFeature::kRmsHigh);
  c.update(1.2, -4.0, 1.0, 20.0, 0.5, 1.5);  // rms 1.5 - 0.3 = 1.2; entropy low 0.5 + 1.5 = 2
  EXPECT_DOUBLE_EQ(c.statistic(), 2.0);
  EXPECT_EQ(c.feature(), SeqFeature::kEntropyLow);
  // A non-finite z still counts one unit above its statistic's own allowance.
  Cusum d;
  d.update(std::nan(""), 0.0, 1.0, 20.0, 2.0, 0.0);
  EXPECT_DOUBLE_EQ(d.statistic(), 1.0);
  // The ARL sees the same allowances: class_cusum_arl with extra 0.5 on the rms equals k 1.5 there.
  const double a = class_cusum_arl(0.0, 1.0, 0.0, 1.0, 1.0, 7.0, 0.5, 0.0);
  const double want = 1.0 / (1.0 / cusum_arl(0.0, 1.0, 1.5, 7.0) + 2.0 / cusum_arl(0.0, 1.0, 1.0, 7.0));
  EXPECT_NEAR(a, want, 1e-9 * want);
}

TEST(CheckSequential, DayAllowanceRange) {
  SequentialConfig s;
  EXPECT_EQ(s.day_allowance, 3.0);
  s.day_allowance = -1.0;
  EXPECT_THROW(check_sequential(s), Error);
  s.day_allowance = 11.0;
  EXPECT_THROW(check_sequential(s), Error);
  s.day_allowance = 0.0;
  EXPECT_NO_THROW(check_sequential(s));
}

// Windows of white noise whose level is set per recording (day): the between-day spread of ln(rms_res)
// of the raw method is then the spread of the ln levels, which the estimate must find.
std::vector<std::vector<float>> noise_windows(const std::vector<double>& level, std::size_t n,
                                              unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<std::vector<float>> w(level.size(), std::vector<float>(n));
  for (std::size_t i = 0; i < level.size(); ++i)
    for (auto& x : w[i]) x = static_cast<float>(level[i] * g(rng));
  return w;
}

TEST(BuildClassBaseline, DaySpreadFromSeveralRecordings) {
  constexpr std::size_t kN = 256;
  // Three days of 8 windows at levels 1, 1.2, 0.9: ln levels 0, 0.182, -0.105.
  std::vector<double> level;
  std::vector<std::uint32_t> rec;
  const std::vector<double> day_level = {1.0, 1.2, 0.9};
  for (std::uint32_t d = 0; d < 3; ++d)
    for (int i = 0; i < 8; ++i) {
      level.push_back(day_level[d]);
      rec.push_back(d);
    }
  const auto w = noise_windows(level, kN, 5);
  ThresholdPolicy p;
  const ClassBaseline three = build_class_baseline(SegmentClass{}, w, {}, p, rec);
  const auto raw = static_cast<std::size_t>(Method::kRaw);
  const DaySpread& d = three.day_spread[raw];
  EXPECT_EQ(d.recordings, 3U);
  // The sd of ln(1, 1.2, 0.9) is 0.145; raw ln(rms) of 256 samples varies by ~0.044 within a day.
  std::printf("raw ln(rms_res): within %.4f, between estimate %.4f (ln levels sd 0.145)\n",
              d.log_rms_within_sd, d.log_rms_between_est);
  EXPECT_GT(d.log_rms_between_est, 0.1);
  EXPECT_LT(d.log_rms_between_est, 0.2);
  EXPECT_LT(d.log_rms_within_sd, 0.07);
  // Pooled with the prior (0.3 x within) as one more degree of freedom.
  const double prior = p.day_sd_floor * d.log_rms_within_sd;
  EXPECT_NEAR(d.log_rms_between_sd,
              std::sqrt((2.0 * d.log_rms_between_est * d.log_rms_between_est + prior * prior) / 3.0), 1e-12);
  // The same windows as one recording: the prior alone, and a band sqrt(1.09) times the sample sd.
  const ClassBaseline one = build_class_baseline(SegmentClass{}, w, {}, p);
  const DaySpread& o = one.day_spread[raw];
  EXPECT_EQ(o.recordings, 1U);
  EXPECT_EQ(o.log_rms_between_est, 0.0);
  EXPECT_NEAR(o.log_rms_between_sd, 0.3 * o.log_rms_within_sd, 1e-15);
  std::vector<double> rms_values;
  for (const auto& x : w) {
    double s = 0.0;
    for (const float v : x) s += static_cast<double>(v) * v;
    rms_values.push_back(std::sqrt(s / kN));
  }
  // The sample sd of the logs is the within sd with one recording.
  std::vector<double> logs;
  for (const double r : rms_values) logs.push_back(std::log(r));
  EXPECT_NEAR(o.log_rms_within_sd, feature_stats(logs).stddev, 1e-6);
  // With the floor at 0 the band is the session-6 one; the floor widens it by sqrt(1 + 0.09).
  ThresholdPolicy p0 = p;
  p0.day_sd_floor = 0.0;
  const ClassBaseline none = build_class_baseline(SegmentClass{}, w, {}, p0);
  const double m = one.log_rms_stats[raw].mean;  // the band is centred on the mean of ln(rms_res)
  EXPECT_NEAR(std::log(one.thresholds[raw].rms.hi) - m,
              std::sqrt(1.09) * (std::log(none.thresholds[raw].rms.hi) - m), 1e-9);
  EXPECT_THROW((void)build_class_baseline(SegmentClass{}, w, {}, p, std::vector<std::uint32_t>{0, 1}), Error);
}

// Bands that cover each training recording (ThresholdPolicy::cover_recordings, docs/method.md §5).
// Reference numbers: python3 (Debian 12), statistics.NormalDist / mean / stdev:
//  - Gaussian, alpha 0.05 (z = 1.959963984540054): {1, 2, 3, 4, 5} -> [-0.09897516152280739,
//    6.098975161522807]; {3, 5, 7, 9, 11} -> [0.8020496769543852, 13.197950323045614];
//  - Tolerance on ln, alpha 1e-3, confidence 0.9, n 6 (Natrella: k1 = 5.3015245165346805):
//    {0.9, 1.0, 1.1, 1.2, 1.3, 0.95} -> [0.5029034856386652, 2.2594868615475074].
TEST(CoverRecordings, UnionOfThePooledBandAndEachRecordingsOwnBand) {
  ThresholdPolicy p;
  p.kind = ThresholdPolicy::Kind::kGaussian;
  p.false_alarm_rate = 0.05;
  const std::vector<double> v = {1, 2, 3, 4, 5, 3, 5, 7, 9, 11, 100, 200};
  const std::vector<std::uint32_t> r = {4, 4, 4, 4, 4, 9,
                                        9, 9, 9, 9, 7, 7};  // recording 7: 2 values, skipped
  const Band b = cover_recordings(Band{2.0, 6.0}, v, r, p);
  EXPECT_NEAR(b.lo, -0.09897516152280739, 1e-12);  // recording 4's own lower end
  EXPECT_NEAR(b.hi, 13.197950323045614, 1e-12);    // recording 9's own upper end
  // A pooled band that already covers both stays as it is.
  const Band wide = cover_recordings(Band{-1.0, 20.0}, v, r, p);
  EXPECT_EQ(wide.lo, -1.0);
  EXPECT_EQ(wide.hi, 20.0);
  // One recording (no ids, or one distinct id) returns the pooled band unchanged.
  const std::vector<double> a = {1, 2, 3, 4, 5};
  const Band one = cover_recordings(Band{2.0, 6.0}, a, {}, p);
  EXPECT_EQ(one.lo, 2.0);
  EXPECT_EQ(one.hi, 6.0);
  const Band same = cover_recordings(Band{2.0, 6.0}, a, std::vector<std::uint32_t>(5, 3), p);
  EXPECT_EQ(same.hi, 6.0);
  EXPECT_THROW((void)cover_recordings(Band{2.0, 6.0}, a, std::vector<std::uint32_t>{0, 1}, p), Error);
}

TEST(CoverRecordings, LogToleranceOfEachRecording) {
  ThresholdPolicy p;  // tolerance, alpha 1e-3, confidence 0.9
  const std::vector<double> v = {1.0, 1.01, 0.99, 1.0, 1.02, 0.98, 0.9, 1.0, 1.1, 1.2, 1.3, 0.95};
  const std::vector<std::uint32_t> r = {0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 1, 1};
  const Band b = cover_recordings(Band{0.8, 1.25}, v, r, p, FeatureScale::kLog);
  EXPECT_NEAR(b.lo, 0.5029034856386652, 1e-6);  // the Phi^-1 of the code agrees with python to ~1e-15;
  EXPECT_NEAR(b.hi, 2.2594868615475074, 1e-6);  // Natrella's k1 is the same closed form
}

TEST(BuildClassBaseline, CoverRecordingsWidensOnlyForARecordingOutsideThePooledBand) {
  constexpr std::size_t kN = 256;
  // Four days of 10 windows; the last one spreads far more within the day (levels alternate x/÷ 1.35:
  // ln +-0.3 against ~0.044 for 256 noise samples), as the top of a load cycle did in the drift soak.
  std::vector<double> level;
  std::vector<std::uint32_t> rec;
  const std::vector<double> day_level = {1.0, 1.02, 0.98, 1.0};
  for (std::uint32_t d = 0; d < 4; ++d)
    for (int i = 0; i < 10; ++i) {
      level.push_back(d == 3 ? (i % 2 == 0 ? 1.35 : 1.0 / 1.35) : day_level[d]);
      rec.push_back(d);
    }
  const auto w = noise_windows(level, kN, 7);
  ThresholdPolicy p;
  EXPECT_TRUE(p.cover_recordings);  // the default since session 10 (docs/method.md §5)
  p.cover_recordings = false;
  const ClassBaseline pooled = build_class_baseline(SegmentClass{}, w, {}, p, rec);
  p.cover_recordings = true;
  const ClassBaseline cover = build_class_baseline(SegmentClass{}, w, {}, p, rec);
  const auto raw = static_cast<std::size_t>(Method::kRaw);
  // The raw rms_res of the fourth day's windows (leave-one-out against the others' mean: ~ its level).
  std::vector<double> day4;
  for (std::size_t i = 30; i < 40; ++i) {
    double s = 0.0;
    for (const float x : w[i]) s += static_cast<double>(x) * x;
    day4.push_back(std::sqrt(s / kN));
  }
  std::printf("raw rms hi: pooled %.4f, covering %.4f; day 4 max %.4f\n", pooled.thresholds[raw].rms.hi,
              cover.thresholds[raw].rms.hi, *std::max_element(day4.begin(), day4.end()));
  EXPECT_GT(cover.thresholds[raw].rms.hi, pooled.thresholds[raw].rms.hi);
  // Measured by this test (session 9; noise seed 7): the pooled hi 1.8030, the covering one 4.0770 (day
  // 4's own one-sided tolerance limit exp(m + k1(10) s) with s ~ 0.3).
  EXPECT_NEAR(pooled.thresholds[raw].rms.hi, 1.8030, 5e-4);
  EXPECT_NEAR(cover.thresholds[raw].rms.hi, 4.0770, 5e-4);
  EXPECT_LT(cover.thresholds[raw].rms.lo, pooled.thresholds[raw].rms.lo);
  EXPECT_GE(cover.thresholds[raw].entropy.hi, pooled.thresholds[raw].entropy.hi);
  EXPECT_LE(cover.thresholds[raw].entropy.lo, pooled.thresholds[raw].entropy.lo);
  // The day spread (and so the CUSUM) is the same: only the bands change.
  EXPECT_EQ(cover.day_spread[raw].log_rms_between_sd, pooled.day_spread[raw].log_rms_between_sd);
  // One recording: identical bands.
  const ClassBaseline one_cover = build_class_baseline(SegmentClass{}, w, {}, p);
  p.cover_recordings = false;
  const ClassBaseline one = build_class_baseline(SegmentClass{}, w, {}, p);
  EXPECT_EQ(one_cover.thresholds[raw].rms.hi, one.thresholds[raw].rms.hi);
  EXPECT_EQ(one_cover.thresholds[raw].entropy.lo, one.thresholds[raw].entropy.lo);
}

}  // namespace
}  // namespace ptda::dsp
