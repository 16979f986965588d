// The monitoring pipeline after the inputs: window slicer -> PTDA/TDA/raw -> features -> thresholds ->
// k-of-n decision. The daemon's processing thread and `ptda monitor` both drive this one class.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "ptda/dsp/analyzer.hpp"
#include "ptda/dsp/band_energy.hpp"
#include "ptda/dsp/baseline.hpp"
#include "ptda/dsp/decision.hpp"
#include "ptda/dsp/mesh_modulation.hpp"
#include "ptda/dsp/window_slicer.hpp"

namespace ptda::dsp {

struct DecisionConfig {
  std::uint32_t k = 3;          ///< abnormal windows ...
  std::uint32_t n = 5;          ///< ... out of the last n scored windows raise the alarm
  SequentialConfig sequential;  ///< per-class CUSUM beside k-of-n (either raises the alarm)
  BandCusumConfig band;         ///< per-class, per-band CUSUM on band energies (any raises it)
  MeshCusumConfig mesh;         ///< per-class CUSUM on the mesh's am and pm (either raises it)
};

/// `decision` with band.half_bins and band.bin_hz set from the baseline (window_len / 2 and
/// fs_hz / window_len), so the alarm record can name a band's frequency range. Thread: any.
[[nodiscard]] DecisionConfig with_band_geometry(DecisionConfig decision, const Baseline& baseline) noexcept;

/// Which detectors hold the alarm (WindowResult::detector): a bit set, k-of-n 1, sequential 2, band 4,
/// mesh 8 (the combinations with mesh have no enumerator of their own; alarm_detector_name() names them).
enum class AlarmDetector : std::uint8_t {
  kNone = 0,
  kKOfN = 1,
  kSequential = 2,
  kBoth = 3,  ///< k-of-n and sequential
  kBand = 4,
  kKOfNBand = 5,
  kSequentialBand = 6,
  kAll = 7,
  kMesh = 8,
};
[[nodiscard]] constexpr const char* alarm_detector_name(AlarmDetector d) noexcept {
  constexpr const char* kNames[16] = {
      "none",      "k_of_n",           "sequential",           "k_of_n+sequential",
      "band",      "k_of_n+band",      "sequential+band",      "k_of_n+sequential+band",
      "mesh",      "k_of_n+mesh",      "sequential+mesh",      "k_of_n+sequential+mesh",
      "band+mesh", "k_of_n+band+mesh", "sequential+band+mesh", "k_of_n+sequential+band+mesh"};
  const auto i = static_cast<unsigned>(d);
  return i < 16 ? kNames[i] : "?";
}

enum class WindowStatus : std::uint8_t {
  kScored = 0,   ///< features computed and judged
  kNoClass = 1,  ///< no segment class of the baseline matches its speed/direction: not scored
};

struct WindowResult {
  WindowRef ref;
  WindowStatus status = WindowStatus::kScored;
  std::int32_t class_id = -1;
  Features features;
  FeatureThresholds thresholds;  ///< of the class and method used
  Verdict verdict;
  bool alarm = false;  ///< alarm state after this window: k-of-n or sequential
  std::uint32_t abnormal_in_last_n = 0;
  // Evidence of the detectors (docs/method.md, "Decision").
  bool kofn_alarm = false;                        ///< k of the last n scored windows abnormal
  bool seq_alarm = false;                         ///< some class's CUSUM >= cusum_alarm
  bool seq_warn = false;                          ///< some class's CUSUM >= cusum_warn
  AlarmDetector detector = AlarmDetector::kNone;  ///< which of them holds `alarm`
  double z_rms = 0.0;                             ///< standardised ln(rms_res) of this window (scored)
  double z_entropy = 0.0;                         ///< standardised entropy_res of this window (scored)
  /// The class's between-day allowances added to cusum_k (scored; SeqScale, docs/method.md §6).
  double seq_allowance_rms = 0.0;
  double seq_allowance_entropy = 0.0;
  double seq_statistic = 0.0;                  ///< this window's class CUSUM after it (scored)
  SeqFeature seq_feature = SeqFeature::kNone;  ///< which of that class's statistics is largest
  double seq_max_statistic = 0.0;              ///< largest CUSUM over all classes
  // Band detector (docs/method.md §6 "Band detector"; only when DecisionConfig::band.enabled).
  bool band_on = false;         ///< the band CUSUM runs (the band_* fields below mean something)
  std::uint8_t band_count = 0;  ///< bands of this window's class (scored)
  /// Per band of this window (scored): z_b minus its class's day allowance (BandScale), the CUSUM's
  /// increment before k; 0 for an unused band.
  std::array<float, kMaxBands> band_excess{};
  double band_z_max = 0.0;           ///< largest band_excess of this window (scored)
  bool band_alarm = false;           ///< some class's band CUSUM > band_cusum_h
  double band_statistic = 0.0;       ///< this window's class: largest band CUSUM after it (scored)
  std::int32_t band_index = -1;      ///< its band (-1 when all are 0)
  double band_max_statistic = 0.0;   ///< largest band CUSUM over all classes and bands
  std::int32_t band_max_index = -1;  ///< its band (-1 when all are 0)
  std::int32_t band_max_class = -1;  ///< its class (the decision's class index)
  double band_lo_hz = 0.0;           ///< band_max_index's first bin's frequency (0 when unknown)
  double band_hi_hz = 0.0;           ///< its last bin's frequency
  // Mesh detector (docs/method.md §6 "Mesh detector"; only when DecisionConfig::mesh.enabled).
  bool mesh_on = false;  ///< the mesh CUSUM runs (the mesh_* fields below mean something)
  /// This window's am and pm (mesh_modulation.hpp); NaN when it has none (not scored, fewer than two
  /// input-shaft revolutions, no mesh line, or a class without mesh statistics).
  double mesh_value[kMeshFeatureCount] = {std::numeric_limits<double>::quiet_NaN(),
                                          std::numeric_limits<double>::quiet_NaN()};
  /// Per feature: z minus the class's day allowance (the CUSUM's increment before k); NaN when the
  /// feature did not enter the CUSUM.
  double mesh_excess[kMeshFeatureCount] = {std::numeric_limits<double>::quiet_NaN(),
                                           std::numeric_limits<double>::quiet_NaN()};
  bool mesh_alarm = false;             ///< some class's mesh CUSUM > mesh_cusum_h
  double mesh_statistic = 0.0;         ///< this window's class: largest mesh CUSUM after it (scored)
  std::int32_t mesh_feature = -1;      ///< its feature (0 am, 1 pm; -1 when both are 0)
  double mesh_max_statistic = 0.0;     ///< largest mesh CUSUM over all classes and features
  std::int32_t mesh_max_feature = -1;  ///< its feature
  std::int32_t mesh_max_class = -1;    ///< its class (the decision's class index)
};

/// The decision after the verdicts: k-of-n over all scored windows and one CUSUM per class (fixed
/// state sized at construction). MonitorEngine runs one; `ptda monitor --windows` replays one over a
/// subset. Constructor: thread any (setup), allocates, throws ptda::Error on a bad configuration.
class DecisionState {
 public:
  DecisionState(const DecisionConfig& decision, std::size_t classes);
  /// A scored window of class index `cls` (< classes): reads w.verdict, w.z_rms, w.z_entropy,
  /// w.seq_allowance_rms and w.seq_allowance_entropy (band CUSUM: w.band_count, w.band_excess; mesh
  /// CUSUM: w.mesh_excess, where a NaN feature leaves its statistic as it was) and fills
  /// the decision fields of w. Thread: the owner's. Never allocates or blocks.
  void scored(WindowResult& w, std::size_t cls) noexcept;
  /// A window not judged: its decision fields repeat the current state. Never allocates or blocks.
  void unscored(WindowResult& w) const noexcept;

