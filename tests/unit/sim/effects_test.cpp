// Sim-to-real effects: scenario keys and each effect's signature in the simulated signals.
#include "ptda/sim/effects.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <filesystem>
#include <numbers>
#include <string>

#include "ptda/common/error.hpp"
#include "ptda/common/time.hpp"
#include "ptda/sim/simulator.hpp"

namespace ptda::sim {
namespace {

constexpr double kPi = std::numbers::pi;

// Amplitude of the sinusoid at f_hz over x[i0, i0 + n) (single-bin DFT, exact for whole periods).
double tone_amplitude(const std::vector<double>& x, double fs, double f_hz, std::size_t i0, std::size_t n) {
  std::complex<double> acc = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    acc += x[i0 + i] * std::polar(1.0, -2.0 * kPi * f_hz * static_cast<double>(i) / fs);
  }
  return 2.0 * std::abs(acc) / static_cast<double>(n);
}

// Mean power of x in [f_lo, f_hi] from single-bin DFTs at 1 Hz spacing over 1 s blocks.
double band_power(const std::vector<double>& x, double fs, double f_lo, double f_hi) {
  const auto n = static_cast<std::size_t>(fs);
  double sum = 0.0;
  int count = 0;
  for (std::size_t b = 0; b + n <= x.size(); b += n) {
    for (double f = f_lo; f <= f_hi; f += 1.0) {
      const double a = tone_amplitude(x, fs, f, b, n);
      sum += a * a;
      ++count;
    }
  }
  return sum / count;
}

// Constant input shaft at 20 Hz through a parallel 30/60 stage: GMF = 600 Hz, fs 8000 Hz, no noise.
Scenario rig(double duration_s = 2.0) {
  Scenario s;
  s.source = "test";
  s.motion.kind = MotionKind::kConstant;
  s.motion.shaft_speed_hz = 20.0;
  s.motion.duration_s = duration_s;
  s.motion.cycles = 2;
  s.gearbox.kind = GearboxKind::kParallel;
  s.gearbox.z_in = 30;
  s.gearbox.z_spur = 60;
  s.gearbox.z_pin = 0;
  s.vibration.gmf_amplitudes = {1.0};
  s.vibration.amplitude_speed_exponent = 0.0;
  s.vibration.noise_rms = 0.0;
  s.sensor.fs_hz = 8000.0;
  s.sensor.format = formats::WavSampleFormat::kFloat32;
  return s;
}

Scenario with(Scenario s, EffectKind k, std::initializer_list<std::pair<const char*, double>> params) {
  EffectSpec e = EffectSpec::with_defaults(k);
  for (const auto& [name, v] : params) e.set(name, v);
  s.effects.push_back(e);
  return s;
}

TEST(EffectsScenario, ParsesEffectsWithDefaults) {
  const Scenario s = parse_scenario(R"([motion]
via_points_rad = [0.0, 1.0]
max_speed_rad_s = 1.0
[[effects]]
kind = "transfer_path"
frequency_hz = 2500.0
[[effects]]
kind = "sample_clock_error"
ppm = -800
)",
                                    "t.toml");
  ASSERT_EQ(s.effects.size(), 2U);
  EXPECT_EQ(s.effects[0].kind, EffectKind::kTransferPath);
  EXPECT_DOUBLE_EQ(s.effects[0].get("frequency_hz"), 2500.0);
  EXPECT_DOUBLE_EQ(s.effects[0].get("gain_db"), 12.0);  // default
  EXPECT_DOUBLE_EQ(s.effects[1].get("ppm"), -800.0);
}

/// The parse error of a scenario text ("" when it parses).
std::string error_of(const std::string& text) {
  try {
    (void)parse_scenario(text, "t.toml");
  } catch (const Error& e) {
    return std::string(e.what());
  }
  return std::string();
}

void expect_error(const std::string& text, const std::string& needle) {
  try {
    (void)parse_scenario(text, "t.toml");
    ADD_FAILURE() << "no error for:\n" << text;
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << "message: " << e.what();
  }
}

