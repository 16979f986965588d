// MonitorEngine end to end on a synthetic reciprocating joint: gear-mesh tones whose phase follows the
// integrated speed (random phase per cycle) plus noise. Trained on healthy cycles through the same
// slicer, then monitoring healthy cycles (no alarm) and cycles with fault impulses (alarm), with PTDA.
#include "ptda/dsp/monitor_engine.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "alloc_counter.hpp"
#include "ptda/common/error.hpp"
#include "ptda/dsp/baseline_training.hpp"
#include "ptda/dsp/training.hpp"

namespace ptda::dsp {
namespace {

constexpr double kFs = 5120.0;
constexpr std::uint32_t kN = 1024;  // 0.2 s windows
constexpr std::int64_t kT0 = 1'650'000'000'000'000'000;
constexpr double kTwoPi = 2.0 * std::numbers::pi;
// Input shaft angle = ratio * joint angle; the mesh tone is z_in teeth per input revolution:
// at 2 rad/s, GMF = 2 * 33.86 * 14 / (2 pi) = 150.9 Hz, with harmonics at 2x and 3x.
constexpr double kRatio = 33.86;
constexpr double kZ = 14.0;

struct Seg {
  double duration_s;
  double v_end;
};

/// One job cycle: +fwd plateau 1.0 s, rest, -1.5 rad/s plateau 0.8 s, rest (2.4 s in all).
std::vector<Seg> cycle(double fwd) {
  return {{0.1, fwd}, {1.0, fwd}, {0.1, 0.0}, {0.1, 0.0}, {0.1, -1.5}, {0.8, -1.5}, {0.1, 0.0}, {0.1, 0.0}};
}

double speed_at(const std::vector<Seg>& segs, double tau) {
  double v0 = 0.0;
  for (const Seg& s : segs) {
    if (tau < s.duration_s) return v0 + (s.v_end - v0) * tau / s.duration_s;
    tau -= s.duration_s;
    v0 = s.v_end;
  }
  return v0;
}

struct Stream {
  std::vector<SpeedSample> speed;
  std::vector<float> x;
};

/// `cycles` job cycles; fwd_speeds[c % size] is the forward plateau speed of cycle c. Tones with
/// amplitudes 1.0, 0.6, 0.4 at 1x, 2x, 3x the mesh frequency, their phases re-drawn every cycle; white
/// noise sigma 0.2; when impulse_amp > 0, decaying 1.8 kHz bursts every 1/23 s (a local fault).
Stream make_stream(int cycles, unsigned seed, double impulse_amp, std::vector<double> fwd_speeds = {2.0}) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.2);
  std::uniform_real_distribution<double> phase(0.0, kTwoPi);
  Stream s;
  const double cycle_s = 2.4;
  const auto per_cycle = static_cast<std::size_t>(cycle_s * kFs);
  double theta = 0.0;  // input shaft angle
  const double dt = 1.0 / kFs;
  for (int c = 0; c < cycles; ++c) {
    const auto segs = cycle(fwd_speeds[static_cast<std::size_t>(c) % fwd_speeds.size()]);
    const double ph[3] = {phase(rng), phase(rng), phase(rng)};
    for (int k = 0; k * 0.004 < cycle_s - 1e-9; ++k) {
      const double tau = k * 0.004;
      const auto t_ns = static_cast<std::int64_t>(std::llround((c * cycle_s + tau) * 1e9)) + 700'000;
      s.speed.push_back(SpeedSample{kT0 + t_ns, speed_at(segs, tau), 0.0, false});
    }
    for (std::size_t i = 0; i < per_cycle; ++i) {
      const double tau = static_cast<double>(i) * dt;
      theta += kRatio * speed_at(segs, tau) * dt;
      double v = 1.0 * std::sin(kZ * theta + ph[0]) + 0.6 * std::sin(2 * kZ * theta + ph[1]) +
                 0.4 * std::sin(3 * kZ * theta + ph[2]) + noise(rng);
      if (impulse_amp > 0.0) {
        const double t = (static_cast<double>(c) * cycle_s + tau) * 23.0;
        const double since = (t - std::floor(t)) / 23.0;  // s since the last impact
        v += impulse_amp * std::exp(-since / 0.002) * std::sin(kTwoPi * 1800.0 * since);
      }
      s.x.push_back(static_cast<float>(v));
    }
  }
  return s;
}

ExtractionConfig extraction() {
  ExtractionConfig c;
  c.window_len = kN;
  c.hop = kN;
  c.min_duration_s = 0.1;
  c.guard_s = 0.02;
  return c;
}

