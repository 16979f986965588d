// Vibration at the sensor: GMF/DMF harmonics phase-locked to the integrated shaft angles, white noise,
// and the faults (spur tooth impacts ringing a structural resonance + mesh AM; distributed wear).
#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <numbers>
#include <numeric>
#include <optional>

#include "ptda/sim/noise_tilt.hpp"
#include "ptda/sim/random.hpp"
#include "ptda/sim/simulator.hpp"
#include "ptda/sim/stream.hpp"
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

// cos and sin of a phase that moves by a small step from one sample to the next: the previous pair
// turned by the step, whose cos/sin come from sin_cos_series() (ptda/sim/random.hpp; for |d| <= kMaxStep
// the first omitted term is below 7e-17), with an exact std::cos/std::sin every kAnchor calls and whenever
// the step is larger or not finite. The difference of two consecutive phases is exact in floating
// point (they are within a factor 2 of each other), so over kAnchor steps the pair differs from the
// exact one by rounding alone (about 1e-14). One libm sin/cos pair per sample was a third of
// `ptda gap`'s time (session 31, perf: __sincos_fma 21 %, __sin_fma 10 %).
class PhaseRotor {
 public:
  static constexpr double kMaxStep = 0.8;  // rad per sample (a line at 0.127 fs)
  static constexpr std::uint32_t kAnchor = 64;

  void at(double phi, double& c, double& s) noexcept {
    const double d = phi - phi_;
    if (since_ >= kAnchor || !(std::fabs(d) <= kMaxStep)) {
      c_ = std::cos(phi);
      s_ = std::sin(phi);
      since_ = 0;
    } else {
      double sd = 0.0;
      double cd = 1.0;
      sin_cos_series(d, sd, cd);
      const double cn = c_ * cd - s_ * sd;
      s_ = s_ * cd + c_ * sd;
      c_ = cn;
      ++since_;
    }
    phi_ = phi;
    c = c_;
    s = s_;
  }

