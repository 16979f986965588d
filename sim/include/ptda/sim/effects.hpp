// Sim-to-real effects: additions to the simulator, each with a few parameters, switched on in a scenario
// with `[[effects]] kind = "..."` tables (docs/gap.md lists them with their signatures). The gap diagnosis
// (gap/) fits them to measured recordings. Every parameter has a documented default and range; a
// parameter is a plain double (integer-valued ones are rounded where used).
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace ptda::sim {

enum class EffectKind : std::uint8_t {
  kTransferPath,            ///< structural/mount resonance between mesh and sensor (peaking filter)
  kSpeedRipple,             ///< random mesh-phase jitter the controller's speed does not show
  kMeshModulation,          ///< AM/PM of the mesh at a shaft order -> sidebands
  kImpacts,                 ///< knocks at torque reversals (and random knocks) ringing a resonance
  kElectricalInterference,  ///< pickup at a fixed frequency and its harmonics
  kAdcClipping,             ///< the acquisition saturates below the sensor range
  kSampleClockError,        ///< the ADC's real rate differs from its nominal rate
  kSpeedLatency,            ///< extra delay and jitter of the CAN speed against the vibration
  kOtherAxis,               ///< another joint's gear mesh with its own (lagged) motion
  kLoadDependence,          ///< mesh amplitude depends on direction and on accelerating/braking
  kNoiseColor,              ///< extra low-pass (red) background noise
};

inline constexpr std::size_t kEffectKinds = 11;

/// One parameter of an effect kind.
struct EffectParamInfo {
  const char* name;
  double default_value;
  double min_value;  ///< valid range (scenario parser and fitting)
  double max_value;
  const char* doc;
};

struct EffectInfo {
  EffectKind kind;
  const char* name;  ///< scenario spelling, e.g. "transfer_path"
  std::span<const EffectParamInfo> params;
  const char* doc;
};

/// All effect kinds in EffectKind order. Any thread; no allocation.
[[nodiscard]] std::span<const EffectInfo> effect_catalog() noexcept;
[[nodiscard]] const EffectInfo& effect_info(EffectKind kind) noexcept;
/// Kind from its scenario name; nullopt when unknown. Any thread; no allocation.
[[nodiscard]] std::optional<EffectKind> effect_kind_from_name(std::string_view name) noexcept;

/// An effect switched on: its kind and one value per catalog parameter (catalog order).
struct EffectSpec {
  EffectKind kind = EffectKind::kTransferPath;
  std::vector<double> params;

  /// Spec with every parameter at its default. Any thread; allocates.
  [[nodiscard]] static EffectSpec with_defaults(EffectKind kind);
  /// Value of parameter `name`; throws ptda::Error naming the kind when there is no such parameter.
  [[nodiscard]] double get(std::string_view name) const;
  /// Sets parameter `name` (no range check); throws ptda::Error for an unknown name.
  void set(std::string_view name, double value);
};

/// "kind(p1=v1, p2=v2)" for messages and reports. Any thread; allocates.
[[nodiscard]] std::string describe(const EffectSpec& e);

/// How many of `e`'s parameters (in catalog order) describe it: all, except for an
/// `electrical_interference` without its drive carrier (pwm_ms2 = 0), whose drive-form keys are left out
/// so that its description and a simulation's truth.toml read as before that form existed. Any thread.
[[nodiscard]] std::size_t shown_param_count(const EffectSpec& e);

}  // namespace ptda::sim
