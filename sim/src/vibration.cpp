// Vibration at the sensor: GMF/DMF harmonics phase-locked to the integrated shaft angles, white noise,
// and the faults (spur tooth impacts ringing a structural resonance + mesh AM; distributed wear).
#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>
#include <optional>

#include "ptda/sim/noise_tilt.hpp"
#include "ptda/sim/random.hpp"
#include "ptda/sim/simulator.hpp"
#include "sim_internal.hpp"

namespace ptda::sim {
namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;
// A ringing is cut where its envelope has decayed to 1e-6 of the start (about -120 dB, below any
// 24-bit quantisation step used here).
constexpr double kRingDecay = 13.8155;  // -ln(1e-6)

struct Harmonic {
  double order = 0.0;      ///< k
  double amplitude = 0.0;  ///< A_k at reference speed
  double phase_rad = 0.0;  ///< phi_k
  std::size_t entry = 0;   ///< index into gmf_amplitudes / dmf_amplitudes
  int whole_order = 0;     ///< k as an integer (orders are entry + 1)
  double cos_phase = 1.0;  ///< cos(phi_k), sin(phi_k) for the rotation form of sin(k b + phi_k)
  double sin_phase = 0.0;
};

double speed_factor(const VibrationSpec& v, double speed_rad_s) {
  if (v.amplitude_speed_exponent == 0.0) return 1.0;
  // pow(x, 1) is exactly x: skip the call in the common linear case (same result, much faster).
  if (v.amplitude_speed_exponent == 1.0) return std::fabs(speed_rad_s) / v.reference_speed_rad_s;
  return std::pow(std::fabs(speed_rad_s) / v.reference_speed_rad_s, v.amplitude_speed_exponent);
}

}  // namespace

CycleVariation draw_cycle_variation(const VibrationSpec& v, std::uint32_t cycles, std::uint64_t seed) {
  CycleVariation out;
  // One draw per cycle and gmf_amplitudes entry, in that order, whether the entry is zero or omitted
  // above Nyquist: the factors of a cycle do not depend on which orders happen to be synthesised.
  if (v.cycle_amplitude_jitter_rel > 0.0) {
    Rng rng(seed, kStreamCycleAmplitude);
    out.amplitude_factors.assign(cycles, std::vector<double>(v.gmf_amplitudes.size(), 1.0));
    for (auto& row : out.amplitude_factors) {
      for (double& f : row) f = std::exp(v.cycle_amplitude_jitter_rel * rng.normal());
    }
  }
  if (v.cycle_noise_jitter_rel > 0.0) {
    Rng rng(seed, kStreamCycleNoise);
    out.noise_factors.resize(cycles);
    for (double& f : out.noise_factors) f = std::exp(v.cycle_noise_jitter_rel * rng.normal());
  }
  return out;
}

void add_ringing(std::vector<double>& x, double fs_hz, double t_imp_s, double amplitude, double resonance_hz,
                 double damping_ratio) {
  const double wn = kTwoPi * resonance_hz;
  const double sigma = damping_ratio * wn;
  const double wd = wn * std::sqrt(1.0 - damping_ratio * damping_ratio);
  const double t_end = t_imp_s + kRingDecay / sigma;
  auto n = static_cast<std::size_t>(std::ceil(t_imp_s * fs_hz));
  for (; n < x.size(); ++n) {
    const double t = static_cast<double>(n) / fs_hz;
    if (t > t_end) break;
    const double tau = t - t_imp_s;
    x[n] += amplitude * std::exp(-sigma * tau) * std::sin(wd * tau);
  }
}

