// GpiodOutput against libgpiod 1.x (Debian 12: 1.6.3, GPIO character-device uAPI v1).
#include <gpiod.h>

#include <cerrno>
#include <cstring>
#include <string>

#include "alarm/gpiod_output.hpp"
#include "ptda/common/error.hpp"

namespace ptda::drivers {

struct GpiodOutput::Impl {
  gpiod_chip* chip = nullptr;
  gpiod_line* line = nullptr;  ///< owned by chip
  bool requested = false;
};

void GpiodOutput::ImplDeleter::operator()(Impl* impl) const noexcept {
  delete impl;
}

const char* GpiodOutput::api_name() noexcept {
  return "libgpiod v1";
}

GpiodOutput::~GpiodOutput() {
  deactivate();
  if (impl_ && impl_->chip != nullptr) gpiod_chip_close(impl_->chip);
}

void GpiodOutput::configure() {
  if (impl_ && impl_->chip != nullptr) {
    deactivate();
    gpiod_chip_close(impl_->chip);
  }
  impl_.reset(new Impl());
  impl_->chip = gpiod_chip_open(config_.chip.c_str());
  if (impl_->chip == nullptr)
    throw Error(config_.chip, 0, 0, std::string("gpiod_chip_open: ") + std::strerror(errno));
  const unsigned int n = gpiod_chip_num_lines(impl_->chip);
  if (config_.line >= n)
    throw Error(
        config_.chip, 0, 0,
        "line " + std::to_string(config_.line) + " out of range (chip has " + std::to_string(n) + ")");
  impl_->line = gpiod_chip_get_line(impl_->chip, config_.line);
  if (impl_->line == nullptr)
    throw Error(config_.chip, 0, 0, std::string("gpiod_chip_get_line: ") + std::strerror(errno));
  if (gpiod_line_is_used(impl_->line)) {
    const char* who = gpiod_line_consumer(impl_->line);
    throw Error(
        config_.chip, 0, 0,
        "line " + std::to_string(config_.line) + " is in use by '" + (who != nullptr ? who : "?") + "'");
  }
}

void GpiodOutput::activate() {
  if (!impl_ || impl_->line == nullptr) throw Error(config_.chip, 0, 0, "activate() before configure()");
  if (impl_->requested) return;
  const int flags = config_.active_low ? GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW : 0;
  if (gpiod_line_request_output_flags(impl_->line, config_.consumer.c_str(), flags, 0) != 0)
    throw Error(config_.chip, 0, 0,
                "request line " + std::to_string(config_.line) + " as output: " + std::strerror(errno));
  impl_->requested = true;
  driven_ = 0;
}

void GpiodOutput::deactivate() noexcept {
  if (!impl_ || !impl_->requested) return;
  (void)gpiod_line_set_value(impl_->line, 0);  // trip before letting go
  gpiod_line_release(impl_->line);
  impl_->requested = false;
  driven_ = -1;
}

OutputStatus GpiodOutput::write(const AlarmReport& report) noexcept {
  if (!impl_ || !impl_->requested) return OutputStatus::kNotActive;
  const int v = gpio_logical_value(report.level, config_.trip_level);
  // Written every time, not only on change: re-asserting costs one ioctl and repairs a line someone
  // else changed.
  if (gpiod_line_set_value(impl_->line, v) != 0) return OutputStatus::kError;
  driven_ = v;
  return OutputStatus::kOk;
}

}  // namespace ptda::drivers
