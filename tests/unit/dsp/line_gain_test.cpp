// PTDA line gain (docs/method.md §3): the line groups of a healthy mean spectrum and the per-window
// gain on each, against closed forms on bin-centred tones.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <random>
#include <vector>

#include "alloc_counter.hpp"
#include "ptda/dsp/analyzer.hpp"
#include "ptda/dsp/features.hpp"

namespace ptda::dsp {
namespace {

constexpr std::size_t kN = 1600;
constexpr std::size_t kBins = kN / 2 + 1;

// x[t] = sum_h amps[h] cos(2 pi bins[h] t / N + phases[h]) + noise.
std::vector<float> tones(const std::vector<std::size_t>& bins, const std::vector<double>& amps,
                         const std::vector<double>& phases, double noise_sd, std::mt19937& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<float> x(kN);
  for (std::size_t t = 0; t < kN; ++t) {
    double v = noise_sd * g(rng);
    for (std::size_t h = 0; h < bins.size(); ++h)
      v += amps[h] *
           std::cos(2.0 * std::numbers::pi * static_cast<double>((bins[h] * t) % kN) / kN + phases[h]);
    x[t] = static_cast<float>(v);
  }
  return x;
}

TEST(LineGroups, LinesTwelveDecibelsAboveTheLocalFloorWithOneBinOfSkirt) {
  std::vector<float> a(kBins, 1.0F);
  a[0] = 100.0F;  // DC is never a line
  a[50] = 10.0F;  // a line spread over two bins: one group [49, 53)
  a[51] = 8.0F;
  a[120] = 4.5F;  // just above 4x the floor
  a[200] = 3.9F;  // just below: not a line
  a[300] = 6.0F;  // two lines two bins apart: their skirts touch, merged into [299, 304)
  a[302] = 6.0F;
  a[kBins - 1] = 9.0F;  // at the Nyquist bin: the skirt is clipped to the spectrum
  const std::vector<LineGroup> g = find_line_groups(a);
  ASSERT_EQ(g.size(), 4U);
  EXPECT_EQ(g[0].begin, 49U);
  EXPECT_EQ(g[0].end, 53U);
  EXPECT_EQ(g[1].begin, 119U);
  EXPECT_EQ(g[1].end, 122U);
  EXPECT_EQ(g[2].begin, 299U);
  EXPECT_EQ(g[2].end, 304U);
  EXPECT_EQ(g[3].begin, kBins - 2);
  EXPECT_EQ(g[3].end, kBins);
  // A tilted floor (x10 across the spectrum) makes no lines: the floor is local.
  std::vector<float> tilt(kBins);
  for (std::size_t k = 0; k < kBins; ++k) tilt[k] = static_cast<float>(std::pow(10.0, double(k) / kBins));
  EXPECT_TRUE(find_line_groups(tilt).empty());
}

// A window whose tones are the healthy ones scaled by 1.3 (a load change): the paper's PTDA leaves
// 0.3 of each tone in the residual, rms 0.3 sqrt(sum A^2 / 2); with the line gain the gain of each
// group is exactly 1.3 and the residual vanishes (to float rounding).
TEST(LineGain, AScaledHarmonicLeavesNoResidualTheFloorAndNewLinesDo) {
  const std::vector<std::size_t> bins = {40, 97, 250};
  const std::vector<double> amps = {1.0, 0.5, 2.0};
  std::mt19937 rng(7);
  // Healthy mean magnitude of the tones alone: |X_k| = A N / 2 at each tone bin, 0 elsewhere (plus a
  // tiny floor so the line test has a floor to compare with).
  std::vector<float> mean(kBins, 1e-3F);
  for (std::size_t h = 0; h < bins.size(); ++h) mean[bins[h]] = static_cast<float>(amps[h] * kN / 2.0);
  const std::vector<LineGroup> groups = find_line_groups(mean);
  ASSERT_EQ(groups.size(), 3U);
  const std::vector<double> scaled = {1.3, 0.65, 2.6};
  const std::vector<float> x = tones(bins, scaled, {0.3, -1.2, 2.0}, 0.0, rng);
  const std::vector<float> tda(kN, 0.0F);
  WindowAnalyzer an(kN);
  const Features plain = an.analyze_with(x, mean, tda, Method::kPtda);
  const double expected = 0.3 * std::sqrt((1.0 + 0.25 + 4.0) / 2.0);
  EXPECT_NEAR(plain.rms_res, expected, 1e-4 * expected);
  const Features lg = an.analyze_with(x, mean, tda, Method::kPtda, groups);
  EXPECT_LT(lg.rms_res, 1e-4);
  // A new line (a fault's sideband at bin 103) stays in the residual whole: rms 0.2 / sqrt 2.
  std::vector<float> y = tones({40, 97, 103, 250}, {1.3, 0.65, 0.2, 2.6}, {0.3, -1.2, 0.5, 2.0}, 0.0, rng);
  const Features side = an.analyze_with(y, mean, tda, Method::kPtda, groups);
  EXPECT_NEAR(side.rms_res, 0.2 / std::sqrt(2.0), 2e-4);
  // Empty groups are the paper's PTDA, bit for bit, through analyze() too.
  ClassBaseline cls;
  cls.mean_magnitude = mean;
  cls.tda_mean = tda;
  const Features via_cls = an.analyze(x, cls, Method::kPtda);
  EXPECT_EQ(via_cls.rms_res, plain.rms_res);
  EXPECT_EQ(via_cls.entropy_res, plain.entropy_res);
  cls.line_groups = groups;
  const Features via_cls_lg = an.analyze(x, cls, Method::kPtda);
  EXPECT_EQ(via_cls_lg.rms_res, lg.rms_res);
}

TEST(LineGain, NoAllocationPerWindow) {
  std::mt19937 rng(3);
  std::vector<float> mean(kBins, 1.0F);
  mean[40] = 800.0F;
  const std::vector<LineGroup> groups = find_line_groups(mean);
  const std::vector<float> x = tones({40}, {1.1}, {0.0}, 0.01, rng);
  const std::vector<float> tda(kN, 0.0F);
  WindowAnalyzer an(kN);
  test::AllocScope scope;
  const Features f = an.analyze_with(x, mean, tda, Method::kPtda, groups);
  EXPECT_EQ(scope.count(), 0U);
  EXPECT_TRUE(std::isfinite(f.rms_res));
}

// Floor gain (docs/method.md §2): a window that is the healthy one scaled by 1.25 (a floor and lines 25 %
// higher on another day) has floor gain exactly 1.25 and no residual, where the line gain alone leaves
// 0.25 of the floor in it.
TEST(FloorGain, AScaledWindowHasTheScaleAsGainAndNoResidual) {
  std::mt19937 rng(11);
  std::vector<float> x0 = tones({40, 97, 250}, {1.0, 0.5, 2.0}, {0.3, -1.2, 2.0}, 0.05, rng);
  // DC is no part of the floor (a sensor offset keeps the healthy mean): remove it from the test signal.
  double dc = 0.0;
  for (const float v : x0) dc += v;
  for (float& v : x0) v -= static_cast<float>(dc / kN);
  WindowAnalyzer an(kN);
  std::vector<float> mean(kBins);
  an.magnitude(x0, mean);
  const std::vector<LineGroup> groups = find_line_groups(mean);
  ASSERT_EQ(groups.size(), 3U);
  std::vector<float> x(kN);
  for (std::size_t t = 0; t < kN; ++t) x[t] = 1.25F * x0[t];
  const std::vector<float> tda(kN, 0.0F);
  const Features lines_only = an.analyze_with(x, mean, tda, Method::kPtda, groups, false);
  EXPECT_EQ(an.floor_gain(), 1.0);
  // The floor part left by the line gain alone: 0.25 of the floor's rms (about 0.05).
  EXPECT_GT(lines_only.rms_res, 0.2 * 0.05);
  const Features f = an.analyze_with(x, mean, tda, Method::kPtda, groups, true);
  EXPECT_NEAR(an.floor_gain(), 1.25, 1e-5);
  EXPECT_LT(f.rms_res, 1e-3 * lines_only.rms_res);
}

// The median ignores a sparse change: a new line on one floor bin (a sideband) leaves g_f at 1.25 and
// stays in the residual whole, referred to the training floor: the time-domain residual of one bin k
// with residual magnitude M is a cosine of rms sqrt(2) M / N, divided by g_f.
TEST(FloorGain, ASidebandStaysInTheResidualReferredToTheTrainingFloor) {
  std::mt19937 rng(12);
  const std::vector<float> x0 = tones({40, 97, 250}, {1.0, 0.5, 2.0}, {0.3, -1.2, 2.0}, 0.05, rng);
  WindowAnalyzer an(kN);
  std::vector<float> mean(kBins);
  an.magnitude(x0, mean);
  const std::vector<LineGroup> groups = find_line_groups(mean);
  std::vector<float> x(kN);
  for (std::size_t t = 0; t < kN; ++t)
    x[t] =
        static_cast<float>(1.25 * x0[t] + 0.2 * std::cos(2.0 * std::numbers::pi * double(103 * t % kN) / kN));
  std::vector<float> mag(kBins);
  an.magnitude(x, mag);
  const double m = mag[103] - 1.25 * mean[103];
  const std::vector<float> tda(kN, 0.0F);
  const Features f = an.analyze_with(x, mean, tda, Method::kPtda, groups, true);
  EXPECT_NEAR(an.floor_gain(), 1.25, 1e-5);
  const double expected = std::sqrt(2.0) * std::abs(m) / kN / 1.25;
  EXPECT_NEAR(f.rms_res, expected, 1e-3 * expected);
  // Through analyze(): the class carries the flag.
  ClassBaseline cls;
  cls.mean_magnitude = mean;
  cls.tda_mean = tda;
  cls.line_groups = groups;
  cls.floor_gain = true;
  EXPECT_EQ(an.analyze(x, cls, Method::kPtda).rms_res, f.rms_res);
}

// Level referral: a whole window scaled by 1.9 (another day, every level nearly doubled, the defect with
// them) gives the same features, where the line gain alone leaves the doubled floor in rms_res. The defect
// here is a tone on a line's skirt bin (inside a group) and one on a floor bin.
TEST(FloorGain, AWindowScaledAsAWholeKeepsItsFeatures) {
  std::mt19937 rng(13);
  std::vector<float> x0 = tones({40, 97, 250}, {1.0, 0.5, 2.0}, {0.3, -1.2, 2.0}, 0.05, rng);
  WindowAnalyzer an(kN);
  std::vector<float> mean(kBins);
  an.magnitude(x0, mean);
  const std::vector<LineGroup> groups = find_line_groups(mean);
  std::mt19937 rng2(14);
  std::vector<float> x1 =
      tones({40, 41, 97, 180, 250}, {1.0, 0.1, 0.5, 0.05, 2.0}, {0.4, 1.0, -1.1, 0.2, 2.1}, 0.05, rng2);
  double dc = 0.0;  // DC keeps the healthy mean (a sensor offset does not scale): none here
  for (const float v : x1) dc += v;
  for (float& v : x1) v -= static_cast<float>(dc / kN);
  // 1.9, not 2: every gain of x1 (about 1) times the scale must stay inside the 6 dB allowance.
  std::vector<float> x2(kN);
  for (std::size_t t = 0; t < kN; ++t) x2[t] = 1.9F * x1[t];
  const std::vector<float> tda(kN, 0.0F);
  const Features a1 = an.analyze_with(x1, mean, tda, Method::kPtda, groups, true);
  const double physical_rms1 = rms(an.residual());  // x1's residual before the referral
  const Features a2 = an.analyze_with(x2, mean, tda, Method::kPtda, groups, true);
  EXPECT_NEAR(a2.rms_res, a1.rms_res, 1e-5 * a1.rms_res);
  EXPECT_NEAR(a2.entropy_res, a1.entropy_res, 1e-5);
  const Features l1 = an.analyze_with(x1, mean, tda, Method::kPtda, groups, false);
  const Features l2 = an.analyze_with(x2, mean, tda, Method::kPtda, groups, false);
  EXPECT_GT(l2.rms_res, 1.5 * l1.rms_res);  // the raised floor stays in: 1.9 |X| - a
  // Beyond the 6 dB allowance the excess counts: at four times the level every part is referred by 2
  // only, so rms_res is twice x1's physical residual (a vibration that quadrupled must not look healthy).
  std::vector<float> x4(kN);
  for (std::size_t t = 0; t < kN; ++t) x4[t] = 4.0F * x1[t];
  const Features a4 = an.analyze_with(x4, mean, tda, Method::kPtda, groups, true);
  EXPECT_NEAR(a4.rms_res, 2.0 * physical_rms1, 1e-4 * physical_rms1);
  EXPECT_GT(a4.rms_res, 1.8 * a1.rms_res);
  // The defect is seen: against the healthy window itself the referred residual is far smaller.
  EXPECT_GT(a1.rms_res, 10.0 * an.analyze_with(x0, mean, tda, Method::kPtda, groups, true).rms_res);
}

// A silent channel has no floor to refer to: g_f stays 1, so it still shows as a low residual.
TEST(FloorGain, ASilentWindowKeepsGainOne) {
  std::vector<float> mean(kBins, 1.0F);
  mean[40] = 800.0F;
  const std::vector<LineGroup> groups = find_line_groups(mean);
  const std::vector<float> x(kN, 0.0F);
  const std::vector<float> tda(kN, 0.0F);
  WindowAnalyzer an(kN);
  test::AllocScope scope;
  const Features f = an.analyze_with(x, mean, tda, Method::kPtda, groups, true);
  EXPECT_EQ(scope.count(), 0U);
  EXPECT_EQ(an.floor_gain(), 1.0);
  EXPECT_TRUE(std::isfinite(f.rms_res));
}

TEST(LineGain, PrepareFollowsThePolicy) {
  Baseline b;
  ClassBaseline c;
  c.mean_magnitude.assign(kBins, 1.0F);
  c.mean_magnitude[60] = 50.0F;
  b.classes.push_back(c);
  EXPECT_TRUE(b.policy.ptda_line_gain);  // the default since session 5
  b.policy.ptda_line_gain = false;
  b.classes[0].line_groups = {LineGroup{1, 2}};
  prepare_line_groups(b);
  EXPECT_TRUE(b.classes[0].line_groups.empty());
  b.policy.ptda_line_gain = true;
  prepare_line_groups(b);
  ASSERT_EQ(b.classes[0].line_groups.size(), 1U);
  EXPECT_EQ(b.classes[0].line_groups[0].begin, 59U);
  EXPECT_EQ(b.classes[0].line_groups[0].end, 62U);
  EXPECT_TRUE(b.classes[0].floor_gain);  // the default since session 6
  b.policy.ptda_floor_gain = false;
  prepare_line_groups(b);
  EXPECT_FALSE(b.classes[0].floor_gain);
  b.policy.ptda_floor_gain = true;
  prepare_line_groups(b);
  EXPECT_TRUE(b.classes[0].floor_gain);
}

// The baseline reader prepares the classes and the engine prepares its copy again: the second call
// must skip an unchanged class (find_line_groups() once per `ptda monitor`, issue 13) and must still
// recompute after any change of its inputs.
TEST(LineGain, PrepareAgainSkipsOnlyUnchangedClasses) {
  Baseline b;
  ClassBaseline c;
  c.mean_magnitude.assign(kBins, 1.0F);
  c.mean_magnitude[60] = 50.0F;
  c.tda_mean.assign(kN, 0.5F);
  b.classes.push_back(c);
  prepare_line_groups(b);
  const ClassBaseline& p = b.classes[0];
  ASSERT_EQ(p.line_groups.size(), 1U);
  EXPECT_EQ(p.line_groups[0].begin, 59U);
  EXPECT_NE(p.prepared_key, 0U);
  ASSERT_EQ(p.tda_spectrum.size(), kBins);
  EXPECT_FLOAT_EQ(p.tda_spectrum[0].real(), 0.5F * kN);

  // Outputs overwritten by hand on an unchanged class stay: proof that the second call skipped.
  b.classes[0].line_groups = {LineGroup{1, 2}};
  prepare_line_groups(b);
  ASSERT_EQ(b.classes[0].line_groups.size(), 1U);
  EXPECT_EQ(b.classes[0].line_groups[0].begin, 1U);

  // Any input change recomputes: the mean spectrum, the TDA mean, or a policy flag.
  b.classes[0].mean_magnitude[60] = 1.0F;
  b.classes[0].mean_magnitude[100] = 50.0F;
  prepare_line_groups(b);
  ASSERT_EQ(b.classes[0].line_groups.size(), 1U);
  EXPECT_EQ(b.classes[0].line_groups[0].begin, 99U);
  b.classes[0].tda_mean[0] = 1.5F;
  prepare_line_groups(b);
  EXPECT_FLOAT_EQ(b.classes[0].tda_spectrum[0].real(), 0.5F * kN + 1.0F);
  b.classes[0].line_groups.clear();
  b.policy.ptda_floor_gain = false;
  prepare_line_groups(b);
  EXPECT_EQ(b.classes[0].line_groups.size(), 1U);
  EXPECT_FALSE(b.classes[0].floor_gain);
}

}  // namespace
}  // namespace ptda::dsp