 private:
  KOfNDebouncer debouncer_;
  SequentialConfig seq_;
  /// Cap of each CUSUM: h_alarm + (n - k) cusum_k, so that from the cap a healthy run (z = 0) ends
  /// the sequential alarm after n - k + 1 windows, as k-of-n ends its own (a latched alarm can then
  /// be cleared as soon after a repair as k-of-n allows). Reaching h_alarm is not affected.
  double cap_ = 0.0;
  std::vector<Cusum> cusum_;  ///< one per class
  BandCusumConfig band_;
  double band_cap_ = 0.0;  ///< cap of each band CUSUM: band h + (n - k) band k (as cap_)
  std::vector<std::array<double, kMaxBands>> band_s_;  ///< per class, per band (empty when off)
  /// Per class and band: the order in which the statistic went above h (0 = not above), so that among
  /// equal statistics (e.g. all at the cap) the band that crossed first is reported.
  std::vector<std::array<std::uint64_t, kMaxBands>> band_since_;
  std::uint64_t band_order_ = 0;
  MeshCusumConfig mesh_;
  double mesh_cap_ = 0.0;                                      ///< as band_cap_
  std::vector<std::array<double, kMeshFeatureCount>> mesh_s_;  ///< per class, per feature (empty when off)

  void fill(WindowResult& w) const noexcept;
};

/// Why the band CUSUM cannot run with this method and baseline (not PTDA, no band statistics, another
/// band count), in words for a log line; empty when it can. Thread: any. Allocates the message.
[[nodiscard]] std::string band_cusum_unusable(const DecisionConfig& decision, const Baseline& baseline,
                                              Method method);
/// decision with the default-on band detector switched off where band_cusum_unusable() says it cannot
/// run; an explicit `band_cusum = true` (decision.band.required) is left on (MonitorEngine then throws).
/// Thread: any. Allocates only inside band_cusum_unusable().
[[nodiscard]] DecisionConfig effective_band(DecisionConfig decision, const Baseline& baseline, Method method);

/// Why the default-on mesh CUSUM cannot run with this baseline (order domain, no mesh statistics), in
/// words for a log line; empty when it can. Thread: any. Allocates the message.
[[nodiscard]] std::string mesh_cusum_unusable(const DecisionConfig& decision, const Baseline& baseline);
/// effective_band(), and the default-on mesh detector switched off where mesh_cusum_unusable() says it
/// cannot run (an explicit `mesh_cusum = true`, decision.mesh.required, is left on: MonitorEngine then
/// throws). The decision a MonitorEngine built from these runs with. Thread: any. Allocates only the
/// messages.
[[nodiscard]] DecisionConfig effective_detectors(DecisionConfig decision, const Baseline& baseline,
                                                 Method method);

class MonitorEngine {
 public:
  /// Copies what it needs of baseline (the caller may drop it). Throws ptda::Error when the baseline's
  /// sample rate or window length disagree with fs_hz / cfg.window_len (says which), or the
  /// sequential parameters are invalid (check_sequential()), or the band CUSUM is on and its parameters
  /// are invalid (check_band_cusum()). With `band_cusum = true` said explicitly (decision.band.required)
  /// it also throws when the method is not PTDA, the baseline has no band statistics (format <= 6 or
  /// trained without band_cusum: retrain) or another band count; on by default, those switch the band
  /// detector off instead and band_off_reason() says why.
  /// Thread: any (setup). Allocates.
  MonitorEngine(const Baseline& baseline, const ExtractionConfig& cfg, const DecisionConfig& decision,
                Method method, double fs_hz, std::int64_t t0_ns);

