// simulate_to_directory: motion -> vibration -> sensor codes + CAN log -> a recording directory, plus
// truth.toml (what was simulated; analysis commands never read it).
#include <toml++/toml.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <functional>
#include <numbers>
#include <sstream>
#include <string>
#include <system_error>

#include "ptda/common/error.hpp"
#include "ptda/formats/candump.hpp"
#include "ptda/formats/recording.hpp"
#include "ptda/formats/wav.hpp"
#include "ptda/sim/simulator.hpp"
#include "ptda/sim/stream.hpp"
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

/// What truth.toml says about the synthesis besides the scenario and the motion.
struct TruthCounts {
  std::uint32_t harmonics_above_nyquist = 0;
  std::uint64_t impulses = 0;
  std::uint64_t effect_impacts = 0;
  std::uint64_t effect_clipped_samples = 0;
  std::uint64_t other_frames = 0;
  /// The cycle variation's factors; nullptr: drawn again while printing (draw_cycle_variation's
  /// streams, from the summary's seed), one cycle at a time.
  const CycleVariation* cycle_variation = nullptr;
};

/// An array of truth.toml written element by element (see write_truth): `path` leads to it (a table key,
/// "[]" for the first table of an array of tables, then the array's own key), elem(i) gives element i.
struct DeferredArray {
  std::vector<std::string> path;
  std::size_t size = 0;
  std::function<void(toml::array&, std::size_t)> push;
};

/// Arrays longer than this are left out of the in-memory table and streamed (per-cycle arrays).
constexpr std::size_t kDeferFrom = 128;
constexpr std::size_t kDeferChunk = 64;

std::string marker(std::size_t k) {
  return "ptda-deferred-array-" + std::to_string(k);
}

/// Puts array `key` into `t`: the whole array, or (`deferred` set and the array long) a marker string
/// standing for it, registered in `deferred`.
void insert_array(toml::table& t, const std::string& key, std::size_t size,
                  std::function<void(toml::array&, std::size_t)> push, std::vector<std::string> path,
                  std::vector<DeferredArray>* deferred) {
  if (deferred == nullptr || size < kDeferFrom) {
    toml::array a;
    for (std::size_t i = 0; i < size; ++i) push(a, i);
    t.insert(key, std::move(a));
    return;
  }
  path.push_back(key);
  t.insert(key, marker(deferred->size()));
  deferred->push_back(DeferredArray{std::move(path), size, std::move(push)});
}

std::function<void(toml::array&, std::size_t)> doubles(const std::vector<double>& v) {
  return [&v](toml::array& a, std::size_t i) { a.push_back(v[i]); };
}

/// f(start of cycle i) for i = 0, 1, 2, ... in order (a lazy plan is walked once, forwards).
std::function<void(toml::array&, std::size_t)> per_cycle_start(const MotionProfile& m,
                                                               std::function<double(double)> f) {
  if (!m.lazy) return [&m, f](toml::array& a, std::size_t i) { a.push_back(f(m.cycle_start_s[i])); };
  struct Walk {
    explicit Walk(std::shared_ptr<const LazyMotionPlan> p) : plan(std::move(p)), walker(*plan) {}
    std::shared_ptr<const LazyMotionPlan> plan;
    CycleWalker walker;
    PlanCycle cycle;
    std::size_t next = 0;
  };
  auto w = std::make_shared<Walk>(m.lazy);
  return [w, f](toml::array& a, std::size_t i) {
    while (w->next <= i) {
      if (!w->walker.next(w->cycle)) throw Error("truth.toml: fewer cycles than announced");
      ++w->next;
    }
    a.push_back(f(w->cycle.start_s));
  };
}

std::size_t cycle_count(const MotionProfile& m) {
  return m.lazy ? m.cycles : m.cycle_start_s.size();
}

bool has_plateaus(const MotionProfile& m) {
  return m.lazy ? !m.lazy->plan.plateaus.empty() : !m.plateaus.empty();
}

/// fn(plateau) for every plateau in order (stored or regenerated).
void for_each_plateau(const MotionProfile& m, const std::function<void(const Plateau&)>& fn) {
  if (!m.lazy) {
    for (const Plateau& p : m.plateaus) fn(p);
    return;
  }
  for_each_cycle(m, [&fn](const PlanCycle& c) {
    for (const Plateau& p : c.plateaus) fn(p);
    return true;
  });
}