namespace ptda::dsp {
namespace {

// local_floor_medians() (one sliding sorted window) against local_floor_median() (one nth_element per
// bin) at every bin: lengths around the 65-bin window, tie-heavy and continuous values, a real-length
// spectrum (N/2 + 1 = 6401), and a NaN (the per-bin path).
TEST(LocalFloorMedians, EqualsThePerBinMedianAtEveryBin) {
  std::mt19937 rng(16);
  std::uniform_real_distribution<float> u(0.0F, 10.0F);
  std::uniform_int_distribution<int> few(0, 4);
  std::vector<float> scratch;
  std::size_t compared = 0;
  for (const std::size_t n :
       {0UL, 1UL, 2UL, 3UL, 33UL, 34UL, 65UL, 66UL, 67UL, 98UL, 99UL, 100UL, 131UL, 500UL, 6401UL}) {
    for (int kind = 0; kind < 3; ++kind) {
      std::vector<float> a(n);
      for (float& x : a) x = kind == 0 ? u(rng) : static_cast<float>(few(rng));
      if (kind == 2 && n > 40) a[40] = std::numeric_limits<float>::quiet_NaN();
      const std::vector<float> m = local_floor_medians(a);
      ASSERT_EQ(m.size(), n);
      if (n > 0) {
        EXPECT_EQ(m[0], 0.0F);
      }
      for (std::size_t k = 1; k < n; ++k) {
        if (kind == 2 && n > 40) {
          // With a NaN both give nth_element's answer; compare bits (NaN != NaN).
          const float r = local_floor_median(a, k, scratch);
          EXPECT_EQ(std::memcmp(&m[k], &r, sizeof r), 0) << "n " << n << " k " << k;
        } else {
          const float r = local_floor_median(a, k, scratch);
          ASSERT_EQ(m[k], r) << "n " << n << " kind " << kind << " k " << k;
        }
        ++compared;
      }
    }
  }
  EXPECT_GT(compared, 20000U);
}

// Values by hand: a[k] = k for k = 1..99 (a[0] = 1000, never in a window). Bin 1's window is bins
// 1..33 (median 17), bin 40's is 8..72 (median 40), bin 98's is 66..98 (median 82).
TEST(LocalFloorMedians, KnownValuesOfARamp) {
  std::vector<float> a(99);
  a[0] = 1000.0F;
  for (std::size_t k = 1; k < a.size(); ++k) a[k] = static_cast<float>(k);
  const std::vector<float> m = local_floor_medians(a);
  EXPECT_EQ(m[1], 17.0F);
  EXPECT_EQ(m[33], 33.0F);
  EXPECT_EQ(m[40], 40.0F);
  EXPECT_EQ(m[98], 82.0F);
}

}  // namespace
}  // namespace ptda::dsp

