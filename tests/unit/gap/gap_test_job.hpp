// The small joint-rotation job the gap unit tests simulate: out and back over pi at 3.49 rad/s (the paper's
// joint rotation plateau), Table 1 harmonic pattern up to order 8, 0.3 m/s^2 noise. Test helper.
#pragma once

#include <cstdint>
#include <numbers>

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

}  // namespace ptda::gap::test