toml::table plateau_table(const GearboxSpec& g, double start_time_s, const Plateau& p) {
  const double ratio = reduction_ratio(g);
  toml::table t;
  t.insert("cycle", static_cast<std::int64_t>(p.cycle));
  t.insert("t_start_s", p.t_start_s);
  t.insert("t_end_s", p.t_end_s);
  t.insert("duration_s", p.t_end_s - p.t_start_s);
  t.insert("unix_start_s", start_time_s + p.t_start_s);
  t.insert("speed_rad_s", p.speed_rad_s);
  t.insert("input_shaft_hz", ratio * std::fabs(p.speed_rad_s) / (2.0 * std::numbers::pi));
  t.insert("gmf_hz", gmf_hz(g, p.speed_rad_s));
  t.insert("dmf_hz", dmf_hz(g, p.speed_rad_s));
  t.insert("spur_hz", gmf_hz(g, p.speed_rad_s) / static_cast<double>(g.z_spur));
  return t;
}

/// truth.toml as a table. With `deferred`, the plateaus and the long per-cycle arrays are left out
/// (markers stand for the arrays) for write_truth to stream.
toml::table truth_table(const Scenario& s, const MotionProfile& m, const TruthCounts& vib,
                        const SimulationSummary& sum, std::vector<DeferredArray>* deferred) {
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
  insert_array(mo, "cycle_start_s", cycle_count(m), per_cycle_start(m, [](double t) { return t; }),
               {"motion"}, deferred);
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

  if (deferred == nullptr || !has_plateaus(m)) {  // streamed by write_truth (the file's last section)
    toml::array plateaus;
    for_each_plateau(m, [&](const Plateau& p) { plateaus.push_back(plateau_table(g, s.start_time_s, p)); });
    root.insert("plateau", std::move(plateaus));
  }

  toml::table vb;
  vb.insert("gmf_amplitudes", to_array(s.vibration.gmf_amplitudes));
  vb.insert("gmf_phases_rad", to_array(s.vibration.gmf_phases_rad));
  vb.insert("dmf_amplitudes", to_array(s.vibration.dmf_amplitudes));
  vb.insert("reference_speed_rad_s", s.vibration.reference_speed_rad_s);
  vb.insert("amplitude_speed_exponent", s.vibration.amplitude_speed_exponent);
  vb.insert("noise_rms", s.vibration.noise_rms);
  if (s.vibration.noise_tilt_db_per_decade != 0.0)
    vb.insert("noise_tilt_db_per_decade", s.vibration.noise_tilt_db_per_decade);
  if (!s.vibration.noise_shape_hz.empty()) {
    vb.insert("noise_shape_hz", to_array(s.vibration.noise_shape_hz));
    vb.insert("noise_shape_db", to_array(s.vibration.noise_shape_db));
  }
  if (!s.vibration.shaft_orders.empty()) {
    toml::array orders;
    for (int j : s.vibration.shaft_orders) orders.push_back(static_cast<std::int64_t>(j));
    vb.insert("shaft_orders", std::move(orders));
    vb.insert("shaft_order_amplitudes", to_array(s.vibration.shaft_order_amplitudes));
  }
  vb.insert("harmonics_above_nyquist", static_cast<std::int64_t>(vib.harmonics_above_nyquist));
  // The cycle variation only when on: without it truth.toml stays as it was before the feature.
  const VibrationSpec& vs = s.vibration;
  const std::size_t cv_cycles = std::max<std::uint32_t>(m.cycles, 1);
  if (vs.cycle_amplitude_jitter_rel > 0.0) {
    vb.insert("cycle_amplitude_jitter_rel", vs.cycle_amplitude_jitter_rel);
    // [cycle][k]: factor on gmf_amplitudes[k] in that cycle
    std::function<void(toml::array&, std::size_t)> rows;
    if (vib.cycle_variation != nullptr) {
      const CycleVariation& cv = *vib.cycle_variation;
      rows = [&cv](toml::array& a, std::size_t i) { a.push_back(to_array(cv.amplitude_factors[i])); };
    } else {  // the rows in order, as draw_cycle_variation draws them
      auto rng = std::make_shared<Rng>(sum.seed, kStreamCycleAmplitude);
      rows = [rng, &vs](toml::array& a, std::size_t) {
        std::vector<double> row(vs.gmf_amplitudes.size());
        for (double& f : row) f = std::exp(vs.cycle_amplitude_jitter_rel * rng->normal());
        a.push_back(to_array(row));
      };
    }
    insert_array(vb, "cycle_amplitude_factors", cv_cycles, std::move(rows), {"vibration"}, deferred);
  }
  if (vs.cycle_noise_jitter_rel > 0.0) {
    vb.insert("cycle_noise_jitter_rel", vs.cycle_noise_jitter_rel);
    std::function<void(toml::array&, std::size_t)> factors;
    if (vib.cycle_variation != nullptr) {
      factors = doubles(vib.cycle_variation->noise_factors);
    } else {
      auto rng = std::make_shared<Rng>(sum.seed, kStreamCycleNoise);
      factors = [rng, &vs](toml::array& a, std::size_t) {
        a.push_back(std::exp(vs.cycle_noise_jitter_rel * rng->normal()));
      };
    }
    insert_array(vb, "cycle_noise_factors", cv_cycles, std::move(factors), {"vibration"}, deferred);
  }
  root.insert("vibration", std::move(vb));

  toml::array faults;
  for (const FaultSpec& f : s.faults) {
    toml::table t;
    t.insert("kind", f.kind == FaultKind::kSpurTooth ? "spur_tooth" : "distributed_wear");
    t.insert("severity", f.severity);
    t.insert("onset_cycle", static_cast<std::int64_t>(f.onset_cycle));
    t.insert("ramp_cycles", static_cast<std::int64_t>(f.ramp_cycles));
    // Only the first fault's array can be streamed (its table is the first of [[fault]]).
    insert_array(
        t, "severity_per_cycle", m.cycles,
        [&f](toml::array& a, std::size_t c) {
          a.push_back(fault_severity(f, static_cast<std::uint32_t>(c)));
        },
        {"fault", "[]"}, faults.empty() ? deferred : nullptr);
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
    for (std::size_t i = 0; i < shown_param_count(e) && i < e.params.size(); ++i)
      t.insert(info.params[i].name, e.params[i]);
    effects.push_back(std::move(t));
  }
  if (!s.effects.empty()) {  // without effects truth.toml stays as it was before the effects library
    root.insert("effect", std::move(effects));
    root.insert("effect_impacts", static_cast<std::int64_t>(vib.effect_impacts));
    root.insert("effect_clipped_samples", static_cast<std::int64_t>(vib.effect_clipped_samples));
  }
  root.insert("impulses", static_cast<std::int64_t>(vib.impulses));
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
    insert_array(dt, "pause_start_s", m.pause_start_s.size(), doubles(m.pause_start_s), {"drift"}, deferred);
    // Factors at each cycle start, and the state at the end: a following recording continues the drift
    // with time_offset_s = time_end_s and initial_coldness = coldness_at_end (scripts/drift_soak.sh).
    // (The model is copied into the functions: the deferred arrays are written after this returns.)
    insert_array(dt, "mesh_gain_at_cycle_start", cycle_count(m),
                 per_cycle_start(m, [model](double t) { return model.at(t).mesh_gain; }), {"drift"},
                 deferred);
    insert_array(dt, "coldness_at_cycle_start", cycle_count(m),
                 per_cycle_start(m, [model](double t) { return model.at(t).coldness; }), {"drift"}, deferred);
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
  cb.insert("other_frames", static_cast<std::int64_t>(vib.other_frames));
  root.insert("can", std::move(cb));
  return root;
}

