// The monitoring configuration shared by `ptda train/monitor` and ptdad (TOML; see config/README.md).
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "ptda/config/speed_codec.hpp"
#include "ptda/dsp/baseline.hpp"
#include "ptda/dsp/monitor_engine.hpp"
#include "ptda/dsp/window_slicer.hpp"

namespace ptda::config {

struct PipelineConfig {
  double fs_hz = 0.0;                    ///< [acquisition] fs_hz: 0 = take the recording's rate
  SpeedFrameSpec speed_frame;            ///< [can.speed_frame]
  double speed_latency_s = 0.0;          ///< [can] speed_latency_s: subtracted from CAN timestamps
  dsp::ExtractionConfig extraction;      ///< [extraction]
  dsp::ClassLearningConfig classes;      ///< [classes]
  dsp::ThresholdPolicy thresholds;       ///< [thresholds]
  dsp::DecisionConfig decision;          ///< [decision]
  dsp::Method method = dsp::Method::kPtda;  ///< [monitor] method
  dsp::GearboxInfo gearbox;              ///< [gearbox]
};

/// Parses TOML text. Unknown keys and wrong types are errors. Throws ptda::Error
/// "<source>:<line>:<column>: <what>".
[[nodiscard]] PipelineConfig parse_pipeline_config(std::string_view toml_text, const std::string& source);
/// Reads the file, then (when given) each drop-in in order, later keys overriding earlier ones.
[[nodiscard]] PipelineConfig load_pipeline_config(const std::filesystem::path& path,
                                                  const std::vector<std::filesystem::path>& dropins = {});

}  // namespace ptda::config
