// Another axis on its own program (issue 11): the library's `other_axis` in its own-program form (a line
// at a fixed frequency that comes and goes on the other joint's schedule), the line-presence measure that
// tells such a line from steady pickup, and the diagnosis that names it by its line.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "gap_test_job.hpp"
#include "ptda/gap/bench.hpp"
#include "ptda/gap/diagnose.hpp"
#include "ptda/gap/signals.hpp"
#include "ptda/sim/simulator.hpp"

namespace ptda::gap {
namespace {

sim::EffectSpec own_axis(double f_hz, double amp, double duty, double h2) {
  sim::EffectSpec e = sim::EffectSpec::with_defaults(sim::EffectKind::kOtherAxis);
  e.set("own_frequency_hz", f_hz);
  e.set("amplitude_ms2", amp);
  e.set("duty", duty);
  e.set("harmonic2", h2);
  return e;
}

sim::EffectSpec steady_line(double f_hz, double amp) {
  sim::EffectSpec e = sim::EffectSpec::with_defaults(sim::EffectKind::kElectricalInterference);
  e.set("frequency_hz", f_hz);
  e.set("amplitude_ms2", amp);
  e.set("harmonics", 1.0);
  return e;
}

GapRecording record(const std::vector<sim::EffectSpec>& effects, std::uint64_t seed) {
  sim::Scenario s = test::joint_rotation_job(6);
  s.effects = effects;
  return recording_from_simulation(sim::simulate_signals(s, seed), s);
}

double gmf_per_rad_s() {
  return std::fabs(sim::gmf_hz(test::joint_rotation_job(6).gearbox, 1.0));
}

// Sum of |DFT|^2 over +-2 bins around f over the whole recording, for the level of a line.
double line_power(const GapRecording& r, double f_hz) {
  const std::size_t n = r.accel_ms2.size();
  const double df = r.fs_hz / static_cast<double>(n);
  double p = 0.0;
  for (int m = -2; m <= 2; ++m) {
    const double w = 2.0 * std::acos(-1.0) * (f_hz + m * df) / r.fs_hz;
    double re = 0.0, im = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      re += r.accel_ms2[i] * std::cos(w * static_cast<double>(i));
      im -= r.accel_ms2[i] * std::sin(w * static_cast<double>(i));
    }
    p += re * re + im * im;
  }
  return p;
}

TEST(OtherAxisOwnProgram, ItsLineComesAndGoesWithItsDutyAndCarriesItsSecondHarmonic) {
  const GapRecording bare = record({}, 7);
  const GapRecording on = record({own_axis(437.0, 0.6, 0.4, 0.5)}, 7);
  // The line is there whatever this joint does, on 40 % of the 0.1 s frames (2.5 s periods, 0.1 s
  // raised-cosine edges: the frames on an edge fall either way).
  const LinePresence lp = line_presence(on, segment_recording(on), {}, 437.0, gmf_per_rad_s());
  ASSERT_TRUE(lp.judged) << lp.frames << " frames, " << lp.on_level_db << " dB";
  EXPECT_NEAR(lp.share, 0.4, 0.08);
  EXPECT_GT(lp.on_level_db, 20.0);
  // Level: amplitude^2 x duty over the line, 2nd harmonic 0.5 x (-6 dB) of the 1st.
  const double p1 = line_power(on, 437.0) - line_power(bare, 437.0);
  const double p2 = line_power(on, 874.0) - line_power(bare, 874.0);
  EXPECT_NEAR(10.0 * std::log10(p2 / p1), 20.0 * std::log10(0.5), 1.0);
  // The lagged form is unchanged by the new parameters' defaults (own_frequency_hz 0): the same signal.
  sim::EffectSpec lagged = sim::EffectSpec::with_defaults(sim::EffectKind::kOtherAxis);
  sim::EffectSpec lagged_explicit = lagged;
  lagged_explicit.set("duty", 0.3);  // unused by the lagged form
  lagged_explicit.set("harmonic2", 0.7);
  EXPECT_EQ(record({lagged}, 7).accel_ms2, record({lagged_explicit}, 7).accel_ms2);
}

TEST(LinePresence, SteadyPickupIsOnInEveryFrameAndAWeakLineIsNotJudged) {
  const GapRecording steady = record({steady_line(437.0, 0.3)}, 8);
  const LinePresence lp = line_presence(steady, segment_recording(steady), {}, 437.0, gmf_per_rad_s());
  ASSERT_TRUE(lp.judged);
  EXPECT_GT(lp.share, 0.95) << lp.frames << " frames";
  // 0.01 m/s^2 in 0.3 m/s^2 of noise: about 4 dB over the floor per frame, below the 10 dB to judge.
  const GapRecording weak = record({steady_line(437.0, 0.01)}, 8);
  const LinePresence lw = line_presence(weak, segment_recording(weak), {}, 437.0, gmf_per_rad_s());
  EXPECT_FALSE(lw.judged) << lw.on_level_db << " dB";
  EXPECT_EQ(lw.share, 1.0);
  // Frames are taken from the selected units only; none selected: nothing to judge.
  const std::vector<Segment> segs = segment_recording(steady);
  std::uint32_t units = 0;
  for (const Segment& sg : segs) units = std::max(units, sg.cycle + 1);
  const LinePresence none = line_presence(steady, segs, std::vector<char>(units, 0), 437.0, gmf_per_rad_s());
  EXPECT_EQ(none.frames, 0U);
  EXPECT_FALSE(none.judged);
}

TEST(Diagnose, AnotherAxisOnItsOwnProgramIsNamedByItsLineAndSteadyPickupStaysInterference) {
  const sim::Scenario nominal = test::joint_rotation_job(6);
  DiagnoseOptions opt = test::one_effect_of({sim::EffectKind::kElectricalInterference,
                                             sim::EffectKind::kOtherAxis, sim::EffectKind::kTransferPath});
  opt.threads = 2;
  const GapRecording axis = record({own_axis(437.0, 0.6, 0.5, 0.3)}, 2026);
  const Diagnosis d = diagnose(nominal, axis, opt);
  ASSERT_EQ(d.chosen.size(), 1U) << d.verdict;
  const sim::EffectSpec& e = d.chosen[0].effect;
  ASSERT_EQ(e.kind, sim::EffectKind::kOtherAxis) << d.verdict;
  EXPECT_NEAR(e.get("own_frequency_hz"), 437.0, 437.0 * 0.005) << d.verdict;
  EXPECT_NEAR(e.get("duty"), 0.5, 0.1) << d.verdict;
  EXPECT_TRUE(location_matches(own_axis(437.0, 0.6, 0.5, 0.3), e));
  EXPECT_GT(d.total_shrink_pct, 70.0) << d.verdict;
  // The same line, steady (mains-like pickup): interference, as before.
  const GapRecording pickup = record({steady_line(437.0, 0.42)}, 2026);
  const Diagnosis p = diagnose(nominal, pickup, opt);
  ASSERT_EQ(p.chosen.size(), 1U) << p.verdict;
  EXPECT_EQ(p.chosen[0].effect.kind, sim::EffectKind::kElectricalInterference) << p.verdict;
  EXPECT_NEAR(p.chosen[0].effect.get("frequency_hz"), 437.0, 437.0 * 0.02) << p.verdict;
}

TEST(BenchLocation, AnotherAxisIsLocatedByItsLineOrByItsRatioNeverAcrossForms) {
  const sim::EffectSpec truth_own = own_axis(437.0, 0.6, 0.5, 0.3);
  EXPECT_TRUE(location_matches(truth_own, own_axis(445.0, 0.2, 0.9, 0.0)));   // 1.8 % off
  EXPECT_FALSE(location_matches(truth_own, own_axis(447.0, 0.6, 0.5, 0.3)));  // 2.3 % off
  sim::EffectSpec lagged = sim::EffectSpec::with_defaults(sim::EffectKind::kOtherAxis);
  lagged.set("frequency_ratio", 1.5);
  EXPECT_FALSE(location_matches(truth_own, lagged));
  sim::EffectSpec own_with_ratio = own_axis(437.0, 0.6, 0.5, 0.3);
  own_with_ratio.set("frequency_ratio", 1.5);
  EXPECT_FALSE(location_matches(lagged, own_with_ratio));
  sim::EffectSpec near = lagged;
  near.set("frequency_ratio", 1.52);
  EXPECT_TRUE(location_matches(lagged, near));
}

}  // namespace
}  // namespace ptda::gap
