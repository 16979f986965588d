// Coverage: is the monitor judging anything? Counts, per segment class and overall, the windows judged
// and the windows cut but not judged (by reason, with the speeds seen), and measures the time the joint
// moved since the last judged window. Fed with MonitorEngine's WindowResults and the speed samples, so
// `ptdad` (processing thread) and `ptda monitor` reach the same state for the same input
// (docs/daemon.md, "Coverage").
//
// Fixed size, allocation-free after construction: every member function is noexcept and may run on a
// real-time thread. Time is the caller's data time (the speed samples' and the windows' t_ns).
#pragma once

#include <array>
#include <cstdint>
#include <string_view>

#include "ptda/dsp/baseline.hpp"
#include "ptda/dsp/monitor_engine.hpp"

namespace ptda::dsp {

inline constexpr std::size_t kCoverageMaxClasses = 32;  ///< classes with a larger id count overall only
inline constexpr std::size_t kCoverageSpeedBins = 8;    ///< distinct unmatched speeds remembered

/// Why a cut window was not judged.
enum class UnmatchedReason : std::uint8_t {
  kSpeed = 0,      ///< classes exist in its direction, but none within tolerance of its speed
  kDirection = 1,  ///< no class in its direction at all
  kInvalid = 2,    ///< discarded by the slicer: invalid, lost or overflowed samples (no speed known)
};
inline constexpr std::size_t kUnmatchedReasonCount = 3;
[[nodiscard]] constexpr std::string_view unmatched_reason_name(UnmatchedReason r) noexcept {
  switch (r) {
    case UnmatchedReason::kSpeed:
      return "speed";
    case UnmatchedReason::kDirection:
      return "direction";
    case UnmatchedReason::kInvalid:
      return "invalid";
  }
  return "?";
}

/// What the coverage says, in order of severity.
enum class CoverageLevel : std::uint8_t {
  kWaiting = 0,     ///< nothing judged yet, and the joint has not moved for timeout_s since the start
  kFull = 1,        ///< every class judged within the last timeout_s of motion
  kPartial = 2,     ///< windows are judged, but some class not within the last timeout_s of motion (or,
                    ///< once finished, never)
  kNotJudging = 3,  ///< nothing judged for timeout_s of motion (or a finished run judged nothing)
};
[[nodiscard]] constexpr std::string_view coverage_level_name(CoverageLevel l) noexcept {
  switch (l) {
    case CoverageLevel::kWaiting:
      return "waiting";
    case CoverageLevel::kFull:
      return "full";
    case CoverageLevel::kPartial:
      return "partial";
    case CoverageLevel::kNotJudging:
      return "not judging";
  }
  return "?";
}

struct CoverageConfig {
  /// Motion without a judged window before the state is kNotJudging (and a class without one before it
  /// is stale). The daemon's [daemon] coverage_timeout_s.
  double timeout_s = 60.0;
  double moving_speed_rad_s = 0.05;  ///< |speed| at or above this is motion ([extraction] min_speed_rad_s)
  double max_speed_gap_s = 0.05;     ///< longer steps between speed samples are silence, not motion
};

struct ClassCoverage {
  std::uint64_t judged = 0;
  bool have = false;                   ///< judged at least once
  std::int64_t last_t_ns = 0;          ///< t_end_ns of its last judged window
  std::int64_t moving_at_last_ns = 0;  ///< CoverageState::moving_ns when it was last judged
};

/// Unmatched windows whose speed lies within 2 % (at least 0.01 rad/s) of one another share a bin.
struct UnmatchedSpeed {
  double speed_rad_s = 0.0;  ///< signed mean of the bin's windows
  std::uint64_t count = 0;
  std::int64_t last_t_ns = 0;  ///< t_end_ns of the bin's newest window
};

/// Trivially copyable (the daemon publishes it through its seqlock).
struct CoverageState {
  std::uint64_t judged = 0;
  std::array<std::uint64_t, kUnmatchedReasonCount> unmatched{};  ///< indexed by UnmatchedReason
  std::array<ClassCoverage, kCoverageMaxClasses> classes{};      ///< indexed by class id
  std::uint32_t class_count = 0;                                 ///< baseline classes (may exceed the array)
  std::array<UnmatchedSpeed, kCoverageSpeedBins> speeds{};
  std::uint32_t speed_bins = 0;         ///< valid entries of `speeds`
  std::uint64_t speeds_not_binned = 0;  ///< unmatched windows whose speed found no free bin
  std::int64_t last_invalid_t_ns = 0;   ///< latest_t_ns when discarded windows were last counted
  bool have_judged = false;
  std::int64_t last_judged_t_ns = 0;  ///< t_end_ns of the last judged window
  bool have_time = false;
  std::int64_t first_t_ns = 0;   ///< first speed sample or window seen (the age's origin before a judgement)
  std::int64_t latest_t_ns = 0;  ///< newest speed sample or window end seen
  std::int64_t moving_ns = 0;    ///< total time the joint moved
  std::int64_t moving_at_last_judged_ns = 0;
  bool finished = false;  ///< finish() was called (end of a replay)
  CoverageLevel level = CoverageLevel::kWaiting;

