// The effects acting on the simulated signals (catalog: effects.cpp; documentation: docs/gap.md).
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>

#include "ptda/sim/effects.hpp"
#include "ptda/sim/random.hpp"
#include "ptda/sim/simulator.hpp"
#include "ptda/sim/stream.hpp"
#include "sim_internal.hpp"

namespace ptda::sim {
namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;
constexpr double kRestShare = 0.1;  // knock_events: at rest below this share of the fastest speed so far

double sign_of(double v) {
  return v > 0.0 ? 1.0 : (v < 0.0 ? -1.0 : 0.0);
}

/// One-pole low-passed unit-variance Gaussian noise with corner `corner_hz`
/// (y[n] = a y[n-1] + sqrt(1 - a^2) w[n], stationary from the first sample), sample by sample.
struct LowpassNoise {
  double a = 0.0;
  double b = 0.0;
  double state = 0.0;
  LowpassNoise() = default;
  LowpassNoise(double fs_hz, double corner_hz, Rng& rng)
      : a(std::exp(-kTwoPi * corner_hz / fs_hz)), b(std::sqrt(1.0 - a * a)), state(rng.normal()) {}
  double next(Rng& rng) noexcept {
    state = a * state + b * rng.normal();
    return state;
  }
};

/// The same noise through a second pole at the same corner: (1 - a z^-1)^-2 on white noise, scaled to
/// unit variance (the double pole's power gain is (1 + a^2) / (1 - a^2)^3; the first stage gives
/// (1 - a^2) of it, the second stage's gain c = (1 - a^2) / sqrt(1 + a^2) the rest).
struct DoublePoleNoise {
  LowpassNoise first;
  double c = 0.0;
  double state = 0.0;
  DoublePoleNoise() = default;
  DoublePoleNoise(double fs_hz, double corner_hz, Rng& rng) : first(fs_hz, corner_hz, rng) {
    c = (1.0 - first.a * first.a) / std::sqrt(1.0 + first.a * first.a);
    state = rng.normal();  // stationary variance; the correlation settles within a few 1 / corner
  }
  double next(Rng& rng) noexcept {
    state = first.a * state + c * first.next(rng);
    return state;
  }
};

}  // namespace

MeshPerturber::MeshPerturber(const Scenario& s, double fs_hz, std::uint64_t seed)
    : ratio_(reduction_ratio(s.gearbox)) {
  const double z_in = s.gearbox.z_in;
  for (std::size_t k = 0; k < s.effects.size(); ++k) {
    const EffectSpec& e = s.effects[k];
    if (e.kind != EffectKind::kSpeedRipple && e.kind != EffectKind::kMeshModulation &&
        e.kind != EffectKind::kLoadDependence) {
      continue;
    }
    Part p{e.kind, Rng(seed, kStreamEffectBase + k)};
    if (e.kind == EffectKind::kSpeedRipple) {
      const LowpassNoise lp(fs_hz, e.get("bandwidth_hz"), p.rng);
      p.a = lp.a;
      p.b = lp.b;
      p.state = lp.state;
      // jitter_rad is mesh phase of order 1 = z_in * input angle.
      p.scale = e.get("jitter_rad") / z_in;
    } else if (e.kind == EffectKind::kMeshModulation) {
      p.rate = e.get("rate_order");
      p.am = e.get("am_depth");
      p.pm = e.get("pm_rad") / z_in;
    } else {
      p.g_dir = e.get("direction_gain");
      p.g_acc = e.get("accel_gain");
    }
    parts_.push_back(p);
  }
}

void MeshPerturber::next(const MotionState& st, double& theta_in_offset_rad, double& gain) noexcept {
  double offset = 0.0;
  double g = 1.0;
  for (Part& p : parts_) {
    if (p.kind == EffectKind::kSpeedRipple) {
      p.state = p.a * p.state + p.b * p.rng.normal();
      offset += p.scale * p.state;
    } else if (p.kind == EffectKind::kMeshModulation) {
      const double theta_in = ratio_ * st.angle_rad;
      g *= 1.0 + p.am * std::cos(p.rate * theta_in);
      offset += p.pm * std::sin(p.rate * theta_in);
    } else {
      const double sv = sign_of(st.speed_rad_s);
      g *= (1.0 + p.g_dir * sv) * (1.0 + p.g_acc * sv * sign_of(st.accel_rad_s2));
    }
  }
  theta_in_offset_rad = offset;
  gain = g;
}