 private:
  double phi_ = std::numeric_limits<double>::quiet_NaN();  // the first call is exact
  double c_ = 1.0;
  double s_ = 0.0;
  std::uint32_t since_ = kAnchor;
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

Ringing make_ringing(double fs_hz, double t_imp_s, double amplitude, double resonance_hz,
                     double damping_ratio, double mode2_ratio, double mode2_share) noexcept {
  Ringing r;
  const double wn = kTwoPi * resonance_hz;
  r.sigma = damping_ratio * wn;
  r.wd = wn * std::sqrt(1.0 - damping_ratio * damping_ratio);
  r.t_end_s = t_imp_s + kRingDecay / r.sigma;
  if (mode2_ratio > 0.0 && mode2_share > 0.0 && mode2_ratio * resonance_hz < 0.49 * fs_hz) {
    r.amplitude2 = amplitude * mode2_share;
    r.sigma2 = r.sigma * mode2_ratio;
    r.wd2 = r.wd * mode2_ratio;
    r.t_end_s = std::max(r.t_end_s, t_imp_s + kRingDecay / r.sigma2);
  }
  r.n0 = static_cast<std::size_t>(std::ceil(t_imp_s * fs_hz));
  r.t_imp_s = t_imp_s;
  r.amplitude = amplitude;
  return r;
}

void RingingSet::apply(std::size_t i0, std::span<double> x, double fs_hz, std::size_t n_total) {
  const std::size_t i1 = std::min(i0 + x.size(), n_total);
  bool any_done = false;
  for (Ringing& r : active_) {
    std::size_t n = std::max(r.n0, i0);
    for (; n < i1; ++n) {
      const double t = static_cast<double>(n) / fs_hz;
      if (t > r.t_end_s) break;
      const double tau = t - r.t_imp_s;
      double v = r.amplitude * std::exp(-r.sigma * tau) * std::sin(r.wd * tau);
      if (r.amplitude2 != 0.0) v += r.amplitude2 * std::exp(-r.sigma2 * tau) * std::sin(r.wd2 * tau);
      x[n - i0] += v;
    }
    if (n < i1 || n >= n_total) {  // ended (or beyond the recording)
      r.amplitude = 0.0;
      r.n0 = std::numeric_limits<std::size_t>::max();
      any_done = true;
    }
  }
  if (any_done) {
    std::erase_if(active_, [](const Ringing& r) { return r.n0 == std::numeric_limits<std::size_t>::max(); });
  }
}

struct VibrationStream::Impl {
  const Scenario& s;
  const MotionProfile& m;
  const bool keep_impulses;
  std::size_t n = 0;
  std::size_t pos = 0;
  MotionSampler motion;  // the samples being synthesised
  std::vector<Harmonic> gmf;
  std::vector<Harmonic> dmf;
  PhaseRotor mesh_rotor;   // z_in theta_mesh: the GMF orders
  PhaseRotor shaft_rotor;  // g0 theta_mesh: the shaft orders
  PhaseRotor dmf_rotor;    // z_pin theta_out: the DMF orders
  std::uint32_t harmonics_above_nyquist = 0;
  std::uint32_t cycles = 1;
  std::uint64_t seed_ = 0;
  // The current cycle's factors, drawn when the synthesis enters it (cycles only increase along the
  // samples): distributed wear and the cycle variation, whose factors come from their own streams in
  // cycle order, as draw_cycle_variation() draws them for every cycle at once.
  std::uint32_t cur_cycle = std::numeric_limits<std::uint32_t>::max();
  double harmonic_gain = 1.0;
  double noise_gain = 1.0;
  std::vector<double> amp;  // GMF amplitudes of cur_cycle
  Rng amp_rng;
  Rng noise_rng;
  std::uint32_t rows_drawn = 0;
  std::vector<double>
      amp_row;  // cycle variation factors of the last row drawn (one per gmf_amplitudes entry)
  double noise_factor = 1.0;
  std::vector<const FaultSpec*> tooth;
  MeshPerturber pert;
  DriftModel drift;
  bool drifting = false;
  Rng rng;
  // Tooth impacts, detected one sample ahead of the synthesis (an impact found at sample i rings from
  // about sample i - 1): one ringing set per spur_tooth fault, in fault order.
  MotionSampler scan;
  std::size_t scan_pos = 0;
  std::vector<double> u_prev;
  std::vector<RingingSet> tooth_rings;
  std::vector<std::vector<double>> impulse_t;  // per tooth fault (keep_impulses)
  std::vector<std::vector<double>> impulse_a;
  std::uint64_t impulses = 0;
  std::unique_ptr<SignalEffects> effects;
  bool finished = false;
  // Shaft-order lines: whole multiples q of a base order g0 (the orders' gcd), by rotation like the mesh.
  int g0 = 0;
  int m_max = 0;
  std::vector<double> shaft_amp;  // [q - 1]: amplitude of order q * g0
  // Tilted background (docs/simulator.md); white noise draws exactly as before when the tilt is 0.
  std::optional<TiltedNoise> tilted;

