// Sim-to-real gap diagnosis (docs/gap.md): calibrate the nominal scenario's free parameters on the fit
// cycles of a measured recording, fit each candidate effect's parameters on the fit cycles, and select
// effects greedily while they shrink the gap on the held-out cycles significantly. Offline: any thread,
// allocates, throws ptda::Error.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "ptda/gap/probes.hpp"
#include "ptda/gap/signals.hpp"
#include "ptda/sim/effects.hpp"
#include "ptda/sim/simulator.hpp"

namespace ptda::gap {

/// What the model's motion follows (docs/gap.md "Method", step 3).
enum class MotionSource : std::uint8_t {
  kAuto,      ///< the measured CAN speed when it is usable, else the scenario's profile
  kMeasured,  ///< the measured CAN speed (an error when it is not usable)
  kScenario,  ///< the scenario's [motion] profile
};

struct DiagnoseOptions {
  MotionSource motion = MotionSource::kAuto;
  std::uint64_t sim_seed = 9001;  ///< seed of the model's simulations (common random numbers)
  std::uint32_t max_effects = 2;  ///< greedy rounds
  std::uint32_t full_fits = 4;    ///< candidates fitted fully per round (after a two-stage screen)
  double min_gain_share = 0.15;   ///< accept an effect when it removes this share of the current gap...
  double min_gain_sd = 2.0;       ///< ... and this many standard deviations of the sampling gap, against
                                  ///< two independent model realisations of the held-out part (both)
  double min_gap_sd = 2.0;        ///< no diagnosis when the gap is within expected + this many sd
  /// Local acceptance (transfer_path, electrical_interference): this share of the gap in the effect's own
  /// octave bands removed, against both realisations, with the overall gain >= min_gain_sd sd.
  double min_local_share = 0.5;
  unsigned threads = 0;  ///< fitting threads (0: one per hardware thread); results do not depend on it
  std::vector<sim::EffectKind> candidates;      ///< empty: the whole catalog
  std::function<void(const std::string&)> log;  ///< progress lines (optional)
};

struct CandidateResult {
  sim::EffectSpec effect;
  double gap_fit = 0.0;      ///< on the fit cycles, with the effect
  double gap_heldout = 0.0;  ///< on the held-out cycles, with the effect
  /// The same against a second, independent model realisation of the held-out part (NaN: not computed)
  double gap_heldout_replicate = 0.0;
  double shrink_pct = 0.0;  ///< held-out gap reduction against the round's starting point
  bool fully_fitted = false;
  std::uint32_t evaluations = 0;
  std::string
      location;  ///< where the fitted effect acts ("resonance 3012 Hz", "sidebands every 1.25 x f_in")
  /// Chosen effects only: other fully fitted candidates whose held-out gap (mean of both realisations) is
  /// within max(min_gain_sd sd, 10 % of the chosen one's gain) of it: not told apart on this recording.
  std::vector<std::string> alternatives;
  /// Held-out gap by octave band with the effect, both realisations (for the local acceptance rule;
  /// not written to the JSON).
  std::map<std::string, double> heldout_by_band, replicate_by_band;
  /// The same by probe (the round's log line; not written to the JSON).
  std::map<std::string, double> heldout_by_probe, replicate_by_probe;
  bool accepted_locally = false;  ///< chosen by the local rule (its own bands), not the global one
};

/// One calibrated parameter of the nominal model (docs/gap.md "Calibration").
struct CalibratedParam {
  std::string name;         ///< "gmf_order_2", "noise_rms"
  int order = 0;            ///< GMF order (0: not a harmonic)
  double nominal = 0.0;     ///< the nominal scenario's value
  double calibrated = 0.0;  ///< after calibration on the fit part
  double offset_db =
      0.0;             ///< 20 log10(calibrated / nominal); the floor tilt: calibrated - nominal (dB/decade)
  double sd_db = 0.0;  ///< sampling standard deviation of the offset (measured fit part's spread)
  bool significant = false;  ///< |offset| > max(1 dB, 2 sd)
  std::string sentence;      ///< "order 2 is 6.1 dB below the nominal (+- 0.4 dB)"
};

struct SelectionRound {
  double gap_before_heldout = 0.0;
  double gap_before_heldout_replicate = 0.0;  ///< the round's starting model, second realisation
  std::vector<CandidateResult> ranked;        ///< by held-out gap (fully fitted first)
  int accepted = -1;                          ///< index into ranked, -1: none significant
  /// The null candidate: the round's model with no effect added, calibrated along the best candidate's
  /// own path (from the nominal's levels, two passes). Its held-out gaps, both realisations.
  double null_heldout = 0.0;
  double null_heldout_replicate = 0.0;
  /// The gain was judged against the null (true) or the round's starting model (false): whichever of the
  /// two has the smaller mean held-out gap, so re-calibration alone never counts as a gain.
  bool null_reference = false;
};

struct Diagnosis {
  std::string scenario;
  std::string real_source;
  double fs_hz = 0.0;
  std::uint32_t cycles = 0;
  std::uint32_t fit_cycles = 0;
  std::uint32_t heldout_cycles = 0;
  std::size_t windows_fit = 0;
  std::size_t windows_heldout = 0;
  std::vector<double> class_speeds_rad_s;
  std::uint32_t period_units = 1;          ///< program period in units (moves or blocks)
  double period_s = 0.0;                   ///< its mean duration
  std::vector<std::string> split_missing;  ///< segment classes present in one part only
  std::string motion_source;               ///< "measured" or "scenario"
  std::string motion_note;                 ///< why, in words
  /// Speed scale (nominal [can] speed_scale_tolerance > 0 only): estimated from the measured lines
  /// before anything else; applied (within the tolerance) to the speed frames when significant.
  double speed_scale_tolerance = 0.0;
  double speed_scale_ppm = 0.0;          ///< estimate, (true / frame speed - 1) * 1e6
  double speed_scale_sd_ppm = 0.0;       ///< its spread over the lines
  int speed_scale_lines = 0;             ///< lines used
  double speed_scale_applied_ppm = 0.0;  ///< what the speed frames were scaled by (0: not applied)
  /// The nominal's [can] speed_scale_slip_only: a shaft faster than its frames is not calibration.
  bool speed_scale_slip_only = false;
  /// Effect kinds left out of the candidates because this recording cannot tell them apart, with why.
  std::vector<std::string> not_identifiable;
  std::vector<CalibratedParam> calibration;  ///< per nominal GMF order, then the noise level
  bool recalibrated = false;                 ///< any calibration parameter significant
  std::vector<double> calibrated_gmf_amplitudes;
  /// The model's GMF phases after step 1c (rad, sin(k b + phi), one per entry of the amplitudes; the
  /// nominal's, or zeros, when they were not re-calibrated).
  std::vector<double> calibrated_gmf_phases_rad;
  double calibrated_noise_rms = 0.0;
  double calibrated_noise_tilt_db_per_decade = 0.0;
  GapBreakdown nominal_heldout;            ///< calibrated nominal model vs held-out cycles
  double nominal_heldout_replicate = 0.0;  ///< the same against a second model realisation
  double noise_gap = 0.0;     ///< held-out gap expected from sampling alone (measured cycles' spread)
  double noise_gap_sd = 0.0;  ///< its standard deviation
  std::vector<SelectionRound> rounds;
  std::vector<CandidateResult> chosen;
  GapBreakdown final_heldout;
  /// Alarm stage: share of the held-out constant-speed windows a PTDA baseline trained on the model
  /// (calibrated nominal / final) flags (mean over classes); NaN when there are too few windows.
  double alarm_rate_nominal = 0.0;
  double alarm_rate_final = 0.0;
  double total_shrink_pct = 0.0;
  bool gap_significant = false;
  std::string verdict;  ///< one plain sentence
  double runtime_s = 0.0;
  std::uint32_t simulations = 0;
  // Spectra for plots (class 0 constant-speed windows, dB of amplitude^2): real held-out, nominal, final.
  double spectrum_df_hz = 0.0;
  std::vector<double> spectrum_real_db, spectrum_nominal_db, spectrum_final_db;
};

/// Runs the diagnosis of `real` against `nominal`. Throws ptda::Error when the recording has too few
/// cycles or windows to split.
/// Why the recording's CAN speed cannot drive the model (empty: usable): fewer than 10 frames, frames
/// covering < 80 % of the recording, or a hole longer than max(0.25 s, 20 x the median interval).
/// Any thread; allocates.
[[nodiscard]] std::string measured_speed_problem(const GapRecording& real);

[[nodiscard]] Diagnosis diagnose(const sim::Scenario& nominal, const GapRecording& real,
                                 const DiagnoseOptions& opt);

/// Indices (into `ranked`, whose first entry is the chosen candidate) of fully fitted runners-up whose
/// held-out gap, mean of both model realisations, is within max(min_gain_sd x noise_sd, 10 % of the chosen
/// one's gain over `before_*`) of the chosen one's: candidates the recording does not tell apart from it.
/// Any thread; allocates.
[[nodiscard]] std::vector<std::size_t> tied_candidates(const std::vector<CandidateResult>& ranked,
                                                       double before_heldout, double before_replicate,
                                                       double noise_sd, double min_gain_sd);

/// JSON document (schema "ptda-gap" version 1, docs/gap.md).
[[nodiscard]] std::string diagnosis_json(const Diagnosis& d);
/// Self-contained HTML report with inline SVG plots.
[[nodiscard]] std::string diagnosis_html(const Diagnosis& d);

/// Keeps a candidate's parameters where the library and the recording allow them while it is fitted:
/// every parameter within its library range (sim::effect_info), and the places that must lie below
/// Nyquist (a `transfer_path`'s frequency_hz, a knock's resonance_hz) at most kFitTopOfFs * fs_hz, the
/// probes' top, so that a named effect always loads back into a scenario (which rejects a path at
/// 0.49 fs or a knock at fs/2 and above). A relative refinement stage (x 1.19) could push a knock at
/// the top of the resonance grid to 0.54 fs. Any thread; never allocates.
void clamp_effect_params(sim::EffectSpec& e, double fs_hz);
inline constexpr double kFitTopOfFs = 0.45;

/// Where an effect with these parameters acts, in words (for reports and the bench's location check).
[[nodiscard]] std::string effect_location(const sim::EffectSpec& e, const sim::Scenario& nominal);

/// Pickup named in two parts, one line at a time: a mains-form `electrical_interference` and another
/// that is one line of at least kDriveMinHz, at least kDriveMinRatio times the first's frequency (no
/// carrier in either). The pair is one source in the library's drive form: the mains entry takes the
/// line as its carrier (`pwm_hz`, `pwm_ms2` = its amplitude, no sidebands) and its location words, at
/// the position of the earlier of the two; the line's entry is removed. The model is the same sum of
/// lines (only the phases' draws differ), so the gaps stay. At most one merge. Any thread; allocates.
void merge_drive_pickup(std::vector<CandidateResult>& chosen, const sim::Scenario& nominal);
inline constexpr double kDriveMinHz = 1000.0;
inline constexpr double kDriveMinRatio = 8.0;

}  // namespace ptda::gap
