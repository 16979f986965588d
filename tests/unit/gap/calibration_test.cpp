// Calibration kept apart from unmodelled effects (docs/gap.md "Calibration"): a nominal that is wrong only
// in its own free parameters (harmonic levels, noise level) is re-calibrated, the offsets are reported
// with their uncertainty, and no library effect is named.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

#include "gap_test_job.hpp"
#include "ptda/gap/diagnose.hpp"
#include "ptda/gap/signals.hpp"
#include "ptda/sim/simulator.hpp"

namespace ptda::gap {
namespace {}  // namespace

inline const CalibratedParam* find(const Diagnosis& d, const std::string& name) {
  for (const CalibratedParam& c : d.calibration)
    if (c.name == name) return &c;
  return nullptr;
}

namespace {

TEST(Calibration, NominalOffByKnownDecibelsIsRecalibratedAndNamesNoEffect) {
  const sim::Scenario truth = test::joint_rotation_job(6);
  const GapRecording real = recording_from_simulation(sim::simulate_signals(truth, 1234), truth);
  // The nominal: order 1 +6 dB, order 5 -6 dB, order 8 +3 dB, noise +30 % (2.3 dB) against the machine.
  sim::Scenario nominal = truth;
  nominal.vibration.gmf_amplitudes[0] *= 2.0;
  nominal.vibration.gmf_amplitudes[4] *= 0.5;
  nominal.vibration.gmf_amplitudes[7] *= std::pow(10.0, 3.0 / 20.0);
  nominal.vibration.noise_rms *= 1.3;
  DiagnoseOptions opt;
  const Diagnosis d = diagnose(nominal, real, opt);
  EXPECT_TRUE(d.chosen.empty()) << d.verdict;
  EXPECT_TRUE(d.recalibrated);
  EXPECT_EQ(d.verdict.rfind("no unmodelled effect; nominal re-calibrated", 0), 0U) << d.verdict;
  // Recovered: calibrated / nominal = the inverse of the error, within 3 stated sd + 0.5 dB (the
  // calibration stops once every offset is below 0.5 dB).
  struct Want {
    const char* name;
    double db;
  };
  for (const Want w : {Want{"gmf_order_1", -6.02}, Want{"gmf_order_5", 6.02}, Want{"gmf_order_8", -3.0},
                       Want{"noise_rms", -2.28}}) {
    const CalibratedParam* c = find(d, w.name);
    ASSERT_NE(c, nullptr) << w.name;
    EXPECT_GT(c->sd_db, 0.0) << w.name;
    EXPECT_NEAR(c->offset_db, w.db, 3.0 * c->sd_db + 0.5) << w.name << ": " << c->sentence;
    EXPECT_TRUE(c->significant) << w.name;
  }
  // Orders the nominal had right are not reported as changed.
  const CalibratedParam* o7 = find(d, "gmf_order_7");
  ASSERT_NE(o7, nullptr);
  EXPECT_FALSE(o7->significant) << o7->sentence;
  EXPECT_NE(d.verdict.find("order 1 is"), std::string::npos) << d.verdict;
}

}  // namespace
}  // namespace ptda::gap

