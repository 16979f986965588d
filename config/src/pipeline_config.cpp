// TOML -> PipelineConfig: per-key checks while applying each file, cross-key checks once at the end
// (so a drop-in may fix what the base file left inconsistent), every error located in its file.
#include "ptda/config/pipeline_config.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "ptda/common/error.hpp"
#include "ptda/config/pipeline_config_builder.hpp"
#include "ptda/config/toml_reader.hpp"
#include "ptda/dsp/angle_resampler.hpp"
#include "ptda/dsp/real_fft.hpp"

namespace ptda::config {
namespace {

constexpr double kMaxFsHz = 200000.0;
constexpr std::uint32_t kMaxWindowLen = 1U << 24;  // 16 Mi samples: ~11 min at 25.6 kHz
constexpr std::uint32_t kMaxTeeth = 100000;
constexpr std::uint32_t kMaxDecisionN = dsp::KOfNDebouncer::kMaxN;

using GearKind = dsp::GearboxInfo::Kind;
using ThresholdKind = dsp::ThresholdPolicy::Kind;

// A float that must be strictly positive: read with lo = 0 and refuse the 0 itself.
bool read_positive(TableReader& r, std::string_view key, double& out, double hi) {
  double v = 0.0;
  if (!r.read(key, v, 0.0, hi)) return false;
  if (v <= 0.0) r.fail_value(key, "must be > 0");
  out = v;
  return true;
}

std::string shortest(double v) {
  char buf[64];
  const auto res = std::to_chars(buf, buf + sizeof buf, v);
  std::string s(buf, res.ptr);
  // TOML floats need a '.' or an exponent; "3" would read back as an integer (also accepted, but
  // keep the type visible).
  if (s.find_first_of(".eEn") == std::string::npos) s += ".0";
  return s;
}

std::string hex(std::uint32_t v) {
  std::ostringstream os;
  os << "0x" << std::hex << std::uppercase << v;
  return os.str();
}

void format_signal(std::ostringstream& os, const char* name, const SignalSpec& s) {
  os << "\n[can.speed_frame." << name << "]\n"
     << "start_byte = " << static_cast<unsigned>(s.start_byte) << "\n"
     << "length = " << static_cast<unsigned>(s.length) << "\n"
     << "byte_order = \"" << (s.little_endian ? "little" : "big") << "\"\n"
     << "signed = " << (s.is_signed ? "true" : "false") << "\n"
     << "scale = " << shortest(s.scale) << "\n"
     << "offset = " << shortest(s.offset) << "\n";
}

}  // namespace

std::string little_endian_deprecation(const std::string& where, const std::string& key, bool little) {
  return where + ": " + key + " = " + (little ? "true" : "false") +
         " is deprecated (accepted until the next release): write byte_order = \"" +
         (little ? "little" : "big") +
         "\" instead, the spelling shared by pipeline configurations and simulator scenarios";
}

std::string_view threshold_kind_name(ThresholdKind kind) noexcept {
  switch (kind) {
    case ThresholdKind::kGaussian:
      return "gaussian";
    case ThresholdKind::kQuantile:
      return "quantile";
    case ThresholdKind::kTolerance:
      return "tolerance";
  }
  return "?";
}

std::string_view gearbox_kind_name(GearKind kind) noexcept {
  switch (kind) {
    case GearKind::kCycloidal:
      return "cycloidal";
    case GearKind::kParallel:
      return "parallel";
    case GearKind::kUnknown:
      return "unknown";
  }
  return "?";
}

PipelineConfigBuilder::PipelineConfigBuilder(std::vector<std::string> ignored_tables)
    : ignored_(std::move(ignored_tables)) {}

void PipelineConfigBuilder::note(const TableReader& reader, std::string_view key) {
  set_at_[reader.qualified(key)] = reader.location(key);
}

void PipelineConfigBuilder::ignore_owned(TableReader& reader) const {
  // "daemon" is a top-level table, "can.interface" a key of [can]: each reader skips its own entries.
  const std::string prefix = reader.name().empty() ? std::string() : reader.name() + ".";
  for (const auto& name : ignored_) {
    if (name.size() > prefix.size() && name.compare(0, prefix.size(), prefix) == 0 &&
        name.find('.', prefix.size()) == std::string::npos) {
      reader.ignore(std::string_view(name).substr(prefix.size()));
    }
  }
}

void PipelineConfigBuilder::fail_key(const std::string& path, const std::string& what) const {
  const auto it = set_at_.find(path);
  fail_at(it != set_at_.end() ? it->second : main_source_, what);
}

void PipelineConfigBuilder::apply(const toml::table& root, const std::string& source) {
  if (main_source_.source.empty()) main_source_ = SourceLocation{source, 0, 0};
  TableReader top(root, "", source);
  ignore_owned(top);

  // Each read that found its key records where, for the cross-key checks in finish().
  const auto get = [this](TableReader& r, std::string_view key, auto& out, auto... range) {
    if (r.read(key, out, range...)) note(r, key);
  };
  const auto choice = [this](TableReader& r, std::string_view key, auto& out, auto choices) {
    if (r.read_choice(key, out, choices)) note(r, key);
  };

  if (const toml::table* t = top.table("acquisition")) {
    TableReader r(*t, "acquisition", source);
    ignore_owned(r);
    double fs_hz = 0.0;
    if (r.read("fs_hz", fs_hz, 0.0, kMaxFsHz)) {
      if (fs_hz > 0.0 && fs_hz < 1.0)
        r.fail_value("fs_hz", "must be 0 (take the recording's rate) or 1..200000");
      cfg_.fs_hz = fs_hz;
      note(r, "fs_hz");
    }
    r.finish();
  }

  if (const toml::table* t = top.table("can")) {
    TableReader r(*t, "can", source);
    ignore_owned(r);
    get(r, "speed_latency_s", cfg_.speed_latency_s, -1.0, 1.0);
    if (const toml::table* f = r.table("speed_frame")) {
      TableReader fr(*f, "can.speed_frame", source);
      ignore_owned(fr);
      SpeedFrameSpec& spec = cfg_.speed_frame;
      get(fr, "id", spec.id, std::uint32_t{0}, std::uint32_t{0x1FFFFFFF});
      get(fr, "extended", spec.extended);
      get(fr, "dlc", spec.dlc, std::uint8_t{1}, std::uint8_t{8});
      if (read_positive(fr, "period_s", spec.period_s, 10.0)) note(fr, "period_s");
      get(fr, "has_angle", spec.has_angle);
      const auto signal = [&](const char* name, SignalSpec& sig) {
        const toml::table* st = fr.table(name);
        if (st == nullptr) return;
        TableReader sr(*st, std::string("can.speed_frame.") + name, source);
        ignore_owned(sr);
        get(sr, "start_byte", sig.start_byte, std::uint8_t{0}, std::uint8_t{7});
        get(sr, "length", sig.length, std::uint8_t{1}, std::uint8_t{8});
        const bool order_given = sr.read_choice(
            "byte_order", sig.little_endian,
            std::initializer_list<std::pair<std::string_view, bool>>{{"little", true}, {"big", false}});
        if (order_given) note(sr, "byte_order");
        // The scenario spelling before issue 17, accepted for one release.
        bool little = true;
        if (sr.read("little_endian", little)) {
          const SourceLocation at = sr.location("little_endian", false);
          const std::string order = little ? "little" : "big";
          if (order_given && little != sig.little_endian) {
            fail_at(at, sr.qualified("little_endian") + " = " + (little ? "true" : "false") +
                            " contradicts byte_order = \"" + (sig.little_endian ? "little" : "big") +
                            "\" in the same table: delete little_endian (deprecated) and keep the right "
                            "byte_order");
          }
          cfg_.warnings.push_back(little_endian_deprecation(
              at.source + ":" + std::to_string(at.line) + ":" + std::to_string(at.column),
              sr.qualified("little_endian"), little));
          sig.little_endian = little;
        }
        get(sr, "signed", sig.is_signed);
        double scale = 0.0;
        if (sr.read("scale", scale, -1e12, 1e12)) {
          if (scale == 0.0) sr.fail_value("scale", "must not be 0");
          sig.scale = scale;
          note(sr, "scale");
        }
        get(sr, "offset", sig.offset, -1e12, 1e12);
        sr.finish();
      };
      signal("speed", spec.speed);
      signal("angle", spec.angle);
      fr.finish();
    }
    r.finish();
  }

  if (const toml::table* t = top.table("extraction")) {
    TableReader r(*t, "extraction", source);
    ignore_owned(r);
    dsp::ExtractionConfig& e = cfg_.extraction;
    std::uint32_t window_len = 0;
    if (r.read("window_len", window_len, 4, kMaxWindowLen)) {
      if (!dsp::RealFft::supported_length(window_len)) {
        r.fail_value("window_len",
                     "= " + std::to_string(window_len) +
                         " is not an FFT length: it must be even with prime factors 2, 3 and 5 only "
                         "(e.g. 3200, 4096, 10240, 12800)");
      }
      e.window_len = window_len;
      note(r, "window_len");
    }
    get(r, "hop", e.hop, std::uint32_t{0}, kMaxWindowLen);
    get(r, "speed_tol_rel", e.speed_tol_rel, 0.0, 1.0);
    get(r, "speed_tol_abs_rad_s", e.speed_tol_abs_rad_s, 0.0, 100.0);
    get(r, "min_speed_rad_s", e.min_speed_rad_s, 0.0, 1e9);
    if (read_positive(r, "max_speed_rad_s", e.max_speed_rad_s, 1e9)) note(r, "max_speed_rad_s");
    get(r, "min_duration_s", e.min_duration_s, 0.0, 3600.0);
    get(r, "guard_s", e.guard_s, 0.0, 3600.0);
    if (read_positive(r, "max_speed_gap_s", e.max_speed_gap_s, 3600.0)) note(r, "max_speed_gap_s");
    get(r, "max_windows_per_region", e.max_windows_per_region, std::uint32_t{0}, std::uint32_t{1000000000});
    get(r, "clip_abs", e.clip_abs, 0.0, 1e30);
    // The order domain (docs/method.md §9): windows of R input-shaft revolutions resampled from the CAN
    // angle to S samples per revolution.
    choice(r, "domain", cfg_.domain,
           std::initializer_list<std::pair<std::string_view, dsp::Domain>>{{"time", dsp::Domain::kTime},
                                                                           {"order", dsp::Domain::kOrder}});
    OrderDomainConfig& o = cfg_.order;
    std::uint32_t spr = 0;
    if (r.read("samples_per_rev", spr, std::uint32_t{16}, std::uint32_t{65536})) {
      if (spr % 2 != 0) r.fail_value("samples_per_rev", "= " + std::to_string(spr) + " must be even");
      o.samples_per_rev = spr;
      note(r, "samples_per_rev");
    }
    get(r, "revolutions", o.revolutions, std::uint32_t{1}, std::uint32_t{4096});
    double band = 0.0;
    if (r.read("speed_band_rel", band, 0.0, 1.0)) {
      if (band <= 0.0) r.fail_value("speed_band_rel", "must be > 0 (the relative width of a speed class)");
      o.speed_band_rel = band;
      note(r, "speed_band_rel");
    }
    get(r, "anti_alias_half_taps", o.anti_alias_half_taps, std::uint32_t{4}, std::uint32_t{256});
    double cutoff = 0.0;
    if (r.read("anti_alias_cutoff", cutoff, 0.0, 1.0)) {
      if (cutoff <= 0.0 || cutoff >= 1.0)
        r.fail_value("anti_alias_cutoff", "must be > 0 and < 1 (a fraction of the output Nyquist order S/2)");
      o.anti_alias_cutoff = cutoff;
      note(r, "anti_alias_cutoff");
    }
    if (read_positive(r, "min_shaft_hz", o.min_shaft_hz, 1000.0)) note(r, "min_shaft_hz");
    get(r, "can_time_smoothing_frames", o.can_time_smoothing_frames, std::uint32_t{0}, std::uint32_t{4096});
    get(r, "speed_law", o.speed_law);
    r.finish();
  }

  if (const toml::table* t = top.table("classes")) {
    TableReader r(*t, "classes", source);
    ignore_owned(r);
    get(r, "speed_tol_rel", cfg_.classes.speed_tol_rel, 0.0, 1.0);
    get(r, "speed_tol_abs_rad_s", cfg_.classes.speed_tol_abs_rad_s, 0.0, 100.0);
    get(r, "min_regions", cfg_.classes.min_regions, std::uint32_t{1}, std::uint32_t{1000000});
    r.finish();
  }

  if (const toml::table* t = top.table("thresholds")) {
    TableReader r(*t, "thresholds", source);
    ignore_owned(r);
    choice(r, "method", cfg_.thresholds.kind,
           std::initializer_list<std::pair<std::string_view, ThresholdKind>>{
               {"gaussian", ThresholdKind::kGaussian},
               {"quantile", ThresholdKind::kQuantile},
               {"tolerance", ThresholdKind::kTolerance}});
    double rate = 0.0;
    if (r.read("false_alarm_rate", rate, 0.0, 0.5)) {
      if (rate <= 0.0 || rate >= 0.5) r.fail_value("false_alarm_rate", "must be > 0 and < 0.5");
      cfg_.thresholds.false_alarm_rate = rate;
      note(r, "false_alarm_rate");
    }
    get(r, "margin", cfg_.thresholds.margin, 0.0, 10.0);
    double confidence = 0.0;
    if (r.read("confidence", confidence, 0.5, 1.0)) {
      if (confidence <= 0.5 || confidence >= 1.0) r.fail_value("confidence", "must be > 0.5 and < 1");
      cfg_.thresholds.confidence = confidence;
      note(r, "confidence");
    }
    get(r, "holdout_fraction", cfg_.thresholds.holdout_fraction, 0.0, 0.9);
    // Floor on the between-day sd of the features, relative to the within-day sd (docs/method.md §5).
    get(r, "day_sd_floor", cfg_.thresholds.day_sd_floor, 0.0, 10.0);
    // Bands that cover each training recording's own band (docs/method.md §5, session 9).
    get(r, "cover_recordings", cfg_.thresholds.cover_recordings);
    r.finish();
  }

  if (const toml::table* t = top.table("decision")) {
    TableReader r(*t, "decision", source);
    ignore_owned(r);
    get(r, "k", cfg_.decision.k, std::uint32_t{1}, kMaxDecisionN);
    get(r, "n", cfg_.decision.n, std::uint32_t{1}, kMaxDecisionN);
    bool cusum = cfg_.decision.sequential.enabled;
    if (r.read_choice(
            "sequential", cusum,
            std::initializer_list<std::pair<std::string_view, bool>>{{"cusum", true}, {"off", false}})) {
      cfg_.decision.sequential.enabled = cusum;
      note(r, "sequential");
    }
    if (read_positive(r, "cusum_k", cfg_.decision.sequential.k, 10.0)) note(r, "cusum_k");
    if (read_positive(r, "cusum_warn", cfg_.decision.sequential.h_warn, 1000.0)) note(r, "cusum_warn");
    if (read_positive(r, "cusum_alarm", cfg_.decision.sequential.h_alarm, 1000.0)) note(r, "cusum_alarm");
    // The CUSUM's allowance for the between-day spread, in between-day sds (docs/method.md §6).
    get(r, "cusum_day_allowance", cfg_.decision.sequential.day_allowance, 0.0, 10.0);
    // Largest step one window adds to a CUSUM (docs/method.md §6 "Step cap"), per detector.
    if (read_positive(r, "cusum_step_cap", cfg_.decision.sequential.step_cap, dsp::kNoStepCap))
      note(r, "cusum_step_cap");
    // The band CUSUM (on by default since session 13; docs/method.md §6 "Band detector"). Training
    // stores band statistics only when it is on. Said explicitly, it is required (errors instead of the
    // default's fallback when the method or the baseline cannot carry it).
    if (r.read("band_cusum", cfg_.decision.band.enabled)) {
      note(r, "band_cusum");
      cfg_.decision.band.required = cfg_.decision.band.enabled;
    }
    if (read_positive(r, "band_cusum_k", cfg_.decision.band.k, 10.0)) note(r, "band_cusum_k");
    if (read_positive(r, "band_cusum_h", cfg_.decision.band.h, 1000.0)) note(r, "band_cusum_h");
    get(r, "band_cusum_day_allowance", cfg_.decision.band.day_allowance, 0.0, 10.0);
    if (read_positive(r, "band_cusum_step_cap", cfg_.decision.band.step_cap, dsp::kNoStepCap))
      note(r, "band_cusum_step_cap");
    get(r, "band_count", cfg_.decision.band.band_count, std::uint32_t{1}, dsp::kMaxBands);
    // The mesh detector (on by default since session 37 where the gearbox's teeth are given and the
    // domain is time; docs/method.md §6 "Mesh detector"): training stores the mesh statistics only when
    // it is on. Said explicitly, it is required (errors instead of the default's fallback).
    if (r.read("mesh_cusum", cfg_.decision.mesh.enabled)) {
      note(r, "mesh_cusum");
      cfg_.decision.mesh.required = cfg_.decision.mesh.enabled;
    }
    if (read_positive(r, "mesh_cusum_k", cfg_.decision.mesh.k, 10.0)) note(r, "mesh_cusum_k");
    if (read_positive(r, "mesh_cusum_h", cfg_.decision.mesh.h, 1000.0)) note(r, "mesh_cusum_h");
    get(r, "mesh_cusum_one_day_allowance", cfg_.decision.mesh.one_day_allowance, 0.0, 10.0);
    if (read_positive(r, "mesh_cusum_step_cap", cfg_.decision.mesh.step_cap, dsp::kNoStepCap))
      note(r, "mesh_cusum_step_cap");
    r.finish();
  }

  if (const toml::table* t = top.table("monitor")) {
    TableReader r(*t, "monitor", source);
    ignore_owned(r);
    choice(r, "method", cfg_.method,
           std::initializer_list<std::pair<std::string_view, dsp::Method>>{
               {"ptda", dsp::Method::kPtda}, {"tda", dsp::Method::kTda}, {"raw", dsp::Method::kRaw}});
    // PTDA with a per-window gain on each line of the healthy spectrum (docs/method.md §3); training
    // stores it in the baseline, which then decides for monitoring.
    r.read("line_gain", cfg_.thresholds.ptda_line_gain);
    // The floor's own per-window gain, rms_res referred to the training floor (docs/method.md §2).
    r.read("floor_gain", cfg_.thresholds.ptda_floor_gain);
    r.finish();
  }

  if (const toml::table* t = top.table("gearbox")) {
    TableReader r(*t, "gearbox", source);
    ignore_owned(r);
    dsp::GearboxInfo& g = cfg_.gearbox;
    choice(r, "kind", g.kind,
           std::initializer_list<std::pair<std::string_view, GearKind>>{{"cycloidal", GearKind::kCycloidal},
                                                                        {"parallel", GearKind::kParallel},
                                                                        {"unknown", GearKind::kUnknown}});
    get(r, "z_in", g.z_in, std::uint32_t{0}, kMaxTeeth);
    get(r, "z_spur", g.z_spur, std::uint32_t{0}, kMaxTeeth);
    get(r, "z_pin", g.z_pin, std::uint32_t{0}, kMaxTeeth);
    if (read_positive(r, "ratio", g.ratio, 1e6)) {
      note(r, "ratio");
      ratio_given_ = true;
    }
    r.finish();
  }

  top.finish();
}

PipelineConfig PipelineConfigBuilder::finish() const {
  PipelineConfig cfg = cfg_;
  const auto is_set = [this](const std::string& path) { return set_at_.count(path) != 0; };

  dsp::ExtractionConfig& e = cfg.extraction;
  if (cfg.domain == dsp::Domain::kOrder) {
    // A window is R revolutions of S samples: window_len follows (when given it must agree).
    const std::uint64_t n = std::uint64_t{cfg.order.samples_per_rev} * cfg.order.revolutions;
    const std::string rs = "revolutions (" + std::to_string(cfg.order.revolutions) + ") x samples_per_rev (" +
                           std::to_string(cfg.order.samples_per_rev) + ") = " + std::to_string(n);
    if (n > kMaxWindowLen || !dsp::RealFft::supported_length(static_cast<std::size_t>(n))) {
      fail_key(is_set("extraction.revolutions") ? "extraction.revolutions" : "extraction.samples_per_rev",
               "[extraction] " + rs +
                   " is not an FFT length up to 2^24: it must have prime factors 2, 3 and 5 only "
                   "(e.g. S = 1024, R = 8)");
    }
    if (e.window_len != 0 && e.window_len != n) {
      fail_key("extraction.window_len", "[extraction] window_len = " + std::to_string(e.window_len) +
                                            " disagrees with domain = \"order\": " + rs +
                                            " (remove window_len; the order domain derives it)");
    }
    e.window_len = static_cast<std::uint32_t>(n);
    if (!cfg.speed_frame.has_angle) {
      fail_key(is_set("can.speed_frame.has_angle") ? "can.speed_frame.has_angle" : "extraction.domain",
               "[extraction] domain = \"order\" resamples the vibration to the joint angle, but "
               "[can.speed_frame] has_angle = false: the speed frame must carry the angle (set has_angle = "
               "true and its [can.speed_frame.angle] signal)");
    }
  }
  if (e.window_len == 0) {
    fail_at(main_source_,
            "[extraction] window_len is required: the window length in samples (only factors 2, 3, 5; it "
            "must fit "
            "inside the job's constant-speed plateau)");
  }
  if (e.speed_tol_rel == 0.0 && e.speed_tol_abs_rad_s == 0.0) {
    fail_key(is_set("extraction.speed_tol_abs_rad_s") ? "extraction.speed_tol_abs_rad_s"
                                                      : "extraction.speed_tol_rel",
             "[extraction] speed_tol_rel and speed_tol_abs_rad_s are both 0: no speed would ever count as "
             "constant");
  }
  if (e.min_speed_rad_s >= e.max_speed_rad_s) {
    fail_key(
        is_set("extraction.max_speed_rad_s") ? "extraction.max_speed_rad_s" : "extraction.min_speed_rad_s",
        "[extraction] min_speed_rad_s (" + shortest(e.min_speed_rad_s) + ") must be below max_speed_rad_s (" +
            shortest(e.max_speed_rad_s) + ")");
  }
  if (cfg.classes.speed_tol_rel == 0.0 && cfg.classes.speed_tol_abs_rad_s == 0.0) {
    fail_key(
        is_set("classes.speed_tol_abs_rad_s") ? "classes.speed_tol_abs_rad_s" : "classes.speed_tol_rel",
        "[classes] speed_tol_rel and speed_tol_abs_rad_s are both 0: no two regions would share a class");
  }
  if (cfg.decision.k > cfg.decision.n) {
    fail_key(is_set("decision.k") ? "decision.k" : "decision.n",
             "[decision] k = " + std::to_string(cfg.decision.k) + " must not exceed n = " +
                 std::to_string(cfg.decision.n) + " (alarm when k of the last n windows are abnormal)");
  }

  // The band detector reads the PTDA residual's band energies: by default it is off for another method;
  // asked for explicitly, that is an error here rather than at monitoring time.
  if (cfg.decision.band.enabled && cfg.method != dsp::Method::kPtda) {
    if (cfg.decision.band.required) {
      fail_key(
          is_set("monitor.method") ? "monitor.method" : "decision.band_cusum",
          std::string("[decision] band_cusum = true needs [monitor] method = \"ptda\" (the band statistics "
                      "are those of the PTDA residual), got \"") +
              std::string(dsp::method_name(cfg.method)) + "\": set band_cusum = false or method = \"ptda\"");
    }
    cfg.decision.band.enabled = false;
  }
  // By default a window too short for band_count bands just goes without the band detector, and so does
  // the order domain, where it has not been measured (docs/method.md §8): there it must be asked for.
  if (cfg.decision.band.enabled && !cfg.decision.band.required &&
      ((!is_set("decision.band_count") && cfg.decision.band.band_count > cfg.extraction.window_len / 2) ||
       cfg.domain == dsp::Domain::kOrder)) {
    cfg.decision.band.enabled = false;
  }
  cfg.thresholds.band_count = cfg.decision.band.enabled ? cfg.decision.band.band_count : 0U;
  if (cfg.decision.band.enabled && cfg.decision.band.band_count > cfg.extraction.window_len / 2) {
    fail_key("decision.band_count",
             "[decision] band_count = " + std::to_string(cfg.decision.band.band_count) +
                 " needs at least one bin per band: must not exceed window_len / 2 = " +
                 std::to_string(cfg.extraction.window_len / 2));
  }

  if (cfg.decision.sequential.h_warn > cfg.decision.sequential.h_alarm) {
    fail_key(is_set("decision.cusum_warn") ? "decision.cusum_warn" : "decision.cusum_alarm",
             "[decision] cusum_warn = " + shortest(cfg.decision.sequential.h_warn) +
                 " must not exceed cusum_alarm = " + shortest(cfg.decision.sequential.h_alarm));
  }

  if (const auto problem = find_problem(cfg.speed_frame)) {
    // Point at the key at fault when a file wrote it, else at the related key most likely changed.
    std::string path = "can.speed_frame." + problem->key;
    for (const auto& related : problem->related) {
      if (is_set(path)) break;
      path = "can.speed_frame." + related;
    }
    fail_key(path, "[can.speed_frame] " + problem->what);
  }

  dsp::GearboxInfo& g = cfg.gearbox;
  double from_teeth = 0.0;
  std::string teeth_text;
  switch (g.kind) {
    case GearKind::kCycloidal:
      for (const auto& [name, z] : {std::pair<const char*, std::uint32_t>{"z_in", g.z_in},
                                    {"z_spur", g.z_spur},
                                    {"z_pin", g.z_pin}}) {
        if (z == 0 && !ratio_given_) {
          fail_key(is_set(std::string("gearbox.") + name) ? std::string("gearbox.") + name : "gearbox.kind",
                   std::string("[gearbox] a cycloidal gearbox needs z_in, z_spur and z_pin > 0 (eq. 1) or an "
                               "explicit ratio; ") +
                       name + " is 0");
        }
      }
      if (g.z_in > 0 && g.z_spur > 0 && g.z_pin > 0) {
        from_teeth = cycloidal_ratio(g.z_in, g.z_spur, g.z_pin);
        teeth_text = "1 + z_spur/z_in * z_pin = " + shortest(from_teeth);
      }
      break;
    case GearKind::kParallel:
      if (g.z_pin != 0)
        fail_key("gearbox.z_pin", "[gearbox] z_pin must be 0 for a parallel gearbox (it has no pins)");
      if ((g.z_in == 0) != (g.z_spur == 0)) {
        fail_key(is_set("gearbox.z_in") ? "gearbox.z_in" : "gearbox.z_spur",
                 "[gearbox] a parallel gearbox needs both z_in (driving) and z_spur (driven), or neither");
      }
      if (g.z_in > 0) {
        from_teeth = static_cast<double>(g.z_spur) / static_cast<double>(g.z_in);
        teeth_text = "z_spur/z_in = " + shortest(from_teeth);
      }
      break;
    case GearKind::kUnknown:
      for (const char* name : {"z_in", "z_spur", "z_pin"}) {
        const std::string path = std::string("gearbox.") + name;
        if (is_set(path)) {
          fail_key(path, std::string("[gearbox] ") + name +
                             " is given but kind is \"unknown\": set kind = \"cycloidal\" or \"parallel\"");
        }
      }
      break;
  }
  if (ratio_given_) {
    // An explicit ratio wins; with teeth too they must agree (0.1 %: the paper rounds R to 33.86).
    if (from_teeth > 0.0 && std::abs(g.ratio - from_teeth) > 1e-3 * from_teeth) {
      fail_key("gearbox.ratio", "[gearbox] ratio = " + shortest(g.ratio) +
                                    " disagrees with the teeth: " + teeth_text + " (remove one of them)");
    }
  } else {
    g.ratio = from_teeth;
  }
  // The mesh detector demodulates the mesh at z_in x the input-shaft rate, ratio x the joint speed. On
  // by default it goes without where it cannot run (no teeth, the order domain); asked for, that is an
  // error at the key.
  if (cfg.decision.mesh.enabled && !cfg.decision.mesh.required) {
    const char* why = nullptr;
    if (cfg.domain != dsp::Domain::kTime) {
      why = "the order domain (not measured with it)";
    } else if (g.z_in == 0 || !(g.ratio > 0.0)) {
      why = "no gearbox teeth: [gearbox] z_in and the ratio are needed for the mesh frequency";
    }
    if (why != nullptr) {
      cfg.decision.mesh.enabled = false;
      cfg.mesh_off_reason = why;
    }
  }
  if (cfg.decision.mesh.enabled) {
    if (cfg.domain != dsp::Domain::kTime) {
      fail_key("decision.mesh_cusum",
               "[decision] mesh_cusum = true runs in the time domain only ([extraction] "
               "domain = \"time\"); the order domain has not been measured with it");
    }
    if (g.z_in == 0 || !(g.ratio > 0.0)) {
      fail_key(
          "decision.mesh_cusum",
          "[decision] mesh_cusum = true needs the input pinion's teeth and the gearbox ratio: set [gearbox] "
          "kind with z_in, z_spur, z_pin (cycloidal) or z_in, z_spur (parallel), or z_in and ratio");
    }
  }
  cfg.thresholds.mesh_stats = cfg.decision.mesh.enabled;
  if (cfg.domain == dsp::Domain::kOrder) {
    if (!(g.ratio > 0.0)) {
      fail_key("extraction.domain",
               "[extraction] domain = \"order\" needs the gearbox ratio (input-shaft angle = ratio x joint "
               "angle): set [gearbox] kind and teeth, or ratio");
    }
    // The resampler passes orders up to 0.3608 S (default c and Q): the first mesh harmonic z_in must
    // be inside, or the order windows hold no mesh at all.
    const double pass = dsp::AngleResampler::pass_order_of(angle_resampler_config(cfg));
    if (!(pass > 0.0)) {
      fail_key("extraction.anti_alias_half_taps",
               "[extraction] anti_alias_half_taps = " + std::to_string(cfg.order.anti_alias_half_taps) +
                   " is too small for anti_alias_cutoff = " + shortest(cfg.order.anti_alias_cutoff) +
                   ": the kernel's transition band leaves no pass band");
    }
    if (g.z_in > 0 && pass < static_cast<double>(g.z_in)) {
      fail_key(is_set("extraction.samples_per_rev") ? "extraction.samples_per_rev" : "gearbox.z_in",
               "[extraction] samples_per_rev = " + std::to_string(cfg.order.samples_per_rev) +
                   " passes orders up to " + shortest(pass) + " only, below the gear mesh order z_in = " +
                   std::to_string(g.z_in) + ": raise samples_per_rev");
    }
  }
  return cfg;
}

void check_baseline_domain(const dsp::Baseline& baseline, const std::string& baseline_source,
                           const PipelineConfig& cfg, const std::string& config_source) {
  const auto num = [](double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.10g", v);
    return std::string(buf);
  };
  if (baseline.domain != cfg.domain) {
    throw Error(baseline_source + ": baseline was trained in the " + dsp::domain_name(baseline.domain) +
                " domain but " + config_source + " sets [extraction] domain = \"" +
                dsp::domain_name(cfg.domain) + "\": use the configuration it was trained with, or retrain");
  }
  if (cfg.domain != dsp::Domain::kOrder) return;
  if (baseline.samples_per_rev != cfg.order.samples_per_rev ||
      baseline.revolutions != cfg.order.revolutions) {
    throw Error(baseline_source +
                ": order baseline has samples_per_rev = " + std::to_string(baseline.samples_per_rev) +
                ", revolutions = " + std::to_string(baseline.revolutions) + " but " + config_source +
                " sets [extraction] samples_per_rev = " + std::to_string(cfg.order.samples_per_rev) +
                ", revolutions = " + std::to_string(cfg.order.revolutions));
  }
  if (std::abs(baseline.gearbox.ratio - cfg.gearbox.ratio) > 1e-9 * cfg.gearbox.ratio) {
    throw Error(baseline_source + ": order baseline was trained with gearbox ratio " +
                num(baseline.gearbox.ratio) + " but " + config_source + " gives " + num(cfg.gearbox.ratio));
  }
}

dsp::AngleResamplerConfig angle_resampler_config(const PipelineConfig& cfg) noexcept {
  dsp::AngleResamplerConfig rc;
  rc.samples_per_rev = cfg.order.samples_per_rev;
  rc.ratio = cfg.gearbox.ratio;
  rc.speed_latency_s = 0.0;  // applied when the frames are decoded
  rc.half_taps = cfg.order.anti_alias_half_taps;
  rc.cutoff = cfg.order.anti_alias_cutoff;
  rc.min_shaft_hz = cfg.order.min_shaft_hz;
  rc.max_speed_gap_s = cfg.extraction.max_speed_gap_s;
  return rc;
}

dsp::OrderWindowConfig order_window_config(const PipelineConfig& cfg, double pass_order) noexcept {
  return dsp::OrderWindowConfig{cfg.order.samples_per_rev, cfg.order.revolutions, cfg.gearbox.ratio,
                                pass_order};
}

PipelineConfig parse_pipeline_config(std::string_view toml_text, const std::string& source) {
  return parse_pipeline_config(toml_text, source, {});
}

PipelineConfig parse_pipeline_config(std::string_view toml_text, const std::string& source,
                                     const std::vector<std::string>& ignored_tables) {
  PipelineConfigBuilder builder(ignored_tables);
  builder.apply(parse_toml(toml_text, source), source);
  return builder.finish();
}

PipelineConfig load_pipeline_config(const std::filesystem::path& path,
                                    const std::vector<std::filesystem::path>& dropins) {
  return load_pipeline_config(path, dropins, {});
}

PipelineConfig load_pipeline_config(const std::filesystem::path& path,
                                    const std::vector<std::filesystem::path>& dropins,
                                    const std::vector<std::string>& ignored_tables) {
  PipelineConfigBuilder builder(ignored_tables);
  builder.apply(read_toml_file(path), path.string());
  for (const auto& dropin : dropins) builder.apply(read_toml_file(dropin), dropin.string());
  return builder.finish();
}

std::string format_pipeline_config(const PipelineConfig& cfg) {
  std::ostringstream os;
  const auto& f = cfg.speed_frame;
  const auto& e = cfg.extraction;
  os << "[acquisition]\nfs_hz = " << shortest(cfg.fs_hz) << "\n"
     << "\n[can]\nspeed_latency_s = " << shortest(cfg.speed_latency_s) << "\n"
     << "\n[can.speed_frame]\n"
     << "id = " << hex(f.id) << "\n"
     << "extended = " << (f.extended ? "true" : "false") << "\n"
     << "dlc = " << static_cast<unsigned>(f.dlc) << "\n"
     << "period_s = " << shortest(f.period_s) << "\n"
     << "has_angle = " << (f.has_angle ? "true" : "false") << "\n";
  format_signal(os, "speed", f.speed);
  format_signal(os, "angle", f.angle);
  os << "\n[extraction]\n"
     << "window_len = " << e.window_len << "\n"
     << "hop = " << e.hop << "\n"
     << "speed_tol_rel = " << shortest(e.speed_tol_rel) << "\n"
     << "speed_tol_abs_rad_s = " << shortest(e.speed_tol_abs_rad_s) << "\n"
     << "min_speed_rad_s = " << shortest(e.min_speed_rad_s) << "\n"
     << "max_speed_rad_s = " << shortest(e.max_speed_rad_s) << "\n"
     << "min_duration_s = " << shortest(e.min_duration_s) << "\n"
     << "guard_s = " << shortest(e.guard_s) << "\n"
     << "max_speed_gap_s = " << shortest(e.max_speed_gap_s) << "\n"
     << "max_windows_per_region = " << e.max_windows_per_region << "\n"
     << "clip_abs = " << shortest(e.clip_abs) << "\n"
     << "domain = \"" << dsp::domain_name(cfg.domain) << "\"\n"
     << "samples_per_rev = " << cfg.order.samples_per_rev << "\n"
     << "revolutions = " << cfg.order.revolutions << "\n"
     << "speed_band_rel = " << shortest(cfg.order.speed_band_rel) << "\n"
     << "anti_alias_half_taps = " << cfg.order.anti_alias_half_taps << "\n"
     << "anti_alias_cutoff = " << shortest(cfg.order.anti_alias_cutoff) << "\n"
     << "min_shaft_hz = " << shortest(cfg.order.min_shaft_hz) << "\n"
     << "can_time_smoothing_frames = " << cfg.order.can_time_smoothing_frames << "\n"
     << "speed_law = " << (cfg.order.speed_law ? "true" : "false") << "\n"
     << "\n[classes]\n"
     << "speed_tol_rel = " << shortest(cfg.classes.speed_tol_rel) << "\n"
     << "speed_tol_abs_rad_s = " << shortest(cfg.classes.speed_tol_abs_rad_s) << "\n"
     << "min_regions = " << cfg.classes.min_regions << "\n"
     << "\n[thresholds]\n"
     << "method = \"" << threshold_kind_name(cfg.thresholds.kind) << "\"\n"
     << "false_alarm_rate = " << shortest(cfg.thresholds.false_alarm_rate) << "\n"
     << "margin = " << shortest(cfg.thresholds.margin) << "\n"
     << "confidence = " << shortest(cfg.thresholds.confidence) << "\n"
     << "holdout_fraction = " << shortest(cfg.thresholds.holdout_fraction) << "\n"
     << "day_sd_floor = " << shortest(cfg.thresholds.day_sd_floor) << "\n"
     << "cover_recordings = " << (cfg.thresholds.cover_recordings ? "true" : "false") << "\n"
     << "\n[decision]\nk = " << cfg.decision.k << "\nn = " << cfg.decision.n << "\n"
     << "sequential = \"" << (cfg.decision.sequential.enabled ? "cusum" : "off") << "\"\n"
     << "cusum_k = " << shortest(cfg.decision.sequential.k) << "\n"
     << "cusum_warn = " << shortest(cfg.decision.sequential.h_warn) << "\n"
     << "cusum_alarm = " << shortest(cfg.decision.sequential.h_alarm) << "\n"
     << "cusum_day_allowance = " << shortest(cfg.decision.sequential.day_allowance) << "\n"
     << "cusum_step_cap = " << shortest(cfg.decision.sequential.step_cap) << "\n"
     << "band_cusum = " << (cfg.decision.band.enabled ? "true" : "false") << "\n"
     << "band_cusum_k = " << shortest(cfg.decision.band.k) << "\n"
     << "band_cusum_h = " << shortest(cfg.decision.band.h) << "\n"
     << "band_cusum_day_allowance = " << shortest(cfg.decision.band.day_allowance) << "\n"
     << "band_cusum_step_cap = " << shortest(cfg.decision.band.step_cap) << "\n"
     << "band_count = " << cfg.decision.band.band_count << "\n"
     << "mesh_cusum = " << (cfg.decision.mesh.enabled ? "true" : "false") << "\n"
     << "mesh_cusum_k = " << shortest(cfg.decision.mesh.k) << "\n"
     << "mesh_cusum_h = " << shortest(cfg.decision.mesh.h) << "\n"
     << "mesh_cusum_one_day_allowance = " << shortest(cfg.decision.mesh.one_day_allowance) << "\n"
     << "mesh_cusum_step_cap = " << shortest(cfg.decision.mesh.step_cap) << "\n"
     << "\n[monitor]\nmethod = \"" << dsp::method_name(cfg.method) << "\"\n"
     << "line_gain = " << (cfg.thresholds.ptda_line_gain ? "true" : "false") << "\n"
     << "floor_gain = " << (cfg.thresholds.ptda_floor_gain ? "true" : "false") << "\n"
     << "\n[gearbox]\n"
     << "kind = \"" << gearbox_kind_name(cfg.gearbox.kind) << "\"\n";
  // Teeth only for a known kind, ratio only when known: exactly what parses back to this config.
  if (cfg.gearbox.kind != GearKind::kUnknown) {
    os << "z_in = " << cfg.gearbox.z_in << "\nz_spur = " << cfg.gearbox.z_spur
       << "\nz_pin = " << cfg.gearbox.z_pin << "\n";
  }
  if (cfg.gearbox.ratio > 0.0) os << "ratio = " << shortest(cfg.gearbox.ratio) << "\n";
  return os.str();
}

}  // namespace ptda::config
