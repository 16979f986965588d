// The live simulator backends: at configure time a scenario (sim/, config/scenarios/*.toml) is
// synthesised once into memory (vibration as stored values x scale, CAN speed frames with their log
// times); at run time SimSampleSource serves the vibration and SimCanChannel the frames, paced on the
// daemon clock (or as fast as the pipeline takes them), looping over the whole simulated recording.
// Both map the recording onto the daemon clock through one SimAnchor, so they line up exactly like the
// WAV and candump replays of a recording: sample g (counted over loops) is at
//   t0 + ceil(g * 1e9 / fs)   (exact integer arithmetic on fs in mHz),
// and frame k of loop L at t0 + (frame log time - recording start) + L * loop_ns, where
// loop_ns = ceil(total_samples * 1e9 / fs) is the time of the first sample of the next loop.
// The job's dwell and lead-in are standstill, so the loop seam is a standstill too.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <vector>

#include "ptda/common/can_frame.hpp"
#include "ptda/drivers/can_channel.hpp"
#include "ptda/drivers/clock.hpp"
#include "ptda/drivers/sample_source.hpp"

namespace ptda::daemon {

/// A simulated recording in memory. Immutable after make_sim_recording(); shared by both backends.
struct SimRecording {
  double fs_hz = 0.0;
  std::int64_t fs_mhz = 0;         ///< fs in millihertz (exact time arithmetic)
  std::vector<float> samples;      ///< stored value * scale (as WavReplaySource delivers a recording)
  std::vector<CanFrame> frames;    ///< t_ns relative to sample 0 (ns), log order
  std::int64_t start_unix_ns = 0;  ///< the scenario's start_time_s (informational)
  std::int64_t loop_ns = 0;        ///< time of sample `samples.size()` relative to sample 0
  std::uint64_t seed = 0;
  std::string scenario_name;

  /// ceil(index * 1e9 / fs) ns, exact for any index. Thread: any. Never allocates.
  [[nodiscard]] std::int64_t sample_offset_ns(std::uint64_t index) const noexcept;
};

/// Synthesises the scenario (sim::load_scenario, build_motion, synthesize_vibration, quantize,
/// generate_can). seed 0 = the scenario's seed. Throws ptda::Error naming the scenario file.
/// Thread: main, configure time. Allocates (tens of MB for a minute at 25.6 kHz) and takes ~0.3 s.
[[nodiscard]] std::shared_ptr<const SimRecording> make_sim_recording(const std::filesystem::path& scenario,
                                                                     std::uint32_t seed);

/// The daemon-clock time of the simulated recording's sample 0, shared by both backends. The first
/// activate() sets it (from the clock, unless preset); the second one reuses it.
/// Thread: the main thread (activate) only.
struct SimAnchor {
  bool set = false;
  std::int64_t t0_mono_ns = 0;
  std::int64_t resolve(const drivers::Clock& clock) noexcept {
    if (!set) {
      t0_mono_ns = clock.now_ns();
      set = true;
    }
    return t0_mono_ns;
  }
};

struct SimSourceConfig {
  std::uint32_t block_len = 256;  ///< 1..kMaxBlock; blocks never cross the loop seam
  bool fast = false;              ///< release as fast as read (timestamps unchanged)
  bool loop = true;               ///< false: kEndOfStream after one pass
};

class SimSampleSource final : public drivers::SampleSource {
 public:
  /// `clock` and `anchor` must outlive the source. Thread: main.
  SimSampleSource(std::shared_ptr<const SimRecording> rec, SimAnchor& anchor, drivers::Clock& clock,
                  SimSourceConfig config);
  /// Checks block_len. Throws ptda::Error. Thread: main, start-up.
  void configure() override;
  /// Anchors (shared with the CAN side) and rewinds. Thread: main. Never allocates.
  void activate() override;
  /// Real-time pace: waits on the clock (at most timeout_ns) until the block's last sample is due.
  /// Thread: the acquisition thread. Never allocates, throws or logs.
  drivers::SourceStatus read(drivers::SampleBlock& out, std::int64_t timeout_ns) noexcept override;
  void deactivate() noexcept override { active_ = false; }
  [[nodiscard]] double fs_hz() const noexcept override { return rec_->fs_hz; }

 private:
  std::shared_ptr<const SimRecording> rec_;
  SimAnchor& anchor_;
  drivers::Clock& clock_;
  SimSourceConfig config_;
  std::int64_t t0_mono_ns_ = 0;
  std::uint64_t next_index_ = 0;  ///< global sample index (over loops)
  bool configured_ = false;
  bool active_ = false;
};

struct SimCanConfig {
  bool fast = false;
  bool loop = true;
  std::size_t tx_capacity = 256;  ///< sent frames kept (oldest overwritten); all are counted
};

class SimCanChannel final : public drivers::CanChannel {
 public:
  SimCanChannel(std::shared_ptr<const SimRecording> rec, SimAnchor& anchor, drivers::Clock& clock,
                SimCanConfig config);
  /// Allocates the transmit record. Thread: main, start-up.
  void configure() override;
  void activate() override;
  /// Releases the frames whose time has come (real-time) or the next ones (fast). Thread: the CAN
  /// thread. Never allocates, throws or logs.
  drivers::CanStatus receive(std::span<CanFrame> out, std::size_t& received,
                             std::int64_t timeout_ns) noexcept override;
  /// Records the frame (alarm frames of the daemon). Thread: one sending thread. Never blocks or allocates.
  drivers::CanStatus send(const CanFrame& frame) noexcept override;
  void deactivate() noexcept override { active_ = false; }

  /// Frames passed to send() so far. Thread: any.
  [[nodiscard]] std::uint64_t sent_count() const noexcept { return stats_.tx_frames.get(); }
  /// The most recent sent frame (zero frame before any). Thread: the sending thread, or any once it stopped.
  [[nodiscard]] CanFrame last_sent() const noexcept;

 private:
  [[nodiscard]] std::int64_t frame_time(std::uint64_t k) const noexcept;

  std::shared_ptr<const SimRecording> rec_;
  SimAnchor& anchor_;
  drivers::Clock& clock_;
  SimCanConfig config_;
  std::vector<CanFrame> tx_;
  std::int64_t t0_mono_ns_ = 0;
  std::uint64_t next_frame_ = 0;  ///< global frame index (over loops)
  bool configured_ = false;
  bool active_ = false;
};

}  // namespace ptda::daemon
