// Replay backend of CanChannel: the frames of a candump log (formats::CandumpReader), validated at
// configure() and streamed from the file in order (one frame read ahead: memory does not depend on the
// log's length), paced at real time on the daemon clock or as fast as the caller reads. Sent frames are
// kept in a fixed buffer for inspection (tests, dry runs).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "ptda/drivers/can_channel.hpp"
#include "ptda/drivers/clock.hpp"

namespace ptda::formats {
class CandumpReader;
struct CandumpRecord;
}  // namespace ptda::formats

namespace ptda::drivers {

struct CandumpReplayConfig {
  std::filesystem::path path;
  std::string interface;         ///< only frames logged on this interface; "" = all
  bool skip_transmitted = true;  ///< drop records marked 'T' (the logger's own transmissions)
  ReplayPace pace = ReplayPace::kRealTime;
  ReplayTimeline timeline;         ///< log time -> daemon clock
  std::size_t tx_capacity = 4096;  ///< sent frames kept; further sends return kTxFull
  /// Emulate the kernel's cyclic transmission (set_cyclic(), CAN_BCM) at real-time pace: its frames go
  /// into the transmit buffer stamped with their due times, as the kernel would have sent them.
  bool cyclic = false;
};

class CandumpReplayChannel final : public CanChannel {
 public:
  /// `clock` must outlive the channel.
  CandumpReplayChannel(CandumpReplayConfig config, Clock& clock);
  ~CandumpReplayChannel() override;

  /// Reads and validates the whole log (one pass, nothing kept but the count and the first frame's
  /// time). Throws ptda::Error "<file>:<line>: <what>" for a malformed line. Thread: main, start-up.
  /// Blocks and allocates.
  void configure() override;
  /// Anchors the timeline and rewinds to the first frame. Throws ptda::Error before configure().
  /// Never allocates.
  void activate() override;
  /// Sets the timeline's daemon-clock origin (ReplayTimeline::origin_mono_ns) for the next activate().
  /// Thread: main, while not active.
  void set_origin_mono_ns(std::int64_t origin_mono_ns) noexcept {
    config_.timeline.origin_mono_ns = origin_mono_ns;
  }
  /// Releases the next frames, read from the file as they go. Real-time pace: only frames whose mapped
  /// time has come, sleeping on the clock up to timeout_ns for the first (none for timeout_ns <= 0);
  /// kEndOfStream once every frame was released. A log that changed since configure() and no longer
  /// parses ends the stream there (counted in rx_errors). Thread: the receiving thread. Reads the file
  /// (as the WAV replay does); never allocates (the reader's line buffer grew at configure) or throws.
  CanStatus receive(std::span<CanFrame> out, std::size_t& received,
                    std::int64_t timeout_ns) noexcept override;
  /// Records the frame (stamped with the clock) in the transmit buffer. Never blocks or allocates.
  CanStatus send(const CanFrame& frame) noexcept override;
  [[nodiscard]] bool cyclic_supported() const noexcept override {
    return config_.cyclic && config_.pace == ReplayPace::kRealTime;
  }
  /// As CAN_BCM's TX_SETUP (CanCyclicTx): the frames the kernel would have sent since the last call are
  /// recorded (stamped with their due times), then the set-up is applied. Thread: the sending thread.
  /// Never blocks or allocates.
  CanStatus set_cyclic(const CanCyclicTx& tx) noexcept override;
  /// Records the cyclic frames due until now, then stops. Thread: main, after sending stopped.
  void deactivate() noexcept override;

  /// Frames in the log (as configure() counted them). Thread: any after configure().
  [[nodiscard]] std::size_t frame_count() const noexcept { return frame_count_; }
  /// Frames released so far. Thread: the receiving thread.
  [[nodiscard]] std::size_t position() const noexcept { return pos_; }
  /// Frames passed to send() (and the emulated cyclic ones) and kept. Thread: the sending thread, or any once
  /// sending stopped.
  [[nodiscard]] std::span<const CanFrame> sent_frames() const noexcept { return {tx_.data(), tx_count_}; }
  /// The daemon-clock time of log time t_unix_ns under the active timeline. Thread: any after activate().
  [[nodiscard]] std::int64_t map_time(std::int64_t t_unix_ns) const noexcept {
    return origin_mono_ns_ + (t_unix_ns - origin_unix_ns_);
  }

 private:
  /// Reads the next kept frame (interface, direction) into next_. False at the end or on a read error.
  bool pull() noexcept;
  /// Keeps one frame stamped t_ns (kTxFull when the buffer is full).
  CanStatus record(const CanFrame& frame, std::int64_t t_ns) noexcept;
  /// The emulated kernel timer: records the cyclic frames due up to now.
  void run_cyclic(std::int64_t now) noexcept;
  /// Sends the cyclic transmission's next frame now (STARTTIMER / TX_ANNOUNCE).
  void cyclic_send_one(std::int64_t now) noexcept;

  struct CyclicState {
    std::array<CanFrame, CanCyclicTx::kMaxFrames> frames{};
    std::size_t n = 0;
    std::size_t next = 0;  ///< the frame in turn
    std::uint32_t count = 0;
    std::int64_t period_ns = 0;
    std::int64_t due_ns = 0;  ///< the timer's next expiry
    bool running = false;
    bool set = false;
  };
  CyclicState cyc_;

  CandumpReplayConfig config_;
  Clock& clock_;
  std::unique_ptr<formats::CandumpReader> reader_;
  std::unique_ptr<formats::CandumpRecord> record_;  ///< scratch (its iface string keeps its capacity)
  CanFrame next_{};                                 ///< the next frame to release; t_ns = log (UNIX) time
  bool have_next_ = false;
  bool at_end_ = false;
  std::size_t frame_count_ = 0;
  std::int64_t first_t_ns_ = 0;  ///< log time of the first frame
  std::vector<CanFrame> tx_;
  std::size_t tx_count_ = 0;
  std::size_t pos_ = 0;
  std::int64_t origin_unix_ns_ = 0;
  std::int64_t origin_mono_ns_ = 0;
  bool configured_ = false;
  bool active_ = false;
};

}  // namespace ptda::drivers
