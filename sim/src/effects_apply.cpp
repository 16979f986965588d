// The effects acting on the simulated signals (catalog: effects.cpp; documentation: docs/gap.md).
#include <algorithm>
#include <cmath>
#include <numbers>

#include "ptda/sim/effects.hpp"
#include "ptda/sim/random.hpp"
#include "ptda/sim/simulator.hpp"
#include "sim_internal.hpp"

namespace ptda::sim {
namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;

double sign_of(double v) {
  return v > 0.0 ? 1.0 : (v < 0.0 ? -1.0 : 0.0);
}

/// Unit-variance Gaussian noise low-passed by a one-pole filter with corner `corner_hz`
/// (y[n] = a y[n-1] + sqrt(1 - a^2) w[n], stationary from the first sample).
std::vector<double> lowpass_noise(std::size_t n, double fs_hz, double corner_hz, Rng& rng) {
  std::vector<double> y(n);
  const double a = std::exp(-kTwoPi * corner_hz / fs_hz);
  const double b = std::sqrt(1.0 - a * a);
  double state = rng.normal();
  for (std::size_t i = 0; i < n; ++i) {
    state = a * state + b * rng.normal();
    y[i] = state;
  }
  return y;
}

void add_impacts(const EffectSpec& e, const MotionProfile& m, Rng& rng, Vibration& v) {
  const double amp = e.get("amplitude_ms2");
  const double f_res = e.get("resonance_hz");
  const double zeta = e.get("damping_ratio");
  if (amp <= 0.0) return;
  // Torque reversals: every start of an acceleration piece whose sign differs from the last non-zero one
  // (start from rest, start of braking, reversal). Backlash closes there.
  double last_sign = 0.0;
  for (const MotionPiece& p : m.pieces) {
    const double sg = sign_of(p.accel_rad_s2);
    if (sg == 0.0) continue;
    if (sg != last_sign) {
      add_ringing(v.accel_ms2, m.fs_hz, p.t0_s, amp, f_res, zeta);
      ++v.effect_impacts;
    }
    last_sign = sg;
  }
  const double rate = e.get("rate_hz");
  if (rate > 0.0) {
    double t = 0.0;
    for (;;) {
      t += -std::log(1.0 - rng.uniform()) / rate;
      if (t >= m.duration_s) break;
      add_ringing(v.accel_ms2, m.fs_hz, t, amp, f_res, zeta);
      ++v.effect_impacts;
    }
  }
}

void add_other_axis(const EffectSpec& e, const Scenario& s, const MotionProfile& m, std::vector<double>& x) {
  const double amp = e.get("amplitude_ms2");
  if (amp <= 0.0) return;
  const double ratio = reduction_ratio(s.gearbox);
  const double freq_ratio = e.get("frequency_ratio");
  const auto lag = static_cast<std::ptrdiff_t>(std::llround(e.get("lag_s") * m.fs_hz));
  const double order = freq_ratio * static_cast<double>(s.gearbox.z_in) * ratio;  // mesh cycles per joint rad
  const VibrationSpec& vs = s.vibration;
  const double nyquist = m.fs_hz / 2.0;
  const auto n = static_cast<std::ptrdiff_t>(x.size());
  for (std::ptrdiff_t i = 0; i < n; ++i) {
    const std::ptrdiff_t j = i - lag;
    const double angle = j < 0 ? m.angle_rad.front() : m.angle_rad[static_cast<std::size_t>(j)];
    const double speed = j < 0 ? 0.0 : m.speed_rad_s[static_cast<std::size_t>(j)];
    if (speed == 0.0) continue;
    if (order * std::fabs(speed) / kTwoPi >= nyquist) continue;
    const double sf =
        vs.amplitude_speed_exponent == 0.0
            ? 1.0
            : std::pow(std::fabs(speed) / vs.reference_speed_rad_s, vs.amplitude_speed_exponent);
    x[static_cast<std::size_t>(i)] += amp * sf * std::sin(order * angle + 0.7);
  }
}

/// RBJ peaking biquad, gain 10^(gain_db/20) at frequency_hz.
void apply_transfer_path(const EffectSpec& e, double fs_hz, std::vector<double>& x) {
  const double f0 = std::min(e.get("frequency_hz"), 0.49 * fs_hz);
  const double a_lin = std::pow(10.0, e.get("gain_db") / 40.0);
  const double w0 = kTwoPi * f0 / fs_hz;
  const double alpha = std::sin(w0) / (2.0 * e.get("q"));
  const double a0 = 1.0 + alpha / a_lin;
  const double b0 = (1.0 + alpha * a_lin) / a0;
  const double b1 = -2.0 * std::cos(w0) / a0;
  const double b2 = (1.0 - alpha * a_lin) / a0;
  const double a1 = -2.0 * std::cos(w0) / a0;
  const double a2 = (1.0 - alpha / a_lin) / a0;
  double x1 = 0.0, x2 = 0.0, y1 = 0.0, y2 = 0.0;
  for (double& v : x) {
    const double y = b0 * v + b1 * x1 + b2 * x2 - a1 * y1 - a2 * y2;
    x2 = x1;
    x1 = v;
    y2 = y1;
    y1 = y;
    v = y;
  }
}

void add_electrical(const EffectSpec& e, double fs_hz, Rng& rng, std::vector<double>& x) {
  const double f0 = e.get("frequency_hz");
  const auto harmonics = static_cast<int>(std::lround(e.get("harmonics")));
  double amp = e.get("amplitude_ms2");
  const double decay = e.get("harmonic_decay");
  for (int h = 1; h <= harmonics; ++h, amp *= decay) {
    const double f = f0 * h;
    const double phase = kTwoPi * rng.uniform();
    if (f >= fs_hz / 2.0 || amp <= 0.0) continue;
    const double w = kTwoPi * f / fs_hz;
    for (std::size_t i = 0; i < x.size(); ++i) x[i] += amp * std::sin(w * static_cast<double>(i) + phase);
  }
}

}  // namespace

