#include "can/socketcan_channel.hpp"

#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <string>
#include <utility>

#include "ptda/common/error.hpp"

namespace ptda::drivers {
namespace {

bool valid_fd_len(std::size_t len) noexcept {
  return len <= 8 || len == 12 || len == 16 || len == 20 || len == 24 || len == 32 || len == 48 || len == 64;
}

std::string hex(std::uint32_t v) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "0x%X", v);
  return buf;
}

timespec to_timespec(std::int64_t ns) noexcept {
  if (ns < 0) ns = 0;
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(ns / 1'000'000'000);
  ts.tv_nsec = static_cast<long>(ns % 1'000'000'000);
  return ts;
}

/// Counts a transmit that did not go through (errno `err`, 0 for a short write) and says how.
CanStatus failed_write(int err, CanChannelStats& stats) noexcept {
  if (err == ENOBUFS || err == EAGAIN || err == EWOULDBLOCK) {
    stats.tx_full.add();
    return CanStatus::kTxFull;
  }
  stats.tx_errors.add();
  if (err == ENETDOWN || err == ENETUNREACH || err == ENXIO) return CanStatus::kBusDown;
  return CanStatus::kError;
}

}  // namespace

std::vector<can_filter> build_can_filters(std::span<const CanIdFilter> filters) {
  std::vector<can_filter> out;
  out.reserve(filters.size());
  for (const CanIdFilter& f : filters) {
    can_filter k{};
    if (f.extended) {
      if (f.id > CAN_EFF_MASK) throw Error("CAN filter: extended id " + hex(f.id) + " exceeds 29 bits");
      k.can_id = f.id | CAN_EFF_FLAG;
      k.can_mask = (f.mask == 0 ? CAN_EFF_MASK : (f.mask & CAN_EFF_MASK)) | CAN_EFF_FLAG;
    } else {
      if (f.id > CAN_SFF_MASK) throw Error("CAN filter: standard id " + hex(f.id) + " exceeds 11 bits");
      k.can_id = f.id;
      k.can_mask = (f.mask == 0 ? CAN_SFF_MASK : (f.mask & CAN_SFF_MASK)) | CAN_EFF_FLAG;
    }
    out.push_back(k);
  }
  return out;
}

can_err_mask_t build_error_mask(bool error_frames, bool bus_error_frames) noexcept {
  if (!error_frames) return 0;
  // State changes only; per-bus-error classes (PROT, BUSERROR, ACK, LOSTARB) arrive once per faulty
  // frame and can flood a broken bus, so they are opt-in.
  can_err_mask_t m = CAN_ERR_TX_TIMEOUT | CAN_ERR_CRTL | CAN_ERR_TRX | CAN_ERR_BUSOFF | CAN_ERR_RESTARTED;
  if (bus_error_frames) m |= CAN_ERR_PROT | CAN_ERR_BUSERROR | CAN_ERR_ACK | CAN_ERR_LOSTARB;
  return m;
}

CanRxMeta parse_rx_cmsgs(const msghdr& msg) noexcept {
  CanRxMeta meta;
  auto& m = const_cast<msghdr&>(msg);  // CMSG_NXTHDR takes a non-const pointer but only reads
  for (cmsghdr* c = CMSG_FIRSTHDR(&m); c != nullptr; c = CMSG_NXTHDR(&m, c)) {
    if (c->cmsg_level != SOL_SOCKET) continue;
    if (c->cmsg_type == SCM_TIMESTAMPNS && c->cmsg_len >= CMSG_LEN(sizeof(timespec))) {
      timespec ts{};
      std::memcpy(&ts, CMSG_DATA(c), sizeof ts);
      meta.has_time = true;
      meta.t_realtime_ns = static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
    } else if (c->cmsg_type == SCM_TIMESTAMP && c->cmsg_len >= CMSG_LEN(sizeof(timeval))) {
      timeval tv{};
      std::memcpy(&tv, CMSG_DATA(c), sizeof tv);
      meta.has_time = true;
      meta.t_realtime_ns =
          static_cast<std::int64_t>(tv.tv_sec) * 1'000'000'000 + static_cast<std::int64_t>(tv.tv_usec) * 1000;
    } else if (c->cmsg_type == SO_RXQ_OVFL && c->cmsg_len >= CMSG_LEN(sizeof(std::uint32_t))) {
      std::memcpy(&meta.drops, CMSG_DATA(c), sizeof meta.drops);
      meta.has_drops = true;
    }
  }
  return meta;
}

bool from_kernel_frame(const canfd_frame& in, std::size_t nbytes, std::int64_t t_ns, CanFrame& out) noexcept {
  out = CanFrame{};
  out.t_ns = t_ns;
  if (nbytes == CAN_MTU) {
    if (in.len > CAN_MAX_DLEN) return false;
    if ((in.can_id & CAN_ERR_FLAG) != 0) {
      out.flags = kCanError;
      out.id = in.can_id & CAN_ERR_MASK;
    } else if ((in.can_id & CAN_EFF_FLAG) != 0) {
      out.flags = kCanExtended;
      out.id = in.can_id & CAN_EFF_MASK;
    } else {
      out.id = in.can_id & CAN_SFF_MASK;
    }
    if ((in.can_id & CAN_RTR_FLAG) != 0 && !out.error()) out.flags |= kCanRtr;
    out.len = in.len;
    if (!out.rtr()) std::memcpy(out.data.data(), in.data, in.len);
    return true;
  }
  if (nbytes == CANFD_MTU) {
    if (!valid_fd_len(in.len) || (in.can_id & (CAN_ERR_FLAG | CAN_RTR_FLAG)) != 0) return false;
    out.flags = kCanFd;
    if ((in.flags & CANFD_BRS) != 0) out.flags |= kCanFdBrs;
    if ((in.flags & CANFD_ESI) != 0) out.flags |= kCanFdEsi;
    if ((in.can_id & CAN_EFF_FLAG) != 0) {
      out.flags |= kCanExtended;
      out.id = in.can_id & CAN_EFF_MASK;
    } else {
      out.id = in.can_id & CAN_SFF_MASK;
    }
    out.len = in.len;
    std::memcpy(out.data.data(), in.data, in.len);
    return true;
  }
  return false;
}

std::size_t to_kernel_frame(const CanFrame& in, canfd_frame& out) noexcept {
  out = canfd_frame{};
  if (in.error()) return 0;
  if (in.extended()) {
    if (in.id > CAN_EFF_MASK) return 0;
    out.can_id = in.id | CAN_EFF_FLAG;
  } else {
    if (in.id > CAN_SFF_MASK) return 0;
    out.can_id = in.id;
  }
  if (in.fd()) {
    if (in.rtr() || !valid_fd_len(in.len)) return 0;
    out.len = in.len;
    if ((in.flags & kCanFdBrs) != 0) out.flags |= CANFD_BRS;
    if ((in.flags & kCanFdEsi) != 0) out.flags |= CANFD_ESI;
    std::memcpy(out.data, in.data.data(), in.len);
    return CANFD_MTU;
  }
  if (in.len > CAN_MAX_DLEN) return 0;
  out.len = in.len;
  if (in.rtr()) {
    out.can_id |= CAN_RTR_FLAG;
  } else {
    std::memcpy(out.data, in.data.data(), in.len);
  }
  return CAN_MTU;
}

SocketCanChannel::SocketCanChannel(SocketCanConfig config, const Clock& clock)
    : config_(std::move(config)), clock_(clock) {}

SocketCanChannel::~SocketCanChannel() {
  if (fd_ >= 0) ::close(fd_);
  if (bcm_fd_ >= 0) ::close(bcm_fd_);
}

void SocketCanChannel::configure() {
  const std::string where = "socketcan " + config_.interface;
  if (config_.interface.empty() || config_.interface.size() >= IFNAMSIZ) {
    throw Error(where, 0, 0, "interface name must be 1.." + std::to_string(IFNAMSIZ - 1) + " characters");
  }
  const auto filters = build_can_filters(config_.filters);  // throws before anything is opened
  if (fd_ >= 0) {
    ::close(fd_);
    fd_ = -1;
  }
  fd_ = ::socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
  if (fd_ < 0) {
    const int e = errno;
    throw Error(where, 0, 0,
                std::string("socket(AF_CAN, SOCK_RAW, CAN_RAW): ") + std::strerror(e) +
                    (e == EAFNOSUPPORT ? " (kernel without CONFIG_CAN, or module can-raw not loaded)" : ""));
  }
  auto fail = [&](const char* call) {
    const int e = errno;
    ::close(fd_);
    fd_ = -1;
    throw Error(where, 0, 0, std::string(call) + ": " + std::strerror(e));
  };
  const unsigned int ifindex = ::if_nametoindex(config_.interface.c_str());
  if (ifindex == 0) fail("if_nametoindex (no such interface?)");

  if (!filters.empty()) {
    if (::setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_FILTER, filters.data(),
                     static_cast<socklen_t>(filters.size() * sizeof(can_filter))) != 0)
      fail("setsockopt(CAN_RAW_FILTER)");
  }
  const can_err_mask_t err_mask = build_error_mask(config_.error_frames, config_.bus_error_frames);
  if (::setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &err_mask, sizeof err_mask) != 0)
    fail("setsockopt(CAN_RAW_ERR_FILTER)");
  if (config_.fd_frames) {
    const int on = 1;
    if (::setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_FD_FRAMES, &on, sizeof on) != 0)
      fail("setsockopt(CAN_RAW_FD_FRAMES) (interface not CAN FD capable?)");
  }
  const int on = 1;
  if (::setsockopt(fd_, SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof on) != 0) fail("setsockopt(SO_TIMESTAMPNS)");
  if (::setsockopt(fd_, SOL_SOCKET, SO_RXQ_OVFL, &on, sizeof on) != 0) fail("setsockopt(SO_RXQ_OVFL)");
  if (config_.rcvbuf_bytes > 0) {
    // SO_RCVBUFFORCE needs CAP_NET_ADMIN; without it the plain option (capped by rmem_max) is used.
    if (::setsockopt(fd_, SOL_SOCKET, SO_RCVBUFFORCE, &config_.rcvbuf_bytes, sizeof config_.rcvbuf_bytes) !=
            0 &&
        ::setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &config_.rcvbuf_bytes, sizeof config_.rcvbuf_bytes) != 0)
      fail("setsockopt(SO_RCVBUF)");
  }
  sockaddr_can addr{};
  addr.can_family = AF_CAN;
  addr.can_ifindex = static_cast<int>(ifindex);
  if (::bind(fd_, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) fail("bind");

  if (bcm_fd_ >= 0) {
    ::close(bcm_fd_);
    bcm_fd_ = -1;
  }
  bcm_error_.clear();
  if (config_.cyclic) {
    // Not fatal: without the broadcast manager the caller sends every frame itself.
    bcm_fd_ = ::socket(PF_CAN, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_BCM);
    if (bcm_fd_ < 0) {
      const int e = errno;
      bcm_error_ =
          std::string("socket(AF_CAN, SOCK_DGRAM, CAN_BCM): ") + std::strerror(e) +
          (e == EPROTONOSUPPORT ? " (kernel without CONFIG_CAN_BCM, or module can-bcm not loaded)" : "");
    } else if (::connect(bcm_fd_, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) {
      bcm_error_ = std::string("connect(CAN_BCM): ") + std::strerror(errno);
      ::close(bcm_fd_);
      bcm_fd_ = -1;
    }
  }

  for (std::size_t i = 0; i < kMaxBatch; ++i) {
    iov_[i].iov_base = &frames_[i];
    iov_[i].iov_len = sizeof(canfd_frame);
    msgs_[i] = mmsghdr{};
    msgs_[i].msg_hdr.msg_iov = &iov_[i];
    msgs_[i].msg_hdr.msg_iovlen = 1;
    msgs_[i].msg_hdr.msg_control = cmsg_[i].bytes;
    msgs_[i].msg_hdr.msg_controllen = kCanCmsgBytes;
  }
}

void SocketCanChannel::activate() {
  if (fd_ < 0) throw Error("socketcan " + config_.interface, 0, 0, "activate() before configure()");
  active_ = true;
}

void SocketCanChannel::deactivate() noexcept {
  if (bcm_fd_ >= 0 && bcm_set_) {
    bcm_msg_head head{};
    head.opcode = TX_DELETE;
    head.can_id = bcm_id_;
    (void)::write(bcm_fd_, &head, sizeof head);
    bcm_set_ = false;
  }
  active_ = false;
}

CanStatus SocketCanChannel::set_cyclic(const CanCyclicTx& tx) noexcept {
  if (!active_) return CanStatus::kNotActive;
  const std::size_t n = tx.frames.size();
  if (bcm_fd_ < 0 || n == 0 || n > CanCyclicTx::kMaxFrames || tx.period_ns <= 0 || tx.count == 0) {
    stats_.tx_errors.add();
    return CanStatus::kError;
  }
  bcm_msg_head head{};
  static_assert(sizeof(bcm_msg_head) % alignof(can_frame) == 0, "the frames follow the head aligned");
  for (std::size_t i = 0; i < n; ++i) {
    const CanFrame& f = tx.frames[i];
    canfd_frame kf{};
    // One id for all (the operation is keyed by it); classic frames only (no CAN_FD_FRAME flag here).
    if (f.fd() || to_kernel_frame(f, kf) != CAN_MTU || (i > 0 && kf.can_id != head.can_id)) {
      stats_.tx_errors.add();
      return CanStatus::kError;
    }
    if (i == 0) head.can_id = kf.can_id;
    std::memcpy(bcm_msg_ + sizeof(bcm_msg_head) + i * sizeof(can_frame), &kf, sizeof(can_frame));
  }
  if (bcm_set_ && head.can_id != bcm_id_) {  // another id: end the old operation first
    bcm_msg_head del{};
    del.opcode = TX_DELETE;
    del.can_id = bcm_id_;
    (void)::write(bcm_fd_, &del, sizeof del);
    bcm_set_ = false;
  }
  head.opcode = TX_SETUP;
  head.flags = SETTIMER;
  // A new operation must start its timer; STARTTIMER also sends one frame at once.
  if (tx.start == CanCyclicTx::Start::kRestart || !bcm_set_) head.flags |= STARTTIMER;
  if (tx.start == CanCyclicTx::Start::kAnnounce) head.flags |= TX_ANNOUNCE;
  head.count = tx.count;
  head.ival1.tv_sec = static_cast<decltype(head.ival1.tv_sec)>(tx.period_ns / 1'000'000'000);
  head.ival1.tv_usec = static_cast<decltype(head.ival1.tv_usec)>((tx.period_ns % 1'000'000'000) / 1000);
  head.ival2 = {};  // after count frames: stop (the lease ran out)
  head.nframes = static_cast<std::uint32_t>(n);
  std::memcpy(bcm_msg_, &head, sizeof head);
  const std::size_t bytes = sizeof(bcm_msg_head) + n * sizeof(can_frame);
  const ssize_t w = ::write(bcm_fd_, bcm_msg_, bytes);
  if (w == static_cast<ssize_t>(bytes)) {
    bcm_set_ = true;
    bcm_id_ = head.can_id;
    stats_.tx_frames.add();  // counts set-ups: the kernel's own sends are not seen here
    return CanStatus::kOk;
  }
  return failed_write(w < 0 ? errno : 0, stats_);
}

CanStatus SocketCanChannel::receive(std::span<CanFrame> out, std::size_t& received,
                                    std::int64_t timeout_ns) noexcept {
  received = 0;
  if (!active_) return CanStatus::kNotActive;
  const std::size_t want = std::min(out.size(), kMaxBatch);
  if (want == 0) return CanStatus::kOk;

  int n = -1;
  for (int attempt = 0; attempt < 2; ++attempt) {
    for (std::size_t i = 0; i < want; ++i) {
      msgs_[i].msg_hdr.msg_controllen = kCanCmsgBytes;
      msgs_[i].msg_hdr.msg_flags = 0;
      msgs_[i].msg_len = 0;
    }
    n = ::recvmmsg(fd_, msgs_.data(), static_cast<unsigned int>(want), MSG_DONTWAIT, nullptr);
    if (n > 0) break;
    if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) {
      stats_.rx_errors.add();
      return CanStatus::kError;
    }
    if (attempt == 1 || timeout_ns <= 0) return CanStatus::kTimeout;  // woken without data (or EINTR); a poll
    pollfd p{fd_, POLLIN, 0};
    const timespec ts = to_timespec(timeout_ns);
    const int r = ::ppoll(&p, 1, &ts, nullptr);
    if (r == 0) return CanStatus::kTimeout;
    if (r < 0) {
      if (errno == EINTR) return CanStatus::kTimeout;
      stats_.rx_errors.add();
      return CanStatus::kError;
    }
  }

  // Kernel stamps are CLOCK_REALTIME; map them onto the daemon clock with the offset sampled now
  // (bracketed: a preemption between two plain clock reads would shift the whole batch, and frames out of
  // order end the slicer's constant-speed run). A wall-clock step between the frame's arrival and this
  // line misplaces only this batch.
  const std::int64_t offset = realtime_offset_ns(clock_);
  const std::int64_t mono_now = clock_.now_ns();
  for (int i = 0; i < n; ++i) {
    const msghdr& h = msgs_[static_cast<std::size_t>(i)].msg_hdr;
    const CanRxMeta meta = parse_rx_cmsgs(h);
    if (meta.has_drops) {
      if (drops_seen_) {
        stats_.rx_overflow_drops.add(static_cast<std::uint32_t>(meta.drops - last_drops_));  // mod 2^32
      } else {
        stats_.rx_overflow_drops.add(meta.drops);
        drops_seen_ = true;
      }
      last_drops_ = meta.drops;
    }
    if ((h.msg_flags & (MSG_TRUNC | MSG_CTRUNC)) != 0) {
      stats_.rx_errors.add();
      continue;
    }
    const std::int64_t t_ns = meta.has_time ? meta.t_realtime_ns - offset : mono_now;
    CanFrame& f = out[received];
    if (!from_kernel_frame(frames_[static_cast<std::size_t>(i)], msgs_[static_cast<std::size_t>(i)].msg_len,
                           t_ns, f)) {
      stats_.rx_errors.add();
      continue;
    }
    if (f.error()) apply_error_frame(f, stats_);
    stats_.rx_frames.add();
    ++received;
  }
  return received > 0 ? CanStatus::kOk : CanStatus::kTimeout;
}

CanStatus SocketCanChannel::send(const CanFrame& frame) noexcept {
  if (!active_) return CanStatus::kNotActive;
  canfd_frame kf{};
  const std::size_t n = to_kernel_frame(frame, kf);
  if (n == 0 || (n == CANFD_MTU && !config_.fd_frames)) {
    stats_.tx_errors.add();
    return CanStatus::kError;
  }
  const ssize_t w = ::send(fd_, &kf, n, MSG_DONTWAIT | MSG_NOSIGNAL);
  if (w == static_cast<ssize_t>(n)) {
    stats_.tx_frames.add();
    return CanStatus::kOk;
  }
  return failed_write(w < 0 ? errno : 0, stats_);
}

}  // namespace ptda::drivers
