// Scenario TOML parsing. Every key is checked: unknown keys, wrong types and impossible values are
// errors naming file:line:column, so a typo never silently falls back to a default.
#include <toml++/toml.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <initializer_list>
#include <limits>
#include <set>
#include <sstream>
#include <string>
#include <utility>

#include "ptda/common/error.hpp"
#include "ptda/common/file_check.hpp"
#include "ptda/config/pipeline_config.hpp"
#include "ptda/sim/noise_tilt.hpp"
#include "ptda/sim/simulator.hpp"
#include "sim_internal.hpp"

namespace ptda::sim {
namespace {

class Reader {
 public:
  Reader(const toml::table& t, std::string path, const std::string& source)
      : t_(t), path_(std::move(path)), source_(source) {}

  [[nodiscard]] Error error_at(const toml::source_region& r, const std::string& what) const {
    return Error(source_, static_cast<long>(r.begin.line), static_cast<long>(r.begin.column), what);
  }
  [[nodiscard]] Error error(const std::string& key, const std::string& what) const {
    const toml::node* n = t_.get(key);
    return error_at(n != nullptr ? n->source() : t_.source(), full(key) + ": " + what);
  }
  [[nodiscard]] std::string full(const std::string& key) const {
    return path_.empty() ? key : path_ + "." + key;
  }
  [[nodiscard]] bool has(const std::string& key) const { return t_.contains(key); }

  const toml::node* node(const std::string& key) {
    seen_.insert(key);
    return t_.get(key);
  }

  double number(const std::string& key, double def) {
    const toml::node* n = node(key);
    if (n == nullptr) return def;
    if (auto v = n->value<double>(); v && n->is_number()) return check_finite(key, *v);
    throw error_at(n->source(), full(key) + ": expected a number");
  }
  double number_required(const std::string& key) {
    if (!has(key)) throw error_at(t_.source(), "[" + path_ + "] needs " + key);
    return number(key, 0.0);
  }
  std::int64_t integer(const std::string& key, std::int64_t def, std::int64_t lo, std::int64_t hi) {
    const toml::node* n = node(key);
    if (n == nullptr) return def;
    if (!n->is_integer()) throw error_at(n->source(), full(key) + ": expected an integer");
    const std::int64_t v = n->as_integer()->get();
    if (v < lo || v > hi) {
      throw error_at(n->source(), full(key) + ": " + std::to_string(v) + " is outside " + std::to_string(lo) +
                                      ".." + std::to_string(hi));
    }
    return v;
  }
  std::uint64_t seed(const std::string& key, std::uint64_t def) {
    const toml::node* n = node(key);
    if (n == nullptr) return def;
    if (!n->is_integer() || n->as_integer()->get() < 0) {
      throw error_at(n->source(), full(key) + ": expected a non-negative integer");
    }
    return static_cast<std::uint64_t>(n->as_integer()->get());
  }
  bool boolean(const std::string& key, bool def) {
    const toml::node* n = node(key);
    if (n == nullptr) return def;
    if (!n->is_boolean()) throw error_at(n->source(), full(key) + ": expected true or false");
    return n->as_boolean()->get();
  }
  std::string string(const std::string& key, const std::string& def) {
    const toml::node* n = node(key);
    if (n == nullptr) return def;
    if (!n->is_string()) throw error_at(n->source(), full(key) + ": expected a string");
    if (const std::string problem = string_value_problem(n->as_string()->get()); !problem.empty())
      throw error_at(n->source(), full(key) + ": " + problem);
    return n->as_string()->get();
  }
  std::vector<double> numbers(const std::string& key) {
    const toml::node* n = node(key);
    if (n == nullptr) return {};
    const toml::array* a = n->as_array();
    if (a == nullptr) throw error_at(n->source(), full(key) + ": expected an array of numbers");
    std::vector<double> out;
    for (std::size_t i = 0; i < a->size(); ++i) {
      const toml::node& e = *a->get(i);
      auto v = e.value<double>();
      if (!e.is_number() || !v) {
        throw error_at(e.source(), full(key) + "[" + std::to_string(i) + "]: expected a number");
      }
      out.push_back(check_finite(key, *v));
    }
    return out;
  }
  const toml::table* table(const std::string& key) {
    const toml::node* n = node(key);
    if (n == nullptr) return nullptr;
    if (!n->is_table()) throw error_at(n->source(), full(key) + ": expected a table [" + full(key) + "]");
    return n->as_table();
  }

  /// Unknown keys are errors (a misspelt key must not silently keep its default). Checked first, so
  /// the typo is reported rather than what its absence causes.
  void known_keys(std::initializer_list<const char*> keys) const {
    for (auto&& [k, v] : t_) {
      const std::string name(k.str());
      bool found = false;
      for (const char* known : keys) found = found || name == known;
      if (!found) throw error_at(k.source(), "unknown key '" + full(name) + "'");
    }
  }
  /// Keys valid in the section but not read for this kind (e.g. shaft_speed_hz with kind = "lspb").
  void finish() const {
    for (auto&& [k, v] : t_) {
      const std::string name(k.str());
      if (seen_.count(name) == 0) {
        throw error_at(k.source(), "key '" + full(name) + "' does not apply here (check `kind`)");
      }
    }
  }