/// Feeds speed and samples in time order (blocks of `block` samples) through `push`, draining with `pop`.
template <typename Target, typename Drain>
void feed(Target& t, const Stream& s, std::size_t block, Drain drain) {
  std::size_t k = 0;
  for (std::size_t i = 0; i < s.x.size(); i += block) {
    const std::size_t len = std::min(block, s.x.size() - i);
    const auto t_end = kT0 + static_cast<std::int64_t>(static_cast<double>(i + len) / kFs * 1e9);
    for (; k < s.speed.size() && s.speed[k].t_ns <= t_end; ++k) t.push_speed(s.speed[k]);
    t.push_samples(std::span<const float>(s.x).subspan(i, len));
    drain();
  }
  for (; k < s.speed.size(); ++k) t.push_speed(s.speed[k]);
  t.finish();
  drain();
}

/// The offline training path: slice the healthy recording, then train_baseline().
Baseline train(const Stream& healthy) {
  WindowSlicer slicer(extraction(), kFs, kT0);
  CollectedWindows data;
  std::vector<float> buf(kN);
  WindowRef ref;
  RegionInfo region;
  feed(slicer, healthy, 512, [&] {
    while (slicer.pop(ref, buf)) {
      data.refs.push_back(ref);
      data.windows.push_back(buf);
    }
    while (slicer.pop_region(region)) data.regions.push_back(region);
  });
  ThresholdPolicy policy;  // Gaussian, 1e-3 per window and feature
  // This fixture's fault is white impulses that raise the whole floor evenly, which the floor gain
  // absorbs by design (docs/method.md §2, "Floor gain"); the engine's mechanics are tested on the line
  // gain's residual, and the default residual end to end in tests/golden.
  policy.ptda_floor_gain = false;
  GearboxInfo gb;
  gb.kind = GearboxInfo::Kind::kCycloidal;
  gb.ratio = kRatio;
  return train_baseline(data, ClassLearningConfig{}, policy, kFs, gb);
}

class MonitorEngineTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { baseline_ = new Baseline(train(make_stream(12, 1, 0.0))); }
  static void TearDownTestSuite() {
    delete baseline_;
    baseline_ = nullptr;
  }
  static std::vector<WindowResult> monitor(const Stream& s, std::size_t block = 700, Method m = Method::kPtda,
                                           double day_allowance = 3.0) {
    DecisionConfig d{3, 5, {}, {}, {}};
    d.sequential.day_allowance = day_allowance;
    MonitorEngine e(*baseline_, extraction(), d, m, kFs, kT0);
    std::vector<WindowResult> out;
    WindowResult r;
    feed(e, s, block, [&] {
      while (e.poll(r)) out.push_back(r);
    });
    return out;
  }
  static Baseline* baseline_;
};
Baseline* MonitorEngineTest::baseline_ = nullptr;

TEST_F(MonitorEngineTest, TrainingFindsBothDirections) {
  const Baseline& b = *baseline_;
  ASSERT_EQ(b.classes.size(), 2U);
  EXPECT_EQ(b.classes[0].segment.direction, 1);
  EXPECT_NEAR(b.classes[0].segment.speed_rad_s, 2.0, 0.01);
  EXPECT_EQ(b.classes[0].segment.regions, 12U);
  EXPECT_EQ(b.classes[1].segment.direction, -1);
  EXPECT_NEAR(b.classes[1].segment.speed_rad_s, 1.5, 0.01);
  EXPECT_EQ(b.classes[1].segment.regions, 12U);
  // Forward plateau ~1.0 s minus 20 ms guard holds 4 windows of 0.2 s; backward ~0.8 s holds 3.
  EXPECT_EQ(b.classes[0].n_windows, 12U * 4U);
  EXPECT_EQ(b.classes[1].n_windows, 12U * 3U);
  EXPECT_EQ(b.window_len, kN);
  EXPECT_EQ(b.fs_hz, kFs);
  EXPECT_EQ(b.gearbox.ratio, kRatio);
}

