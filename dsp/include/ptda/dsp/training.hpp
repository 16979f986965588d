// Learning a class baseline from healthy windows (offline or in the daemon's training mode; allocates).
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "ptda/dsp/baseline.hpp"
#include "ptda/dsp/decision.hpp"
#include "ptda/dsp/spill.hpp"

namespace ptda::dsp {

/// Phi^{-1}(p): the standard normal quantile (a rational starting guess refined by Halley steps on
/// std::erfc; Phi(result) matches p to ~1e-12 relative in the tail, tested down to p = 1e-200).
/// Thread: any. Never allocates, except the message of the ptda::Error thrown when p is not in (0, 1).
[[nodiscard]] double inverse_normal_cdf(double p);

/// Normal one-sided tolerance factor k1: with probability `confidence`, mean + k1 sd of n normal
/// values lies above the p-quantile of their distribution. Natrella's approximation
/// k1 = (z_p + sqrt(z_p^2 - a b)) / a, a = 1 - z_g^2 / (2 (n - 1)), b = z_p^2 - z_g^2 / n
/// (NIST/SEMATECH e-Handbook 7.2.6.3). Throws ptda::Error for n < 3, p or confidence not in (0.5, 1),
/// or when n is too small for the approximation (a <= 0). Thread: any.
[[nodiscard]] double tolerance_factor_one_sided(std::uint32_t n, double p, double confidence);

/// Normal two-sided tolerance factor k2: with probability `confidence`, mean +- k2 sd covers a
/// fraction p of the distribution. Howe's approximation
/// k2 = z_{(1+p)/2} sqrt((n - 1) (1 + 1/n) / chi2_{1-confidence, n-1}) with the chi-square quantile by
/// Wilson-Hilferty. Throws like tolerance_factor_one_sided(). Thread: any.
[[nodiscard]] double tolerance_factor_two_sided(std::uint32_t n, double p, double confidence);

/// Small-sample scale of the standardised features: k1(n, 1 - alpha, confidence) / Phi^{-1}(1 - alpha)
/// with the policy's alpha and confidence, so that a value at the tolerance limit standardises to the
/// asymptotic z whatever n. 1 for n < 3 or where the approximation does not exist; tends to 1 as n
/// grows (1.28 at n = 20, 1.18 at n = 40 for alpha 1e-3, confidence 0.9). Thread: any. Never throws.
[[nodiscard]] double small_sample_scale(std::uint32_t n, const ThresholdPolicy& policy) noexcept;

/// One-way random-effects (ANOVA) decomposition of values in groups (here: the training recordings,
/// i.e. days). With N values in R groups of n_r, group means m_r and grand mean m:
/// MSW = sum_r sum_i (x_ri - m_r)^2 / (N - R), MSB = sum_r n_r (m_r - m)^2 / (R - 1),
/// n0 = (N - sum_r n_r^2 / N) / (R - 1), between_var = max(0, (MSB - MSW) / n0) (the method-of-moments
/// estimator; Searle, Casella & McCulloch, Variance Components, 3.5). One group: within_var is the
/// sample variance (N - 1), between_var 0. N == R (one value per group): within and between cannot be
/// told apart; within_var is then the sample variance and between_var 0. Empty `groups`: one group.
/// Throws ptda::Error when groups.size() is neither 0 nor values.size() or there are no values.
/// Thread: any. Allocates (per-group sums).
struct VarianceComponents {
  double mean = 0.0;         ///< grand mean of all values
  double within_var = 0.0;   ///< MSW
  double between_var = 0.0;  ///< max(0, (MSB - MSW) / n0)
  double msb = 0.0;          ///< MSB (0 for one group)
  double n0 = 0.0;           ///< effective group size (0 for one group)
  std::uint32_t groups = 0;  ///< R
  std::uint32_t n = 0;       ///< N
};
[[nodiscard]] VarianceComponents variance_components(std::span<const double> values,
                                                     std::span<const std::uint32_t> groups);

/// variance_components() without keeping the values: add them one at a time (any order of groups).
/// Per group it keeps the count, the sum and Welford's running sum of squared deviations, so memory is
/// O(groups), not O(values). The grand mean and the group means are the same sums in the same order as
/// variance_components()'s, and that function is built on this class, so both give the same result.
/// Thread: any (one object per thread). add() allocates when a new group appears.
class VarianceAccumulator {
 public:
  void add(double value, std::uint32_t group);
  /// Throws ptda::Error when no value was added.
  [[nodiscard]] VarianceComponents result() const;
  [[nodiscard]] std::size_t count() const noexcept { return n_; }

