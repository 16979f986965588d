// Window decision, k-of-n alarm debouncing and the sequential (CUSUM) detector (fixed capacity,
// allocation-free at run time). Formulas: docs/method.md, "Decision".
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>

#include "ptda/dsp/baseline.hpp"
#include "ptda/dsp/types.hpp"

namespace ptda::dsp {

struct Verdict {
  bool rms_out = false;      ///< rms_res above its band (or not finite): gear-fault evidence
  bool entropy_out = false;  ///< entropy_res outside its band
  /// rms_res below its band: less residual than any healthy window (a loose sensor, a stopped mesh,
  /// a lost channel). Its own cause, not a gear fault: it does not make the window abnormal.
  bool rms_low = false;
  [[nodiscard]] bool abnormal() const noexcept { return rms_out || entropy_out; }
};

/// A window is abnormal when its residual RMS is above its band or its entropy outside its band
/// (paper section 3.4, made one-sided for the RMS: see Verdict::rms_low). Never allocates.
[[nodiscard]] inline Verdict judge(const Features& f, const FeatureThresholds& t) noexcept {
  Verdict v;
  v.rms_out = !(f.rms_res <= t.rms.hi);  // NaN (size mismatch) is never healthy
  v.rms_low = f.rms_res < t.rms.lo;
  v.entropy_out = !t.entropy.contains(f.entropy_res);
  return v;
}

/// Standardised features of a window for the sequential detector: z_rms = (ln rms_res - m) / (c s)
/// with m, s of the class's leave-one-out ln(rms_res), z_entropy = (entropy_res - mean) / (c sd), c the
/// small-sample scale (training.hpp small_sample_scale(); 1 = none). An sd of 0 is floored at
/// 1e-9 max(1, |mean|); rms_res = 0 gives z_rms = -1e3 (far below healthy, finite); NaN stays NaN.
/// Thread: any. Never allocates.
struct StandardScores {
  double rms = 0.0;
  double entropy = 0.0;
};
[[nodiscard]] StandardScores standardize(const Features& f, const FeatureStats& log_rms,
                                         const FeatureStats& entropy, double scale = 1.0) noexcept;

/// How one class standardises a method's features for the sequential detector, and the CUSUM's extra
/// allowance for the between-day spread (training.hpp sequential_scale(); docs/method.md §6):
/// z_rms = (ln rms_res - log_rms.mean) / (scale log_rms.stddev), likewise for the entropy, where the
/// stddevs are the within-day ones; the CUSUM on z_rms uses the allowance k + rms_allowance (in z
/// units), those on z_entropy k + entropy_allowance.
struct SeqScale {
  FeatureStats log_rms;  ///< mean and within-day sd of ln(rms_res) (other fields unused)
  FeatureStats entropy;  ///< mean and within-day sd of entropy_res
  double scale = 1.0;    ///< small-sample scale c_n
  double rms_allowance = 0.0;
  double entropy_allowance = 0.0;
};
/// standardize(f, s.log_rms, s.entropy, s.scale). Thread: any. Never allocates.
[[nodiscard]] inline StandardScores standardize(const Features& f, const SeqScale& s) noexcept {
  return standardize(f, s.log_rms, s.entropy, s.scale);
}

/// Parameters of the per-class CUSUM on the standardised features ([decision] cusum_* keys).
struct SequentialConfig {
  bool enabled = true;
  double k = 1.0;        ///< reference value (allowance) in standard deviations per window
  double h_warn = 4.0;   ///< decision interval of the warning level
  double h_alarm = 7.0;  ///< decision interval of the alarm level (the statistic is capped at 2 h_alarm)
  /// Allowance for the between-day spread, in between-day standard deviations (`[decision]
  /// cusum_day_allowance`, docs/method.md §6): a class's CUSUMs tolerate a persistent shift of the
  /// features up to day_allowance * sd_between * sqrt(1 + 1/R) (R training days) before they
  /// accumulate. 0 = the within-day CUSUM of session 6.
  double day_allowance = 3.0;
  /// Largest step one window adds to a statistic (`[decision] cusum_step_cap`, docs/method.md §6 "Step
  /// cap"; session 38): the increment z - k is clipped to it, so a few outlying windows cannot raise the
  /// alarm on their own (k-of-n judges single windows). kNoStepCap (1000) = no clipping.
  double step_cap = 2.5;
};

/// The largest value a `*_step_cap` key takes: a step that large never clips.
inline constexpr double kNoStepCap = 1000.0;

/// One step of a one-sided CUSUM, shared by the feature, band and mesh detectors:
/// S <- min(cap, max(0, S + min(increment, step_cap))) with increment = x - k (docs/method.md §6).
/// Thread: any. Never allocates.
[[nodiscard]] inline double cusum_step(double s, double increment, double step_cap, double cap) noexcept {
  return std::min(cap, std::max(0.0, s + std::min(increment, step_cap)));
}

/// Throws ptda::Error naming `decision.<key>` unless 0 < cap <= kNoStepCap. Thread: any. Allocates only
/// the message.
void check_step_cap(const char* key, double cap);

/// Throws ptda::Error naming the [decision] key unless 0 < k <= 10, 0 < h_warn <= h_alarm <= 1000,
/// 0 <= day_allowance <= 10 and 0 < step_cap <= kNoStepCap.
/// Thread: any (setup). Allocates only for the message.
void check_sequential(const SequentialConfig& cfg);

/// Which CUSUM statistic of a class is the largest.
enum class SeqFeature : std::uint8_t { kNone = 0, kRmsHigh = 1, kEntropyHigh = 2, kEntropyLow = 3 };
[[nodiscard]] constexpr const char* seq_feature_name(SeqFeature f) noexcept {
  switch (f) {
    case SeqFeature::kNone:
      return "none";
    case SeqFeature::kRmsHigh:
      return "rms_high";
    case SeqFeature::kEntropyHigh:
      return "entropy_high";
    case SeqFeature::kEntropyLow:
      return "entropy_low";
  }
  return "?";
}

/// One class's CUSUM statistics: upper on z_rms (low residuals are not gear faults), upper and lower
/// on z_entropy. S <- min(cap, max(0, S + z - k)) each (docs/method.md, "Sequential detector").
class Cusum {
 public:
  /// A non-finite z counts as z = k + 1 (one sd of evidence above the allowance), like the k-of-n
  /// rule that counts a non-finite feature as abnormal. extra_rms / extra_entropy are added to k for
  /// the z_rms statistic / the two z_entropy statistics (the class's between-day allowance, SeqScale).
  /// Thread: the owner's. Never allocates.
  /// step_cap clips each statistic's increment z - k (SequentialConfig::step_cap).
  void update(double z_rms, double z_entropy, double k, double cap, double extra_rms = 0.0,
              double extra_entropy = 0.0, double step_cap = kNoStepCap) noexcept;
  /// max of the three statistics and which one it is.
  [[nodiscard]] double statistic() const noexcept;
  [[nodiscard]] SeqFeature feature() const noexcept;
  void reset() noexcept { s_rms_ = s_ent_hi_ = s_ent_lo_ = 0.0; }