TEST_F(MonitorEngineTest, HealthyCyclesRaiseNoAlarmImpulsesDo) {
  const auto healthy = monitor(make_stream(6, 2, 0.0));
  const auto faulty = monitor(make_stream(6, 2, 2.0));
  ASSERT_EQ(healthy.size(), 6U * 7U);
  ASSERT_EQ(faulty.size(), healthy.size());
  std::size_t healthy_abnormal = 0;
  double healthy_rms = 0.0;
  for (const WindowResult& r : healthy) {
    EXPECT_EQ(r.status, WindowStatus::kScored);
    EXPECT_EQ(r.class_id, r.ref.speed_rad_s > 0 ? 0 : 1);
    EXPECT_FALSE(r.alarm) << "healthy window " << r.ref.seq;
    healthy_abnormal += r.verdict.abnormal() ? 1 : 0;
    healthy_rms += r.features.rms_res / static_cast<double>(healthy.size());
  }
  EXPECT_LE(healthy_abnormal, 1U);

  // PTDA removes the tones whatever their phase: the healthy residual (0.11 here; below the noise
  // sigma 0.2 because |D_avg| also holds the mean noise magnitude) is far below the raw signal's RMS,
  // sqrt(0.5 * (1 + 0.36 + 0.16) + 0.04) = 0.90. TDA cannot: the phases differ every cycle, the time
  // average of the tones is near zero, and its residual keeps them.
  EXPECT_LT(healthy_rms, 0.15);
  double tda_rms = 0.0;
  const auto tda = monitor(make_stream(6, 2, 0.0), 700, Method::kTda);
  for (const auto& r : tda) tda_rms += r.features.rms_res / static_cast<double>(tda.size());
  EXPECT_GT(tda_rms, 0.8);
  std::size_t faulty_abnormal = 0;
  for (std::size_t i = 0; i < faulty.size(); ++i) {
    faulty_abnormal += faulty[i].verdict.abnormal() ? 1 : 0;
    std::uint32_t last5 = 0;  // recount of the debouncer's window from the verdicts
    for (std::size_t j = i >= 4 ? i - 4 : 0; j <= i; ++j) last5 += faulty[j].verdict.abnormal() ? 1 : 0;
    EXPECT_EQ(faulty[i].abnormal_in_last_n, last5) << i;
    EXPECT_EQ(faulty[i].kofn_alarm, last5 >= 3) << i;
    EXPECT_EQ(faulty[i].alarm, faulty[i].kofn_alarm || faulty[i].seq_alarm) << i;
  }
  EXPECT_GE(faulty_abnormal, faulty.size() - 1);
  EXPECT_TRUE(faulty.back().alarm);
  // k = 3 of n = 5: the k-of-n alarm is up from the third abnormal window on. On a fault this large
  // (z_rms far above cusum_alarm + k in one window) the CUSUM adds its step cap, 2.5, per window
  // (session 38; up to session 37 it held the alarm from the first window): 2.5, 5, then 7.5 >=
  // cusum_alarm = 7 at the third window, with k-of-n.
  EXPECT_FALSE(faulty[1].kofn_alarm);
  EXPECT_TRUE(faulty[4].kofn_alarm);
  EXPECT_DOUBLE_EQ(faulty[0].seq_statistic, 2.5);
  EXPECT_DOUBLE_EQ(faulty[1].seq_statistic, 5.0);
  EXPECT_FALSE(faulty[1].alarm);
  EXPECT_TRUE(faulty[2].seq_alarm);
  EXPECT_EQ(faulty[2].detector, AlarmDetector::kBoth);
  EXPECT_EQ(faulty[4].detector, AlarmDetector::kBoth);
  EXPECT_GT(faulty[4].features.rms_res, faulty[4].thresholds.rms.hi);
}

// The engine's sequential evidence is the documented recursion on the standardised features, one
// CUSUM per class: recomputed here from each window's features and the baseline's statistics.
// The CUSUM's cap h_alarm + (n - k) cusum_k: after a fault of any size, a healthy run (z = 0) ends
// the sequential alarm after n - k + 1 windows, like k-of-n. An uncapped (or 2 h_alarm) statistic
// would hold the alarm 7+ windows after a repair and delay the operator's clear (the VM test's
// repaired part is about 8 windows long).
TEST(DecisionStateTest, CusumCapBoundsTheRecoveryToKOfNs) {
  for (const auto& [k, n] : {std::pair<std::uint32_t, std::uint32_t>{3, 5}, {5, 5}, {2, 8}}) {
    DecisionConfig cfg{k, n, {}, {}, {}};
    DecisionState d(cfg, 1);
    WindowResult w;
    for (int i = 0; i < 20; ++i) {  // a large fault: z = 50 per window, abnormal
      w.verdict.rms_out = true;
      w.z_rms = 50.0;
      w.z_entropy = 0.0;
      d.scored(w, 0);
    }
    EXPECT_TRUE(w.seq_alarm);
    EXPECT_DOUBLE_EQ(w.seq_statistic, cfg.sequential.h_alarm + (n - k) * cfg.sequential.k);
    int healthy = 0;
    do {  // healthy: z = 0, normal verdicts
      w.verdict.rms_out = false;
      w.z_rms = 0.0;
      d.scored(w, 0);
      ++healthy;
    } while (w.seq_alarm && healthy < 100);
    EXPECT_EQ(healthy, static_cast<int>(n - k + 1)) << "k " << k << " n " << n;
  }
}