/// One [[effects]] entry's state, in scenario order.
struct SignalEffects::Step {
  Step(EffectKind k, const Rng& r) : kind(k), rng(r) {}
  EffectKind kind;
  Rng rng;
  bool active = false;
  // impacts: knocks at torque reversals (pieces in order), then random (Poisson) knocks
  double amp = 0.0, f_res = 0.0, zeta = 0.0, rate = 0.0;
  double mode2_ratio = 0.0, mode2_share = 0.0;  // impacts: the second mode (0: one mode)
  int knock_events = 0;                         // 0 torque reversals, 1 starts from rest and stops, 2 both
  double prev_sign = 0.0;                       // the last piece's acceleration sign (0 included)
  bool prev_rest = true;                        // the last piece was at rest
  double top_speed = 0.0;                       // the fastest |speed| of the pieces walked
  std::optional<PieceCursor> rev;               // the next piece to look at for a reversal
  bool rev_done = false;
  double last_sign = 0.0;
  bool random_pending = false;
  double t_random = 0.0;
  RingingSet reversals;
  RingingSet random;
  // other_axis: this joint's motion delayed by lag samples
  std::ptrdiff_t lag = 0;
  double order = 0.0;
  std::optional<MotionSampler> lagged;
  // other_axis on its own program: its line (rad per sample), the on share of each gate period, where
  // in the period the signal starts (samples), the period and its raised-cosine edges (samples)
  double own_w = 0.0, own_phase = 0.0, duty = 1.0, gate_offset = 0.0, gate_period = 0.0, gate_edge = 0.0;
  double harmonic2 = 0.0;
  // noise_color
  LowpassNoise lp;
  DoublePoleNoise lp2;
  bool two_poles = false;
  // transfer_path: RBJ peaking biquad and its state
  double b0 = 0.0, b1 = 0.0, b2 = 0.0, a1 = 0.0, a2 = 0.0;
  double x1 = 0.0, x2 = 0.0, y1 = 0.0, y2 = 0.0;
  // electrical_interference: the harmonics that are synthesised
  struct Tone {
    double amp, w, phase;
  };
  std::vector<Tone> tones;
  // adc_clipping
  double level = 0.0;
};

