// Order-domain PTDA windows (issue 16, docs/method.md §9): windows of a whole number of input-shaft
// revolutions cut from the AngleResampler's output, and their segment classes (direction and speed
// band). The per-window analysis is the time domain's WindowAnalyzer unchanged: a window of R S angle
// samples is analysed exactly like a window of N time samples, its bins are orders k / R instead of
// frequencies k fs / N.
#pragma once

#include <complex>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "ptda/dsp/angle_resampler.hpp"
#include "ptda/dsp/baseline.hpp"
#include "ptda/dsp/baseline_training.hpp"
#include "ptda/dsp/real_fft.hpp"
#include "ptda/dsp/spill.hpp"
#include "ptda/dsp/training.hpp"
#include "ptda/dsp/window_slicer.hpp"

namespace ptda::dsp {

struct OrderWindowConfig {
  std::uint32_t samples_per_rev = 0;  ///< S, as the resampler's
  std::uint32_t revolutions = 0;      ///< R: a window spans R input-shaft revolutions (N = R S)
  double ratio = 0.0;                 ///< input-shaft / joint speed, to report the joint speed
  /// Orders above this are set to exactly 0 in every window (one forward and one inverse FFT per
  /// window); 0 = keep every bin. Set it to the resampler's pass_order(): above it the spectrum holds
  /// only the kernel's transition and stop band, whose tiny leakage of whatever the window contains
  /// would otherwise enter PTDA's floor gain (the median of |X| / a over the floor bins) as a level
  /// change that scales with a defect, and refer the defect away (docs/method.md §9).
  double max_order = 0.0;
};

/// Where an order window lies. Bin k of its spectrum is order k / R of the input shaft.
struct OrderWindowRef {
  std::uint64_t seq = 0;      ///< windows cut so far (0-based)
  std::uint64_t segment = 0;  ///< resampler segment (an unbroken run of motion in one direction)
  std::int64_t k_start = 0;   ///< grid index of the first sample (a multiple of N)
  std::int64_t t_start_ns = 0;
  std::int64_t t_end_ns = 0;  ///< time of the last sample
  std::int8_t direction = 1;
  double shaft_speed_rad_s = 0.0;  ///< mean |input-shaft speed|: angle span / time span
  double min_shaft_speed_rad_s = 0.0;
  double max_shaft_speed_rad_s = 0.0;
  double joint_speed_rad_s = 0.0;  ///< signed mean joint speed (shaft / ratio), for Baseline::match
};

/// The time-domain description of an order window, as MonitorEngine::judge_window and the outputs take
/// it: seq, region_seq = resampler segment, index_in_region = k_start / N, first_sample = k_start (the
/// grid index), times, speed_rad_s = the signed mean joint speed. `ptda monitor` and ptdad both use it.
/// Thread: any. Never allocates.
[[nodiscard]] WindowRef window_ref_of(const OrderWindowRef& ref, std::size_t window_len) noexcept;

/// Cuts non-overlapping windows of N = R S consecutive order samples of one segment, starting at grid
/// indices that are multiples of N (so a window always starts at the same shaft angle modulo R
/// revolutions from the resampler's origin). A gap in k or a new segment drops the partial window.
class OrderWindowCutter {
 public:
  /// Thread: any (setup). Allocates the window buffer. Throws ptda::Error naming the field when
  /// R S is not a RealFft length or a field is out of range.
  explicit OrderWindowCutter(const OrderWindowConfig& cfg);
  /// Feeds one order sample; returns true when it completes a window, which is then copied to `out`
  /// (size N, else false and nothing copied) and described in `ref`. Thread: the owner's. Never
  /// allocates or blocks.
  bool push(const OrderSample& s, OrderWindowRef& ref, std::span<float> out) noexcept;
  [[nodiscard]] std::size_t window_len() const noexcept { return buf_.size(); }
  [[nodiscard]] std::uint64_t windows() const noexcept { return seq_; }

