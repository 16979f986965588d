// The libgpiod-independent part of GpiodOutput.
#include "alarm/gpiod_output.hpp"

#include <utility>

#include "ptda/common/error.hpp"

namespace ptda::drivers {

GpiodOutput::GpiodOutput(GpiodOutputConfig config) : config_(std::move(config)) {
  if (config_.trip_level == AlarmLevel::kNormal)
    throw Error(config_.chip, 0, 0,
                "trip_level must be warning, alarm or fault (normal would never be healthy)");
  if (config_.consumer.empty()) throw Error(config_.chip, 0, 0, "empty consumer name");
}

}  // namespace ptda::drivers
