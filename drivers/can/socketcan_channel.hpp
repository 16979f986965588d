// SocketCAN CAN_RAW backend of CanChannel: id filters, error frames, kernel receive timestamps and the
// kernel's drop counter, batched receive with recvmmsg. Requires a kernel with CONFIG_CAN/CAN_RAW.
#pragma once

#include <linux/can.h>
#include <linux/can/bcm.h>
#include <sys/socket.h>
#include <sys/uio.h>
#include <time.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "ptda/drivers/can_channel.hpp"
#include "ptda/drivers/clock.hpp"

namespace ptda::drivers {

/// One receive filter: frames whose id matches `id` under `mask` pass.
struct CanIdFilter {
  std::uint32_t id = 0;
  bool extended = false;
  std::uint32_t mask = 0;  ///< 0 = exact match on all 11 / 29 id bits
};

struct SocketCanConfig {
  std::string interface = "can0";
  std::vector<CanIdFilter> filters;  ///< empty = receive every data frame
  bool error_frames = true;          ///< subscribe to controller/bus-off/restart/protocol error frames
  bool bus_error_frames = false;     ///< also CAN_ERR_BUSERROR (one per bus error: may flood a bad bus)
  bool fd_frames = false;            ///< CAN_RAW_FD_FRAMES
  int rcvbuf_bytes = 0;              ///< > 0: SO_RCVBUFFORCE, falling back to SO_RCVBUF
  /// Open a CAN_BCM socket too, for set_cyclic(). When the kernel has no CAN_BCM (module can-bcm) the
  /// channel works without it: cyclic_supported() is false and cyclic_error() says why.
  bool cyclic = false;
};

/// Receive metadata carried in control messages.
struct CanRxMeta {
  bool has_time = false;
  std::int64_t t_realtime_ns = 0;  ///< SO_TIMESTAMP(NS): kernel receive time on CLOCK_REALTIME
  bool has_drops = false;
  std::uint32_t drops = 0;  ///< SO_RXQ_OVFL: cumulative drops of this socket (wraps at 2^32)
};

/// Control-message buffer size for one received frame (timestamp + drop counter).
inline constexpr std::size_t kCanCmsgBytes =
    CMSG_SPACE(sizeof(struct timespec)) + CMSG_SPACE(sizeof(std::uint32_t));

// Pure helpers (no kernel needed; unit-tested directly).

/// The CAN_RAW_FILTER array for `filters` (standard ids cannot match extended frames and vice versa;
/// RTR frames pass so the decoder can count them). Throws ptda::Error for an id wider than its format.
/// Thread: any, at configure time. Allocates.
[[nodiscard]] std::vector<can_filter> build_can_filters(std::span<const CanIdFilter> filters);
/// The CAN_RAW_ERR_FILTER mask. Thread: any. Never allocates.
[[nodiscard]] can_err_mask_t build_error_mask(bool error_frames, bool bus_error_frames) noexcept;
/// Walks msg's control messages (SCM_TIMESTAMPNS or SCM_TIMESTAMP, SO_RXQ_OVFL).
/// Thread: any. Never allocates.
[[nodiscard]] CanRxMeta parse_rx_cmsgs(const msghdr& msg) noexcept;
/// Converts a kernel frame of `nbytes` (CAN_MTU or CANFD_MTU) into out. False for any other size or
/// a length the format does not have (classic: above 8; FD: other than 0..8, 12, 16, 20, 24, 32, 48,
/// 64), so every accepted frame converts back with to_kernel_frame(). Thread: any. Never allocates.
[[nodiscard]] bool from_kernel_frame(const canfd_frame& in, std::size_t nbytes, std::int64_t t_ns,
                                     CanFrame& out) noexcept;
/// Converts a frame for write(); returns CAN_MTU or CANFD_MTU, or 0 when the frame is invalid
/// (an error frame, len > 8 classic / > 64 FD). Thread: any. Never allocates.
[[nodiscard]] std::size_t to_kernel_frame(const CanFrame& in, canfd_frame& out) noexcept;

class SocketCanChannel final : public CanChannel {
 public:
  static constexpr std::size_t kMaxBatch = 64;  ///< frames per recvmmsg call

  /// `clock` is the daemon clock that kernel timestamps are mapped onto; it must outlive the channel.
  SocketCanChannel(SocketCanConfig config, const Clock& clock);
  ~SocketCanChannel() override;

  /// Opens the socket, applies filters and options, binds to the interface. Throws ptda::Error
  /// "socketcan <iface>: <call>: <reason>"; EAFNOSUPPORT means the kernel has no AF_CAN.
  void configure() override;
  void activate() override;
  CanStatus receive(std::span<CanFrame> out, std::size_t& received,
                    std::int64_t timeout_ns) noexcept override;
  CanStatus send(const CanFrame& frame) noexcept override;
  [[nodiscard]] bool cyclic_supported() const noexcept override { return bcm_fd_ >= 0; }
  /// One TX_SETUP on the CAN_BCM socket (SETTIMER, plus STARTTIMER / TX_ANNOUNCE per tx.start).
  CanStatus set_cyclic(const CanCyclicTx& tx) noexcept override;
  /// Ends a cyclic transmission (TX_DELETE) and the channel.
  void deactivate() noexcept override;

  /// Why set_cyclic() is not available ("" when it is, or when it was not asked for). Thread: the main
  /// thread after configure().
  [[nodiscard]] const std::string& cyclic_error() const noexcept { return bcm_error_; }

  /// The socket (for a caller that polls several fds). -1 before configure(). Thread: any.
  [[nodiscard]] int fd() const noexcept { return fd_; }

 private:
  SocketCanConfig config_;
  const Clock& clock_;
  int fd_ = -1;
  int bcm_fd_ = -1;
  std::string bcm_error_;
  std::uint32_t bcm_id_ = 0;  ///< can_id (with CAN_EFF_FLAG) of the set-up cyclic transmission
  bool bcm_set_ = false;
  // One TX_SETUP message: the head, then the frames (bcm_msg_head ends in a flexible array).
  alignas(bcm_msg_head) unsigned char bcm_msg_[sizeof(bcm_msg_head) +
                                               CanCyclicTx::kMaxFrames * sizeof(can_frame)]{};
  bool active_ = false;
  bool drops_seen_ = false;
  std::uint32_t last_drops_ = 0;
  std::array<canfd_frame, kMaxBatch> frames_{};
  std::array<iovec, kMaxBatch> iov_{};
  struct alignas(cmsghdr) CmsgBuffer {
    unsigned char bytes[kCanCmsgBytes];
  };
  std::array<CmsgBuffer, kMaxBatch> cmsg_{};
  std::array<mmsghdr, kMaxBatch> msgs_{};
};

}  // namespace ptda::drivers