TEST(EffectsScenario, ErrorsNameTheKeyAndLine) {
  const std::string head = "[motion]\nvia_points_rad = [0.0, 1.0]\nmax_speed_rad_s = 1.0\n[[effects]]\n";
  expect_error(head + "kind = \"warp_drive\"\n", "t.toml:5:8: [[effects]] kind must be one of transfer_path");
  expect_error(head + "kind = \"impacts\"\nresonanse_hz = 100.0\n",
               "t.toml:6:1: unknown key 'effects[0].resonanse_hz'");
  expect_error(head + "kind = \"adc_clipping\"\nlevel_ms2 = -1.0\n",
               "t.toml:6:13: effects[0].level_ms2: must be in");
  expect_error(head + "kind = \"transfer_path\"\nfrequency_hz = 20000.0\n",
               "frequency_hz: must be below 0.49 fs_hz");
  expect_error(head + "kind = \"speed_latency\"\njitter_s = 0.0045\n",
               "jitter_s: plus [can] jitter_s must stay below");
}

TEST(EffectsScenario, EveryShippedScenarioStillParses) {
  int n = 0;
  for (const auto& f :
       std::filesystem::directory_iterator(std::filesystem::path(PTDA_SOURCE_DIR) / "config" / "scenarios")) {
    if (f.path().extension() != ".toml") continue;
    EXPECT_NO_THROW((void)load_scenario(f.path())) << f.path();
    ++n;
  }
  EXPECT_GE(n, 9);
}

TEST(Effects, TransferPathBoostsItsBandOnly) {
  Scenario s = rig(2.0);
  s.vibration.gmf_amplitudes.clear();
  s.vibration.noise_rms = 1.0;
  const SimulatedSignals a = simulate_signals(s, 5);
  const SimulatedSignals b = simulate_signals(
      with(s, EffectKind::kTransferPath, {{"frequency_hz", 2000.0}, {"gain_db", 12.0}, {"q", 4.0}}), 5);
  const double fs = s.sensor.fs_hz;
  const double in_band =
      band_power(b.vibration.accel_ms2, fs, 1950, 2050) / band_power(a.vibration.accel_ms2, fs, 1950, 2050);
  const double far =
      band_power(b.vibration.accel_ms2, fs, 400, 500) / band_power(a.vibration.accel_ms2, fs, 400, 500);
  // Peak gain 12 dB = x15.8 in power; over +-50 Hz (a fifth of the 500 Hz bandwidth) nearly all of it.
  EXPECT_GT(10.0 * std::log10(in_band), 11.0);
  EXPECT_LT(10.0 * std::log10(in_band), 12.5);
  EXPECT_NEAR(10.0 * std::log10(far), 0.0, 0.5);
}

TEST(Effects, MeshModulationMakesSidebandsAtItsRate) {
  const Scenario s =
      with(rig(), EffectKind::kMeshModulation, {{"rate_order", 1.5}, {"am_depth", 0.4}, {"pm_rad", 0.0}});
  const SimulatedSignals sig = simulate_signals(s, 1);
  const double fs = s.sensor.fs_hz;
  const auto n = static_cast<std::size_t>(fs);  // 1 s: whole periods of 600 and 600 +- 30 Hz
  // AM depth m puts m/2 of the carrier into each sideband at GMF +- 1.5 x 20 Hz.
  EXPECT_NEAR(tone_amplitude(sig.vibration.accel_ms2, fs, 600.0, 0, n), 1.0, 1e-3);
  EXPECT_NEAR(tone_amplitude(sig.vibration.accel_ms2, fs, 570.0, 0, n), 0.2, 1e-3);
  EXPECT_NEAR(tone_amplitude(sig.vibration.accel_ms2, fs, 630.0, 0, n), 0.2, 1e-3);
  EXPECT_LT(tone_amplitude(sig.vibration.accel_ms2, fs, 580.0, 0, n), 1e-3);
}

