// Learning a class baseline from healthy windows (offline or in the daemon's training mode; allocates).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "ptda/dsp/baseline.hpp"

namespace ptda::dsp {

/// Fits a two-sided band to healthy feature values according to the policy. Needs >= 2 values.
/// Throws ptda::Error when there are too few values.
[[nodiscard]] Band fit_band(std::span<const double> values, const ThresholdPolicy& policy);

/// Summary statistics of values (population of the training set; stddev with n-1).
[[nodiscard]] FeatureStats feature_stats(std::span<const double> values);

/// Builds one class baseline from its M healthy windows (each of length N):
///  - mean_magnitude = mean |X_i| (eq. 7) and tda_mean = mean x_i (eq. 5) over all M windows;
///  - thresholds and stats per method from leave-one-group-out features: window i is scored against
///    the means of the windows whose group differs from groups[i] (groups = constant-speed region, so
///    overlapping windows of one cycle never enter each other's average either); a window is never
///    part of its own |D_avg|. Empty groups: every window is its own group.
/// Throws ptda::Error when fewer than 3 groups, or a window has the wrong length.
[[nodiscard]] ClassBaseline build_class_baseline(const SegmentClass& segment,
                                                 const std::vector<std::vector<float>>& windows,
                                                 std::span<const std::uint64_t> groups,
                                                 const ThresholdPolicy& policy);

}  // namespace ptda::dsp
