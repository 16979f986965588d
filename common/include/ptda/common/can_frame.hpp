// Plain CAN frame exchanged between CAN channels (SocketCAN, candump replay) and decoders.
#pragma once

#include <array>
#include <cstdint>

namespace ptda {

/// Flags of a CanFrame (bit set in CanFrame::flags).
enum CanFlag : std::uint8_t {
  kCanExtended = 1U << 0,  ///< 29-bit identifier
  kCanRtr = 1U << 1,       ///< remote transmission request (no payload)
  kCanError = 1U << 2,     ///< SocketCAN error frame; id holds the CAN_ERR_* class bits
  kCanFd = 1U << 3,        ///< CAN FD frame (len up to 64)
  kCanFdBrs = 1U << 4,     ///< CAN FD bit-rate switch
  kCanFdEsi = 1U << 5,     ///< CAN FD error state indicator
};

/// One CAN frame with its receive timestamp. Trivially copyable; safe to pass through lock-free rings.
struct CanFrame {
  std::int64_t t_ns = 0;   ///< receive time in ns (UNIX epoch for logs; the daemon's clock in ptdad)
  std::uint32_t id = 0;    ///< identifier without flag bits (11 or 29 bit; error class bits for errors)
  std::uint8_t len = 0;    ///< payload length in bytes, 0..8 classic, 0..64 FD; RTR: requested DLC
  std::uint8_t flags = 0;  ///< CanFlag bits
  std::array<std::uint8_t, 64> data{};

  [[nodiscard]] bool extended() const noexcept { return (flags & kCanExtended) != 0; }
  [[nodiscard]] bool rtr() const noexcept { return (flags & kCanRtr) != 0; }
  [[nodiscard]] bool error() const noexcept { return (flags & kCanError) != 0; }
  [[nodiscard]] bool fd() const noexcept { return (flags & kCanFd) != 0; }
};

}  // namespace ptda