TEST(Effects, SampleClockErrorShiftsTheMeshByTheRatio) {
  const Scenario s = with(rig(1.0), EffectKind::kSampleClockError, {{"ppm", 2000.0}});
  const SimulatedSignals sig = simulate_signals(s, 1);
  EXPECT_EQ(sig.fs_nominal_hz, 8000.0);
  // Frequency from the first and last upward zero crossings, on the nominal sample grid.
  const std::vector<double>& x = sig.vibration.accel_ms2;
  double first = -1, last = -1;
  int crossings = 0;
  for (std::size_t i = 1; i < x.size(); ++i) {
    if (x[i - 1] < 0.0 && x[i] >= 0.0) {
      const double t = (static_cast<double>(i - 1) + x[i - 1] / (x[i - 1] - x[i])) / sig.fs_nominal_hz;
      if (first < 0) first = t;
      last = t;
      ++crossings;
    }
  }
  const double f = (crossings - 1) / (last - first);
  EXPECT_NEAR(f / 600.0, 1.0 / 1.002, 2e-6);
}

TEST(Effects, AdcClippingsSimulationLevelOverridesTheMachinesLevel) {
  // The gap diagnosis's second form: the machine's rails at level_ms2, the model clamped at
  // sim_level_ms2 (where a model with a lighter tail has the machine's share at its rails).
  const Scenario s = with(rig(), EffectKind::kAdcClipping, {{"level_ms2", 0.9}, {"sim_level_ms2", 0.5}});
  const SimulatedSignals sig = simulate_signals(s, 1);
  double mx = 0.0;
  for (double v : sig.vibration.accel_ms2) mx = std::max(mx, std::fabs(v));
  EXPECT_DOUBLE_EQ(mx, 0.5);
  const Scenario plain = with(rig(), EffectKind::kAdcClipping, {{"level_ms2", 0.9}, {"sim_level_ms2", 0.0}});
  const SimulatedSignals sig_plain = simulate_signals(plain, 1);
  mx = 0.0;
  for (double v : sig_plain.vibration.accel_ms2) mx = std::max(mx, std::fabs(v));
  EXPECT_DOUBLE_EQ(mx, 0.9);
}

TEST(Effects, AdcClippingCapsTheSignal) {
  const Scenario s = with(rig(), EffectKind::kAdcClipping, {{"level_ms2", 0.7}});
  const SimulatedSignals sig = simulate_signals(s, 1);
  double mx = 0.0;
  for (double v : sig.vibration.accel_ms2) mx = std::max(mx, std::fabs(v));
  EXPECT_DOUBLE_EQ(mx, 0.7);
  // 600 Hz at 8000 Hz repeats every 40 samples (3 periods): the share of those sample phases with
  // |sin| > 0.7 is exactly the share of clipped samples (continuous-time value 1 - 2 asin(0.7)/pi = 0.506).
  int above = 0;
  for (int k = 0; k < 40; ++k) above += std::fabs(std::sin(2.0 * kPi * 3.0 * k / 40.0)) > 0.7 ? 1 : 0;
  EXPECT_EQ(above, 22);
  EXPECT_DOUBLE_EQ(
      static_cast<double>(sig.vibration.effect_clipped_samples) / static_cast<double>(sig.codes.size()),
      above / 40.0);
}

TEST(Effects, ElectricalInterferenceAtFixedFrequencies) {
  Scenario s = rig();
  s.vibration.gmf_amplitudes.clear();
  s = with(s, EffectKind::kElectricalInterference,
           {{"frequency_hz", 50.0}, {"amplitude_ms2", 0.3}, {"harmonics", 3.0}, {"harmonic_decay", 0.5}});
  const SimulatedSignals sig = simulate_signals(s, 1);
  const auto n = static_cast<std::size_t>(s.sensor.fs_hz);
  EXPECT_NEAR(tone_amplitude(sig.vibration.accel_ms2, 8000, 50, 0, n), 0.3, 1e-6);
  EXPECT_NEAR(tone_amplitude(sig.vibration.accel_ms2, 8000, 100, 0, n), 0.15, 1e-6);
  EXPECT_NEAR(tone_amplitude(sig.vibration.accel_ms2, 8000, 150, 0, n), 0.075, 1e-6);
  EXPECT_LT(tone_amplitude(sig.vibration.accel_ms2, 8000, 200, 0, n), 1e-6);
}

