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
// The daemon re-sends the current verdict periodically; a receiver treats a missing frame (no frame
// within its timeout) or a frozen alive counter like level "fault".
#pragma once

#include <cstdint>

#include "ptda/common/can_frame.hpp"
#include "ptda/drivers/alarm_output.hpp"
#include "ptda/drivers/can_channel.hpp"

namespace ptda::drivers {

struct CanAlarmConfig {
  std::uint32_t id = 0x3A0;
  bool extended = false;
  double rms_lsb = 1e-3;      ///< rms_res per raw step (recording unit): 0..65.534 by default
  double entropy_lsb = 1e-4;  ///< entropy_res per raw step: [0, 1] -> 0..10000
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
  /// `channel` must outlive the output; its owner configures and activates it first.
  CanAlarmOutput(CanAlarmConfig config, CanChannel& channel);

  /// Validates the configuration. Throws ptda::Error.
  void configure() override;
  /// Sends a "fault" frame (the fail-safe state until the first verdict). Throws ptda::Error when the
  /// channel refuses it.
  void activate() override;
  /// Sends a final "fault" frame (cause internal); never throws.
  void deactivate() noexcept override;

  /// The status of the last send (kOk, kTxFull, kBusDown...). Thread: the alarm thread.
  [[nodiscard]] CanStatus last_send_status() const noexcept { return last_send_; }

 private:
  OutputStatus write(const AlarmReport& report) noexcept override;
  CanStatus send_frame(const AlarmReport& report) noexcept;

  CanAlarmConfig config_;
  CanChannel& channel_;
  std::uint8_t alive_ = 0;
  bool active_ = false;
  CanStatus last_send_ = CanStatus::kNotActive;
};

}  // namespace ptda::drivers