Vibration synthesize_vibration(const Scenario& s, const MotionProfile& m, std::uint64_t seed) {
  const VibrationSpec& vs = s.vibration;
  const GearboxSpec& g = s.gearbox;
  const double fs = m.fs_hz;
  const double nyquist = fs / 2.0;
  const double ratio = reduction_ratio(g);
  const std::size_t n = m.angle_rad.size();
  Vibration out;
  out.accel_ms2.assign(n, 0.0);

  double w_max = 0.0;
  for (double w : m.speed_rad_s) w_max = std::max(w_max, std::fabs(w));
  // Orders whose frequency at the top speed reaches Nyquist would alias: leave them out and count them.
  std::vector<Harmonic> gmf;
  for (std::size_t k = 0; k < vs.gmf_amplitudes.size(); ++k) {
    if (vs.gmf_amplitudes[k] == 0.0) continue;
    const double order = static_cast<double>(k + 1);
    if (order * gmf_hz(g, w_max) >= nyquist) {
      ++out.harmonics_above_nyquist;
      continue;
    }
    const double phi = vs.gmf_phases_rad.empty() ? 0.0 : vs.gmf_phases_rad[k];
    gmf.push_back(
        {order, vs.gmf_amplitudes[k], phi, k, static_cast<int>(k + 1), std::cos(phi), std::sin(phi)});
  }
  std::vector<Harmonic> dmf;
  for (std::size_t k = 0; k < vs.dmf_amplitudes.size(); ++k) {
    if (vs.dmf_amplitudes[k] == 0.0) continue;
    const double order = static_cast<double>(k + 1);
    if (order * dmf_hz(g, w_max) >= nyquist) {
      ++out.harmonics_above_nyquist;
      continue;
    }
    dmf.push_back({order, vs.dmf_amplitudes[k], 0.0, k, static_cast<int>(k + 1), 1.0, 0.0});
  }

  // Per-cycle gains of the faults (severity is constant within a cycle).
  const std::uint32_t cycles = std::max<std::uint32_t>(m.cycles, 1);
  std::vector<double> harmonic_gain(cycles, 1.0);
  std::vector<double> noise_gain(cycles, 1.0);
  for (const FaultSpec& f : s.faults) {
    if (f.kind != FaultKind::kDistributedWear) continue;
    for (std::uint32_t c = 0; c < cycles; ++c) {
      const double sev = fault_severity(f, c);
      harmonic_gain[c] *= 1.0 + f.harmonic_gain * sev;
      noise_gain[c] *= 1.0 + f.noise_gain * sev;
    }
  }
  // Cycle-to-cycle variation: the GMF amplitudes of each cycle (a copy of the nominal ones per cycle
  // when off, so the product below is the same as without the feature) and the noise level.
  out.cycle_variation = draw_cycle_variation(vs, cycles, seed);
  const CycleVariation& cv = out.cycle_variation;
  std::vector<std::vector<double>> gmf_amplitude(cycles, std::vector<double>(gmf.size()));
  for (std::uint32_t c = 0; c < cycles; ++c) {
    for (std::size_t j = 0; j < gmf.size(); ++j) {
      gmf_amplitude[c][j] = cv.amplitude_factors.empty()
                                ? gmf[j].amplitude
                                : gmf[j].amplitude * cv.amplitude_factors[c][gmf[j].entry];
    }
    if (!cv.noise_factors.empty()) noise_gain[c] *= cv.noise_factors[c];
  }
  std::vector<const FaultSpec*> tooth;
  for (const FaultSpec& f : s.faults) {
    if (f.kind == FaultKind::kSpurTooth) tooth.push_back(&f);
  }

  const double z_in = g.z_in;
  const double spur_per_in = z_in / static_cast<double>(g.z_spur);  // spur turns per input turn
  const MeshPerturbation pert = mesh_perturbation(s, m, seed);
  const bool perturbed = !pert.gain.empty();
  // [drift]: slow load/temperature and warm-up factors (off: the loop below is unchanged).
  const DriftModel drift(s.drift, m.pause_start_s);
  const bool drifting = s.drift.load_on() || s.drift.warmup_on();
  Rng rng(seed, kStreamNoise);
  // Shaft-order lines: whole multiples m of a base order g0 (the orders' gcd), by rotation like the mesh.
  int g0 = 0, m_max = 0;
  for (int j : vs.shaft_orders) g0 = std::gcd(g0, j);
  std::vector<double> shaft_amp;  // [m - 1]: amplitude of order m * g0
  for (std::size_t i = 0; i < vs.shaft_orders.size() && i < vs.shaft_order_amplitudes.size(); ++i) {
    if (vs.shaft_order_amplitudes[i] <= 0.0) continue;
    const int mult = vs.shaft_orders[i] / g0;
    if (static_cast<double>(vs.shaft_orders[i]) * gmf_hz(g, w_max) / std::max(g.z_in, 1U) >= nyquist)
      continue;
    if (mult > m_max) {
      shaft_amp.resize(static_cast<std::size_t>(mult), 0.0);
      m_max = mult;
    }
    shaft_amp[static_cast<std::size_t>(mult - 1)] = vs.shaft_order_amplitudes[i];
  }
  // Tilted background (docs/simulator.md); white noise draws exactly as before when the tilt is 0.
  std::optional<TiltedNoise> tilted;
  if (vs.noise_tilt_db_per_decade != 0.0 && vs.noise_rms > 0.0)
    tilted.emplace(vs.noise_tilt_db_per_decade, fs);
  for (std::size_t i = 0; i < n; ++i) {
    const double theta_out = m.angle_rad[i];
    const double theta_in = ratio * theta_out;
    const double theta_mesh = perturbed ? theta_in + pert.theta_in_offset_rad[i] : theta_in;
    const std::uint32_t c = std::min(m.cycle[i], cycles - 1);
    const double sf = speed_factor(vs, m.speed_rad_s[i]);
    const DriftFactors d = drifting ? drift.at(static_cast<double>(i) / fs) : DriftFactors{};
    double mesh = 0.0;
    if (sf != 0.0) {
      // phase_k = k * Z_in * theta_in + phi_k: follows the integrated input angle, so speed changes
      // and cycle-to-cycle start differences move the phase exactly as a real mesh does.
      // The orders are whole numbers: e^{i k b} by repeated rotation from e^{i b}, one sin/cos pair per
      // sample instead of one sin per harmonic (the simulator's hot loop in `ptda gap`'s fits).
      const std::vector<double>& amp = gmf_amplitude[c];
      const double b = z_in * theta_mesh;
      const double c1 = std::cos(b), s1 = std::sin(b);
      double ck = 1.0, sk = 0.0;
      int k = 0;
      for (std::size_t j = 0; j < gmf.size(); ++j) {
        for (; k < gmf[j].whole_order; ++k) {
          const double cn = ck * c1 - sk * s1;
          sk = sk * c1 + ck * s1;
          ck = cn;
        }
        mesh += amp[j] * (sk * gmf[j].cos_phase + ck * gmf[j].sin_phase);  // sin(k b + phi)
      }
      mesh *= harmonic_gain[c];
      if (perturbed) mesh *= pert.gain[i];
      for (const FaultSpec* f : tooth) {
        const double depth = f->am_depth * fault_severity(*f, c);
        if (depth > 0.0) mesh *= 1.0 + depth * std::cos(spur_per_in * theta_in + f->spur_phase_rad);
      }
      for (const Harmonic& h : dmf) {
        mesh += h.amplitude * std::sin(h.order * static_cast<double>(g.z_pin) * theta_out);
      }
      if (drifting) mesh *= d.mesh_gain;  // mesh stiffness (load, temperature) and cold oil
      if (m_max > 0) {
        const double b0 = static_cast<double>(g0) * theta_mesh;
        const double sc1 = std::cos(b0), ss1 = std::sin(b0);
        double sck = 1.0, ssk = 0.0;
        for (int q = 1; q <= m_max; ++q) {
          const double cn = sck * sc1 - ssk * ss1;
          ssk = ssk * sc1 + sck * ss1;
          sck = cn;
          mesh += shaft_amp[static_cast<std::size_t>(q - 1)] * ssk;  // sin(q g0 theta_in)
        }
      }
    }
    double noise = 0.0;
    if (vs.noise_rms > 0.0) {
      noise = vs.noise_rms * noise_gain[c] * (tilted ? tilted->next(rng) : rng.normal());
    }
    if (drifting) noise *= d.noise_gain;
    out.accel_ms2[i] = sf * mesh + noise;
  }

  // Tooth impacts: once per spur revolution, when the defect angle passes a multiple of 2 pi (either
  // direction), located between samples by linear interpolation of the angle.
  for (const FaultSpec* f : tooth) {
    if (f->impulse_amplitude_ms2 <= 0.0) continue;
    double u_prev = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      const double u = (spur_per_in * ratio * m.angle_rad[i] + f->spur_phase_rad) / kTwoPi;
      if (i > 0 && std::floor(u) != std::floor(u_prev)) {
        const double lo = std::min(u, u_prev);
        const double hi = std::max(u, u_prev);
        for (double k = std::floor(lo) + 1.0; k <= hi; k += 1.0) {
          const double frac = (k - u_prev) / (u - u_prev);
          const double t_imp = (static_cast<double>(i - 1) + frac) / fs;
          const double sev = fault_severity(*f, std::min(m.cycle[i], cycles - 1));
          const double amp = f->impulse_amplitude_ms2 * sev * speed_factor(vs, m.speed_rad_s[i]);
          if (amp <= 0.0) continue;
          // [drift]: the structural resonance moves with the stiffness (load/temperature cycle).
          const double res_hz =
              drifting ? f->resonance_hz * drift.at(t_imp).resonance_factor : f->resonance_hz;
          add_ringing(out.accel_ms2, fs, t_imp, amp, res_hz, f->damping_ratio);
          out.impulse_times_s.push_back(t_imp);
          out.impulse_amplitudes_ms2.push_back(amp);
        }
      }
      u_prev = u;
    }
  }
  if (tooth.size() > 1) {
    std::vector<std::size_t> idx(out.impulse_times_s.size());
    for (std::size_t i = 0; i < idx.size(); ++i) idx[i] = i;
    std::sort(idx.begin(), idx.end(),
              [&](std::size_t a, std::size_t b) { return out.impulse_times_s[a] < out.impulse_times_s[b]; });
    std::vector<double> t(idx.size());
    std::vector<double> a(idx.size());
    for (std::size_t i = 0; i < idx.size(); ++i) {
      t[i] = out.impulse_times_s[idx[i]];
      a[i] = out.impulse_amplitudes_ms2[idx[i]];
    }
    out.impulse_times_s = std::move(t);
    out.impulse_amplitudes_ms2 = std::move(a);
  }
  if (!s.effects.empty()) apply_signal_effects(s, m, seed, out);
  return out;
}