namespace ptda::gap {
namespace {

// Step 1c (session 37): the machine's mesh waveform has other harmonic phases than the nominal's. They
// are read off the measured fit part: the calibrated phases equal the machine's up to a common shift of
// the mesh angle (phase k + k d), and no effect is named. The same nominal with the machine's phases keeps
// them (the entry is there and not significant).
TEST(Calibration, HarmonicPhasesAreReadOffTheMeasurementUpToACommonShift) {
  sim::Scenario truth = test::joint_rotation_job(6);
  const std::size_t n_h = truth.vibration.gmf_amplitudes.size();
  ASSERT_GE(n_h, 3U);
  const double pattern[] = {0.0, 1.9, -2.4, 0.7, 2.8, -1.1, 0.4, -2.9, 1.3, -0.6};
  truth.vibration.gmf_phases_rad.assign(n_h, 0.0);
  for (std::size_t k = 0; k < n_h; ++k) truth.vibration.gmf_phases_rad[k] = pattern[k % 10];
  const GapRecording real = recording_from_simulation(sim::simulate_signals(truth, 4321), truth);
  sim::Scenario nominal = truth;
  nominal.vibration.gmf_phases_rad.clear();  // the nominal knows the levels, not the phases
  const Diagnosis d = diagnose(nominal, real, DiagnoseOptions{});
  EXPECT_TRUE(d.chosen.empty()) << d.verdict;
  const CalibratedParam* p = find(d, "gmf_phases");
  ASSERT_NE(p, nullptr);
  EXPECT_TRUE(p->significant) << p->sentence;
  ASSERT_EQ(d.calibrated_gmf_phases_rad.size(), n_h);
  // The common shift d from orders 1 and 2 (phase k - k d), then every strong order within 0.2 rad.
  double best = -1e300, shift = 0.0;
  for (int st = 0; st < 3600; ++st) {
    const double dd = 2.0 * std::numbers::pi * st / 3600.0;
    double r = 0.0;
    for (std::size_t k = 0; k < n_h; ++k) {
      if (truth.vibration.gmf_amplitudes[k] <= 0.0) continue;
      r += truth.vibration.gmf_amplitudes[k] *
           std::cos(d.calibrated_gmf_phases_rad[k] - static_cast<double>(k + 1) * dd -
                    truth.vibration.gmf_phases_rad[k]);
    }
    if (r > best) {
      best = r;
      shift = dd;
    }
  }
  double top = 0.0;
  for (double a : truth.vibration.gmf_amplitudes) top = std::max(top, a);
  int checked = 0;
  for (std::size_t k = 0; k < n_h; ++k) {
    if (truth.vibration.gmf_amplitudes[k] < 0.2 * top) continue;
    const double err = std::remainder(d.calibrated_gmf_phases_rad[k] - static_cast<double>(k + 1) * shift -
                                          truth.vibration.gmf_phases_rad[k],
                                      2.0 * std::numbers::pi);
    EXPECT_LT(std::fabs(err), 0.2) << "order " << k + 1;
    ++checked;
  }
  EXPECT_GE(checked, 3);
  // Told the machine's phases, the nominal keeps them.
  const Diagnosis same = diagnose(truth, real, DiagnoseOptions{});
  const CalibratedParam* q = find(same, "gmf_phases");
  ASSERT_NE(q, nullptr);
  EXPECT_FALSE(q->significant) << q->sentence;
  EXPECT_EQ(same.calibrated_gmf_phases_rad, truth.vibration.gmf_phases_rad);
}

TEST(Calibration, SpeedExponentIsCalibratedWithinOneDirection) {
  // Two plateau speeds in the positive direction (2.0 and 3.49 rad/s), one negative: the levels follow
  // speed^1.0, the nominal says speed^1.8 (+4.5 dB between 2.0 and 3.49 rad/s).
  sim::Scenario truth = test::joint_rotation_job(6);
  truth.motion.via_points_rad = {0.0, 1.2, 3.0, 0.0};
  truth.motion.segment_speeds_rad_s = {2.0, 3.49068, 3.0};
  const GapRecording real = recording_from_simulation(sim::simulate_signals(truth, 99), truth);
  sim::Scenario nominal = truth;
  nominal.vibration.amplitude_speed_exponent = 1.8;
  const Diagnosis d = diagnose(nominal, real, DiagnoseOptions{});
  const CalibratedParam* e = find(d, "amplitude_speed_exponent");
  ASSERT_NE(e, nullptr);
  EXPECT_GT(e->sd_db, 0.0);
  EXPECT_TRUE(e->significant) << e->sentence;
  // Recovered within 3 sd (in exponent units: sd_db / span_db) + the 0.05 step below which it stops.
  const double span_db = 20.0 * std::log10(3.49068 / 2.0);
  EXPECT_NEAR(e->calibrated, 1.0, 3.0 * e->sd_db / span_db + 0.05) << e->sentence;
  EXPECT_TRUE(d.chosen.empty()) << d.verdict;
}

}  // namespace
}  // namespace ptda::gap

namespace ptda::gap {
namespace {

TEST(Calibration, FloorSlopeIsCalibrationNotAnEffect) {
  // The machine's floor rises by 8 dB per decade; the nominal's is white (docs/gap.md "Calibration").
  sim::Scenario truth = test::joint_rotation_job(6);
  truth.vibration.noise_tilt_db_per_decade = 8.0;
  const GapRecording real = recording_from_simulation(sim::simulate_signals(truth, 4321), truth);
  sim::Scenario nominal = truth;
  nominal.vibration.noise_tilt_db_per_decade = 0.0;
  const Diagnosis d = diagnose(nominal, real, DiagnoseOptions{});
  EXPECT_TRUE(d.chosen.empty()) << d.verdict;
  const CalibratedParam* t = find(d, "noise_tilt_db_per_decade");
  ASSERT_NE(t, nullptr);
  EXPECT_GT(t->sd_db, 0.0);
  EXPECT_TRUE(t->significant) << t->sentence;
  // Recovered within 3 sd + 1 dB/decade (the calibration stops below a 0.5 dB step).
  EXPECT_NEAR(t->calibrated, 8.0, 3.0 * t->sd_db + 1.0) << t->sentence;
  EXPECT_NEAR(d.calibrated_noise_tilt_db_per_decade, t->calibrated, 1e-12);
  EXPECT_EQ(d.verdict.rfind("no unmodelled effect; nominal re-calibrated", 0), 0U) << d.verdict;
  EXPECT_NE(d.verdict.find("slope"), std::string::npos) << d.verdict;
}

TEST(Calibration, WhiteFloorKeepsItsSlopeAtZero) {
  // Same machine with the nominal's white floor: the slope is not reported as changed.
  const sim::Scenario truth = test::joint_rotation_job(6);
  const GapRecording real = recording_from_simulation(sim::simulate_signals(truth, 4321), truth);
  const Diagnosis d = diagnose(truth, real, DiagnoseOptions{});
  const CalibratedParam* t = find(d, "noise_tilt_db_per_decade");
  ASSERT_NE(t, nullptr);
  EXPECT_FALSE(t->significant) << t->sentence;
  EXPECT_LT(std::fabs(t->calibrated), 1.0) << t->sentence;
}

}  // namespace
}  // namespace ptda::gap

