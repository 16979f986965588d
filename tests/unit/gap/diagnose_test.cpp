// Gap diagnosis on small simulated recordings: effects the nominal scenario already lists stay in the
// model, and an effect that moves energy out of the harmonics (speed ripple) is fitted from the nominal
// amplitudes rather than from ones calibrated without it.
#include "ptda/gap/diagnose.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <string>

#include "gap_test_job.hpp"
#include "ptda/gap/signals.hpp"
#include "ptda/sim/simulator.hpp"

namespace ptda::gap {
namespace {

sim::Scenario job() {
  return test::joint_rotation_job(6);
}

sim::EffectSpec ripple() {
  sim::EffectSpec e = sim::EffectSpec::with_defaults(sim::EffectKind::kSpeedRipple);
  e.set("jitter_rad", 0.5);
  e.set("bandwidth_hz", 30.0);
  return e;
}

GapRecording measured_with_ripple() {
  sim::Scenario s = job();
  s.effects = {ripple()};
  return recording_from_simulation(sim::simulate_signals(s, 41), s);
}

TEST(Diagnose, EffectsOfTheNominalScenarioStayInTheModel) {
  const GapRecording real = measured_with_ripple();
  DiagnoseOptions opt = test::one_effect_of({sim::EffectKind::kAdcClipping, sim::EffectKind::kNoiseColor});
  const Diagnosis without = diagnose(job(), real, opt);
  sim::Scenario known = job();
  known.effects = {ripple()};
  const Diagnosis with = diagnose(known, real, opt);
  // Without the ripple the calibrated nominal is far off (smeared harmonics, PTDA residual); with it the
  // held-out gap is near the sampling level and no candidate is accepted. Measured: 253.8 vs 2.96
  // (second model realisation 5.35; expected from sampling 2.35 +- 0.59: the chi-square sd ignores the
  // correlation between elements, so the significance gate alone is not trusted, see docs/gap.md).
  EXPECT_TRUE(without.gap_significant);
  EXPECT_GT(without.nominal_heldout.total, 20.0 * with.nominal_heldout.total);
  EXPECT_LT(with.nominal_heldout.total, with.noise_gap + 2.0 * with.noise_gap_sd);
  EXPECT_TRUE(with.chosen.empty()) << with.verdict;
  for (const SelectionRound& r : with.rounds) {
    for (const CandidateResult& c : r.ranked) EXPECT_NE(c.effect.kind, sim::EffectKind::kSpeedRipple);
  }
}

TEST(Diagnose, SpeedRippleIsFittedFromTheNominalAmplitudes) {
  const GapRecording real = measured_with_ripple();
  DiagnoseOptions opt = test::one_effect_of({sim::EffectKind::kSpeedRipple});
  // The scenario's motion (the recording's CAN log is the job's own profile here). With the model driven
  // by the measured CAN speed (the default) the fit picks a slow wander instead: 1.44 rad over 4 Hz,
  // held-out 247.7 -> 6.32, replicate 250.6 -> 19.1 (measured with this build; not located; docs/gap.md
  // "Not done yet"), checked by MeasuredMotionStillNamesTheRipple below.
  opt.motion = MotionSource::kScenario;
  const Diagnosis d = diagnose(job(), real, opt);
  ASSERT_EQ(d.chosen.size(), 1U) << d.verdict;
  EXPECT_EQ(d.chosen[0].effect.kind, sim::EffectKind::kSpeedRipple);
  // Located within a factor of 2 of the 0.5 rad simulated (the bench's criterion), and most of the gap
  // explained. Measured: 0.44 rad, shrink 98.5 %, second realisation 5.31 from 253.9. Calibrating the
  // candidate from the amplitudes fitted without the ripple (the earlier code) reached only 12 % shrink
  // on development bench case 9100/1 (arc welding, 0.58 rad at 31 Hz; docs/gap.md).
  EXPECT_GT(d.chosen[0].effect.get("jitter_rad"), 0.25);
  EXPECT_LT(d.chosen[0].effect.get("jitter_rad"), 1.0);
  EXPECT_GT(d.total_shrink_pct, 70.0);
  EXPECT_TRUE(std::isfinite(d.chosen[0].gap_heldout_replicate));
  EXPECT_LT(d.chosen[0].gap_heldout_replicate, 0.3 * d.rounds[0].gap_before_heldout_replicate);
}

TEST(Diagnose, MeasuredMotionStillNamesTheRipple) {
  const GapRecording real = measured_with_ripple();
  DiagnoseOptions opt = test::one_effect_of({sim::EffectKind::kSpeedRipple});
  const Diagnosis d = diagnose(job(), real, opt);
  EXPECT_EQ(d.motion_source, "measured");
  ASSERT_EQ(d.chosen.size(), 1U) << d.verdict;
  EXPECT_GT(d.total_shrink_pct, 90.0);  // measured: 97.4 %
  EXPECT_LT(d.chosen[0].gap_heldout_replicate, 0.3 * d.rounds[0].gap_before_heldout_replicate);
}

// The fits score each stage's grid on several threads (session 34; before, one candidate per thread).
// The grid is scored in its own order whatever the threads, so every number is the same with 1 or 3.
TEST(Diagnose, TheResultDoesNotDependOnTheNumberOfThreads) {
  const GapRecording real = measured_with_ripple();
  DiagnoseOptions opt = test::one_effect_of({sim::EffectKind::kSpeedRipple, sim::EffectKind::kImpacts});
  opt.threads = 1;
  const Diagnosis one = diagnose(job(), real, opt);
  opt.threads = 3;
  const Diagnosis three = diagnose(job(), real, opt);
  EXPECT_EQ(one.verdict, three.verdict);
  ASSERT_EQ(one.rounds.size(), three.rounds.size());
  std::size_t compared = 0;
  for (std::size_t r = 0; r < one.rounds.size(); ++r) {
    ASSERT_EQ(one.rounds[r].ranked.size(), three.rounds[r].ranked.size());
    for (std::size_t i = 0; i < one.rounds[r].ranked.size(); ++i) {
      const CandidateResult& a = one.rounds[r].ranked[i];
      const CandidateResult& b = three.rounds[r].ranked[i];
      EXPECT_EQ(a.effect.kind, b.effect.kind);
      EXPECT_EQ(a.effect.params, b.effect.params);
      EXPECT_EQ(a.evaluations, b.evaluations);
      EXPECT_EQ(a.gap_fit, b.gap_fit);
      if (a.fully_fitted) {
        EXPECT_EQ(a.gap_heldout, b.gap_heldout);
      }
      ++compared;
    }
  }
  EXPECT_GE(compared, 2U);  // both kinds screened
}

TEST(Diagnose, RunnersUpWithinTheTieMarginAreAlternatives) {
  // ranked[0] is the chosen candidate: held-out gaps 10 / 12 (mean 11) from 100 / 104 (mean 102), gain 91;
  // tie margin max(2 x 1.5, 10 % of 91) = 9.1: a runner-up at mean 20 ties, one at mean 20.2 does not,
  // one that was only screened never does.
  auto cand = [](double held, double rep, bool full) {
    CandidateResult c;
    c.gap_heldout = held;
    c.gap_heldout_replicate = rep;
    c.fully_fitted = full;
    return c;
  };
  const std::vector<CandidateResult> ranked{cand(10, 12, true), cand(19, 21, true), cand(20, 20.4, true),
                                            cand(15, 15, false)};
  EXPECT_EQ(tied_candidates(ranked, 100.0, 104.0, 1.5, 2.0), (std::vector<std::size_t>{1}));
  // With a large sampling sd the margin is 2 sd = 10: both fully fitted runners-up tie.
  EXPECT_EQ(tied_candidates(ranked, 100.0, 104.0, 5.0, 2.0), (std::vector<std::size_t>{1, 2}));
  EXPECT_TRUE(tied_candidates({cand(10, 12, true)}, 100.0, 104.0, 1.5, 2.0).empty());
}

}  // namespace
}  // namespace ptda::gap

