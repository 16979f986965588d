// The small joint-rotation job the gap unit tests simulate: out and back over pi at 3.49 rad/s (the paper's
// joint rotation plateau), Table 1 harmonic pattern up to order 8, 0.3 m/s^2 noise; and the options and
// effects the diagnosis tests share. Test helpers.
#pragma once

#include <cstdint>
#include <initializer_list>
#include <numbers>

#include "ptda/gap/diagnose.hpp"
#include "ptda/sim/simulator.hpp"

namespace ptda::gap::test {

inline sim::Scenario joint_rotation_job(std::uint32_t cycles) {
  sim::Scenario s;
  s.source = "test";
  s.name = "test_job";
  s.motion.via_points_rad = {0.0, std::numbers::pi, 0.0};
  s.motion.segment_speeds_rad_s = {3.49068, 3.49068};
  s.motion.accel_rad_s2 = 17.45;
  s.motion.cycles = cycles;
  s.motion.dwell_s = 0.4;
  s.vibration.gmf_amplitudes = {0.43, 0.0, 0.0, 0.48, 1.40, 0.0, 1.10, 1.60};
  s.vibration.reference_speed_rad_s = 3.49068;
  s.vibration.noise_rms = 0.3;
  s.sensor.range_ms2 = 50.0;
  return s;
}

/// Options that let the diagnosis name at most one effect, of the given kinds only.
inline DiagnoseOptions one_effect_of(std::initializer_list<sim::EffectKind> kinds) {
  DiagnoseOptions opt;
  opt.candidates = kinds;
  opt.max_effects = 1;
  return opt;
}

/// Coloured noise of `rms_ms2` below `corner_hz` with `poles` poles.
inline sim::EffectSpec noise_color(double rms_ms2, double corner_hz, double poles) {
  sim::EffectSpec e = sim::EffectSpec::with_defaults(sim::EffectKind::kNoiseColor);
  e.set("rms_ms2", rms_ms2);
  e.set("corner_hz", corner_hz);
  e.set("poles", poles);
  return e;
}

}  // namespace ptda::gap::test