  [[nodiscard]] std::uint64_t unmatched_total() const noexcept {
    return unmatched[0] + unmatched[1] + unmatched[2];
  }
  /// Motion since the last judged window (since the start before one), seconds.
  [[nodiscard]] double moving_since_judged_s() const noexcept {
    return static_cast<double>(moving_ns - moving_at_last_judged_ns) * 1e-9;
  }
  /// Data time since the last judged window ended (since the first data before one), seconds.
  [[nodiscard]] double last_judged_age_s() const noexcept {
    if (!have_time) return 0.0;
    return static_cast<double>(latest_t_ns - (have_judged ? last_judged_t_ns : first_t_ns)) * 1e-9;
  }
  /// Whether class `id` was judged within the last timeout of motion.
  [[nodiscard]] bool class_current(std::uint32_t id, double timeout_s) const noexcept {
    if (id >= kCoverageMaxClasses) return true;       // not tracked
    if (finished && !classes[id].have) return false;  // the whole run went by without it
    // A class never judged counts from the start (moving_at_last_ns is then 0).
    return static_cast<double>(moving_ns - classes[id].moving_at_last_ns) * 1e-9 < timeout_s;
  }
};

/// One line for status, STATUS= and `ptda monitor`, e.g. "not judging: no window matches a trained class
/// (seen 2.50 rad/s; trained ±1.05, ±2.10)", "partial coverage: class 1 (+2.10 rad/s) not judged for
/// 42 s of motion", "not judged yet"; empty for kFull. Items that do not fit are left out whole (the text
/// stays valid UTF-8). Writes at most out_size bytes including the NUL; returns the length.
/// Thread: any. Never allocates or throws.
std::size_t describe_coverage(const CoverageState& st, const Baseline& baseline, double timeout_s, char* out,
                              std::size_t out_size) noexcept;

class CoverageTracker {
 public:
  /// Keeps the class ids, directions and tolerances of `baseline` (fixed arrays). Throws ptda::Error
  /// ("coverage_timeout_s: ...") when timeout_s is not finite and positive. Thread: any (setup).
  CoverageTracker(const Baseline& baseline, const CoverageConfig& cfg);

  /// A speed sample in time order (as pushed to the engine): motion between it and the previous sample
  /// counts while both are at or above moving_speed_rad_s and no more than max_speed_gap_s apart.
  /// Thread: the owner. Never allocates, blocks or throws.
  void on_speed(const SpeedSample& s) noexcept;
  /// A polled window (scored or kNoClass). A judged window resets the motion count as of its own end
  /// (t_end_ns, interpolated between the speed samples kept), not as of the newest speed sample, so the
  /// motion since it does not depend on how late it was judged (block size, processing lag). A window
  /// that ended before the oldest speed sample kept counts from that sample.
  /// Thread: the owner. Never allocates, blocks or throws.
  void on_window(const WindowResult& w) noexcept;
  /// The slicer's discarded-window count (windows_invalid + windows_lost + windows_overflow), cumulative:
  /// the increase is counted as kInvalid. Thread: the owner. Never allocates, blocks or throws.
  void on_discarded_total(std::uint64_t discarded_total) noexcept;
  /// End of the input: a run that judged nothing although the joint moved is kNotJudging even before
  /// the timeout. Thread: the owner. Never allocates, blocks or throws.
  void finish() noexcept;

  [[nodiscard]] const CoverageState& state() const noexcept { return st_; }
  [[nodiscard]] double timeout_s() const noexcept { return cfg_.timeout_s; }

 private:
  void see_time(std::int64_t t_ns) noexcept;
  void update_level() noexcept;
  /// CoverageState::moving_ns as it was at data time t_ns (never more than now).
  [[nodiscard]] std::int64_t moving_at(std::int64_t t_ns) const noexcept;

  /// moving_ns after each speed sample, for moving_at(): a ring of the newest kMotionMarks.
  struct MotionMark {
    std::int64_t t_ns = 0;
    std::int64_t moving_ns = 0;
  };
  // 1024 marks hold 1 s of speed frames at 1 kHz (10 s at 100 Hz); a window is judged within a block
  // or a processing period of its end.
  static constexpr std::size_t kMotionMarks = 1024;
  static_assert((kMotionMarks & (kMotionMarks - 1)) == 0, "kMotionMarks: a power of two (index mask)");
  std::array<MotionMark, kMotionMarks> marks_{};
  std::uint64_t marks_pushed_ = 0;

  CoverageConfig cfg_;
  std::int64_t timeout_ns_ = 0;
  std::int64_t max_gap_ns_ = 0;
  bool has_forward_ = false, has_backward_ = false;
  bool have_speed_ = false;
  SpeedSample last_speed_{};
  std::uint64_t discarded_seen_ = 0;
  CoverageState st_;
};

}  // namespace ptda::dsp