namespace ptda::gap {
namespace {

/// A constant-speed test rig: one 30-tooth mesh on a 30 Hz shaft (GMF 900 Hz), 2.4 s, white floor.
sim::Scenario constant_speed_rig() {
  sim::Scenario s;
  s.source = "test";
  s.name = "rig";
  s.motion.kind = sim::MotionKind::kConstant;
  s.motion.shaft_speed_hz = 30.0;
  s.motion.duration_s = 2.4;
  s.motion.cycles = 1;
  s.gearbox.kind = sim::GearboxKind::kParallel;
  s.gearbox.z_in = 30;
  s.gearbox.z_spur = 75;
  s.gearbox.z_pin = 0;
  s.vibration.gmf_amplitudes = {0.9, 0.1, 0.1};
  s.vibration.reference_speed_rad_s = 75.398;
  s.vibration.noise_rms = 0.5;
  s.sensor.range_ms2 = 200.0;
  return s;
}

TEST(Diagnose, FittedPlacesStayBelowTheProbesTopSoThatANamedEffectLoadsBack) {
  // The knock grid's top value at 25600 Hz is 600 * 1.6^6 = 10066 Hz; one relative refinement (x 1.19)
  // took such a knock to 11979 Hz, and a path guessed at 0.44 fs to 13404 Hz: 0.47 and 0.52 fs. A
  // scenario rejects a path at 0.49 fs or a knock at fs/2 and above.
  constexpr double kFs = 25600.0;
  sim::EffectSpec knock = sim::EffectSpec::with_defaults(sim::EffectKind::kImpacts);
  knock.set("resonance_hz", 10066.3 * 1.19 * 1.1);
  knock.set("damping_ratio", 0.001);  // below the library's 0.005
  clamp_effect_params(knock, kFs);
  EXPECT_DOUBLE_EQ(knock.get("resonance_hz"), 11520.0);  // 0.45 fs
  EXPECT_DOUBLE_EQ(knock.get("damping_ratio"), 0.005);
  sim::EffectSpec path = sim::EffectSpec::with_defaults(sim::EffectKind::kTransferPath);
  path.set("frequency_hz", 0.44 * kFs * 1.19);
  clamp_effect_params(path, kFs);
  EXPECT_DOUBLE_EQ(path.get("frequency_hz"), 11520.0);
  // Below the top nothing moves; other kinds' frequencies are not places of a resonance.
  path.set("frequency_hz", 3000.0);
  clamp_effect_params(path, kFs);
  EXPECT_DOUBLE_EQ(path.get("frequency_hz"), 3000.0);
  sim::EffectSpec noise = sim::EffectSpec::with_defaults(sim::EffectKind::kNoiseColor);
  noise.set("corner_hz", 12000.0);
  clamp_effect_params(noise, kFs);
  EXPECT_DOUBLE_EQ(noise.get("corner_hz"), 12000.0);
}

TEST(Diagnose, KnocksOnAConstantSpeedRigAreFittedAtAPoissonRate) {
  // A constant-speed rig (no torque reversal) with random knocks, 6 per second ringing at 3 kHz: the
  // impacts candidate can only reproduce them with rate_hz > 0, which its fit now tries.
  const sim::Scenario s = constant_speed_rig();
  sim::Scenario truth = s;
  sim::EffectSpec knocks = sim::EffectSpec::with_defaults(sim::EffectKind::kImpacts);
  knocks.set("rate_hz", 6.0);
  knocks.set("resonance_hz", 3000.0);
  knocks.set("amplitude_ms2", 20.0);
  truth.effects = {knocks};
  const GapRecording real = recording_from_simulation(sim::simulate_signals(truth, 5), truth);
  DiagnoseOptions opt = test::one_effect_of({sim::EffectKind::kImpacts, sim::EffectKind::kTransferPath});
  const Diagnosis d = diagnose(s, real, opt);
  ASSERT_EQ(d.chosen.size(), 1U) << d.verdict;
  EXPECT_EQ(d.chosen[0].effect.kind, sim::EffectKind::kImpacts) << d.verdict;
  EXPECT_GT(d.chosen[0].effect.get("rate_hz"), 0.0);
  EXPECT_NEAR(d.chosen[0].effect.get("resonance_hz") / 3000.0, 1.0, 0.2) << d.verdict;
}

}  // namespace
}  // namespace ptda::gap