TEST(Effects, ElectricalInterferenceOddHarmonicsOnly) {
  Scenario s = rig();
  s.vibration.gmf_amplitudes.clear();
  s = with(s, EffectKind::kElectricalInterference,
           {{"frequency_hz", 50.0},
            {"amplitude_ms2", 0.3},
            {"harmonics", 3.0},
            {"harmonic_decay", 0.5},
            {"odd_only", 1.0}});
  const SimulatedSignals sig = simulate_signals(s, 1);
  const auto n = static_cast<std::size_t>(s.sensor.fs_hz);
  // Three lines at harmonics 1, 3, 5, each half the last; nothing at the even ones or beyond the third.
  EXPECT_NEAR(tone_amplitude(sig.vibration.accel_ms2, 8000, 50, 0, n), 0.3, 1e-6);
  EXPECT_NEAR(tone_amplitude(sig.vibration.accel_ms2, 8000, 150, 0, n), 0.15, 1e-6);
  EXPECT_NEAR(tone_amplitude(sig.vibration.accel_ms2, 8000, 250, 0, n), 0.075, 1e-6);
  for (double f : {100.0, 200.0, 300.0, 350.0})
    EXPECT_LT(tone_amplitude(sig.vibration.accel_ms2, 8000, f, 0, n), 1e-6) << f << " Hz";
}

// The second form: a drive's switching carrier with two sidebands beside the mains lines, one source.
TEST(Effects, ElectricalInterferenceDriveCarrierWithSidebands) {
  Scenario s = rig();
  s.vibration.gmf_amplitudes.clear();
  s = with(s, EffectKind::kElectricalInterference,
           {{"frequency_hz", 50.0},
            {"amplitude_ms2", 0.3},
            {"harmonics", 1.0},
            {"pwm_hz", 3000.0},
            {"pwm_ms2", 0.2},
            {"pwm_side_hz", 120.0},
            {"pwm_side_rel", 0.25}});
  const SimulatedSignals sig = simulate_signals(s, 1);
  const auto n = static_cast<std::size_t>(s.sensor.fs_hz);
  const std::vector<double>& x = sig.vibration.accel_ms2;
  EXPECT_NEAR(tone_amplitude(x, 8000, 50, 0, n), 0.3, 1e-6);
  EXPECT_NEAR(tone_amplitude(x, 8000, 3000, 0, n), 0.2, 1e-6);
  EXPECT_NEAR(tone_amplitude(x, 8000, 2880, 0, n), 0.05, 1e-6);
  EXPECT_NEAR(tone_amplitude(x, 8000, 3120, 0, n), 0.05, 1e-6);
  for (double f : {100.0, 2760.0, 3240.0, 6000.0}) EXPECT_LT(tone_amplitude(x, 8000, f, 0, n), 1e-6) << f;
  // No sidebands with a spacing of 0: the carrier alone.
  s.effects[0].set("pwm_side_hz", 0.0);
  const SimulatedSignals one = simulate_signals(s, 1);
  EXPECT_NEAR(tone_amplitude(one.vibration.accel_ms2, 8000, 3000, 0, n), 0.2, 1e-6);
  EXPECT_LT(tone_amplitude(one.vibration.accel_ms2, 8000, 2880, 0, n), 1e-6);
}

// With pwm_ms2 = 0 (the default) the mains form simulates sample for sample as before the drive form
// existed (the carrier's phases are drawn after the mains lines'), and describes itself as before.
TEST(Effects, ElectricalInterferenceWithoutCarrierIsTheMainsFormUnchanged) {
  Scenario s = rig();
  s.vibration.noise_rms = 0.2;
  s = with(s, EffectKind::kElectricalInterference, {{"frequency_hz", 60.0}, {"amplitude_ms2", 0.3}});
  Scenario carrier_off = s;
  carrier_off.effects[0].set("pwm_hz", 2500.0);  // a frequency without strength adds nothing
  const SimulatedSignals a = simulate_signals(s, 7), b = simulate_signals(carrier_off, 7);
  ASSERT_EQ(a.vibration.accel_ms2.size(), b.vibration.accel_ms2.size());
  EXPECT_EQ(a.vibration.accel_ms2, b.vibration.accel_ms2);
  EXPECT_EQ(describe(s.effects[0]),
            "electrical_interference(frequency_hz=60, amplitude_ms2=0.3, harmonics=3, harmonic_decay=0.5, "
            "odd_only=0)");
  s.effects[0].set("pwm_ms2", 0.1);
  EXPECT_NE(describe(s.effects[0]).find("pwm_ms2=0.1"), std::string::npos) << describe(s.effects[0]);
}

