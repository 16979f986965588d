// SocketCAN error frame -> bus state and counters (linux/can/error.h semantics).
#include <linux/can/error.h>

#include "ptda/drivers/can_channel.hpp"

namespace ptda::drivers {
namespace {

void enter(CanChannelStats& s, CanBusState next) noexcept {
  const CanBusState cur = s.state.load(std::memory_order_relaxed);
  if (cur == next) return;
  switch (next) {
    case CanBusState::kBusOff:
      s.bus_off.add();
      break;
    case CanBusState::kErrorPassive:
      s.error_passive.add();
      break;
    case CanBusState::kErrorWarning:
      s.error_warning.add();
      break;
    case CanBusState::kErrorActive:
      break;
  }
  s.state.store(next, std::memory_order_relaxed);
}

}  // namespace

void apply_error_frame(const CanFrame& frame, CanChannelStats& stats) noexcept {
  if (!frame.error()) return;
  stats.rx_error_frames.add();
  const std::uint32_t cls = frame.id;
  const std::uint8_t ctrl = frame.len > 1 ? frame.data[1] : 0;

  if ((cls & CAN_ERR_CRTL) != 0 && (ctrl & (CAN_ERR_CRTL_RX_OVERFLOW | CAN_ERR_CRTL_TX_OVERFLOW)) != 0) {
    stats.controller_overflows.add();
  }
  if ((cls & (CAN_ERR_PROT | CAN_ERR_BUSERROR | CAN_ERR_ACK | CAN_ERR_TRX)) != 0) stats.protocol_errors.add();

  // One frame may carry several classes; bus-off dominates, then a restart, then the controller state
  // (the highest level it reports: drivers also report a drop from passive to warning this way).
  if ((cls & CAN_ERR_BUSOFF) != 0) {
    enter(stats, CanBusState::kBusOff);
    return;
  }
  if ((cls & CAN_ERR_RESTARTED) != 0) {
    stats.restarts.add();
    enter(stats, CanBusState::kErrorActive);
  }
  if ((cls & CAN_ERR_CRTL) != 0) {
    const bool bus_off = stats.state.load(std::memory_order_relaxed) == CanBusState::kBusOff;
    if ((ctrl & (CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE)) != 0) {
      if (!bus_off) enter(stats, CanBusState::kErrorPassive);  // leaving bus-off needs a restart
    } else if ((ctrl & (CAN_ERR_CRTL_RX_WARNING | CAN_ERR_CRTL_TX_WARNING)) != 0) {
      if (!bus_off) enter(stats, CanBusState::kErrorWarning);
    } else if ((ctrl & CAN_ERR_CRTL_ACTIVE) != 0) {
      enter(stats, CanBusState::kErrorActive);
    }
  }
}

}  // namespace ptda::drivers
