// ptda monitor --recording DIR --config FILE --baseline BASELINE [--method M] [--jsonl OUT] [--windows F:T]
#include <algorithm>
#include <fstream>
#include <iostream>
#include <ostream>

#include "ptda/cli/args.hpp"
#include "ptda/cli/commands.hpp"
#include "ptda/cli/doctor.hpp"
#include "ptda/cli/jsonl.hpp"
#include "ptda/cli/monitor_output.hpp"
#include "ptda/cli/pipeline_runner.hpp"
#include "ptda/cli/text.hpp"
#include "ptda/common/error.hpp"
#include "ptda/common/time.hpp"
#include "ptda/config/pipeline_config.hpp"
#include "ptda/dsp/mesh_modulation.hpp"
#include "ptda/formats/baseline_file.hpp"

namespace ptda::cli {

namespace {

std::string band_text(const dsp::Band& b) {
  return "[" + general(b.lo, 4) + ", " + general(b.hi, 4) + "]";
}

// " > " above the band, " < " below, "   " inside (NaN is outside: shown as "?").
std::string relation(double v, const dsp::Band& b) {
  if (b.contains(v)) return "   ";
  if (v > b.hi) return " > ";
  if (v < b.lo) return " < ";
  return " ? ";
}

}  // namespace

std::string window_json(const dsp::WindowResult& w, dsp::Method method) {
  return window_json(w, method, dsp::Domain::kTime);
}

std::string window_json(const dsp::WindowResult& w, dsp::Method method, dsp::Domain domain) {
  JsonObject o;
  o.add("n", static_cast<std::uint64_t>(w.ref.seq));
  o.add("t_start", ns_to_seconds(w.ref.t_start_ns));
  o.add("t_end", ns_to_seconds(w.ref.t_end_ns));
  const bool scored = w.status == dsp::WindowStatus::kScored;
  o.add_optional("segment", w.class_id >= 0 ? std::optional<std::int64_t>(w.class_id) : std::nullopt);
  o.add("region", static_cast<std::uint64_t>(w.ref.region_seq));
  o.add("speed_rad_s", w.ref.speed_rad_s);
  o.add("status", scored ? "scored" : "no_class");
  o.add("method", dsp::method_name(method));
  // The order domain is marked; time-domain lines stay as they were (no key).
  if (domain == dsp::Domain::kOrder) o.add("domain", dsp::domain_name(domain));
  if (scored) {
    o.add("rms_res", w.features.rms_res);
    o.add("entropy_res", w.features.entropy_res);
    o.add_pair("rms_band", w.thresholds.rms.lo, w.thresholds.rms.hi);
    o.add_pair("entropy_band", w.thresholds.entropy.lo, w.thresholds.entropy.hi);
  } else {
    o.add_null("rms_res").add_null("entropy_res").add_null("rms_band").add_null("entropy_band");
  }
  o.add("rms_out", scored && w.verdict.rms_out);
  o.add("entropy_out", scored && w.verdict.entropy_out);
  o.add("abnormal", scored && w.verdict.abnormal());
  o.add("alarm", w.alarm);
  o.add("abnormal_in_last_n", static_cast<std::uint64_t>(w.abnormal_in_last_n));
  // Low residual (below the healthy band): its own cause, not a gear fault (docs/method.md).
  o.add("rms_low", scored && w.verdict.rms_low);
  o.add("detector", dsp::alarm_detector_name(w.detector));
  o.add("kofn_alarm", w.kofn_alarm);
  o.add("seq_alarm", w.seq_alarm);
  o.add("seq_warn", w.seq_warn);
  if (scored) {
    o.add("z_rms", w.z_rms);
    o.add("z_entropy", w.z_entropy);
    o.add("cusum", w.seq_statistic);
    o.add("cusum_feature", dsp::seq_feature_name(w.seq_feature));
  } else {
    o.add_null("z_rms").add_null("z_entropy").add_null("cusum").add_null("cusum_feature");
  }
  o.add("cusum_max", w.seq_max_statistic);
  if (w.band_on) {  // the band CUSUM (only when [decision] band_cusum is on: other lines stay as before)
    o.add("band_alarm", w.band_alarm);
    if (scored) {
      o.add("band_z_max", w.band_z_max);
      o.add("band_cusum", w.band_statistic);
      o.add_optional("band_cusum_band",
                     w.band_index >= 0 ? std::optional<std::int64_t>(w.band_index) : std::nullopt);
    } else {
      o.add_null("band_z_max").add_null("band_cusum").add_null("band_cusum_band");
    }
    o.add("band_cusum_max", w.band_max_statistic);
    o.add_optional("band",
                   w.band_max_index >= 0 ? std::optional<std::int64_t>(w.band_max_index) : std::nullopt);
    if (w.band_max_index >= 0) {
      o.add_pair("band_hz", w.band_lo_hz, w.band_hi_hz);
    } else {
      o.add_null("band_hz");
    }
  }
  if (w.mesh_on) {                      // the mesh CUSUM (only when [decision] mesh_cusum is on)
    o.add("mesh_alarm", w.mesh_alarm);  // NaN values below are written as null
    o.add("mesh_am", w.mesh_value[0]);
    o.add("mesh_pm", w.mesh_value[1]);
    o.add("mesh_excess_am", w.mesh_excess[0]);
    o.add("mesh_excess_pm", w.mesh_excess[1]);
    if (scored) {
      o.add("mesh_cusum", w.mesh_statistic);
      o.add("mesh_cusum_feature", dsp::mesh_feature_label(w.mesh_feature));
    } else {
      o.add_null("mesh_cusum").add_null("mesh_cusum_feature");
    }
    o.add("mesh_cusum_max", w.mesh_max_statistic);
    o.add("mesh_feature", dsp::mesh_feature_label(w.mesh_max_feature));
  }
  return o.str();
}

std::string window_table_header() {
  return pad_left("n", 6) + pad_left("t [s]", 10) + pad_left("class", 7) + pad_left("speed", 10) + "  " +
         pad_left("rms_res", 10) + "   " + pad_right("rms band", 20) + pad_left("entropy", 8) + "   " +
         pad_right("entropy band", 18) + "verdict\n";
}

std::string window_table_row(const dsp::WindowResult& w, std::int64_t t0_ns, std::uint32_t decision_n) {
  std::string s = pad_left(std::to_string(w.ref.seq), 6) +
                  pad_left(fixed(ns_to_seconds(w.ref.t_start_ns - t0_ns), 3), 10);
  if (w.status != dsp::WindowStatus::kScored) {
    return s + pad_left("-", 7) + pad_left(fixed(w.ref.speed_rad_s, 3), 10) +
           "  no segment class matches this speed: not scored\n";
  }
  s += pad_left(std::to_string(w.class_id), 7) + pad_left(fixed(w.ref.speed_rad_s, 3), 10) + "  " +
       pad_left(general(w.features.rms_res, 5), 10) + relation(w.features.rms_res, w.thresholds.rms) +
       pad_right(band_text(w.thresholds.rms), 20) + pad_left(fixed(w.features.entropy_res, 4), 8) +
       relation(w.features.entropy_res, w.thresholds.entropy) +
       pad_right(band_text(w.thresholds.entropy), 18);
  if (w.verdict.abnormal()) {
    s += "ABNORMAL(";
    s += w.verdict.rms_out ? (w.verdict.entropy_out ? "rms+entropy" : "rms") : "entropy";
    s += ")";
  } else {
    s += "ok";
  }
  if (w.verdict.rms_low) s += " low-residual";
  if (w.alarm) {
    s += " ALARM (";
    if (w.kofn_alarm)
      s += std::to_string(w.abnormal_in_last_n) + " of the last " + std::to_string(decision_n);
    if (w.kofn_alarm && w.seq_alarm) s += "; ";
    if (w.seq_alarm) s += "CUSUM " + general(w.seq_max_statistic, 3);
    if (w.band_alarm) {
      if (w.kofn_alarm || w.seq_alarm) s += "; ";
      s += "band CUSUM " + general(w.band_max_statistic, 3) + " in band " + std::to_string(w.band_max_index) +
           " (" + general(w.band_lo_hz, 4) + "-" + general(w.band_hi_hz, 4) + " Hz)";
    }
    if (w.mesh_alarm) {
      if (w.kofn_alarm || w.seq_alarm || w.band_alarm) s += "; ";
      s += "mesh CUSUM " + general(w.mesh_max_statistic, 3) + " on " +
           dsp::mesh_feature_label(w.mesh_max_feature) + " (the mesh's " +
           (w.mesh_max_feature == 0 ? "amplitude" : "phase") +
           " modulation repeats once per input-shaft revolution)";
    }
    s += ")";
  } else if (w.seq_warn) {
    s += " warning (CUSUM " + general(w.seq_max_statistic, 3) + ")";
  }
  return s + "\n";
}

void summarize_add(MonitorSummary& s, const dsp::WindowResult& w) {
  ++s.windows;
  if (w.status != dsp::WindowStatus::kScored) {
    ++s.no_class;
    return;
  }
  ++s.scored;
  s.rms_sum += w.features.rms_res;
  s.entropy_sum += w.features.entropy_res;
  if (w.verdict.rms_low) ++s.rms_low;
  if (w.verdict.abnormal()) {
    ++s.abnormal;
    if (w.verdict.rms_out) ++s.rms_out;
    if (w.verdict.entropy_out) ++s.entropy_out;
    if (!s.first_abnormal) s.first_abnormal = w;
  }
  if (w.alarm) {
    ++s.alarm_windows;
    if (!s.first_alarm) s.first_alarm = w;
  }
}

MonitorSummary summarize(const std::vector<dsp::WindowResult>& windows, std::int64_t t0_ns) {
  MonitorSummary s;
  for (const auto& w : windows) summarize_add(s, w);
  s.t0_ns = t0_ns;
  return s;
}

void print_summary(std::ostream& out, const MonitorSummary& s, const dsp::SlicerCounters& slicer,
                   const CanCounters& can, dsp::Method method) {
  out << "summary (" << dsp::method_name(method) << "): " << s.windows << " windows, " << s.scored
      << " scored, " << s.no_class << " without a matching class\n";
  out << "  abnormal   " << s.abnormal << " (rms " << s.rms_out << ", entropy " << s.entropy_out << ")";
  if (s.rms_low > 0) {
    out << "; low residual (below the healthy band: sensor or mesh suspicion, not a gear fault) in "
        << s.rms_low << " windows";
  }
  if (s.first_abnormal) {
    out << ", first at " << fixed(ns_to_seconds(s.first_abnormal->ref.t_start_ns - s.t0_ns), 3)
        << " s (window " << s.first_abnormal->ref.seq << ")";
  }
  out << "\n";
  if (s.first_alarm) {
    const double t = ns_to_seconds(s.first_alarm->ref.t_start_ns);
    out << "  ALARM      first raised at " << fixed(ns_to_seconds(s.first_alarm->ref.t_start_ns - s.t0_ns), 3)
        << " s (window " << s.first_alarm->ref.seq << ", " << utc_time(t) << ") by "
        << dsp::alarm_detector_name(s.first_alarm->detector) << ", active in " << s.alarm_windows
        << " windows\n";
  } else {
    out << "  alarm      never raised\n";
  }
  if (s.scored > 0) {
    out << "  mean       rms_res " << general(s.rms_sum / static_cast<double>(s.scored), 6)
        << ", entropy_res " << fixed(s.entropy_sum / static_cast<double>(s.scored), 4) << "\n";
  }
  out << "  slicer     " << slicer.regions << " regions, " << slicer.windows_invalid << " invalid windows, "
      << slicer.windows_lost << " lost and " << slicer.windows_overflow << " overflowed windows, "
      << slicer.speed_gaps << " speed gaps, " << slicer.speed_out_of_order << " out-of-order and "
      << slicer.speed_out_of_range << " out-of-range speed samples, " << slicer.samples_nonfinite
      << " non-finite and " << slicer.samples_clipped << " clipped samples\n";
  out << "  CAN        " << can.frames << " frames: " << can.speed_frames << " speed, " << can.other_id
      << " other ids, " << can.wrong_dlc << " wrong DLC, " << can.rtr << " remote, " << can.error_frames
      << " error frames\n";
}

void print_coverage(std::ostream& out, const dsp::CoverageState& c, const dsp::Baseline& baseline,
                    double timeout_s, std::int64_t t0_ns) {
  const std::uint64_t unmatched = c.unmatched_total();
  out << "  coverage   " << c.judged << " windows judged, " << unmatched << " cut but not judged (speed "
      << c.unmatched[static_cast<std::size_t>(dsp::UnmatchedReason::kSpeed)] << ", direction "
      << c.unmatched[static_cast<std::size_t>(dsp::UnmatchedReason::kDirection)] << ", invalid "
      << c.unmatched[static_cast<std::size_t>(dsp::UnmatchedReason::kInvalid)] << "); "
      << fixed(c.moving_ns * 1e-9, 1) << " s of motion, " << fixed(c.moving_since_judged_s(), 1)
      << " s since the last judged window\n";
  for (std::size_t i = 0; i < baseline.classes.size(); ++i) {
    const dsp::SegmentClass& seg = baseline.classes[i].segment;
    out << "  class " << pad_right(std::to_string(seg.id), 4) << " " << (seg.direction < 0 ? "-" : "+")
        << fixed(seg.speed_rad_s, 3) << " rad/s: ";
    if (i >= dsp::kCoverageMaxClasses) {
      out << "not tracked\n";
      continue;
    }
    const dsp::ClassCoverage& k = c.classes[i];
    out << k.judged << " judged";
    if (k.have) {
      out << ", last ending at " << fixed(ns_to_seconds(k.last_t_ns - t0_ns), 3) << " s";
    }
    if (!c.class_current(static_cast<std::uint32_t>(i), timeout_s)) out << "  (NOT JUDGED RECENTLY)";
    out << "\n";
  }
  if (c.speed_bins > 0) {
    out << "  unmatched  speeds seen:";
    for (std::uint32_t i = 0; i < c.speed_bins; ++i) {
      out << (i == 0 ? " " : ", ") << fixed(c.speeds[i].speed_rad_s, 3) << " rad/s x " << c.speeds[i].count;
    }
    if (c.speeds_not_binned > 0) out << ", " << c.speeds_not_binned << " more at other speeds";
    out << "\n";
  }
  char text[256];
  dsp::describe_coverage(c, baseline, timeout_s, text, sizeof text);
  // The text starts with the state ("not judging: ...", "partial coverage: ..."); full has none.
  out << "  state      " << (text[0] != '\0' ? std::string_view(text) : dsp::coverage_level_name(c.level))
      << " (timeout " << general(timeout_s) << " s of motion)\n";
}

std::size_t print_coverage_warnings(std::ostream& out, const dsp::CoverageState& c,
                                    const dsp::Baseline& baseline, double timeout_s) {
  std::size_t n = 0;
  char text[256];
  dsp::describe_coverage(c, baseline, timeout_s, text, sizeof text);
  if (c.judged == 0) {
    out << "warning: judged nothing: no window matched a class of the baseline" << (text[0] ? " (" : "")
        << text << (text[0] ? ")" : "") << "\n";
    ++n;
  } else if (c.level == dsp::CoverageLevel::kNotJudging || c.level == dsp::CoverageLevel::kPartial) {
    out << "warning: low coverage: " << text << "\n";
    ++n;
  }
  const std::uint64_t cut = c.judged + c.unmatched_total();
  if (c.judged > 0 && 2 * c.judged < cut) {
    out << "warning: low coverage: only " << c.judged << " of " << cut << " windows cut were judged\n";
    ++n;
  }
  return n;
}

void WindowSpan::add(const dsp::WindowResult& w) noexcept {
  if (!any) {
    any = true;
    from_ns = w.ref.t_start_ns;
    to_ns = w.ref.t_end_ns;
  }
  from_ns = std::min(from_ns, w.ref.t_start_ns);
  to_ns = std::max(to_ns, w.ref.t_end_ns);
}

bool print_training_overlap(std::ostream& out, const dsp::Baseline& baseline, const std::string& recording_id,
                            const std::vector<dsp::WindowResult>& windows, std::int64_t t0_ns) {
  WindowSpan span;
  for (const auto& w : windows) span.add(w);
  return print_training_overlap(out, baseline, recording_id, span, t0_ns);
}

bool print_training_overlap(std::ostream& out, const dsp::Baseline& baseline, const std::string& recording_id,
                            const WindowSpan& judged, std::int64_t t0_ns) {
  if (baseline.training.empty()) {
    out << "note: the baseline does not list its training recordings (format version 1 or field "
           "training): in-sample use not checked\n";
    return false;
  }
  if (!judged.any) return false;
  const std::int64_t from_ns = judged.from_ns;
  const std::int64_t to_ns = judged.to_ns;
  const double t0_s = ns_to_seconds(t0_ns);
  const auto span = [&](double a_s, double b_s) {
    return fixed(a_s - t0_s, 1) + "-" + fixed(b_s - t0_s, 1) + " s";
  };
  const double from_s = ns_to_seconds(from_ns);
  const double to_s = ns_to_seconds(to_ns);
  bool warned = false;
  for (const dsp::TrainingRecording& t : baseline.training) {
    if (t.id != recording_id) continue;
    const double lo = std::max(from_s, t.from_unix_s);
    const double hi = std::min(to_s, t.to_unix_s);
    if (lo < hi) {
      out << "warning: in-sample: this recording is the baseline's training recording " << t.path << " (id "
          << t.id << "): the windows judged (" << span(from_s, to_s) << ") overlap the " << t.windows
          << " windows trained on (" << span(t.from_unix_s, t.to_unix_s)
          << "); judge data the baseline did not see (e.g. train --windows 0:0.5, monitor --windows 0.5:1)\n";
      warned = true;
    } else {
      out << "note: this recording is the baseline's training recording " << t.path
          << ", but the windows judged (" << span(from_s, to_s) << ") do not overlap the ones trained on ("
          << span(t.from_unix_s, t.to_unix_s) << "): a held-out part\n";
    }
  }
  return warned;
}

MonitorInputs load_monitor_inputs(const std::string& recording, const std::string& config_path,
                                  const std::string& baseline_path) {
  MonitorInputs in;
  in.config_path = config_path;
  in.baseline_path = baseline_path;
  in.rec = open_recording(recording);
  in.cfg = config::load_pipeline_config(config_path);
  for (const std::string& w : in.cfg.warnings) std::cerr << "warning: " << w << "\n";
  in.baseline = formats::read_baseline(baseline_path);
  in.fs_hz = pipeline_fs_hz(in.rec, in.cfg, config_path);
  check_baseline_matches(in.baseline, baseline_path, in.cfg, config_path, in.fs_hz, in.rec.wav_path.string());
  if (in.cfg.thresholds.ptda_line_gain != in.baseline.policy.ptda_line_gain) {
    // The bands only hold for the residual they were trained on, so the baseline decides.
    std::cerr << "warning: " << config_path
              << ": [monitor] line_gain = " << (in.cfg.thresholds.ptda_line_gain ? "true" : "false")
              << ", but " << baseline_path
              << " was trained with line_gain = " << (in.baseline.policy.ptda_line_gain ? "true" : "false")
              << "; the baseline's setting is used (retrain to change it)\n";
  }
  if (in.cfg.thresholds.ptda_floor_gain != in.baseline.policy.ptda_floor_gain) {
    std::cerr << "warning: " << config_path
              << ": [monitor] floor_gain = " << (in.cfg.thresholds.ptda_floor_gain ? "true" : "false")
              << ", but " << baseline_path
              << " was trained with floor_gain = " << (in.baseline.policy.ptda_floor_gain ? "true" : "false")
              << "; the baseline's setting is used (retrain to change it)\n";
  }
  return in;
}

int cmd_monitor(std::span<const std::string> args, std::ostream& out) {
  ArgParser parser(
      "monitor",
      "--recording DIR --config FILE --baseline BASELINE [--method ptda|tda|raw] [--jsonl OUT] [--windows "
      "F:T]",
      "Replays a recording through the monitoring engine (the same one the daemon runs): constant-speed\n"
      "windows, residual by the chosen method, RMS and spectral entropy against the class's bands, k-of-n\n"
      "alarm. Prints a table of the windows and a summary; --jsonl writes one JSON object per window.");
  parser.option("recording", "DIR", "recording directory", true)
      .option("config", "FILE", "pipeline configuration TOML (the one used for training)", true)
      .option("baseline", "BASELINE", "baseline file written by ptda train", true)
      .option("method", "ptda|tda|raw", "how the deterministic part is removed (default: [monitor] method)")
      .option("jsonl", "OUT", "write one JSON object per window to OUT ('-' = stdout, then no table)")
      .option("windows", "FROM:TO", "report only this fraction of the windows (alarm recomputed over them)")
      .option("coverage-timeout", "S",
              "seconds of motion without a judged window before the run counts as not judging (default 60)")
      .flag("quiet", "print only the summary, not the table of windows");
  const ParsedArgs a = parser.parse(args);
  if (a.help()) {
    out << parser.help_text();
    return kExitOk;
  }
  std::optional<dsp::Method> method_opt;
  if (a.has("method")) {
    method_opt = dsp::parse_method(a.value("method"));
    if (!method_opt) throw UsageError("--method: expected ptda, tda or raw, got '" + a.value("method") + "'");
  }
  FractionRange range;
  if (a.has("windows")) range = parse_fraction_range(a.value("windows"), "windows");
  RunOptions opts;
  if (a.has("coverage-timeout")) {
    opts.coverage_timeout_s = parse_double_arg(a.value("coverage-timeout"), "coverage-timeout");
    if (!(opts.coverage_timeout_s > 0.0 && opts.coverage_timeout_s <= 86400.0))
      throw UsageError("--coverage-timeout: must be in (0, 86400] seconds, got " +
                       a.value("coverage-timeout"));
  }

  MonitorInputs in = load_monitor_inputs(a.value("recording"), a.value("config"), a.value("baseline"));
  const dsp::Method method = method_opt.value_or(in.cfg.method);
  if (in.cfg.decision.band.enabled) {
    if (const std::string why = dsp::band_cusum_unusable(in.cfg.decision, in.baseline, method);
        !why.empty() && !in.cfg.decision.band.required) {
      std::cerr << "note: band detector off: " << why << " (k-of-n and the feature CUSUM still judge)\n";
    }
  }

  if (in.cfg.decision.mesh.enabled && !in.cfg.decision.mesh.required) {
    if (const std::string why = dsp::mesh_cusum_unusable(in.cfg.decision, in.baseline); !why.empty())
      std::cerr << "note: mesh detector off: " << why << " (the other detectors still judge)\n";
  }
  if (in.cfg.decision.mesh.enabled && in.baseline.policy.mesh_stats) {
    // Say which classes the mesh detector cannot watch (too slow for two input-shaft revolutions per
    // window, or no mesh line): a commissioning engineer should not take its silence there as health.
    std::string without;
    std::size_t with = 0;
    for (const dsp::ClassBaseline& c : in.baseline.classes) {
      bool on = c.mesh_stats.size() == dsp::kMeshFeatureCount &&
                (c.mesh_stats[0].windows > 0 || c.mesh_stats[1].windows > 0);
      if (on) {
        // As the engine decides: no mesh line at the class's speed also leaves the class without it.
        try {
          const dsp::MeshDemodulator d(
              dsp::mesh_geometry(in.baseline.fs_hz, in.baseline.window_len, in.baseline.gearbox, c.segment),
              c.mean_magnitude);
          on = d.line_harmonics() > 0;
        } catch (const Error&) {
          on = false;  // the engine reports the reason when it is built
        }
      }
      if (on) {
        ++with;
      } else {
        without += (without.empty() ? "" : ", ") + std::to_string(c.segment.id);
      }
    }
    if (!without.empty()) {
      std::cerr << "note: mesh detector on for " << with << " of " << in.baseline.classes.size()
                << " classes; none for class(es) " << without
                << " (fewer than 2 input-shaft revolutions per window, or no mesh line: see ptda train)\n";
    }
  }

  // Open the JSONL output before the long run so a bad path fails fast.
  const std::string jsonl_path = a.value_or("jsonl", "");
  std::ofstream jsonl_file;
  std::ostream* jsonl = nullptr;
  if (jsonl_path == "-") {
    jsonl = &out;
  } else if (!jsonl_path.empty()) {
    jsonl_file.open(jsonl_path, std::ios::out | std::ios::trunc);
    if (!jsonl_file) throw Error(jsonl_path + ": cannot open for writing");
    jsonl = &jsonl_file;
  }
  const bool table = jsonl_path != "-" && !a.has("quiet");

  opts.progress_label = "monitor " + in.rec.dir.filename().string();
  opts.config_source = in.config_path;
  const auto print_table_head = [&](std::size_t selected) {
    out << "monitor " << in.rec.dir.string() << " with " << dsp::method_name(method)
        << (in.cfg.domain == dsp::Domain::kOrder ? " (order domain)" : "") << " against " << in.baseline_path
        << " (" << in.baseline.classes.size() << " classes, N = " << in.baseline.window_len << ", alarm "
        << in.cfg.decision.k << " of " << in.cfg.decision.n << ")\n";
    if (!range.whole()) out << "windows " << a.value("windows") << ": " << selected << " windows\n";
    out << window_table_header();
  };
  // Each window goes to the table, the JSONL and the running summary as it is judged; the whole run keeps
  // none of them (memory does not grow with the recording). --windows needs the count first: it keeps
  // them, selects and recomputes the alarm over the selection.
  MonitorSummary summary;
  WindowSpan judged_span;
  std::size_t judged = 0;
  const auto emit = [&](const dsp::WindowResult& w) {
    if (table) out << window_table_row(w, in.rec.t0_ns, in.cfg.decision.n);
    if (jsonl != nullptr) *jsonl << window_json(w, method, in.cfg.domain) << "\n";
    summarize_add(summary, w);
    judged_span.add(w);
    judged += w.status == dsp::WindowStatus::kScored ? 1 : 0;
  };
  MonitorResult r;
  if (range.whole()) {
    if (table) print_table_head(0);
    const WindowObserver observer = [&](const dsp::WindowResult& w, const dsp::MonitorEngine&) { emit(w); };
    r = monitor_recording(in.rec, in.cfg, in.baseline, method, in.fs_hz, observer, opts, false);
  } else {
    r = monitor_recording(in.rec, in.cfg, in.baseline, method, in.fs_hz, {}, opts);
    const auto first = static_cast<std::ptrdiff_t>(range.first(r.windows.size()));
    const auto last = static_cast<std::ptrdiff_t>(range.last(r.windows.size()));
    r.windows = std::vector<dsp::WindowResult>(r.windows.begin() + first, r.windows.begin() + last);
    redebounce(r.windows, dsp::with_band_geometry(
                              dsp::effective_detectors(in.cfg.decision, in.baseline, method), in.baseline));
    if (table) print_table_head(r.windows.size());
    for (const auto& w : r.windows) emit(w);
    r.windows.clear();
    r.windows.shrink_to_fit();
  }
  summary.t0_ns = in.rec.t0_ns;
  if (jsonl != nullptr) {
    jsonl->flush();
    if (!*jsonl) throw Error(jsonl_path + ": write failed");
  }
  if (jsonl_path != "-") {
    print_summary(out, summary, r.slicer, r.can, method);
    if (r.domain == dsp::Domain::kOrder) {
      // The slicer line above is all zero in the order domain: the resampler's counters instead.
      const dsp::AngleResamplerCounters& rc = r.resampler;
      out << "  domain     order: " << r.order_windows_cut << " windows of " << in.cfg.order.revolutions
          << " revolutions x " << in.cfg.order.samples_per_rev << " samples; resampler " << rc.frames
          << " angle frames, " << rc.breaks << " breaks, " << rc.frames_no_angle << " frames without angle, "
          << rc.angle_inconsistent << " inconsistent angle steps, " << rc.samples_overrun
          << " samples overrun, " << rc.outputs_dropped << " outputs dropped\n";
    }
    print_coverage(out, r.coverage, in.baseline, opts.coverage_timeout_s, in.rec.t0_ns);
  }
  // With the JSONL on stdout the warnings go to stderr, so the JSONL stays clean.
  std::ostream& warn = jsonl_path == "-" ? std::cerr : out;
  print_coverage_warnings(warn, r.coverage, in.baseline, opts.coverage_timeout_s);
  if (r.coverage.judged == 0 && in.cfg.domain == dsp::Domain::kTime) {
    // Why nothing was judged, in the words of `ptda doctor` (its checks are the time domain's).
    const DoctorReport d =
        diagnose_commissioning(in.rec, in.cfg, in.config_path, &in.baseline, in.baseline_path);
    for (const DoctorFinding& f : d.findings) {
      if (f.kind == DoctorFinding::Kind::kProblem) warn << "diagnosis: " << f.text << "\n";
    }
  }
  print_training_overlap(warn, in.baseline, recording_id(in.rec), judged_span, in.rec.t0_ns);
  if (judged == 0 || r.coverage.level == dsp::CoverageLevel::kNotJudging) return kExitNotJudged;
  return kExitOk;
}

}  // namespace ptda::cli