SignalEffects::SignalEffects(const Scenario& s, const MotionProfile& m, std::uint64_t seed)
    : s_(&s), m_(&m), n_total_(motion_samples(m)) {
  const double fs = m.fs_hz;
  for (std::size_t k = 0; k < s.effects.size(); ++k) {
    const EffectSpec& e = s.effects[k];
    Step st{e.kind, Rng(seed, kStreamEffectBase + k)};
    switch (e.kind) {
      case EffectKind::kImpacts:
        st.amp = e.get("amplitude_ms2");
        st.f_res = e.get("resonance_hz");
        st.zeta = e.get("damping_ratio");
        st.rate = e.get("rate_hz");
        st.mode2_ratio = e.get("mode2_ratio");
        st.mode2_share = e.get("mode2_share");
        st.knock_events = static_cast<int>(std::lround(e.get("knock_events")));
        st.active = st.amp > 0.0;
        if (st.active) st.rev.emplace(m);
        if (st.active && st.rate > 0.0) {
          st.t_random = 0.0;
          st.t_random += -std::log(1.0 - st.rng.uniform()) / st.rate;
          st.random_pending = st.t_random < m.duration_s;
        }
        break;
      case EffectKind::kOtherAxis: {
        const double amp = e.get("amplitude_ms2");
        st.active = amp > 0.0;
        st.amp = amp;
        const double ratio = reduction_ratio(s.gearbox);
        st.lag = static_cast<std::ptrdiff_t>(std::llround(e.get("lag_s") * fs));
        st.order = e.get("frequency_ratio") * static_cast<double>(s.gearbox.z_in) * ratio;  // per joint rad
        const double own_hz = e.get("own_frequency_hz");
        if (own_hz > 0.0) {
          // Its own program: moving a `duty` share of every 2.5 s (a move and a rest of another joint), at
          // one speed, from a random point of the period; the line's level is its mesh amplitude.
          st.own_w = kTwoPi * own_hz / fs;
          st.own_phase = kTwoPi * st.rng.uniform();
          st.duty = std::clamp(e.get("duty"), 0.0, 1.0);
          st.harmonic2 = 2.0 * own_hz < 0.5 * fs ? e.get("harmonic2") : 0.0;
          st.gate_period = 2.5 * fs;
          st.gate_edge = std::min(0.1 * fs, 0.5 * st.duty * st.gate_period);
          st.gate_offset = st.rng.uniform() * st.gate_period;
          st.active = amp > 0.0 && own_hz < 0.5 * fs;
        } else {
          st.lagged.emplace(m);
        }
        break;
      }
      case EffectKind::kNoiseColor:
        st.amp = e.get("rms_ms2");
        st.active = st.amp > 0.0;
        st.two_poles = std::lround(e.get("poles")) >= 2;
        if (st.active && st.two_poles) st.lp2 = DoublePoleNoise(fs, e.get("corner_hz"), st.rng);
        if (st.active && !st.two_poles) st.lp = LowpassNoise(fs, e.get("corner_hz"), st.rng);
        break;
      case EffectKind::kTransferPath: {
        st.active = true;
        const double f0 = std::min(e.get("frequency_hz"), 0.49 * fs);
        const double a_lin = std::pow(10.0, e.get("gain_db") / 40.0);
        const double w0 = kTwoPi * f0 / fs;
        const double alpha = std::sin(w0) / (2.0 * e.get("q"));
        const double a0 = 1.0 + alpha / a_lin;
        st.b0 = (1.0 + alpha * a_lin) / a0;
        st.b1 = -2.0 * std::cos(w0) / a0;
        st.b2 = (1.0 - alpha * a_lin) / a0;
        st.a1 = -2.0 * std::cos(w0) / a0;
        st.a2 = (1.0 - alpha / a_lin) / a0;
        break;
      }
      case EffectKind::kElectricalInterference: {
        st.active = true;
        const double f0 = e.get("frequency_hz");
        const auto harmonics = static_cast<int>(std::lround(e.get("harmonics")));
        double amp = e.get("amplitude_ms2");
        const double decay = e.get("harmonic_decay");
        // `harmonics` lines, line j at harmonic j (all) or 2j - 1 (odd only), each `decay` below the last.
        const int step = std::lround(e.get("odd_only")) != 0 ? 2 : 1;
        for (int line = 1; line <= harmonics; ++line, amp *= decay) {
          const double f = f0 * (1 + step * (line - 1));
          const double phase = kTwoPi * st.rng.uniform();
          if (f >= fs / 2.0 || amp <= 0.0) continue;
          st.tones.push_back({amp, kTwoPi * f / fs, phase});
        }
        // The drive's carrier and its two sidebands (phases drawn after the mains lines', so a scenario
        // without the carrier simulates as before).
        const double pwm_amp = e.get("pwm_ms2"), pwm_hz = e.get("pwm_hz");
        if (pwm_amp > 0.0 && pwm_hz > 0.0) {
          const double side = e.get("pwm_side_hz"), side_amp = pwm_amp * e.get("pwm_side_rel");
          const double lines[3][2] = {
              {pwm_hz, pwm_amp}, {pwm_hz - side, side_amp}, {pwm_hz + side, side_amp}};
          for (std::size_t j = 0; j < (side > 0.0 ? 3U : 1U); ++j) {
            const double phase = kTwoPi * st.rng.uniform();
            if (lines[j][0] <= 0.0 || lines[j][0] >= fs / 2.0 || lines[j][1] <= 0.0) continue;
            st.tones.push_back({lines[j][1], kTwoPi * lines[j][0] / fs, phase});
          }
        }
        break;
      }
      case EffectKind::kAdcClipping:
        st.active = true;
        st.level = e.get("sim_level_ms2") > 0.0 ? e.get("sim_level_ms2") : e.get("level_ms2");
        break;
      default:
        break;  // timing and mesh effects act elsewhere
    }
    steps_.push_back(std::move(st));
  }
}

SignalEffects::~SignalEffects() = default;

void SignalEffects::schedule(std::size_t i_end) {
  const double fs = m_->fs_hz;
  const auto start_of = [fs](double t) { return static_cast<std::size_t>(std::ceil(t * fs)); };
  for (Step& st : steps_) {
    if (st.kind != EffectKind::kImpacts || !st.active) continue;
    // Torque reversals: every start of an acceleration piece whose sign differs from the last non-zero
    // one (start from rest, start of braking, reversal). Backlash closes there.
    while (!st.rev_done) {
      const MotionPiece p = st.rev->current();
      const double sg = sign_of(p.accel_rad_s2);
      const bool reversal = sg != 0.0 && sg != st.last_sign;
      // A start (acceleration after a constant-speed piece at rest) or a stop (a constant-speed piece at rest
      // after acceleration). "At rest": below kRestShare of the fastest speed so far. A measured trace's
      // first accelerating piece may already move a little (one CAN period of acceleration), so the start
      // is judged by the piece before it.
      st.top_speed = std::max(st.top_speed, std::fabs(p.speed0_rad_s));
      const double rest_rad_s = std::max(kRestShare * st.top_speed, 1e-3);
      const bool start = sg != 0.0 && st.prev_sign == 0.0 && st.prev_rest;
      const bool stop = sg == 0.0 && st.prev_sign != 0.0 && std::fabs(p.speed0_rad_s) < rest_rad_s;
      const bool start_stop = start || stop;
      const bool knock = (st.knock_events != 1 && reversal) || (st.knock_events >= 1 && start_stop);
      if (knock) {
        if (start_of(p.t0_s) >= i_end) break;
        st.reversals.add(make_ringing(fs, p.t0_s, st.amp, st.f_res, st.zeta, st.mode2_ratio, st.mode2_share));
        ++impacts_;
      }
      if (sg != 0.0) st.last_sign = sg;
      st.prev_sign = sg;
      st.prev_rest = std::fabs(p.speed0_rad_s) < rest_rad_s;
      if (st.rev->has_next()) {
        st.rev->advance();
      } else {
        st.rev_done = true;
      }
    }
    while (st.random_pending && start_of(st.t_random) < i_end) {
      st.random.add(make_ringing(fs, st.t_random, st.amp, st.f_res, st.zeta, st.mode2_ratio, st.mode2_share));
      ++impacts_;
      st.t_random += -std::log(1.0 - st.rng.uniform()) / st.rate;
      st.random_pending = st.t_random < m_->duration_s;
    }
  }
}