namespace ptda::gap {
namespace {

TEST(Diagnose, OtherAxisIsNotACandidateAtOneConstantSpeed) {
  // A constant-speed rig with a steady line the nominal lacks (shaft order 47): at one speed, with no
  // standstill and no speed change, another axis's mesh looks exactly like it, so `other_axis` is left
  // out (and said so); the line may be named as a fixed-frequency line or stay unexplained.
  const sim::Scenario s = constant_speed_rig();
  sim::Scenario truth = s;
  truth.vibration.shaft_orders = {47};
  truth.vibration.shaft_order_amplitudes = {1.0};
  const GapRecording real = recording_from_simulation(sim::simulate_signals(truth, 8), truth);
  DiagnoseOptions opt =
      test::one_effect_of({sim::EffectKind::kOtherAxis, sim::EffectKind::kElectricalInterference});
  const Diagnosis d = diagnose(s, real, opt);
  ASSERT_EQ(d.not_identifiable.size(), 1U);
  EXPECT_EQ(d.not_identifiable[0].rfind("other_axis:", 0), 0U) << d.not_identifiable[0];
  for (const CandidateResult& c : d.chosen)
    EXPECT_NE(c.effect.kind, sim::EffectKind::kOtherAxis) << d.verdict;
  for (const SelectionRound& r : d.rounds)
    for (const CandidateResult& c : r.ranked) EXPECT_NE(c.effect.kind, sim::EffectKind::kOtherAxis);
  // A robot job (two speed classes, rests) keeps it.
  const sim::Scenario job = test::joint_rotation_job(4);
  const GapRecording moving = recording_from_simulation(sim::simulate_signals(job, 9), job);
  opt.max_effects = 0;
  EXPECT_TRUE(diagnose(job, moving, opt).not_identifiable.empty());
}

TEST(Diagnose, DoublePoleNoiseIsFittedWithItsSlopeAndCorner) {
  // Extra red noise with a double pole at 60 Hz (the second generator's form, gen2 development 1047 and
  // 1064). The poles searched alone after the corner kept one pole at a corner far below the truth
  // (gen2 1064: 9.8 Hz for 57 Hz); the corner and the slope are now searched jointly.
  const sim::EffectSpec e = test::noise_color(0.6, 60.0, 2.0);
  sim::Scenario s = job();
  s.effects = {e};
  const GapRecording real = recording_from_simulation(sim::simulate_signals(s, 43), s);
  DiagnoseOptions opt = test::one_effect_of({sim::EffectKind::kNoiseColor});
  const Diagnosis d = diagnose(job(), real, opt);
  ASSERT_EQ(d.chosen.size(), 1U) << d.verdict;
  const sim::EffectSpec& f = d.chosen[0].effect;
  // Located by the bench's rule (corner within a factor of 2) and with the truth's slope. Measured with
  // this build: 2 poles at 60 Hz, rms 0.64, shrink 95.7 %; the earlier stages gave 1 pole at 14 Hz.
  EXPECT_EQ(std::lround(f.get("poles")), 2) << f.get("corner_hz");
  EXPECT_GT(f.get("corner_hz"), 30.0);
  EXPECT_LT(f.get("corner_hz"), 120.0);
  EXPECT_GT(d.total_shrink_pct, 70.0);
}

TEST(Diagnose, NoiseLevelIsSearchedUpToMultiplesOfALoudFloor) {
  // A loud machine (floor 4 m/s^2 rms, like the GFD rig's 5.9) with extra red noise of 4 m/s^2 (double
  // pole at 60 Hz): the absolute level grid (up to 1.6 m/s^2, then x1.25 refinements, at most 2.5)
  // could not reach it (development case gfd-1005: 5.7 m/s^2 injected); the grid now goes on to 0.5, 1
  // and 2 x the calibrated floor.
  sim::Scenario loud = job();
  loud.vibration.noise_rms = 4.0;
  const sim::EffectSpec e = test::noise_color(4.0, 60.0, 2.0);
  sim::Scenario s = loud;
  s.effects = {e};
  const GapRecording real = recording_from_simulation(sim::simulate_signals(s, 44), s);
  DiagnoseOptions opt = test::one_effect_of({sim::EffectKind::kNoiseColor});
  const Diagnosis d = diagnose(loud, real, opt);
  ASSERT_EQ(d.chosen.size(), 1U) << d.verdict;
  const sim::EffectSpec& f = d.chosen[0].effect;
  // Measured with this build: rms 3.79 at 60 Hz, 2 poles, shrink 88.3 %; with the grid not extended the
  // level stops at 2.50 (shrink 82.1 %) and the first expectation fails.
  EXPECT_GT(f.get("rms_ms2"), 3.0) << f.get("corner_hz");
  EXPECT_LT(f.get("rms_ms2"), 6.0) << f.get("corner_hz");
  EXPECT_GT(f.get("corner_hz"), 30.0);
  EXPECT_LT(f.get("corner_hz"), 120.0);
}

TEST(Diagnose, RedNoiseThatTiltedTheCalibratedFloorIsStillFound) {
  // The machine's floor rises by 14 dB per decade (the GFD rig's), the nominal's is white, and strong
  // red noise (double pole at 250 Hz, 4 m/s^2 rms on a 0.5 m/s^2 floor) was added: the calibrated floor
  // slope turns negative and holds most of it (here -10.8 dB/decade; GFD development gfd-1101: -11.9 for
  // the rig's +14). A noise candidate starting from that slope, with its level searched at the corner
  // picked at the default level, was not accepted ("unexplained"). It now starts from the nominal's
  // slope, which its calibration pass re-fits with the noise in the model, and the screen searches
  // corner and level jointly.
  sim::Scenario machine = job();
  machine.vibration.noise_rms = 0.5;
  machine.vibration.noise_tilt_db_per_decade = 14.0;
  const sim::EffectSpec e = test::noise_color(4.0, 250.0, 2.0);
  machine.effects = {e};
  const GapRecording real = recording_from_simulation(sim::simulate_signals(machine, 45), machine);
  sim::Scenario nominal = job();
  nominal.vibration.noise_rms = 0.5;
  DiagnoseOptions opt = test::one_effect_of({sim::EffectKind::kNoiseColor});
  const Diagnosis d = diagnose(nominal, real, opt);
  ASSERT_EQ(d.chosen.size(), 1U) << d.verdict;
  const sim::EffectSpec& f = d.chosen[0].effect;
  // Measured with this build: 3.43 m/s^2 below 300 Hz, 2 poles, shrink 85.1 %. The bench's location rule
  // (corner within a factor of 2) and the level within a factor of 2.
  EXPECT_GT(f.get("corner_hz"), 125.0) << f.get("rms_ms2");
  EXPECT_LT(f.get("corner_hz"), 500.0) << f.get("rms_ms2");
  EXPECT_GT(f.get("rms_ms2"), 2.0) << f.get("corner_hz");
  EXPECT_LT(f.get("rms_ms2"), 8.0) << f.get("corner_hz");
  EXPECT_GT(d.total_shrink_pct, 60.0);
}

TEST(Diagnose, WeakRedNoiseIsNamedWhateverTheModelSeed) {
  // Red noise a little above a white floor (0.52 m/s^2 below 260 Hz, one pole, on 0.3 m/s^2), as in the
  // project simulator's development case 9100/10, where the verdict changed with the model seed. Two
  // defects showed: a noise candidate scored after one calibration pass from the floor that had held the
  // noise (fits went to 35-50 Hz), and a latency fitted to 0 s with no jitter, which changes nothing in
  // the model, was named with 29 % shrink (seed 424242). Noise candidates are now scored after two
  // passes and an effect fitted to "no effect" is never named. Measured with this build: 0.3 m/s^2 below
  // 100 Hz (one pole) for both seeds, shrink 96.7 % and 94.9 % (seed 9001: 0.2 below 166.6 Hz, 93.8 %).
  // The corner is low by 1.6-2.6 x on this short job; not asserted.
  const sim::Scenario nominal = job();
  sim::Scenario machine = job();
  machine.effects = {test::noise_color(0.52, 260.0, 1.0)};
  const GapRecording real = recording_from_simulation(sim::simulate_signals(machine, 46), machine);
  for (std::uint64_t seed : {424242ULL, 433342ULL}) {
    DiagnoseOptions opt = test::one_effect_of({sim::EffectKind::kNoiseColor, sim::EffectKind::kSpeedLatency});
    opt.sim_seed = seed;
    const Diagnosis d = diagnose(nominal, real, opt);
    ASSERT_EQ(d.chosen.size(), 1U) << seed << ": " << d.verdict;
    const sim::EffectSpec& f = d.chosen[0].effect;
    EXPECT_EQ(f.kind, sim::EffectKind::kNoiseColor) << seed << ": " << sim::describe(f);
    EXPECT_GT(d.total_shrink_pct, 80.0) << seed;
  }
}

TEST(Diagnose, AGainIsJudgedAgainstTheNullCandidateWhenItsGapIsSmaller) {
  // The weak red noise above: the round's model was calibrated three passes from the nominal, the
  // candidates two passes from the nominal's levels. The null candidate (no effect, the candidates' own
  // path) is the reference when its held-out gap is the smaller one, so re-calibration alone is never
  // counted as an effect's gain (session 33: 29 % of the gap for an effect that changes nothing).
  const sim::Scenario nominal = job();
  sim::Scenario machine = job();
  machine.effects = {test::noise_color(0.52, 260.0, 1.0)};
  const GapRecording real = recording_from_simulation(sim::simulate_signals(machine, 46), machine);
  DiagnoseOptions opt = test::one_effect_of({sim::EffectKind::kNoiseColor});
  opt.sim_seed = 424242;
  const Diagnosis d = diagnose(nominal, real, opt);
  ASSERT_EQ(d.rounds.size(), 1U) << d.verdict;
  const SelectionRound& r = d.rounds[0];
  ASSERT_EQ(d.chosen.size(), 1U) << d.verdict;
  const double before = r.gap_before_heldout + r.gap_before_heldout_replicate;
  const double null = r.null_heldout + r.null_heldout_replicate;
  ASSERT_TRUE(std::isfinite(null) && null > 0.0);
  EXPECT_EQ(r.null_reference, null < before);
  // Measured with this build: the round's model 82.28 and 67.24 (both realisations), the null candidate
  // 58.39 and 46.57 (the reference), the noise fit 2.75 and 2.80: shares 0.958 of the round's gap and
  // 0.953 of the null's.
  ASSERT_TRUE(r.null_reference) << "before " << before << ", null " << null;
  // With the acceptance share between the gain's share of the round's gap and of the null's, the same
  // fit is accepted only if the gain is judged against the round's model: it must not be.
  const CandidateResult& best = r.ranked.front();
  const double share_before = std::min(
      (r.gap_before_heldout - best.gap_heldout) / r.gap_before_heldout,
      (r.gap_before_heldout_replicate - best.gap_heldout_replicate) / r.gap_before_heldout_replicate);
  const double share_null =
      std::max((r.null_heldout - best.gap_heldout) / r.null_heldout,
               (r.null_heldout_replicate - best.gap_heldout_replicate) / r.null_heldout_replicate);
  ASSERT_LT(share_null, share_before);
  DiagnoseOptions strict = opt;
  strict.min_gain_share = 0.5 * (share_null + share_before);
  strict.min_local_share = 2.0;  // the local rule off: this is about the global one
  const Diagnosis s = diagnose(nominal, real, strict);
  ASSERT_EQ(s.rounds.size(), 1U);
  EXPECT_EQ(s.rounds[0].ranked.front().effect.params, best.effect.params);  // the same fit
  EXPECT_TRUE(s.chosen.empty()) << s.verdict;
}

TEST(Diagnose, ClippingStartsFromTheCalibratedLevel) {
  // The machine's floor rises by 14 dB per decade (the GFD rig's calibrated slope); the user's nominal
  // has a white floor at the recording's measured rms, as one would write it down. The floor's
  // level (density at the pivot) and slope are calibration. The acquisition clips at 70 % of the peak.
  // Candidates used to start from the nominal's noise level with the calibrated slope: a model several
  // times too loud, which a clamp at the measured peak distorted throughout before the one calibration
  // pass of a fit could lower it (GFD development case gfd-1115: fit gap 124 with the clamp against 77
  // without it, so clipping was never a candidate). Clipping now starts from the calibrated level.
  sim::Scenario truth = job();
  truth.vibration.noise_tilt_db_per_decade = 14.0;
  const GapRecording clean = recording_from_simulation(sim::simulate_signals(truth, 4322), truth);
  double peak = 0.0;
  for (float v : clean.accel_ms2) peak = std::max(peak, static_cast<double>(std::fabs(v)));
  sim::EffectSpec clip = sim::EffectSpec::with_defaults(sim::EffectKind::kAdcClipping);
  clip.set("level_ms2", 0.7 * peak);
  sim::Scenario s = truth;
  s.effects = {clip};
  const GapRecording real = recording_from_simulation(sim::simulate_signals(s, 4322), s);
  double sq = 0.0;
  for (float v : clean.accel_ms2) sq += static_cast<double>(v) * v;
  sim::Scenario nominal = job();
  nominal.vibration.noise_rms = std::sqrt(sq / static_cast<double>(clean.accel_ms2.size()));
  DiagnoseOptions opt = test::one_effect_of({sim::EffectKind::kAdcClipping});
  const Diagnosis d = diagnose(nominal, real, opt);
  ASSERT_EQ(d.chosen.size(), 1U) << d.verdict;
  // Located by the bench's rule (level within 5 %). Measured with this build: 8.37 m/s^2 for 8.33, the
  // nominal's held-out gap 17.4 shrunk by 91.0 %; before, nothing was named (the clamp was no candidate).
  EXPECT_NEAR(d.chosen[0].effect.get("level_ms2"), 0.7 * peak, 0.05 * 0.7 * peak) << d.verdict;
  EXPECT_GT(d.total_shrink_pct, 50.0) << d.verdict;
}

sim::EffectSpec knocks(double amplitude_ms2) {
  sim::EffectSpec e = sim::EffectSpec::with_defaults(sim::EffectKind::kImpacts);
  e.set("amplitude_ms2", amplitude_ms2);
  e.set("resonance_hz", 3000.0);
  e.set("rate_hz", 0.0);
  return e;
}

TEST(Diagnose, ClippingClampsAModelWithALighterTailWhereItHasTheMeasuredShareAtTheRails) {
  // The machine knocks twice as hard as its nominal says (a heavier amplitude tail than the model's, as
  // the GFD rig's impulses against a Gaussian floor), and its acquisition clips the loudest knocks at
  // 60 % of the peak. A clamp at the measured rails never touches the model's weaker knocks, so it
  // could not show the flat tops. The model clamps where it puts the same share of its samples at its
  // rails; the reported level stays the measured one.
  sim::Scenario truth = job();
  truth.effects = {knocks(12.0)};
  const GapRecording clean = recording_from_simulation(sim::simulate_signals(truth, 4323), truth);
  double peak = 0.0;
  for (float v : clean.accel_ms2) peak = std::max(peak, static_cast<double>(std::fabs(v)));
  sim::EffectSpec clip = sim::EffectSpec::with_defaults(sim::EffectKind::kAdcClipping);
  clip.set("level_ms2", 0.6 * peak);
  sim::Scenario s = truth;
  s.effects.push_back(clip);
  const GapRecording real = recording_from_simulation(sim::simulate_signals(s, 4323), s);
  sim::Scenario nominal = job();
  nominal.effects = {knocks(6.0)};
  DiagnoseOptions opt = test::one_effect_of({sim::EffectKind::kAdcClipping});
  const Diagnosis d = diagnose(nominal, real, opt);
  ASSERT_FALSE(d.rounds.empty()) << d.verdict;
  ASSERT_FALSE(d.rounds[0].ranked.empty()) << d.verdict;
  const sim::EffectSpec& c = d.rounds[0].ranked[0].effect;
  ASSERT_EQ(c.kind, sim::EffectKind::kAdcClipping);
  auto amp = [](const std::map<std::string, double>& by) {
    const auto it = by.find("amplitude");
    return it == by.end() ? 0.0 : it->second;
  };
  // Measured with this build: named at 7.83 m/s^2 for 7.83 (the measured rails), the model clamped at
  // 4.94; the nominal's held-out gap 10.12 shrunk by 79.1 %, its `amplitude` probe (the share at the
  // rails) 8.87 -> 0.67 (second realisation 0.59). With the clamp at the measured level (the form
  // before): shrink 15.5 %, `amplitude` 8.87 -> 7.29.
  EXPECT_NEAR(c.get("level_ms2"), 0.6 * peak, 0.05 * 0.6 * peak) << d.verdict;
  EXPECT_GT(c.get("sim_level_ms2"), 0.0) << d.verdict;
  EXPECT_LT(c.get("sim_level_ms2"), 0.9 * c.get("level_ms2")) << d.verdict;
  ASSERT_EQ(d.chosen.size(), 1U) << d.verdict;
  EXPECT_GT(d.total_shrink_pct, 50.0) << d.verdict;
  const double amp_before = amp(d.nominal_heldout.by_probe);
  EXPECT_GT(amp_before, 4.0) << d.verdict;
  EXPECT_LT(amp(d.rounds[0].ranked[0].heldout_by_probe), 0.25 * amp_before) << d.verdict;
  EXPECT_LT(amp(d.rounds[0].ranked[0].replicate_by_probe), 0.25 * amp_before) << d.verdict;
}

}  // namespace
}  // namespace ptda::gap