namespace ptda::dsp {
namespace {

// The floor-given overload (clean_floor_bins() computes the floor once for both uses) finds the same
// groups as the one-argument form, and nothing when the floor does not belong to the spectrum.
TEST(FindLineGroups, WithTheFloorGivenEqualsTheOneArgumentForm) {
  std::mt19937 rng(31);
  std::uniform_real_distribution<float> u(0.5F, 1.5F);
  std::vector<float> a(6401);
  for (float& x : a) x = u(rng);
  for (const std::size_t k : {40UL, 41UL, 800UL, 2600UL, 2601UL, 2602UL, 6390UL}) a[k] = 12.0F;
  const std::vector<LineGroup> one = find_line_groups(a);
  const std::vector<LineGroup> two = find_line_groups(a, local_floor_medians(a));
  ASSERT_EQ(one.size(), 4U);  // 40-41, 800, 2600-2602 and 6390, each widened by one bin per side
  ASSERT_EQ(two.size(), one.size());
  for (std::size_t i = 0; i < one.size(); ++i) {
    EXPECT_EQ(two[i].begin, one[i].begin);
    EXPECT_EQ(two[i].end, one[i].end);
  }
  EXPECT_EQ(one[0].begin, 39U);
  EXPECT_EQ(one[0].end, 43U);
  EXPECT_TRUE(find_line_groups(a, std::vector<float>(a.size() - 1, 1.0F)).empty());
}

}  // namespace
}  // namespace ptda::dsp
