// GPIO alarm line through libgpiod's C API (the v1 or v2 implementation file is chosen at build time
// from the libgpiod version pkg-config reports; the rest of the daemon does not know which).
//
// Fail-safe polarity: the line is logically ACTIVE ("energised", e.g. a relay held closed) only while
// the level is below trip_level, i.e. while the gearbox is judged healthy. Tripping, deactivate(), a
// crashed daemon (the kernel frees the request and the line is no longer driven) and a power loss all
// end in the inactive state, so wire the output such that inactive/undriven reads as "alarm".
// active_low inverts the physical level (for an active-low relay driver or an open-collector stage).
#pragma once

#include <memory>
#include <string>

#include "ptda/drivers/alarm_output.hpp"

namespace ptda::drivers {

struct GpiodOutputConfig {
  std::string chip = "/dev/gpiochip0";  ///< character device path
  unsigned int line = 0;                ///< line offset on the chip
  bool active_low = false;
  std::string consumer = "ptdad-alarm";        ///< shown by gpioinfo
  AlarmLevel trip_level = AlarmLevel::kAlarm;  ///< levels >= this de-energise the line
};

/// Logical value to drive for `level`: 1 (active, healthy) when level < trip_level, else 0.
[[nodiscard]] constexpr int gpio_logical_value(AlarmLevel level, AlarmLevel trip_level) noexcept {
  return static_cast<int>(level) < static_cast<int>(trip_level) ? 1 : 0;
}

class GpiodOutput final : public AlarmOutput {
 public:
  /// Throws ptda::Error when trip_level is kNormal (the line could never signal "healthy").
  explicit GpiodOutput(GpiodOutputConfig config);
  ~GpiodOutput() override;

  /// Opens the chip and checks the line exists and is free. Throws ptda::Error
  /// "<chip>: <what>" (e.g. no such device on a kernel without GPIO). Thread: main, start-up.
  void configure() override;
  /// Requests the line as an output, initially inactive (tripped). Throws ptda::Error.
  void activate() override;
  /// Drives the line inactive, then releases it. Never throws.
  void deactivate() noexcept override;

  /// "libgpiod v1" or "libgpiod v2": which implementation was built in.
  [[nodiscard]] static const char* api_name() noexcept;
  /// Logical value last driven (-1 when the line is not requested). Thread: the alarm thread.
  [[nodiscard]] int driven_value() const noexcept { return driven_; }

 private:
  OutputStatus write(const AlarmReport& report) noexcept override;

  struct Impl;  ///< libgpiod objects; defined by gpiod_output_v1.cpp or gpiod_output_v2.cpp
  struct ImplDeleter {
    void operator()(Impl* impl) const noexcept;
  };
  GpiodOutputConfig config_;
  std::unique_ptr<Impl, ImplDeleter> impl_;
  int driven_ = -1;
};

}  // namespace ptda::drivers
