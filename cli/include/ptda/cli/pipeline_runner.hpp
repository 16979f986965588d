// The one place where a recording directory is turned into the two input streams of the monitoring
// pipeline: vibration samples (WAV, streamed in blocks, times recording scale) and joint speed samples
// (candump log, decoded with config::decode_speed, latency applied), interleaved by time. `ptda train`,
// `ptda monitor` and `ptda report` all feed their slicer/engine through run_recording(), so they cut
// exactly the same windows. Thread: any (offline). Allocates; throws ptda::Error naming the file.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <span>
#include <string>
#include <vector>

#include "ptda/cli/args.hpp"
#include "ptda/config/pipeline_config.hpp"
#include "ptda/dsp/baseline_training.hpp"
#include "ptda/dsp/coverage.hpp"
#include "ptda/dsp/monitor_engine.hpp"
#include "ptda/dsp/order_windows.hpp"
#include "ptda/dsp/types.hpp"
#include "ptda/formats/recording.hpp"
#include "ptda/formats/wav.hpp"

namespace ptda::cli {

/// What a recording directory holds, validated (recording.toml read, WAV header read).
struct RecordingInfo {
  std::filesystem::path dir;
  formats::RecordingMeta meta;
  formats::WavInfo wav;
  std::filesystem::path wav_path;
  std::filesystem::path can_path;
  std::int64_t t0_ns = 0;   ///< UNIX ns of sample 0
  double duration_s = 0.0;  ///< frames / rate
};

/// Reads DIR/recording.toml and the WAV header. Throws ptda::Error (missing directory, bad toml,
/// unreadable WAV, channel out of range), naming the file.
[[nodiscard]] RecordingInfo open_recording(const std::filesystem::path& dir);

/// A content fingerprint of the recording's vibration data: "wav:<file size>:<CRC-32 of its first
/// 1 MiB, hex>:ch<channel>". Copies of a recording share it; other runs (another seed, another day)
/// do not. Stored in the baseline for each training recording (docs/recording-format.md).
/// Throws ptda::Error when the file cannot be read. Thread: any. Blocks (reads up to 1 MiB), allocates.
[[nodiscard]] std::string recording_id(const RecordingInfo& rec);

/// The sample rate the pipeline runs at: the recording's, which must equal the configuration's
/// [acquisition] fs_hz when that is non-zero. Throws ptda::Error naming both sources on a mismatch.
[[nodiscard]] double pipeline_fs_hz(const RecordingInfo& rec, const config::PipelineConfig& cfg,
                                    const std::string& config_source);

/// How the CAN log decoded.
struct CanCounters {
  std::uint64_t frames = 0;        ///< every frame line in the log
  std::uint64_t speed_frames = 0;  ///< decoded speed samples handed to the pipeline
  std::uint64_t other_id = 0;      ///< frames with another identifier (not an error)
  std::uint64_t wrong_dlc = 0;     ///< the speed id with an unexpected length
  std::uint64_t rtr = 0;           ///< remote frames with the speed id
  std::uint64_t error_frames = 0;  ///< bus error frames
  /// Frames per identifier (error frames excluded); extended ids carry kExtendedIdKey.
  std::map<std::uint32_t, std::uint64_t> ids;
  static constexpr std::uint32_t kExtendedIdKey = 0x80000000U;
  std::int64_t first_frame_t_ns = 0;  ///< log time of the first and last frame (when frames > 0)
  std::int64_t last_frame_t_ns = 0;
  std::int64_t first_speed_t_ns = 0;  ///< first and last decoded speed sample (latency applied)
  std::int64_t last_speed_t_ns = 0;
  std::uint64_t comment_lines = 0;  ///< non-blank lines that are not frames (candump comments)
  long first_comment_line = 0;
};

/// Refuses CAN input the pipeline cannot use, after the recording was streamed: a file with no frame
/// (not a candump log: "<log>:<line>: not a candump log ..."), a log without a usable frame of the
/// configured speed id ("no frame with id 0x184 in the CAN log (N frames); ids seen: ...; set id in
/// [can.speed_frame] of <config>"), and speed frames whose time range does not overlap the vibration
/// recording's (both ranges, in seconds from the recording's start_time). Throws ptda::Error;
/// `config_source` names the configuration in the advice. Thread: any; allocates for the message.
void check_can_input(const RecordingInfo& rec, const config::PipelineConfig& cfg, const CanCounters& can,
                     const std::string& config_source);

/// Receives the interleaved streams. Speed samples up to the end time of a block are delivered before
/// the block; on_block_end() follows each block (poll windows there).
class PipelineSink {
 public:
  virtual ~PipelineSink() = default;
  virtual void on_speed(const dsp::SpeedSample& s) = 0;
  virtual void on_samples(std::span<const float> block) = 0;
  virtual void on_block_end() {}
  /// End of both streams.
  virtual void on_finish() = 0;
};

struct RunOptions {
  std::size_t block_frames = 4096;  ///< frames read per block; at most a quarter second is used
  bool progress = true;             ///< progress bar when stderr is a terminal
  std::string progress_label;       ///< e.g. "monitor run1"
  /// Coverage of a monitor run (dsp/coverage.hpp): motion without a judged window before "not judging".
  /// The daemon's [daemon] coverage_timeout_s default.
  double coverage_timeout_s = 60.0;
  /// The configuration file, named in the advice of check_can_input (which run_recording calls).
  std::string config_source = "the configuration";
};

/// Streams the recording into sink. Returns the CAN decode counters. Throws ptda::Error on unreadable
/// or malformed input (WAV short/corrupt, malformed candump line with file:line) and, at the end, on
/// CAN input the pipeline cannot use (check_can_input).
CanCounters run_recording(const RecordingInfo& rec, const config::PipelineConfig& cfg, PipelineSink& sink,
                          const RunOptions& options = {});

// ---- the three uses ------------------------------------------------------------------------------

/// Every valid window of a recording and the regions that ended (for training).
struct CollectResult {
  dsp::CollectedWindows data;
  dsp::SlicerCounters slicer;
  CanCounters can;
  double fs_hz = 0.0;
};
/// Receives each window as it is cut (its samples live for the call only).
using CollectVisitor = std::function<void(const dsp::WindowRef&, std::span<const float>)>;
/// Cuts the recording's windows as the monitor does. Without a visitor, every window is kept in
/// data.windows with its ref, and the regions in data.regions (memory grows with the recording: 4 N
/// bytes per window); with one, each window goes to it and nothing is kept (data stays empty; `ptda
/// train` streams its passes this way, index_windows() its index).
[[nodiscard]] CollectResult collect_windows(const RecordingInfo& rec, const config::PipelineConfig& cfg,
                                            double fs_hz, const RunOptions& options = {},
                                            const CollectVisitor& visitor = {});

/// The order domain's windows of a recording ([extraction] domain = "order", docs/method.md §9): the
/// CAN angle frames and the vibration go through AngleResampler and OrderWindowCutter (configured by
/// config::angle_resampler_config / order_window_config). Every window is kept (4 N bytes each).
struct OrderCollectResult {
  dsp::OrderWindows data;
  dsp::AngleResamplerCounters resampler;
  CanCounters can;
};
/// Receives each order window as it is cut (its samples live for the call only).
using OrderVisitor = std::function<void(const dsp::OrderWindowRef&, std::span<const float>)>;
/// With a visitor, each window goes to it and nothing is kept (data stays empty; memory stays flat).
[[nodiscard]] OrderCollectResult collect_order_windows(const RecordingInfo& rec,
                                                       const config::PipelineConfig& cfg, double fs_hz,
                                                       const RunOptions& options = {},
                                                       const OrderVisitor& visitor = {});
/// Appends `more` to `all` renumbering window seq and segment so they stay unique across recordings;
/// the appended windows get the next recording index in all.recording.
void append_order_windows(dsp::OrderWindows& all, dsp::OrderWindows more);
/// The time-domain description of an order window (moved to dsp, where ptdad uses it too).
using dsp::window_ref_of;

/// Appends `more` to `all` (its windows when it holds them; refs only when its windows are empty),
/// renumbering window and region sequence numbers so they stay unique
/// (several training recordings: a region of one recording is never confused with another's). The
/// appended windows get the next recording index in all.recording (the first recording is 0), which
/// training uses as the day of each window (docs/method.md §5).
void append_collected(dsp::CollectedWindows& all, dsp::CollectedWindows more);

/// Pass 0 of `ptda train` in bounded memory: cuts the recording's windows as collect_windows() does,
/// without their samples, and appends each window's place and recording and the regions to `index`
/// (spilled: memory does not grow with the recording), renumbered as append_collected() does; the
/// recording gets the index's next recording number. `renumber` carries the offsets from one recording
/// to the next (start with {}).
struct IndexRenumber {
  std::uint32_t recordings = 0;     ///< recordings indexed so far (the next one's number)
  std::uint64_t region_offset = 0;  ///< one past the largest region seq indexed so far
  std::uint64_t window_offset = 0;  ///< one past the largest window seq indexed so far
};
struct IndexResult {
  dsp::SlicerCounters slicer;
  CanCounters can;
  std::uint64_t windows = 0;  ///< windows this recording added
  std::uint64_t regions = 0;  ///< regions this recording added
};
[[nodiscard]] IndexResult index_windows(const RecordingInfo& rec, const config::PipelineConfig& cfg,
                                        double fs_hz, const RunOptions& options, dsp::TrainingIndex& index,
                                        IndexRenumber& renumber);

/// select_windows() of a streamed index: the windows [range.first(count), range.last(count)) in cut order
/// with their recordings, and the regions they lie in (in region order), in a new index with the same
/// spill configuration.
[[nodiscard]] dsp::TrainingIndex select_windows(const dsp::TrainingIndex& all, const FractionRange& range);

/// Keeps the windows [range.first(count), range.last(count)) in cut order and the regions they lie in
/// (refs only when `all` holds no windows).
[[nodiscard]] dsp::CollectedWindows select_windows(const dsp::CollectedWindows& all,
                                                   const FractionRange& range);

/// Monitoring results of one recording with one method.
struct MonitorResult {
  std::vector<dsp::WindowResult> windows;
  dsp::CoverageState coverage;  ///< over the whole recording, as the daemon tracks it
  dsp::SlicerCounters slicer;
  CanCounters can;
  double fs_hz = 0.0;
  dsp::Domain domain = dsp::Domain::kTime;
  dsp::AngleResamplerCounters resampler;  ///< order domain only (slicer is then all zero)
  std::uint64_t order_windows_cut = 0;    ///< order domain only
};
/// Called for each polled window while the engine still holds its buffers (engine.last_window(),
/// engine.analyzer().deterministic()/residual()).
using WindowObserver = std::function<void(const dsp::WindowResult&, const dsp::MonitorEngine&)>;

/// Checks that baseline and configuration/recording agree (domain; time: sample rate, window length;
/// order: samples per revolution and revolutions); throws
/// ptda::Error naming the baseline file and the disagreeing values.
void check_baseline_matches(const dsp::Baseline& baseline, const std::string& baseline_source,
                            const config::PipelineConfig& cfg, const std::string& config_source, double fs_hz,
                            const std::string& recording_source);

/// Monitors the recording; every window goes to `observer` as it is judged and, with keep_windows, into
/// MonitorResult::windows (which then grows with the recording: ~300 bytes per window).
[[nodiscard]] MonitorResult monitor_recording(const RecordingInfo& rec, const config::PipelineConfig& cfg,
                                              const dsp::Baseline& baseline, dsp::Method method, double fs_hz,
                                              const WindowObserver& observer = {},
                                              const RunOptions& options = {}, bool keep_windows = true);

/// Recomputes the k-of-n alarm over a subset of the windows (after --windows selection) with a fresh
/// debouncer, as if monitoring had started at the subset's first window.
void redebounce(std::vector<dsp::WindowResult>& windows, const dsp::DecisionConfig& decision);

}  // namespace ptda::cli
