// Joint + gearbox + sensor + CAN simulator: turns a scenario file into a recording directory
// (recording.toml, vibration.wav, can.log) plus truth.toml (what was simulated; no analysis reads it).
// Model and keys: docs/simulator.md; commented examples: config/scenarios/*.toml.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "ptda/config/speed_codec.hpp"
#include "ptda/dsp/baseline.hpp"
#include "ptda/formats/wav.hpp"
#include "ptda/sim/drift.hpp"
#include "ptda/sim/effects.hpp"

namespace ptda::sim {

// ------------------------------------------------------------------------------------------------
// Scenario: everything a scenario file describes. Defaults are the documented defaults of the keys.

/// [motion]: how joint 4 (or the input shaft of a parallel stage) moves.
enum class MotionKind : std::uint8_t {
  kLspb,      ///< via points joined by linear segments with parabolic blends, repeated as job cycles
  kConstant,  ///< constant shaft speed for the whole recording (test rigs)
  /// Follows a measured speed trace (in memory only, not a scenario key: `ptda gap` drives its model
  /// along a recording's own CAN speed, docs/gap.md "Method"). See MotionSpec::measured_*.
  kMeasured,
};

struct MotionSpec {
  MotionKind kind = MotionKind::kLspb;
  // --- kLspb ---
  std::vector<double> via_points_rad;  ///< joint angles visited in order (>= 2)
  // Exactly one of the next three sets the timing (Craig's LSPB with via points):
  std::vector<double> segment_durations_s;   ///< via-to-via time of each segment (via_points - 1)
  std::vector<double> segment_speeds_rad_s;  ///< cruise speed magnitude of each segment
  double max_speed_rad_s = 0.0;              ///< one cruise speed for every segment
  double accel_rad_s2 = 10.0;                ///< blend acceleration (magnitude)
  double dwell_s = 0.5;                      ///< standstill at the end of each cycle
  std::uint32_t cycles = 20;                 ///< job repetitions
  double start_jitter_s = 0.05;              ///< uniform random extra dwell [0, jitter) before each cycle
  double lead_in_s = 0.2;                    ///< standstill before the first cycle
  // --- kConstant ---
  double shaft_speed_hz = 0.0;  ///< input-shaft rotation frequency (kConstant; sign = direction)
  double duration_s = 0.0;      ///< recording length (kConstant, kMeasured), split into `cycles` blocks
  // --- kMeasured ---
  /// Instants of the measured output speed, seconds from sample 0 on the true (CAN log) time base,
  /// strictly ascending; the speed is interpolated linearly between them and held before the first and
  /// after the last. At least 2.
  std::vector<double> measured_t_s;
  std::vector<double> measured_speed_rad_s;  ///< signed output speed at measured_t_s
  /// Start of each job cycle (ascending; cycle c from [c] to [c + 1]); empty: one cycle.
  std::vector<double> measured_cycle_start_s;
};

/// [gearbox]
enum class GearboxKind : std::uint8_t {
  kCycloidal,  ///< RV-type: spur (involute) stage Z_in -> Z_spur, then cycloid with Z_pin pins
  kParallel,   ///< one parallel-axis stage: pinion (input) -> gear
};

struct GearboxSpec {
  GearboxKind kind = GearboxKind::kCycloidal;
  std::uint32_t z_in = 28;    ///< input pinion teeth (cycloidal) / pinion teeth (parallel)
  std::uint32_t z_spur = 23;  ///< spur gear teeth (cycloidal) / driven gear teeth (parallel)
  std::uint32_t z_pin = 40;   ///< ring pins (cycloidal only)
};

/// Reduction ratio input speed / output speed (0 when z_in is 0). Cycloidal: eq. 1, R = 1 + Z_spur/Z_in *
/// Z_pin. Parallel: Z_gear / Z_pinion. Any thread; no allocation.
[[nodiscard]] double reduction_ratio(const GearboxSpec& g) noexcept;
/// Gear mesh frequency (eq. 3, Z_in * f_in) for an output (joint) speed. Any thread.
[[nodiscard]] double gmf_hz(const GearboxSpec& g, double output_speed_rad_s) noexcept;
/// Cycloid (pin) mesh frequency (eq. 4, Z_pin * f_out); 0 for a parallel stage. Any thread.
[[nodiscard]] double dmf_hz(const GearboxSpec& g, double output_speed_rad_s) noexcept;

/// [vibration]: the healthy signal at the sensor, in m/s^2.
struct VibrationSpec {
  std::vector<double> gmf_amplitudes;     ///< amplitude of GMF harmonic k = 1..n at reference speed
  std::vector<double> gmf_phases_rad;     ///< phi_k (empty: all 0; else one per amplitude)
  double reference_speed_rad_s = 1.0;     ///< output speed where the amplitudes apply
  double amplitude_speed_exponent = 1.0;  ///< A_k(w) = A_k * (|w| / w_ref)^exponent
  std::vector<double> dmf_amplitudes;     ///< cycloid mesh harmonics (small), same speed law
  double noise_rms = 0.05;                ///< Gaussian background (white, or its level at the tilt's pivot)
  /// Spectral tilt of the background: its PSD changes by this many dB per decade, with noise_rms kept
  /// as the white level at noise_tilt_pivot_hz(fs) (ptda/sim/noise_tilt.hpp). 0: white. |tilt| <= 18.
  double noise_tilt_db_per_decade = 0.0;
  /// Known shape of the background's PSD on top of the tilt (a machine's or rig's own floor, read off a
  /// healthy recording at commissioning): dB at the frequencies noise_shape_hz (increasing, > 0),
  /// interpolated linearly in log frequency, flat beyond the ends; relative values (the shape is
  /// referred to its value at the tilt's pivot, so noise_rms keeps its meaning). Empty: no shape.
  std::vector<double> noise_shape_hz;
  std::vector<double> noise_shape_db;  ///< one per entry of noise_shape_hz, each in [-60, 60]
  /// Lines at whole orders of the input shaft that are not GMF harmonics (unbalance, run-out, a second
  /// shaft or belt, the GFD rig's multiples of 5): sin(order * theta_in), amplitude at the reference
  /// speed with the mesh's speed law. Orders must be > 0, distinct and not multiples of z_in.
  std::vector<int> shaft_orders;
  std::vector<double> shaft_order_amplitudes;  ///< one per entry of shaft_orders
  /// Cycle-to-cycle variation of the mesh (payload, temperature, lubrication, load sharing): in job
  /// cycle c, GMF entry k is multiplied by exp(rel * z_ck), z_ck ~ N(0, 1) independent per cycle and
  /// entry (log-normal: median 1, relative spread ~rel). 0: off, every cycle has the same amplitudes.
  double cycle_amplitude_jitter_rel = 0.0;
  /// The same for the background noise level: noise_rms times exp(rel * z_c) in cycle c. 0: off.
  double cycle_noise_jitter_rel = 0.0;
};

/// [[fault]]
enum class FaultKind : std::uint8_t {
  kSpurTooth,        ///< localised tooth defect on a spur gear: impulses once per spur rev + mesh AM
  kDistributedWear,  ///< raises GMF harmonic amplitudes and the noise level
};

struct FaultSpec {
  FaultKind kind = FaultKind::kSpurTooth;
  double severity = 1.0;          ///< final severity 0..1
  std::uint32_t onset_cycle = 0;  ///< first cycle (0-based) with the fault
  std::uint32_t ramp_cycles = 0;  ///< severity grows linearly over this many cycles (0: step)
  // kSpurTooth
  double impulse_amplitude_ms2 = 2.0;  ///< ringing amplitude at severity 1 and reference speed
  double resonance_hz = 3000.0;
  double damping_ratio = 0.05;
  double am_depth = 0.2;        ///< mesh amplitude modulation depth at severity 1
  double spur_phase_rad = 0.0;  ///< spur-gear angle of the defect
  // kDistributedWear
  double harmonic_gain = 0.5;  ///< harmonic amplitudes * (1 + gain * severity)
  double noise_gain = 0.5;     ///< noise rms * (1 + gain * severity)
};

/// [sensor]
struct SensorSpec {
  double fs_hz = 25600.0;
  double sensitivity_v_per_ms2 = 0.0102;  ///< informational (100 mV/g)
  double range_ms2 = 490.0;               ///< +-range: values beyond are clipped
  formats::WavSampleFormat format = formats::WavSampleFormat::kPcm24;
};

/// [can]
struct CanSpec {
  config::SpeedFrameSpec speed_frame;    ///< [can.speed_frame]; its period_s is set from [can] period_s
  double period_s = 0.004;               ///< controller clock period (nominal)
  double clock_offset_s = 0.0013;        ///< controller clock phase relative to sample 0
  double clock_drift_ppm = 0.0;          ///< controller clock rate error
  double delay_s = 0.0005;               ///< transport delay added to the log timestamps
  double jitter_s = 0.0001;              ///< uniform [0, jitter) added to each timestamp
  std::uint32_t other_frames_per_s = 0;  ///< unrelated frames (ids 0x080..) on the bus
  std::string iface = "can0";
  /// Nominal models only (`ptda gap`): relative uncertainty of the speed frames' scale against the shaft's
  /// true speed (a drive that slips under load, a log whose speed was written from a nominal). 0: the
  /// frames' speed is exact. The simulator ignores it.
  double speed_scale_tolerance = 0.0;
  /// Nominal models only: the shaft can only lag its frames, never lead them (an induction motor's slip
  /// under load, frames that carry the drive's set speed). A shaft that turns faster than the frames is
  /// then not calibration: the frames are not scaled up, and the offset is left to the effects (a
  /// sample-clock error explains it). Needs speed_scale_tolerance > 0.
  bool speed_scale_slip_only = false;
};

struct Scenario {
  std::string name;
  std::string description;
  std::uint64_t seed = 1;
  double start_time_s = 1.7e9;  ///< UNIX seconds of sample 0
  MotionSpec motion;
  GearboxSpec gearbox;
  VibrationSpec vibration;
  std::vector<FaultSpec> faults;
  std::vector<EffectSpec> effects;  ///< [[effects]]: sim-to-real additions (sim/include/ptda/sim/effects.hpp)
  DriftSpec drift;  ///< [drift]: slow healthy drift (sim/include/ptda/sim/drift.hpp); off by default
  SensorSpec sensor;
  CanSpec can;
  std::string source;  ///< where it was read from (for messages)
  /// Accepted but deprecated spellings, one "file:line:col: what to write instead" each (printed as
  /// warnings by the tools that read scenarios).
  std::vector<std::string> warnings;
};

/// The gearbox as the analysis side describes it (for baselines/reports). Any thread; no allocation.
[[nodiscard]] dsp::GearboxInfo to_gearbox_info(const GearboxSpec& g) noexcept;

/// Parses scenario TOML. Unknown keys, wrong types and inconsistent values are errors:
/// throws ptda::Error "<source>:<line>:<column>: <what>". Any thread; allocates.
[[nodiscard]] Scenario parse_scenario(std::string_view toml_text, const std::string& source);
/// Reads and parses a scenario file. Throws ptda::Error (naming the path). Any thread; allocates.
[[nodiscard]] Scenario load_scenario(const std::filesystem::path& path);

// ------------------------------------------------------------------------------------------------
// In-memory pieces (used by simulate_to_directory and by tests).

/// One constant-speed plateau of the joint profile (truth).
struct Plateau {
  std::uint32_t cycle = 0;
  double t_start_s = 0.0;  ///< from sample 0
  double t_end_s = 0.0;
  double speed_rad_s = 0.0;  ///< signed output speed
};

/// A piece of constant acceleration of the output (joint) motion: exact, used for CAN sampling.
struct MotionPiece {
  double t0_s = 0.0;  ///< from sample 0
  double t1_s = 0.0;
  double angle0_rad = 0.0;    ///< output angle at t0_s
  double speed0_rad_s = 0.0;  ///< output speed at t0_s
  double accel_rad_s2 = 0.0;
  std::uint32_t cycle = 0;
};

struct MotionState {
  double angle_rad = 0.0;
  double speed_rad_s = 0.0;
  double accel_rad_s2 = 0.0;
  std::uint32_t cycle = 0;
};

struct LazyMotionPlan;  // sim/src/sim_internal.hpp

/// Output (joint) motion sampled on the ADC clock plus its plateaus.
struct MotionProfile {
  double fs_hz = 0.0;
  std::vector<double> angle_rad;     ///< output angle per sample
  std::vector<double> speed_rad_s;   ///< output speed per sample
  std::vector<double> accel_rad_s2;  ///< output acceleration per sample
  std::vector<std::uint32_t>
      cycle;  ///< job cycle per sample (lead-in: 0; jitter wait and dwell: their cycle)
  std::vector<double> cycle_start_s;  ///< start time of each cycle's motion
  std::vector<Plateau> plateaus;
  std::vector<MotionPiece> pieces;    ///< contiguous, covering [0, duration_s]
  std::vector<double> pause_start_s;  ///< program pauses ([drift] pause_every_cycles), each pause_s long
  std::uint32_t cycles = 0;
  double duration_s = 0.0;
  /// Set by build_motion_lazy(): pieces, plateaus and cycle_start_s stay empty and are regenerated cycle
  /// by cycle, in order, by PieceCursor and for_each_cycle() (what a streamed simulation reads).
  std::shared_ptr<const LazyMotionPlan> lazy;
};

/// One job cycle of a motion plan, in order (for_each_cycle).
struct PlanCycle {
  std::uint32_t cycle = 0;
  double start_s = 0.0;             ///< cycle_start_s[cycle]
  std::vector<MotionPiece> pieces;  ///< its pieces (cycle 0 starts with the lead-in)
  std::vector<Plateau> plateaus;    ///< its plateaus
};

/// Calls fn(const PlanCycle&) for each cycle of the plan in order (stored or lazy); stops when fn
/// returns false. Any thread; allocates (one cycle at a time).
void for_each_cycle(const MotionProfile& m, const std::function<bool(const PlanCycle&)>& fn);

/// The plan's pieces one after the other (stored or regenerated). Thread: the owner's; allocates only
/// one cycle's pieces at a time.
class PieceCursor {
 public:
  explicit PieceCursor(const MotionProfile& m);
  ~PieceCursor();
  PieceCursor(PieceCursor&&) noexcept;
  PieceCursor& operator=(PieceCursor&&) noexcept;
  /// The current piece (the first one after construction). Needs at least one piece.
  [[nodiscard]] const MotionPiece& current() const noexcept;
  /// Whether a piece follows the current one.
  [[nodiscard]] bool has_next();
  /// Moves to the next piece (has_next() must be true).
  void advance();

