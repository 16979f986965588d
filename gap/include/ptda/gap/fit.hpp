// Least-squares fits of the calibration (docs/gap.md "Calibration"): small dense problems solved with
// Eigen. Offline: any thread, allocates.
#pragma once

#include <vector>

namespace ptda::gap {

/// One harmonic level difference (real - model, dB) of GMF order `order` in a class run at
/// `speed_rad_s` (signed: the sign is the direction of rotation).
struct LevelObservation {
  int order = 0;
  double speed_rad_s = 0.0;
  double diff_db = 0.0;
};

struct SpeedLawFit {
  /// Change of the amplitude's speed exponent: dB of level per dB of speed (20 log10 |speed|).
  double exponent_step = 0.0;
  /// False when the data cannot separate a speed law from the per-order and per-direction offsets (no
  /// direction with two distinct speeds among the observations); exponent_step is then 0.
  bool identifiable = false;
  /// Within-direction sum of squares of 20 log10 |speed| left after the offsets (dB^2): the slope's
  /// information. A class counts once per observation.
  double speed_ss_db2 = 0.0;
};

/// Fits diff_db = a_order + g_direction + exponent_step * 20 log10 |speed_rad_s| by least squares over
/// all observations: per-order offsets (the calibration's free GMF amplitudes) and a level per
/// direction (a load that differs between directions) are nuisance terms, profiled out exactly
/// (Frisch-Waugh: the slope from the residuals of the speed term and of the data after projecting both
/// on the nuisance columns, with a complete orthogonal decomposition so that nuisance columns confounded
/// with each other do no harm). Observations with a zero or non-finite speed or difference are ignored.
/// With every class seen at every order this equals the pooled within-direction regression of the
/// class means on 20 log10 |speed|; with cells missing, it stays unbiased where class means are not.
[[nodiscard]] SpeedLawFit fit_speed_law(const std::vector<LevelObservation>& obs);

}  // namespace ptda::gap