 private:
  struct Group {
    std::uint32_t id = 0;
    std::size_t n = 0;
    double sum = 0.0;
    double mean = 0.0;  ///< Welford's running mean (for m2 only)
    double m2 = 0.0;    ///< sum of squared deviations from the group mean
  };
  std::vector<Group> groups_;  ///< in order of first appearance (few: one per recording)
  std::size_t last_ = 0;       ///< the group of the previous value (values come in runs)
  double total_ = 0.0;
  std::size_t n_ = 0;
};

/// The sequential detector's standardisation for `method` in class `c` (docs/method.md §6): means of the
/// leave-one-out ln(rms_res) and entropy_res, their within-day sds (c.day_spread; the stats' stddev for a
/// baseline of format <= 3), the small-sample scale c_n of small_sample_scale(), and the between-day
/// allowances q sd_between sqrt(1 + 1/R) / (c_n sd_within) with q = day_allowance (0 when the baseline
/// has no between-day spread). Thread: any. Never allocates or throws.
[[nodiscard]] SeqScale sequential_scale(const ClassBaseline& c, Method method, const ThresholdPolicy& policy,
                                        double day_allowance) noexcept;

/// How a feature's band is modelled by a kTolerance policy (other kinds ignore it).
enum class FeatureScale : std::uint8_t {
  kLinear = 0,  ///< two-sided tolerance interval on the values
  kLog = 1,     ///< one-sided tolerance limits (upper and lower, each at 1 - alpha) on ln(values)
};

/// Fits a two-sided band to healthy feature values according to the policy. Needs >= 2 values.
///  - kGaussian: mean +- z stddev with z = Phi^{-1}(1 - alpha/2), alpha = policy.false_alarm_rate;
///  - kQuantile: linear-interpolated sample quantiles at alpha/2 and 1 - alpha/2 (h = (n-1) q);
///  - kTolerance: kLinear: mean +- k2(n, 1 - alpha, confidence) sd; kLog: exp(m +- k1(n, 1 - alpha,
///    confidence) s) with m, s the mean and sd of ln(values) (needs values > 0 and n >= 3);
/// then both ends move out by policy.margin * (hi - lo).
/// Between-day spread (docs/method.md §5): day_ratio = sd_between / sd_within and within_ratio =
/// sd_within / sample sd of the feature (unitless, so they hold on the ln or the linear scale); when
/// day_ratio > 0, kGaussian and kTolerance use sample sd x within_ratio x sqrt(1 + day_ratio^2) =
/// sqrt(sd_within^2 + sd_between^2), and kQuantile moves both quantiles away from the median by the
/// factor within_ratio x sqrt(1 + day_ratio^2). The tolerance factor keeps n = values.size().
/// Throws ptda::Error when there are too few values, a value is not finite, alpha is not in (0, 1)
/// or the margin is negative. Thread: any. Allocates (kQuantile sorts a copy).
[[nodiscard]] Band fit_band(std::span<const double> values, const ThresholdPolicy& policy,
                            FeatureScale scale = FeatureScale::kLinear, double day_ratio = 0.0,
                            double within_ratio = 1.0);
/// fit_band() of values in a spill vector: the same code on the values in memory when none spilled;
/// else the sums chunk by chunk (equal up to rounding) and kQuantile's order statistics from sorted()
/// (exact). Also throws when the spill file fails.
[[nodiscard]] Band fit_band(const SpillVector<double>& values, const ThresholdPolicy& policy,
                            FeatureScale scale = FeatureScale::kLinear, double day_ratio = 0.0,
                            double within_ratio = 1.0);

/// The band `pooled` widened to cover each recording's own band (ThresholdPolicy::cover_recordings,
/// docs/method.md §5): for every recording id in `recordings` with at least 3 values (for kLog: 3 values
/// > 0), fit_band(those values, policy, scale) with no between-day widening; the result is
/// [min(lo), max(hi)] over `pooled` and these bands. `recordings` gives the recording of each value
/// (same size as values; empty = one recording, which returns `pooled` unchanged, as does one distinct
/// id). Throws ptda::Error on a size mismatch or as fit_band. Thread: any. Allocates.
[[nodiscard]] Band cover_recordings(const Band& pooled, std::span<const double> values,
                                    std::span<const std::uint32_t> recordings, const ThresholdPolicy& policy,
                                    FeatureScale scale = FeatureScale::kLinear);
/// cover_recordings() of values in spill vectors (recordings must have one id per value).
[[nodiscard]] Band cover_recordings(const Band& pooled, const SpillVector<double>& values,
                                    const SpillVector<std::uint32_t>& recordings,
                                    const ThresholdPolicy& policy,
                                    FeatureScale scale = FeatureScale::kLinear);

/// Problems with the amount of training data for the policy's false-alarm rate, one sentence each,
/// saying how many windows would be needed: kQuantile needs n >= 2 / alpha leave-one-out values per
/// class (else the band is the sample range); kGaussian and kTolerance warn when the tolerance factor
/// for n exceeds the asymptotic z by more than 20 % (the band rests on few windows: kGaussian then
/// promises a rate it cannot know, kTolerance is that much wider); a hold-out of m windows can only
/// show a rate >= 3 / m (95 % bound with none abnormal); a class seen in one training recording only
/// has its between-day spread assumed, and the advice says how to train on more days: `more_days_how`
/// (the CLI's "repeat --recording"; the daemon, whose field training sees one run, says `ptda train`).
/// Thread: any. Allocates.
[[nodiscard]] std::vector<std::string> training_warnings(
    const Baseline& baseline, std::string_view more_days_how = "repeat --recording");

/// Summary statistics of values (population of the training set; stddev with n-1, 0 for n < 2;
/// all zero with n = 0 for no values). Thread: any. Never allocates or throws.
[[nodiscard]] FeatureStats feature_stats(std::span<const double> values);
/// feature_stats() of a spill vector: identical to the span version when none spilled, else summed
/// chunk by chunk (equal up to rounding). Thread: any. Allocates; throws when the spill file fails.
[[nodiscard]] FeatureStats feature_stats(const SpillVector<double>& values);

/// The class baseline of build_class_baseline(), built from windows handed over one at a time, so a
/// caller can stream them from a recording in two passes instead of holding them (`ptda train`):
///  1. add_to_mean() every window of the class (in the order build_class_baseline() would sum them),
///     then finish_mean(): mean magnitude, TDA mean and spectrum, line groups (means() is then valid
///     for scoring other windows, e.g. a hold-out);
///  2. score_group() each leave-out group with all its windows (in group order, as
///     build_class_baseline() visits its groups), then finish(): thresholds, stats, day spread.
/// Same arithmetic in the same order as build_class_baseline() (which is built on it), so the same
/// windows give the same bytes. Memory: O(N) (sums in double) plus 6 doubles and 4 bytes per window
/// for the features; the caller holds at most one group's windows. Thread: one at a time (offline or
/// the daemon's training mode). Allocates; throws ptda::Error on a wrong length, a non-finite sample,
/// a call out of order or (finish) fewer than 3 groups.
class ClassBaselineBuilder {
 public:
  /// `spill`: where the per-window leave-one-out features go beyond spill.memory_bytes per feature
  /// (memory does not grow with the class's windows; docs/cli.md, `ptda train`, "Memory").
  ClassBaselineBuilder(const SegmentClass& segment, std::size_t window_len, const ThresholdPolicy& policy,
                       const SpillConfig& spill = {});
  ~ClassBaselineBuilder();
  ClassBaselineBuilder(ClassBaselineBuilder&&) noexcept;
  ClassBaselineBuilder& operator=(ClassBaselineBuilder&&) noexcept;
  ClassBaselineBuilder(const ClassBaselineBuilder&) = delete;
  ClassBaselineBuilder& operator=(const ClassBaselineBuilder&) = delete;

