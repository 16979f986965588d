// The healthy reference learned by training: one ClassBaseline per recurring constant-speed segment.
// Persisted by formats/baseline_file.hpp; consumed read-only by the monitor path.
#pragma once

#include <array>
#include <complex>
#include <cstdint>
#include <string>
#include <vector>

#include "ptda/dsp/types.hpp"

namespace ptda::dsp {

/// Closed interval [lo, hi]; a feature outside it makes a window abnormal.
struct Band {
  double lo = 0.0;
  double hi = 0.0;
  [[nodiscard]] bool contains(double v) const noexcept { return v >= lo && v <= hi; }
};

struct FeatureThresholds {
  Band rms;
  Band entropy;
};

/// Distribution of one feature over the (leave-one-out) healthy training windows.
struct FeatureStats {
  double mean = 0.0;
  double stddev = 0.0;
  double min = 0.0;
  double max = 0.0;
  std::uint32_t n = 0;
};

/// How thresholds are set from the healthy leave-one-out feature distribution (docs/method.md,
/// "Thresholds").
struct ThresholdPolicy {
  enum class Kind : std::uint8_t {
    kGaussian = 0,   ///< mean +- z * stddev, z from the two-sided false-alarm target
    kQuantile = 1,   ///< empirical quantiles alpha/2 and 1-alpha/2, widened by margin
    kTolerance = 2,  ///< normal tolerance limits with confidence `confidence` for n values: rms_res
                     ///< on log(rms_res), one-sided limits at 1-alpha; entropy two-sided at 1-alpha
  };
  Kind kind = Kind::kTolerance;    ///< default: holds best on held-out healthy data (docs/method.md §8)
  double false_alarm_rate = 1e-3;  ///< per window and per feature, two-sided
  double margin = 0.0;             ///< extra relative widening of the band (0.1 = 10 % of its width)
  double confidence = 0.9;         ///< kTolerance: probability that the limits cover 1 - alpha
  /// Fraction of each class's training windows (the latest cycles) held out of the fit and used to
  /// measure the false-alarm rate of the bands that are stored (0 = none).
  double holdout_fraction = 0.0;
  /// PTDA with a per-window gain on each line group of the healthy mean spectrum (`[monitor]
  /// line_gain`, docs/method.md §3): a harmonic whose level moved with load or temperature leaves no
  /// residual, sidebands, impacts and the floor still do. Stored in the baseline (format >= 3) because
  /// the bands are only valid for the residual they were trained on. On by default since session 5
  /// (docs/method.md §8: a new day's harmonic levels no longer alarm); false is the paper's PTDA.
  bool ptda_line_gain = true;
  /// PTDA with a per-window gain on the floor (`[monitor] floor_gain`, docs/method.md §2): the bins
  /// outside every line group get the window's own floor gain g_f (the median of |X[k]| / a[k] over
  /// them), and the features are those of the level-referred residual (each line group's part divided
  /// by its gain, the floor's by g_f, within a 6 dB allowance), so a floor or a line that is a few
  /// percent higher on another day is not read as a defect. Sidebands and impacts are sparse and move
  /// the median little. Stored in the baseline (format >= 3, option bit 1). On by default since
  /// session 6 (docs/method.md §2 and §8).
  bool ptda_floor_gain = true;
  /// The between-day (between-recording) standard deviation of each feature assumed when a class was
  /// trained on one recording, as a fraction of its within-day sd (`[thresholds] day_sd_floor`,
  /// docs/method.md §5; default measured there). With several recordings the random-effects estimate
  /// is used instead. 0 = one recording is taken to show the whole spread (the session-6 bands).
  double day_sd_floor = 0.3;
  /// Cover each training recording (`[thresholds] cover_recordings`, docs/method.md §5, session 9): with
  /// two or more recordings, each band is the union of the pooled band (above) and, per recording, the
  /// band fitted on that recording's leave-one-out values alone (same method, no between-day widening).
  /// The pooled model assumes one within-day sd for every day and Gaussian day offsets; a healthy
  /// recording whose spread is larger or whose level is further out (e.g. the top of a load cycle) then
  /// lies partly outside the pooled band, i.e. the baseline would flag its own healthy training data.
  /// On by default since session 10 (docs/method.md §5: on the second generator's fresh seeds it kept
  /// every detection and removed the drift soak's false alarms). Not stored in the baseline file; the
  /// bands it gives are.
  bool cover_recordings = true;
  /// Band-energy statistics for the band CUSUM (`[decision] band_cusum`, docs/method.md §6 "Band
  /// detector"): training computes, per class, the leave-one-out ln energy of the referred PTDA residual
  /// in this many equal bands of bins 1..N/2 (clean floor bins only; dsp/band_energy.hpp) and stores
  /// them (baseline format 7). 0 = none (format <= 6, byte-identical to before).
  std::uint32_t band_count = 0;
  /// Mesh-modulation statistics for the mesh CUSUM (`[decision] mesh_cusum`, docs/method.md §6 "Mesh
  /// detector"): training computes, per class, the am and pm features of every fit window
  /// (dsp/mesh_modulation.hpp; needs the gearbox's z_in and ratio) and stores their day spread (baseline
  /// format 8). false = none (format <= 7, byte-identical to before).
  bool mesh_stats = false;
};

/// Largest band count of the band CUSUM (fixed capacity of its run-time state).
inline constexpr std::uint32_t kMaxBands = 64;

/// One band's healthy distribution of ln band energy in one class (format >= 7). Units: ln(energy).
struct BandEnergyStats {
  double mean = 0.0;         ///< grand mean over the leave-one-out training windows
  double within_sd = 0.0;    ///< pooled within-recording sd (MSW^1/2; one recording: the sample sd)
  double between_est = 0.0;  ///< random-effects estimate of the between-day sd (0 for 1 recording)
  /// The between-day sd used: max(between_est, day_sd_floor * within_sd).
  double between_sd = 0.0;
  std::uint32_t clean_bins = 0;  ///< clean floor bins of the band (0: the band is not used)
};

/// Within- and between-day (between-recording) spread of one method's features in one class
/// (docs/method.md §5): a one-way random-effects decomposition of the leave-one-out features with the
/// training recordings as groups. Standard deviations in the features' model units: ln(rms_res) and
/// entropy_res. All 0 in baselines of format <= 3 (read as: within = the stats' stddev, no between).
struct DaySpread {
  std::uint32_t recordings = 0;      ///< training recordings (days) with windows in the class
  double log_rms_within_sd = 0.0;    ///< pooled within-recording sd of ln(rms_res) (MSW^1/2)
  double log_rms_between_est = 0.0;  ///< random-effects estimate of the between-day sd (0 for 1 recording)
  double log_rms_between_sd = 0.0;  ///< the one used: the estimate, or day_sd_floor * within sd (1 recording)
  double entropy_within_sd = 0.0;
  double entropy_between_est = 0.0;
  double entropy_between_sd = 0.0;
};

/// One mesh feature's healthy distribution in one class (format >= 8): am or pm (mesh_modulation.hpp).
struct MeshFeatureStats {
  double mean = 0.0;          ///< grand mean over the training windows that have the feature
  double within_sd = 0.0;     ///< pooled within-recording sd (one recording: the sample sd)
  double between_est = 0.0;   ///< random-effects estimate of the between-day sd (0 for 1 recording)
  double between_sd = 0.0;    ///< the one used: max(between_est, day_sd_floor * within_sd)
  std::uint32_t windows = 0;  ///< training windows with the feature (0: the class has no mesh detector)
};

/// Bins [begin, end) of one spectral line of the healthy mean magnitude (with its leakage skirt).
struct LineGroup {
  std::uint32_t begin = 0;
  std::uint32_t end = 0;
};

/// The bands of one method measured on held-out healthy windows of its class (never part of the
/// class's means or bands). All counts 0 when there was no hold-out.
struct HoldoutStats {
  std::uint32_t windows = 0;      ///< held-out windows scored
  std::uint32_t abnormal = 0;     ///< of them: gear-fault abnormal (rms above or entropy outside)
  std::uint32_t rms_high = 0;     ///< rms_res above its band
  std::uint32_t rms_low = 0;      ///< rms_res below its band (low residual: not a gear fault)
  std::uint32_t entropy_out = 0;  ///< entropy_res outside its band
  double z_rms_mean = 0.0;        ///< mean and sd of the standardised log rms_res (sequential input)
  double z_rms_sd = 0.0;
  double z_entropy_mean = 0.0;  ///< mean and sd of the standardised entropy_res
  double z_entropy_sd = 0.0;
};

/// A recurring constant-speed segment of the job: a window is only compared with its own class.
struct SegmentClass {
  std::uint32_t id = 0;
  std::int8_t direction = 1;     ///< +1 or -1 (sign of the joint speed)
  double speed_rad_s = 0.0;      ///< mean |speed| of the class's regions
  double speed_tol_rad_s = 0.0;  ///< a window matches when | |speed| - speed_rad_s | <= this
  double duration_s = 0.0;       ///< median constant-speed region length seen in training
  std::uint32_t regions = 0;     ///< training regions (cycles) in the class
};

/// Healthy reference of one segment class, for every method.
struct ClassBaseline {
  SegmentClass segment;
  std::uint32_t n_windows = 0;                               ///< healthy windows M averaged
  std::vector<float> mean_magnitude;                         ///< |D_avg[k]| (eq. 7), k = 0..N/2
  std::vector<float> tda_mean;                               ///< d[n] (eq. 5), n = 0..N-1
  std::array<FeatureThresholds, kMethodCount> thresholds{};  ///< indexed by Method
  std::array<FeatureStats, kMethodCount> rms_stats{};        ///< leave-one-out, indexed by Method
  std::array<FeatureStats, kMethodCount> entropy_stats{};
  /// Leave-one-out statistics of ln(rms_res): the sequential detector standardises with them.
  std::array<FeatureStats, kMethodCount> log_rms_stats{};
  std::array<HoldoutStats, kMethodCount> holdout{};
  /// Within- and between-day spread per method (format >= 4): bands and the sequential detector's
  /// scale and allowance use it (docs/method.md §5, §6).
  std::array<DaySpread, kMethodCount> day_spread{};
  double windows_per_hour = 0.0;  ///< training windows of this class per hour of recording
  /// Band-energy statistics (policy.band_count entries; empty when the baseline has none, format <= 6).
  std::vector<BandEnergyStats> band_stats;
  std::uint32_t band_recordings = 0;  ///< training recordings (days) behind band_stats
  /// Mesh-modulation statistics, am then pm (2 entries when policy.mesh_stats, else empty). A class
  /// too slow for two input-shaft revolutions per window, or without a mesh line, has windows = 0.
  std::vector<MeshFeatureStats> mesh_stats;
  std::uint32_t mesh_recordings = 0;  ///< training recordings (days) behind mesh_stats
  /// Runtime only (not stored): the line groups of mean_magnitude when the policy asks for PTDA line
  /// gains (find_line_groups(), filled by prepare_line_groups()), else empty = the paper's PTDA.
  std::vector<LineGroup> line_groups;
  /// Runtime only (not stored): DFT(tda_mean), k = 0..N/2 (prepare_line_groups()), so TDA needs no
  /// second transform per window. Empty = not prepared (the analyzer then transforms tda_mean).
  std::vector<std::complex<float>> tda_spectrum;
  /// Runtime only (not stored): the policy's ptda_floor_gain, set by prepare_line_groups() and by
  /// training, so analyze() needs only the class.
  bool floor_gain = false;
  /// Runtime only (not stored): a 64-bit fingerprint of what prepare_line_groups() derived the three
  /// fields above from (mean_magnitude, tda_mean, the policy's line and floor gain flags); 0 = never
  /// prepared. A second call on an unchanged class (the baseline reader's copy handed to the engine)
  /// then skips find_line_groups() and the transform (issue 13).
  std::uint64_t prepared_key = 0;
};

/// Gearbox description, kept in the baseline so a report can name the mesh frequencies.
struct GearboxInfo {
  enum class Kind : std::uint8_t { kCycloidal = 0, kParallel = 1, kUnknown = 2 };
  Kind kind = Kind::kUnknown;
  std::uint32_t z_in = 0;    ///< cycloidal: input gear teeth; parallel: pinion (driving) teeth
  std::uint32_t z_spur = 0;  ///< cycloidal: spur gear teeth; parallel: driven gear teeth
  std::uint32_t z_pin = 0;   ///< cycloidal: pins; parallel: 0
  double ratio = 0.0;        ///< input shaft speed / output (joint) speed (eq. 1 for cycloidal)
};

/// A recording the baseline was trained on (baseline format >= 2), so a monitor run can tell when it
/// judges its own training data. Times are UNIX seconds of the windows actually used.
struct TrainingRecording {
  std::string id;             ///< content fingerprint of the vibration file (cli::recording_id)
  std::string path;           ///< the recording directory as given to the trainer (for messages only)
  double from_unix_s = 0.0;   ///< start of the first window used
  double to_unix_s = 0.0;     ///< end of the last window used
  std::uint32_t windows = 0;  ///< windows used from this recording
};

/// The axis the windows were cut on (`[extraction] domain`, docs/method.md §9).
enum class Domain : std::uint8_t {
  kTime = 0,   ///< constant-speed windows of N time samples (the paper's PTDA)
  kOrder = 1,  ///< windows of R input-shaft revolutions resampled to S samples per revolution
};
[[nodiscard]] constexpr const char* domain_name(Domain d) noexcept {
  return d == Domain::kOrder ? "order" : "time";
}

struct Baseline {
  double fs_hz = 0.0;            ///< time domain: sample rate; order domain: S (samples per revolution)
  std::uint32_t window_len = 0;  ///< N samples per window (order domain: R S)
  /// Format >= 5 stores the domain; older files are time domain. Order domain: samples_per_rev S and
  /// revolutions R of the windows (0 in the time domain).
  Domain domain = Domain::kTime;
  std::uint32_t samples_per_rev = 0;
  std::uint32_t revolutions = 0;
  /// Order domain, format >= 6 (docs/method.md §9 "Speed law"): the window RMS grows as |speed|^p
  /// within a class. speed_law_fit / speed_law_se: the pooled within-class fit on the healthy windows;
  /// speed_law_exponent: the p applied (the fit when significant, |fit| > 2 se, else 0). A window at
  /// joint speed v judged against class c is multiplied by (v_c / |v|)^p first, in training and in
  /// MonitorEngine. Always 0 in the time domain.
  double speed_law_exponent = 0.0;
  double speed_law_fit = 0.0;
  double speed_law_se = 0.0;
  GearboxInfo gearbox;
  ThresholdPolicy policy;
  std::vector<ClassBaseline> classes;
  std::string source;  ///< free text: what it was trained on (recording path, tool version)
  std::vector<TrainingRecording> training;  ///< empty when unknown (format version 1, field training)

  /// The class matching a window's speed and direction, or nullptr. Picks the closest speed when
  /// several match. Thread: any. Never allocates.
  [[nodiscard]] const ClassBaseline* match(double speed_rad_s) const noexcept {
    const ClassBaseline* best = nullptr;
    double best_d = 0.0;
    const std::int8_t dir = speed_rad_s < 0.0 ? -1 : 1;
    const double mag = speed_rad_s < 0.0 ? -speed_rad_s : speed_rad_s;
    for (const auto& c : classes) {
      if (c.segment.direction != dir) continue;
      const double d =
          mag > c.segment.speed_rad_s ? mag - c.segment.speed_rad_s : c.segment.speed_rad_s - mag;
      if (d <= c.segment.speed_tol_rad_s && (best == nullptr || d < best_d)) {
        best = &c;
        best_d = d;
      }
    }
    return best;
  }
};

}  // namespace ptda::dsp