 private:
  struct Walk;
  const MotionProfile* m_;
  std::size_t k_ = 0;           // stored pieces: index
  std::unique_ptr<Walk> walk_;  // lazy: the cycles being regenerated
};

/// Dead band (rad/s^2) below which an interval of a measured speed trace counts as constant speed:
/// max(0.2 x the 99th percentile of the intervals' |acceleration|, 0.02 x the top |speed| per second).
/// Any thread; allocates.
[[nodiscard]] double measured_motion_deadband(const std::vector<double>& t_s,
                                              const std::vector<double>& speed_rad_s);

/// Exact motion at t_s (clamped to [0, duration_s]). Any thread; no allocation.
[[nodiscard]] MotionState motion_at(const MotionProfile& m, double t_s) noexcept;

/// Builds the motion (analytic LSPB / constant speed / measured trace) sampled at fs_hz. Jitter draws
/// from seed. A measured trace becomes constant-acceleration pieces between its instants (the angle is
/// the exact integral of the pieces' speed); an interval whose acceleration is below the trace's dead
/// band (measured_motion_deadband()) becomes a constant-speed piece at the interval's mean speed, so that
/// CAN quantisation and small ripple do not count as torque reversals. At the measured instants the
/// motion's speed then differs from the trace by at most half the dead band times the interval.
/// Throws ptda::Error when the motion is infeasible or the trace is malformed. Any thread; allocates.
[[nodiscard]] MotionProfile build_motion(const Scenario& s, std::uint64_t seed);
/// build_motion without the per-sample arrays (angle_rad, speed_rad_s, accel_rad_s2 and cycle stay
/// empty): the pieces, plateaus, cycle starts, pauses and duration, for the streaming synthesis
/// (sim/include/ptda/sim/stream.hpp). Same throws. Any thread; allocates (O(cycles), not O(samples)).
[[nodiscard]] MotionProfile build_motion_plan(const Scenario& s, std::uint64_t seed);
/// Samples of a motion: round(duration_s * fs_hz) (the size of build_motion's arrays). Any thread.
[[nodiscard]] std::size_t motion_samples(const MotionProfile& m) noexcept;
/// Largest |speed| over the sample grid: from speed_rad_s when filled, else sampled from the pieces
/// (the same values). Any thread; no allocation.
[[nodiscard]] double max_abs_speed_rad_s(const MotionProfile& m);

/// The motion of a plan on the sample grid, sample by sample (exactly the values build_motion stores).
/// Keeps a cursor into m.pieces: the indices passed to at() must not decrease. `m` must outlive it.
/// Thread: the owner's; no allocation.
class MotionSampler {
 public:
  explicit MotionSampler(const MotionProfile& m) : fs_hz_(m.fs_hz), pieces_(m) {}
  /// Motion at sample i (time i / fs_hz). Needs at least one piece.
  [[nodiscard]] MotionState at(std::size_t i);