void SignalEffects::apply(std::size_t i0, std::span<double> x) {
  const double fs = m_->fs_hz;
  const std::size_t n = x.size();
  schedule(i0 + n);
  const VibrationSpec& vs = s_->vibration;
  const double nyquist = fs / 2.0;
  // 1. Mechanical additions (they travel the transfer path).
  for (Step& st : steps_) {
    if (!st.active) continue;
    if (st.kind == EffectKind::kImpacts) {
      st.reversals.apply(i0, x, fs, n_total_);
      st.random.apply(i0, x, fs, n_total_);
    } else if (st.kind == EffectKind::kOtherAxis && st.own_w > 0.0) {
      const double on = st.duty * st.gate_period;
      for (std::size_t q = 0; q < n; ++q) {
        const double i = static_cast<double>(i0 + q);
        const double u = std::fmod(i + st.gate_offset, st.gate_period);  // place in the gate period
        if (u >= on) continue;
        double gate = 1.0;
        if (st.duty < 1.0 && st.gate_edge > 0.0) {
          const double d_edge = std::min(u, on - u);  // distance to the nearer edge of the move
          if (d_edge < st.gate_edge) gate = 0.5 - 0.5 * std::cos(std::numbers::pi * d_edge / st.gate_edge);
        }
        const double ph = st.own_w * i + st.own_phase;
        x[q] += st.amp * gate * (std::sin(ph) + st.harmonic2 * std::sin(2.0 * ph + 0.7));
      }
    } else if (st.kind == EffectKind::kOtherAxis) {
      for (std::size_t q = 0; q < n; ++q) {
        const std::ptrdiff_t j = static_cast<std::ptrdiff_t>(i0 + q) - st.lag;
        if (j < 0) continue;  // standing still before the lagged motion starts: speed 0, nothing added
        const MotionState ms = st.lagged->at(static_cast<std::size_t>(j));
        const double angle = ms.angle_rad;
        const double speed = ms.speed_rad_s;
        if (speed == 0.0) continue;
        if (st.order * std::fabs(speed) / kTwoPi >= nyquist) continue;
        const double sf =
            vs.amplitude_speed_exponent == 0.0
                ? 1.0
                : std::pow(std::fabs(speed) / vs.reference_speed_rad_s, vs.amplitude_speed_exponent);
        x[q] += st.amp * sf * std::sin(st.order * angle + 0.7);
      }
    } else if (st.kind == EffectKind::kNoiseColor) {
      if (st.two_poles) {
        for (std::size_t q = 0; q < n; ++q) x[q] += st.amp * st.lp2.next(st.rng);
      } else {
        for (std::size_t q = 0; q < n; ++q) x[q] += st.amp * st.lp.next(st.rng);
      }
    }
  }
  // 2. Structural path to the sensor.
  for (Step& st : steps_) {
    if (st.kind != EffectKind::kTransferPath) continue;
    for (double& v : x) {
      const double y = st.b0 * v + st.b1 * st.x1 + st.b2 * st.x2 - st.a1 * st.y1 - st.a2 * st.y2;
      st.x2 = st.x1;
      st.x1 = v;
      st.y2 = st.y1;
      st.y1 = y;
      v = y;
    }
  }
  // 3. Electrical pickup at the sensor/cable.
  for (const Step& st : steps_) {
    if (st.kind != EffectKind::kElectricalInterference) continue;
    for (const Step::Tone& tone : st.tones) {
      for (std::size_t q = 0; q < n; ++q)
        x[q] += tone.amp * std::sin(tone.w * static_cast<double>(i0 + q) + tone.phase);
    }
  }
  // 4. Acquisition saturates.
  for (const Step& st : steps_) {
    if (st.kind != EffectKind::kAdcClipping) continue;
    const double level = st.level;
    for (double& val : x) {
      if (val > level || val < -level) {
        val = std::clamp(val, -level, level);
        ++clipped_;
      }
    }
  }
}

void SignalEffects::finish() {
  schedule(std::numeric_limits<std::size_t>::max());
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