TEST_F(MonitorEngineTest, SequentialDetectorIsPerClassCusumOnStandardisedFeatures) {
  for (const double q : {3.0, 0.0}) {  // the default between-day allowance, and none (session 6)
    const auto res = monitor(make_stream(6, 6, 0.65), 700, Method::kPtda, q);
    SequentialConfig seq;  // defaults: k 1, warn 4, alarm 7, step cap 2.5
    seq.day_allowance = q;
    std::vector<double> s_rms(2, 0.0), s_hi(2, 0.0), s_lo(2, 0.0);
    bool seq_alarm_seen = false;
    bool kofn_seen = false;
    for (const WindowResult& r : res) {
      ASSERT_EQ(r.status, WindowStatus::kScored);
      const auto c = static_cast<std::size_t>(r.class_id);
      const ClassBaseline& cls = baseline_->classes[c];
      const auto m = static_cast<std::size_t>(Method::kPtda);
      // Small-sample scale: n = 48 (class 0) and 36 (class 1) training windows.
      const double c_n = small_sample_scale(cls.log_rms_stats[m].n, baseline_->policy);
      EXPECT_GT(c_n, 1.0);
      const double zr =
          (std::log(r.features.rms_res) - cls.log_rms_stats[m].mean) / (c_n * cls.log_rms_stats[m].stddev);
      const double ze =
          (r.features.entropy_res - cls.entropy_stats[m].mean) / (c_n * cls.entropy_stats[m].stddev);
      EXPECT_NEAR(r.z_rms, zr, 1e-9 * std::max(1.0, std::abs(zr)));
      EXPECT_NEAR(r.z_entropy, ze, 1e-9 * std::max(1.0, std::abs(ze)));
      // One training recording: the between-day sd is the prior 0.3 x within, so each statistic's allowance
      // is k + 3 x 0.3 x sqrt(1 + 1/1) / c_n (docs/method.md §6).
      const double extra = q * baseline_->policy.day_sd_floor * std::sqrt(2.0) / c_n;
      EXPECT_EQ(cls.day_spread[m].recordings, 1U);
      EXPECT_NEAR(r.seq_allowance_rms, extra, 1e-9);
      EXPECT_NEAR(r.seq_allowance_entropy, extra, 1e-9);
      // Cap h_alarm + (n - k) cusum_k with the engine's k-of-n 3 of 5: 7 + 2 = 9.
      const double cap = seq.h_alarm + 2.0 * seq.k;
      const double k_f = seq.k + extra;
      s_rms[c] = std::min(cap, std::max(0.0, s_rms[c] + std::min(zr - k_f, seq.step_cap)));
      s_hi[c] = std::min(cap, std::max(0.0, s_hi[c] + std::min(ze - k_f, seq.step_cap)));
      s_lo[c] = std::min(cap, std::max(0.0, s_lo[c] + std::min(-ze - k_f, seq.step_cap)));
      const double mine = std::max(s_rms[c], std::max(s_hi[c], s_lo[c]));
      EXPECT_NEAR(r.seq_statistic, mine, 1e-6);
      const double worst = std::max(std::max(s_rms[0], std::max(s_hi[0], s_lo[0])),
                                    std::max(s_rms[1], std::max(s_hi[1], s_lo[1])));
      EXPECT_NEAR(r.seq_max_statistic, worst, 1e-6);
      EXPECT_EQ(r.seq_alarm, worst >= seq.h_alarm);
      EXPECT_EQ(r.seq_warn, worst >= seq.h_warn);
      EXPECT_EQ(r.alarm, r.kofn_alarm || r.seq_alarm);
      const AlarmDetector want = r.kofn_alarm
                                     ? (r.seq_alarm ? AlarmDetector::kBoth : AlarmDetector::kKOfN)
                                     : (r.seq_alarm ? AlarmDetector::kSequential : AlarmDetector::kNone);
      EXPECT_EQ(r.detector, want);
      seq_alarm_seen = seq_alarm_seen || r.seq_alarm;
      kofn_seen = kofn_seen || r.kofn_alarm;
    }
    // Impulses of amplitude 0.65 raise the residual by about 1-2 sd: no window of 42 leaves its (widened)
    // band, so k-of-n never fires, but the evidence accumulates and the CUSUM reaches its alarm (measured:
    // uncapped its largest value was 11.7 against cusum_alarm 7, so it reaches the cap of 9; at
    // amplitude 0.5 it stays at 3.7).
    // With the between-day allowance (about 0.95 more here, the baseline knows one recording) the same
    // evidence no longer alarms: measured, the largest statistic was 1.57; amplitude 0.9 was the first of
    // 0.65, 0.7, ..., 0.9 to alarm, and there k-of-n fires too (7 of 42 windows abnormal).
    EXPECT_FALSE(kofn_seen);
    EXPECT_EQ(seq_alarm_seen, q == 0.0) << "q " << q;
  }
  // Switched off, the same data leaves every sequential field at rest and the alarm to k-of-n.
  DecisionConfig off{3, 5, {}, {}, {}};
  off.sequential.enabled = false;
  MonitorEngine e(*baseline_, extraction(), off, Method::kPtda, kFs, kT0);
  WindowResult r;
  feed(e, make_stream(6, 6, 0.65), 700, [&] {
    while (e.poll(r)) {
      EXPECT_EQ(r.seq_statistic, 0.0);
      EXPECT_FALSE(r.seq_alarm);
      EXPECT_EQ(r.alarm, r.kofn_alarm);
    }
  });
}