 private:
  double fs_hz_;
  PieceCursor pieces_;
};

/// build_motion_plan for a streamed simulation: an lspb motion's pieces, plateaus and cycle starts are
/// not stored but regenerated in order (MotionProfile::lazy; the same values), so that the plan's memory
/// does not grow with the cycles; pause_start_s, cycles and duration_s are filled. Other motion kinds:
/// build_motion_plan. Any thread; allocates.
[[nodiscard]] MotionProfile build_motion_lazy(const Scenario& s, std::uint64_t seed);
/// Motion at t_s (clamped to [0, duration_s]) through a cursor: motion_at() for times that do not
/// decrease between calls, also on a lazy plan. Thread: the cursor's owner; no allocation per call
/// beyond the cursor's cycle.
[[nodiscard]] MotionState motion_at(const MotionProfile& m, PieceCursor& cursor, double t_s);

/// Severity of fault f in job cycle `cycle`: 0 before onset_cycle, then
/// severity * min(1, (cycle - onset + 1) / ramp_cycles) (a step when ramp_cycles = 0). Any thread; no
/// allocation.
[[nodiscard]] double fault_severity(const FaultSpec& f, std::uint32_t cycle) noexcept;

/// The per-cycle factors of VibrationSpec's cycle variation (truth). Each kind is drawn from its own
/// random stream, so switching one on changes neither the other nor the noise, jitter or CAN draws.
struct CycleVariation {
  /// [cycle][k]: multiplies gmf_amplitudes[k] in that cycle (one entry per gmf_amplitudes entry, zeros
  /// and omitted orders included). Empty when cycle_amplitude_jitter_rel is 0.
  std::vector<std::vector<double>> amplitude_factors;
  /// [cycle]: multiplies noise_rms in that cycle. Empty when cycle_noise_jitter_rel is 0.
  std::vector<double> noise_factors;
};

/// Draws the cycle variation for `cycles` job cycles. Deterministic from seed. Any thread; allocates.
[[nodiscard]] CycleVariation draw_cycle_variation(const VibrationSpec& v, std::uint32_t cycles,
                                                  std::uint64_t seed);

/// Synthesised vibration in m/s^2 (before clipping and quantisation).
struct Vibration {
  std::vector<double> accel_ms2;
  std::uint32_t harmonics_above_nyquist = 0;   ///< GMF/DMF orders omitted (k * max mesh freq >= fs/2)
  std::vector<double> impulse_times_s;         ///< spur-tooth impact times (truth), ascending
  std::vector<double> impulse_amplitudes_ms2;  ///< matching ringing amplitudes
  std::uint64_t effect_clipped_samples = 0;    ///< samples clamped by an adc_clipping effect
  std::uint64_t effect_impacts = 0;            ///< knocks added by impacts effects
  CycleVariation cycle_variation;              ///< the factors used (empty when the variation is off)
};

/// Synthesises the sensor signal for the profile. Deterministic from seed. Any thread; allocates.
[[nodiscard]] Vibration synthesize_vibration(const Scenario& s, const MotionProfile& m, std::uint64_t seed);

/// Stored codes for the configured format: round(clip(v)/lsb) with lsb = range / 2^(bits-1)
/// (float32: clip(v) as is, scale 1); |v| > range counts as clipped (via `clipped`). Any thread; allocates.
[[nodiscard]] std::vector<float> quantize(const SensorSpec& sensor, const std::vector<double>& accel_ms2,
                                          std::uint64_t* clipped = nullptr);
/// Scale (stored value * scale = m/s^2) for the sensor format. Any thread; no allocation.
[[nodiscard]] double sensor_scale(const SensorSpec& sensor) noexcept;

/// A CAN frame to be logged (the speed frames and the unrelated ones), in timestamp order.
struct SimCanFrame {
  CanFrame frame;            ///< frame.t_ns = log timestamp (UNIX ns)
  double true_time_s = 0.0;  ///< sampling instant of the speed (from sample 0); NaN for other frames
  bool is_speed = false;
};

/// Speed frames from the free-running controller clock (+ delay, jitter, other frames), sorted by log
/// timestamp (rounded to microseconds, as candump logs). Deterministic from seed. Any thread; allocates.
[[nodiscard]] std::vector<SimCanFrame> generate_can(const Scenario& s, const MotionProfile& m,
                                                    std::uint64_t seed);

/// Everything a simulation produces, in memory (what simulate_to_directory writes, plus the truth).
struct SimulatedSignals {
  MotionProfile motion;      ///< on the ADC's true sample grid (differs from nominal with sample_clock_error)
  Vibration vibration;       ///< m/s^2 before quantisation (effects included)
  std::vector<float> codes;  ///< stored sample values (quantize()); codes * sensor_scale = m/s^2
  std::uint64_t clipped_samples = 0;  ///< by the sensor range
  std::vector<SimCanFrame> can;
  double fs_nominal_hz = 0.0;  ///< the rate the WAV header states
  std::uint64_t seed = 0;
};

/// Motion, vibration (with effects), quantisation and CAN for scenario `s` with `seed`, whole in memory
/// (O(samples): for the gap fits and tests; simulate_to_directory streams). Deterministic.
/// Throws ptda::Error like build_motion. Any thread; allocates.
[[nodiscard]] SimulatedSignals simulate_signals(const Scenario& s, std::uint64_t seed);

// ------------------------------------------------------------------------------------------------

struct SimulationSummary {
  std::uint32_t cycles = 0;
  double duration_s = 0.0;
  std::uint64_t samples = 0;
  std::uint64_t can_frames = 0;  ///< all frames written (speed + other)
  std::uint64_t speed_frames = 0;
  double fs_hz = 0.0;
  std::vector<double> plateau_speeds_rad_s;  ///< distinct plateau speeds of one cycle, in order
  std::vector<double> plateau_durations_s;   ///< matching durations
  double gmf_hz_at_first_plateau = 0.0;
  double ratio = 0.0;
  std::uint32_t harmonics_above_nyquist = 0;
  std::uint64_t clipped_samples = 0;
  std::uint64_t seed = 0;
  std::vector<double> severity_per_cycle;  ///< max fault severity in each cycle
};

/// Writes a recording directory (recording.toml, vibration.wav, can.log, truth.toml), creating it.
/// `seed` overrides the scenario seed when set. Streams (sim/include/ptda/sim/stream.hpp, docs/simulator.md
/// "Streaming"): memory does not grow with the samples, nor with an lspb motion's cycles beyond 8 bytes
/// per cycle (severity_per_cycle); the files are the ones simulate_signals() would give. Throws
/// ptda::Error. Any thread; allocates; file I/O.
SimulationSummary simulate_to_directory(const Scenario& s, const std::filesystem::path& out_dir,
                                        std::optional<std::uint64_t> seed = std::nullopt);

}  // namespace ptda::sim
