// Probes: documented comparisons of a measured and a simulated recording, each element normalised by a
// fixed scale so that squared differences add up (docs/gap.md, "Probes"). Offline: any thread, allocates.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "ptda/gap/signals.hpp"
#include "ptda/sim/simulator.hpp"

namespace ptda::gap {

enum class Stage : std::uint8_t { kRaw = 0, kResidual = 1, kAlarm = 2, kAveraging = 3 };
[[nodiscard]] const char* stage_name(Stage s) noexcept;

struct ProbeElement {
  /// harmonics, sidebands, coherence, phase_coherence, noise_floor, lines, transients, amplitude,
  /// residual, tracking
  std::string probe;
  std::string key;  ///< unique within the probe, e.g. "c0.k5" or "constant.b12"
  double value = 0.0;
  double scale = 1.0;    ///< normalisation: z = (real - sim) / scale
  double f_lo_hz = 0.0;  ///< frequency range the element describes (0, 0: not frequency-specific)
  double f_hi_hz = 0.0;
  SegmentType segment = SegmentType::kConstant;
  Stage stage = Stage::kRaw;
  int order = 0;  ///< harmonics: GMF order
};

/// Per constant-speed class reference for the alarm probe (from the simulated recording).
struct ClassReference {
  std::vector<float> mean_magnitude;  ///< |DFT| averaged over the class's windows (PTDA eq. 7)
  double rms_mean = 0.0;              ///< leave-one-out residual rms over its windows
  double rms_std = 0.0;
};

/// Samples of the spectrum taken around each segment boundary's knock (the `transients` probe).
inline constexpr std::size_t kTransientLen = 512;

struct ProbeSet {
  std::vector<ProbeElement> elements;
  std::vector<ClassReference> classes;  ///< indexed like AnalysisPlan::speeds
  std::size_t windows = 0;
  double fs_hz = 0.0;  ///< the recording's rate (the floor tilt's pivot, sim::noise_tilt_pivot_hz)
  // For calibration and effect initialisation (averaged spectra in power, amplitude^2 of a sine).
  std::map<int, std::vector<double>> class_power;  ///< per constant class
  std::vector<double> accel_power;
  std::vector<double> still_power;
  /// Mean power spectrum of the kTransientLen samples around each segment boundary's largest difference
  /// (the `transients` probe's knock spectrum, bins fs / kTransientLen apart); empty without boundaries.
  std::vector<double> transient_power;
  double max_abs_ms2 = 0.0;
  /// Samples of the judged windows within 0.2 % of max_abs_ms2 (flat tops at the rails), and all their
  /// samples: the `amplitude` probe's extreme share.
  std::size_t rail_samples = 0;
  std::size_t window_samples = 0;
  double lag_s = 0.0;  ///< envelope-vs-CAN lag (NaN when the speed does not vary)
  /// Per constant class: share of windows whose PTDA residual rms is outside the reference's mean +- 3 sd
  /// (with a reference: the measured windows judged by the simulation's baseline). Not a gap element.
  std::map<int, double> alarm_rate;
};

struct ProbeContext {
  sim::GearboxSpec gearbox;
  std::vector<int> nominal_orders;        ///< GMF orders with a non-zero nominal amplitude
  std::vector<int> nominal_shaft_orders;  ///< input-shaft orders with a non-zero nominal line amplitude
  AnalysisPlan plan;
};

/// Probes over the windows whose cycle is selected (`use_cycle` empty: all). With `reference` the alarm
/// probe is computed against it (the measured recording judged by the simulation's baseline); without,
/// against the set's own leave-one-out statistics.
[[nodiscard]] ProbeSet compute_probes(const GapRecording& rec, const std::vector<Segment>& segs,
                                      const std::vector<Window>& windows, const std::vector<char>& use_cycle,
                                      const ProbeContext& ctx, const ProbeSet* reference = nullptr);

/// The speed frames' scale against the shaft's true speed, read off the measured lines (the nominal's
/// GMF orders and shaft orders) in every constant-speed class: the weighted median of f_meas / f_expected - 1
/// over lines >= 12 dB above their local floor. First from the lines whose search range (+-2 `tolerance`)
/// stays within 0.4 x the distance to the nearest other listed line, then from every line, searched within
/// 3 bins + 3 sd of where that first estimate puts it. Weights (f / df)^2: a high line tells the ratio
/// more precisely. Fewer than 2 lines in the first pass: nothing. docs/gap.md, step 1b.
struct SpeedScaleEstimate {
  double ppm = 0.0;     ///< (true / frame speed - 1) * 1e6
  double sd_ppm = 0.0;  ///< spread of the lines' ratios (1.4826 weighted MAD / sqrt(lines))
  int lines = 0;        ///< lines used
};
/// `ps` is a probe set of the measured recording (its class_power). Any thread; allocates.
[[nodiscard]] SpeedScaleEstimate estimate_speed_scale(const ProbeSet& ps, const ProbeContext& ctx,
                                                      double tolerance);

/// Element-wise mean of two probe sets of the same recording (e.g. its even and odd cycles): values of
/// elements present in both, averaged spectra, the first set's class references. Any thread; allocates.
[[nodiscard]] ProbeSet average_probes(const ProbeSet& a, const ProbeSet& b);

/// Where a gap lies.
struct GapBreakdown {
  double total = 0.0;
  std::map<std::string, double> by_probe;
  std::map<std::string, double>
      by_band;  ///< octave bands "lo-hi Hz" by element centre; "broadband" otherwise
  std::map<std::string, double> by_segment;
  std::map<std::string, double> by_stage;
  struct Top {
    std::string probe;
    std::string key;
    double real = 0.0;
    double sim = 0.0;
    double z = 0.0;
    double contribution = 0.0;
  };
  std::vector<Top> top;                    ///< largest contributions, descending (at most 12)
  std::vector<double> harmonic_offset_db;  ///< profiled-out per-order level offsets (real - sim), by order
  double noise_offset_db = 0.0;            ///< profiled-out noise-floor offset at the tilt pivot
  double noise_tilt_db_per_decade = 0.0;   ///< profiled-out noise-floor slope (real - sim)
  std::map<int, double>
      shaft_order_offset_db;  ///< profiled-out level offsets of the nominal shaft-order lines
  double expected = 0.0;      ///< gap expected from sampling alone (0 without a noise model)
  double expected_sd = 0.0;   ///< its standard deviation
};

/// Sampling variance per element ("probe/key" -> variance in the element's units) to add to its fixed
/// scale: z = diff / sqrt(scale^2 + variance).
using ElementVariance = std::map<std::string, double>;

/// gap = sum over probes of mean z^2 over the probe's elements, after profiling out the nominal model's
/// free parameters: per-order harmonic and shaft-order line level offsets (mean over classes) and the
/// noise floor's level and
/// slope (a robust line in dB against log10 frequency over the constant-speed bands: Theil-Sen slope,
/// median intercept at sim::noise_tilt_pivot_hz). Elements present on one side only are skipped. With
/// `noise`, each element's scale is widened by its sampling variance, and the breakdown carries the gap
/// expected from sampling alone and its standard deviation (chi-square approximation).
[[nodiscard]] GapBreakdown compare_probes(const ProbeSet& real, const ProbeSet& sim,
                                          const ElementVariance* noise = nullptr);

/// The per-element differences real - sim after profiling out the free parameters (as compare_probes
/// uses them), keyed "probe/key", plus the profiled-out offsets themselves ("calib/order.kK" per GMF
/// order, "calib/shaft.sJ" per nominal shaft order, "calib/noise_offset"; dB; "calib/noise_tilt",
/// dB/decade), whose jackknife variance is the
/// calibration's uncertainty.
[[nodiscard]] std::map<std::string, double> profiled_differences(const ProbeSet& real, const ProbeSet& sim);

/// Jackknife over cycles: the sampling variance of each element's profiled value when the probes use
/// all `cycles` cycles of `rec` (leave-one-cycle-out replicates compared with the all-cycle set).
[[nodiscard]] ElementVariance jackknife_variance(const GapRecording& rec, const std::vector<Segment>& segs,
                                                 const std::vector<Window>& windows, std::uint32_t cycles,
                                                 const ProbeContext& ctx);

/// Per noise_floor band of segment type `type` present in both sets, in the measured set's order: (band
/// centre Hz, measured − model − offset_db dB). Any thread; allocates.
[[nodiscard]] std::vector<std::pair<double, double>> floor_excess_db(const ProbeSet& real,
                                                                     const ProbeSet& sim, SegmentType type,
                                                                     double offset_db);

/// Floor-excess peaks after the largest: the local maxima over frequency of the measured − model − offset
/// noise_floor band levels (dB) of segment type `type`, by excess descending; only maxima at least
/// `min_db` above the model and at least an octave from every peak taken before (the largest included,
/// which is not returned). Band centres in Hz, at most `max_peaks`. Elements of one side only are
/// skipped. Any thread; allocates.
[[nodiscard]] std::vector<double> more_excess_peaks_hz(const ProbeSet& real, const ProbeSet& sim,
                                                       SegmentType type, double offset_db, double min_db,
                                                       std::size_t max_peaks);

/// Where the knock spectrum (ProbeSet::transient_power) exceeds the model's most, at bin resolution: the
/// measured / model power ratio is averaged over 5 bins (a knock's ring is tens of bins wide, a mesh
/// line 1-3), and the largest at or above `min_hz` (and below 0.45 fs) returned when it is at least
/// `min_db` above 1. 0 when the sets have no such spectrum, or nothing reaches `min_db`. Finer than the
/// probe's octaves: a ring at 1.83 kHz is the 1-2 kHz octave's excess, whose centre 1.41 kHz and the
/// screen's log grid left the fit to settle at 3.5 kHz (gen2). Any thread; allocates.
[[nodiscard]] double transient_excess_peak_hz(const ProbeSet& real, const ProbeSet& sim, double min_hz,
                                              double min_db);

/// A drive's switching carrier and its sidebands in a power spectrum: measured `real_power` against the
/// model's `model_power` (same bins, `df_hz` apart). Near a line found at `near_hz` (it may be the carrier
/// or one of its sidebands), the carrier is the local maximum of largest excess (dB) within
/// +-kDriveSearchHz that is at least `min_excess_db` above the model; the sideband spacing is that of the
/// strongest pair of such maxima mirrored about it (within max(2 bins, 2 %)), 0 when there is none.
/// Peaks are refined by a parabola through their three bins. {0, 0} when nothing stands out. Any
/// thread; allocates.
struct DriveCarrier {
  double carrier_hz = 0.0;
  double side_hz = 0.0;
};
inline constexpr double kDriveSearchHz = 600.0;
[[nodiscard]] DriveCarrier drive_carrier(const std::vector<double>& real_power,
                                         const std::vector<double>& model_power, double df_hz, double near_hz,
                                         double min_excess_db);

}  // namespace ptda::gap
