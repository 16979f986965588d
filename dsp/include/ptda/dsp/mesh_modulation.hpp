// The gear mesh's own amplitude and phase modulation at the input-shaft rate (`am`, `pm`; the mesh
// detector, `[decision] mesh_cusum`, docs/method.md §6 "Mesh detector", measured in §8 "Session 18").
//
// A local defect on a tooth of the input pinion disturbs the mesh once per revolution of its shaft:
// the mesh lines' amplitude dips and their phase slips, every revolution. PTDA subtracts those lines,
// so the residual features see little of it. Here each mesh harmonic h (GMF = z_in f_in) that is a line
// of the class mean is demodulated from the window's own spectrum: the bins over (h - 1/2 .. h + 1/2)
// GMF, carrier moved to 0 Hz, give the band's analytic signal z_h at a decimated rate (one inverse
// complex FFT of a few hundred points). am_h = |z_h| / mean|z_h| - 1 and pm_h = (unwrapped phase of
// z_h, linear trend removed) / h are averaged over the harmonics, and each feature is the
// autocorrelation of that average at lags of one and two input-shaft revolutions (those that leave at
// least one revolution of overlap), over its zero-lag value: about 0 for a stationary modulation,
// towards 1 for one that repeats every revolution. Both are ratios (gain-invariant).
#pragma once

#include <complex>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <span>
#include <vector>

#include "ptda/dsp/baseline.hpp"

namespace ptda::dsp {

inline constexpr std::uint32_t kMeshMaxHarmonics = 6;  ///< mesh harmonics demodulated, at most
inline constexpr std::uint32_t kMeshMaxLags = 2;       ///< revolutions of lag, at most
/// A window needs this many input-shaft revolutions for the features (below: NaN, not scored).
inline constexpr double kMeshMinRevolutions = 2.0;
inline constexpr std::size_t kMeshFeatureCount = 2;  ///< am, pm (indices of MeshValues::v)

[[nodiscard]] constexpr const char* mesh_feature_name(std::size_t i) noexcept {
  return i == 0 ? "am" : (i == 1 ? "pm" : "?");
}

/// The name of feature index f of the decision's fields (WindowResult::mesh_feature): "none" for -1.
[[nodiscard]] constexpr const char* mesh_feature_label(std::int32_t f) noexcept {
  return f >= 0 ? mesh_feature_name(static_cast<std::size_t>(f)) : "none";
}

/// One window's mesh features: v[0] = am, v[1] = pm; NaN when the window holds fewer than
/// kMeshMinRevolutions input-shaft revolutions, no mesh harmonic is a line of the class mean, or the
/// window's speed is outside the range the demodulator was sized for.
struct MeshValues {
  double v[kMeshFeatureCount] = {std::numeric_limits<double>::quiet_NaN(),
                                 std::numeric_limits<double>::quiet_NaN()};
  std::uint32_t harmonics = 0;  ///< mesh harmonics averaged
  [[nodiscard]] bool valid() const noexcept { return harmonics > 0; }
};

/// What a class's demodulator is sized for.
struct MeshGeometry {
  std::size_t window_len = 0;    ///< N
  double fs_hz = 0.0;            ///< sample rate
  std::uint32_t z_in = 0;        ///< teeth of the input pinion (the mesh frequency is z_in f_in)
  double ratio = 0.0;            ///< input-shaft speed / joint speed (GearboxInfo::ratio)
  double speed_rad_s = 0.0;      ///< the class's |joint speed| (its line harmonics are counted there)
  double speed_max_rad_s = 0.0;  ///< largest |joint speed| a window of the class may have
};

/// Input-shaft rotation frequency at joint speed speed_rad_s: ratio |speed| / (2 pi). Thread: any.
[[nodiscard]] double input_shaft_hz(double ratio, double speed_rad_s) noexcept;

/// One class's mesh demodulator: plan and buffers made at construction, nothing allocated after.
class MeshDemodulator {
 public:
  /// `mean_magnitude` is the class's healthy mean |X[k]|, k = 0..N/2: a harmonic is demodulated only
  /// where it is a line of it (find_line_groups() within one bin of h GMF). Throws ptda::Error naming
  /// the value when the geometry is unusable (N not even or < 8, fs, ratio or speed not > 0, z_in = 0,
  /// mean_magnitude not N/2 + 1 bins). Thread: any (setup). Allocates.
  MeshDemodulator(const MeshGeometry& geometry, std::span<const float> mean_magnitude);
  ~MeshDemodulator();
  MeshDemodulator(MeshDemodulator&&) noexcept;
  MeshDemodulator& operator=(MeshDemodulator&&) noexcept;
  MeshDemodulator(const MeshDemodulator&) = delete;
  MeshDemodulator& operator=(const MeshDemodulator&) = delete;

