// Alarm verdicts as a classic CAN frame (8 bytes) through a CanChannel. Layout (docs/drivers.md):
//   byte 0     bits 0-1 level (0 normal, 1 warning, 2 alarm, 3 fault); bits 2-3 zero;
//              bits 4-7 alive counter (+1 per frame, wraps 15 -> 0)
//   byte 1     cause bits (AlarmCause: 0 rms, 1 entropy, 2 sensor, 3 speed, 4 baseline, 5 internal,
//              6 coverage); level fault with no cause bit = "not judged yet"
//   byte 2     segment class of the last judged window (0xFF = none)
//   byte 3     abnormal windows among the debouncer's last n
//   bytes 4-5  rms_res, unsigned little-endian, raw = round(rms / rms_lsb), saturated at 0xFFFE;
//              0xFFFF = not available (NaN)
//   bytes 6-7  entropy_res, same coding with entropy_lsb
// The current verdict is re-sent periodically; a receiver treats a missing frame (no frame within its
// timeout) or a frozen alive counter like level "fault". Who times the re-sends: the daemon (one send
// per period), or, where the channel offers it (SocketCAN's broadcast manager), the kernel: the output
// hands it 16 frames of the verdict with alive counters 0..15, sent in turn every period, and renews a
// lease of `lease_ns` on each call; a daemon that stops renewing goes silent within the lease.
#pragma once

#include <array>
#include <cstdint>

#include "ptda/common/can_frame.hpp"
#include "ptda/drivers/alarm_output.hpp"
#include "ptda/drivers/can_channel.hpp"
#include "ptda/drivers/clock.hpp"

namespace ptda::drivers {

struct CanAlarmConfig {
  std::uint32_t id = 0x3A0;
  bool extended = false;
  double rms_lsb = 1e-3;      ///< rms_res per raw step (recording unit): 0..65.534 by default
  double entropy_lsb = 1e-4;  ///< entropy_res per raw step: [0, 1] -> 0..10000
  bool kernel_timer = false;  ///< let the channel's kernel timer re-send (when the channel has one)
  std::int64_t period_ns = 100'000'000;  ///< the kernel timer's period
  std::int64_t lease_ns = 500'000'000;   ///< the kernel stops this long after the last call (>= 2 periods)
};

inline constexpr std::uint16_t kAlarmValueUnavailable = 0xFFFF;

/// Throws ptda::Error when the id does not fit its format or an lsb is not positive. Thread: any.
void validate(const CanAlarmConfig& config);
/// Builds the frame (t_ns 0). Thread: any. Never allocates.
[[nodiscard]] CanFrame encode_alarm_frame(const AlarmReport& report, const CanAlarmConfig& config,
                                          std::uint8_t alive) noexcept;
/// Reads a frame back (values rounded to the lsb; unavailable -> NaN). False when the id, format or
/// length do not match. Thread: any. Never allocates.
[[nodiscard]] bool decode_alarm_frame(const CanFrame& frame, const CanAlarmConfig& config,
                                      AlarmReport& report, std::uint8_t& alive) noexcept;

class CanAlarmOutput final : public AlarmOutput {
 public:
  /// `channel` (and `clock`, needed for the kernel timer) must outlive the output; its owner configures
  /// and activates the channel first.
  CanAlarmOutput(CanAlarmConfig config, CanChannel& channel, const Clock* clock = nullptr);

  /// Validates the configuration. Throws ptda::Error.
  void configure() override;
  /// Chooses the timer (the kernel's when configured, given a clock and offered by the channel), then
  /// sends a "fault" frame (the fail-safe state until the first verdict). Throws ptda::Error when the
  /// channel refuses it.
  void activate() override;
  /// Sends a final "fault" frame (cause internal; with the kernel timer the last frame it sends); never
  /// throws.
  void deactivate() noexcept override;

  /// Whether the kernel re-sends the frame (known after activate()). Then set() must still be called at
  /// least every refresh_period_ns() to renew the lease. Thread: any after activate().
  [[nodiscard]] bool kernel_timed() const noexcept { return kernel_; }
  /// How often set() must come at the latest: the period (daemon timer) or half the lease (kernel
  /// timer). Thread: any after activate().
  [[nodiscard]] std::int64_t refresh_period_ns() const noexcept {
    return kernel_ ? config_.lease_ns / 2 : config_.period_ns;
  }

  /// The status of the last send (kOk, kTxFull, kBusDown...). Thread: the alarm thread.
  [[nodiscard]] CanStatus last_send_status() const noexcept { return last_send_; }

 private:
  OutputStatus write(const AlarmReport& report) noexcept override;
  CanStatus send_frame(const AlarmReport& report) noexcept;
  /// One set-up of the kernel's cyclic transmission for `report`. `final_frame`: one frame now, then
  /// stop.
  CanStatus set_cyclic(const AlarmReport& report, bool final_frame) noexcept;

  CanAlarmConfig config_;
  CanChannel& channel_;
  const Clock* clock_ = nullptr;
  bool kernel_ = false;
  std::uint32_t lease_frames_ = 0;
  std::int64_t last_setup_ns_ = 0;
  bool set_up_ = false;  ///< a set-up went through since activate()
  AlarmReport last_report_{};
  std::array<CanFrame, CanCyclicTx::kMaxFrames> cyclic_frames_{};
  std::uint8_t alive_ = 0;
  bool active_ = false;
  CanStatus last_send_ = CanStatus::kNotActive;
};

}  // namespace ptda::drivers
