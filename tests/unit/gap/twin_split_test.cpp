// The measured-motion twin (the model moves along a recording's CAN speed) and the program-period
// split (docs/gap.md "Method", steps 2-3).
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "gap_test_job.hpp"
#include "ptda/common/error.hpp"
#include "ptda/gap/diagnose.hpp"
#include "ptda/gap/signals.hpp"
#include "ptda/sim/simulator.hpp"

namespace ptda::gap {
namespace {

// A back-and-forth job that rests before every move: out over pi, rest, back, rest. Each move is one unit
// of the segmentation, so the program period is two units.
sim::Scenario rest_before_every_move(std::uint32_t cycles) {
  sim::Scenario s = test::joint_rotation_job(cycles);
  s.motion.via_points_rad = {0.0, std::numbers::pi, std::numbers::pi, 0.0};
  s.motion.segment_durations_s.clear();
  s.motion.segment_speeds_rad_s.clear();
  // Durations: move, hold (0.5 s standstill inside the cycle), move.
  s.motion.segment_durations_s = {1.2, 0.5, 1.2};
  return s;
}

struct Cut {
  std::vector<Segment> segs;
  AnalysisPlan plan;
  std::vector<Window> windows;
};

Cut cut(const GapRecording& rec) {
  Cut c;
  c.segs = segment_recording(rec);
  c.plan = make_plan(rec, c.segs);
  c.windows = cut_windows(rec, c.segs, c.plan);
  return c;
}

TEST(ProgramSplit, BackAndForthWithRestsHasATwoMovePeriodAndBothPartsHoldEveryClass) {
  const sim::Scenario s = rest_before_every_move(4);
  const GapRecording rec = recording_from_simulation(sim::simulate_signals(s, 3), s);
  const Cut c = cut(rec);
  ASSERT_EQ(c.plan.cycles, 8U);  // 4 cycles x 2 moves, each starting from rest
  ASSERT_EQ(c.plan.speeds.size(), 2U);
  const ProgramSplit sp =
      find_program_split(c.segs, c.plan, static_cast<double>(rec.accel_ms2.size()) / rec.fs_hz);
  EXPECT_EQ(sp.period_units, 2U);
  EXPECT_EQ(sp.periods, 4U);
  EXPECT_TRUE(sp.enough);
  // The old even/odd split put every outward move in the fit part: here both directions are in both.
  EXPECT_TRUE(missing_classes(c.windows, c.plan, sp.fit, sp.held).empty());
  std::vector<char> even(8, 0), odd(8, 0);
  for (int u = 0; u < 8; ++u) (u % 2 == 0 ? even : odd)[static_cast<std::size_t>(u)] = 1;
  EXPECT_EQ(missing_classes(c.windows, c.plan, even, odd).size(), 2U);  // the failure the split avoids
  // A period starts every move pair: 2 x (1.2 + 0.5 + 1.2 ... ) -> start to start of a cycle.
  EXPECT_NEAR(sp.period_s, 2.9 + s.motion.dwell_s + 0.5 * s.motion.start_jitter_s, 0.1);
}

TEST(ProgramSplit, OneMoveCyclesKeepThePeriodOfOne) {
  const sim::Scenario s = test::joint_rotation_job(6);  // out and back without a rest between: one unit
  const GapRecording rec = recording_from_simulation(sim::simulate_signals(s, 3), s);
  const Cut c = cut(rec);
  const ProgramSplit sp =
      find_program_split(c.segs, c.plan, static_cast<double>(rec.accel_ms2.size()) / rec.fs_hz);
  EXPECT_EQ(sp.period_units, 1U);
  EXPECT_EQ(sp.units, 6U);
  EXPECT_EQ(std::count(sp.fit.begin(), sp.fit.end(), 1), 3);
  EXPECT_TRUE(missing_classes(c.windows, c.plan, sp.fit, sp.held).empty());
}

TEST(ProgramSplit, TooShortRecordingSaysWhatLengthIsNeeded) {
  const sim::Scenario s = rest_before_every_move(1);  // one period: two moves
  const GapRecording rec = recording_from_simulation(sim::simulate_signals(s, 3), s);
  const Cut c = cut(rec);
  const ProgramSplit sp =
      find_program_split(c.segs, c.plan, static_cast<double>(rec.accel_ms2.size()) / rec.fs_hz);
  EXPECT_FALSE(sp.enough);
  EXPECT_NE(sp.need.find("too short to split"), std::string::npos) << sp.need;
  EXPECT_NE(sp.need.find("periods and >= 4 moves"), std::string::npos) << sp.need;
  EXPECT_NE(sp.need.find("s of recording"), std::string::npos) << sp.need;
  // diagnose() refuses with the same message, naming the recording.
  sim::Scenario nominal = s;
  try {
    (void)diagnose(nominal, rec, DiagnoseOptions{});
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("too short to split"), std::string::npos) << e.what();
  }
}

TEST(MeasuredTwin, SimulatedSpeedFollowsTheMeasuredCanSpeed) {
  // "Measured": the back-and-forth job with 20 ms of extra CAN latency it does not announce and start
  // jitter the nominal cannot know.
  sim::Scenario real_s = rest_before_every_move(3);
  real_s.motion.start_jitter_s = 0.3;
  const GapRecording rec = recording_from_simulation(sim::simulate_signals(real_s, 77), real_s);
  sim::Scenario twin = test::joint_rotation_job(1);
  twin.motion.kind = sim::MotionKind::kMeasured;
  twin.motion.duration_s = static_cast<double>(rec.accel_ms2.size()) / rec.fs_hz;
  for (const SpeedPoint& p : rec.speed) {
    twin.motion.measured_t_s.push_back(p.t_s);
    twin.motion.measured_speed_rad_s.push_back(p.speed_rad_s);
  }
  const sim::MotionProfile m = sim::build_motion(twin, 1);
  const double deadband =
      sim::measured_motion_deadband(twin.motion.measured_t_s, twin.motion.measured_speed_rad_s);
  // The dead band sits between the CAN quantisation (1e-4 rad/s per 4 ms) and the blend acceleration.
  EXPECT_GT(deadband, 0.02 * 3.49);
  EXPECT_LT(deadband, 0.5 * 17.45);
  // Bound (simulator.hpp): at the measured instants |speed - measured| <= deadband x interval / 2.
  double worst = 0.0;
  for (std::size_t i = 1; i < rec.speed.size(); ++i) {
    const double t = rec.speed[i].t_s;
    if (t <= 0.0 || t >= m.duration_s) continue;
    const double bound = 0.5 * deadband * (rec.speed[i].t_s - rec.speed[i - 1].t_s) + 1e-9;
    const double err = std::fabs(sim::motion_at(m, t).speed_rad_s - rec.speed[i].speed_rad_s);
    EXPECT_LE(err, bound + 0.5 * deadband * 0.0042) << "t " << t;
    worst = std::max(worst, err);
  }
  EXPECT_LT(worst, 0.02);  // rad/s: the twin moves as the recording did (top speed 3.49 rad/s)
  // The angle is the integral of the speed: the net travel of the 3 cycles (out and back) is ~0, each
  // outward move pi.
  EXPECT_NEAR(sim::motion_at(m, m.duration_s).angle_rad - sim::motion_at(m, 0.0).angle_rad, 0.0, 0.02);
  double peak = 0.0;
  for (std::size_t i = 0; i < m.angle_rad.size(); i += 64)
    peak = std::max(peak, m.angle_rad[i] - m.angle_rad[0]);
  EXPECT_NEAR(peak, std::numbers::pi, 0.02);
  // Torque reversals (starts of acceleration pieces of a new sign, where the impacts effect knocks) are
  // the job's, not CAN noise: as many as in the profile that made the recording (+ - - + per cycle:
  // 1 + 2 x 3 = 7).
  auto reversals = [](const sim::MotionProfile& p) {
    int n = 0;
    double last = 0.0;
    for (const sim::MotionPiece& q : p.pieces) {
      const double sg = q.accel_rad_s2 > 0 ? 1.0 : (q.accel_rad_s2 < 0 ? -1.0 : 0.0);
      if (sg == 0.0) continue;
      if (sg != last) ++n;
      last = sg;
    }
    return n;
  };
  EXPECT_EQ(reversals(sim::build_motion(real_s, 77)), 7);
  EXPECT_EQ(reversals(m), 7);
}

TEST(MeasuredTwin, MalformedTraceIsAClearError) {
  sim::Scenario s = test::joint_rotation_job(1);
  s.motion.kind = sim::MotionKind::kMeasured;
  s.motion.duration_s = 1.0;
  s.motion.measured_t_s = {0.0, 0.5, 0.4};
  s.motion.measured_speed_rad_s = {0.0, 1.0, 1.0};
  EXPECT_THROW((void)sim::build_motion(s, 1), Error);
  s.motion.measured_t_s = {0.0};
  s.motion.measured_speed_rad_s = {0.0};
  EXPECT_THROW((void)sim::build_motion(s, 1), Error);
}

TEST(MeasuredTwin, ModelDurationEqualsTheMeasuredDuration) {
  // The diagnosis of a rest-before-every-move recording runs on the twin: the JSON says so, and the
  // split holds both directions on both sides.
  const sim::Scenario s = rest_before_every_move(3);
  const GapRecording rec = recording_from_simulation(sim::simulate_signals(s, 5), s);
  EXPECT_EQ(measured_speed_problem(rec), "");
  DiagnoseOptions opt;
  opt.max_effects = 0;
  const Diagnosis d = diagnose(s, rec, opt);
  EXPECT_EQ(d.motion_source, "measured");
  EXPECT_EQ(d.period_units, 2U);
  EXPECT_TRUE(d.split_missing.empty());
  EXPECT_EQ(d.fit_cycles, 3U);
  EXPECT_EQ(d.heldout_cycles, 3U);
  // The nominal is the truth here: the calibrated model's gap is at the sampling level.
  EXPECT_FALSE(d.gap_significant) << d.verdict;
}

}  // namespace
}  // namespace ptda::gap