  Impl(const Scenario& sc, const MotionProfile& mp, std::uint64_t seed, bool keep)
      : s(sc),
        m(mp),
        keep_impulses(keep),
        n(motion_samples(mp)),
        motion(mp),
        seed_(seed),
        amp_rng(seed, kStreamCycleAmplitude),
        noise_rng(seed, kStreamCycleNoise),
        pert(sc, mp.fs_hz, seed),
        drift(sc.drift, mp.pause_start_s),
        drifting(sc.drift.load_on() || sc.drift.warmup_on()),
        rng(seed, kStreamNoise),
        scan(mp) {
    const VibrationSpec& vs = s.vibration;
    const GearboxSpec& g = s.gearbox;
    const double nyquist = m.fs_hz / 2.0;
    const double w_max = max_abs_speed_rad_s(m);
    // Orders whose frequency at the top speed reaches Nyquist would alias: leave them out and count them.
    for (std::size_t k = 0; k < vs.gmf_amplitudes.size(); ++k) {
      if (vs.gmf_amplitudes[k] == 0.0) continue;
      const double order = static_cast<double>(k + 1);
      if (order * gmf_hz(g, w_max) >= nyquist) {
        ++harmonics_above_nyquist;
        continue;
      }
      const double phi = vs.gmf_phases_rad.empty() ? 0.0 : vs.gmf_phases_rad[k];
      gmf.push_back(
          {order, vs.gmf_amplitudes[k], phi, k, static_cast<int>(k + 1), std::cos(phi), std::sin(phi)});
    }
    for (std::size_t k = 0; k < vs.dmf_amplitudes.size(); ++k) {
      if (vs.dmf_amplitudes[k] == 0.0) continue;
      const double order = static_cast<double>(k + 1);
      if (order * dmf_hz(g, w_max) >= nyquist) {
        ++harmonics_above_nyquist;
        continue;
      }
      dmf.push_back({order, vs.dmf_amplitudes[k], 0.0, k, static_cast<int>(k + 1), 1.0, 0.0});
    }

    cycles = std::max<std::uint32_t>(m.cycles, 1);
    amp.resize(gmf.size());
    amp_row.assign(vs.gmf_amplitudes.size(), 1.0);
    for (const FaultSpec& f : s.faults) {
      if (f.kind == FaultKind::kSpurTooth) tooth.push_back(&f);
    }
    u_prev.assign(tooth.size(), 0.0);
    tooth_rings.resize(tooth.size());
    impulse_t.resize(tooth.size());
    impulse_a.resize(tooth.size());
    if (!s.effects.empty()) effects = std::make_unique<SignalEffects>(s, m, seed);
    for (int j : vs.shaft_orders) g0 = std::gcd(g0, j);
    for (std::size_t i = 0; i < vs.shaft_orders.size() && i < vs.shaft_order_amplitudes.size(); ++i) {
      if (vs.shaft_order_amplitudes[i] <= 0.0) continue;
      if (static_cast<double>(vs.shaft_orders[i]) * gmf_hz(g, w_max) / std::max(g.z_in, 1U) >= nyquist)
        continue;
      const int mult = vs.shaft_orders[i] / g0;
      if (mult > m_max) {
        shaft_amp.resize(static_cast<std::size_t>(mult), 0.0);
        m_max = mult;
      }
      shaft_amp[static_cast<std::size_t>(mult - 1)] = vs.shaft_order_amplitudes[i];
    }
    if ((vs.noise_tilt_db_per_decade != 0.0 || !vs.noise_shape_hz.empty()) && vs.noise_rms > 0.0)
      tilted.emplace(vs.noise_tilt_db_per_decade, m.fs_hz, vs.noise_shape_hz, vs.noise_shape_db);
  }

  /// Enters cycle c (>= the current one): the per-cycle gains of the faults (severity is constant within
  /// a cycle) and the cycle variation (the GMF amplitudes of the cycle, the nominal ones when off, and
  /// the noise level).
  void enter_cycle(std::uint32_t c) {
    const VibrationSpec& vs = s.vibration;
    for (; rows_drawn <= c; ++rows_drawn) {
      if (vs.cycle_amplitude_jitter_rel > 0.0) {
        for (double& f : amp_row) f = std::exp(vs.cycle_amplitude_jitter_rel * amp_rng.normal());
      }
      if (vs.cycle_noise_jitter_rel > 0.0)
        noise_factor = std::exp(vs.cycle_noise_jitter_rel * noise_rng.normal());
    }
    harmonic_gain = 1.0;
    noise_gain = 1.0;
    for (const FaultSpec& f : s.faults) {
      if (f.kind != FaultKind::kDistributedWear) continue;
      const double sev = fault_severity(f, c);
      harmonic_gain *= 1.0 + f.harmonic_gain * sev;
      noise_gain *= 1.0 + f.noise_gain * sev;
    }
    if (vs.cycle_noise_jitter_rel > 0.0) noise_gain *= noise_factor;
    for (std::size_t j = 0; j < gmf.size(); ++j) {
      amp[j] =
          vs.cycle_amplitude_jitter_rel > 0.0 ? gmf[j].amplitude * amp_row[gmf[j].entry] : gmf[j].amplitude;
    }
    cur_cycle = c;
  }