/// Text of `key = [...]` printed by toml++ in the context of `path` for elements [i0, i1) (at least 24,
/// so that toml++ prints it one element per line): returns the text after " = ".
std::string array_text(const DeferredArray& d, std::size_t i0, std::size_t i1) {
  toml::array chunk;
  for (std::size_t i = i0; i < i1; ++i) d.push(chunk, i);
  toml::table inner;
  inner.insert(d.path.back(), std::move(chunk));
  // Wrap from the inside out: a table key holds a table, "[]" an array of one table.
  for (std::size_t k = d.path.size() - 1; k-- > 0;) {
    if (d.path[k] == "[]") continue;
    toml::table outer;
    if (k + 1 < d.path.size() - 1 && d.path[k + 1] == "[]") {
      toml::array aot;
      aot.push_back(std::move(inner));
      outer.insert(d.path[k], std::move(aot));
    } else {
      outer.insert(d.path[k], std::move(inner));
    }
    inner = std::move(outer);
  }
  std::ostringstream ss;
  ss << inner;
  const std::string text = ss.str();
  const std::string head = d.path.back() + " = ";
  const std::size_t at = text.find(head);
  if (at == std::string::npos) throw Error("truth.toml: cannot format " + d.path.back());
  return text.substr(at + head.size());
}

