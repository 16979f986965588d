// simulate_to_directory: motion -> vibration -> sensor codes + CAN log -> a recording directory, plus
// truth.toml (what was simulated; analysis commands never read it).
#include <toml++/toml.h>

#include <cmath>
#include <fstream>
#include <numbers>
#include <string>
#include <system_error>

#include "ptda/common/error.hpp"
#include "ptda/formats/candump.hpp"
#include "ptda/formats/recording.hpp"
#include "ptda/formats/wav.hpp"
#include "ptda/sim/simulator.hpp"
#include "sim_internal.hpp"

namespace ptda::sim {
namespace {

const char* format_name(formats::WavSampleFormat f) {
  switch (f) {
    case formats::WavSampleFormat::kPcm16:
      return "pcm16";
    case formats::WavSampleFormat::kPcm24:
      return "pcm24";
    case formats::WavSampleFormat::kPcm32:
      return "pcm32";
    case formats::WavSampleFormat::kFloat32:
      return "float32";
  }
  return "?";
}

toml::array to_array(const std::vector<double>& v) {
  toml::array a;
  for (double x : v) a.push_back(x);
  return a;
}

toml::table truth_table(const Scenario& s, const MotionProfile& m, const Vibration& vib,
                        const std::vector<SimCanFrame>& can, const SimulationSummary& sum) {
  const GearboxSpec& g = s.gearbox;
  toml::table root;
  root.insert("format", "ptda-sim-truth");
  root.insert("version", 1);
  root.insert("scenario", s.name);
  root.insert("source", s.source);
  root.insert("seed", static_cast<std::int64_t>(sum.seed));
  root.insert("start_time_s", s.start_time_s);

  toml::table gb;
  gb.insert("kind", g.kind == GearboxKind::kCycloidal ? "cycloidal" : "parallel");
  gb.insert("z_in", static_cast<std::int64_t>(g.z_in));
  gb.insert("z_spur", static_cast<std::int64_t>(g.z_spur));
  gb.insert("z_pin", static_cast<std::int64_t>(g.z_pin));
  gb.insert("ratio", reduction_ratio(g));
  root.insert("gearbox", std::move(gb));

  toml::table mo;
  mo.insert("kind", s.motion.kind == MotionKind::kLspb       ? "lspb"
                    : s.motion.kind == MotionKind::kConstant ? "constant"
                                                             : "measured");
  mo.insert("duration_s", m.duration_s);
  mo.insert("cycles", static_cast<std::int64_t>(m.cycles));
  mo.insert("cycle_start_s", to_array(m.cycle_start_s));
  if (s.motion.kind == MotionKind::kLspb) {
    mo.insert("via_points_rad", to_array(s.motion.via_points_rad));
    mo.insert("accel_rad_s2", s.motion.accel_rad_s2);
    mo.insert("dwell_s", s.motion.dwell_s);
    mo.insert("start_jitter_s", s.motion.start_jitter_s);
    mo.insert("lead_in_s", s.motion.lead_in_s);
  } else if (s.motion.kind == MotionKind::kConstant) {
    mo.insert("shaft_speed_hz", s.motion.shaft_speed_hz);
  }
  root.insert("motion", std::move(mo));

  toml::array plateaus;
  const double ratio = reduction_ratio(g);
  for (const Plateau& p : m.plateaus) {
    toml::table t;
    t.insert("cycle", static_cast<std::int64_t>(p.cycle));
    t.insert("t_start_s", p.t_start_s);
    t.insert("t_end_s", p.t_end_s);
    t.insert("duration_s", p.t_end_s - p.t_start_s);
    t.insert("unix_start_s", s.start_time_s + p.t_start_s);
    t.insert("speed_rad_s", p.speed_rad_s);
    t.insert("input_shaft_hz", ratio * std::fabs(p.speed_rad_s) / (2.0 * std::numbers::pi));
    t.insert("gmf_hz", gmf_hz(g, p.speed_rad_s));
    t.insert("dmf_hz", dmf_hz(g, p.speed_rad_s));
    t.insert("spur_hz", gmf_hz(g, p.speed_rad_s) / static_cast<double>(g.z_spur));
    plateaus.push_back(std::move(t));
  }
  root.insert("plateau", std::move(plateaus));

  toml::table vb;
  vb.insert("gmf_amplitudes", to_array(s.vibration.gmf_amplitudes));
  vb.insert("gmf_phases_rad", to_array(s.vibration.gmf_phases_rad));
  vb.insert("dmf_amplitudes", to_array(s.vibration.dmf_amplitudes));
  vb.insert("reference_speed_rad_s", s.vibration.reference_speed_rad_s);
  vb.insert("amplitude_speed_exponent", s.vibration.amplitude_speed_exponent);
  vb.insert("noise_rms", s.vibration.noise_rms);
  if (s.vibration.noise_tilt_db_per_decade != 0.0)
    vb.insert("noise_tilt_db_per_decade", s.vibration.noise_tilt_db_per_decade);
  if (!s.vibration.shaft_orders.empty()) {
    toml::array orders;
    for (int j : s.vibration.shaft_orders) orders.push_back(static_cast<std::int64_t>(j));
    vb.insert("shaft_orders", std::move(orders));
    vb.insert("shaft_order_amplitudes", to_array(s.vibration.shaft_order_amplitudes));
  }
  vb.insert("harmonics_above_nyquist", static_cast<std::int64_t>(vib.harmonics_above_nyquist));
  // The cycle variation only when on: without it truth.toml stays as it was before the feature.
  const CycleVariation& cv = vib.cycle_variation;
  if (s.vibration.cycle_amplitude_jitter_rel > 0.0) {
    vb.insert("cycle_amplitude_jitter_rel", s.vibration.cycle_amplitude_jitter_rel);
    toml::array rows;  // [cycle][k]: factor on gmf_amplitudes[k] in that cycle
    for (const std::vector<double>& row : cv.amplitude_factors) rows.push_back(to_array(row));
    vb.insert("cycle_amplitude_factors", std::move(rows));
  }
  if (s.vibration.cycle_noise_jitter_rel > 0.0) {
    vb.insert("cycle_noise_jitter_rel", s.vibration.cycle_noise_jitter_rel);
    vb.insert("cycle_noise_factors", to_array(cv.noise_factors));
  }
  root.insert("vibration", std::move(vb));

  toml::array faults;
  for (const FaultSpec& f : s.faults) {
    toml::table t;
    t.insert("kind", f.kind == FaultKind::kSpurTooth ? "spur_tooth" : "distributed_wear");
    t.insert("severity", f.severity);
    t.insert("onset_cycle", static_cast<std::int64_t>(f.onset_cycle));
    t.insert("ramp_cycles", static_cast<std::int64_t>(f.ramp_cycles));
    std::vector<double> sev;
    for (std::uint32_t c = 0; c < m.cycles; ++c) sev.push_back(fault_severity(f, c));
    t.insert("severity_per_cycle", to_array(sev));
    if (f.kind == FaultKind::kSpurTooth) {
      t.insert("impulse_amplitude_ms2", f.impulse_amplitude_ms2);
      t.insert("resonance_hz", f.resonance_hz);
      t.insert("damping_ratio", f.damping_ratio);
      t.insert("am_depth", f.am_depth);
      t.insert("spur_phase_rad", f.spur_phase_rad);
    } else {
      t.insert("harmonic_gain", f.harmonic_gain);
      t.insert("noise_gain", f.noise_gain);
    }
    faults.push_back(std::move(t));
  }
  root.insert("fault", std::move(faults));

  toml::array effects;
  for (const EffectSpec& e : s.effects) {
    const EffectInfo& info = effect_info(e.kind);
    toml::table t;
    t.insert("kind", info.name);
    for (std::size_t i = 0; i < info.params.size() && i < e.params.size(); ++i)
      t.insert(info.params[i].name, e.params[i]);
    effects.push_back(std::move(t));
  }
  if (!s.effects.empty()) {  // without effects truth.toml stays as it was before the effects library
    root.insert("effect", std::move(effects));
    root.insert("effect_impacts", static_cast<std::int64_t>(vib.effect_impacts));
    root.insert("effect_clipped_samples", static_cast<std::int64_t>(vib.effect_clipped_samples));
  }
  root.insert("impulses", static_cast<std::int64_t>(vib.impulse_times_s.size()));
  if (s.drift.on()) {  // without [drift] truth.toml stays as it was before the drift model
    const DriftSpec& d = s.drift;
    const DriftModel model(d, m.pause_start_s);
    toml::table dt;
    dt.insert("time_offset_s", d.time_offset_s);
    dt.insert("load_period_s", d.load_period_s);
    dt.insert("load_phase_rad", d.load_phase_rad);
    dt.insert("mesh_amplitude_rel", d.mesh_amplitude_rel);
    dt.insert("resonance_shift_rel", d.resonance_shift_rel);
    dt.insert("warmup_tau_s", d.warmup_tau_s);
    dt.insert("initial_coldness", d.initial_coldness);
    dt.insert("cold_amplitude_rel", d.cold_amplitude_rel);
    dt.insert("cold_noise_rel", d.cold_noise_rel);
    dt.insert("cooldown_tau_s", d.cooldown_tau_s);
    dt.insert("pause_every_cycles", static_cast<std::int64_t>(d.pause_every_cycles));
    dt.insert("pause_s", d.pause_s);
    dt.insert("pause_start_s", to_array(m.pause_start_s));
    // Factors at each cycle start, and the state at the end: a following recording continues the drift
    // with time_offset_s = time_end_s and initial_coldness = coldness_at_end (scripts/drift_soak.sh).
    std::vector<double> gain;
    std::vector<double> cold;
    for (double t : m.cycle_start_s) {
      const DriftFactors f = model.at(t);
      gain.push_back(f.mesh_gain);
      cold.push_back(f.coldness);
    }
    dt.insert("mesh_gain_at_cycle_start", to_array(gain));
    dt.insert("coldness_at_cycle_start", to_array(cold));
    const DriftFactors end = model.at(m.duration_s);
    dt.insert("time_end_s", d.time_offset_s + m.duration_s);
    dt.insert("coldness_at_end", end.coldness);
    dt.insert("load_at_end", end.load);
    root.insert("drift", std::move(dt));
  }

  toml::table se;
  se.insert("fs_hz", s.sensor.fs_hz);
  se.insert("format", format_name(s.sensor.format));
  se.insert("range_ms2", s.sensor.range_ms2);
  se.insert("sensitivity_v_per_ms2", s.sensor.sensitivity_v_per_ms2);
  se.insert("scale", sensor_scale(s.sensor));
  se.insert("samples", static_cast<std::int64_t>(sum.samples));
  se.insert("clipped_samples", static_cast<std::int64_t>(sum.clipped_samples));
  root.insert("sensor", std::move(se));

  toml::table cb;
  cb.insert("iface", s.can.iface);
  cb.insert("speed_id", static_cast<std::int64_t>(s.can.speed_frame.id));
  cb.insert("period_s", s.can.period_s);
  cb.insert("clock_offset_s", s.can.clock_offset_s);
  cb.insert("clock_drift_ppm", s.can.clock_drift_ppm);
  cb.insert("delay_s", s.can.delay_s);
  cb.insert("jitter_s", s.can.jitter_s);
  cb.insert("speed_frames", static_cast<std::int64_t>(sum.speed_frames));
  cb.insert("other_frames", static_cast<std::int64_t>(can.size() - sum.speed_frames));
  root.insert("can", std::move(cb));
  return root;
}

}  // namespace

SimulatedSignals simulate_signals(const Scenario& s, std::uint64_t seed) {
  SimulatedSignals out;
  out.seed = seed;
  out.fs_nominal_hz = s.sensor.fs_hz;
  if (s.effects.empty()) {
    out.motion = build_motion(s, seed);
    out.vibration = synthesize_vibration(s, out.motion, seed);
    out.can = generate_can(s, out.motion, seed);
  } else {
    Scenario for_motion;
    Scenario for_can;
    timing_scenarios(s, for_motion, for_can);
    out.motion = build_motion(for_motion, seed);
    out.vibration = synthesize_vibration(for_motion, out.motion, seed);
    out.can = generate_can(for_can, out.motion, seed);
  }
  out.codes = quantize(s.sensor, out.vibration.accel_ms2, &out.clipped_samples);
  return out;
}

SimulationSummary simulate_to_directory(const Scenario& s, const std::filesystem::path& out_dir,
                                        std::optional<std::uint64_t> seed) {
  SimulationSummary sum;
  sum.seed = seed.value_or(s.seed);
  SimulatedSignals sig = simulate_signals(s, sum.seed);
  const MotionProfile& m = sig.motion;
  const Vibration& vib = sig.vibration;
  const std::uint64_t clipped = sig.clipped_samples + vib.effect_clipped_samples;
  std::vector<std::vector<float>> channels(1);
  channels[0] = std::move(sig.codes);
  const std::vector<SimCanFrame>& can = sig.can;

  sum.cycles = m.cycles;
  sum.duration_s = m.duration_s;
  sum.samples = m.angle_rad.size();
  sum.can_frames = can.size();
  for (const SimCanFrame& f : can) sum.speed_frames += f.is_speed ? 1U : 0U;
  sum.fs_hz = sig.fs_nominal_hz;
  for (const Plateau& p : m.plateaus) {
    if (p.cycle != 0) break;
    sum.plateau_speeds_rad_s.push_back(p.speed_rad_s);
    sum.plateau_durations_s.push_back(p.t_end_s - p.t_start_s);
  }
  sum.gmf_hz_at_first_plateau = m.plateaus.empty() ? 0.0 : gmf_hz(s.gearbox, m.plateaus.front().speed_rad_s);
  sum.ratio = reduction_ratio(s.gearbox);
  sum.harmonics_above_nyquist = vib.harmonics_above_nyquist;
  sum.clipped_samples = clipped;
  for (std::uint32_t c = 0; c < m.cycles; ++c) {
    double sev = 0.0;
    for (const FaultSpec& f : s.faults) sev = std::max(sev, fault_severity(f, c));
    sum.severity_per_cycle.push_back(sev);
  }

  std::error_code ec;
  std::filesystem::create_directories(out_dir, ec);
  if (ec) throw Error(out_dir.string() + ": cannot create the recording directory: " + ec.message());

  formats::RecordingMeta meta;
  meta.start_time_s = s.start_time_s;
  meta.scale = sensor_scale(s.sensor);
  meta.unit = "m/s^2";
  formats::write_wav(out_dir / meta.vibration_file, static_cast<std::uint32_t>(sig.fs_nominal_hz),
                     s.sensor.format, channels);

  std::vector<formats::CandumpRecord> records;
  records.reserve(can.size());
  for (const SimCanFrame& f : can) records.push_back(formats::CandumpRecord{f.frame, s.can.iface, 0});
  formats::write_candump(out_dir / meta.can_file, records);
  formats::write_recording_meta(out_dir, meta);

  const std::filesystem::path truth_path = out_dir / "truth.toml";
  std::ofstream out(truth_path, std::ios::binary | std::ios::trunc);
  if (!out) throw Error(truth_path.string() + ": cannot open for writing");
  out << "# Ground truth written by the ptda simulator: what was simulated (faults, severities per cycle,\n"
         "# plateaus, seeds, parameters). No analysis command reads this file; tests and reports may.\n";
  out << truth_table(s, m, vib, can, sum) << "\n";
  out.flush();
  if (!out) throw Error(truth_path.string() + ": write failed");
  return sum;
}

}  // namespace ptda::sim
