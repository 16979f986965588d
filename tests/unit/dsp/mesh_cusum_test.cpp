// The mesh detector's decision (DecisionState, docs/method.md §6 "Mesh detector") and the path from
// training to an alarm: train_baseline() stores the class's am/pm statistics, MonitorEngine
// standardises each window's am/pm with them and the mesh CUSUM raises the alarm.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <vector>

#include "ptda/common/error.hpp"
#include "ptda/dsp/baseline_training.hpp"
#include "ptda/dsp/mesh_modulation.hpp"
#include "ptda/dsp/monitor_engine.hpp"

namespace ptda::dsp {
namespace {

DecisionConfig mesh_on() {
  DecisionConfig d{3, 5, {}, {}, {}};
  d.band.enabled = false;
  d.mesh.enabled = true;
  d.mesh.required = true;  // as `mesh_cusum = true` said in the configuration
  // The recursion's arithmetic below is the uncapped one with k = 1 (the defaults up to session 37); the
  // step cap and the default k have their own test.
  d.mesh.k = 1.0;
  d.mesh.step_cap = kNoStepCap;
  return d;
}

// S <- min(cap, max(0, S + x - k)), alarm when S > h: with x = 3, k = 1 the statistic grows by 2 per
// window, is 10 (not above h = 10) after 5 windows and 12 (the cap h + (n - k_of_n) k = 10 + 2) after 6.
TEST(MeshCusumDecision, CrossesHAfterTheComputedWindowsAndNamesTheFeature) {
  DecisionState st(mesh_on(), 2);
  WindowResult w;
  for (int i = 1; i <= 6; ++i) {
    w = WindowResult{};
    w.mesh_excess[1] = 3.0;
    st.scored(w, 0);
    EXPECT_EQ(w.mesh_statistic, std::min(12.0, 2.0 * i)) << i;
    EXPECT_EQ(w.mesh_feature, 1) << i;
    EXPECT_EQ(w.mesh_alarm, i == 6) << i;
    EXPECT_EQ(w.alarm, i == 6) << i;
  }
  EXPECT_TRUE(w.mesh_on);
  EXPECT_EQ(w.detector, AlarmDetector::kMesh);
  EXPECT_STREQ(alarm_detector_name(w.detector), "mesh");
  EXPECT_EQ(w.mesh_max_feature, 1);
  EXPECT_EQ(w.mesh_max_class, 0);
  // A window without mesh features (NaN: too slow, no mesh line) leaves the statistic where it was.
  WindowResult none;
  st.scored(none, 0);
  EXPECT_EQ(none.mesh_statistic, 12.0);
  EXPECT_TRUE(none.mesh_alarm);
  // The other class's statistics are its own; healthy windows take k per window off.
  WindowResult other;
  other.mesh_excess[0] = 0.0;
  other.mesh_excess[1] = 0.0;
  st.scored(other, 1);
  EXPECT_EQ(other.mesh_statistic, 0.0);
  EXPECT_EQ(other.mesh_max_statistic, 12.0);
  WindowResult healthy;
  healthy.mesh_excess[0] = 0.0;
  healthy.mesh_excess[1] = 0.0;
  st.scored(healthy, 0);
  EXPECT_EQ(healthy.mesh_statistic, 11.0);
  st.scored(healthy, 0);
  EXPECT_EQ(healthy.mesh_statistic, 10.0);
  EXPECT_FALSE(healthy.mesh_alarm);
  EXPECT_FALSE(healthy.alarm);
  // Off (the default): no mesh fields, whatever the window says.
  DecisionConfig off = mesh_on();
  off.mesh.enabled = false;
  DecisionState o(off, 1);
  WindowResult ow;
  ow.mesh_excess[1] = 100.0;
  o.scored(ow, 0);
  EXPECT_FALSE(ow.mesh_on);
  EXPECT_FALSE(ow.mesh_alarm);
  EXPECT_EQ(ow.detector, AlarmDetector::kNone);
}

// The defaults since session 38: k = 0.75 and a step cap of 2.5. A window with an excess of 5 adds
// min(5 - 0.75, 2.5) = 2.5, so the statistic is 2.5 i, 10 (not above h) after 4 windows and above it after
// 5, capped at C = h + (n - k_of_n) k = 10 + 2 x 0.75 = 11.5. Without the cap the same windows add 4.25
// each and alarm after 3.
TEST(MeshCusumDecision, OneWindowAddsAtMostTheStepCap) {
  DecisionConfig d{3, 5, {}, {}, {}};
  d.band.enabled = false;
  d.mesh.enabled = true;
  ASSERT_EQ(d.mesh.k, 0.75);
  ASSERT_EQ(d.mesh.step_cap, 2.5);
  DecisionState st(d, 1);
  for (int i = 1; i <= 5; ++i) {
    WindowResult w;
    w.mesh_excess[0] = 5.0;
    st.scored(w, 0);
    EXPECT_DOUBLE_EQ(w.mesh_statistic, std::min(11.5, 2.5 * i)) << i;
    EXPECT_EQ(w.mesh_alarm, i == 5) << i;
  }
  d.mesh.step_cap = kNoStepCap;
  DecisionState uncapped(d, 1);
  for (int i = 1; i <= 3; ++i) {
    WindowResult w;
    w.mesh_excess[0] = 5.0;
    uncapped.scored(w, 0);
    EXPECT_DOUBLE_EQ(w.mesh_statistic, std::min(11.5, 4.25 * i)) << i;
    EXPECT_EQ(w.mesh_alarm, i == 3) << i;
  }
  // A healthy window (excess 0) takes k off, whatever the cap.
  WindowResult healthy;
  healthy.mesh_excess[0] = 0.0;
  st.scored(healthy, 0);
  EXPECT_DOUBLE_EQ(healthy.mesh_statistic, 11.5 - 0.75);
}

TEST(MeshCusumDecision, DetectorNamesCombineEveryBit) {
  EXPECT_STREQ(alarm_detector_name(static_cast<AlarmDetector>(12)), "band+mesh");
  EXPECT_STREQ(alarm_detector_name(static_cast<AlarmDetector>(15)), "k_of_n+sequential+band+mesh");
  EXPECT_STREQ(alarm_detector_name(AlarmDetector::kSequentialBand), "sequential+band");
  EXPECT_STREQ(alarm_detector_name(static_cast<AlarmDetector>(16)), "?");
}

TEST(MeshCusumDecision, ParametersAreCheckedByName) {
  MeshCusumConfig c;
  c.enabled = true;
  c.k = 0.0;
  try {
    check_mesh_cusum(c);
    FAIL() << "k = 0 accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("decision.mesh_cusum_k"), std::string::npos) << e.what();
  }
  c = MeshCusumConfig{};
  c.h = 2000.0;
  EXPECT_THROW(check_mesh_cusum(c), Error);
  c = MeshCusumConfig{};
  c.one_day_allowance = -1.0;
  EXPECT_THROW(check_mesh_cusum(c), Error);
  for (const double bad : {0.0, -1.0, 1000.5, std::numeric_limits<double>::quiet_NaN()}) {
    c = MeshCusumConfig{};
    c.step_cap = bad;
    try {
      check_mesh_cusum(c);
      FAIL() << "step cap " << bad << " accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("decision.mesh_cusum_step_cap"), std::string::npos) << e.what();
    }
  }
}

TEST(MeshScale, StandardisesWithTheTotalSdAndAddsTheAllowanceOnlyForOneTrainingDay) {
  ClassBaseline c;
  c.mesh_recordings = 1;
  c.mesh_stats = {{0.2, 0.3, 0.1, 0.4, 50}, {0.1, 0.2, 0.0, 0.06, 0}};
  MeshScale s = mesh_scale(c, 1.5);
  EXPECT_TRUE(s.active[0]);
  EXPECT_FALSE(s.active[1]);
  EXPECT_DOUBLE_EQ(s.mean[0], 0.2);
  EXPECT_DOUBLE_EQ(s.sd[0], 0.5);  // sqrt(0.3^2 + 0.4^2)
  // One recording: allowance = 1.5 x 0.4 x sqrt(1 + 1/1) / 0.5
  EXPECT_NEAR(s.allowance[0], 1.5 * 0.4 * std::sqrt(2.0) / 0.5, 1e-12);
  EXPECT_EQ(s.allowance[1], 0.0);
  // Three recordings: the between-day sd is estimated and in the total sd; nothing is added.
  c.mesh_recordings = 3;
  s = mesh_scale(c, 1.5);
  EXPECT_DOUBLE_EQ(s.sd[0], 0.5);
  EXPECT_EQ(s.allowance[0], 0.0);
  EXPECT_FALSE(mesh_scale(ClassBaseline{}, 1.0).any());
}

// --- From training to an alarm -------------------------------------------------------------------

constexpr double kFs = 25600.0;
constexpr std::uint32_t kN = 12800;
constexpr double kRatio = 40.0;
constexpr std::uint32_t kZin = 20;
constexpr double kSpeed = 2.0 * std::numbers::pi * 10.0 / kRatio;  // f_in 10 Hz, 5 revolutions per window

// Three mesh harmonics with noise from a per-window LCG seed; pm_rad > 0 slips the phase once per
// input-shaft revolution (a local tooth defect on the input pinion).
std::vector<float> window(std::uint64_t seed, double pm_rad, double speed = kSpeed) {
  std::vector<float> x(kN);
  std::uint64_t state = seed * 7919 + 1;
  const double f_in = kRatio * speed / (2.0 * std::numbers::pi);
  const double gmf = kZin * f_in;
  const double amp[3] = {1.0, 0.6, 0.35};
  const double phase0 = 0.37 * static_cast<double>(seed % 17);
  for (std::size_t i = 0; i < kN; ++i) {
    const double t = static_cast<double>(i) / kFs;
    double c = f_in * t + 0.3;
    c -= std::floor(c);
    const double u = (c - 0.5) / 0.04;
    const double bump = std::exp(-0.5 * u * u);
    double v = 0.0;
    for (int h = 1; h <= 3; ++h)
      v += amp[h - 1] * std::cos(2.0 * std::numbers::pi * h * gmf * t + h * phase0 + h * pm_rad * bump);
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    v += 0.3 * (2.0 * static_cast<double>(state >> 11) * (1.0 / 9007199254740992.0) - 1.0);
    x[i] = static_cast<float>(v);
  }
  return x;
}

Baseline train(bool mesh, const GearboxInfo& gb) {
  CollectedWindows data;
  for (std::uint64_t r = 0; r < 12; ++r) {
    const std::int64_t t0 = static_cast<std::int64_t>(r) * 10'000'000'000;
    data.regions.push_back(RegionInfo{r, t0, t0 + 2'000'000'000, kSpeed, 1});
    for (std::uint32_t j = 0; j < 2; ++j) {
      WindowRef ref;
      ref.seq = data.refs.size();
      ref.region_seq = r;
      ref.index_in_region = j;
      ref.first_sample = static_cast<std::int64_t>(r) * 256000 + j * kN;
      ref.t_start_ns = t0 + static_cast<std::int64_t>(j) * 500'000'000;
      ref.t_end_ns = ref.t_start_ns + 500'000'000;
      ref.speed_rad_s = kSpeed;
      data.refs.push_back(ref);
      data.windows.push_back(window(data.refs.size(), 0.0));
      data.recording.push_back(r < 6 ? 0U : 1U);  // two training days
    }
  }
  ThresholdPolicy policy;
  policy.mesh_stats = mesh;
  return train_baseline(data, ClassLearningConfig{}, policy, kFs, gb);
}

GearboxInfo gearbox() {
  GearboxInfo gb;
  gb.kind = GearboxInfo::Kind::kParallel;
  gb.z_in = kZin;
  gb.z_spur = 40 * kZin;
  gb.ratio = kRatio;
  return gb;
}

ExtractionConfig extraction() {
  ExtractionConfig c;
  c.window_len = kN;
  return c;
}

TEST(MeshDetector, TrainingStoresTheStatisticsAndSlipsRaiseTheMeshAlarmAloneWhileHealthyWindowsDoNot) {
  const Baseline b = train(true, gearbox());
  ASSERT_EQ(b.classes.size(), 1U);
  const ClassBaseline& c = b.classes[0];
  ASSERT_EQ(c.mesh_stats.size(), 2U);
  EXPECT_EQ(c.mesh_recordings, 2U);
  for (const MeshFeatureStats& st : c.mesh_stats) {
    EXPECT_EQ(st.windows, 24U);
    EXPECT_GT(st.within_sd, 0.0);
    EXPECT_LT(std::fabs(st.mean), 0.5);  // a steady mesh: no once-per-revolution modulation
  }
  MonitorEngine e(b, extraction(), mesh_on(), Method::kPtda, kFs, 0);
  EXPECT_TRUE(e.mesh_cusum_on());
  EXPECT_EQ(e.mesh_classes(), 1U);
  WindowRef ref;
  ref.speed_rad_s = kSpeed;
  WindowResult w;
  // 30 new healthy windows (seeds never trained on): no mesh alarm.
  double top = 0.0;
  for (std::uint64_t s = 1000; s < 1030; ++s) {
    e.judge_window(ref, window(s, 0.0), w);
    ASSERT_EQ(w.status, WindowStatus::kScored);
    ASSERT_TRUE(std::isfinite(w.mesh_value[1]));
    top = std::max(top, w.mesh_max_statistic);
  }
  EXPECT_FALSE(w.mesh_alarm) << top;
  EXPECT_LT(top, 10.0);
  // A phase slip of 0.03 rad once per revolution: the residual's verdicts stay ok (no abnormal window,
  // so neither k-of-n nor the feature CUSUM moves), while the mesh CUSUM on pm (z 1.2-4.6 per window
  // when this was written) raises the alarm at the fifth window, alone.
  int first = -1;
  int abnormal = 0;
  for (int i = 0; i < 10; ++i) {
    e.judge_window(ref, window(2000 + static_cast<std::uint64_t>(i), 0.03), w);
    if (w.mesh_alarm && first < 0) {
      first = i;
      EXPECT_EQ(w.detector, AlarmDetector::kMesh) << alarm_detector_name(w.detector);
    }
    abnormal += w.verdict.abnormal() ? 1 : 0;
  }
  EXPECT_EQ(abnormal, 0);
  EXPECT_EQ(first, 4);  // pinned from this run: the fifth window
  EXPECT_EQ(w.mesh_max_feature, 1);
}

TEST(MeshDetector, ASlowClassGetsNoStatisticsAndAMissingGearboxOrBaselineIsAnError) {
  // No tooth counts: training refuses with the keys to set.
  try {
    (void)train(true, GearboxInfo{});
    FAIL() << "trained without z_in";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("mesh_cusum needs"), std::string::npos) << e.what();
  }
  // A baseline trained without the mesh statistics cannot run the mesh detector.
  const Baseline plain = train(false, gearbox());
  EXPECT_TRUE(plain.classes[0].mesh_stats.empty());
  try {
    MonitorEngine e(plain, extraction(), mesh_on(), Method::kPtda, kFs, 0);
    FAIL() << "mesh detector ran without statistics";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("retrain it with [decision] mesh_cusum = true"), std::string::npos)
        << e.what();
  }
  // On by default (not required), the same baseline runs without it and the engine says why.
  {
    DecisionConfig def = mesh_on();
    def.mesh.required = false;
    const MonitorEngine e(plain, extraction(), def, Method::kPtda, kFs, 0);
    EXPECT_FALSE(e.mesh_cusum_on());
    EXPECT_EQ(e.mesh_off_reason().rfind("the baseline has no mesh statistics", 0), 0U) << e.mesh_off_reason();
    EXPECT_FALSE(effective_detectors(def, plain, Method::kPtda).mesh.enabled);
    EXPECT_TRUE(effective_detectors(mesh_on(), plain, Method::kPtda).mesh.enabled);  // asked for: kept
    WindowRef ref;
    ref.speed_rad_s = kSpeed;
    WindowResult w;
    MonitorEngine run(plain, extraction(), def, Method::kPtda, kFs, 0);
    run.judge_window(ref, window(5, 0.0), w);
    EXPECT_FALSE(w.mesh_on);  // the window record says the detector did not run
  }
  // A baseline with them: the default-on detector runs and there is nothing to explain.
  {
    DecisionConfig def = mesh_on();
    def.mesh.required = false;
    const MonitorEngine e(train(true, gearbox()), extraction(), def, Method::kPtda, kFs, 0);
    EXPECT_TRUE(e.mesh_cusum_on());
    EXPECT_TRUE(e.mesh_off_reason().empty()) << e.mesh_off_reason();
  }
  // Ratio 6: f_in 1.5 Hz, 0.75 revolutions per window: the class has no mesh statistics and the engine
  // runs without a mesh detector for it (mesh fields NaN, statistic 0).
  GearboxInfo slow = gearbox();
  slow.ratio = 6.0;
  const Baseline b = train(true, slow);
  ASSERT_EQ(b.classes[0].mesh_stats.size(), 2U);
  EXPECT_EQ(b.classes[0].mesh_stats[0].windows, 0U);
  EXPECT_EQ(b.classes[0].mesh_stats[1].windows, 0U);
  MonitorEngine e(b, extraction(), mesh_on(), Method::kPtda, kFs, 0);
  EXPECT_EQ(e.mesh_classes(), 0U);
  WindowRef ref;
  ref.speed_rad_s = kSpeed;
  WindowResult w;
  e.judge_window(ref, window(5, 0.3), w);
  EXPECT_TRUE(std::isnan(w.mesh_value[1]));
  EXPECT_EQ(w.mesh_max_statistic, 0.0);
}

}  // namespace
}  // namespace ptda::dsp