  [[nodiscard]] const toml::table& raw() const { return t_; }
  [[nodiscard]] const std::string& source() const { return source_; }

 private:
  double check_finite(const std::string& key, double v) const {
    if (!std::isfinite(v)) throw error(key, "must be finite");
    return v;
  }

  const toml::table& t_;
  std::string path_;
  const std::string& source_;
  std::set<std::string> seen_;
};

void require(bool ok, const Reader& r, const std::string& key, const std::string& what) {
  if (!ok) throw r.error(key, what);
}

void parse_motion(Reader& r, MotionSpec& m) {
  r.known_keys({"kind", "cycles", "shaft_speed_hz", "duration_s", "via_points_rad", "segment_durations_s",
                "segment_speeds_rad_s", "max_speed_rad_s", "accel_rad_s2", "dwell_s", "start_jitter_s",
                "lead_in_s"});
  const std::string kind = r.string("kind", "lspb");
  if (kind == "lspb") {
    m.kind = MotionKind::kLspb;
  } else if (kind == "constant") {
    m.kind = MotionKind::kConstant;
  } else {
    throw r.error("kind", "'" + kind + "' is not a motion kind (lspb, constant)");
  }
  m.cycles = static_cast<std::uint32_t>(r.integer("cycles", m.cycles, 1, 100000));
  if (m.kind == MotionKind::kConstant) {
    m.shaft_speed_hz = r.number_required("shaft_speed_hz");
    m.duration_s = r.number_required("duration_s");
    require(m.shaft_speed_hz != 0.0 && std::fabs(m.shaft_speed_hz) < 1000.0, r, "shaft_speed_hz",
            "must be non-zero and below 1000 Hz");
    require(m.duration_s > 0.0 && m.duration_s <= 3600.0, r, "duration_s", "must be in (0, 3600] s");
    r.finish();
    return;
  }
  m.via_points_rad = r.numbers("via_points_rad");
  require(m.via_points_rad.size() >= 2, r, "via_points_rad", "needs at least 2 via points");
  m.segment_durations_s = r.numbers("segment_durations_s");
  m.segment_speeds_rad_s = r.numbers("segment_speeds_rad_s");
  m.max_speed_rad_s = r.number("max_speed_rad_s", 0.0);
  const int timing = static_cast<int>(!m.segment_durations_s.empty()) +
                     static_cast<int>(!m.segment_speeds_rad_s.empty()) +
                     static_cast<int>(r.has("max_speed_rad_s"));
  if (timing != 1) {
    throw r.error_at(
        r.raw().source(),
        "[motion] needs exactly one of segment_durations_s, segment_speeds_rad_s, max_speed_rad_s");
  }
  const std::size_t segs = m.via_points_rad.size() - 1;
  if (!m.segment_durations_s.empty()) {
    require(m.segment_durations_s.size() == segs, r, "segment_durations_s",
            "needs one duration per segment (" + std::to_string(segs) + ")");
    for (double d : m.segment_durations_s)
      require(d > 0.0, r, "segment_durations_s", "durations must be > 0");
  }
  if (!m.segment_speeds_rad_s.empty()) {
    require(m.segment_speeds_rad_s.size() == segs, r, "segment_speeds_rad_s",
            "needs one speed per segment (" + std::to_string(segs) + ")");
    for (double v : m.segment_speeds_rad_s) require(v > 0.0, r, "segment_speeds_rad_s", "speeds must be > 0");
  }
  if (r.has("max_speed_rad_s")) require(m.max_speed_rad_s > 0.0, r, "max_speed_rad_s", "must be > 0");
  m.accel_rad_s2 = r.number("accel_rad_s2", m.accel_rad_s2);
  require(m.accel_rad_s2 > 0.0, r, "accel_rad_s2", "must be > 0");
  m.dwell_s = r.number("dwell_s", m.dwell_s);
  require(m.dwell_s >= 0.0, r, "dwell_s", "must be >= 0");
  m.start_jitter_s = r.number("start_jitter_s", m.start_jitter_s);
  require(m.start_jitter_s >= 0.0, r, "start_jitter_s", "must be >= 0");
  m.lead_in_s = r.number("lead_in_s", m.lead_in_s);
  require(m.lead_in_s >= 0.0, r, "lead_in_s", "must be >= 0");
  // Infeasible timing (segment too short for the acceleration) is reported at the via points.
  try {
    (void)plan_cycle(m);
  } catch (const Error& e) {
    throw r.error("via_points_rad", e.what());
  }
  r.finish();
}

void parse_gearbox(Reader& r, GearboxSpec& g) {
  r.known_keys({"kind", "z_in", "z_spur", "z_pin", "z_pinion", "z_gear"});
  const std::string kind = r.string("kind", "cycloidal");
  if (kind == "cycloidal") {
    g.kind = GearboxKind::kCycloidal;
    g.z_in = static_cast<std::uint32_t>(r.integer("z_in", g.z_in, 1, 100000));
    g.z_spur = static_cast<std::uint32_t>(r.integer("z_spur", g.z_spur, 1, 100000));
    g.z_pin = static_cast<std::uint32_t>(r.integer("z_pin", g.z_pin, 1, 100000));
  } else if (kind == "parallel") {
    g.kind = GearboxKind::kParallel;
    if (!r.has("z_pinion") || !r.has("z_gear")) {
      throw r.error_at(r.raw().source(), "[gearbox] kind = \"parallel\" needs z_pinion and z_gear");
    }
    g.z_in = static_cast<std::uint32_t>(r.integer("z_pinion", 0, 1, 100000));
    g.z_spur = static_cast<std::uint32_t>(r.integer("z_gear", 0, 1, 100000));
    g.z_pin = 0;
  } else {
    throw r.error("kind", "'" + kind + "' is not a gearbox kind (cycloidal, parallel)");
  }
  r.finish();
}

void parse_vibration(Reader& r, VibrationSpec& v, const GearboxSpec& g) {
  r.known_keys({"gmf_amplitudes", "gmf_phases_rad", "reference_speed_rad_s", "amplitude_speed_exponent",
                "dmf_amplitudes", "noise_rms", "noise_tilt_db_per_decade", "noise_shape_hz", "noise_shape_db",
                "cycle_amplitude_jitter_rel", "cycle_noise_jitter_rel", "shaft_orders",
                "shaft_order_amplitudes"});
  v.gmf_amplitudes = r.numbers("gmf_amplitudes");
  for (double a : v.gmf_amplitudes) require(a >= 0.0, r, "gmf_amplitudes", "amplitudes must be >= 0");
  v.gmf_phases_rad = r.numbers("gmf_phases_rad");
  require(v.gmf_phases_rad.empty() || v.gmf_phases_rad.size() == v.gmf_amplitudes.size(), r, "gmf_phases_rad",
          "needs one phase per entry of gmf_amplitudes");
  v.reference_speed_rad_s = r.number("reference_speed_rad_s", v.reference_speed_rad_s);
  require(v.reference_speed_rad_s > 0.0, r, "reference_speed_rad_s", "must be > 0");
  v.amplitude_speed_exponent = r.number("amplitude_speed_exponent", v.amplitude_speed_exponent);
  require(v.amplitude_speed_exponent >= 0.0 && v.amplitude_speed_exponent <= 4.0, r,
          "amplitude_speed_exponent", "must be in [0, 4]");
  v.dmf_amplitudes = r.numbers("dmf_amplitudes");
  for (double a : v.dmf_amplitudes) require(a >= 0.0, r, "dmf_amplitudes", "amplitudes must be >= 0");
  require(v.dmf_amplitudes.empty() || g.kind == GearboxKind::kCycloidal, r, "dmf_amplitudes",
          "only a cycloidal gearbox has a disk mesh");
  v.noise_rms = r.number("noise_rms", v.noise_rms);
  require(v.noise_rms >= 0.0, r, "noise_rms", "must be >= 0");
  v.noise_tilt_db_per_decade = r.number("noise_tilt_db_per_decade", v.noise_tilt_db_per_decade);
  require(std::fabs(v.noise_tilt_db_per_decade) <= TiltedNoise::kMaxTiltDbPerDecade, r,
          "noise_tilt_db_per_decade", "must be in [-18, 18] dB per decade");
  v.noise_shape_hz = r.numbers("noise_shape_hz");
  v.noise_shape_db = r.numbers("noise_shape_db");
  require(v.noise_shape_hz.size() == v.noise_shape_db.size(), r,
          v.noise_shape_hz.empty() ? "noise_shape_db" : "noise_shape_hz",
          "needs one level in noise_shape_db per entry of noise_shape_hz");
  for (std::size_t i = 0; i < v.noise_shape_hz.size(); ++i) {
    require(v.noise_shape_hz[i] > 0.0 && (i == 0 || v.noise_shape_hz[i] > v.noise_shape_hz[i - 1]), r,
            "noise_shape_hz", "frequencies must be > 0 and increasing (entry " + std::to_string(i + 1) + ")");
    require(std::fabs(v.noise_shape_db[i]) <= 60.0, r, "noise_shape_db",
            "levels must be in [-60, 60] dB (entry " + std::to_string(i + 1) + ")");
  }
  {
    const std::vector<double> orders = r.numbers("shaft_orders");
    v.shaft_order_amplitudes = r.numbers("shaft_order_amplitudes");
    require(orders.size() == v.shaft_order_amplitudes.size(), r,
            orders.empty() ? "shaft_order_amplitudes" : "shaft_orders",
            "needs one amplitude in shaft_order_amplitudes per entry of shaft_orders");
    v.shaft_orders.clear();
    for (double o : orders) {
      require(o >= 1.0 && o <= 10000.0 && o == std::floor(o), r, "shaft_orders",
              "orders must be whole numbers in [1, 10000]");
      const int j = static_cast<int>(o);
      require(g.z_in == 0 || j % static_cast<int>(g.z_in) != 0, r, "shaft_orders",
              "order " + std::to_string(j) + " is GMF order " +
                  std::to_string(g.z_in == 0 ? 0 : j / static_cast<int>(g.z_in)) +
                  " (a multiple of z_in): list it in gmf_amplitudes");
      require(std::find(v.shaft_orders.begin(), v.shaft_orders.end(), j) == v.shaft_orders.end(), r,
              "shaft_orders", "order " + std::to_string(j) + " is listed twice");
      v.shaft_orders.push_back(j);
    }
    for (double a : v.shaft_order_amplitudes)
      require(a >= 0.0, r, "shaft_order_amplitudes", "amplitudes must be >= 0");
  }
  v.cycle_amplitude_jitter_rel = r.number("cycle_amplitude_jitter_rel", v.cycle_amplitude_jitter_rel);
  require(v.cycle_amplitude_jitter_rel >= 0.0 && v.cycle_amplitude_jitter_rel <= 1.0, r,
          "cycle_amplitude_jitter_rel", "must be in [0, 1] (a relative spread; 0.03 is 3 %)");
  v.cycle_noise_jitter_rel = r.number("cycle_noise_jitter_rel", v.cycle_noise_jitter_rel);
  require(v.cycle_noise_jitter_rel >= 0.0 && v.cycle_noise_jitter_rel <= 1.0, r, "cycle_noise_jitter_rel",
          "must be in [0, 1] (a relative spread; 0.03 is 3 %)");
  r.finish();
}

// [drift] (sim/include/ptda/sim/drift.hpp). A key that needs another one (e.g. mesh_amplitude_rel without
// load_period_s) is an error rather than a drift that silently does nothing.
void parse_drift(Reader& r, DriftSpec& d, const MotionSpec& m) {
  r.known_keys({"time_offset_s", "load_period_s", "load_phase_rad", "mesh_amplitude_rel",
                "resonance_shift_rel", "warmup_tau_s", "initial_coldness", "cold_amplitude_rel",
                "cold_noise_rel", "cooldown_tau_s", "pause_every_cycles", "pause_s"});
  d.time_offset_s = r.number("time_offset_s", d.time_offset_s);
  require(d.time_offset_s >= 0.0 && d.time_offset_s <= 1.0e9, r, "time_offset_s", "must be in [0, 1e9] s");
  d.load_period_s = r.number("load_period_s", d.load_period_s);
  require(d.load_period_s >= 0.0, r, "load_period_s", "must be >= 0 (0 = no load cycle)");
  d.load_phase_rad = r.number("load_phase_rad", d.load_phase_rad);
  d.mesh_amplitude_rel = r.number("mesh_amplitude_rel", d.mesh_amplitude_rel);
  require(d.mesh_amplitude_rel >= 0.0 && d.mesh_amplitude_rel <= 0.9, r, "mesh_amplitude_rel",
          "must be in [0, 0.9] (0.3 = +-30 %)");
  d.resonance_shift_rel = r.number("resonance_shift_rel", d.resonance_shift_rel);
  require(d.resonance_shift_rel >= 0.0 && d.resonance_shift_rel <= 0.5, r, "resonance_shift_rel",
          "must be in [0, 0.5]");
  const std::pair<const char*, bool> load_keys[] = {{"mesh_amplitude_rel", d.mesh_amplitude_rel != 0.0},
                                                    {"resonance_shift_rel", d.resonance_shift_rel != 0.0},
                                                    {"load_phase_rad", d.load_phase_rad != 0.0}};
  for (const auto& [key, set] : load_keys) {
    require(!set || d.load_period_s > 0.0, r, key, "needs load_period_s > 0 (the load cycle)");
  }
  d.warmup_tau_s = r.number("warmup_tau_s", d.warmup_tau_s);
  require(d.warmup_tau_s >= 0.0, r, "warmup_tau_s", "must be >= 0 (0 = no warm-up)");
  d.initial_coldness = r.number("initial_coldness", d.initial_coldness);
  require(d.initial_coldness >= 0.0 && d.initial_coldness <= 1.0, r, "initial_coldness",
          "must be in [0, 1] (1 = cold start, 0 = warm)");
  d.cold_amplitude_rel = r.number("cold_amplitude_rel", d.cold_amplitude_rel);
  require(d.cold_amplitude_rel >= -0.9 && d.cold_amplitude_rel <= 2.0, r, "cold_amplitude_rel",
          "must be in [-0.9, 2]");
  d.cold_noise_rel = r.number("cold_noise_rel", d.cold_noise_rel);
  require(d.cold_noise_rel >= -0.9 && d.cold_noise_rel <= 5.0, r, "cold_noise_rel", "must be in [-0.9, 5]");
  d.cooldown_tau_s = r.number("cooldown_tau_s", d.cooldown_tau_s);
  require(d.cooldown_tau_s >= 0.0, r, "cooldown_tau_s", "must be >= 0 (0 = no cooling in pauses)");
  const std::pair<const char*, bool> warm_keys[] = {{"initial_coldness", d.initial_coldness != 1.0},
                                                    {"cold_amplitude_rel", d.cold_amplitude_rel != 0.0},
                                                    {"cold_noise_rel", d.cold_noise_rel != 0.0},
                                                    {"cooldown_tau_s", d.cooldown_tau_s != 0.0}};
  for (const auto& [key, set] : warm_keys) {
    require(!set || d.warmup_tau_s > 0.0, r, key, "needs warmup_tau_s > 0 (the warm-up)");
  }
  d.pause_every_cycles = static_cast<std::uint32_t>(r.integer("pause_every_cycles", 0, 0, 1000000));
  d.pause_s = r.number("pause_s", d.pause_s);
  require(d.pause_s >= 0.0 && d.pause_s <= 86400.0, r, "pause_s", "must be in [0, 86400] s");
  require((d.pause_every_cycles == 0) == (d.pause_s == 0.0), r,
          r.has("pause_s") ? "pause_s" : "pause_every_cycles",
          "pause_every_cycles and pause_s go together (both > 0 for program pauses)");
  require(d.pause_every_cycles == 0 || m.kind == MotionKind::kLspb, r, "pause_every_cycles",
          "program pauses need [motion] kind = \"lspb\"");
  r.finish();
}

void parse_fault(Reader& r, FaultSpec& f, std::uint32_t cycles) {
  r.known_keys({"kind", "severity", "onset_cycle", "ramp_cycles", "impulse_amplitude_ms2", "resonance_hz",
                "damping_ratio", "am_depth", "spur_phase_rad", "harmonic_gain", "noise_gain"});
  const std::string kind = r.string("kind", "");
  if (kind == "spur_tooth") {
    f.kind = FaultKind::kSpurTooth;
  } else if (kind == "distributed_wear") {
    f.kind = FaultKind::kDistributedWear;
  } else {
    throw r.error_at(r.has("kind") ? r.raw().get("kind")->source() : r.raw().source(),
                     "[[fault]] kind must be \"spur_tooth\" or \"distributed_wear\"");
  }
  f.severity = r.number("severity", f.severity);
  require(f.severity >= 0.0 && f.severity <= 1.0, r, "severity", "must be in [0, 1]");
  f.onset_cycle = static_cast<std::uint32_t>(r.integer("onset_cycle", 0, 0, 100000));
  require(f.onset_cycle < cycles, r, "onset_cycle",
          "is beyond the last cycle (" + std::to_string(cycles - 1) + ", 0-based)");
  f.ramp_cycles = static_cast<std::uint32_t>(r.integer("ramp_cycles", 0, 0, 100000));
  if (f.kind == FaultKind::kSpurTooth) {
    f.impulse_amplitude_ms2 = r.number("impulse_amplitude_ms2", f.impulse_amplitude_ms2);
    require(f.impulse_amplitude_ms2 >= 0.0, r, "impulse_amplitude_ms2", "must be >= 0");
    f.resonance_hz = r.number("resonance_hz", f.resonance_hz);
    require(f.resonance_hz > 0.0, r, "resonance_hz", "must be > 0");
    f.damping_ratio = r.number("damping_ratio", f.damping_ratio);
    require(f.damping_ratio > 0.0 && f.damping_ratio < 1.0, r, "damping_ratio", "must be in (0, 1)");
    f.am_depth = r.number("am_depth", f.am_depth);
    require(f.am_depth >= 0.0 && f.am_depth <= 1.0, r, "am_depth", "must be in [0, 1]");
    f.spur_phase_rad = r.number("spur_phase_rad", f.spur_phase_rad);
  } else {
    f.harmonic_gain = r.number("harmonic_gain", f.harmonic_gain);
    require(f.harmonic_gain >= 0.0, r, "harmonic_gain", "must be >= 0");
    f.noise_gain = r.number("noise_gain", f.noise_gain);
    require(f.noise_gain >= 0.0, r, "noise_gain", "must be >= 0");
  }
  r.finish();
}

void parse_sensor(Reader& r, SensorSpec& s) {
  r.known_keys({"fs_hz", "sensitivity_v_per_ms2", "range_ms2", "format"});
  s.fs_hz = r.number("fs_hz", s.fs_hz);
  require(s.fs_hz >= 1000.0 && s.fs_hz <= 200000.0 && s.fs_hz == std::floor(s.fs_hz), r, "fs_hz",
          "must be a whole number of Hz in [1000, 200000] (the WAV header holds an integer rate)");
  s.sensitivity_v_per_ms2 = r.number("sensitivity_v_per_ms2", s.sensitivity_v_per_ms2);
  require(s.sensitivity_v_per_ms2 > 0.0, r, "sensitivity_v_per_ms2", "must be > 0");
  s.range_ms2 = r.number("range_ms2", s.range_ms2);
  require(s.range_ms2 > 0.0, r, "range_ms2", "must be > 0");
  const std::string fmt = r.string("format", "pcm24");
  if (fmt == "pcm16") {
    s.format = formats::WavSampleFormat::kPcm16;
  } else if (fmt == "pcm24") {
    s.format = formats::WavSampleFormat::kPcm24;
  } else if (fmt == "pcm32") {
    s.format = formats::WavSampleFormat::kPcm32;
  } else if (fmt == "float32") {
    s.format = formats::WavSampleFormat::kFloat32;
  } else {
    throw r.error("format", "'" + fmt + "' is not a sample format (pcm16, pcm24, pcm32, float32)");
  }
  r.finish();
}

// The byte order is `byte_order = "little" | "big"`, as in pipeline configurations (config/README.md);
// the older `little_endian = true | false` is accepted for one release with a warning naming file:line.
void parse_signal(Reader& r, config::SignalSpec& s, std::vector<std::string>& warnings) {
  r.known_keys({"start_byte", "length", "byte_order", "little_endian", "signed", "scale", "offset"});
  s.start_byte = static_cast<std::uint8_t>(r.integer("start_byte", s.start_byte, 0, 63));
  s.length = static_cast<std::uint8_t>(r.integer("length", s.length, 1, 8));
  const bool order_given = r.has("byte_order");
  if (order_given) {
    const std::string order = r.string("byte_order", "");
    if (order != "little" && order != "big")
      throw r.error("byte_order", "must be one of \"little\", \"big\", not \"" + order + "\"");
    s.little_endian = order == "little";
  }
  if (r.has("little_endian")) {
    const bool little = r.boolean("little_endian", s.little_endian);
    const auto it = r.raw().find("little_endian");
    const toml::source_region& at = it->first.source();
    if (order_given && little != s.little_endian) {
      throw r.error_at(at, r.full("little_endian") + " = " + (little ? "true" : "false") +
                               " contradicts byte_order = \"" + (s.little_endian ? "little" : "big") +
                               "\" in the same table: delete little_endian (deprecated) and keep the "
                               "right byte_order");
    }
    warnings.push_back(config::little_endian_deprecation(
        r.source() + ":" + std::to_string(at.begin.line) + ":" + std::to_string(at.begin.column),
        r.full("little_endian"), little));
    s.little_endian = little;
  }
  s.is_signed = r.boolean("signed", s.is_signed);
  s.scale = r.number("scale", s.scale);
  s.offset = r.number("offset", s.offset);
  r.finish();
}

void parse_can(Reader& r, CanSpec& c, const std::string& source, std::vector<std::string>& warnings) {
  r.known_keys({"period_s", "clock_offset_s", "clock_drift_ppm", "delay_s", "jitter_s", "other_frames_per_s",
                "iface", "speed_frame", "speed_scale_tolerance", "speed_scale_slip_only"});
  c.period_s = r.number("period_s", c.period_s);
  require(c.period_s >= 1e-4 && c.period_s <= 1.0, r, "period_s", "must be in [0.0001, 1] s");
  c.clock_offset_s = r.number("clock_offset_s", c.clock_offset_s);
  require(c.clock_offset_s >= 0.0 && c.clock_offset_s < c.period_s, r, "clock_offset_s",
          "must be in [0, period_s)");
  c.clock_drift_ppm = r.number("clock_drift_ppm", c.clock_drift_ppm);
  require(std::fabs(c.clock_drift_ppm) <= 1000.0, r, "clock_drift_ppm", "must be within +-1000 ppm");
  c.delay_s = r.number("delay_s", c.delay_s);
  require(c.delay_s >= 0.0 && c.delay_s <= 1.0, r, "delay_s", "must be in [0, 1] s");
  c.jitter_s = r.number("jitter_s", c.jitter_s);
  require(c.jitter_s >= 0.0 && c.jitter_s < c.period_s, r, "jitter_s",
          "must be in [0, period_s) so frames stay in order");
  c.other_frames_per_s = static_cast<std::uint32_t>(r.integer("other_frames_per_s", 0, 0, 10000));
  c.speed_scale_tolerance = r.number("speed_scale_tolerance", c.speed_scale_tolerance);
  require(c.speed_scale_tolerance >= 0.0 && c.speed_scale_tolerance <= 0.05, r, "speed_scale_tolerance",
          "must be in [0, 0.05] (a fraction of the speed)");
  c.speed_scale_slip_only = r.boolean("speed_scale_slip_only", c.speed_scale_slip_only);
  require(!c.speed_scale_slip_only || c.speed_scale_tolerance > 0.0, r, "speed_scale_slip_only",
          "needs speed_scale_tolerance > 0 (without a tolerance the frames' speed is exact)");
  c.iface = r.string("iface", c.iface);
  require(!c.iface.empty() && c.iface.find_first_of(" \t()#") == std::string::npos, r, "iface",
          "must be a non-empty interface name without blanks");
  require(c.iface.size() <= kMaxInterfaceNameBytes, r, "iface",
          "is " + std::to_string(c.iface.size()) + " bytes long; an interface name has at most " +
              std::to_string(kMaxInterfaceNameBytes) + " (IFNAMSIZ 16 with the NUL)");
  if (const toml::table* sf = r.table("speed_frame")) {
    Reader sr(*sf, "can.speed_frame", source);
    sr.known_keys({"id", "extended", "dlc", "period_s", "has_angle", "speed", "angle"});
    auto& spec = c.speed_frame;
    spec.extended = sr.boolean("extended", spec.extended);
    spec.id = static_cast<std::uint32_t>(sr.integer("id", spec.id, 0, spec.extended ? 0x1FFFFFFF : 0x7FF));
    spec.dlc = static_cast<std::uint8_t>(sr.integer("dlc", spec.dlc, 0, 8));
    spec.has_angle = sr.boolean("has_angle", spec.has_angle);
    // period_s here is the pipeline configuration's key for the same period as [can] period_s, so a
    // [can.speed_frame] block copies both ways.
    if (sr.has("period_s")) {
      const double period_s = sr.number("period_s", c.period_s);
      require(period_s >= 1e-4 && period_s <= 1.0, sr, "period_s", "must be in [0.0001, 1] s");
      require(!r.has("period_s") || period_s == c.period_s, sr, "period_s",
              "disagrees with [can] period_s = " + std::to_string(c.period_s) + " (give the period once)");
      c.period_s = period_s;
      require(c.clock_offset_s < c.period_s, r, "clock_offset_s", "must be in [0, period_s)");
      require(c.jitter_s < c.period_s, r, "jitter_s", "must be in [0, period_s) so frames stay in order");
    }
    if (const toml::table* t = sr.table("speed")) {
      Reader x(*t, "can.speed_frame.speed", source);
      parse_signal(x, spec.speed, warnings);
    }
    if (const toml::table* t = sr.table("angle")) {
      Reader x(*t, "can.speed_frame.angle", source);
      parse_signal(x, spec.angle, warnings);
    }
    sr.finish();
    try {
      config::validate(spec);
    } catch (const Error& e) {
      throw sr.error_at(sf->source(), std::string("[can.speed_frame]: ") + e.what());
    }
  }
  c.speed_frame.period_s = c.period_s;
  r.finish();
}

void parse_effect(Reader& r, EffectSpec& e, const Scenario& s) {
  const toml::node* kn = r.raw().get("kind");
  const std::string kind = r.string("kind", "");
  const std::optional<EffectKind> k = effect_kind_from_name(kind);
  if (!k) {
    std::string names;
    for (const EffectInfo& info : effect_catalog())
      names += std::string(names.empty() ? "" : ", ") + info.name;
    throw r.error_at(
        kn != nullptr ? kn->source() : r.raw().source(),
        "[[effects]] kind must be one of " + names + (kind.empty() ? "" : " (got '" + kind + "')"));
  }
  const EffectInfo& info = effect_info(*k);
  e = EffectSpec::with_defaults(*k);
  for (auto&& [key, v] : r.raw()) {
    const std::string name(key.str());
    if (name == "kind") continue;
    bool found = false;
    for (const EffectParamInfo& p : info.params) found = found || name == p.name;
    if (!found) {
      std::string names;
      for (const EffectParamInfo& p : info.params) names += std::string(names.empty() ? "" : ", ") + p.name;
      throw r.error_at(key.source(),
                       "unknown key '" + r.full(name) + "' (" + info.name + " has " + names + ")");
    }
  }
  for (std::size_t i = 0; i < info.params.size(); ++i) {
    const EffectParamInfo& p = info.params[i];
    e.params[i] = r.number(p.name, p.default_value);
    require(e.params[i] >= p.min_value && e.params[i] <= p.max_value, r, p.name,
            "must be in [" + std::to_string(p.min_value) + ", " + std::to_string(p.max_value) + "]");
  }
  const double nyquist = s.sensor.fs_hz / 2.0;
  if (*k == EffectKind::kTransferPath) {
    require(e.get("frequency_hz") < 0.49 * s.sensor.fs_hz, r, "frequency_hz", "must be below 0.49 fs_hz");
  } else if (*k == EffectKind::kImpacts) {
    require(e.get("resonance_hz") < nyquist, r, "resonance_hz", "must be below fs_hz / 2");
    if (e.get("mode2_ratio") > 0.0) {
      // A second mode at or above 0.49 fs_hz is not simulated (the anti-alias filter's side), as a fit may
      // propose it; it is not an error.
      require(e.get("mode2_ratio") > 1.0, r, "mode2_ratio",
              "must be 0 (one mode) or above 1 (a higher mode)");
    }
  } else if (*k == EffectKind::kElectricalInterference) {
    require(e.get("frequency_hz") < nyquist, r, "frequency_hz", "must be below fs_hz / 2");
    if (e.get("pwm_ms2") > 0.0) {
      require(e.get("pwm_hz") > 0.0 && e.get("pwm_hz") < nyquist, r, "pwm_hz",
              "must be in (0, fs_hz / 2) when pwm_ms2 > 0");
      require(e.get("pwm_side_hz") < e.get("pwm_hz"), r, "pwm_side_hz", "must be below pwm_hz");
    }
  } else if (*k == EffectKind::kSpeedLatency) {
    require(e.get("jitter_s") + s.can.jitter_s < s.can.period_s, r, "jitter_s",
            "plus [can] jitter_s must stay below [can] period_s (frames of one sender keep their order)");
  }
  r.finish();
}

}  // namespace

Scenario parse_scenario(std::string_view toml_text, const std::string& source) {
  toml::table root;
  try {
    root = toml::parse(toml_text, source);
  } catch (const toml::parse_error& e) {
    throw Error(source, static_cast<long>(e.source().begin.line), static_cast<long>(e.source().begin.column),
                std::string(e.description()));
  }
  Scenario s;
  s.source = source;
  Reader r(root, "", source);
  r.known_keys({"name", "description", "seed", "start_time_s", "motion", "gearbox", "vibration", "fault",
                "sensor", "can", "effects", "drift"});
  s.name = r.string("name", "");
  s.description = r.string("description", "");
  s.seed = r.seed("seed", s.seed);
  s.start_time_s = r.number("start_time_s", s.start_time_s);
  require(s.start_time_s >= 0.0 && s.start_time_s < 4.0e9, r, "start_time_s",
          "must be UNIX seconds in [0, 4e9)");

  // Sections are read in dependency order (faults need the cycle count, DMF needs the gearbox kind).
  const toml::table* motion = r.table("motion");
  if (motion == nullptr) throw Error(source, 0, 0, "missing [motion] table");
  {
    Reader mr(*motion, "motion", source);
    parse_motion(mr, s.motion);
  }
  if (const toml::table* t = r.table("gearbox")) {
    Reader x(*t, "gearbox", source);
    parse_gearbox(x, s.gearbox);
  }
  if (const toml::table* t = r.table("vibration")) {
    Reader x(*t, "vibration", source);
    parse_vibration(x, s.vibration, s.gearbox);
  }
  if (const toml::node* n = r.node("fault")) {
    const toml::array* a = n->as_array();
    if (a == nullptr) throw r.error_at(n->source(), "fault: expected an array of tables [[fault]]");
    for (std::size_t i = 0; i < a->size(); ++i) {
      const toml::table* t = a->get(i)->as_table();
      if (t == nullptr)
        throw r.error_at(a->get(i)->source(), "fault[" + std::to_string(i) + "]: expected a table");
      Reader x(*t, "fault[" + std::to_string(i) + "]", source);
      FaultSpec f;
      parse_fault(x, f, s.motion.cycles);
      s.faults.push_back(f);
    }
  }
  if (const toml::table* t = r.table("sensor")) {
    Reader x(*t, "sensor", source);
    parse_sensor(x, s.sensor);
  }
  if (const toml::table* t = r.table("can")) {
    Reader x(*t, "can", source);
    parse_can(x, s.can, source, s.warnings);
  }
  if (const toml::table* t = r.table("drift")) {
    Reader x(*t, "drift", source);
    parse_drift(x, s.drift, s.motion);
  }
  // Effects last: their ranges depend on the sensor rate and the CAN timing.
  if (const toml::node* n = r.node("effects")) {
    const toml::array* a = n->as_array();
    if (a == nullptr) throw r.error_at(n->source(), "effects: expected an array of tables [[effects]]");
    for (std::size_t i = 0; i < a->size(); ++i) {
      const toml::table* t = a->get(i)->as_table();
      if (t == nullptr)
        throw r.error_at(a->get(i)->source(), "effects[" + std::to_string(i) + "]: expected a table");
      Reader x(*t, "effects[" + std::to_string(i) + "]", source);
      EffectSpec e;
      parse_effect(x, e, s);
      s.effects.push_back(std::move(e));
    }
  }
  r.finish();
  return s;
}

Scenario load_scenario(const std::filesystem::path& path) {
  // As configuration files (issue 14): a regular file of at most 16 MiB (a FIFO cannot hang it, a
  // device cannot flood it), and, when running as root, not writable by others, nor its directories.
  return parse_scenario(read_regular_file(path, kMaxConfigFileBytes, "scenario file", ::geteuid()),
                        path.string());
}

}  // namespace ptda::sim