  /// Tooth impacts: once per spur revolution, when the defect angle passes a multiple of 2 pi (either
  /// direction), located between samples by linear interpolation of the angle. Scans samples up to
  /// i_end (exclusive).
  void detect_impacts(std::size_t i_end) {
    const VibrationSpec& vs = s.vibration;
    const double fs = m.fs_hz;
    const double ratio = reduction_ratio(s.gearbox);
    const double spur_per_in = static_cast<double>(s.gearbox.z_in) / static_cast<double>(s.gearbox.z_spur);
    i_end = std::min(i_end, n);
    for (; scan_pos < i_end; ++scan_pos) {
      const std::size_t i = scan_pos;
      const MotionState ms = scan.at(i);
      for (std::size_t q = 0; q < tooth.size(); ++q) {
        const FaultSpec* f = tooth[q];
        if (f->impulse_amplitude_ms2 <= 0.0) continue;
        const double u = (spur_per_in * ratio * ms.angle_rad + f->spur_phase_rad) / kTwoPi;
        const double u_last = u_prev[q];
        if (i > 0 && std::floor(u) != std::floor(u_last)) {
          const double lo = std::min(u, u_last);
          const double hi = std::max(u, u_last);
          for (double k = std::floor(lo) + 1.0; k <= hi; k += 1.0) {
            const double frac = (k - u_last) / (u - u_last);
            const double t_imp = (static_cast<double>(i - 1) + frac) / fs;
            const double sev = fault_severity(*f, std::min(ms.cycle, cycles - 1));
            const double a = f->impulse_amplitude_ms2 * sev * speed_factor(vs, ms.speed_rad_s);
            if (a <= 0.0) continue;
            // [drift]: the structural resonance moves with the stiffness (load/temperature cycle).
            const double res_hz =
                drifting ? f->resonance_hz * drift.at(t_imp).resonance_factor : f->resonance_hz;
            tooth_rings[q].add(make_ringing(fs, t_imp, a, res_hz, f->damping_ratio));
            ++impulses;
            if (keep_impulses) {
              impulse_t[q].push_back(t_imp);
              impulse_a[q].push_back(a);
            }
          }
        }
        u_prev[q] = u;
      }
    }
  }