/// Writes a long array as toml++ prints it whole: "[", the elements one per line (chunk by chunk, each
/// printed by toml++ in the same context), "]".
void write_deferred(std::ostream& out, const DeferredArray& d) {
  std::string closing;
  for (std::size_t i0 = 0; i0 < d.size;) {
    std::size_t i1 = std::min(d.size, i0 + kDeferChunk);
    if (d.size - i1 < kDeferChunk) i1 = d.size;  // the last chunk takes the rest (each chunk >= 64 elements)
    const std::string text = array_text(d, i0, i1);  // "[\n    e,\n    e\n]"
    const std::size_t last_nl = text.rfind('\n');
    if (text.empty() || text.front() != '[' || last_nl == std::string::npos)
      throw Error("truth.toml: unexpected format of " + d.path.back());
    if (i0 > 0)
      out << ',';
    else
      out << '[';
    out << std::string_view(text).substr(1, last_nl - 1);
    closing = text.substr(last_nl);
    i0 = i1;
  }
  out << closing;
}

/// truth.toml: the table without the plateaus and the long per-cycle arrays, printed by toml++, with the
/// arrays streamed in place of their markers and the plateaus (the last section) one table at a time:
/// the same bytes as printing the whole table, without holding it (it grows with the recording).
void write_truth(std::ostream& out, const Scenario& s, const MotionProfile& m, const TruthCounts& counts,
                 const SimulationSummary& sum) {
  std::vector<DeferredArray> deferred;
  const toml::table root = truth_table(s, m, counts, sum, &deferred);
  std::ostringstream ss;
  ss << root;
  const std::string text = ss.str();
  std::vector<std::pair<std::size_t, std::size_t>> at;  // position in text, deferred index
  for (std::size_t k = 0; k < deferred.size(); ++k) {
    const std::size_t pos = text.find("'" + marker(k) + "'");
    if (pos == std::string::npos) throw Error("truth.toml: lost " + deferred[k].path.back());
    at.emplace_back(pos, k);
  }
  std::sort(at.begin(), at.end());
  std::size_t from = 0;
  for (const auto& [pos, k] : at) {
    out << std::string_view(text).substr(from, pos - from);
    write_deferred(out, deferred[k]);
    from = pos + marker(k).size() + 2;
  }
  out << std::string_view(text).substr(from);
  if (has_plateaus(m)) {
    for_each_plateau(m, [&](const Plateau& p) {
      toml::table one;
      toml::array aot;
      aot.push_back(plateau_table(s.gearbox, s.start_time_s, p));
      one.insert("plateau", std::move(aot));
      out << "\n\n" << one;
    });
  }
}

void fill_summary(const Scenario& s, const MotionProfile& m, SimulationSummary& sum) {
  sum.cycles = m.cycles;
  sum.duration_s = m.duration_s;
  sum.samples = motion_samples(m);
  sum.fs_hz = s.sensor.fs_hz;
  std::vector<Plateau> first;  // the first plateau and those of cycle 0
  for_each_plateau(m, [&first](const Plateau& p) {
    if (first.empty() || p.cycle == 0) first.push_back(p);
  });
  for (const Plateau& p : first) {
    if (p.cycle != 0) break;
    sum.plateau_speeds_rad_s.push_back(p.speed_rad_s);
    sum.plateau_durations_s.push_back(p.t_end_s - p.t_start_s);
  }
  sum.gmf_hz_at_first_plateau = first.empty() ? 0.0 : gmf_hz(s.gearbox, first.front().speed_rad_s);
  sum.ratio = reduction_ratio(s.gearbox);
  sum.severity_per_cycle.reserve(m.cycles);
  for (std::uint32_t c = 0; c < m.cycles; ++c) {
    double sev = 0.0;
    for (const FaultSpec& f : s.faults) sev = std::max(sev, fault_severity(f, c));
    sum.severity_per_cycle.push_back(sev);
  }
}

}  // namespace

std::string truth_toml_whole(const Scenario& s, const MotionProfile& m, const Vibration& vib,
                             std::uint64_t other_frames, const SimulationSummary& sum) {
  TruthCounts counts;
  counts.harmonics_above_nyquist = vib.harmonics_above_nyquist;
  counts.impulses = vib.impulse_times_s.size();
  counts.effect_impacts = vib.effect_impacts;
  counts.effect_clipped_samples = vib.effect_clipped_samples;
  counts.other_frames = other_frames;
  counts.cycle_variation = &vib.cycle_variation;
  std::ostringstream ss;
  ss << truth_table(s, m, counts, sum, nullptr);
  return ss.str();
}

