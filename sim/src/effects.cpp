// The effects catalog: names, parameters, defaults and ranges (docs/gap.md explains each effect).
#include "ptda/sim/effects.hpp"

#include <array>
#include <cmath>
#include <cstdio>

#include "ptda/common/error.hpp"

namespace ptda::sim {
namespace {

/// electrical_interference: the parameters of its mains (one-source) form come first.
constexpr std::size_t kElectricalMainsParams = 5;
/// impacts: the parameters of its one-mode form come first.
constexpr std::size_t kImpactsOneModeParams = 4;

constexpr std::array<EffectParamInfo, 3> kTransferPath{{
    {"frequency_hz", 3000.0, 20.0, 100000.0, "resonance centre frequency (below fs/2)"},
    {"gain_db", 12.0, 0.0, 40.0, "peak gain at the centre"},
    {"q", 5.0, 0.5, 50.0, "quality factor (bandwidth = frequency / q)"},
}};
constexpr std::array<EffectParamInfo, 2> kSpeedRipple{{
    {"jitter_rad", 0.3, 0.0, 3.0, "rms mesh-phase jitter of GMF order 1 (order k: k times)"},
    {"bandwidth_hz", 20.0, 0.5, 500.0, "bandwidth of the jitter (one-pole low-pass)"},
}};
constexpr std::array<EffectParamInfo, 3> kMeshModulation{{
    {"rate_order", 1.0, 0.1, 10.0, "modulation cycles per input-shaft revolution"},
    {"am_depth", 0.3, 0.0, 1.0, "amplitude modulation depth"},
    {"pm_rad", 0.0, 0.0, 2.0, "phase modulation of GMF order 1 (order k: k times)"},
}};
constexpr std::array<EffectParamInfo, 7> kImpacts{{
    {"amplitude_ms2", 5.0, 0.0, 500.0, "ringing amplitude of each knock"},
    {"resonance_hz", 4000.0, 20.0, 100000.0, "resonance the knocks excite (below fs/2)"},
    {"damping_ratio", 0.05, 0.005, 0.5, "damping of that resonance"},
    {"rate_hz", 0.0, 0.0, 100.0, "extra random knocks per second (Poisson), besides the reversals"},
    // A knock rings more than one structural mode (issue 11): one higher mode, same damping ratio. Off
    // while mode2_ratio = 0, so the one-mode form is unchanged.
    {"mode2_ratio", 0.0, 0.0, 6.0, "a second, higher mode at this multiple of resonance_hz (0: one mode)"},
    {"mode2_share", 0.4, 0.0, 2.0, "amplitude of the second mode / the first's"},
    {"knock_events", 0.0, 0.0, 2.0,
     "where the motion knocks: 0 torque reversals; 1 every start from rest and every stop; 2 both (rounded)"},
}};
constexpr std::array<EffectParamInfo, 9> kElectrical{{
    {"frequency_hz", 50.0, 1.0, 100000.0, "fundamental (mains, drive switching)"},
    {"amplitude_ms2", 0.3, 0.0, 100.0, "amplitude of the fundamental"},
    {"harmonics", 3.0, 1.0, 50.0, "number of harmonics including the fundamental (rounded)"},
    {"harmonic_decay", 0.5, 0.0, 1.0, "amplitude ratio between successive harmonics"},
    {"odd_only", 0.0, 0.0, 1.0,
     "1: only odd harmonics (1, 3, 5, ...: mains pickup through a symmetric non-linearity); 0: all "
     "(rounded)"},
    // The second form (issue 11): a servo drive's switching carrier beside the mains lines, one source of
    // pickup with two parts. Off while pwm_ms2 = 0, so the one-line form is unchanged.
    {"pwm_hz", 0.0, 0.0, 100000.0, "drive switching carrier (0: none)"},
    {"pwm_ms2", 0.0, 0.0, 100.0, "amplitude of the carrier (0: the mains form alone)"},
    {"pwm_side_hz", 0.0, 0.0, 5000.0, "sidebands at pwm_hz +- this (0: none)"},
    {"pwm_side_rel", 0.5, 0.0, 2.0, "amplitude of each sideband / the carrier's"},
}};
constexpr std::array<EffectParamInfo, 2> kAdcClipping{{
    {"level_ms2", 5.0, 0.001, 1.0e5, "the acquisition saturates at +-level"},
    // The second form (issue 11): a model whose amplitude tail is lighter than the machine's (a Gaussian
    // floor against a rig's impulses) almost never reaches the machine's rails. The gap diagnosis then
    // clamps the model where it puts the same share of samples at its rails as the machine does.
    {"sim_level_ms2", 0.0, 0.0, 1.0e5,
     "level the simulation clamps at, where it differs from the machine's level_ms2 (0: level_ms2)"},
}};
constexpr std::array<EffectParamInfo, 1> kSampleClock{{
    {"ppm", 500.0, -20000.0, 20000.0, "real ADC rate = nominal * (1 + ppm 1e-6)"},
}};
constexpr std::array<EffectParamInfo, 2> kSpeedLatency{{
    {"delay_s", 0.02, 0.0, 0.5, "extra delay of the CAN speed frames"},
    {"jitter_s", 0.0, 0.0, 0.1, "extra uniform jitter (jitter + [can] jitter_s must stay below period_s)"},
}};
constexpr std::array<EffectParamInfo, 6> kOtherAxis{{
    {"amplitude_ms2", 0.5, 0.0, 100.0, "mesh amplitude of the other joint at this joint's reference speed"},
    {"frequency_ratio", 1.37, 0.05, 20.0, "its mesh frequency / this GMF at the same joint speed"},
    {"lag_s", 0.1, 0.0, 10.0, "its motion is this joint's motion delayed by lag_s"},
    {"own_frequency_hz", 0.0, 0.0, 1.0e5,
     "0: it follows this joint (ratio, lag); > 0: it runs its own program, its mesh line at this frequency "
     "while it moves (frequency_ratio and lag_s unused)"},
    {"duty", 1.0, 0.02, 1.0, "own program: share of the time it moves (on/off in 2.5 s periods)"},
    {"harmonic2", 0.0, 0.0, 2.0, "own program: level of its mesh's 2nd harmonic / the 1st"},
}};
constexpr std::array<EffectParamInfo, 2> kLoadDependence{{
    {"direction_gain", 0.3, -0.95, 0.95, "mesh amplitude * (1 + g sign(speed))"},
    {"accel_gain", 0.0, -0.95, 0.95, "mesh amplitude * (1 + a sign(speed accel)) while accelerating/braking"},
}};
constexpr std::array<EffectParamInfo, 3> kNoiseColor{{
    {"rms_ms2", 0.3, 0.0, 100.0, "rms of the extra noise"},
    {"corner_hz", 200.0, 1.0, 100000.0, "corner of its low-pass (red above the corner)"},
    {"poles", 1.0, 1.0, 2.0,
     "1: one pole (-20 dB/decade above the corner); 2: a double pole (-40) (rounded)"},
}};

constexpr std::array<EffectInfo, kEffectKinds> kCatalog{{
    {EffectKind::kTransferPath, "transfer_path", kTransferPath,
     "peaking resonance applied to the mechanical signal (mesh, noise, knocks) on its way to the sensor"},
    {EffectKind::kSpeedRipple, "speed_ripple", kSpeedRipple,
     "band-limited random jitter of the input-shaft angle seen by the mesh, not by the CAN speed"},
    {EffectKind::kMeshModulation, "mesh_modulation", kMeshModulation,
     "mesh amplitude and phase modulated at rate_order x the input-shaft rotation"},
    {EffectKind::kImpacts, "impacts", kImpacts,
     "knocks at every torque reversal of the motion (and random ones) ringing a resonance"},
    {EffectKind::kElectricalInterference, "electrical_interference", kElectrical,
     "fixed-frequency pickup (fundamental + decaying harmonics), added at the sensor"},
    {EffectKind::kAdcClipping, "adc_clipping", kAdcClipping, "the signal is clamped to +-level_ms2"},
    {EffectKind::kSampleClockError, "sample_clock_error", kSampleClock,
     "the ADC samples at nominal * (1 + ppm 1e-6) while the WAV header says nominal"},
    {EffectKind::kSpeedLatency, "speed_latency", kSpeedLatency,
     "the CAN speed frames are logged later (and with more jitter) than the simulator's [can] says"},
    {EffectKind::kOtherAxis, "other_axis", kOtherAxis,
     "another joint's mesh, driven by this joint's motion delayed by lag_s, or on its own program"},
    {EffectKind::kLoadDependence, "load_dependence", kLoadDependence,
     "mesh amplitude depends on the direction of motion and on accelerating vs braking"},
    {EffectKind::kNoiseColor, "noise_color", kNoiseColor, "extra red (low-pass) Gaussian background noise"},
}};

std::size_t param_index(const EffectInfo& info, std::string_view name) {
  for (std::size_t i = 0; i < info.params.size(); ++i) {
    if (name == info.params[i].name) return i;
  }
  throw Error(std::string("effect '") + info.name + "' has no parameter '" + std::string(name) + "'");
}

}  // namespace

std::span<const EffectInfo> effect_catalog() noexcept {
  return kCatalog;
}

const EffectInfo& effect_info(EffectKind kind) noexcept {
  return kCatalog[static_cast<std::size_t>(kind)];
}

std::optional<EffectKind> effect_kind_from_name(std::string_view name) noexcept {
  for (const EffectInfo& e : kCatalog) {
    if (name == e.name) return e.kind;
  }
  return std::nullopt;
}

EffectSpec EffectSpec::with_defaults(EffectKind kind) {
  EffectSpec e;
  e.kind = kind;
  for (const EffectParamInfo& p : effect_info(kind).params) e.params.push_back(p.default_value);
  return e;
}

double EffectSpec::get(std::string_view name) const {
  const std::size_t i = param_index(effect_info(kind), name);
  if (i >= params.size())
    throw Error(std::string("effect '") + effect_info(kind).name + "': parameters missing");
  return params[i];
}

void EffectSpec::set(std::string_view name, double value) {
  const std::size_t i = param_index(effect_info(kind), name);
  if (params.size() < effect_info(kind).params.size()) *this = with_defaults(kind);
  params[i] = value;
}

std::size_t shown_param_count(const EffectSpec& e) {
  const std::size_t n = effect_info(e.kind).params.size();
  // The interference's drive-carrier parameters only when that form is on, the knocks' second mode only
  // when it rings: the one-part forms read as they always did.
  if (e.kind == EffectKind::kElectricalInterference && e.params.size() == n && e.get("pwm_ms2") <= 0.0)
    return kElectricalMainsParams;
  if (e.kind == EffectKind::kImpacts && e.params.size() == n && e.get("mode2_ratio") <= 0.0 &&
      std::lround(e.get("knock_events")) == 0)
    return kImpactsOneModeParams;
  return n;
}

std::string describe(const EffectSpec& e) {
  const EffectInfo& info = effect_info(e.kind);
  std::string s = std::string(info.name) + "(";
  const std::size_t n = shown_param_count(e);
  for (std::size_t i = 0; i < n && i < e.params.size(); ++i) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%s%s=%.4g", i == 0 ? "" : ", ", info.params[i].name, e.params[i]);
    s += buf;
  }
  return s + ")";
}

}  // namespace ptda::sim
