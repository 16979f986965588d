// Streaming synthesis: the vibration and the CAN log of a scenario block by block, with memory that does
// not grow with the recording's length (with a lazy motion plan, build_motion_lazy()). The
// whole-signal functions of simulator.hpp (synthesize_vibration, generate_can) give the same values,
// sample for sample and frame for frame; simulate_to_directory writes through these streams.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>

#include "ptda/sim/simulator.hpp"

namespace ptda::sim {

/// The sensor signal of synthesize_vibration() (m/s^2, effects included, before quantisation), block by
/// block: block boundaries do not change a single bit. `s` and `m` (a motion plan from
/// build_motion_plan() or build_motion_lazy() is enough) must outlive the stream. Thread: the owner's.
/// Allocates at construction, and in next() while knocks ring (a few ringings at a time) and when a
/// lazy plan's next cycle is generated.
class VibrationStream {
 public:
  /// `keep_impulses`: record the spur-tooth impact times and amplitudes (impulse_times_s(); they grow
  /// with the length) instead of only counting them. Throws like synthesize_vibration.
  VibrationStream(const Scenario& s, const MotionProfile& m, std::uint64_t seed, bool keep_impulses = false);
  ~VibrationStream();
  VibrationStream(const VibrationStream&) = delete;
  VibrationStream& operator=(const VibrationStream&) = delete;

  /// Total samples (motion_samples(m)) and the next sample's index.
  [[nodiscard]] std::size_t samples() const noexcept;
  [[nodiscard]] std::size_t position() const noexcept;
  /// Writes the next min(x.size(), samples() - position()) samples to x; returns how many (0 at the end).
  std::size_t next(std::span<double> x);

  // Truth, complete once position() == samples():
  [[nodiscard]] std::uint32_t harmonics_above_nyquist() const noexcept;
  [[nodiscard]] std::uint64_t impulses() const noexcept;        ///< spur-tooth impacts
  [[nodiscard]] std::uint64_t effect_impacts() const noexcept;  ///< knocks of impacts effects
  [[nodiscard]] std::uint64_t effect_clipped_samples() const noexcept;
  /// Moves the truth into v (impulse times sorted as synthesize_vibration sorts them when kept; the cycle
  /// variation drawn again: the stream keeps only the current cycle's factors).
  void take_truth(Vibration& v);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Stored codes of quantize() for a block: out[i] = code of accel_ms2[i] (same size); adds the samples
/// clipped at the sensor range to *clipped. Any thread; no allocation.
void quantize_block(const SensorSpec& sensor, std::span<const double> accel_ms2, std::span<float> out,
                    std::uint64_t* clipped) noexcept;

/// The frames of generate_can() one by one, in the same order (log timestamp, speed frames first on
/// equal timestamps), without holding the whole log: the unrelated frames are drawn again for each
/// time window of at most `window_frames` frames. Requires [can] jitter_s < period_s (what the scenario
/// parser and timing_scenarios() guarantee; throws ptda::Error otherwise). `s` and `m` must outlive it.
/// Thread: the owner's; allocates at most window_frames frames.
class CanStream {
 public:
  CanStream(const Scenario& s, const MotionProfile& m, std::uint64_t seed, std::size_t window_frames = 65536);
  ~CanStream();
  CanStream(const CanStream&) = delete;
  CanStream& operator=(const CanStream&) = delete;
  /// The next frame; false at the end.
  bool next(SimCanFrame& out);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Sample-clock and CAN-latency effects act on the scenario: `for_motion` has the ADC's true rate (motion
/// and vibration are generated on the true sample grid), `for_can` the extra CAN delay/jitter (what
/// simulate_signals and simulate_to_directory synthesise from). Any thread; allocates.
void timing_scenarios(const Scenario& s, Scenario& for_motion, Scenario& for_can);

/// simulate_to_directory's knobs (tests cut the synthesis at odd block sizes).
struct SimulateOptions {
  std::size_t block_samples = 65536;      ///< samples synthesised and written per block
  std::size_t can_window_frames = 65536;  ///< CanStream window
};

/// simulate_to_directory with options. Throws ptda::Error. Any thread; allocates; file I/O.
SimulationSummary simulate_to_directory(const Scenario& s, const std::filesystem::path& out_dir,
                                        std::optional<std::uint64_t> seed, const SimulateOptions& options);

/// truth.toml's text (without the leading comment and the final newline) for a simulation held in memory:
/// printed whole by toml++ (`whole`) or as simulate_to_directory streams it (the plateaus and the long
/// per-cycle arrays element by element; vib.cycle_variation empty: its factors drawn again from sum.seed
/// while printing, as simulate_to_directory does). The two are equal; tests compare them. Any thread;
/// allocates.
[[nodiscard]] std::string truth_toml_whole(const Scenario& s, const MotionProfile& m, const Vibration& vib,
                                           std::uint64_t other_frames, const SimulationSummary& sum);
[[nodiscard]] std::string truth_toml_streamed(const Scenario& s, const MotionProfile& m, const Vibration& vib,
                                              std::uint64_t other_frames, const SimulationSummary& sum);

}  // namespace ptda::sim
