// Internals shared by the simulator's translation units (not installed).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "ptda/sim/random.hpp"
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

/// What regenerates an lspb motion plan cycle by cycle (MotionProfile::lazy).
struct LazyMotionPlan {
  MotionSpec motion;
  DriftSpec drift;
  CyclePlan plan;
  std::uint64_t seed = 0;
};

/// The cycles of an lspb plan in order, as build_motion_plan lays them out: a pause (drift), the start
/// jitter wait, the cycle's pieces, the dwell; cycle 0 starts with the lead-in.
class CycleWalker {
 public:
  explicit CycleWalker(const LazyMotionPlan& lp);
  /// The next cycle (its pause start, if any, in *pause_start_s); false after the last one.
  bool next(PlanCycle& out, double* pause_start_s = nullptr);
  /// End of what has been walked (the duration once next() returned false).
  [[nodiscard]] double t_s() const noexcept { return t_; }

 private:
  const LazyMotionPlan* lp_;
  Rng rng_;
  double t_ = 0.0;
  double angle_ = 0.0;
  std::uint32_t c_ = 0;
};

/// PRNG stream ids (one per independent kind of draw).
inline constexpr std::uint64_t kStreamJitter = 1;
inline constexpr std::uint64_t kStreamNoise = 2;
inline constexpr std::uint64_t kStreamCan = 3;
inline constexpr std::uint64_t kStreamOtherFrames = 4;
inline constexpr std::uint64_t kStreamCycleAmplitude = 5;
inline constexpr std::uint64_t kStreamCycleNoise = 6;
/// Effect i of the scenario draws from stream kStreamEffectBase + i.
inline constexpr std::uint64_t kStreamEffectBase = 100;

// ---- ringing (sim/src/vibration.cpp) -------------------------------------------------------

/// A damped ringing A e^{-zeta wn tau} sin(wd tau) starting at t_imp_s, cut where its envelope has decayed
/// to 1e-6: the terms the whole-signal add_ringing() adds, kept so that they can be added block by block.
struct Ringing {
  std::size_t n0 = 0;  ///< first sample, ceil(t_imp_s * fs)
  double t_imp_s = 0.0;
  double amplitude = 0.0;
  double sigma = 0.0;       ///< zeta wn
  double wd = 0.0;          ///< damped angular frequency
  double amplitude2 = 0.0;  ///< a second, higher mode (impacts' mode2); 0: none
  double sigma2 = 0.0;
  double wd2 = 0.0;
  double t_end_s = 0.0;
};
/// mode2_ratio > 0: a second mode at mode2_ratio * resonance_hz with amplitude mode2_share * amplitude and
/// the same damping ratio; left out at or above 0.49 fs_hz (the anti-alias filter's side).
[[nodiscard]] Ringing make_ringing(double fs_hz, double t_imp_s, double amplitude, double resonance_hz,
                                   double damping_ratio, double mode2_ratio = 0.0,
                                   double mode2_share = 0.0) noexcept;

/// The ringings of one source (a tooth fault, the reversal knocks, the random knocks), added to each
/// sample in the order they were scheduled, as the whole-signal code adds them one after the other.
class RingingSet {
 public:
  void add(const Ringing& r) { active_.push_back(r); }
  /// Adds the terms falling on samples [i0, i0 + x.size()) (x[0] is sample i0) of a recording of n_total
  /// samples; blocks must come in order. Drops the ringings that have ended.
  void apply(std::size_t i0, std::span<double> x, double fs_hz, std::size_t n_total);

 private:
  std::vector<Ringing> active_;
};

// ---- effects (sim/src/effects_apply.cpp) ------------------------------------------------------

/// Per-sample changes of the GMF mesh by speed_ripple, mesh_modulation and load_dependence, sample by
/// sample from 0. off() when no such effect is on (the mesh is then computed exactly as without effects).
class MeshPerturber {
 public:
  MeshPerturber(const Scenario& s, double fs_hz, std::uint64_t seed);
  [[nodiscard]] bool on() const noexcept { return !parts_.empty(); }
  /// Offset added to the input angle the GMF harmonics follow and the gain on the GMF part of the mesh,
  /// for the next sample (samples in order).
  void next(const MotionState& st, double& theta_in_offset_rad, double& gain) noexcept;

 private:
  struct Part {
    Part(EffectKind k, const Rng& r) : kind(k), rng(r) {}
    EffectKind kind;
    Rng rng;
    double a = 0.0, b = 0.0, state = 0.0, scale = 0.0;  // speed_ripple: low-passed noise
    double rate = 0.0, am = 0.0, pm = 0.0;              // mesh_modulation
    double g_dir = 0.0, g_acc = 0.0;                    // load_dependence
  };
  std::vector<Part> parts_;
  double ratio_ = 0.0;
};

/// The signal effects, block by block: adds impacts, other_axis and noise_color, then applies
/// transfer_path, then adds electrical_interference, then clamps for adc_clipping (in scenario order
/// within each step), giving to every sample what the whole-signal code gives it.
class SignalEffects {
 public:
  /// `m` (a plan is enough: pieces, duration) must outlive this object.
  SignalEffects(const Scenario& s, const MotionProfile& m, std::uint64_t seed);
  ~SignalEffects();
  SignalEffects(const SignalEffects&) = delete;
  SignalEffects& operator=(const SignalEffects&) = delete;
  /// x = samples [i0, i0 + x.size()) of the vibration (mesh, noise, fault ringings); blocks in order.
  void apply(std::size_t i0, std::span<double> x);
  /// Counts the knocks scheduled after the last sample (the whole-signal code counts every one).
  void finish();
  [[nodiscard]] std::uint64_t impacts() const noexcept { return impacts_; }
  [[nodiscard]] std::uint64_t clipped_samples() const noexcept { return clipped_; }

 private:
  struct Step;
  void schedule(std::size_t i_end);
  const Scenario* s_;
  const MotionProfile* m_;
  std::size_t n_total_ = 0;
  std::vector<Step> steps_;
  std::uint64_t impacts_ = 0;
  std::uint64_t clipped_ = 0;
};

}  // namespace ptda::sim