  /// Pass 1: adds one window to the class's sums.
  void add_to_mean(std::span<const float> x);
  /// Ends pass 1 (needs at least one window).
  void finish_mean();
  /// The class baseline so far: segment, n_windows, means, TDA spectrum, line groups (after
  /// finish_mean()); thresholds and stats are set by finish().
  [[nodiscard]] const ClassBaseline& means() const noexcept;
  /// Pass 2: scores each window of one group against the means of all pass-1 windows outside it (the
  /// group's windows must be among them). `recordings`: the recording (day) of each window, or empty.
  void score_group(std::span<const std::span<const float>> windows,
                   std::span<const std::uint32_t> recordings);
  /// Ends pass 2 and returns the class baseline.
  [[nodiscard]] ClassBaseline finish();

 private:
  struct State;
  std::unique_ptr<State> s_;
};

/// Builds one class baseline from its M healthy windows (each of length N):
///  - mean_magnitude = mean |X_i| (eq. 7) and tda_mean = mean x_i (eq. 5) over all M windows;
///  - thresholds and stats per method from leave-one-group-out features: window i is scored against
///    the means of the windows whose group differs from groups[i] (groups = constant-speed region, so
///    overlapping windows of one cycle never enter each other's average either); a window is never
///    part of its own |D_avg|. Empty groups: every window is its own group.
///  - day_spread per method: variance_components() of the leave-one-out ln(rms_res) and entropy_res with
///    `recordings` (the training recording, i.e. day, of each window; empty = one recording) as groups;
///    the between-day sd used pools the estimate with the prior policy.day_sd_floor * within sd
///    (((R - 1) estimate^2 + prior^2) / R), and the bands are widened by it (fit_band()).
/// Band lower ends are clamped at 0 (both features are non-negative).
/// Throws ptda::Error when there are no windows, fewer than 3 groups, groups.size() is neither 0 nor M,
/// recordings.size() is neither 0 nor M, a window has the wrong length or a non-finite sample (naming the
/// window and sample), or N is not a RealFft length. Thread: any (offline or the daemon's training mode).
/// Allocates; O(M) FFTs, memory O(N) beyond the windows.
[[nodiscard]] ClassBaseline build_class_baseline(const SegmentClass& segment,
                                                 const std::vector<std::vector<float>>& windows,
                                                 std::span<const std::uint64_t> groups,
                                                 const ThresholdPolicy& policy,
                                                 std::span<const std::uint32_t> recordings = {});

}  // namespace ptda::dsp