namespace ptda::gap {
namespace {

TEST(Calibration, ShaftOrderLineLevelsAreCalibration) {
  // The machine has shaft-order lines 3 and 7 at 0.5 and 0.3 m/s^2; the nominal lists them 6 dB too low
  // and 4 dB too high.
  sim::Scenario truth = test::joint_rotation_job(6);
  truth.vibration.shaft_orders = {3, 7};
  truth.vibration.shaft_order_amplitudes = {0.5, 0.3};
  const GapRecording real = recording_from_simulation(sim::simulate_signals(truth, 77), truth);
  sim::Scenario nominal = truth;
  nominal.vibration.shaft_order_amplitudes = {0.25, 0.3 * std::pow(10.0, 4.0 / 20.0)};
  const Diagnosis d = diagnose(nominal, real, DiagnoseOptions{});
  EXPECT_TRUE(d.chosen.empty()) << d.verdict;
  const CalibratedParam* s3 = find(d, "shaft_order_3");
  const CalibratedParam* s7 = find(d, "shaft_order_7");
  ASSERT_NE(s3, nullptr);
  ASSERT_NE(s7, nullptr);
  EXPECT_GT(s3->sd_db, 0.0);
  EXPECT_NEAR(s3->offset_db, 6.02, 3.0 * s3->sd_db + 0.5) << s3->sentence;
  EXPECT_NEAR(s7->offset_db, -4.0, 3.0 * s7->sd_db + 0.5) << s7->sentence;
  EXPECT_TRUE(s3->significant);
  EXPECT_TRUE(s7->significant);
  EXPECT_NE(d.verdict.find("shaft order 3 is"), std::string::npos) << d.verdict;
}

}  // namespace
}  // namespace ptda::gap