TEST(EffectsScenario, DriveCarrierMustLieBelowNyquistAndAboveItsSidebands) {
  const std::string head = R"([motion]
via_points_rad = [0.0, 1.0]
max_speed_rad_s = 1.0
[sensor]
fs_hz = 8000.0
[[effects]]
kind = "electrical_interference"
pwm_ms2 = 0.1
)";
  EXPECT_NE(error_of(head + "pwm_hz = 4000.0\n").find("pwm_hz"), std::string::npos);
  EXPECT_NE(error_of(head + "pwm_hz = 0.0\n").find("pwm_hz"), std::string::npos);
  EXPECT_NE(error_of(head + "pwm_hz = 3000.0\npwm_side_hz = 3000.0\n").find("pwm_side_hz"),
            std::string::npos);
  EXPECT_EQ(error_of(head + "pwm_hz = 3000.0\npwm_side_hz = 150.0\n"), "");
  // Without strength the carrier's frequency is not checked (the mains form's default pwm_hz is 0).
  EXPECT_EQ(error_of("[motion]\nvia_points_rad = [0.0, 1.0]\nmax_speed_rad_s = 1.0\n[[effects]]\n"
                     "kind = \"electrical_interference\"\n"),
            "");
}

TEST(Effects, OtherAxisAddsAnOffOrderMesh) {
  const Scenario s = with(rig(), EffectKind::kOtherAxis,
                          {{"amplitude_ms2", 0.4}, {"frequency_ratio", 1.25}, {"lag_s", 0.0}});
  const SimulatedSignals sig = simulate_signals(s, 1);
  const auto n = static_cast<std::size_t>(s.sensor.fs_hz);
  EXPECT_NEAR(tone_amplitude(sig.vibration.accel_ms2, 8000, 750, 0, n), 0.4, 1e-3);  // 1.25 x 600 Hz
  EXPECT_NEAR(tone_amplitude(sig.vibration.accel_ms2, 8000, 600, 0, n), 1.0, 1e-3);
}

Scenario reciprocating(std::uint32_t cycles) {
  Scenario s;
  s.source = "test";
  s.motion.via_points_rad = {0.0, kPi, 0.0};
  s.motion.segment_speeds_rad_s = {3.49068, 3.49068};
  s.motion.accel_rad_s2 = 17.45;
  s.motion.cycles = cycles;
  s.motion.dwell_s = 0.4;
  s.motion.start_jitter_s = 0.0;
  s.motion.lead_in_s = 0.2;
  s.vibration.gmf_amplitudes = {1.0};
  s.vibration.reference_speed_rad_s = 3.49068;
  s.vibration.amplitude_speed_exponent = 0.0;
  s.vibration.noise_rms = 0.0;
  return s;
}

TEST(Effects, ImpactsAtTorqueReversals) {
  Scenario s = reciprocating(2);
  s.vibration.gmf_amplitudes.clear();
  s = with(s, EffectKind::kImpacts,
           {{"amplitude_ms2", 4.0}, {"resonance_hz", 3000.0}, {"damping_ratio", 0.05}});
  const SimulatedSignals sig = simulate_signals(s, 1);
  // Accel signs per cycle: + (start), - (braking and reversal at pi), + (braking back). The second
  // cycle starts with + after +: no reversal. 3 + 2 knocks.
  EXPECT_EQ(sig.vibration.effect_impacts, 5U);
  // The first knock rings right at the start of the motion (after the 0.2 s lead-in).
  double before = 0, after = 0;
  const auto i0 = static_cast<std::size_t>(0.2 * s.sensor.fs_hz);
  for (std::size_t i = i0 - 100; i < i0; ++i)
    before = std::max(before, std::fabs(sig.vibration.accel_ms2[i]));
  for (std::size_t i = i0; i < i0 + 100; ++i) after = std::max(after, std::fabs(sig.vibration.accel_ms2[i]));
  EXPECT_EQ(before, 0.0);
  EXPECT_GT(after, 3.0);
}

