// Vocabulary of the signal-processing core.
#pragma once

#include <cstdint>
#include <optional>
#include <string_view>

namespace ptda::dsp {

/// One joint speed measurement from the robot controller (decoded CAN frame).
struct SpeedSample {
  std::int64_t t_ns = 0;     ///< time on the vibration clock (latency offset already applied)
  double speed_rad_s = 0.0;  ///< joint (output shaft) angular speed, signed
  double angle_rad = 0.0;    ///< joint angle, valid when has_angle
  bool has_angle = false;
};

/// How the deterministic part of a window is estimated before taking the residual.
enum class Method : std::uint8_t {
  kRaw = 0,   ///< nothing removed: residual = window (the paper's "extracted raw signal")
  kTda = 1,   ///< eq. 5: time-domain mean of healthy windows subtracted
  kPtda = 2,  ///< eqs. 8-9/12-13: healthy mean magnitude with the window's own phase subtracted
};
inline constexpr std::size_t kMethodCount = 3;

[[nodiscard]] constexpr std::string_view method_name(Method m) noexcept {
  switch (m) {
    case Method::kRaw:
      return "raw";
    case Method::kTda:
      return "tda";
    case Method::kPtda:
      return "ptda";
  }
  return "?";
}
[[nodiscard]] inline std::optional<Method> parse_method(std::string_view s) noexcept {
  if (s == "raw") return Method::kRaw;
  if (s == "tda") return Method::kTda;
  if (s == "ptda") return Method::kPtda;
  return std::nullopt;
}

/// Health features of one window's residual.
struct Features {
  double rms_res = 0.0;      ///< eq. 14, in the recording's unit
  double entropy_res = 0.0;  ///< eqs. 15-16, normalised to [0, 1] (see features.hpp)
};

}  // namespace ptda::dsp