std::string truth_toml_streamed(const Scenario& s, const MotionProfile& m, const Vibration& vib,
                                std::uint64_t other_frames, const SimulationSummary& sum) {
  TruthCounts counts;
  counts.harmonics_above_nyquist = vib.harmonics_above_nyquist;
  counts.impulses = vib.impulse_times_s.size();
  counts.effect_impacts = vib.effect_impacts;
  counts.effect_clipped_samples = vib.effect_clipped_samples;
  counts.other_frames = other_frames;
  const CycleVariation& cv = vib.cycle_variation;
  // Empty factors: drawn again while printing, as simulate_to_directory does.
  counts.cycle_variation = cv.amplitude_factors.empty() && cv.noise_factors.empty() ? nullptr : &cv;
  std::ostringstream ss;
  write_truth(ss, s, m, counts, sum);
  return ss.str();
}

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
  return simulate_to_directory(s, out_dir, seed, SimulateOptions{});
}

SimulationSummary simulate_to_directory(const Scenario& s, const std::filesystem::path& out_dir,
                                        std::optional<std::uint64_t> seed, const SimulateOptions& options) {
  SimulationSummary sum;
  sum.seed = seed.value_or(s.seed);
  // Sample-clock and CAN-latency effects act on copies of the scenario (timing_scenarios).
  Scenario for_motion;
  Scenario for_can;
  if (!s.effects.empty()) timing_scenarios(s, for_motion, for_can);
  const Scenario& sm = s.effects.empty() ? s : for_motion;
  const Scenario& sc = s.effects.empty() ? s : for_can;
  const MotionProfile m = build_motion_lazy(sm, sum.seed);
  fill_summary(s, m, sum);

  std::error_code ec;
  std::filesystem::create_directories(out_dir, ec);
  if (ec) throw Error(out_dir.string() + ": cannot create the recording directory: " + ec.message());

  formats::RecordingMeta meta;
  meta.start_time_s = s.start_time_s;
  meta.scale = sensor_scale(s.sensor);
  meta.unit = "m/s^2";

  // Vibration: synthesised, quantised and written block by block.
  VibrationStream vib(sm, m, sum.seed);
  {
    const std::size_t block = std::max<std::size_t>(options.block_samples, 1);
    std::vector<double> accel(block);
    std::vector<float> codes(block);
    formats::WavWriter wav(out_dir / meta.vibration_file, static_cast<std::uint32_t>(s.sensor.fs_hz),
                           s.sensor.format, 1, vib.samples());
    std::uint64_t clipped = 0;
    for (;;) {
      const std::size_t n = vib.next(accel);
      if (n == 0) break;
      quantize_block(s.sensor, std::span<const double>(accel.data(), n), std::span<float>(codes.data(), n),
                     &clipped);
      wav.write(std::span<const float>(codes.data(), n));
    }
    wav.close();
    sum.clipped_samples = clipped + vib.effect_clipped_samples();
  }
  sum.harmonics_above_nyquist = vib.harmonics_above_nyquist();

  // CAN log: frame by frame.
  {
    CanStream can(sc, m, sum.seed, options.can_window_frames);
    formats::CandumpWriter log(out_dir / meta.can_file);
    SimCanFrame f;
    while (can.next(f)) {
      log.write(formats::CandumpRecord{f.frame, s.can.iface, 0});
      ++sum.can_frames;
      sum.speed_frames += f.is_speed ? 1U : 0U;
    }
    log.close();
  }
  formats::write_recording_meta(out_dir, meta);

  TruthCounts counts;
  counts.harmonics_above_nyquist = vib.harmonics_above_nyquist();
  counts.impulses = vib.impulses();
  counts.effect_impacts = vib.effect_impacts();
  counts.effect_clipped_samples = vib.effect_clipped_samples();
  counts.other_frames = sum.can_frames - sum.speed_frames;
  counts.cycle_variation = nullptr;  // drawn again while printing
  const std::filesystem::path truth_path = out_dir / "truth.toml";
  std::ofstream out(truth_path, std::ios::binary | std::ios::trunc);
  if (!out) throw Error(truth_path.string() + ": cannot open for writing");
  out << "# Ground truth written by the ptda simulator: what was simulated (faults, severities per cycle,\n"
         "# plateaus, seeds, parameters). No analysis command reads this file; tests and reports may.\n";
  write_truth(out, s, m, counts, sum);
  out << "\n";
  out.flush();
  if (!out) throw Error(truth_path.string() + ": write failed");
  return sum;
}

}  // namespace ptda::sim
