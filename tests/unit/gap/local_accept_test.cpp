// The local acceptance rule (docs/gap.md step 8): an exactly located line is named even when the model's
// other shortcomings (here a strong mesh order the nominal lacks) keep the global gap large.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
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
  DiagnoseOptions opt;
  opt.candidates = {sim::EffectKind::kElectricalInterference};
  opt.max_effects = 1;
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

// Two interference sources (mains with odd harmonics and a drive's switching line) are both named, the
// mains with its odd harmonics (the library's `odd_only` form). Here the greedy rounds would also find
// both with one line guess (checked with kLineGuesses = 1): the case that needed one candidate per
// distinct excess line is the gen2 development case 1024 (docs/gap.md "Session 12"), where the line
// with the largest excess was not the one holding the gap.
TEST(LocalAcceptance, EachDistinctExcessLineIsItsOwnInterferenceCandidate) {
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
  ASSERT_EQ(d.chosen.size(), 2U) << d.verdict;
  std::vector<double> f;
  for (const CandidateResult& c : d.chosen) {
    EXPECT_EQ(c.effect.kind, sim::EffectKind::kElectricalInterference) << d.verdict;
    f.push_back(c.effect.get("frequency_hz"));
  }
  std::sort(f.begin(), f.end());
  EXPECT_NEAR(f[0], 50.0, 0.5) << d.verdict;
  EXPECT_NEAR(f[1], 2500.0, 25.0) << d.verdict;
  // The mains candidate keeps the odd harmonics it started from.
  for (const CandidateResult& c : d.chosen) {
    if (c.effect.get("frequency_hz") < 100.0) {
      EXPECT_EQ(std::lround(c.effect.get("odd_only")), 1) << d.verdict;
      EXPECT_GE(std::lround(c.effect.get("harmonics")), 3) << d.verdict;
    }
  }
  EXPECT_GT(d.total_shrink_pct, 70.0) << d.verdict;
}

}  // namespace
}  // namespace ptda::gap