TEST(Effects, ImpactsAtStartsAndStopsOrBoth) {
  // Issue 11: a generator (or a machine) may knock where the motion starts from rest and where it stops,
  // not only where the torque reverses. reciprocating(2): each cycle starts from rest, reverses at pi
  // without resting, and stops back at 0 (the dwell).
  auto knocks = [](double events) {
    Scenario s = reciprocating(2);
    s.vibration.gmf_amplitudes.clear();
    s = with(s, EffectKind::kImpacts,
             {{"amplitude_ms2", 4.0},
              {"resonance_hz", 3000.0},
              {"damping_ratio", 0.05},
              {"knock_events", events}});
    return simulate_signals(s, 1).vibration.effect_impacts;
  };
  EXPECT_EQ(knocks(0.0), 5U);  // torque reversals (ImpactsAtTorqueReversals)
  EXPECT_EQ(knocks(1.0), 4U);  // one start and one stop per cycle
  // Both: per cycle the start (a reversal in the first cycle, counted once), the braking at pi, the
  // braking back and the stop.
  EXPECT_EQ(knocks(2.0), 8U);
}

TEST(Effects, ImpactsRingASecondModeAtItsRatioAndShare) {
  Scenario s = reciprocating(1);
  s.vibration.gmf_amplitudes.clear();
  const double fn_hz = 2000.0, zeta = 0.05, amp = 4.0;
  const Scenario one = with(s, EffectKind::kImpacts,
                            {{"amplitude_ms2", amp}, {"resonance_hz", fn_hz}, {"damping_ratio", zeta}});
  const Scenario two = with(s, EffectKind::kImpacts,
                            {{"amplitude_ms2", amp},
                             {"resonance_hz", fn_hz},
                             {"damping_ratio", zeta},
                             {"mode2_ratio", 2.5},
                             {"mode2_share", 0.5}});
  const SimulatedSignals a = simulate_signals(one, 1);
  const SimulatedSignals b = simulate_signals(two, 1);
  ASSERT_EQ(a.vibration.effect_impacts, b.vibration.effect_impacts);
  // The difference is the second mode alone: 0.5 amp exp(-zeta w2 t) sin(w2 sqrt(1 - zeta^2) t), w2 = 2.5
  // x 2 pi fn, from the first knock (the start of the motion after the 0.2 s lead-in; no mesh, no noise).
  const double fs = s.sensor.fs_hz;
  const double t_imp = 0.2;
  const auto i0 = static_cast<std::size_t>(std::ceil(t_imp * fs));
  const double w2 = 2.5 * 2.0 * kPi * fn_hz;
  double worst = 0.0, peak = 0.0;
  for (std::size_t i = i0; i < i0 + 200; ++i) {
    const double tau = static_cast<double>(i) / fs - t_imp;
    const double want =
        0.5 * amp * std::exp(-zeta * w2 * tau) * std::sin(w2 * std::sqrt(1.0 - zeta * zeta) * tau);
    const double got = b.vibration.accel_ms2[i] - a.vibration.accel_ms2[i];
    worst = std::max(worst, std::fabs(got - want));
    peak = std::max(peak, std::fabs(got));
  }
  EXPECT_GT(peak, 1.5);  // the second mode rings (0.5 x 4 m/s^2 at most)
  EXPECT_LT(worst, 1e-9);
  // Above 0.49 fs the second mode is not simulated.
  Scenario high = two;
  high.effects.back().set("mode2_ratio", 0.49 * fs / fn_hz + 0.01);
  EXPECT_EQ(simulate_signals(high, 1).vibration.accel_ms2, a.vibration.accel_ms2);
}

