// GpiodOutput against libgpiod 2.x (Debian 13 and later; GPIO uAPI v2). Written to the libgpiod 2.0
// API but NOT BUILT OR TESTED on Debian 12 (which ships 1.6.3); drivers/CMakeLists.txt selects it
// when pkg-config reports libgpiod >= 2.
#include <gpiod.h>

#include <cerrno>
#include <cstring>
#include <string>

#include "alarm/gpiod_output.hpp"
#include "ptda/common/error.hpp"

namespace ptda::drivers {

struct GpiodOutput::Impl {
  gpiod_chip* chip = nullptr;
  gpiod_line_request* request = nullptr;
};

void GpiodOutput::ImplDeleter::operator()(Impl* impl) const noexcept {
  delete impl;
}

const char* GpiodOutput::api_name() noexcept {
  return "libgpiod v2";
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
  gpiod_chip_info* info = gpiod_chip_get_info(impl_->chip);
  if (info == nullptr)
    throw Error(config_.chip, 0, 0, std::string("gpiod_chip_get_info: ") + std::strerror(errno));
  const std::size_t n = gpiod_chip_info_get_num_lines(info);
  gpiod_chip_info_free(info);
  if (config_.line >= n)
    throw Error(
        config_.chip, 0, 0,
        "line " + std::to_string(config_.line) + " out of range (chip has " + std::to_string(n) + ")");
  gpiod_line_info* li = gpiod_chip_get_line_info(impl_->chip, config_.line);
  if (li == nullptr)
    throw Error(config_.chip, 0, 0, std::string("gpiod_chip_get_line_info: ") + std::strerror(errno));
  const bool used = gpiod_line_info_is_used(li);
  const char* who = gpiod_line_info_get_consumer(li);
  const std::string consumer = who != nullptr ? who : "?";
  gpiod_line_info_free(li);
  if (used)
    throw Error(config_.chip, 0, 0,
                "line " + std::to_string(config_.line) + " is in use by '" + consumer + "'");
}

void GpiodOutput::activate() {
  if (!impl_ || impl_->chip == nullptr) throw Error(config_.chip, 0, 0, "activate() before configure()");
  if (impl_->request != nullptr) return;
  gpiod_line_settings* settings = gpiod_line_settings_new();
  gpiod_line_config* line_cfg = gpiod_line_config_new();
  gpiod_request_config* req_cfg = gpiod_request_config_new();
  std::string failure;
  if (settings == nullptr || line_cfg == nullptr || req_cfg == nullptr) {
    failure = "out of memory";
  } else {
    gpiod_line_settings_set_direction(settings, GPIOD_LINE_DIRECTION_OUTPUT);
    gpiod_line_settings_set_active_low(settings, config_.active_low);
    gpiod_line_settings_set_output_value(settings, GPIOD_LINE_VALUE_INACTIVE);
    const unsigned int offset = config_.line;
    if (gpiod_line_config_add_line_settings(line_cfg, &offset, 1, settings) != 0) {
      failure = std::string("gpiod_line_config_add_line_settings: ") + std::strerror(errno);
    } else {
      gpiod_request_config_set_consumer(req_cfg, config_.consumer.c_str());
      impl_->request = gpiod_chip_request_lines(impl_->chip, req_cfg, line_cfg);
      if (impl_->request == nullptr)
        failure = "request line " + std::to_string(config_.line) + " as output: " + std::strerror(errno);
    }
  }
  if (req_cfg != nullptr) gpiod_request_config_free(req_cfg);
  if (line_cfg != nullptr) gpiod_line_config_free(line_cfg);
  if (settings != nullptr) gpiod_line_settings_free(settings);
  if (!failure.empty()) throw Error(config_.chip, 0, 0, failure);
  driven_ = 0;
}

void GpiodOutput::deactivate() noexcept {
  if (!impl_ || impl_->request == nullptr) return;
  (void)gpiod_line_request_set_value(impl_->request, config_.line, GPIOD_LINE_VALUE_INACTIVE);  // trip first
  gpiod_line_request_release(impl_->request);
  impl_->request = nullptr;
  driven_ = -1;
}

OutputStatus GpiodOutput::write(const AlarmReport& report) noexcept {
  if (!impl_ || impl_->request == nullptr) return OutputStatus::kNotActive;
  const int v = gpio_logical_value(report.level, config_.trip_level);
  if (gpiod_line_request_set_value(impl_->request, config_.line,
                                   v != 0 ? GPIOD_LINE_VALUE_ACTIVE : GPIOD_LINE_VALUE_INACTIVE) != 0)
    return OutputStatus::kError;
  driven_ = v;
  return OutputStatus::kOk;
}

}  // namespace ptda::drivers
