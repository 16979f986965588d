// Angle-domain resampling (computed order tracking, issue 16): the vibration, sampled at fs on the
// time axis, is resampled to a fixed number of samples per input-shaft revolution using the joint angle
// and speed that the controller sends over CAN. A gear-mesh line is then a fixed order whatever the
// speed. Streaming and allocation-free after construction; the method is in docs/method.md §9.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "ptda/dsp/types.hpp"

namespace ptda::dsp {

struct AngleResamplerConfig {
  std::uint32_t samples_per_rev = 0;  ///< S: output samples per input-shaft revolution (even, >= 16)
  double ratio = 0.0;                 ///< input-shaft angle / joint angle (the gearbox reduction), > 0
  /// Subtracted from SpeedSample::t_ns ([can] speed_latency_s). 0 when the caller already applied it,
  /// as cli::run_recording and the daemon do when they decode the frames.
  double speed_latency_s = 0.0;
  std::uint32_t half_taps = 32;  ///< Q: half-width of the anti-alias kernel, in output samples (4..256)
  /// c: cutoff of the anti-alias kernel as a fraction of the output Nyquist order S/2, in (0, 1).
  double cutoff = 0.8;
  double min_shaft_hz = 0.5;      ///< |input-shaft speed| below this breaks the stream (standstill)
  double max_speed_gap_s = 0.05;  ///< CAN speed frames further apart break the stream
  double max_lead_s = 1.0;        ///< vibration may run this far ahead of the speed frames (buffering)
};

/// One output sample on the angle grid.
struct OrderSample {
  /// Grid index: the sample lies at travelled input-shaft angle k * 2 pi / S from the first accepted
  /// speed frame's angle (travelled = counted in the direction of motion, so it never decreases).
  std::int64_t k = 0;
  std::uint64_t segment = 0;       ///< increments at every break (standstill, reversal, gap, bad frame)
  std::int8_t direction = 1;       ///< sign of the shaft speed
  float value = 0.0F;              ///< anti-aliased vibration at that angle
  std::int64_t t_ns = 0;           ///< time of the grid point (vibration clock), linearly interpolated
  double shaft_speed_rad_s = 0.0;  ///< |input-shaft speed| there (linearly interpolated)
};

struct AngleResamplerCounters {
  std::uint64_t frames = 0;               ///< speed frames accepted
  std::uint64_t frames_no_angle = 0;      ///< frames without an angle (break)
  std::uint64_t frames_out_of_order = 0;  ///< not after the previous one: dropped
  std::uint64_t frames_overflow = 0;      ///< frame queue full (vibration too far behind): dropped
  std::uint64_t angle_inconsistent = 0;   ///< angle step disagreeing with the speeds: speed integral used
  std::uint64_t breaks = 0;               ///< segments ended
  std::uint64_t samples = 0;              ///< vibration samples pushed
  std::uint64_t samples_unused = 0;       ///< before the first frame, in a break, or not finite (no output)
  std::uint64_t samples_overrun = 0;      ///< lost because the speed frames lagged more than max_lead_s
  std::uint64_t outputs = 0;              ///< order samples produced
  std::uint64_t outputs_dropped = 0;      ///< produced but the output queue was full (pop() not called)
};

/// Streaming resampler from the time axis to the input-shaft angle axis.
///
/// Angle law: between two consecutive CAN frames a and b (times t, joint angle theta, joint speed v,
/// times already corrected by speed_latency_s) the input-shaft angle phi = ratio * theta follows the
/// cubic Hermite polynomial with phi and dphi/dt = ratio * v at both frames. So the angle and the
/// speed agree at every frame, the law has a continuous first derivative, it is exact for a constant
/// acceleration, and its error is at most h^4 / 384 * max |phi''''| over a frame interval h. When the
/// angle step disagrees with the trapezoid integral of the speeds by more than half of it (an angle
/// wrap, a bad frame) the integral is used instead (counted in angle_inconsistent).
///
/// Anti-alias filter and resampling in one step, a convolution in the angle domain: the output at
/// grid angle s_k is y_k = sum_n x[n] h(s_k - s(t_n)) |phi'(t_n)| / fs, the Riemann sum of
/// integral x(s) h(s_k - s) ds, with h a Kaiser-windowed sinc (80 dB, beta 7.857) of cutoff c * S / 2
/// orders and half-width Q output samples. The filter is therefore fixed in orders, whatever the speed:
///   passband (ripple <= 1e-4) up to pass_order() = (c/2 - 2.51/Q/2) S,
///   stopband (>= 80 dB) from stop_order() = (c/2 + 2.51/Q/2) S,
/// (defaults S: 0.3608 S and 0.4392 S). The Riemann sum is exact when the kernel, seen on the time
/// axis, stays below fs/2: the shaft frequency must stay below max_shaft_hz() = fs / (2 stop_order()),
/// faster motion breaks the stream. The highest order of interest at shaft speed f is therefore
/// min(pass_order(), fs / (2 f)) - and pass_order() is the one that holds at every accepted speed.
/// Cost: about 2 Q fs kernel taps per second whatever the speed (a table lookup and a multiply-add).
///
/// Breaks (standstill, a speed-sign change inside a frame interval, |shaft speed| outside
/// [min_shaft_hz, max_shaft_hz()], frames further apart than max_speed_gap_s, a frame without angle)
/// end the segment: outputs resume Q samples into the next good interval with segment + 1.
class AngleResampler {
 public:
  /// fs_hz: vibration sample rate; t0_ns: time of sample 0 (sample n is at t0_ns + n * 1e9 / fs).
  /// Thread: any (setup). Allocates every buffer. Throws ptda::Error naming the field on a bad
  /// configuration (e.g. "angle_resampler.samples_per_rev must be even and >= 16").
  AngleResampler(const AngleResamplerConfig& cfg, double fs_hz, std::int64_t t0_ns);

