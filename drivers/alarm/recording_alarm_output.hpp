// Fake AlarmOutput for tests and dry runs: records every verdict in a buffer allocated at configure().
#pragma once

#include <cstddef>
#include <span>
#include <vector>

#include "ptda/drivers/alarm_output.hpp"

namespace ptda::drivers {

class RecordingAlarmOutput final : public AlarmOutput {
 public:
  explicit RecordingAlarmOutput(std::size_t capacity = 4096) : capacity_(capacity) {}

  /// Allocates the record buffer. Never throws for a sane capacity.
  void configure() override;
  /// Shows kFault (the fail-safe state) until the first set().
  void activate() override;
  /// Shows kFault again.
  void deactivate() noexcept override;

  /// What the output currently shows (kFault when inactive). Thread: the alarm thread.
  [[nodiscard]] AlarmLevel shown() const noexcept { return shown_; }
  /// Verdicts passed to set() while active, oldest first (at most `capacity`). Thread: the alarm thread
  /// or any once it stopped.
  [[nodiscard]] std::span<const AlarmReport> reports() const noexcept { return {records_.data(), count_}; }
  /// Verdicts that did not fit. Thread: as reports().
  [[nodiscard]] std::size_t dropped() const noexcept { return dropped_; }
  /// Clears the recorded verdicts (not the counters). Thread: the alarm thread.
  void clear() noexcept { count_ = dropped_ = 0; }
  /// Makes the next write() calls fail (kError), to test how callers count failures.
  void fail_writes(bool fail) noexcept { fail_ = fail; }

 private:
  OutputStatus write(const AlarmReport& report) noexcept override;

  std::size_t capacity_;
  std::vector<AlarmReport> records_;
  std::size_t count_ = 0, dropped_ = 0;
  AlarmLevel shown_ = AlarmLevel::kFault;
  bool active_ = false;
  bool fail_ = false;
};

}  // namespace ptda::drivers