  /// Forwarded to the WindowSlicer (see window_slicer.hpp). Thread: the owner's (the daemon's
  /// processing thread). Never allocate or block.
  void push_speed(const SpeedSample& s) noexcept;
  void push_samples(std::span<const float> block) noexcept;
  void mark_gap(std::uint64_t count) noexcept;
  void finish() noexcept;
  /// Next processed window (scored or kNoClass), oldest first. A kNoClass window is not judged and
  /// does not enter the k-of-n decision or any CUSUM (its alarm fields repeat the current state).
  /// A scored window updates k-of-n and its class's CUSUM; the alarm holds while either holds. The slicer's
  /// ended regions are drained and dropped here. Thread: the owner's. Never allocates or blocks.
  bool poll(WindowResult& out) noexcept;
  /// Judges one window cut elsewhere (the order domain's OrderWindowCutter, docs/method.md §9) exactly
  /// as poll() judges the slicer's: class match on ref.speed_rad_s, analysis, bands, k-of-n and CUSUM.
  /// `window` must hold window_len samples (else the window is reported kNoClass). poll() uses it.
  /// Thread: the owner's. Never allocates or blocks.
  void judge_window(const WindowRef& ref, std::span<const float> window, WindowResult& out) noexcept;

  /// The last polled window's samples and the analyzer's buffers for it (reports).
  [[nodiscard]] std::span<const float> last_window() const noexcept { return window_; }
  [[nodiscard]] const WindowAnalyzer& analyzer() const noexcept { return analyzer_; }
  [[nodiscard]] const WindowSlicer& slicer() const noexcept { return slicer_; }
  [[nodiscard]] const Baseline& baseline() const noexcept { return baseline_; }
  /// Whether the band CUSUM runs, and why the default-on band detector does not (empty when it runs or
  /// was switched off by the configuration). Thread: any. Never allocates.
  [[nodiscard]] bool band_cusum_on() const noexcept { return !band_scale_.empty(); }
  [[nodiscard]] const std::string& band_off_reason() const noexcept { return band_off_reason_; }
  /// Whether the mesh CUSUM runs, and on how many classes (those with mesh statistics and mesh lines).
  [[nodiscard]] bool mesh_cusum_on() const noexcept { return !mesh_scale_.empty(); }
  /// Why the default-on mesh detector does not run with this baseline (empty when it runs or was
  /// switched off by the configuration). Thread: any. Never allocates.
  [[nodiscard]] const std::string& mesh_off_reason() const noexcept { return mesh_off_reason_; }
  [[nodiscard]] std::size_t mesh_classes() const noexcept;

 private:
  void score(const WindowRef& ref, WindowResult& out) noexcept;  ///< window_ holds the samples

  Baseline baseline_;
  Method method_;
  WindowSlicer slicer_;
  WindowAnalyzer analyzer_;
  DecisionState decision_;                              ///< per-class state sized here at configure
  std::vector<SeqScale> z_scale_;                       ///< per class: sequential_scale() of the method
  std::vector<BandScale> band_scale_;                   ///< per class (band CUSUM on)
  std::vector<std::vector<unsigned char>> band_clean_;  ///< per class: clean_floor_bins()
  std::array<double, kMaxBands> band_tmp_{};
  std::vector<std::optional<MeshDemodulator>> mesh_demod_;  ///< per class (mesh CUSUM on; empty: none)
  std::vector<MeshScale> mesh_scale_;                       ///< per class (mesh CUSUM on)
  std::vector<float> window_;
  std::string band_off_reason_;  ///< default-on band detector switched off: why (empty otherwise)
  std::string mesh_off_reason_;  ///< default-on mesh detector switched off: why (empty otherwise)
};

}  // namespace ptda::dsp