  /// The mesh, noise and drift of samples [i0, i0 + x.size()).
  void synthesize(std::size_t i0, std::span<double> x) {
    const VibrationSpec& vs = s.vibration;
    const GearboxSpec& g = s.gearbox;
    const double fs = m.fs_hz;
    const double ratio = reduction_ratio(g);
    const double z_in = g.z_in;
    const double spur_per_in = z_in / static_cast<double>(g.z_spur);  // spur turns per input turn
    const bool perturbed = pert.on();
    for (std::size_t q = 0; q < x.size(); ++q) {
      const std::size_t i = i0 + q;
      const MotionState ms = motion.at(i);
      double pert_offset = 0.0;
      double pert_gain = 1.0;
      if (perturbed) pert.next(ms, pert_offset, pert_gain);
      const double theta_out = ms.angle_rad;
      const double theta_in = ratio * theta_out;
      const double theta_mesh = perturbed ? theta_in + pert_offset : theta_in;
      const std::uint32_t c = std::min(ms.cycle, cycles - 1);
      if (c != cur_cycle) enter_cycle(c);
      const double sf = speed_factor(vs, ms.speed_rad_s);
      const DriftFactors d = drifting ? drift.at(static_cast<double>(i) / fs) : DriftFactors{};
      double mesh = 0.0;
      if (sf != 0.0) {
        // phase_k = k * Z_in * theta_in + phi_k: follows the integrated input angle, so speed changes
        // and cycle-to-cycle start differences move the phase exactly as a real mesh does.
        // The orders are whole numbers: e^{i k b} by repeated rotation from e^{i b}, one sin/cos pair per
        // sample instead of one sin per harmonic (the simulator's hot loop in `ptda gap`'s fits).
        const std::vector<double>& amp_c = amp;
        double c1 = 1.0, s1 = 0.0;
        mesh_rotor.at(z_in * theta_mesh, c1, s1);
        double ck = 1.0, sk = 0.0;
        int k = 0;
        for (std::size_t j = 0; j < gmf.size(); ++j) {
          for (; k < gmf[j].whole_order; ++k) {
            const double cn = ck * c1 - sk * s1;
            sk = sk * c1 + ck * s1;
            ck = cn;
          }
          mesh += amp_c[j] * (sk * gmf[j].cos_phase + ck * gmf[j].sin_phase);  // sin(k b + phi)
        }
        mesh *= harmonic_gain;
        if (perturbed) mesh *= pert_gain;
        for (const FaultSpec* f : tooth) {
          const double depth = f->am_depth * fault_severity(*f, c);
          if (depth > 0.0) mesh *= 1.0 + depth * std::cos(spur_per_in * theta_in + f->spur_phase_rad);
        }
        if (!dmf.empty()) {
          // The DMF orders are whole numbers too (k + 1): sin(k p) by rotation from e^{i p}.
          double dc1 = 1.0, ds1 = 0.0;
          dmf_rotor.at(static_cast<double>(g.z_pin) * theta_out, dc1, ds1);
          double dck = 1.0, dsk = 0.0;
          int dk = 0;
          for (const Harmonic& h : dmf) {
            for (; dk < h.whole_order; ++dk) {
              const double cn = dck * dc1 - dsk * ds1;
              dsk = dsk * dc1 + dck * ds1;
              dck = cn;
            }
            mesh += h.amplitude * dsk;  // sin(k z_pin theta_out)
          }
        }
        if (drifting) mesh *= d.mesh_gain;  // mesh stiffness (load, temperature) and cold oil
        if (m_max > 0) {
          double sc1 = 1.0, ss1 = 0.0;
          shaft_rotor.at(static_cast<double>(g0) * theta_mesh, sc1, ss1);
          double sck = 1.0, ssk = 0.0;
          for (int r = 1; r <= m_max; ++r) {
            const double cn = sck * sc1 - ssk * ss1;
            ssk = ssk * sc1 + sck * ss1;
            sck = cn;
            mesh += shaft_amp[static_cast<std::size_t>(r - 1)] * ssk;  // sin(r g0 theta_in)
          }
        }
      }
      double noise = 0.0;
      if (vs.noise_rms > 0.0) noise = vs.noise_rms * noise_gain * (tilted ? tilted->next(rng) : rng.normal());
      if (drifting) noise *= d.noise_gain;
      x[q] = sf * mesh + noise;
    }
  }
};

VibrationStream::VibrationStream(const Scenario& s, const MotionProfile& m, std::uint64_t seed,
                                 bool keep_impulses)
    : impl_(std::make_unique<Impl>(s, m, seed, keep_impulses)) {}

VibrationStream::~VibrationStream() = default;

std::size_t VibrationStream::samples() const noexcept {
  return impl_->n;
}

std::size_t VibrationStream::position() const noexcept {
  return impl_->pos;
}

std::size_t VibrationStream::next(std::span<double> x) {
  Impl& im = *impl_;
  const std::size_t count = std::min(x.size(), im.n - im.pos);
  if (count == 0) {
    if (!im.finished && im.effects) im.effects->finish();
    im.finished = true;
    return 0;
  }
  const std::span<double> block = x.first(count);
  const std::size_t i0 = im.pos;
  // An impact found at sample i starts ringing at ceil(t_imp fs) >= i - 1 (up to rounding): scan two
  // samples past the block so that every ringing reaching into it is known.
  im.detect_impacts(i0 + count + 2);
  im.synthesize(i0, block);
  for (RingingSet& rings : im.tooth_rings) rings.apply(i0, block, im.m.fs_hz, im.n);
  if (im.effects) im.effects->apply(i0, block);
  im.pos += count;
  if (im.pos == im.n && !im.finished) {
    if (im.effects) im.effects->finish();
    im.finished = true;
  }
  return count;
}

std::uint32_t VibrationStream::harmonics_above_nyquist() const noexcept {
  return impl_->harmonics_above_nyquist;
}

std::uint64_t VibrationStream::impulses() const noexcept {
  return impl_->impulses;
}

std::uint64_t VibrationStream::effect_impacts() const noexcept {
  return impl_->effects ? impl_->effects->impacts() : 0;
}

std::uint64_t VibrationStream::effect_clipped_samples() const noexcept {
  return impl_->effects ? impl_->effects->clipped_samples() : 0;
}

void VibrationStream::take_truth(Vibration& v) {
  Impl& im = *impl_;
  v.harmonics_above_nyquist = im.harmonics_above_nyquist;
  v.effect_impacts = effect_impacts();
  v.effect_clipped_samples = effect_clipped_samples();
  v.cycle_variation = draw_cycle_variation(im.s.vibration, im.cycles, im.seed_);
  v.impulse_times_s.clear();
  v.impulse_amplitudes_ms2.clear();
  for (std::size_t q = 0; q < im.impulse_t.size(); ++q) {
    v.impulse_times_s.insert(v.impulse_times_s.end(), im.impulse_t[q].begin(), im.impulse_t[q].end());
    v.impulse_amplitudes_ms2.insert(v.impulse_amplitudes_ms2.end(), im.impulse_a[q].begin(),
                                    im.impulse_a[q].end());
  }
  if (im.tooth.size() > 1) {
    std::vector<std::size_t> idx(v.impulse_times_s.size());
    for (std::size_t i = 0; i < idx.size(); ++i) idx[i] = i;
    std::sort(idx.begin(), idx.end(),
              [&](std::size_t a, std::size_t b) { return v.impulse_times_s[a] < v.impulse_times_s[b]; });
    std::vector<double> t(idx.size());
    std::vector<double> a(idx.size());
    for (std::size_t i = 0; i < idx.size(); ++i) {
      t[i] = v.impulse_times_s[idx[i]];
      a[i] = v.impulse_amplitudes_ms2[idx[i]];
    }
    v.impulse_times_s = std::move(t);
    v.impulse_amplitudes_ms2 = std::move(a);
  }
}

Vibration synthesize_vibration(const Scenario& s, const MotionProfile& m, std::uint64_t seed) {
  Vibration out;
  VibrationStream stream(s, m, seed, true);
  out.accel_ms2.assign(stream.samples(), 0.0);
  while (stream.next(std::span<double>(out.accel_ms2).subspan(stream.position())) > 0) {
  }
  stream.take_truth(out);
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

void quantize_block(const SensorSpec& sensor, std::span<const double> accel_ms2, std::span<float> out,
                    std::uint64_t* clipped) noexcept {
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
  if (clipped != nullptr) *clipped += n_clipped;
}

std::vector<float> quantize(const SensorSpec& sensor, const std::vector<double>& accel_ms2,
                            std::uint64_t* clipped) {
  std::vector<float> out(accel_ms2.size());
  std::uint64_t n_clipped = 0;
  quantize_block(sensor, accel_ms2, out, &n_clipped);
  if (clipped != nullptr) *clipped = n_clipped;
  return out;
}

}  // namespace ptda::sim
