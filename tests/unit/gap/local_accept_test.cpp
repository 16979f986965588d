// The local acceptance rule (docs/gap.md step 8): an exactly located line is named even when the model's
// other shortcomings (here a strong mesh order the nominal lacks) keep the global gap large.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "gap_test_job.hpp"
#include "ptda/gap/diagnose.hpp"
#include "ptda/gap/signals.hpp"
#include "ptda/sim/simulator.hpp"

namespace ptda::gap {
namespace {

TEST(LocalAcceptance, ExactLineIsNamedBesideALargeUnexplainedGap) {
  sim::Scenario truth = test::joint_rotation_job(6);
  truth.vibration.gmf_amplitudes[2] = 3.0;  // order 3: absent from the nominal, not calibratable
  truth.vibration.gmf_amplitudes[5] = 2.5;  // order 6 likewise
  sim::EffectSpec mains = sim::EffectSpec::with_defaults(sim::EffectKind::kElectricalInterference);
  mains.set("frequency_hz", 50.0);
  mains.set("amplitude_ms2", 0.08);
  mains.set("harmonics", 1.0);
  truth.effects = {mains};
  const GapRecording real = recording_from_simulation(sim::simulate_signals(truth, 2024), truth);
  const sim::Scenario nominal = test::joint_rotation_job(6);
  DiagnoseOptions opt = test::one_effect_of({sim::EffectKind::kElectricalInterference});
  const Diagnosis d = diagnose(nominal, real, opt);
  ASSERT_EQ(d.chosen.size(), 1U) << d.verdict;
  EXPECT_NEAR(d.chosen[0].effect.get("frequency_hz"), 50.0, 0.5);
  EXPECT_NEAR(d.chosen[0].effect.get("amplitude_ms2"), 0.08, 0.02);
  // Measured with this build: held-out 98.4 -> 94.3 (4 %, below the global 15 % rule), accepted because
  // it removes most of the gap in its own octave (32-64 Hz) against both realisations.
  EXPECT_TRUE(d.chosen[0].accepted_locally);
  EXPECT_LT(d.total_shrink_pct, 15.0);
  EXPECT_NE(d.verdict.find("is not explained"), std::string::npos) << d.verdict;
  // Without the local rule the line is not named (the session-3 behaviour on real data, issue 11).
  opt.min_local_share = 2.0;
  const Diagnosis off = diagnose(nominal, real, opt);
  EXPECT_TRUE(off.chosen.empty()) << off.verdict;
  EXPECT_EQ(off.verdict.rfind("unexplained:", 0), 0U) << off.verdict;
}

// Two interference sources (mains with odd harmonics and a drive's switching line) are named as one
// source in the library's drive form: the mains with its odd harmonics (`odd_only`) and the carrier
// (`pwm_hz`). Before that form existed they were named one line at a time (two effects), and with one
// line guess per candidate the line with the largest excess could be named first although it was not
// the one holding the gap (gen2 development case 1024, docs/gap.md "Session 12").
TEST(LocalAcceptance, MainsAndADriveLineAreNamedAsOnePickupWithItsCarrier) {
  sim::Scenario truth = test::joint_rotation_job(6);
  sim::EffectSpec mains = sim::EffectSpec::with_defaults(sim::EffectKind::kElectricalInterference);
  mains.set("frequency_hz", 50.0);
  mains.set("amplitude_ms2", 0.1);
  mains.set("harmonics", 4.0);  // 50, 150, 250, 350 Hz
  mains.set("harmonic_decay", 0.8);
  mains.set("odd_only", 1.0);
  sim::EffectSpec pwm = sim::EffectSpec::with_defaults(sim::EffectKind::kElectricalInterference);
  pwm.set("frequency_hz", 2500.0);
  pwm.set("amplitude_ms2", 0.2);
  pwm.set("harmonics", 1.0);
  truth.effects = {mains, pwm};
  const GapRecording real = recording_from_simulation(sim::simulate_signals(truth, 2025), truth);
  const sim::Scenario nominal = test::joint_rotation_job(6);
  DiagnoseOptions opt;
  opt.candidates = {sim::EffectKind::kElectricalInterference, sim::EffectKind::kTransferPath};
  opt.max_effects = 2;
  const Diagnosis d = diagnose(nominal, real, opt);
  ASSERT_GE(d.chosen.size(), 1U) << d.verdict;
  const sim::EffectSpec& e = d.chosen[0].effect;
  ASSERT_EQ(e.kind, sim::EffectKind::kElectricalInterference) << d.verdict;
  EXPECT_NEAR(e.get("frequency_hz"), 50.0, 0.5) << d.verdict;
  EXPECT_EQ(std::lround(e.get("odd_only")), 1) << d.verdict;
  EXPECT_GE(std::lround(e.get("harmonics")), 3) << d.verdict;
  EXPECT_NEAR(e.get("pwm_hz"), 2500.0, 5.0) << d.verdict;
  EXPECT_GT(e.get("pwm_ms2"), 0.1) << d.verdict;
  EXPECT_LT(e.get("pwm_ms2"), 0.4) << d.verdict;
  EXPECT_NE(d.chosen[0].location.find("drive carrier at 2500 Hz"), std::string::npos) << d.chosen[0].location;
  EXPECT_GT(d.total_shrink_pct, 70.0) << d.verdict;
}

// The drive form with sidebands, simulated as one source: named with its carrier and spacing, although
// the excess lines the guesses start from are the mains and a sideband.
TEST(LocalAcceptance, ADriveCarrierWithSidebandsIsNamedWithTheMains) {
  sim::Scenario truth = test::joint_rotation_job(6);
  sim::EffectSpec e0 = sim::EffectSpec::with_defaults(sim::EffectKind::kElectricalInterference);
  e0.set("frequency_hz", 60.0);
  e0.set("amplitude_ms2", 0.12);
  e0.set("harmonics", 3.0);  // 60, 180, 300 Hz
  e0.set("harmonic_decay", 0.6);
  e0.set("odd_only", 1.0);
  e0.set("pwm_hz", 3000.0);
  e0.set("pwm_ms2", 0.15);
  e0.set("pwm_side_hz", 150.0);
  e0.set("pwm_side_rel", 0.5);
  truth.effects = {e0};
  const GapRecording real = recording_from_simulation(sim::simulate_signals(truth, 2026), truth);
  const sim::Scenario nominal = test::joint_rotation_job(6);
  DiagnoseOptions opt =
      test::one_effect_of({sim::EffectKind::kElectricalInterference, sim::EffectKind::kTransferPath});
  const Diagnosis d = diagnose(nominal, real, opt);
  ASSERT_EQ(d.chosen.size(), 1U) << d.verdict;
  const sim::EffectSpec& e = d.chosen[0].effect;
  ASSERT_EQ(e.kind, sim::EffectKind::kElectricalInterference) << d.verdict;
  EXPECT_NEAR(e.get("frequency_hz"), 60.0, 0.6) << d.verdict;
  EXPECT_NEAR(e.get("pwm_hz"), 3000.0, 5.0) << d.verdict;
  EXPECT_NEAR(e.get("pwm_side_hz"), 150.0, 3.0) << d.verdict;
  EXPECT_GT(d.total_shrink_pct, 70.0) << d.verdict;
}

// Mains and a drive line named one at a time (a round each) are reported as one drive-form pickup at
// the place of the first; a pair that is not mains + kHz line is left alone.
TEST(DrivePickup, MainsAndAKhzLineNamedApartAreMergedIntoTheDriveForm) {
  auto interference = [](double f, double a, double harmonics) {
    CandidateResult c;
    c.effect = sim::EffectSpec::with_defaults(sim::EffectKind::kElectricalInterference);
    c.effect.set("frequency_hz", f);
    c.effect.set("amplitude_ms2", a);
    c.effect.set("harmonics", harmonics);
    c.location = "lines at " + std::to_string(f);
    c.shrink_pct = f;  // marks which entry survives
    return c;
  };
  CandidateResult path;
  path.effect = sim::EffectSpec::with_defaults(sim::EffectKind::kTransferPath);
  const sim::Scenario nominal = test::joint_rotation_job(2);
  std::vector<CandidateResult> chosen{interference(4000.0, 0.125, 1.0), path, interference(60.0, 0.06, 5.0)};
  chosen[0].alternatives = {"a"};
  merge_drive_pickup(chosen, nominal);
  ASSERT_EQ(chosen.size(), 2U);
  const sim::EffectSpec& e = chosen[0].effect;
  EXPECT_EQ(e.kind, sim::EffectKind::kElectricalInterference);
  EXPECT_EQ(e.get("frequency_hz"), 60.0);
  EXPECT_EQ(e.get("harmonics"), 5.0);
  EXPECT_EQ(e.get("pwm_hz"), 4000.0);
  EXPECT_EQ(e.get("pwm_ms2"), 0.125);
  EXPECT_EQ(e.get("pwm_side_hz"), 0.0);
  EXPECT_EQ(chosen[0].shrink_pct, 4000.0);  // the first round's numbers, at its place
  EXPECT_EQ(chosen[0].alternatives, std::vector<std::string>{"a"});
  EXPECT_EQ(chosen[0].location, "lines at 60.00 Hz and harmonics, drive carrier at 4000 Hz");
  EXPECT_EQ(chosen[1].effect.kind, sim::EffectKind::kTransferPath);
  // Not merged: the kHz entry has harmonics; the line is below 8 x the mains; both are low.
  for (const auto& pair : {std::pair{interference(4000.0, 0.1, 3.0), interference(60.0, 0.06, 5.0)},
                           std::pair{interference(400.0, 0.1, 1.0), interference(60.0, 0.06, 5.0)},
                           std::pair{interference(900.0, 0.1, 1.0), interference(50.0, 0.06, 5.0)}}) {
    std::vector<CandidateResult> two{pair.first, pair.second};
    merge_drive_pickup(two, nominal);
    EXPECT_EQ(two.size(), 2U) << two[0].location;
  }
}

// A drive line that sits on a high mesh order of the job's class (order 17, beyond twice the nominal's
// highest order 8) is still a line guess, so the mains + carrier candidate exists. Before session 17 every
// line within 3.6 input-shaft orders of any whole GMF multiple was left out (gen2-1024: a 4 kHz carrier
// 2 Hz from order 26), and with one effect allowed the mains alone was named.
TEST(LocalAcceptance, ADriveLineOnAHighMeshOrderIsStillACarrier) {
  sim::Scenario truth = test::joint_rotation_job(6);
  const double gmf = std::fabs(sim::gmf_hz(truth.gearbox, truth.motion.segment_speeds_rad_s[0]));
  const double f_drive = 17.0 * gmf + 1.0;
  ASSERT_LT(f_drive, 0.45 * truth.sensor.fs_hz) << gmf;
  sim::EffectSpec e0 = sim::EffectSpec::with_defaults(sim::EffectKind::kElectricalInterference);
  e0.set("frequency_hz", 50.0);
  e0.set("amplitude_ms2", 0.12);
  e0.set("harmonics", 2.0);  // 50, 150 Hz
  e0.set("odd_only", 1.0);
  e0.set("pwm_hz", f_drive);
  e0.set("pwm_ms2", 0.2);
  truth.effects = {e0};
  const GapRecording real = recording_from_simulation(sim::simulate_signals(truth, 2027), truth);
  DiagnoseOptions opt = test::one_effect_of({sim::EffectKind::kElectricalInterference});
  const Diagnosis d = diagnose(test::joint_rotation_job(6), real, opt);
  ASSERT_EQ(d.chosen.size(), 1U) << d.verdict;
  EXPECT_NEAR(d.chosen[0].effect.get("frequency_hz"), 50.0, 0.5) << d.verdict;
  EXPECT_NEAR(d.chosen[0].effect.get("pwm_hz"), f_drive, 0.002 * f_drive) << d.verdict;
}

TEST(LocalAcceptance, KnocksRingingTwoModesAtStartsAndStopsAreNamedAtTheLowerMode) {
  // Issue 11: gen2's knocks (and GFD-injected ones) ring two modes and sit at every start and stop; a
  // one-mode ring at torque reversals was fitted at several times the lower mode, to match the
  // differenced signal's peaks. Here the model's own form of that knock is the truth.
  sim::Scenario truth = test::joint_rotation_job(6);
  const double fn_hz = 2500.0;
  ASSERT_LT(2.0 * fn_hz, 0.45 * truth.sensor.fs_hz);
  sim::EffectSpec e = sim::EffectSpec::with_defaults(sim::EffectKind::kImpacts);
  e.set("amplitude_ms2", 8.0);
  e.set("resonance_hz", fn_hz);
  e.set("damping_ratio", 0.06);
  e.set("mode2_ratio", 2.0);
  e.set("mode2_share", 0.4);
  e.set("knock_events", 1.0);
  truth.effects = {e};
  const GapRecording real = recording_from_simulation(sim::simulate_signals(truth, 2031), truth);
  DiagnoseOptions opt = test::one_effect_of({sim::EffectKind::kImpacts, sim::EffectKind::kTransferPath});
  const Diagnosis d = diagnose(test::joint_rotation_job(6), real, opt);
  ASSERT_EQ(d.chosen.size(), 1U) << d.verdict;
  EXPECT_EQ(d.chosen[0].effect.kind, sim::EffectKind::kImpacts) << d.verdict;
  EXPECT_NEAR(d.chosen[0].effect.get("resonance_hz") / fn_hz, 1.0, 0.2) << d.verdict;
  // The starts and stops are among the knock places. The fit also adds the braking reversals here
  // (knock_events 2, held-out shrink 95 % on 2026-11-29), as on gen2's development knock cases.
  EXPECT_GE(std::lround(d.chosen[0].effect.get("knock_events")), 1) << d.verdict;
}

}  // namespace
}  // namespace ptda::gap