TEST(EffectsScenario, ImpactsSecondModeMustBeHigherAndItsKeysShowOnlyWhenOn) {
  const std::string head =
      "[motion]\nvia_points_rad = [0.0, 1.0]\nmax_speed_rad_s = 1.0\n[[effects]]\n"
      "kind = \"impacts\"\n";
  EXPECT_NE(error_of(head + "mode2_ratio = 0.8\n").find("mode2_ratio"), std::string::npos);
  EXPECT_EQ(error_of(head + "mode2_ratio = 1.8\n"), "");
  EXPECT_NE(error_of(head + "knock_events = 3\n").find("knock_events"), std::string::npos);
  // describe() keeps the one-mode text unless the second mode or other knock places are on.
  EffectSpec e = EffectSpec::with_defaults(EffectKind::kImpacts);
  EXPECT_EQ(describe(e), "impacts(amplitude_ms2=5, resonance_hz=4000, damping_ratio=0.05, rate_hz=0)");
  e.set("knock_events", 1.0);
  EXPECT_NE(describe(e).find("knock_events=1"), std::string::npos);
}

TEST(Effects, LoadDependenceScalesTheMeshByDirection) {
  const Scenario s =
      with(reciprocating(1), EffectKind::kLoadDependence, {{"direction_gain", 0.5}, {"accel_gain", 0.0}});
  const SimulatedSignals sig = simulate_signals(s, 1);
  double pos = 0, neg = 0;
  for (std::size_t i = 0; i < sig.codes.size(); ++i) {
    const double w = sig.motion.speed_rad_s[i];
    if (w > 3.4) pos = std::max(pos, std::fabs(sig.vibration.accel_ms2[i]));
    if (w < -3.4) neg = std::max(neg, std::fabs(sig.vibration.accel_ms2[i]));
  }
  EXPECT_NEAR(pos, 1.5, 1e-3);
  EXPECT_NEAR(neg, 0.5, 1e-3);
}

TEST(Effects, SpeedLatencyDelaysOnlyTheCanFrames) {
  const Scenario s = reciprocating(1);
  const SimulatedSignals a = simulate_signals(s, 3);
  const SimulatedSignals b =
      simulate_signals(with(s, EffectKind::kSpeedLatency, {{"delay_s", 0.025}, {"jitter_s", 0.0}}), 3);
  ASSERT_EQ(a.can.size(), b.can.size());
  for (std::size_t i = 0; i < a.can.size(); i += 97) {
    EXPECT_NEAR(static_cast<double>(b.can[i].frame.t_ns - a.can[i].frame.t_ns), 25e6, 1000.0);
  }
  EXPECT_EQ(a.codes, b.codes);  // the vibration is untouched
}

TEST(Effects, SpeedRippleSmearsTheMeshLine) {
  const Scenario s = with(rig(4.0), EffectKind::kSpeedRipple, {{"jitter_rad", 0.5}, {"bandwidth_hz", 20.0}});
  const SimulatedSignals sig = simulate_signals(s, 2);
  const auto n = static_cast<std::size_t>(s.sensor.fs_hz);
  double mean = 0;
  for (int b = 0; b < 4; ++b)
    mean += tone_amplitude(sig.vibration.accel_ms2, 8000, 600, static_cast<std::size_t>(b) * n, n) / 4;
  // Gaussian phase jitter of 0.5 rad rms keeps exp(-0.5^2 / 2) = 0.8825 of the line coherent.
  EXPECT_NEAR(mean, 0.8825, 0.04);
  const SimulatedSignals plain = simulate_signals(rig(4.0), 2);
  ASSERT_EQ(plain.can.size(), sig.can.size());
  EXPECT_EQ(plain.can[100].frame.data, sig.can[100].frame.data);  // the CAN speed does not show it
}

