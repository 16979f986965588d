// Slow healthy drift ([drift], sim/include/ptda/sim/drift.hpp): each drift's signature, measured on the
// synthesised signal, equals its closed form; the keys are validated with file:line:column; the state
// at the end of a recording is recorded so that the next one continues it; off changes nothing.
#include <gtest/gtest.h>
#include <toml++/toml.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <numbers>
#include <string>
#include <vector>

#include "ptda/common/error.hpp"
#include "ptda/sim/simulator.hpp"

namespace ptda::sim {
namespace {

constexpr double kPi = std::numbers::pi;

// Constant input-shaft speed (cycloidal Table 2 gearbox), one GMF order of amplitude 1 at exactly the
// running speed (speed factor 1), no noise. f_in = 10 Hz: GMF = 280 Hz.
Scenario constant_mesh(double fs_hz, double duration_s) {
  Scenario s;
  s.source = "test";
  s.motion.kind = MotionKind::kConstant;
  s.motion.shaft_speed_hz = 10.0;
  s.motion.duration_s = duration_s;
  s.motion.cycles = 1;
  s.sensor.fs_hz = fs_hz;
  s.sensor.format = formats::WavSampleFormat::kFloat32;
  s.vibration.gmf_amplitudes = {1.0};
  s.vibration.reference_speed_rad_s = 2.0 * kPi * 10.0 / reduction_ratio(s.gearbox);
  s.vibration.noise_rms = 0.0;
  return s;
}

// Amplitude of the 280 Hz line in x[i0, i0 + n) by quadrature demodulation against the mesh phase (n
// spans whole GMF periods, so the two products are orthogonal).
double amplitude_280(const std::vector<double>& x, std::size_t i0, std::size_t n, double fs_hz) {
  double a = 0.0;
  double b = 0.0;
  for (std::size_t i = i0; i < i0 + n; ++i) {
    const double t = static_cast<double>(i) / fs_hz;
    a += x[i] * std::sin(2.0 * kPi * 280.0 * t);
    b += x[i] * std::cos(2.0 * kPi * 280.0 * t);
  }
  return 2.0 * std::hypot(a, b) / static_cast<double>(n);
}

TEST(Drift, MeshAmplitudeFollowsLoadCycleAndWarmUp) {
  const double fs = 5000.0;
  Scenario s = constant_mesh(fs, 20.0);
  s.drift.time_offset_s = 3.0;
  s.drift.load_period_s = 20.0;
  s.drift.load_phase_rad = 0.5;
  s.drift.mesh_amplitude_rel = 0.3;
  s.drift.warmup_tau_s = 6.0;
  s.drift.initial_coldness = 0.8;
  s.drift.cold_amplitude_rel = -0.2;
  const MotionProfile m = build_motion(s, 1);
  const Vibration v = synthesize_vibration(s, m, 1);
  // Blocks of 0.1 s = 28 GMF periods (500 samples); the closed form at the block centre (the drift is
  // smooth: its curvature over 0.1 s changes the block mean by < 1e-5).
  const std::size_t block = 500;
  double worst = 0.0;
  for (std::size_t b = 0; b + 1 < v.accel_ms2.size() / block; ++b) {
    const double t_mid = (static_cast<double>(b * block) + (block - 1) / 2.0) / fs;
    const double load = std::sin(2.0 * kPi * (t_mid + 3.0) / 20.0 + 0.5);
    const double cold = 0.8 * std::exp(-t_mid / 6.0);
    const double expected = (1.0 + 0.3 * load) * (1.0 - 0.2 * cold);
    const double got = amplitude_280(v.accel_ms2, b * block, block, fs);
    worst = std::max(worst, std::fabs(got - expected));
  }
  EXPECT_LT(worst, 2e-4);
  // The swing is really +-30 % (times the warm-up): max and min over the run.
  const DriftModel model(s.drift, m.pause_start_s);
  EXPECT_NEAR(model.at(20.0 * (0.25 - 0.5 / (2.0 * kPi)) - 3.0).load, 1.0, 1e-12);
}

TEST(Drift, ColdOilNoiseDecaysWithWarmUpTimeConstant) {
  const double fs = 20000.0;
  Scenario s = constant_mesh(fs, 12.0);
  s.vibration.gmf_amplitudes = {};
  s.vibration.noise_rms = 1.0;
  s.drift.warmup_tau_s = 4.0;
  s.drift.cold_noise_rel = 1.0;  // cold start: twice the noise
  const MotionProfile m = build_motion(s, 7);
  const Vibration v = synthesize_vibration(s, m, 7);
  // Blocks of 0.5 s (10000 samples: the rms of a Gaussian block scatters by ~0.7 %).
  const std::size_t block = 10000;
  for (std::size_t b = 0; b < v.accel_ms2.size() / block; ++b) {
    double e2 = 0.0;
    double expected2 = 0.0;
    for (std::size_t i = b * block; i < (b + 1) * block; ++i) {
      e2 += v.accel_ms2[i] * v.accel_ms2[i];
      const double g = 1.0 + std::exp(-(static_cast<double>(i) / fs) / 4.0);
      expected2 += g * g;
    }
    EXPECT_NEAR(std::sqrt(e2 / expected2), 1.0, 0.025) << "block " << b;
  }
}

// Joint rotation without start jitter, so the pause is the only change of the cycle spacing.
Scenario paused_job() {
  Scenario s;
  s.source = "test";
  s.motion.via_points_rad = {0.0, kPi, 0.0};
  s.motion.segment_speeds_rad_s = {3.49068, 3.49068};
  s.motion.accel_rad_s2 = 17.45;
  s.motion.cycles = 9;
  s.motion.dwell_s = 0.1;
  s.motion.start_jitter_s = 0.0;
  s.sensor.fs_hz = 2000.0;
  s.vibration.gmf_amplitudes = {0.0};
  s.vibration.noise_rms = 0.0;
  s.drift.pause_every_cycles = 4;
  s.drift.pause_s = 2.5;
  s.drift.warmup_tau_s = 10.0;
  s.drift.cooldown_tau_s = 5.0;
  s.drift.initial_coldness = 1.0;
  return s;
}

TEST(Drift, ProgramPausesStopTheJointAndCoolTheGearbox) {
  const Scenario s = paused_job();
  const MotionProfile m = build_motion(s, 1);
  ASSERT_EQ(m.pause_start_s.size(), 2U);  // before cycles 4 and 8
  const double period = m.cycle_start_s[1] - m.cycle_start_s[0];
  for (std::size_t c = 1; c < m.cycle_start_s.size(); ++c) {
    const double extra = (c == 4 || c == 8) ? 2.5 : 0.0;
    EXPECT_NEAR(m.cycle_start_s[c] - m.cycle_start_s[c - 1], period + extra, 1e-9) << "cycle " << c;
  }
  // The pause starts where cycle 3's dwell ends and the joint stands still through it.
  EXPECT_NEAR(m.pause_start_s[0] + 2.5, m.cycle_start_s[4], 1e-9);
  for (double t = m.pause_start_s[0]; t < m.pause_start_s[0] + 2.5; t += 0.1) {
    EXPECT_EQ(motion_at(m, t).speed_rad_s, 0.0);
  }
  // Coldness: e^{-t/10} until the pause, then 1 - (1 - c_p) e^{-dt/5}, then decaying again.
  const DriftModel model(s.drift, m.pause_start_s);
  const double p0 = m.pause_start_s[0];
  const double c_p = std::exp(-p0 / 10.0);
  const double c_end = 1.0 - (1.0 - c_p) * std::exp(-2.5 / 5.0);
  EXPECT_NEAR(model.coldness_at(0.5 * p0), std::exp(-0.05 * p0), 1e-12);
  EXPECT_NEAR(model.coldness_at(p0 + 1.0), 1.0 - (1.0 - c_p) * std::exp(-1.0 / 5.0), 1e-12);
  EXPECT_NEAR(model.coldness_at(p0 + 2.5 + 3.0), c_end * std::exp(-0.3), 1e-12);
  EXPECT_GT(model.coldness_at(p0 + 2.5), model.coldness_at(p0));  // the pause cooled it
}

// Zero crossings (linearly interpolated) of x in [t0, t0 + span): the mean spacing of the first and
// last crossing gives the ringing frequency.
double ringing_hz(const std::vector<double>& x, double fs_hz, double t0, double span) {
  const auto i0 = static_cast<std::size_t>(std::ceil(t0 * fs_hz)) + 1;
  const auto i1 = static_cast<std::size_t>((t0 + span) * fs_hz);
  double first = -1.0;
  double last = -1.0;
  int crossings = 0;
  for (std::size_t i = i0 + 1; i < i1; ++i) {
    if ((x[i - 1] < 0.0) != (x[i] < 0.0)) {
      const double t = (static_cast<double>(i - 1) + x[i - 1] / (x[i - 1] - x[i])) / fs_hz;
      if (first < 0.0) first = t;
      last = t;
      ++crossings;
    }
  }
  return (crossings - 1) / 2.0 / (last - first);
}

TEST(Drift, ResonanceShiftsWithTheLoadCycle) {
  const double fs = 200000.0;
  Scenario s = constant_mesh(fs, 1.0);
  s.vibration.gmf_amplitudes = {};
  FaultSpec f;
  f.kind = FaultKind::kSpurTooth;
  f.impulse_amplitude_ms2 = 2.0;
  f.resonance_hz = 3000.0;
  f.damping_ratio = 0.05;
  f.am_depth = 0.0;
  s.faults.push_back(f);
  s.drift.load_period_s = 2.0;  // one impulse every 82 ms: L sweeps through half a cycle
  s.drift.resonance_shift_rel = 0.2;
  const MotionProfile m = build_motion(s, 1);
  const Vibration v = synthesize_vibration(s, m, 1);
  ASSERT_GE(v.impulse_times_s.size(), 10U);
  for (std::size_t k = 0; k + 1 < v.impulse_times_s.size(); ++k) {
    const double t = v.impulse_times_s[k];
    const double load = std::sin(2.0 * kPi * t / 2.0);
    const double expected = 3000.0 * (1.0 + 0.2 * load) * std::sqrt(1.0 - 0.05 * 0.05);  // damped
    EXPECT_NEAR(ringing_hz(v.accel_ms2, fs, t, 0.004) / expected, 1.0, 2e-3) << "impulse " << k;
  }
}

TEST(Drift, OffIsByteIdenticalAndZeroTableIsOff) {
  Scenario plain = paused_job();
  plain.drift = DriftSpec{};
  plain.vibration.gmf_amplitudes = {0.43, 0.0, 0.0, 0.48};
  plain.vibration.noise_rms = 0.5;
  const MotionProfile m = build_motion(plain, 3);
  const Vibration a = synthesize_vibration(plain, m, 3);
  // A [drift] table whose keys are all at their defaults is the same as no table.
  const Scenario parsed = parse_scenario(R"([motion]
via_points_rad = [0.0, 1.0]
max_speed_rad_s = 1.0
[drift]
load_period_s = 0
mesh_amplitude_rel = 0
)",
                                         "t.toml");
  EXPECT_FALSE(parsed.drift.on());
  // Drift with every factor at 1 (a load cycle of amplitude 0) leaves the signal bit-identical.
  Scenario unit = plain;
  unit.drift.load_period_s = 100.0;
  const Vibration b = synthesize_vibration(unit, m, 3);
  ASSERT_EQ(a.accel_ms2.size(), b.accel_ms2.size());
  EXPECT_EQ(a.accel_ms2, b.accel_ms2);
}

void expect_error(const std::string& text, const std::string& needle) {
  try {
    (void)parse_scenario(text, "t.toml");
    ADD_FAILURE() << "no error for:\n" << text;
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << "message: " << e.what();
  }
}

TEST(Drift, KeysAreValidatedWithLocation) {
  const std::string motion = "[motion]\nvia_points_rad = [0.0, 1.0]\nmax_speed_rad_s = 1.0\n";
  expect_error(motion + "[drift]\nload_perod_s = 3600\n", "t.toml:5:1: unknown key 'drift.load_perod_s'");
  expect_error(motion + "[drift]\nmesh_amplitude_rel = 0.3\n",
               "t.toml:5:22: drift.mesh_amplitude_rel: needs load_period_s > 0");
  expect_error(motion + "[drift]\nload_period_s = 3600\nmesh_amplitude_rel = 1.5\n",
               "t.toml:6:22: drift.mesh_amplitude_rel: must be in [0, 0.9]");
  expect_error(motion + "[drift]\ncold_noise_rel = 0.5\n",
               "t.toml:5:18: drift.cold_noise_rel: needs warmup_tau_s");
  expect_error(motion + "[drift]\nwarmup_tau_s = 600\ninitial_coldness = 2\n",
               "t.toml:6:20: drift.initial_coldness: must be in [0, 1]");
  expect_error(motion + "[drift]\npause_s = 30\n",
               "t.toml:5:11: drift.pause_s: pause_every_cycles and pause_s");
  expect_error(motion + "[drift]\npause_every_cycles = -1\npause_s = 30\n",
               "t.toml:5:22: drift.pause_every_cycles: -1 is outside 0..1000000");
  expect_error(
      "[motion]\nkind = \"constant\"\nshaft_speed_hz = 10\nduration_s = 5\n[drift]\npause_every_cycles = "
      "2\npause_s = 1\n",
      "t.toml:6:22: drift.pause_every_cycles: program pauses need [motion] kind = \"lspb\"");
}

TEST(Drift, TruthRecordsTheStateToContinueFrom) {
  Scenario s = paused_job();
  s.drift.load_period_s = 50.0;
  s.drift.mesh_amplitude_rel = 0.3;
  s.drift.time_offset_s = 7.0;
  const char* env = std::getenv("TMPDIR");
  const std::filesystem::path dir =
      (env != nullptr ? std::filesystem::path(env) : std::filesystem::temp_directory_path()) /
      ("ptda_drift_truth_" + std::to_string(::getpid()));
  const SimulationSummary sum = simulate_to_directory(s, dir);
  const toml::table truth = toml::parse_file((dir / "truth.toml").string());
  std::filesystem::remove_all(dir);
  const toml::table* d = truth["drift"].as_table();
  ASSERT_NE(d, nullptr);
  EXPECT_DOUBLE_EQ((*d)["time_end_s"].value_or(0.0), 7.0 + sum.duration_s);
  const MotionProfile m = build_motion(s, s.seed);
  const DriftModel model(s.drift, m.pause_start_s);
  EXPECT_DOUBLE_EQ((*d)["coldness_at_end"].value_or(-1.0), model.coldness_at(sum.duration_s));
  ASSERT_EQ((*d)["pause_start_s"].as_array()->size(), 2U);
  // A recording that starts where this one ended has the same drift at its sample 0.
  DriftSpec next = s.drift;
  next.time_offset_s = (*d)["time_end_s"].value_or(0.0);
  next.initial_coldness = (*d)["coldness_at_end"].value_or(0.0);
  const DriftModel cont(next, {});
  EXPECT_NEAR(cont.at(0.0).mesh_gain, model.at(sum.duration_s).mesh_gain, 1e-12);
  EXPECT_NEAR(cont.at(0.0).load, (*d)["load_at_end"].value_or(9.0), 1e-12);
}

}  // namespace
}  // namespace ptda::sim
