// What the gap diagnosis sees of a recording: the vibration in m/s^2 and the decoded CAN speed, both on
// the vibration's clock (seconds from sample 0), cut into segments (standstill / constant speed /
// acceleration) and job cycles from the CAN speed alone. Offline: any thread, allocates, throws
// ptda::Error naming the file.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "ptda/config/speed_codec.hpp"
#include "ptda/sim/simulator.hpp"

namespace ptda::gap {

struct SpeedPoint {
  double t_s = 0.0;  ///< seconds from vibration sample 0 (log time - start time - nominal CAN delay)
  double speed_rad_s = 0.0;
};

struct GapRecording {
  std::string source;  ///< directory or "simulation"
  double fs_hz = 0.0;  ///< nominal rate (WAV header)
  std::vector<float> accel_ms2;
  std::vector<SpeedPoint> speed;
};

/// Reads DIR (recording.toml, WAV, candump) decoding speed frames with `frame`; `can_delay_s` (the
/// nominal scenario's [can] delay_s) is subtracted from the log times. Throws ptda::Error.
[[nodiscard]] GapRecording load_recording(const std::filesystem::path& dir,
                                          const config::SpeedFrameSpec& frame, double can_delay_s);
/// The same view of an in-memory simulation of scenario `s` (decoding its own speed frames).
[[nodiscard]] GapRecording recording_from_simulation(const sim::SimulatedSignals& sig,
                                                     const sim::Scenario& s);

enum class SegmentType : std::uint8_t { kConstant = 0, kAccel = 1, kStandstill = 2 };
[[nodiscard]] const char* segment_type_name(SegmentType t) noexcept;

struct Segment {
  SegmentType type = SegmentType::kConstant;
  double t0_s = 0.0;
  double t1_s = 0.0;
  double speed_rad_s = 0.0;  ///< mean signed speed
  std::uint32_t cycle = 0;   ///< job cycle (count of starts from standstill), or block index
};

/// Segments from the CAN speed: standstill below 2 % of the top speed, constant where the speed changes
/// by less than 2 % of the top speed per second, acceleration otherwise. A recording without standstill
/// (test rig) is split into blocks of `block_s` that play the role of cycles.
[[nodiscard]] std::vector<Segment> segment_recording(const GapRecording& rec, double block_s = 0.2);

/// One analysis window: [start, start + len) samples.
struct Window {
  std::size_t start = 0;
  std::size_t len = 0;
  SegmentType type = SegmentType::kConstant;
  int speed_class = -1;      ///< constant windows: index into AnalysisPlan::speeds
  double speed_rad_s = 0.0;  ///< mean CAN speed of its segment
  std::uint32_t cycle = 0;
};

/// Window lengths and constant-speed classes, fixed once (from the measured recording) so real and
/// simulated data are cut alike.
struct AnalysisPlan {
  double fs_hz = 0.0;
  std::vector<double> speeds;          ///< signed class speeds (rad/s)
  std::vector<std::size_t> const_len;  ///< window length per class
  std::size_t accel_len = 0;           ///< 0: no acceleration windows
  std::size_t still_len = 0;           ///< 0: no standstill windows
  std::uint32_t cycles = 0;
};

[[nodiscard]] AnalysisPlan make_plan(const GapRecording& rec, const std::vector<Segment>& segs);
/// Windows of `rec` by the plan; windows of constant segments whose speed matches no class are dropped.
[[nodiscard]] std::vector<Window> cut_windows(const GapRecording& rec, const std::vector<Segment>& segs,
                                              const AnalysisPlan& plan);

/// The fit/held-out split by the job's program period (docs/gap.md "Method", step 2). Units are the
/// segments' `cycle` values: moves (starts from a rest of >= 0.1 s) or rig blocks. A move's signature
/// is the sequence of its constant-speed classes (or its direction when it has none); the program
/// period is the smallest P with signature(u) = signature(u + P) for >= 75 % of the units (1 when none
/// repeats). Unit u in period i = u / P at position j = u % P goes to the fit part when i + j is even:
/// with >= 2 periods both parts hold every position of the program, hence every segment class (a job that
/// rests before every move of a back-and-forth program has P = 2: fit = moves 0, 3, 4, ..., held-out =
/// 1, 2, 5, ...).
struct ProgramSplit {
  std::uint32_t units = 0;         ///< moves or blocks
  std::uint32_t period_units = 1;  ///< program period in units
  double period_s = 0.0;           ///< mean duration of one period (start to start)
  std::uint32_t periods = 0;       ///< whole periods in the recording
  std::vector<char> fit, held;     ///< per unit: 1 when in that part
  bool enough = false;             ///< >= 2 periods and >= 4 units
  std::string need;                ///< when not enough: what the recording lacks and the length needed
};

/// Finds the program period and the split. `duration_s` is the recording length (for the message).
/// Any thread; allocates.
[[nodiscard]] ProgramSplit find_program_split(const std::vector<Segment>& segs, const AnalysisPlan& plan,
                                              double duration_s);

/// Segment classes ("constant class 1 (+0.80 rad/s)", "acceleration", "standstill") that have windows
/// in one part but not in the other, each with the part it is missing from. Any thread; allocates.
[[nodiscard]] std::vector<std::string> missing_classes(const std::vector<Window>& windows,
                                                       const AnalysisPlan& plan, const std::vector<char>& fit,
                                                       const std::vector<char>& held);

/// How steadily a line at `f_hz` is present (issue 11: another axis on its own program comes and goes,
/// mains pickup does not). The selected units' standstill and constant-speed segments are cut into
/// 0.1 s frames; a constant-speed frame is skipped when a multiple of this joint's GMF lies within 4
/// bins of the line (`gmf_per_rad_s`: GMF in Hz per rad/s of joint speed; 0 skips none). Per frame,
/// the Hann-windowed power at f_hz over the median power at f_hz +- 3..8 bins. The "on" level is the
/// median of the frames' top 10 % (a line on in a tenth of the frames is still seen); a frame is on above the
/// geometric midpoint between that level and the floor. `share` = on frames / frames; 1 (cannot tell) with
/// fewer than 8 frames or an on level below 10 dB. Any thread; allocates.
struct LinePresence {
  double share = 1.0;        ///< share of frames in which the line stands out
  double on_level_db = 0.0;  ///< its level over the local floor when on
  std::uint32_t frames = 0;
  bool judged = false;  ///< false: too few frames or too weak a line
};
[[nodiscard]] LinePresence line_presence(const GapRecording& rec, const std::vector<Segment>& segs,
                                         const std::vector<char>& use_cycle, double f_hz,
                                         double gmf_per_rad_s);

}  // namespace ptda::gap