TEST_F(MonitorEngineTest, HoldoutLeavesTheLatestCyclesOutAndCountsThem) {
  const Stream healthy = make_stream(12, 1, 0.0);
  WindowSlicer slicer(extraction(), kFs, kT0);
  CollectedWindows data;
  std::vector<float> buf(kN);
  WindowRef ref;
  RegionInfo region;
  feed(slicer, healthy, 512, [&] {
    while (slicer.pop(ref, buf)) {
      data.refs.push_back(ref);
      data.windows.push_back(buf);
    }
    while (slicer.pop_region(region)) data.regions.push_back(region);
  });
  ThresholdPolicy policy;
  policy.holdout_fraction = 0.25;
  const Baseline b = train_baseline(data, ClassLearningConfig{}, policy, kFs, GearboxInfo{});
  ASSERT_EQ(b.classes.size(), 2U);
  // Disjoint windows are their own groups: class 0 has 48 (12 held out), class 1 has 36 (9 held out).
  EXPECT_EQ(b.classes[0].n_windows, 36U);
  EXPECT_EQ(b.classes[1].n_windows, 27U);
  for (std::size_t m = 0; m < kMethodCount; ++m) {
    EXPECT_EQ(b.classes[0].holdout[m].windows, 12U);
    EXPECT_EQ(b.classes[1].holdout[m].windows, 9U);
  }
  // Healthy held-out windows: PTDA flags at most one, and their standardised scores are near N(0, 1).
  const auto p = static_cast<std::size_t>(Method::kPtda);
  EXPECT_LE(b.classes[0].holdout[p].abnormal + b.classes[1].holdout[p].abnormal, 1U);
  EXPECT_LT(std::abs(b.classes[0].holdout[p].z_rms_mean), 1.5);
  EXPECT_GT(b.classes[0].holdout[p].z_rms_sd, 0.3);
  EXPECT_LT(b.classes[0].holdout[p].z_rms_sd, 3.0);
  // 12 cycles of 2.4 s with 4 forward windows each: 4 / 2.4 s = 6000 windows per hour (the last
  // window adds one median start-to-start interval, so the operating time is close to 28.8 s).
  EXPECT_NEAR(b.classes[0].windows_per_hour, 6000.0, 400.0);
  // The bands are fitted without the held-out windows: the same as training on the first 75 %.
  policy.holdout_fraction = 0.95;
  EXPECT_THROW((void)train_baseline(data, ClassLearningConfig{}, policy, kFs, GearboxInfo{}), Error);
}

