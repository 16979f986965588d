// Segment classes from regions (learn_segment_classes) and the training glue (train_baseline):
// class grouping, ids, durations, leave-out groups from window overlap, and the errors.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "ptda/common/error.hpp"
#include "ptda/dsp/baseline_training.hpp"
#include "ptda/dsp/training.hpp"

namespace ptda::dsp {
namespace {

constexpr std::int64_t kS = 1'000'000'000;

RegionInfo region(std::uint64_t seq, double speed, double duration_s, std::int64_t t_begin_ns = 0) {
  RegionInfo r;
  r.seq = seq;
  r.t_begin_ns = t_begin_ns;
  r.t_end_ns = t_begin_ns + static_cast<std::int64_t>(std::llround(duration_s * 1e9));
  r.mean_speed_rad_s = speed;
  r.direction = speed < 0 ? -1 : 1;
  return r;
}

TEST(LearnSegmentClasses, TwoDirectionsTwoSpeedsEach) {
  // A reciprocating job: +1.0 and +2.0 rad/s forwards, -1.0 and -2.0 backwards, with cycle-to-cycle
  // speed jitter well inside the tolerance; one stray +3.0 region is too rare for a class.
  std::vector<RegionInfo> regions;
  std::uint64_t seq = 0;
  const double fwd1[] = {1.00, 1.01, 0.99, 1.005};
  const double fwd2[] = {2.02, 1.98, 2.00, 2.01, 1.99};
  const double bwd1[] = {-1.0, -1.0, -1.02};
  const double bwd2[] = {-2.0, -2.05, -1.97, -2.0};
  const double dur_fwd1[] = {0.50, 0.70, 0.60, 0.40};  // median (0.5 + 0.6) / 2 = 0.55
  for (int c = 0; c < 5; ++c) {                        // interleaved as in a real recording
    if (c < 4) regions.push_back(region(seq++, fwd1[c], dur_fwd1[c]));
    regions.push_back(region(seq++, fwd2[c], 1.0 + 0.1 * c));  // median 1.2
    if (c < 3) regions.push_back(region(seq++, bwd1[c], 0.3));
    if (c < 4) regions.push_back(region(seq++, bwd2[c], 0.8 + 0.1 * c));  // median (0.9 + 1.0) / 2
  }
  regions.push_back(region(seq++, 3.0, 1.0));

  ClassLearningConfig cfg;  // rel 0.05, abs 0.02, min 3 regions
  const auto classes = learn_segment_classes(regions, cfg);
  ASSERT_EQ(classes.size(), 4U);
  // Order: forward classes by speed, then backward classes by speed.
  EXPECT_EQ(classes[0].id, 0U);
  EXPECT_EQ(classes[0].direction, 1);
  EXPECT_DOUBLE_EQ(classes[0].speed_rad_s, (1.00 + 1.01 + 0.99 + 1.005) / 4);
  EXPECT_DOUBLE_EQ(classes[0].speed_tol_rad_s, std::max(0.05 * classes[0].speed_rad_s, 0.02));
  EXPECT_NEAR(classes[0].duration_s, 0.55, 1e-9);
  EXPECT_EQ(classes[0].regions, 4U);

  EXPECT_EQ(classes[1].id, 1U);
  EXPECT_EQ(classes[1].direction, 1);
  EXPECT_DOUBLE_EQ(classes[1].speed_rad_s, (2.02 + 1.98 + 2.00 + 2.01 + 1.99) / 5);
  EXPECT_DOUBLE_EQ(classes[1].speed_tol_rad_s, 0.05 * classes[1].speed_rad_s);
  EXPECT_NEAR(classes[1].duration_s, 1.2, 1e-9);
  EXPECT_EQ(classes[1].regions, 5U);

  EXPECT_EQ(classes[2].id, 2U);
  EXPECT_EQ(classes[2].direction, -1);
  EXPECT_DOUBLE_EQ(classes[2].speed_rad_s, (1.0 + 1.0 + 1.02) / 3);
  EXPECT_NEAR(classes[2].duration_s, 0.3, 1e-9);
  EXPECT_EQ(classes[2].regions, 3U);

  EXPECT_EQ(classes[3].id, 3U);
  EXPECT_EQ(classes[3].direction, -1);
  EXPECT_DOUBLE_EQ(classes[3].speed_rad_s, (2.0 + 2.05 + 1.97 + 2.0) / 4);
  EXPECT_NEAR(classes[3].duration_s, 0.95, 1e-9);
  EXPECT_EQ(classes[3].regions, 4U);

  // Every training region of a kept class matches its own class through Baseline::match.
  Baseline b;
  for (const auto& c : classes) {
    ClassBaseline cb;
    cb.segment = c;
    b.classes.push_back(cb);
  }
  for (const RegionInfo& r : regions) {
    const ClassBaseline* m = b.match(r.mean_speed_rad_s);
    if (r.mean_speed_rad_s == 3.0) {
      EXPECT_EQ(m, nullptr);
      continue;
    }
    ASSERT_NE(m, nullptr) << r.mean_speed_rad_s;
    EXPECT_EQ(m->segment.direction, r.direction);
    EXPECT_LE(std::fabs(std::fabs(r.mean_speed_rad_s) - m->segment.speed_rad_s), m->segment.speed_tol_rad_s);
  }
}

TEST(LearnSegmentClasses, GreedyGroupsAreAnchoredAtTheSlowestRegion) {
  // rel 0.05, abs 0.02: anchor 1.00 takes up to 1.05 -> {1.00, 1.04}; anchor 1.06 takes up to 1.113
  // -> {1.06}; then {1.12}. A chain 1.00 -> 1.04 -> 1.06 -> 1.12 would otherwise drift.
  const std::vector<RegionInfo> regions = {region(0, 1.12, 1), region(1, 1.00, 1), region(2, 1.06, 1),
                                           region(3, 1.04, 1)};
  ClassLearningConfig cfg;
  cfg.min_regions = 1;
  const auto classes = learn_segment_classes(regions, cfg);
  ASSERT_EQ(classes.size(), 3U);
  EXPECT_DOUBLE_EQ(classes[0].speed_rad_s, 1.02);
  EXPECT_EQ(classes[0].regions, 2U);
  EXPECT_DOUBLE_EQ(classes[1].speed_rad_s, 1.06);
  EXPECT_DOUBLE_EQ(classes[2].speed_rad_s, 1.12);
  // Low speeds use the absolute tolerance: 0.10 and 0.115 share a class (0.05 * 0.1 < 0.02).
  const auto slow =
      learn_segment_classes({region(0, 0.10, 1), region(1, 0.115, 1), region(2, 0.125, 1)}, cfg);
  ASSERT_EQ(slow.size(), 2U);
  EXPECT_EQ(slow[0].regions, 2U);
  EXPECT_DOUBLE_EQ(slow[0].speed_tol_rad_s, 0.02);
}

TEST(LearnSegmentClasses, EmptyInputAndBadConfig) {
  EXPECT_TRUE(learn_segment_classes({}, ClassLearningConfig{}).empty());
  ClassLearningConfig bad;
  bad.speed_tol_rel = -0.1;
  EXPECT_THROW((void)learn_segment_classes({region(0, 1.0, 1)}, bad), Error);
  bad = ClassLearningConfig{};
  bad.min_regions = 0;
  try {
    (void)learn_segment_classes({region(0, 1.0, 1)}, bad);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("classes.min_regions"), std::string::npos) << e.what();
  }
}

// --- train_baseline ----------------------------------------------------------------------------

constexpr std::size_t kN = 64;

std::vector<float> tone_window(std::mt19937& rng, double cycles_per_window) {
  std::uniform_real_distribution<double> phase(0.0, 2.0 * std::numbers::pi);
  std::normal_distribution<double> noise(0.0, 0.3);
  const double p = phase(rng);
  std::vector<float> w(kN);
  for (std::size_t i = 0; i < kN; ++i) {
    w[i] = static_cast<float>(
        std::sin(2.0 * std::numbers::pi * cycles_per_window * static_cast<double>(i) / kN + p) + noise(rng));
  }
  return w;
}

/// Adds one region with `count` windows at `hop` samples spacing.
void add_region(CollectedWindows& d, std::mt19937& rng, std::uint64_t region_seq, double speed,
                std::size_t count, std::int64_t hop, std::int64_t first0) {
  d.regions.push_back(region(region_seq, speed, 0.5, static_cast<std::int64_t>(region_seq) * 10 * kS));
  for (std::size_t j = 0; j < count; ++j) {
    WindowRef r;
    r.seq = d.refs.size();
    r.region_seq = region_seq;
    r.index_in_region = static_cast<std::uint32_t>(j);
    r.first_sample = first0 + static_cast<std::int64_t>(j) * hop;
    r.speed_rad_s = speed;
    d.refs.push_back(r);
    d.windows.push_back(tone_window(rng, 8.0));
  }
}

bool same_thresholds(const ClassBaseline& a, const ClassBaseline& b) {
  for (std::size_t m = 0; m < kMethodCount; ++m) {
    if (a.thresholds[m].rms.lo != b.thresholds[m].rms.lo ||
        a.thresholds[m].rms.hi != b.thresholds[m].rms.hi ||
        a.thresholds[m].entropy.lo != b.thresholds[m].entropy.lo ||
        a.thresholds[m].entropy.hi != b.thresholds[m].entropy.hi) {
      return false;
    }
  }
  return true;
}

TEST(TrainBaseline, OverlappingWindowsOfARegionShareAGroup) {
  std::mt19937 rng(3);
  CollectedWindows d;
  // Class +1.0: 4 regions of 3 windows with hop N/2 (each region is one overlap chain -> 4 groups).
  for (std::uint64_t r = 0; r < 4; ++r)
    add_region(d, rng, 2 * r, 1.0, 3, kN / 2, 1000 * static_cast<std::int64_t>(r));
  // Class -2.0: 3 regions (enough for a class), but the windows of each region overlap and one
  // region has no windows at all: 2 groups < 3, so the class is left out.
  add_region(d, rng, 1, -2.0, 2, kN / 2, 50'000);
  add_region(d, rng, 3, -2.0, 2, kN / 2, 60'000);
  d.regions.push_back(region(5, -2.0, 0.2));
  GearboxInfo gb;
  gb.kind = GearboxInfo::Kind::kCycloidal;
  gb.z_in = 10;
  gb.ratio = 33.86;
  ThresholdPolicy policy;
  policy.kind = ThresholdPolicy::Kind::kQuantile;
  policy.false_alarm_rate = 0.01;

  std::vector<std::string> dropped;
  const Baseline b = train_baseline(d, ClassLearningConfig{}, policy, 2000.0, gb, &dropped);
  // The class left out is named with its reason (issue 17), for `ptda train` to print.
  ASSERT_EQ(dropped.size(), 1U);
  EXPECT_EQ(dropped[0],
            "speed -2 rad/s: 3 regions but its 4 windows fall in 2 non-overlapping group(s), "
            "leave-one-group-out needs >= 3 (longer regions or more cycles)");
  EXPECT_EQ(b.fs_hz, 2000.0);
  EXPECT_EQ(b.window_len, kN);
  EXPECT_EQ(b.gearbox.ratio, 33.86);
  EXPECT_EQ(b.gearbox.z_in, 10U);
  EXPECT_EQ(b.policy.kind, ThresholdPolicy::Kind::kQuantile);
  ASSERT_EQ(b.classes.size(), 1U);
  const ClassBaseline& c = b.classes[0];
  EXPECT_EQ(c.segment.id, 0U);
  EXPECT_EQ(c.segment.direction, 1);
  EXPECT_EQ(c.segment.regions, 4U);
  EXPECT_EQ(c.n_windows, 12U);

  // Same as building the class directly with one group per region ...
  std::vector<std::vector<float>> w(d.windows.begin(), d.windows.begin() + 12);
  const std::vector<std::uint64_t> per_region = {0, 0, 0, 1, 1, 1, 2, 2, 2, 3, 3, 3};
  const ClassBaseline direct = build_class_baseline(c.segment, w, per_region, policy);
  EXPECT_TRUE(same_thresholds(c, direct));
  EXPECT_EQ(c.mean_magnitude, direct.mean_magnitude);
  // ... and not the same as treating every window as its own group (so the grouping is observable).
  const ClassBaseline per_window = build_class_baseline(c.segment, w, {}, policy);
  EXPECT_FALSE(same_thresholds(c, per_window));
}

TEST(TrainBaseline, OneLongConstantSpeedRegionGivesManyGroupsWhenWindowsAreDisjoint) {
  std::mt19937 rng(4);
  ClassLearningConfig cls;
  cls.min_regions = 1;
  CollectedWindows disjoint;
  add_region(disjoint, rng, 0, 1.5, 6, kN, 0);  // hop = N: windows touch but do not overlap
  const Baseline b = train_baseline(disjoint, cls, ThresholdPolicy{}, 2000.0, GearboxInfo{});
  ASSERT_EQ(b.classes.size(), 1U);
  EXPECT_EQ(b.classes[0].n_windows, 6U);
  std::vector<std::uint64_t> each = {0, 1, 2, 3, 4, 5};
  EXPECT_TRUE(same_thresholds(
      b.classes[0], build_class_baseline(b.classes[0].segment, disjoint.windows, each, ThresholdPolicy{})));

  // Hop N - 1: one overlap chain, one group: not trainable; the error says what was found.
  CollectedWindows chained;
  add_region(chained, rng, 0, 1.5, 6, kN - 1, 0);
  try {
    (void)train_baseline(chained, cls, ThresholdPolicy{}, 2000.0, GearboxInfo{});
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("1 regions, 6 windows"), std::string::npos) << msg;
    EXPECT_NE(msg.find("6 windows in 1 non-overlapping groups"), std::string::npos) << msg;
    EXPECT_NE(msg.find("; dropped speed +1.5 rad/s: 1 regions but its 6 windows fall in 1 non-overlapping "
                       "group(s), leave-one-group-out needs >= 3"),
              std::string::npos)
        << msg;
  }
}

TEST(TrainBaseline, ErrorsNameTheProblem) {
  std::mt19937 rng(5);
  CollectedWindows none;
  none.regions.push_back(region(0, 1.0, 1.0));
  try {
    (void)train_baseline(none, ClassLearningConfig{}, ThresholdPolicy{}, 2000.0, GearboxInfo{});
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("no constant-speed windows"), std::string::npos) << e.what();
  }
  CollectedWindows few;  // 2 regions: no class reaches min_regions = 3
  add_region(few, rng, 0, 1.0, 3, kN, 0);
  add_region(few, rng, 1, 1.0, 3, kN, 0);
  try {
    (void)train_baseline(few, ClassLearningConfig{}, ThresholdPolicy{}, 2000.0, GearboxInfo{});
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    const std::string msg = e.what();
    // Which speed group was dropped and why, not an anonymous count of "windows matching no class".
    EXPECT_NE(msg.find("2 regions, 6 windows, 6 of them in dropped speed groups; no class learned; dropped "
                       "speed +1 rad/s: 2 region(s), fewer than classes.min_regions = 3"),
              std::string::npos)
        << msg;
  }
  CollectedWindows mismatch = few;
  mismatch.windows.pop_back();
  EXPECT_THROW(
      (void)train_baseline(mismatch, ClassLearningConfig{}, ThresholdPolicy{}, 2000.0, GearboxInfo{}), Error);
}

// Streamed training (`ptda train`): the windows come through two passes instead of being held.
TEST(TrainBaselineStreamed, TwoPassesGiveTheSameBaselineAsTheWindowsHeldWithAHoldOut) {
  std::mt19937 rng(6);
  CollectedWindows d;
  // 6 regions of class +1.0 with overlapping windows (groups of 3), cut interleaved with a second class
  // -2.0 so each class's groups arrive between the other's windows.
  for (std::uint64_t r = 0; r < 6; ++r) {
    add_region(d, rng, 2 * r, 1.0, 3, kN / 2, 1000 * static_cast<std::int64_t>(r));
    add_region(d, rng, 2 * r + 1, -2.0, 2, kN, 100'000 + 1000 * static_cast<std::int64_t>(r));
  }
  d.recording.assign(d.refs.size(), 0U);
  for (std::size_t i = d.refs.size() / 2; i < d.refs.size(); ++i) d.recording[i] = 1U;  // two days
  ThresholdPolicy policy;
  policy.holdout_fraction = 0.34;  // 2 of the 6 groups of +1.0 and of the 6 of -2.0
  const Baseline held = train_baseline(d, ClassLearningConfig{}, policy, 2000.0, GearboxInfo{});
  ASSERT_EQ(held.classes.size(), 2U);
  EXPECT_EQ(held.classes[0].holdout[0].windows, 6U);  // 2 groups of 3 windows
  EXPECT_EQ(held.classes[1].holdout[0].windows, 4U);  // 4 of its 12 one-window groups

  CollectedWindows index = d;
  index.windows.clear();
  int passes = 0;
  const TrainingWindowPass pass = [&](const TrainingWindowVisitor& visit) {
    ++passes;
    std::vector<float> scratch;  // the samples live for the call only
    for (std::size_t i = 0; i < d.windows.size(); ++i) {
      scratch = d.windows[i];
      visit(i, scratch);
      std::fill(scratch.begin(), scratch.end(), std::nanf(""));
    }
  };
  const Baseline streamed =
      train_baseline_streamed(index, kN, pass, ClassLearningConfig{}, policy, 2000.0, GearboxInfo{});
  EXPECT_EQ(passes, 2);
  ASSERT_EQ(streamed.classes.size(), held.classes.size());
  for (std::size_t k = 0; k < held.classes.size(); ++k) {
    const ClassBaseline& a = held.classes[k];
    const ClassBaseline& b = streamed.classes[k];
    EXPECT_TRUE(same_thresholds(a, b)) << k;
    EXPECT_EQ(a.mean_magnitude, b.mean_magnitude);
    EXPECT_EQ(a.tda_mean, b.tda_mean);
    EXPECT_EQ(a.n_windows, b.n_windows);
    for (std::size_t m = 0; m < kMethodCount; ++m) {
      EXPECT_EQ(a.rms_stats[m].mean, b.rms_stats[m].mean);
      EXPECT_EQ(a.entropy_stats[m].stddev, b.entropy_stats[m].stddev);
      EXPECT_EQ(a.day_spread[m].log_rms_between_sd, b.day_spread[m].log_rms_between_sd);
      EXPECT_EQ(a.holdout[m].windows, b.holdout[m].windows);
      EXPECT_EQ(a.holdout[m].z_rms_mean, b.holdout[m].z_rms_mean);
      EXPECT_EQ(a.holdout[m].z_entropy_sd, b.holdout[m].z_entropy_sd);
    }
  }
  // The per-class builder, fed group by group, is what train_baseline runs: the same as building the
  // class from its windows (the fit windows of class +1.0: the first 4 regions).
  std::vector<std::vector<float>> w;
  std::vector<std::uint64_t> groups;
  std::vector<std::uint32_t> days;
  for (std::size_t i = 0; i < d.refs.size(); ++i) {
    if (d.refs[i].speed_rad_s > 0.0 && d.refs[i].region_seq < 8) {
      w.push_back(d.windows[i]);
      groups.push_back(d.refs[i].region_seq);
      days.push_back(d.recording[i]);
    }
  }
  ASSERT_EQ(w.size(), 12U);
  const ClassBaseline direct = build_class_baseline(held.classes[0].segment, w, groups, policy, days);
  EXPECT_EQ(direct.mean_magnitude, held.classes[0].mean_magnitude);
  EXPECT_TRUE(same_thresholds(direct, held.classes[0]));
}

// Every per-window list of the streamed training (index, groups, classes, leave-one-out features,
// hold-out features, durations) spills beyond SpillConfig::memory_bytes. With 64 bytes (8 doubles, one
// WindowRef) every list spills: the classes, counts and means are identical to the in-memory training,
// and the thresholds and statistics agree to rounding (the sums are formed chunk by chunk; the
// quantiles are exact). A directory that does not exist proves the spill happens: the training names it.
TEST(TrainBaselineStreamed, SpilledListsGiveTheSameBaselineForEveryThresholdModel) {
  std::mt19937 rng(11);
  CollectedWindows d;
  for (std::uint64_t r = 0; r < 40; ++r) {
    add_region(d, rng, 2 * r, 1.0 + 0.001 * static_cast<double>(r % 3), 3, kN / 2,
               1000 * static_cast<std::int64_t>(r));
    add_region(d, rng, 2 * r + 1, -2.0, 2, kN, 100'000 + 1000 * static_cast<std::int64_t>(r));
  }
  d.recording.assign(d.refs.size(), 0U);
  for (std::size_t i = 0; i < d.refs.size(); ++i)
    d.recording[i] = static_cast<std::uint32_t>(3 * i / d.refs.size());
  const auto rel = [](double a, double b) {
    return std::abs(a - b) / std::max(1e-300, std::max(std::abs(a), std::abs(b)));
  };
  for (const auto kind : {ThresholdPolicy::Kind::kGaussian, ThresholdPolicy::Kind::kQuantile,
                          ThresholdPolicy::Kind::kTolerance}) {
    SCOPED_TRACE(static_cast<int>(kind));
    ThresholdPolicy policy;
    policy.kind = kind;
    policy.false_alarm_rate = 0.05;
    policy.holdout_fraction = 0.25;
    policy.cover_recordings = true;
    const Baseline mem = train_baseline(d, ClassLearningConfig{}, policy, 2000.0, GearboxInfo{});
    const TrainingWindowPass pass = [&](const TrainingWindowVisitor& visit) {
      for (std::size_t i = 0; i < d.windows.size(); ++i) visit(i, d.windows[i]);
    };
    SpillConfig tiny;
    tiny.memory_bytes = 64;
    const Baseline spilled = train_baseline_streamed(make_training_index(d, tiny), kN, pass,
                                                     ClassLearningConfig{}, policy, 2000.0, GearboxInfo{});
    ASSERT_EQ(spilled.classes.size(), 2U);
    ASSERT_EQ(spilled.classes.size(), mem.classes.size());
    for (std::size_t k = 0; k < mem.classes.size(); ++k) {
      const ClassBaseline& a = mem.classes[k];
      const ClassBaseline& b = spilled.classes[k];
      EXPECT_EQ(a.segment.speed_rad_s, b.segment.speed_rad_s);
      EXPECT_EQ(a.segment.duration_s, b.segment.duration_s);
      EXPECT_EQ(a.segment.regions, b.segment.regions);
      EXPECT_EQ(a.n_windows, b.n_windows);
      EXPECT_EQ(a.mean_magnitude, b.mean_magnitude);
      EXPECT_EQ(a.tda_mean, b.tda_mean);
      for (std::size_t m = 0; m < kMethodCount; ++m) {
        EXPECT_LT(rel(a.thresholds[m].rms.lo, b.thresholds[m].rms.lo), 1e-12) << k << " " << m;
        EXPECT_LT(rel(a.thresholds[m].rms.hi, b.thresholds[m].rms.hi), 1e-12) << k << " " << m;
        EXPECT_LT(rel(a.thresholds[m].entropy.lo, b.thresholds[m].entropy.lo), 1e-12) << k << " " << m;
        EXPECT_LT(rel(a.thresholds[m].entropy.hi, b.thresholds[m].entropy.hi), 1e-12) << k << " " << m;
        EXPECT_EQ(a.rms_stats[m].n, b.rms_stats[m].n);
        EXPECT_EQ(a.rms_stats[m].min, b.rms_stats[m].min);
        EXPECT_EQ(a.rms_stats[m].max, b.rms_stats[m].max);
        EXPECT_LT(rel(a.rms_stats[m].mean, b.rms_stats[m].mean), 1e-12);
        EXPECT_LT(rel(a.entropy_stats[m].stddev, b.entropy_stats[m].stddev), 1e-12);
        EXPECT_LT(rel(a.log_rms_stats[m].stddev, b.log_rms_stats[m].stddev), 1e-12);
        EXPECT_EQ(a.day_spread[m].recordings, b.day_spread[m].recordings);
        EXPECT_EQ(a.day_spread[m].log_rms_between_sd, b.day_spread[m].log_rms_between_sd);
        EXPECT_EQ(a.holdout[m].windows, b.holdout[m].windows);
        EXPECT_EQ(a.holdout[m].abnormal, b.holdout[m].abnormal);
        EXPECT_LT(rel(a.holdout[m].z_rms_mean, b.holdout[m].z_rms_mean), 1e-9);
      }
    }
    EXPECT_GT(mem.classes[0].holdout[0].windows, 0U);
    // The lists did spill: a training whose spill directory does not exist stops with its name...
    SpillConfig nowhere = tiny;
    nowhere.dir = "/nonexistent-ptda-spill-dir";
    try {
      (void)train_baseline_streamed(make_training_index(d, nowhere), kN, pass, ClassLearningConfig{}, policy,
                                    2000.0, GearboxInfo{});
      ADD_FAILURE() << "no error";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("/nonexistent-ptda-spill-dir"), std::string::npos) << e.what();
    }
    // ...and the default 32 KiB per list holds these in memory: the same directory is never touched,
    // and the result is the in-memory training's, bit for bit.
    nowhere.memory_bytes = SpillConfig{}.memory_bytes;
    const Baseline held = train_baseline_streamed(make_training_index(d, nowhere), kN, pass,
                                                  ClassLearningConfig{}, policy, 2000.0, GearboxInfo{});
    ASSERT_EQ(held.classes.size(), mem.classes.size());
    for (std::size_t k = 0; k < mem.classes.size(); ++k)
      EXPECT_TRUE(same_thresholds(mem.classes[k], held.classes[k]));
  }
}

TEST(TrainBaselineStreamed, APassThatSkipsOrReordersWindowsIsRefused) {
  std::mt19937 rng(7);
  CollectedWindows d;
  for (std::uint64_t r = 0; r < 4; ++r)
    add_region(d, rng, r, 1.0, 2, kN, 1000 * static_cast<std::int64_t>(r));
  CollectedWindows index = d;
  index.windows.clear();
  const auto train = [&](const TrainingWindowPass& pass) {
    return train_baseline_streamed(index, kN, pass, ClassLearningConfig{}, ThresholdPolicy{}, 2000.0,
                                   GearboxInfo{});
  };
  const auto message = [&](const TrainingWindowPass& pass) -> std::string {
    try {
      (void)train(pass);
    } catch (const Error& e) {
      return e.what();
    }
    return "no error";
  };
  EXPECT_EQ(train([&](const TrainingWindowVisitor& v) {
              for (std::size_t i = 0; i < d.windows.size(); ++i) v(i, d.windows[i]);
            }).classes.size(),
            1U);
  EXPECT_EQ(message([&](const TrainingWindowVisitor& v) {
              for (std::size_t i = 0; i + 1 < d.windows.size(); ++i) v(i, d.windows[i]);
            }),
            "train_baseline: pass 1 handed over 7 of 8 windows (the windows changed between passes)");
  EXPECT_EQ(message([&](const TrainingWindowVisitor& v) {
              for (std::size_t i = 1; i < d.windows.size(); ++i) v(i, d.windows[i]);
            }),
            "train_baseline: pass 1 handed over window 1 where window 0 was expected (the windows changed "
            "between passes)");
  const std::vector<float> short_window(kN / 2, 0.0F);
  EXPECT_EQ(message([&](const TrainingWindowVisitor& v) {
              for (std::size_t i = 0; i < d.windows.size(); ++i) v(i, i == 3 ? short_window : d.windows[i]);
            }),
            "class 0: window 3 has 32 samples, expected 64");
}

}  // namespace
}  // namespace ptda::dsp
