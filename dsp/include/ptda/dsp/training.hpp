// Learning a class baseline from healthy windows (offline or in the daemon's training mode; allocates).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "ptda/dsp/baseline.hpp"

namespace ptda::dsp {

/// Phi^{-1}(p): the standard normal quantile (a rational starting guess refined by Halley steps on
/// std::erfc; Phi(result) matches p to ~1e-12 relative in the tail, tested down to p = 1e-200).
/// Thread: any. Never allocates, except the message of the ptda::Error thrown when p is not in (0, 1).
[[nodiscard]] double inverse_normal_cdf(double p);

/// Fits a two-sided band to healthy feature values according to the policy. Needs >= 2 values.
///  - kGaussian: mean +- z stddev with z = Phi^{-1}(1 - alpha/2), alpha = policy.false_alarm_rate;
///  - kQuantile: linear-interpolated sample quantiles at alpha/2 and 1 - alpha/2 (h = (n-1) q);
/// then both ends move out by policy.margin * (hi - lo).
/// Throws ptda::Error when there are too few values, a value is not finite, alpha is not in (0, 1)
/// or the margin is negative. Thread: any. Allocates (kQuantile sorts a copy).
[[nodiscard]] Band fit_band(std::span<const double> values, const ThresholdPolicy& policy);

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
