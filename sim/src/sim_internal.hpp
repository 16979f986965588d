// Internals shared by the simulator's translation units (not installed).
#pragma once

#include <cstdint>
#include <vector>

#include "ptda/sim/simulator.hpp"

namespace ptda::sim {

/// One job cycle's motion in cycle-local time (t = 0 at the first via point), starting at rest.
struct CyclePlan {
  std::vector<MotionPiece> pieces;  ///< angle0_rad relative to via point 0; cycle field unused
  std::vector<Plateau> plateaus;    ///< linear (constant-speed) parts, cycle-local times
  double duration_s = 0.0;          ///< first to last via point
};

/// Plans one cycle with Craig's LSPB through the via points. Throws ptda::Error (plain message, no
/// location) when a segment is too short for the acceleration limit.
[[nodiscard]] CyclePlan plan_cycle(const MotionSpec& m);

/// PRNG stream ids (one per independent kind of draw).
inline constexpr std::uint64_t kStreamJitter = 1;
inline constexpr std::uint64_t kStreamNoise = 2;
inline constexpr std::uint64_t kStreamCan = 3;
inline constexpr std::uint64_t kStreamOtherFrames = 4;
inline constexpr std::uint64_t kStreamCycleAmplitude = 5;
inline constexpr std::uint64_t kStreamCycleNoise = 6;
/// Effect i of the scenario draws from stream kStreamEffectBase + i.
inline constexpr std::uint64_t kStreamEffectBase = 100;

// ---- effects (sim/src/effects_apply.cpp) ------------------------------------------------------

/// Per-sample changes of the GMF mesh by speed_ripple, mesh_modulation and load_dependence. Empty
/// vectors when no such effect is on (the mesh is then computed exactly as without effects).
struct MeshPerturbation {
  std::vector<double> theta_in_offset_rad;  ///< added to the input angle the GMF harmonics follow
  std::vector<double> gain;                 ///< multiplies the GMF part of the mesh
};
[[nodiscard]] MeshPerturbation mesh_perturbation(const Scenario& s, const MotionProfile& m,
                                                 std::uint64_t seed);

/// Adds impacts, other_axis and noise_color, then applies transfer_path, then adds
/// electrical_interference, then clamps for adc_clipping (in scenario order within each step).
void apply_signal_effects(const Scenario& s, const MotionProfile& m, std::uint64_t seed, Vibration& v);

/// Sample-clock and CAN-latency effects act on the scenario: `for_motion` has the ADC's true rate (motion
/// and vibration are generated on the true sample grid), `for_can` the extra CAN delay/jitter.
void timing_scenarios(const Scenario& s, Scenario& for_motion, Scenario& for_can);

/// Adds a damped ringing A e^{-zeta wn tau} sin(wd tau) starting at t_imp_s (vibration.cpp).
void add_ringing(std::vector<double>& x, double fs_hz, double t_imp_s, double amplitude, double resonance_hz,
                 double damping_ratio);

}  // namespace ptda::sim