TEST(Effects, NoiseColorRaisesLowFrequencies) {
  Scenario s = rig(2.0);
  s.vibration.gmf_amplitudes.clear();
  s.vibration.noise_rms = 0.1;
  const SimulatedSignals a = simulate_signals(s, 4);
  const SimulatedSignals b =
      simulate_signals(with(s, EffectKind::kNoiseColor, {{"rms_ms2", 0.5}, {"corner_hz", 50.0}}), 4);
  const double low =
      band_power(b.vibration.accel_ms2, 8000, 10, 40) / band_power(a.vibration.accel_ms2, 8000, 10, 40);
  const double high = band_power(b.vibration.accel_ms2, 8000, 3000, 3100) /
                      band_power(a.vibration.accel_ms2, 8000, 3000, 3100);
  // Expected power ratio 1 + rms^2 |H(f)|^2 / sigma^2 for the one-pole y = a y + sqrt(1 - a^2) w:
  // |H|^2 = (1 - a^2) / |1 - a e^{-j w}|^2 (both noises are white before filtering, same bin scaling).
  auto expected_db = [](double f) {
    const double pole = std::exp(-2.0 * kPi * 50.0 / 8000.0);
    const double w = 2.0 * kPi * f / 8000.0;
    const double h2 =
        (1.0 - pole * pole) / (std::pow(1.0 - pole * std::cos(w), 2) + std::pow(pole * std::sin(w), 2));
    return 10.0 * std::log10(1.0 + 0.25 * h2 / 0.01);
  };
  EXPECT_NEAR(expected_db(3050.0), 1.948, 0.001);  // the formula at 3050 Hz
  EXPECT_NEAR(10.0 * std::log10(high), expected_db(3050.0), 0.5);
  EXPECT_GT(10.0 * std::log10(low), 20.0);  // about 29 dB at 25 Hz
}

TEST(Effects, NoiseColorWithTwoPolesFallsTwiceAsFast) {
  // poles = 2: the double pole's |H|^2 = (1 - a^2)^2 / (1 + a^2) / |1 - a e^{-jw}|^4, unit variance.
  Scenario s = rig(4.0);
  s.vibration.gmf_amplitudes.clear();
  s.vibration.noise_rms = 0.0;
  const SimulatedSignals b = simulate_signals(
      with(s, EffectKind::kNoiseColor, {{"rms_ms2", 0.5}, {"corner_hz", 50.0}, {"poles", 2.0}}), 4);
  double e = 0.0;
  for (double v : b.vibration.accel_ms2) e += v * v;
  // rms over 32000 samples of noise correlated over ~1 / (2 pi 50 Hz): a few % of sampling spread.
  EXPECT_NEAR(std::sqrt(e / static_cast<double>(b.vibration.accel_ms2.size())), 0.5, 0.05);
  auto h2 = [](double f) {
    const double a = std::exp(-2.0 * kPi * 50.0 / 8000.0);
    const double w = 2.0 * kPi * f / 8000.0;
    const double d2 = std::pow(1.0 - a * std::cos(w), 2) + std::pow(a * std::sin(w), 2);
    return (1.0 - a * a) * (1.0 - a * a) / (1.0 + a * a) / (d2 * d2);
  };
  // A decade above the corner and the next octave: ~ -40 dB/decade (12 dB per octave).
  const double p1 = band_power(b.vibration.accel_ms2, 8000, 480, 520);
  const double p2 = band_power(b.vibration.accel_ms2, 8000, 960, 1040);
  EXPECT_NEAR(10.0 * std::log10(h2(500.0) / h2(1000.0)), 11.64, 0.01);  // the formula at fs 8 kHz
  EXPECT_NEAR(10.0 * std::log10(p1 / p2), 10.0 * std::log10(h2(500.0) / h2(1000.0)), 1.0);
}

TEST(Effects, DeterministicForASeed) {
  const Scenario s =
      with(with(rig(), EffectKind::kSpeedRipple, {}), EffectKind::kImpacts, {{"rate_hz", 3.0}});
  EXPECT_EQ(simulate_signals(s, 9).codes, simulate_signals(s, 9).codes);
  EXPECT_NE(simulate_signals(s, 9).codes, simulate_signals(s, 10).codes);
}

}  // namespace
}  // namespace ptda::sim
