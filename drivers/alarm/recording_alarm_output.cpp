#include "alarm/recording_alarm_output.hpp"

namespace ptda::drivers {

void RecordingAlarmOutput::configure() {
  records_.assign(capacity_, AlarmReport{});
  count_ = dropped_ = 0;
}

void RecordingAlarmOutput::activate() {
  active_ = true;
  shown_ = AlarmLevel::kFault;
}

void RecordingAlarmOutput::deactivate() noexcept {
  active_ = false;
  shown_ = AlarmLevel::kFault;
}

OutputStatus RecordingAlarmOutput::write(const AlarmReport& report) noexcept {
  if (!active_) return OutputStatus::kNotActive;
  if (fail_) return OutputStatus::kError;
  shown_ = report.level;
  if (count_ < records_.size()) {
    records_[count_++] = report;
  } else {
    ++dropped_;
  }
  return OutputStatus::kOk;
}

}  // namespace ptda::drivers
