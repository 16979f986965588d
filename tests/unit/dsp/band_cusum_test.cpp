// The band CUSUM (docs/method.md §6 "Band detector"): band geometry, clean floor bins, training's band
// statistics, the per-band recursion and its day allowance, and MonitorEngine's band evidence.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "ptda/common/error.hpp"
#include "ptda/dsp/analyzer.hpp"
#include "ptda/dsp/band_energy.hpp"
#include "ptda/dsp/monitor_engine.hpp"
#include "ptda/dsp/training.hpp"

namespace {

using namespace ptda::dsp;

constexpr std::size_t kN = 1024;
constexpr double kFs = 25600.0;    // bins of 25 Hz
constexpr std::size_t kBand = 10;  // of 32 over bins 1..512: bins 161..176, 4025-4400 Hz

// One window: a mesh tone at bin 64 (a line), white noise (sd 0.1) and a band noise in band kBand (16
// cosines at bins 161..176 of amplitude `band_amp`, random phases). With band_amp <= 0.007 the band's
// mean magnitude stays within 6 dB of the floor: its bins are clean.
std::vector<float> make_window(std::mt19937& rng, double band_amp) {
  std::normal_distribution<double> noise(0.0, 0.1);
  std::uniform_real_distribution<double> phase(0.0, 2.0 * std::numbers::pi);
  std::vector<double> ph(16);
  for (double& p : ph) p = phase(rng);
  const double tone_phase = phase(rng);
  std::vector<float> x(kN);
  for (std::size_t n = 0; n < kN; ++n) {
    const double t = 2.0 * std::numbers::pi * static_cast<double>(n) / static_cast<double>(kN);
    double v = std::sin(64.0 * t + tone_phase) + noise(rng);
    for (std::size_t j = 0; j < 16; ++j) v += band_amp * std::cos(static_cast<double>(161 + j) * t + ph[j]);
    x[n] = static_cast<float>(v);
  }
  return x;
}

// Three training days of 12 windows whose band kBand differs from day to day (a persistent offset).
struct TrainingSet {
  std::vector<std::vector<float>> windows;
  std::vector<std::uint32_t> recordings;
};
TrainingSet training_set() {
  TrainingSet t;
  std::mt19937 rng(12);
  const double amp[3] = {0.003, 0.005, 0.007};
  for (std::uint32_t day = 0; day < 3; ++day) {
    for (int i = 0; i < 12; ++i) {
      t.windows.push_back(make_window(rng, amp[day]));
      t.recordings.push_back(day);
    }
  }
  return t;
}

Baseline band_baseline(std::uint32_t band_count) {
  const TrainingSet t = training_set();
  ThresholdPolicy policy;
  policy.band_count = band_count;
  SegmentClass seg;
  seg.speed_rad_s = 2.0;
  seg.speed_tol_rad_s = 0.1;
  Baseline b;
  b.fs_hz = kFs;
  b.window_len = kN;
  b.policy = policy;
  b.classes.push_back(build_class_baseline(seg, t.windows, {}, policy, t.recordings));
  prepare_line_groups(b);
  return b;
}

ExtractionConfig extraction() {
  ExtractionConfig c;
  c.window_len = kN;
  c.hop = kN;
  return c;
}

// `band_cusum = true` said in the configuration: required (errors instead of the default's fallback).
DecisionConfig band_on() {
  DecisionConfig d{3, 5, {}, {}, {}};
  d.band.enabled = true;
  d.band.required = true;
  return d;
}

DecisionConfig band_off() {
  DecisionConfig d{3, 5, {}, {}, {}};
  d.band.enabled = false;
  return d;
}

TEST(BandEnergy, EdgesSplitBinsOneToHalfEvenly) {
  EXPECT_EQ(band_edge(512, 32, 0), 1U);
  EXPECT_EQ(band_edge(512, 32, 10), 161U);
  EXPECT_EQ(band_edge(512, 32, 11), 177U);
  EXPECT_EQ(band_edge(512, 32, 32), 513U);
  // Not divisible: 100 bins in 32 bands of 3 or 4 bins, the last ending at bin 100.
  for (std::size_t b = 0; b < 32; ++b) {
    const std::size_t w = band_edge(100, 32, b + 1) - band_edge(100, 32, b);
    EXPECT_TRUE(w == 3 || w == 4) << b;
  }
  EXPECT_EQ(band_edge(100, 32, 32), 101U);
}

TEST(BandEnergy, CleanBinsExcludeLinesAndTheirSkirts) {
  std::vector<float> a(257, 1.0F);
  a[100] = 10.0F;  // a line (> 4 x floor): with its neighbours 99 and 101 a line group
  a[98] = 3.0F;    // a skirt bin: above 2 x floor (6 dB) but not a line
  a[150] = 1.9F;   // within 6 dB of the floor: clean
  const std::vector<unsigned char> c = clean_floor_bins(a);
  EXPECT_EQ(c[0], 0);  // DC
  EXPECT_EQ(c[1], 1);
  EXPECT_EQ(c[97], 1);
  EXPECT_EQ(c[98], 0);
  EXPECT_EQ(c[99], 0);
  EXPECT_EQ(c[100], 0);
  EXPECT_EQ(c[101], 0);
  EXPECT_EQ(c[102], 1);
  EXPECT_EQ(c[150], 1);
  // Energies summed over the clean bins only: band 3 of 8 over 256 bins is bins 97..128.
  std::vector<float> e(257, 0.0F);
  for (std::size_t k = 97; k < 129; ++k) e[k] = static_cast<float>(k);
  std::array<double, 8> ln{};
  band_log_energies(e, c, 8, ln);
  const double want = 97.0 + (102.0 + 128.0) * 27.0 / 2.0;  // 97 plus 102..128 (98..101 not clean)
  EXPECT_NEAR(ln[3], std::log(want), 1e-12);
  EXPECT_EQ(ln[0], std::log(1e-30));  // no energy: the floor of the log
  std::array<std::uint32_t, 8> counts{};
  clean_bins_per_band(c, 8, counts);
  EXPECT_EQ(counts[3], 28U);
  EXPECT_EQ(counts[0], 32U);
}

// Training's band statistics are the random-effects split of each window's leave-one-out ln band energy
// (recomputed here from the analyzer, window by window) with the days as groups.
TEST(BandCusumTraining, StatisticsAreTheLeaveOneOutBandEnergiesByDay) {
  const TrainingSet t = training_set();
  const Baseline b = band_baseline(32);
  const ClassBaseline& c = b.classes[0];
  ASSERT_EQ(c.band_stats.size(), 32U);
  EXPECT_EQ(c.band_recordings, 3U);
  const std::vector<unsigned char> clean = clean_floor_bins(c.mean_magnitude);
  WindowAnalyzer an(kN);
  const std::size_t bins = kN / 2 + 1;
  std::vector<std::vector<float>> mags(t.windows.size(), std::vector<float>(bins));
  std::vector<double> total(bins, 0.0);
  for (std::size_t i = 0; i < t.windows.size(); ++i) {
    an.magnitude(t.windows[i], mags[i]);
    for (std::size_t k = 0; k < bins; ++k) total[k] += mags[i][k];
  }
  std::vector<std::vector<double>> per_band(32);
  std::vector<float> loo(bins);
  const std::vector<float> no_tda(kN, 0.0F);
  for (std::size_t i = 0; i < t.windows.size(); ++i) {
    for (std::size_t k = 0; k < bins; ++k) {
      loo[k] = static_cast<float>((total[k] - static_cast<double>(mags[i][k])) /
                                  static_cast<double>(t.windows.size() - 1));
    }
    (void)an.analyze_with(t.windows[i], loo, no_tda, Method::kPtda, c.line_groups, true);
    std::array<double, 32> ln{};
    band_log_energies(an.residual_energy(), clean, 32, ln);
    for (std::size_t band = 0; band < 32; ++band) per_band[band].push_back(ln[band]);
  }
  std::array<std::uint32_t, 32> counts{};
  clean_bins_per_band(clean, 32, counts);
  for (std::size_t band = 0; band < 32; ++band) {
    const VarianceComponents v = variance_components(per_band[band], t.recordings);
    const BandEnergyStats& s = c.band_stats[band];
    EXPECT_NEAR(s.mean, v.mean, 1e-9) << band;
    EXPECT_NEAR(s.within_sd, std::sqrt(v.within_var), 1e-9) << band;
    EXPECT_NEAR(s.between_est, std::sqrt(v.between_var), 1e-9) << band;
    EXPECT_EQ(s.between_sd, std::max(s.between_est, 0.3 * s.within_sd)) << band;
    EXPECT_EQ(s.clean_bins, counts[band]) << band;
  }
  // The band with the day offsets: 16 clean bins, a between-day estimate above the 0.3 x within prior
  // (so it is the one used) and above the median band's (with 3 days the estimate of a band without a
  // day offset is itself noisy: 2 degrees of freedom).
  EXPECT_EQ(c.band_stats[kBand].clean_bins, 16U);
  std::vector<double> est;
  for (const BandEnergyStats& st : c.band_stats) est.push_back(st.between_est);
  std::nth_element(est.begin(), est.begin() + 16, est.end());
  EXPECT_GT(c.band_stats[kBand].between_est, est[16]);
  EXPECT_EQ(c.band_stats[kBand].between_sd, c.band_stats[kBand].between_est);
  EXPECT_GT(c.band_stats[kBand].between_est, 0.3 * c.band_stats[kBand].within_sd);
}

// The recursion S <- min(cap, max(0, S + x - k)) per band, alarm when S > h: with x = 3, k = 1 the
// statistic grows by 2 per window, is 10 (not above h = 10) after 5 windows and 12 (the cap h +
// (n - k_of_n) k = 10 + 2) after 6. Healthy windows (x = 0) then take 1 per window: 11, then 10 ends it.
TEST(BandCusumDecision, CrossesHAfterTheComputedWindowsAndNamesTheBand) {
  DecisionConfig d = band_on();
  d.band.half_bins = 512;
  d.band.bin_hz = 25.0;
  DecisionState st(d, 2);
  WindowResult w;
  for (int i = 1; i <= 6; ++i) {
    w = WindowResult{};
    w.band_count = 32;
    w.band_excess[5] = 3.0F;
    st.scored(w, 0);
    EXPECT_EQ(w.band_statistic, std::min(12.0, 2.0 * i)) << i;
    EXPECT_EQ(w.band_index, 5) << i;
    EXPECT_EQ(w.band_alarm, i == 6) << i;
    EXPECT_EQ(w.alarm, i == 6) << i;
  }
  EXPECT_EQ(w.detector, AlarmDetector::kBand);
  EXPECT_STREQ(alarm_detector_name(w.detector), "band");
  EXPECT_EQ(w.band_max_index, 5);
  EXPECT_EQ(w.band_max_class, 0);
  EXPECT_EQ(w.band_lo_hz, 81 * 25.0);  // bins 81..96 of band 5
  EXPECT_EQ(w.band_hi_hz, 96 * 25.0);
  // The other class's statistics are its own.
  WindowResult other;
  other.band_count = 32;
  st.scored(other, 1);
  EXPECT_EQ(other.band_statistic, 0.0);
  EXPECT_EQ(other.band_max_statistic, 12.0);
  EXPECT_TRUE(other.band_alarm);
  WindowResult healthy;
  healthy.band_count = 32;
  st.scored(healthy, 0);
  EXPECT_EQ(healthy.band_statistic, 11.0);
  EXPECT_TRUE(healthy.band_alarm);
  st.scored(healthy, 0);
  EXPECT_EQ(healthy.band_statistic, 10.0);
  EXPECT_FALSE(healthy.band_alarm);
  // A non-finite increment counts as k + 1.
  WindowResult nan;
  nan.band_count = 32;
  nan.band_excess[7] = std::numeric_limits<float>::quiet_NaN();
  st.scored(nan, 1);
  EXPECT_EQ(nan.band_statistic, 1.0);
  // Off: no band fields, the detectors of before.
  DecisionState off(band_off(), 1);
  WindowResult o;
  o.band_count = 32;
  o.band_excess[5] = 100.0F;
  off.scored(o, 0);
  EXPECT_FALSE(o.band_on);
  EXPECT_FALSE(o.band_alarm);
  EXPECT_EQ(o.detector, AlarmDetector::kNone);
}

// band_cusum_step_cap (session 38; none by default): with a cap of 2.5 a window with x = 20 adds 2.5
// (20 - k = 19 uncapped, which alone crosses h = 10), so the band alarms at the fifth such window (12.5 >
// 10, held at the cap C = 12); a healthy window still takes k off. The default: one window alarms.
TEST(BandCusumDecision, AStepCapLimitsWhatOneWindowAdds) {
  DecisionConfig d = band_on();
  EXPECT_EQ(d.band.step_cap, kNoStepCap);
  DecisionState uncapped(d, 1);
  WindowResult u;
  u.band_count = 32;
  u.band_excess[3] = 20.0F;
  uncapped.scored(u, 0);
  EXPECT_EQ(u.band_statistic, 12.0);
  EXPECT_TRUE(u.band_alarm);
  d.band.step_cap = 2.5;
  DecisionState st(d, 1);
  for (int i = 1; i <= 5; ++i) {
    WindowResult w;
    w.band_count = 32;
    w.band_excess[3] = 20.0F;
    st.scored(w, 0);
    EXPECT_EQ(w.band_statistic, std::min(12.0, 2.5 * i)) << i;
    EXPECT_EQ(w.band_alarm, i == 5) << i;
  }
  WindowResult healthy;
  healthy.band_count = 32;
  st.scored(healthy, 0);
  EXPECT_EQ(healthy.band_statistic, 11.0);
  d.band.step_cap = 0.0;
  EXPECT_THROW(DecisionState bad(d, 1), ptda::Error);
}

// Several bands at the cap: the one that went above h first is reported, not the lowest index.
TEST(BandCusumDecision, AmongEqualStatisticsTheFirstToCrossIsReported) {
  DecisionState st(band_on(), 1);
  WindowResult w;
  for (int i = 0; i < 12; ++i) {
    w = WindowResult{};
    w.band_count = 32;
    w.band_excess[20] = 5.0F;                 // above h = 10 after 3 windows (4, 8, 12)
    w.band_excess[3] = i >= 2 ? 5.0F : 0.0F;  // two windows later
    st.scored(w, 0);
  }
  EXPECT_EQ(w.band_statistic, 12.0);  // both at the cap 10 + (5 - 3) x 1
  EXPECT_EQ(w.band_index, 20);
  EXPECT_EQ(w.band_max_index, 20);
}

// A persistent new-day offset within the between-day term does not accumulate. Band sds within 0.2,
// between 0.3, R = 3 days: total sd sqrt(0.2^2 + 0.3^2) = 0.360555. An offset of 0.3 (one between-day
// sd) gives z = 0.832 < k = 1: never. An offset of 0.5 gives z = 1.38675: S = 0.38675 w, above h = 10
// first at w = 26 (25 -> 9.67, 26 -> 10.06). With band_cusum_day_allowance 1 the allowance is
// 0.3 sqrt(1 + 1/3) / 0.360555 = 0.960769 and the same offset (excess 0.42598) never accumulates.
TEST(BandCusumDecision, DayOffsetWithinTheBetweenDayTermDoesNotAlarm) {
  ClassBaseline c;
  c.band_recordings = 3;
  c.band_stats.assign(4, BandEnergyStats{0.0, 0.2, 0.3, 0.3, 16});
  const BandScale s0 = band_scale(c, 0.0);
  const BandScale s1 = band_scale(c, 1.0);
  EXPECT_NEAR(s0.sd[2], 0.360555127546399, 1e-12);
  EXPECT_EQ(s0.allowance[2], 0.0);
  EXPECT_NEAR(s1.allowance[2], 0.960768922830522, 1e-12);
  const auto first_alarm = [&](const BandScale& s, double offset, int windows) {
    DecisionState st(band_on(), 1);
    for (int i = 1; i <= windows; ++i) {
      WindowResult w;
      w.band_count = 4;
      for (std::size_t b = 0; b < 4; ++b) {
        w.band_excess[b] =
            static_cast<float>((s.mean[b] + (b == 2 ? offset : 0.0) - s.mean[b]) / s.sd[b] - s.allowance[b]);
      }
      st.scored(w, 0);
      if (w.band_alarm) return i;
    }
    return 0;
  };
  EXPECT_EQ(first_alarm(s0, 0.3, 1000), 0);
  EXPECT_EQ(first_alarm(s0, 0.5, 1000), 26);
  EXPECT_EQ(first_alarm(s1, 0.5, 1000), 0);
  // A band without clean bins is not used.
  c.band_stats[1].clean_bins = 0;
  EXPECT_EQ(band_scale(c, 0.0).active[1], 0);
}

TEST(BandCusumEngine, ABaselineWithoutBandStatisticsIsAClearError) {
  const Baseline old = band_baseline(0);  // as format <= 6 reads: no band statistics
  try {
    MonitorEngine e(old, extraction(), band_on(), Method::kPtda, kFs, 0);
    FAIL() << "band CUSUM on a baseline without band statistics";
  } catch (const ptda::Error& e) {
    EXPECT_NE(
        std::string(e.what()).find("this baseline has none: retrain it with [decision] band_cusum = true"),
        std::string::npos)
        << e.what();
  }
  EXPECT_NO_THROW(MonitorEngine(old, extraction(), band_off(), Method::kPtda, kFs, 0));
  const Baseline b = band_baseline(32);
  DecisionConfig d16 = band_on();
  d16.band.band_count = 16;
  try {
    MonitorEngine e(b, extraction(), d16, Method::kPtda, kFs, 0);
    FAIL() << "band count mismatch";
  } catch (const ptda::Error& e) {
    EXPECT_NE(std::string(e.what()).find("band_count = 16 but the baseline was trained with 32 bands"),
              std::string::npos)
        << e.what();
  }
  try {
    MonitorEngine e(b, extraction(), band_on(), Method::kTda, kFs, 0);
    FAIL() << "band CUSUM on TDA";
  } catch (const ptda::Error& e) {
    EXPECT_NE(std::string(e.what()).find("band_cusum needs [monitor] method = \"ptda\""), std::string::npos)
        << e.what();
  }
  Baseline forged = b;
  forged.classes[0].band_stats[kBand].clean_bins = 3;
  try {
    MonitorEngine e(forged, extraction(), band_on(), Method::kPtda, kFs, 0);
    FAIL() << "clean bins that do not belong to the mean";
  } catch (const ptda::Error& e) {
    EXPECT_NE(std::string(e.what()).find("band 10 has 3 clean bins stored but its mean spectrum gives 16"),
              std::string::npos)
        << e.what();
  }
}

// End to end: the engine's per-band increments are (ln E_b - mean_b) / sd_b of the window's own referred
// residual (recomputed here with a second analyzer), a healthy new day at the highest training day's
// level stays quiet, and a band noise 4x stronger (+12 dB in amplitude) raises the band alarm in band 10
// exactly when the recursion on those increments crosses h.
// On by default (session 13) but not said in the configuration: where it cannot run (a baseline of format
// <= 6, another band count, TDA or raw) the band detector is off with a reason, never an error; where it
// can, it runs.
TEST(BandCusumEngine, OnByDefaultItRunsWhereItCanAndSaysWhyNotElsewhere) {
  DecisionConfig def{3, 5, {}, {}, {}};
  ASSERT_TRUE(def.band.enabled);
  ASSERT_FALSE(def.band.required);
  const Baseline old = band_baseline(0);
  const Baseline b = band_baseline(32);
  {
    const MonitorEngine e(old, extraction(), def, Method::kPtda, kFs, 0);
    EXPECT_FALSE(e.band_cusum_on());
    EXPECT_NE(e.band_off_reason().find("the baseline has no band statistics"), std::string::npos)
        << e.band_off_reason();
    EXPECT_FALSE(effective_band(def, old, Method::kPtda).band.enabled);
  }
  {
    const MonitorEngine e(b, extraction(), def, Method::kTda, kFs, 0);
    EXPECT_FALSE(e.band_cusum_on());
    EXPECT_EQ(e.band_off_reason(), "method \"tda\" (the band statistics are those of the PTDA residual)");
  }
  {
    DecisionConfig d16 = def;
    d16.band.band_count = 16;
    const MonitorEngine e(b, extraction(), d16, Method::kPtda, kFs, 0);
    EXPECT_FALSE(e.band_cusum_on());
    EXPECT_EQ(e.band_off_reason(), "the baseline has 32 bands, [decision] band_count is 16");
  }
  {
    const MonitorEngine e(b, extraction(), def, Method::kPtda, kFs, 0);
    EXPECT_TRUE(e.band_cusum_on());
    EXPECT_TRUE(e.band_off_reason().empty());
    EXPECT_TRUE(effective_band(def, b, Method::kPtda).band.enabled);
  }
  {
    const MonitorEngine e(b, extraction(), band_off(), Method::kPtda, kFs, 0);
    EXPECT_FALSE(e.band_cusum_on());
    EXPECT_TRUE(e.band_off_reason().empty());  // switched off by the configuration: nothing to explain
  }
}

TEST(BandCusumEngine, EvidenceIsTheRecursionOnTheWindowsOwnResidual) {
  const Baseline b = band_baseline(32);
  const ClassBaseline& c = b.classes[0];
  MonitorEngine engine(b, extraction(), band_on(), Method::kPtda, kFs, 0);
  WindowAnalyzer an(kN);
  const std::vector<unsigned char> clean = clean_floor_bins(c.mean_magnitude);
  // The engine's increments subtract the configured day allowance (default 1 since session 12).
  const double q = band_on().band.day_allowance;
  EXPECT_EQ(q, 1.0);
  const BandScale s = band_scale(c, q);
  std::mt19937 rng(77);
  WindowRef ref;
  ref.speed_rad_s = 2.0;
  WindowResult w;
  double top = 0.0;
  for (int i = 0; i < 300; ++i) {
    const std::vector<float> x = make_window(rng, 0.007);
    ref.seq = static_cast<std::uint64_t>(i);
    engine.judge_window(ref, x, w);
    ASSERT_EQ(w.status, WindowStatus::kScored);
    ASSERT_TRUE(w.band_on);
    EXPECT_FALSE(w.band_alarm) << "healthy window " << i << ", band " << w.band_max_index;
    top = std::max(top, w.band_max_statistic);
  }
  EXPECT_LT(top, 10.0);
  // The faulty day on a fresh engine (statistics from 0), beside the reference recursion on band 10.
  MonitorEngine fresh(b, extraction(), band_on(), Method::kPtda, kFs, 0);
  double s10 = 0.0;
  int expected_alarm = -1;
  int engine_alarm = -1;
  for (int i = 0; i < 40; ++i) {
    const std::vector<float> x = make_window(rng, 0.028);
    ref.seq = static_cast<std::uint64_t>(300 + i);
    fresh.judge_window(ref, x, w);
    (void)an.analyze(x, c, Method::kPtda);
    std::array<double, 32> ln{};
    band_log_energies(an.residual_energy(), clean, 32, ln);
    for (std::size_t band = 0; band < 32; ++band) {
      const double z = s.active[band] != 0 ? (ln[band] - s.mean[band]) / s.sd[band] - s.allowance[band] : 0.0;
      EXPECT_NEAR(w.band_excess[band], z, 1e-5 * std::max(1.0, std::abs(z)))
          << "window " << i << " band " << band;
    }
    s10 = std::min(12.0, std::max(0.0, s10 + static_cast<double>(w.band_excess[kBand]) - 1.0));
    if (expected_alarm < 0 && s10 > 10.0) expected_alarm = i;
    if (engine_alarm < 0 && w.band_alarm) engine_alarm = i;
  }
  ASSERT_GE(engine_alarm, 0);
  EXPECT_EQ(engine_alarm, expected_alarm);
  EXPECT_EQ(w.band_max_index, static_cast<std::int32_t>(kBand));
  EXPECT_EQ(w.band_lo_hz, 161 * 25.0);
  EXPECT_EQ(w.band_hi_hz, 176 * 25.0);
  EXPECT_TRUE((static_cast<unsigned>(w.detector) & 4U) != 0U);
}

}  // namespace