 private:
  double s_rms_ = 0.0, s_ent_hi_ = 0.0, s_ent_lo_ = 0.0;
};

/// Average run length (windows) of a one-sided CUSUM S <- max(0, S + x - k) to reach h when x is
/// normal with this mean and sd: Siegmund's approximation with delta = (mean - k) / sd and
/// b = h / sd + 1.166: ARL = (exp(-2 delta b) + 2 delta b - 1) / (2 delta^2), b^2 at delta = 0.
/// +inf when it overflows. Throws ptda::Error unless sd > 0 and h > 0. Thread: any. No allocation
/// except the message.
[[nodiscard]] double cusum_arl(double mean, double sd, double k, double h);

/// Combined ARL of a class's three CUSUMs (upper on z_rms, upper and lower on z_entropy) for
/// healthy standardised features with these means and sds: 1 / sum(1 / ARL_i) (rare, nearly
/// independent crossings). Thread: any.
[[nodiscard]] double class_cusum_arl(double z_rms_mean, double z_rms_sd, double z_entropy_mean,
                                     double z_entropy_sd, double k, double h, double extra_rms = 0.0,
                                     double extra_entropy = 0.0);

/// Alarm when at least k of the last n judged windows were abnormal. n <= kMaxN.
class KOfNDebouncer {
 public:
  static constexpr std::uint32_t kMaxN = 64;
  /// Throws ptda::Error unless 1 <= k <= n <= kMaxN. Thread: any (setup).
  KOfNDebouncer(std::uint32_t k, std::uint32_t n);
  /// Records one window; returns whether the k-of-n condition holds now (fewer than n windows seen:
  /// counts over those). Thread: the owner's. Never allocates or blocks.
  bool push(bool abnormal) noexcept;
  [[nodiscard]] bool active() const noexcept { return count_ >= k_; }
  [[nodiscard]] std::uint32_t abnormal_in_window() const noexcept { return count_; }
  /// Forgets all history (e.g. after a class change or a gap). Thread: the owner's. Never allocates.
  void reset() noexcept;

 private:
  std::uint32_t k_, n_;
  std::array<bool, kMaxN> hist_{};
  std::uint32_t pos_ = 0, filled_ = 0, count_ = 0;
};

}  // namespace ptda::dsp
