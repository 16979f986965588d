#include "alarm/can_alarm_output.hpp"

#include <algorithm>
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
  if (c.period_ns <= 0) throw Error("alarm frame", 0, 0, "period must be > 0");
  if (c.kernel_timer && c.lease_ns < 2 * c.period_ns)
    throw Error("alarm frame", 0, 0, "the kernel timer's lease must be at least two periods");
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

CanAlarmOutput::CanAlarmOutput(CanAlarmConfig config, CanChannel& channel, const Clock* clock)
    : config_(config), channel_(channel), clock_(clock) {}

void CanAlarmOutput::configure() {
  validate(config_);
}

CanStatus CanAlarmOutput::send_frame(const AlarmReport& report) noexcept {
  last_send_ = channel_.send(encode_alarm_frame(report, config_, alive_));
  alive_ = static_cast<std::uint8_t>((alive_ + 1) & 0x0F);
  return last_send_;
}

CanStatus CanAlarmOutput::set_cyclic(const AlarmReport& report, bool final_frame) noexcept {
  const std::int64_t now = clock_->now_ns();
  const bool same = report.level == last_report_.level && report.causes == last_report_.causes;
  if (!set_up_ || !same_report(report, last_report_)) {
    for (std::size_t i = 0; i < cyclic_frames_.size(); ++i)
      cyclic_frames_[i] = encode_alarm_frame(report, config_, static_cast<std::uint8_t>(i));
  }
  CanCyclicTx tx;
  tx.frames = cyclic_frames_;
  tx.period_ns = config_.period_ns;
  tx.count = final_frame ? 1 : lease_frames_;
  // The kernel sends at most lease_frames_ more frames after the last set-up, the last of them no
  // sooner than (lease_frames_ - 1) periods later: from then on the timer may have stopped (a stalled
  // caller), so it is started again. A new level or cause goes out at once, with the timer's phase kept.
  const bool expired =
      !set_up_ || now - last_setup_ns_ >= static_cast<std::int64_t>(lease_frames_ - 1) * config_.period_ns;
  tx.start = (expired || final_frame) ? CanCyclicTx::Start::kRestart
             : !same                  ? CanCyclicTx::Start::kAnnounce
                                      : CanCyclicTx::Start::kKeepTimer;
  last_send_ = channel_.set_cyclic(tx);
  if (last_send_ == CanStatus::kOk) {
    set_up_ = true;
    last_setup_ns_ = now;
    last_report_ = report;
  }
  return last_send_;
}

void CanAlarmOutput::activate() {
  AlarmReport fault;  // level kFault, no causes: "not judged yet"
  kernel_ = config_.kernel_timer && clock_ != nullptr && channel_.cyclic_supported();
  lease_frames_ = static_cast<std::uint32_t>(
      std::max<std::int64_t>(2, (config_.lease_ns + config_.period_ns - 1) / config_.period_ns));
  set_up_ = false;
  last_report_ = AlarmReport{};
  active_ = true;
  const CanStatus s = kernel_ ? set_cyclic(fault, false) : send_frame(fault);
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
  if (kernel_) {
    (void)set_cyclic(fault, true);
  } else {
    (void)send_frame(fault);
  }
  active_ = false;
}

OutputStatus CanAlarmOutput::write(const AlarmReport& report) noexcept {
  if (!active_) return OutputStatus::kNotActive;
  const CanStatus s = kernel_ ? set_cyclic(report, false) : send_frame(report);
  return s == CanStatus::kOk ? OutputStatus::kOk : OutputStatus::kError;
}

}  // namespace ptda::drivers