  /// The features of the window whose one-sided spectrum X[k], k = 0..N/2 (RealFft::forward) is
  /// `spectrum`, at the window's own joint speed. A wrong spectrum size gives NaN.
  /// Thread: the owner's. Never allocates, throws or blocks.
  [[nodiscard]] MeshValues compute(std::span<const std::complex<float>> spectrum,
                                   double speed_rad_s) noexcept;

  /// Length of the decimated analytic signal (a 2-3-5 length >= twice the widest band).
  [[nodiscard]] std::size_t decimated_len() const noexcept;
  /// Mesh harmonics that are lines of the class mean at the class's speed (0: the class gets no mesh
  /// features). Thread: any.
  [[nodiscard]] std::uint32_t line_harmonics() const noexcept;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// The geometry of class `seg` of a baseline with sample rate fs_hz, window length window_len and gearbox
/// g: speeds up to the class's speed plus its tolerance. Thread: any. Never throws (the demodulator
/// checks it).
[[nodiscard]] MeshGeometry mesh_geometry(double fs_hz, std::size_t window_len, const GearboxInfo& g,
                                         const SegmentClass& seg) noexcept;

/// Fewest training windows with mesh features for a class's mesh statistics (fewer: windows = 0).
inline constexpr std::uint32_t kMeshMinTrainingWindows = 5;

/// Parameters of the mesh CUSUM ([decision] mesh_* keys, config/README.md). Off by default: it needs a
/// baseline trained with it (format 8) and the gearbox's tooth counts.
struct MeshCusumConfig {
  /// `mesh_cusum`: on by default since session 37 (opt-in in sessions 19-36). On by default it runs only
  /// where it can (time domain, the gearbox's teeth and ratio known, a baseline with mesh statistics)
  /// and is off elsewhere with a notice.
  bool enabled = true;
  /// The configuration said `mesh_cusum = true` itself: then a baseline without mesh statistics, a
  /// gearbox without teeth or the order domain is an error, not a silent fallback.
  bool required = false;
  /// `mesh_cusum_k`: reference value in total sds per window (1 in sessions 19-37; 0.75 with the step
  /// cap since session 38, docs/method.md §8 "Session 38").
  double k = 0.75;
  double h = 10.0;  ///< `mesh_cusum_h`: alarm when a feature's statistic exceeds h
  /// `mesh_cusum_one_day_allowance`: extra k in between-day sds for a class trained on one recording,
  /// whose between-day sd is only the day_sd_floor prior (docs/method.md §8 "Session 19": one day of
  /// training under-states the mesh features' day-to-day spread). With two or more recordings the
  /// estimated between-day sd is in the total sd and nothing is added.
  double one_day_allowance = 1.0;
  double step_cap = 2.5;  ///< `mesh_cusum_step_cap`: largest step one window adds
};

/// Throws ptda::Error naming the [decision] key unless 0 < k <= 10, 0 < h <= 1000,
/// 0 <= one_day_allowance <= 10 and 0 < step_cap <= 1000. Thread: any. Allocates only the message.
void check_mesh_cusum(const MeshCusumConfig& cfg);

/// How one class standardises its mesh features (as BandScale): z = (v - mean) / sd with
/// sd = sqrt(within_sd^2 + between_sd^2), minus allowance = q x between_sd x sqrt(1 + 1/R) / sd with
/// q = one_day_allowance for a class trained on one recording (R <= 1), else 0. active = 0 where the
/// class has no statistics for the feature (windows 0).
struct MeshScale {
  double mean[kMeshFeatureCount] = {};
  double sd[kMeshFeatureCount] = {};
  double allowance[kMeshFeatureCount] = {};
  bool active[kMeshFeatureCount] = {};
  [[nodiscard]] bool any() const noexcept { return active[0] || active[1]; }
};
/// The MeshScale of class c (all inactive when c has no mesh statistics). Thread: any. Never throws.
[[nodiscard]] MeshScale mesh_scale(const ClassBaseline& c, double one_day_allowance) noexcept;

/// Autocorrelation of x - mean(x) at lags round(m samples_per_rev), m = 1..kMeshMaxLags with
/// m samples_per_rev <= x.size() - samples_per_rev, each the mean lag product over its overlap, over the
/// mean square; their mean. NaN when no lag fits or x is constant. Thread: any. Never allocates.
[[nodiscard]] double revolution_autocorrelation(std::span<const double> x, double samples_per_rev) noexcept;

}  // namespace ptda::dsp