TEST_F(MonitorEngineTest, UnknownSpeedIsReportedButNotScored) {
  // Every other cycle runs forwards at 3.0 rad/s, which no class covers.
  const auto res = monitor(make_stream(4, 3, 2.0, {2.0, 3.0}));
  std::size_t no_class = 0;
  std::uint32_t abnormal_before = 0;
  for (const WindowResult& r : res) {
    if (r.status == WindowStatus::kNoClass) {
      ++no_class;
      EXPECT_EQ(r.class_id, -1);
      EXPECT_NEAR(r.ref.speed_rad_s, 3.0, 0.01);
      EXPECT_FALSE(r.verdict.abnormal());
      EXPECT_EQ(r.abnormal_in_last_n, abnormal_before);  // the debouncer did not see it
    } else {
      EXPECT_NE(r.class_id, -1);
    }
    abnormal_before = r.abnormal_in_last_n;
  }
  EXPECT_EQ(no_class, 2U * 4U);
  EXPECT_EQ(res.size(), 4U * 7U);
}

TEST_F(MonitorEngineTest, BlockSizeDoesNotChangeResults) {
  const Stream s = make_stream(2, 4, 1.0);
  const auto a = monitor(s, 64);
  const auto b = monitor(s, 4096);
  ASSERT_EQ(a.size(), b.size());
  ASSERT_GT(a.size(), 0U);
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].ref.first_sample, b[i].ref.first_sample);
    EXPECT_EQ(std::memcmp(&a[i].features, &b[i].features, sizeof(Features)), 0) << i;
    EXPECT_EQ(a[i].alarm, b[i].alarm);
  }
}

TEST_F(MonitorEngineTest, PollDoesNotAllocateAfterWarmUp) {
  const Stream s = make_stream(8, 5, 2.0);
  MonitorEngine e(*baseline_, extraction(), DecisionConfig{3, 5, {}, {}, {}}, Method::kPtda, kFs, kT0);
  WindowResult r;
  std::size_t polled = 0;
  std::size_t k = 0;
  const std::size_t warm_up = static_cast<std::size_t>(2.4 * kFs);  // one cycle
  std::uint64_t allocations = 0;
  bool scoped = false;
  test::AllocScope scope;
  for (std::size_t i = 0; i < s.x.size(); i += 333) {
    if (!scoped && i >= warm_up) {
      scope = test::AllocScope();
      scoped = true;
    }
    const std::size_t len = std::min<std::size_t>(333, s.x.size() - i);
    const auto t_end = kT0 + static_cast<std::int64_t>(static_cast<double>(i + len) / kFs * 1e9);
    for (; k < s.speed.size() && s.speed[k].t_ns <= t_end; ++k) e.push_speed(s.speed[k]);
    e.push_samples(std::span<const float>(s.x).subspan(i, len));
    while (e.poll(r)) polled += scoped ? 1 : 0;
  }
  e.finish();
  while (e.poll(r)) ++polled;
  allocations = scope.count();
  EXPECT_EQ(allocations, 0U);
  EXPECT_GE(polled, 7U * 7U - 1U);
  EXPECT_TRUE(r.alarm);
  EXPECT_EQ(e.last_window().size(), kN);
}

TEST_F(MonitorEngineTest, RejectsMismatchedBaselineAndDecision) {
  const auto expect_error = [](auto make, const std::string& needle) {
    try {
      make();
      ADD_FAILURE() << "no error, wanted " << needle;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  expect_error([] { MonitorEngine e(*baseline_, extraction(), {}, Method::kPtda, 5120.1, kT0); }, "fs_hz");
  ExtractionConfig other = extraction();
  other.window_len = 2048;
  other.hop = 0;
  expect_error([&] { MonitorEngine e(*baseline_, other, {}, Method::kPtda, kFs, kT0); },
               "extraction.window_len");
  expect_error(
      [] {
        MonitorEngine e(*baseline_, extraction(), {6, 5, {}, {}, {}}, Method::kPtda, kFs, kT0);
      },
      "");
  Baseline empty = *baseline_;
  empty.classes.clear();
  expect_error([&] { MonitorEngine e(empty, extraction(), {}, Method::kPtda, kFs, kT0); },
               "no segment classes");
  Baseline broken = *baseline_;
  broken.classes[1].tda_mean.resize(10);
  expect_error([&] { MonitorEngine e(broken, extraction(), {}, Method::kPtda, kFs, kT0); }, "class 1");
  // Within 1e-6 relative is accepted (5120.003 Hz: 5.9e-7; the slicer needs a multiple of 1 mHz).
  EXPECT_NO_THROW(MonitorEngine(*baseline_, extraction(), {}, Method::kTda, kFs + 0.003, kT0));
}

}  // namespace
}  // namespace ptda::dsp