double sensor_scale(const SensorSpec& sensor) noexcept {
  switch (sensor.format) {
    case formats::WavSampleFormat::kPcm16:
      return sensor.range_ms2 / 32768.0;
    case formats::WavSampleFormat::kPcm24:
      return sensor.range_ms2 / 8388608.0;
    case formats::WavSampleFormat::kPcm32:
      return sensor.range_ms2 / 2147483648.0;
    case formats::WavSampleFormat::kFloat32:
      return 1.0;
  }
  return 1.0;
}

std::vector<float> quantize(const SensorSpec& sensor, const std::vector<double>& accel_ms2,
                            std::uint64_t* clipped) {
  std::vector<float> out(accel_ms2.size());
  std::uint64_t n_clipped = 0;
  const double range = sensor.range_ms2;
  const bool is_float = sensor.format == formats::WavSampleFormat::kFloat32;
  const double lsb = sensor_scale(sensor);
  double code_max = 0.0;
  switch (sensor.format) {
    case formats::WavSampleFormat::kPcm16:
      code_max = 32767.0;
      break;
    case formats::WavSampleFormat::kPcm24:
      code_max = 8388607.0;
      break;
    case formats::WavSampleFormat::kPcm32:
      code_max = 2147483647.0;
      break;
    case formats::WavSampleFormat::kFloat32:
      break;
  }
  for (std::size_t i = 0; i < accel_ms2.size(); ++i) {
    double v = accel_ms2[i];
    if (v > range || v < -range) {
      ++n_clipped;
      v = std::clamp(v, -range, range);  // the sensor/ADC saturates
    }
    if (is_float) {
      out[i] = static_cast<float>(v);
    } else {
      // Codes -2^(bits-1) .. 2^(bits-1)-1; +range itself saturates to the top code.
      const double code = std::clamp(std::round(v / lsb), -code_max - 1.0, code_max);
      out[i] = static_cast<float>(code);
    }
  }
  if (clipped != nullptr) *clipped = n_clipped;
  return out;
}

}  // namespace ptda::sim