namespace ptda::gap {
namespace {

// The speed frames' scale (docs/gap.md step 1b): the machine's shaft turns 3000 ppm faster than its speed
// frames say (a slipping drive seen the other way round, or a log written from a nominal speed).
GapRecording frames_slow_by(const sim::Scenario& truth, double ppm, std::uint64_t seed) {
  GapRecording real = recording_from_simulation(sim::simulate_signals(truth, seed), truth);
  for (SpeedPoint& p : real.speed) p.speed_rad_s /= 1.0 + ppm * 1e-6;
  return real;
}

TEST(SpeedScale, EstimateReadsTheLinesOffsetAndStaysInsideTheNeighbouringOrders) {
  sim::Scenario truth = test::joint_rotation_job(4);
  truth.vibration.shaft_orders = {3, 7};
  truth.vibration.shaft_order_amplitudes = {0.5, 0.3};
  const GapRecording real = frames_slow_by(truth, 3000.0, 91);
  const std::vector<Segment> segs = segment_recording(real);
  ProbeContext ctx;
  ctx.gearbox = truth.gearbox;
  ctx.plan = make_plan(real, segs);
  for (std::size_t k = 0; k < truth.vibration.gmf_amplitudes.size(); ++k)
    if (truth.vibration.gmf_amplitudes[k] > 0.0) ctx.nominal_orders.push_back(static_cast<int>(k + 1));
  ctx.nominal_shaft_orders = {3, 7};
  const ProbeSet ps = compute_probes(real, segs, cut_windows(real, segs, ctx.plan), {}, ctx);
  const SpeedScaleEstimate e = estimate_speed_scale(ps, ctx, 0.01);
  EXPECT_GE(e.lines, 4);
  // Within 3 stated sd plus the parabolic interpolation's bias on a Hann window. Measured here: 2981.3 +- 0.6
  // ppm for 3000, and -13.4 +- 2.6 for exact frames.
  EXPECT_NEAR(e.ppm, 3000.0, 3.0 * e.sd_ppm + 60.0) << e.sd_ppm << " from " << e.lines;
  EXPECT_GT(e.sd_ppm, 0.0);
  // Without a tolerance nothing is estimated.
  EXPECT_EQ(estimate_speed_scale(ps, ctx, 0.0).lines, 0);
  // Exact frames read as exact, within the bias the diagnosis leaves alone (kSpeedScaleMinPpm = 100).
  const GapRecording exact = frames_slow_by(truth, 0.0, 91);
  const std::vector<Segment> segs0 = segment_recording(exact);
  ProbeContext ctx0 = ctx;
  ctx0.plan = make_plan(exact, segs0);
  const ProbeSet ps0 = compute_probes(exact, segs0, cut_windows(exact, segs0, ctx0.plan), {}, ctx0);
  const SpeedScaleEstimate e0 = estimate_speed_scale(ps0, ctx0, 0.01);
  EXPECT_LT(std::fabs(e0.ppm), 100.0) << e0.sd_ppm;
  std::printf("speed scale estimate: %.1f +- %.1f ppm (3000 true), %.1f +- %.1f (0 true), %d lines\n", e.ppm,
              e.sd_ppm, e0.ppm, e0.sd_ppm, e.lines);
}

TEST(SpeedScale, WithinTheToleranceItIsCalibrationAndNamesNoEffect) {
  sim::Scenario truth = test::joint_rotation_job(6);
  const GapRecording real = frames_slow_by(truth, 3000.0, 92);
  sim::Scenario nominal = truth;
  nominal.can.speed_scale_tolerance = 0.01;
  const Diagnosis d = diagnose(nominal, real, DiagnoseOptions{});
  EXPECT_NEAR(d.speed_scale_applied_ppm, 3000.0, 3.0 * d.speed_scale_sd_ppm + 60.0);
  EXPECT_TRUE(d.chosen.empty()) << d.verdict;
  const CalibratedParam* c = find(d, "speed_scale");
  ASSERT_NE(c, nullptr);
  EXPECT_TRUE(c->significant);
  EXPECT_NE(d.verdict.find("ppm against the speed frames"), std::string::npos) << d.verdict;
}

TEST(SpeedScale, BeyondTheToleranceOnlyTheToleranceIsApplied) {
  sim::Scenario truth = test::joint_rotation_job(4);
  const GapRecording real = frames_slow_by(truth, 3000.0, 93);
  sim::Scenario nominal = truth;
  nominal.can.speed_scale_tolerance = 0.002;
  DiagnoseOptions opt;
  opt.max_effects = 0;  // the scale is what this test is about
  const Diagnosis d = diagnose(nominal, real, opt);
  EXPECT_DOUBLE_EQ(d.speed_scale_applied_ppm, 2000.0) << d.speed_scale_ppm;
  // An exact speed (no tolerance): the frames are used as they are and no row is reported.
  nominal.can.speed_scale_tolerance = 0.0;
  const Diagnosis d0 = diagnose(nominal, real, opt);
  EXPECT_EQ(d0.speed_scale_applied_ppm, 0.0);
  EXPECT_EQ(find(d0, "speed_scale"), nullptr);
}

TEST(SpeedScale, ASlipOnlyNominalScalesALaggingShaftButLeavesALeadingOneToTheEffects) {
  sim::Scenario truth = test::joint_rotation_job(4);
  sim::Scenario nominal = truth;
  nominal.can.speed_scale_tolerance = 0.01;
  nominal.can.speed_scale_slip_only = true;
  DiagnoseOptions opt;
  opt.max_effects = 0;  // the scale is what this test is about
  // The shaft turns 3000 ppm faster than its frames: not slip.
  const Diagnosis lead = diagnose(nominal, frames_slow_by(truth, 3000.0, 93), opt);
  EXPECT_NEAR(lead.speed_scale_ppm, 3000.0, 3.0 * lead.speed_scale_sd_ppm + 60.0);
  EXPECT_EQ(lead.speed_scale_applied_ppm, 0.0);
  EXPECT_TRUE(lead.speed_scale_slip_only);
  const CalibratedParam* c = find(lead, "speed_scale");
  ASSERT_NE(c, nullptr);
  EXPECT_FALSE(c->significant);
  EXPECT_NE(c->sentence.find("which slip cannot do"), std::string::npos) << c->sentence;
  // 3000 ppm slower than its frames: slip, calibrated as without the flag.
  const Diagnosis lag = diagnose(nominal, frames_slow_by(truth, -3000.0, 93), opt);
  EXPECT_NEAR(lag.speed_scale_applied_ppm, -3000.0, 3.0 * lag.speed_scale_sd_ppm + 60.0);
  const CalibratedParam* c2 = find(lag, "speed_scale");
  ASSERT_NE(c2, nullptr);
  EXPECT_TRUE(c2->significant);
}

}  // namespace
}  // namespace ptda::gap
