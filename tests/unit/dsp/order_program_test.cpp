// Issue 16, done-when: "On a job with no plateau of 0.2 s, the order domain alarms on a fault and stays
// quiet on healthy data." The job is order_bench's --program short (dsp/bench/order_program.hpp):
// 0.15 s plateaus between 0.2 s ramps, +-3 % speed ripple. The time domain (the product's WindowSlicer at
// its default 2 % tolerance, N = 8192) cuts nothing there; the order domain (S = 1024, R = 8, speed band
// [0.4, 1.07] f0) trains on a healthy job, stays quiet on a fresh healthy job and alarms (k-of-n 3 of 5,
// the product default) on the spur-tooth fault at full severity.
// Pinned numbers come from `order_bench --program short --seeds 1 --ripples 0.03 --severities 1`
// (development seed 1, session 10): 44 training / 31 healthy / 31 faulty order windows, 0 of 31 healthy
// windows abnormal, 31 of 31 faulty windows abnormal, first abnormal window 0, alarm at window 2 ending
// 2.411 s after the job start, coverage 58.1 % of motion time.
#include "../../../dsp/bench/order_program.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstddef>
#include <vector>

#include "ptda/dsp/analyzer.hpp"
#include "ptda/dsp/decision.hpp"
#include "ptda/dsp/monitor_engine.hpp"
#include "ptda/dsp/training.hpp"

namespace {

using namespace ptda::dsp;
namespace ob = ptda::order_bench;

constexpr std::uint64_t kSeed = 1;  // a development seed of order_bench
constexpr double kRipple = 0.03;

struct Judged {
  std::size_t abnormal = 0;
  long first_abnormal = -1;
  long first_alarm = -1;
  double first_alarm_s = -1.0;
  bool alarm = false;
};

Judged judge_all(const ClassBaseline& c, const ob::Cut& cut) {
  WindowAnalyzer a(ob::kN);
  const FeatureThresholds& th = c.thresholds[static_cast<std::size_t>(Method::kPtda)];
  const DecisionConfig dc;  // product default k-of-n
  KOfNDebouncer deb(dc.k, dc.n);
  Judged j;
  for (std::size_t i = 0; i < cut.w.size(); ++i) {
    const bool ab = judge(a.analyze(cut.w[i], c, Method::kPtda), th).abnormal();
    if (ab) {
      ++j.abnormal;
      if (j.first_abnormal < 0) j.first_abnormal = static_cast<long>(i);
    }
    if (deb.push(ab)) {
      j.alarm = true;
      if (j.first_alarm < 0) {
        j.first_alarm = static_cast<long>(i);
        j.first_alarm_s = cut.t_end_s[i];
      }
    }
  }
  return j;
}

TEST(OrderProgram, ShortPlateauJobHasNoPlateauOf200ms) {
  double motion_plateau_max_s = 0.0;
  for (const ob::Segment& s : ob::program_cycle("short"))
    if (s.v0 == s.v1 && s.v0 > 0.0) motion_plateau_max_s = std::max(motion_plateau_max_s, s.dur_s);
  EXPECT_GT(motion_plateau_max_s, 0.0);
  EXPECT_LT(motion_plateau_max_s, 0.2);
  for (const ob::Segment& s : ob::program_cycle("accel")) EXPECT_TRUE(s.v0 != s.v1 || s.v0 == 0.0);
}

TEST(OrderProgram, OrderDomainAlarmsOnFaultAndStaysQuietWithoutPlateau) {
  const ob::ProgJob tr = ob::make_program_job(kSeed * 1000 + 1, 24, "short", kRipple, ob::Fault{});
  const ob::ProgJob he = ob::make_program_job(kSeed * 1000 + 2, 16, "short", kRipple, ob::Fault{});
  const ob::ProgJob fa = ob::make_program_job(kSeed * 1000 + 3, 16, "short", kRipple, ob::Fault{0.3, 0.1});

  // The time domain at the default tolerance cuts no window from any of the three jobs.
  EXPECT_EQ(ob::time_cut(tr).w.size(), 0U);
  EXPECT_EQ(ob::time_cut(he).w.size(), 0U);
  EXPECT_EQ(ob::time_cut(fa).w.size(), 0U);

  const ob::Cut trc = ob::order_cut(tr), hec = ob::order_cut(he), fac = ob::order_cut(fa);
  ASSERT_EQ(trc.w.size(), 44U);
  ASSERT_EQ(hec.w.size(), 31U);
  ASSERT_EQ(fac.w.size(), 31U);
  EXPECT_NEAR(hec.judged_s / he.motion_s, 0.5814, 5e-4);

  std::vector<std::uint64_t> groups(trc.w.size());
  for (std::size_t i = 0; i < groups.size(); ++i) groups[i] = i;
  const ClassBaseline c = build_class_baseline(SegmentClass{}, trc.w, groups, ThresholdPolicy{});

  const Judged h = judge_all(c, hec);
  EXPECT_EQ(h.abnormal, 0U);
  EXPECT_FALSE(h.alarm);

  const Judged f = judge_all(c, fac);
  EXPECT_EQ(f.abnormal, 31U);
  EXPECT_EQ(f.first_abnormal, 0);
  EXPECT_EQ(f.first_alarm, 2);
  EXPECT_NEAR(f.first_alarm_s, 2.411, 1e-3);
}

}  // namespace
