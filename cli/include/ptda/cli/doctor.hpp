// `ptda doctor`: the commissioning check. Reads one recording with the pipeline configuration (and
// optionally a baseline) and says, in plain sentences with the fix, whether they fit together: the
// CAN ids seen and which one carries the speed, the decoded speed range against [gearbox] and against
// the vibration's own GMF comb (a wrong speed scale shows as a factor), the plateau lengths against
// the window length, and the baseline's classes against the recording's speeds. `ptda train` and
// `ptda monitor` print the same diagnosis when they cut or score nothing. Thread: any (offline).
// Allocates; reads the recording (blocks).
#pragma once

#include <cstdint>
#include <map>
#include <ostream>
#include <span>
#include <string>
#include <vector>

#include "ptda/cli/pipeline_runner.hpp"
#include "ptda/config/pipeline_config.hpp"
#include "ptda/dsp/baseline.hpp"

namespace ptda::cli {

/// One sentence of the diagnosis. Problems make `ptda doctor` exit kExitCommissioning.
struct DoctorFinding {
  enum class Kind : std::uint8_t { kOk = 0, kNote = 1, kProblem = 2 };
  Kind kind = Kind::kOk;
  std::string topic;  ///< "can", "speed", "scale", "plateaus", "baseline"
  std::string text;
};

/// Constant-speed plateaus of one speed group (direction and speed within [classes] tolerance).
struct PlateauGroup {
  std::int8_t direction = 1;
  double speed_rad_s = 0.0;  ///< mean |speed|
  std::uint32_t plateaus = 0;
  double shortest_s = 0.0, median_s = 0.0, longest_s = 0.0;
  std::uint32_t plateaus_with_windows = 0;  ///< with the configured [extraction]
  std::uint64_t windows = 0;                ///< windows the configured [extraction] cuts
};

/// The vibration's GMF comb against the CAN speed. factor = the speed scale that best explains the
/// vibration (1 = consistent; 10 = the CAN speed reads 10 times too low).
struct ScaleCheck {
  bool checked = false;          ///< a gearbox with teeth and a window to look at
  double can_speed_rad_s = 0.0;  ///< |speed| of the window looked at
  double expected_gmf_hz = 0.0;  ///< GMF from the CAN speed and [gearbox]
  double measured_gmf_hz = 0.0;  ///< GMF the vibration's comb says
  double factor = 1.0;           ///< measured / expected, snapped to the hypothesis that won
  double score = 0.0;            ///< mean comb peak over the spectrum's median for `factor`
  double score_at_1 = 0.0;       ///< the same for the configured scale
  [[nodiscard]] bool mismatch() const noexcept { return checked && factor != 1.0; }
};

/// Scores GMF combs (harmonics 1..12 below 0.45 fs) of the window for speed scale hypotheses 1, 10,
/// 0.1, 100, 0.01, 1000, 0.001, 2 pi, 1/(2 pi) and keeps the best; a hypothesis other than 1 wins only
/// with a comb at least twice as strong as the configured scale's and 4 times the median level.
/// Thread: any. Allocates (FFT).
[[nodiscard]] ScaleCheck check_speed_scale(std::span<const float> window, double fs_hz, double speed_rad_s,
                                           const dsp::GearboxInfo& gearbox);

/// The sentence for a mismatch ("the vibration's GMF comb is at X Hz, 10 times the Y Hz the CAN speed
/// ... multiply [can.speed_frame.speed] scale by 10: scale = 1e-4 in <config>"). Thread: any.
[[nodiscard]] std::string scale_mismatch_text(const ScaleCheck& s, const config::PipelineConfig& cfg,
                                              const std::string& config_source);

struct DoctorReport {
  std::vector<DoctorFinding> findings;
  std::vector<PlateauGroup> groups;
  ScaleCheck scale;
  std::map<std::uint32_t, std::uint64_t> can_ids;  ///< frames per id (CanCounters key)
  std::uint64_t can_frames = 0, speed_frames = 0;
  double speed_min_rad_s = 0.0, speed_max_rad_s = 0.0;
  [[nodiscard]] bool problems() const noexcept;
};

/// Runs the checks on one recording. baseline may be null. Never throws for what it diagnoses (a
/// wrong id, no windows, a baseline of another job: findings); throws ptda::Error for input it cannot
/// read at all (no recording directory, bad WAV). Thread: any. Allocates, reads files.
[[nodiscard]] DoctorReport diagnose_commissioning(const RecordingInfo& rec, const config::PipelineConfig& cfg,
                                                  const std::string& config_source,
                                                  const dsp::Baseline* baseline,
                                                  const std::string& baseline_source);

/// Writes the findings, one per line ("ok: ...", "note: ...", "PROBLEM: ..."). Thread: any.
void print_diagnosis(std::ostream& out, const DoctorReport& report);

}  // namespace ptda::cli
