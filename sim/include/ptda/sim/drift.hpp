// Slow healthy drift of the simulated gearbox ([drift] in a scenario; docs/simulator.md, "Slow drift"):
// a slow load/temperature cycle (mesh stiffness: mesh amplitude and structural resonance), the
// lubricant warm-up after a cold start (mesh amplitude and churning noise), and program pauses during
// which the gearbox cools down again. Everything is a closed form of the time, so a long run can be
// generated as consecutive recordings that continue one another (time_offset_s, initial_coldness).
#pragma once

#include <cstdint>
#include <vector>

namespace ptda::sim {

/// [drift]. All defaults are off: a scenario without the table is simulated exactly as before.
struct DriftSpec {
  /// Drift time of sample 0 (s): lets consecutive recordings continue one drift programme.
  double time_offset_s = 0.0;
  // --- slow load / temperature cycle: L(t) = sin(2 pi (t + time_offset_s) / load_period_s + load_phase_rad)
  double load_period_s = 0.0;        ///< 0: off
  double load_phase_rad = 0.0;       ///< phase of L at drift time 0
  double mesh_amplitude_rel = 0.0;   ///< mesh (GMF and DMF) amplitude x (1 + rel L(t)); 0.3 = +-30 %
  double resonance_shift_rel = 0.0;  ///< tooth-impact resonance x (1 + rel L(t))
  // --- lubricant warm-up: coldness c(t) in [0, 1] (1 = cold start, 0 = warm) ---
  double warmup_tau_s = 0.0;        ///< while the joint works, c decays as e^{-t/tau}; 0: off
  double initial_coldness = 1.0;    ///< c at sample 0
  double cold_amplitude_rel = 0.0;  ///< mesh amplitude x (1 + rel c(t)) (cold, viscous oil damps: < 0)
  double cold_noise_rel = 0.0;      ///< noise rms x (1 + rel c(t)) (churning of cold oil: > 0)
  double cooldown_tau_s = 0.0;      ///< in a program pause c rises as 1 - (1 - c0) e^{-t/tau}; 0: no cooling
  // --- program pauses (lspb motion only): the robot stands still for pause_s before every
  //     pause_every_cycles-th cycle (cycles pause_every_cycles, 2 pause_every_cycles, ...) ---
  std::uint32_t pause_every_cycles = 0;  ///< 0: off
  double pause_s = 0.0;

  [[nodiscard]] bool load_on() const noexcept { return load_period_s > 0.0; }
  [[nodiscard]] bool warmup_on() const noexcept { return warmup_tau_s > 0.0; }
  [[nodiscard]] bool pauses_on() const noexcept { return pause_every_cycles > 0 && pause_s > 0.0; }
  /// Any drift at all (the vibration and truth.toml are unchanged when false). Any thread.
  [[nodiscard]] bool on() const noexcept { return load_on() || warmup_on() || pauses_on(); }
};

/// The drift's factors at one instant.
struct DriftFactors {
  double load = 0.0;              ///< L(t) in [-1, 1]
  double coldness = 0.0;          ///< c(t) in [0, 1] (0 when the warm-up is off)
  double mesh_gain = 1.0;         ///< (1 + mesh_amplitude_rel L)(1 + cold_amplitude_rel c)
  double noise_gain = 1.0;        ///< 1 + cold_noise_rel c
  double resonance_factor = 1.0;  ///< 1 + resonance_shift_rel L
};

/// Evaluates the drift of one recording: the closed forms above, with the coldness piecewise between
/// the program pauses (exponential decay while working, exponential recovery towards 1 in a pause).
class DriftModel {
 public:
  /// `pause_start_s`: start of each program pause (from sample 0, ascending; MotionProfile), each
  /// spec.pause_s long. Any thread; allocates.
  DriftModel(const DriftSpec& spec, const std::vector<double>& pause_start_s);
  /// Factors at t_s from sample 0 (t_s >= 0). Any thread; no allocation.
  [[nodiscard]] DriftFactors at(double t_s) const noexcept;
  /// Coldness alone (the `coldness` of at()). Any thread; no allocation.
  [[nodiscard]] double coldness_at(double t_s) const noexcept;

 private:
  DriftSpec spec_;
  // Coldness segments: [start_s[j], start_s[j+1]) with coldness c0[j] at the start; paused[j] is true
  // inside a pause.
  std::vector<double> start_s_;
  std::vector<double> c0_;
  std::vector<bool> paused_;
};

}  // namespace ptda::sim