  /// Speed frames in time order (t_ns before the latency correction). Thread: the owner's. Never
  /// allocates or blocks.
  void push_speed(const SpeedSample& s) noexcept;
  /// The next consecutive vibration samples. Thread: the owner's. Never allocates or blocks.
  void push_samples(std::span<const float> block) noexcept;
  /// The oldest produced order sample; false when none. Thread: the owner's. Never allocates.
  bool pop(OrderSample& out) noexcept;

  [[nodiscard]] const AngleResamplerCounters& counters() const noexcept { return counters_; }
  [[nodiscard]] const AngleResamplerConfig& config() const noexcept { return cfg_; }
  [[nodiscard]] double pass_order() const noexcept { return pass_order_; }
  /// pass_order() of a resampler built from cfg (no check of cfg). Thread: any. Never allocates.
  [[nodiscard]] static double pass_order_of(const AngleResamplerConfig& cfg) noexcept;
  [[nodiscard]] double stop_order() const noexcept { return stop_order_; }
  [[nodiscard]] double max_shaft_hz() const noexcept { return max_shaft_hz_; }
  /// Bound on the kernel's passband ripple and stopband leakage (Kaiser design value 10^(-80/20)).
  [[nodiscard]] static constexpr double kernel_ripple() noexcept { return 1e-4; }

 private:
  struct Frame {
    double t_s;      ///< relative to t0, latency corrected
    double phi_rad;  ///< input-shaft angle (not yet checked)
    double w_rad_s;  ///< input-shaft speed
    bool has_angle;
  };

  void process() noexcept;
  void angle_interval(const Frame& a, const Frame& b) noexcept;
  void angle_sample(std::int64_t n, double u, double h, double dphi, double wa, double wb,
                    double dir) noexcept;
  void start_segment() noexcept;
  void break_segment() noexcept;
  void emit() noexcept;
  [[nodiscard]] double kernel(double u) const noexcept;

  AngleResamplerConfig cfg_;
  double fs_hz_;
  std::int64_t t0_ns_;
  std::int64_t latency_ns_;
  double pass_order_ = 0.0;
  double stop_order_ = 0.0;
  double max_shaft_hz_ = 0.0;
  double sigma_per_rad_ = 0.0;  ///< output samples per rad of shaft angle (S / 2 pi)
  AngleResamplerCounters counters_;

  // Anti-alias kernel table: h at u = i / kTableStep output samples, i = 0..Q*kTableStep (+1 zero).
  std::vector<double> table_;

  // Frames waiting for their interval's samples.
  std::vector<Frame> frames_;
  std::size_t frame_head_ = 0, frame_count_ = 0;
  bool have_prev_ = false;
  Frame prev_{};  ///< the frame that starts the current interval
  // The interval (prev_, next frame) as last checked by angle_interval().
  double interval_dphi_ = 0.0;  ///< shaft angle step used (the frames' or the speed integral)
  bool interval_valid_ = false;
  bool interval_inconsistent_ = false;
  double sigma_ = 0.0;         ///< travelled angle at prev_, output samples, relative to seg_base_
  std::int64_t seg_base_ = 0;  ///< k of sigma = 0 in the current segment (re-based per segment)

  // Raw samples waiting for an angle: ring indexed by absolute sample index.
  std::vector<float> raw_;
  std::int64_t raw_next_ = 0;     ///< absolute index of the next pushed sample
  std::int64_t angled_next_ = 0;  ///< absolute index of the next sample to angle

  // Angled samples of the current segment: ring.
  std::vector<double> a_sigma_, a_g_, a_t_, a_w_;
  std::size_t a_head_ = 0, a_count_ = 0;
  bool in_segment_ = false;
  std::uint64_t segment_ = 0;
  std::int8_t dir_ = 1;
  std::int64_t next_k_ = 0;  ///< next grid index (relative to seg_base_) to emit
  bool next_k_set_ = false;

  // Output queue.
  std::vector<OrderSample> out_;
  std::size_t out_head_ = 0, out_count_ = 0;
};

}  // namespace ptda::dsp