MeshPerturbation mesh_perturbation(const Scenario& s, const MotionProfile& m, std::uint64_t seed) {
  MeshPerturbation p;
  const std::size_t n = m.angle_rad.size();
  const double ratio = reduction_ratio(s.gearbox);
  const double z_in = s.gearbox.z_in;
  for (std::size_t k = 0; k < s.effects.size(); ++k) {
    const EffectSpec& e = s.effects[k];
    if (e.kind != EffectKind::kSpeedRipple && e.kind != EffectKind::kMeshModulation &&
        e.kind != EffectKind::kLoadDependence) {
      continue;
    }
    if (p.gain.empty()) {
      p.gain.assign(n, 1.0);
      p.theta_in_offset_rad.assign(n, 0.0);
    }
    if (e.kind == EffectKind::kSpeedRipple) {
      Rng rng(seed, kStreamEffectBase + k);
      const std::vector<double> j = lowpass_noise(n, m.fs_hz, e.get("bandwidth_hz"), rng);
      // jitter_rad is mesh phase of order 1 = z_in * input angle.
      const double scale = e.get("jitter_rad") / z_in;
      for (std::size_t i = 0; i < n; ++i) p.theta_in_offset_rad[i] += scale * j[i];
    } else if (e.kind == EffectKind::kMeshModulation) {
      const double rate = e.get("rate_order");
      const double am = e.get("am_depth");
      const double pm = e.get("pm_rad") / z_in;
      for (std::size_t i = 0; i < n; ++i) {
        const double theta_in = ratio * m.angle_rad[i];
        p.gain[i] *= 1.0 + am * std::cos(rate * theta_in);
        p.theta_in_offset_rad[i] += pm * std::sin(rate * theta_in);
      }
    } else {
      const double g_dir = e.get("direction_gain");
      const double g_acc = e.get("accel_gain");
      for (std::size_t i = 0; i < n; ++i) {
        const double sv = sign_of(m.speed_rad_s[i]);
        p.gain[i] *= (1.0 + g_dir * sv) * (1.0 + g_acc * sv * sign_of(m.accel_rad_s2[i]));
      }
    }
  }
  return p;
}

void apply_signal_effects(const Scenario& s, const MotionProfile& m, std::uint64_t seed, Vibration& v) {
  std::vector<double>& x = v.accel_ms2;
  // 1. Mechanical additions (they travel the transfer path).
  for (std::size_t k = 0; k < s.effects.size(); ++k) {
    const EffectSpec& e = s.effects[k];
    Rng rng(seed, kStreamEffectBase + k);
    if (e.kind == EffectKind::kImpacts) {
      add_impacts(e, m, rng, v);
    } else if (e.kind == EffectKind::kOtherAxis) {
      add_other_axis(e, s, m, x);
    } else if (e.kind == EffectKind::kNoiseColor) {
      const double rms = e.get("rms_ms2");
      if (rms <= 0.0) continue;
      const std::vector<double> c = lowpass_noise(x.size(), m.fs_hz, e.get("corner_hz"), rng);
      for (std::size_t i = 0; i < x.size(); ++i) x[i] += rms * c[i];
    }
  }
  // 2. Structural path to the sensor.
  for (const EffectSpec& e : s.effects) {
    if (e.kind == EffectKind::kTransferPath) apply_transfer_path(e, m.fs_hz, x);
  }
  // 3. Electrical pickup at the sensor/cable.
  for (std::size_t k = 0; k < s.effects.size(); ++k) {
    if (s.effects[k].kind != EffectKind::kElectricalInterference) continue;
    Rng rng(seed, kStreamEffectBase + k);
    add_electrical(s.effects[k], m.fs_hz, rng, x);
  }
  // 4. Acquisition saturates.
  for (const EffectSpec& e : s.effects) {
    if (e.kind != EffectKind::kAdcClipping) continue;
    const double level = e.get("level_ms2");
    for (double& val : x) {
      if (val > level || val < -level) {
        val = std::clamp(val, -level, level);
        ++v.effect_clipped_samples;
      }
    }
  }
}

void timing_scenarios(const Scenario& s, Scenario& for_motion, Scenario& for_can) {
  for_motion = s;
  for_can = s;
  for (const EffectSpec& e : s.effects) {
    if (e.kind == EffectKind::kSampleClockError) {
      for_motion.sensor.fs_hz *= 1.0 + e.get("ppm") * 1e-6;
    } else if (e.kind == EffectKind::kSpeedLatency) {
      for_can.can.delay_s += e.get("delay_s");
      // Frames of one sender never overtake each other: keep the total jitter below the period.
      for_can.can.jitter_s = std::min(for_can.can.jitter_s + e.get("jitter_s"), 0.999 * for_can.can.period_s);
    }
  }
}

}  // namespace ptda::sim