 private:
  OrderWindowConfig cfg_;
  std::vector<float> buf_;
  std::unique_ptr<RealFft> fft_;  ///< when max_order > 0
  std::vector<std::complex<float>> spec_;
  std::size_t keep_bins_ = 0;  ///< bins 0..keep_bins_-1 kept
  std::size_t fill_ = 0;
  std::int64_t k_start_ = 0;
  std::int64_t t_start_ns_ = 0;
  std::uint64_t segment_ = 0;
  std::int8_t direction_ = 1;
  double min_w_ = 0.0, max_w_ = 0.0;
  std::uint64_t seq_ = 0;
};

/// Order-domain training input: every order window of the healthy recordings.
struct OrderWindows {
  std::vector<OrderWindowRef> refs;
  std::vector<std::vector<float>> windows;
  std::vector<std::uint32_t> recording;  ///< per window (days); empty = one recording
};

/// The index of a streamed order-domain training (`ptda train` in the order domain): each window's place,
/// training recording (0-based) and mean square (mean of x^2, for the speed law), in cut order, in spill
/// vectors (memory does not grow with the training data; docs/cli.md, `ptda train`, "Memory").
struct OrderTrainingIndex {
  explicit OrderTrainingIndex(const SpillConfig& cfg = {});
  SpillConfig spill;
  SpillVector<OrderWindowRef> refs;
  SpillVector<std::uint32_t> recording;  ///< one per ref
  SpillVector<double> mean_square;       ///< one per ref
};
/// The mean of x^2 in double, as the speed law's fit takes it. Thread: any. Never allocates.
[[nodiscard]] double window_mean_square(std::span<const float> x) noexcept;

/// Classes of order windows: per direction, windows sorted by |joint speed| are grouped greedily, a new
/// class starting when a speed exceeds the class's first by more than band_rel (relative). A class's
/// speed_rad_s is the mean of its windows, its speed_tol_rad_s half of band_rel times that (so adjacent
/// classes do not overlap and Baseline::match() picks the nearest), `regions` the distinct segments.
/// Classes with fewer than min_segments segments are dropped (one line each appended to `dropped`).
/// Ids 0.. forward by speed, then backward by speed. Thread: any. Allocates.
[[nodiscard]] std::vector<SegmentClass> learn_order_classes(const std::vector<OrderWindowRef>& refs,
                                                            double band_rel, std::uint32_t min_segments,
                                                            std::vector<std::string>* dropped = nullptr);
/// learn_order_classes() of refs in a spill vector (sorted in bounded memory; the same classes).
[[nodiscard]] std::vector<SegmentClass> learn_order_classes_streamed(
    const SpillVector<OrderWindowRef>& refs, double band_rel, std::uint32_t min_segments,
    std::vector<std::string>* dropped = nullptr);

/// The order-domain baseline: learn_order_classes(), then build_class_baseline() per class with the
/// resampler segment as leave-out group. fs_hz of the result is S (samples per revolution: the
/// "sample rate" of the angle axis) and window_len N = R S. Throws ptda::Error when no class has
/// enough windows (the message names every dropped class). Thread: any (offline). Allocates.
/// A class needs windows from min_segments resampler segments ([classes] min_regions; 3 by default).
/// With learn_speed_law, the amplitude's speed law is fitted first (Baseline::speed_law_*: pooled
/// within-class least squares of log window RMS on log |joint speed|) and, when significant, each
/// window is normalised to its class's speed before the class is trained.
[[nodiscard]] Baseline train_order_baseline(const OrderWindows& data, const OrderWindowConfig& cfg,
                                            double band_rel, const ThresholdPolicy& policy,
                                            const GearboxInfo& gearbox,
                                            std::vector<std::string>* dropped = nullptr,
                                            bool learn_speed_law = false, std::uint32_t min_segments = 3);
/// train_order_baseline() without holding the windows: `index` holds the refs, recordings and mean
/// squares and `pass` hands the windows over (twice: the class sums, then each window's leave-one-out
/// features), as train_baseline_streamed() takes them. The same baseline, bit for bit, while no
/// per-window list spills (index.spill.memory_bytes); beyond, the thresholds' sums agree to rounding.
/// Throws as train_order_baseline(), when a pass does not hand over every window once in order, and
/// when a spill file fails. Thread: any (offline). Allocates.
[[nodiscard]] Baseline train_order_baseline_streamed(
    const OrderTrainingIndex& index, const TrainingWindowPass& pass, const OrderWindowConfig& cfg,
    double band_rel, const ThresholdPolicy& policy, const GearboxInfo& gearbox,
    std::vector<std::string>* dropped = nullptr, bool learn_speed_law = false,
    std::uint32_t min_segments = 3);

/// The speed law's fit (see train_order_baseline): exponent p, its standard error, and the p applied
/// (p when |p| > 2 se and the fit has >= 3 residual degrees of freedom, else 0). Windows of no class are
/// left out. Thread: any. Allocates.
struct SpeedLawFit {
  double exponent = 0.0;
  double se = 0.0;
  double applied = 0.0;
  std::size_t windows = 0;
};
[[nodiscard]] SpeedLawFit fit_speed_law(const std::vector<OrderWindowRef>& refs,
                                        const std::vector<std::vector<float>>& windows,
                                        const std::vector<SegmentClass>& classes);
/// fit_speed_law() from each window's mean square (window_mean_square()) instead of its samples.
[[nodiscard]] SpeedLawFit fit_speed_law_streamed(const SpillVector<OrderWindowRef>& refs,
                                                 const SpillVector<double>& mean_square,
                                                 const std::vector<SegmentClass>& classes);
/// (v_c / |v|)^p, the factor that takes a window at joint speed v to its class's speed v_c; 1 when p = 0
/// or a speed is not positive. Thread: any. Never allocates.
[[nodiscard]] double speed_law_gain(double class_speed_rad_s, double speed_rad_s, double exponent) noexcept;

}  // namespace ptda::dsp
