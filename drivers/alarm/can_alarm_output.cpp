#include "alarm/can_alarm_output.hpp"

#include <cmath>
#include <limits>
#include <string>

#include "ptda/common/error.hpp"

namespace ptda::drivers {
namespace {

constexpr std::uint8_t kLevelMask = 0x03;

std::uint16_t encode_value(float v, double lsb) noexcept {
  if (std::isnan(v)) return kAlarmValueUnavailable;
  const double raw = std::round(static_cast<double>(v) / lsb);
  if (!(raw > 0.0)) return 0;  // negative (cannot happen for rms/entropy) -> 0
  if (raw >= 65534.0) return 0xFFFE;
  return static_cast<std::uint16_t>(raw);
}

float decode_value(std::uint16_t raw, double lsb) noexcept {
  if (raw == kAlarmValueUnavailable) return std::numeric_limits<float>::quiet_NaN();
  return static_cast<float>(raw * lsb);
}

}  // namespace

void validate(const CanAlarmConfig& c) {
  if (c.extended ? c.id > 0x1FFFFFFFU : c.id > 0x7FFU)
    throw Error(
        "alarm frame", 0, 0,
        "id " + std::to_string(c.id) + " does not fit a " + (c.extended ? "29" : "11") + "-bit identifier");
  if (!(c.rms_lsb > 0.0) || !std::isfinite(c.rms_lsb))
    throw Error("alarm frame", 0, 0, "rms_lsb must be > 0");
  if (!(c.entropy_lsb > 0.0) || !std::isfinite(c.entropy_lsb))
    throw Error("alarm frame", 0, 0, "entropy_lsb must be > 0");
}

CanFrame encode_alarm_frame(const AlarmReport& r, const CanAlarmConfig& c, std::uint8_t alive) noexcept {
  CanFrame f;
  f.id = c.id;
  f.flags = c.extended ? kCanExtended : 0;
  f.len = 8;
  f.data[0] =
      static_cast<std::uint8_t>((static_cast<std::uint8_t>(r.level) & kLevelMask) | ((alive & 0x0F) << 4));
  f.data[1] = r.causes;
  f.data[2] = r.segment_class;
  f.data[3] = r.abnormal_windows;
  const std::uint16_t rms = encode_value(r.rms, c.rms_lsb);
  const std::uint16_t ent = encode_value(r.entropy, c.entropy_lsb);
  f.data[4] = static_cast<std::uint8_t>(rms & 0xFF);
  f.data[5] = static_cast<std::uint8_t>(rms >> 8);
  f.data[6] = static_cast<std::uint8_t>(ent & 0xFF);
  f.data[7] = static_cast<std::uint8_t>(ent >> 8);
  return f;
}

bool decode_alarm_frame(const CanFrame& f, const CanAlarmConfig& c, AlarmReport& r,
                        std::uint8_t& alive) noexcept {
  if (f.error() || f.rtr() || f.fd() || f.extended() != c.extended || f.id != c.id || f.len != 8)
    return false;
  if ((f.data[0] & 0x0C) != 0) return false;  // reserved bits must be zero
  r.level = static_cast<AlarmLevel>(f.data[0] & kLevelMask);
  alive = static_cast<std::uint8_t>(f.data[0] >> 4);
  r.causes = f.data[1];
  r.segment_class = f.data[2];
  r.abnormal_windows = f.data[3];
  r.rms = decode_value(static_cast<std::uint16_t>(f.data[4] | (f.data[5] << 8)), c.rms_lsb);
  r.entropy = decode_value(static_cast<std::uint16_t>(f.data[6] | (f.data[7] << 8)), c.entropy_lsb);
  return true;
}

CanAlarmOutput::CanAlarmOutput(CanAlarmConfig config, CanChannel& channel)
    : config_(config), channel_(channel) {}

void CanAlarmOutput::configure() {
  validate(config_);
}

CanStatus CanAlarmOutput::send_frame(const AlarmReport& report) noexcept {
  last_send_ = channel_.send(encode_alarm_frame(report, config_, alive_));
  alive_ = static_cast<std::uint8_t>((alive_ + 1) & 0x0F);
  return last_send_;
}

void CanAlarmOutput::activate() {
  AlarmReport fault;  // level kFault, no causes: "not judged yet"
  active_ = true;
  const CanStatus s = send_frame(fault);
  if (s != CanStatus::kOk && s != CanStatus::kTxFull) {
    active_ = false;
    throw Error(
        "alarm frame", 0, 0,
        "the CAN channel refused the first frame (status " + std::to_string(static_cast<int>(s)) + ")");
  }
}

void CanAlarmOutput::deactivate() noexcept {
  if (!active_) return;
  AlarmReport fault;
  fault.causes = kCauseInternal;
  (void)send_frame(fault);
  active_ = false;
}

OutputStatus CanAlarmOutput::write(const AlarmReport& report) noexcept {
  if (!active_) return OutputStatus::kNotActive;
  return send_frame(report) == CanStatus::kOk ? OutputStatus::kOk : OutputStatus::kError;
}

}  // namespace ptda::drivers
