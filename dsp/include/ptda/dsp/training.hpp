// Learning a class baseline from healthy windows (offline or in the daemon's training mode; allocates).
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "ptda/dsp/baseline.hpp"

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
/// Throws ptda::Error when there are too few values, a value is not finite, alpha is not in (0, 1)
/// or the margin is negative. Thread: any. Allocates (kQuantile sorts a copy).
[[nodiscard]] Band fit_band(std::span<const double> values, const ThresholdPolicy& policy,
                            FeatureScale scale = FeatureScale::kLinear);

/// Problems with the amount of training data for the policy's false-alarm rate, one sentence each,
/// saying how many windows would be needed: kQuantile needs n >= 2 / alpha leave-one-out values per
/// class (else the band is the sample range); kGaussian and kTolerance warn when the tolerance factor
/// for n exceeds the asymptotic z by more than 20 % (the band rests on few windows: kGaussian then
/// promises a rate it cannot know, kTolerance is that much wider); a hold-out of m windows can only
/// show a rate >= 3 / m (95 % bound with none abnormal). Thread: any. Allocates.
[[nodiscard]] std::vector<std::string> training_warnings(const Baseline& baseline);

/// Summary statistics of values (population of the training set; stddev with n-1, 0 for n < 2;
/// all zero with n = 0 for no values). Thread: any. Never allocates or throws.
[[nodiscard]] FeatureStats feature_stats(std::span<const double> values);

/// Builds one class baseline from its M healthy windows (each of length N):
///  - mean_magnitude = mean |X_i| (eq. 7) and tda_mean = mean x_i (eq. 5) over all M windows;
///  - thresholds and stats per method from leave-one-group-out features: window i is scored against
///    the means of the windows whose group differs from groups[i] (groups = constant-speed region, so
///    overlapping windows of one cycle never enter each other's average either); a window is never
///    part of its own |D_avg|. Empty groups: every window is its own group.
/// Band lower ends are clamped at 0 (both features are non-negative).
/// Throws ptda::Error when there are no windows, fewer than 3 groups, groups.size() is neither 0 nor M,
/// a window has the wrong length or a non-finite sample (naming the window and sample), or N is not a
/// RealFft length. Thread: any (offline or the daemon's training mode). Allocates; O(M) FFTs, memory
/// O(N) beyond the windows.
[[nodiscard]] ClassBaseline build_class_baseline(const SegmentClass& segment,
                                                 const std::vector<std::vector<float>>& windows,
                                                 std::span<const std::uint64_t> groups,
                                                 const ThresholdPolicy& policy);

}  // namespace ptda::dsp
