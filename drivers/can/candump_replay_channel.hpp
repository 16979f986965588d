// Replay backend of CanChannel: the frames of a candump log (formats::CandumpReader), loaded at
// configure() into one buffer and released in order, paced at real time on the daemon clock or as
// fast as the caller reads. Sent frames are kept in a fixed buffer for inspection (tests, dry runs).
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "ptda/drivers/can_channel.hpp"
#include "ptda/drivers/clock.hpp"

namespace ptda::drivers {

struct CandumpReplayConfig {
  std::filesystem::path path;
  std::string interface;         ///< only frames logged on this interface; "" = all
  bool skip_transmitted = true;  ///< drop records marked 'T' (the logger's own transmissions)
  ReplayPace pace = ReplayPace::kRealTime;
  ReplayTimeline timeline;             ///< log time -> daemon clock
  std::size_t max_frames = 4'000'000;  ///< configure() refuses longer logs (memory is fixed up front)
  std::size_t tx_capacity = 4096;      ///< sent frames kept; further sends return kTxFull
};

class CandumpReplayChannel final : public CanChannel {
 public:
  /// `clock` must outlive the channel.
  CandumpReplayChannel(CandumpReplayConfig config, Clock& clock);

  /// Reads and validates the whole log. Throws ptda::Error "<file>:<line>: <what>" for a malformed line,
  /// "<file>: more than N frames" beyond max_frames. Thread: main, start-up. Blocks and allocates.
  void configure() override;
  /// Anchors the timeline and rewinds to the first frame. Throws ptda::Error before configure().
  void activate() override;
  /// Sets the timeline's daemon-clock origin (ReplayTimeline::origin_mono_ns) for the next activate().
  /// Thread: main, while not active.
  void set_origin_mono_ns(std::int64_t origin_mono_ns) noexcept {
    config_.timeline.origin_mono_ns = origin_mono_ns;
  }
  /// Releases the next frames. Real-time pace: only frames whose mapped time has come, sleeping on the
  /// clock up to timeout_ns for the first; kEndOfStream once every frame was released.
  CanStatus receive(std::span<CanFrame> out, std::size_t& received,
                    std::int64_t timeout_ns) noexcept override;
  /// Records the frame (stamped with the clock) in the transmit buffer. Never blocks or allocates.
  CanStatus send(const CanFrame& frame) noexcept override;
  void deactivate() noexcept override { active_ = false; }

  /// Frames loaded by configure(). Thread: any after configure().
  [[nodiscard]] std::size_t frame_count() const noexcept { return frames_.size(); }
  /// Frames released so far. Thread: the receiving thread.
  [[nodiscard]] std::size_t position() const noexcept { return pos_; }
  /// Frames passed to send() and kept. Thread: the sending thread, or any once sending stopped.
  [[nodiscard]] std::span<const CanFrame> sent_frames() const noexcept { return {tx_.data(), tx_count_}; }
  /// The daemon-clock time of log time t_unix_ns under the active timeline. Thread: any after activate().
  [[nodiscard]] std::int64_t map_time(std::int64_t t_unix_ns) const noexcept {
    return origin_mono_ns_ + (t_unix_ns - origin_unix_ns_);
  }

 private:
  CandumpReplayConfig config_;
  Clock& clock_;
  std::vector<CanFrame> frames_;  ///< t_ns = log (UNIX) time
  std::vector<CanFrame> tx_;
  std::size_t tx_count_ = 0;
  std::size_t pos_ = 0;
  std::int64_t origin_unix_ns_ = 0;
  std::int64_t origin_mono_ns_ = 0;
  bool configured_ = false;
  bool active_ = false;
};

}  // namespace ptda::drivers
