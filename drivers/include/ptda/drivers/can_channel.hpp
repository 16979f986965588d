// The CAN seam: receive frames with receive timestamps on the daemon's clock, send alarm frames.
// Backends: SocketCAN (socketcan_channel), candump replay (candump_replay_channel).
//
// Lifecycle: constructed -> configure() (open, validate, allocate) -> activate() -> receive()/send()
// -> deactivate(). Error frames are passed through to the caller (flag kCanError) after they updated
// bus_state() and the counters.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <span>

#include "ptda/common/can_frame.hpp"
#include "ptda/drivers/counter.hpp"

namespace ptda::drivers {

enum class CanStatus : std::uint8_t {
  kOk = 0,       ///< receive: >= 1 frame; send: queued
  kTimeout,      ///< receive: nothing within the timeout
  kEndOfStream,  ///< replay ended
  kError,        ///< a system call failed (counted)
  kTxFull,       ///< send: the transmit queue is full (counted; frame dropped)
  kBusDown,      ///< send: bus-off or interface down (counted)
  kNotActive,
};

/// ISO 11898 fault confinement as reported by SocketCAN error frames.
enum class CanBusState : std::uint8_t {
  kErrorActive = 0,   ///< normal
  kErrorWarning = 1,  ///< an error counter passed 96
  kErrorPassive = 2,  ///< an error counter passed 127: the node may no longer signal errors actively
  kBusOff = 3,        ///< transmit error counter passed 255: the controller left the bus
};

struct CanCounters {
  std::uint64_t rx_frames = 0;  ///< frames handed to the caller (error frames included)
  std::uint64_t rx_error_frames = 0;
  std::uint64_t rx_overflow_drops = 0;  ///< frames the kernel dropped on a full socket queue (SO_RXQ_OVFL)
  std::uint64_t rx_errors = 0;          ///< failed or malformed reads
  std::uint64_t tx_frames = 0;
  std::uint64_t tx_full = 0;               ///< ENOBUFS / EAGAIN on send
  std::uint64_t tx_errors = 0;             ///< other send failures
  std::uint64_t bus_off = 0;               ///< transitions into bus-off
  std::uint64_t error_passive = 0;         ///< transitions into error-passive
  std::uint64_t error_warning = 0;         ///< transitions into error-warning
  std::uint64_t restarts = 0;              ///< controller restarted after bus-off (CAN_ERR_RESTARTED)
  std::uint64_t controller_overflows = 0;  ///< controller rx/tx buffer overflow reported in error frames
  std::uint64_t protocol_errors = 0;       ///< bus errors (CAN_ERR_PROT / BUSERROR / ACK / TRX)
};

/// The live counters and bus state: written by the receiving thread, read by any.
struct CanChannelStats {
  Counter rx_frames, rx_error_frames, rx_overflow_drops, rx_errors, tx_frames, tx_full, tx_errors, bus_off,
      error_passive, error_warning, restarts, controller_overflows, protocol_errors;
  std::atomic<CanBusState> state{CanBusState::kErrorActive};

  [[nodiscard]] CanCounters snapshot() const noexcept {
    return {rx_frames.get(),      rx_error_frames.get(), rx_overflow_drops.get(), rx_errors.get(),
            tx_frames.get(),      tx_full.get(),         tx_errors.get(),         bus_off.get(),
            error_passive.get(),  error_warning.get(),   restarts.get(),          controller_overflows.get(),
            protocol_errors.get()};
  }
};

/// A transmission the kernel times (SocketCAN's broadcast manager, CAN_BCM TX_SETUP): `frames` go out
/// in turn, one every `period_ns`, until `count` frames have gone out after this call; then the kernel
/// stops. Calling again before that replaces the frames' content and sets the remaining count anew (a
/// lease the sender renews); the turn (which frame is next) and the timer's phase are kept unless
/// `start` says otherwise. A sender that stops renewing (hung, killed) goes silent within count periods.
struct CanCyclicTx {
  enum class Start : std::uint8_t {
    kKeepTimer,  ///< the running timer goes on; nothing is sent now
    kAnnounce,   ///< one frame now (the next in turn), the timer's phase kept
    kRestart,    ///< one frame now, the timer restarted from now (also starts a stopped one)
  };
  static constexpr std::size_t kMaxFrames = 16;
  std::span<const CanFrame> frames;  ///< 1..kMaxFrames classic frames of one id
  std::int64_t period_ns = 0;        ///< > 0
  std::uint32_t count = 0;           ///< frames after this call before the kernel stops, >= 1
  Start start = Start::kKeepTimer;
};

/// Applies one SocketCAN error frame (frame.error(); id = CAN_ERR_* class bits, data[] = details) to
/// the bus state and counters. Pure state machine shared by every backend. Thread: the receiving thread.
/// Never allocates.
void apply_error_frame(const CanFrame& frame, CanChannelStats& stats) noexcept;

class CanChannel {
 public:
  virtual ~CanChannel() = default;
  CanChannel(const CanChannel&) = delete;
  CanChannel& operator=(const CanChannel&) = delete;

  /// Opens and validates (socket, filters, log file...). Throws ptda::Error (what and where).
  /// Thread: the main thread at start-up. Blocks and allocates.
  virtual void configure() = 0;
  /// Starts receiving (anchors replay time). Throws ptda::Error. Thread: the main thread. Never allocates.
  virtual void activate() = 0;
  /// Receives up to out.size() frames into out[0..received), waiting at most timeout_ns for the first
  /// (the receiving thread's one wait; timeout_ns <= 0 polls without waiting, as ptdad drains a burst).
  /// Timestamps are on the daemon's clock. Thread: the one receiving
  /// thread. Never allocates, throws or logs.
  virtual CanStatus receive(std::span<CanFrame> out, std::size_t& received,
                            std::int64_t timeout_ns) noexcept = 0;
  /// Queues one frame for transmission without waiting. Thread: one sending thread (may differ from the
  /// receiving one). Never blocks, allocates or throws.
  virtual CanStatus send(const CanFrame& frame) noexcept = 0;
  /// Whether set_cyclic() works on this channel (SocketCAN with CAN_BCM; a real-time replay emulates
  /// it). Known after configure(). Thread: any. Never blocks.
  [[nodiscard]] virtual bool cyclic_supported() const noexcept { return false; }
  /// Sets up or renews a kernel-timed cyclic transmission (CanCyclicTx). kError when unsupported or the
  /// request is invalid; kTxFull / kBusDown as send(). Thread: the sending thread. Never blocks,
  /// allocates or throws; one system call.
  virtual CanStatus set_cyclic(const CanCyclicTx& tx) noexcept {
    (void)tx;
    stats_.tx_errors.add();
    return CanStatus::kError;
  }
  /// Stops; safe in any state and twice. Thread: the main thread after receive()/send() stopped.
  virtual void deactivate() noexcept = 0;

  /// Thread: any. Never blocks.
  [[nodiscard]] CanBusState bus_state() const noexcept {
    return stats_.state.load(std::memory_order_relaxed);
  }
  /// Thread: any. Never blocks or allocates.
  [[nodiscard]] CanCounters counters() const noexcept { return stats_.snapshot(); }

 protected:
  CanChannel() = default;
  CanChannelStats stats_;
};

}  // namespace ptda::drivers
