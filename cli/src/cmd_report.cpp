// ptda report --recording DIR [...] --config FILE --baseline BASELINE --html OUT [--label NAME ...]
#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>
#include <ostream>
#include <string_view>

#include "ptda/cli/args.hpp"
#include "ptda/cli/commands.hpp"
#include "ptda/cli/history_report.hpp"
#include "ptda/cli/monitor_output.hpp"
#include "ptda/cli/pipeline_runner.hpp"
#include "ptda/cli/report.hpp"
#include "ptda/cli/text.hpp"
#include "ptda/common/error.hpp"
#include "ptda/common/time.hpp"
#include "ptda/config/pipeline_config.hpp"
#include "ptda/dsp/analyzer.hpp"
#include "ptda/dsp/angle_resampler.hpp"
#include "ptda/formats/baseline_file.hpp"

namespace ptda::cli {

namespace {

constexpr std::array<dsp::Method, 3> kMethods = {dsp::Method::kRaw, dsp::Method::kTda, dsp::Method::kPtda};

/// A window kept during the verdict method's run as a candidate example. Only the best candidate of
/// each kind per recording is kept, so memory stays at a few windows whatever the recording length.
struct CapturedWindow {
  bool valid = false;
  double excess = 0.0;  ///< band_excess(): > 0 outside the band
  dsp::WindowResult result;
  std::vector<float> raw;
};

struct RecordingEvidence {
  CapturedWindow most_abnormal;   ///< the abnormal window furthest outside its band
  CapturedWindow closest_normal;  ///< the normal window closest to its band
};

const dsp::ClassBaseline* find_class(const dsp::Baseline& baseline, std::int32_t class_id) {
  for (const auto& k : baseline.classes) {
    if (static_cast<std::int32_t>(k.segment.id) == class_id) return &k;
  }
  return nullptr;
}

/// The joint speed at which the input shaft turns once per second: gear_orders() at it gives the gearbox's
/// frequencies in input-shaft orders (order domain).
double shaft_order_speed_rad_s(const dsp::Baseline& baseline) {
  return baseline.gearbox.ratio > 0.0 ? 2.0 * std::numbers::pi / baseline.gearbox.ratio : 0.0;
}

std::string feature_text(const dsp::WindowResult& w) {
  const auto& t = w.thresholds;
  return "rms_res " + general(w.features.rms_res, 5) + " (band " + general(t.rms.lo, 5) + ".." +
         general(t.rms.hi, 5) + "), entropy_res " + fixed(w.features.entropy_res, 4) + " (band " +
         fixed(t.entropy.lo, 4) + ".." + fixed(t.entropy.hi, 4) + ")";
}

WindowExample make_example(const CapturedWindow& c, const std::string& title, const dsp::Baseline& baseline,
                           double fs_hz, bool order, dsp::WindowAnalyzer& analyzer) {
  WindowExample ex;
  ex.title = title;
  ex.fs_hz = fs_hz;
  ex.raw = c.raw;
  ex.orders =
      gear_orders(baseline.gearbox, order ? shaft_order_speed_rad_s(baseline) : c.result.ref.speed_rad_s);
  const dsp::ClassBaseline* cls = find_class(baseline, c.result.class_id);
  if (cls == nullptr) return ex;
  (void)analyzer.analyze(c.raw, *cls, dsp::Method::kTda);
  ex.det_tda.assign(analyzer.deterministic().begin(), analyzer.deterministic().end());
  ex.res_tda.assign(analyzer.residual().begin(), analyzer.residual().end());
  (void)analyzer.analyze(c.raw, *cls, dsp::Method::kPtda);
  ex.det_ptda.assign(analyzer.deterministic().begin(), analyzer.deterministic().end());
  ex.res_ptda.assign(analyzer.residual().begin(), analyzer.residual().end());
  return ex;
}

EnvelopeBand parse_envelope_band(const std::string& text, double fs_hz, bool order) {
  const char* unit = order ? " orders" : " Hz";
  const auto colon = text.find(':');
  if (colon == std::string::npos) {
    throw UsageError(order ? "--envelope-band: expected LO:HI in input-shaft orders (order domain) such as "
                             "40:120, got '" +
                                 text + "'"
                           : "--envelope-band: expected LO:HI in Hz such as 2000:4000, got '" + text + "'");
  }
  EnvelopeBand b;
  b.lo_hz = parse_double_arg(std::string_view(text).substr(0, colon), "envelope-band");
  b.hi_hz = parse_double_arg(std::string_view(text).substr(colon + 1), "envelope-band");
  if (!(b.lo_hz >= 0.0) || !(b.lo_hz < b.hi_hz) || !(b.hi_hz <= fs_hz / 2.0)) {
    throw UsageError(std::string("--envelope-band: need 0 <= LO < HI <= ") +
                     (order ? "samples_per_rev/2 = " : "fs/2 = ") + general(fs_hz / 2.0, 10) + unit +
                     ", got '" + text + "'");
  }
  b.reason = "given by --envelope-band";
  return b;
}

}  // namespace

int cmd_report(std::span<const std::string> args, std::ostream& out) {
  ArgParser parser(
      "report",
      "--recording DIR [--recording DIR ...] --config FILE --baseline BASELINE --html OUT [--label NAME "
      "...]\n"
      "       [--envelope-band LO:HI]\n"
      "       ptda report --history DIR --html OUT [--last-hours H]",
      "Monitors each recording with raw, TDA and PTDA residuals and writes one self-contained HTML file:\n"
      "a verdict per recording, the gearbox orders, the feature trends against the class bands on a time\n"
      "axis, and per recording its most abnormal window and its normal window closest to the band (raw,\n"
      "deterministic and residual parts in time, as dB spectra, zoomed on the GMF harmonics, and as\n"
      "envelope spectra).");
  parser
      .option("recording", "DIR",
              "recording directory (e.g. a healthy and a faulty one) (required unless --history)", false,
              true)
      .option("config", "FILE", "pipeline configuration TOML (required unless --history)")
      .option("baseline", "BASELINE", "baseline file written by ptda train (required unless --history)")
      .option("html", "OUT", "HTML file to write", true)
      .option("history", "DIR",
              "instead of recordings: a daemon's event history ([history] dir; docs/fleet.md): its trends, "
              "alarms\n"
              "                         and state changes")
      .option("last-hours", "H", "with --history: only its last H hours (default: all of it)")
      .option("label", "NAME", "name of each recording in the report, in --recording order", false, true)
      .option("envelope-band", "LO:HI",
              "band of the envelope spectra in Hz (default: chosen from the most abnormal window)");
  const ParsedArgs a = parser.parse(args);
  if (a.help()) {
    out << parser.help_text();
    return kExitOk;
  }
  if (a.has("history")) {
    for (const char* o : {"recording", "config", "baseline", "label", "envelope-band"}) {
      if (a.has(o))
        throw UsageError(std::string("--") + o + " does not go with --history (a history has no samples)");
    }
    HistoryReadOptions ho;
    if (a.has("last-hours")) {
      ho.last_hours = parse_double_arg(a.value("last-hours"), "last-hours");
      if (!(ho.last_hours > 0.0))
        throw UsageError("--last-hours: must be > 0, got '" + a.value("last-hours") + "'");
    }
    const ReportData data = history_report_data(a.value("history"), ho);
    write_html_report(a.value("html"), data);
    out << "report: " << a.value("html") << " (" << data.recordings.front().verdict << ")\n";
    return kExitOk;
  }
  if (a.has("last-hours")) throw UsageError("--last-hours goes with --history");
  for (const auto& [o, v] : {std::pair{"recording", "DIR"}, {"config", "FILE"}, {"baseline", "BASELINE"}}) {
    if (!a.has(o)) {
      throw UsageError(std::string("missing required option --") + o + " " + v +
                       " (or --history DIR for a daemon's event history)");
    }
  }
  const std::vector<std::string> recordings = a.values("recording");
  std::vector<std::string> labels = a.values("label");
  if (!labels.empty() && labels.size() != recordings.size()) {
    throw UsageError("--label given " + std::to_string(labels.size()) + " time(s) for " +
                     std::to_string(recordings.size()) + " recording(s): give one per recording or none");
  }
  const std::string config_path = a.value("config");
  const std::string baseline_path = a.value("baseline");
  const std::string html_path = a.value("html");

  std::vector<MonitorInputs> inputs;
  for (std::size_t i = 0; i < recordings.size(); ++i) {
    inputs.push_back(load_monitor_inputs(recordings[i], config_path, baseline_path));
    if (labels.size() < recordings.size()) {
      labels.push_back(inputs.back().rec.dir.filename().string());
    }
  }
  const dsp::Baseline& baseline = inputs.front().baseline;
  const double fs_hz = inputs.front().fs_hz;
  // Order domain: the windows are on the input shaft's angle axis, S samples per revolution (the
  // baseline's fs_hz), so the examples' "rate" is S and their spectra are over input-shaft orders.
  const bool order = inputs.front().cfg.domain == dsp::Domain::kOrder;
  const double example_rate = order ? baseline.fs_hz : fs_hz;
  const dsp::Method verdict_method = inputs.front().cfg.method;
  const std::string verdict_name(dsp::method_name(verdict_method));
  std::optional<EnvelopeBand> given_band;
  if (a.has("envelope-band")) given_band = parse_envelope_band(a.value("envelope-band"), example_rate, order);

  ReportData data;
  data.title = "PTDA condition monitoring report";
  data.signal_unit = inputs.front().rec.meta.unit;
  data.gearbox = baseline.gearbox;
  for (const auto& c : baseline.classes) {
    data.class_speeds_rad_s.emplace_back(static_cast<std::int32_t>(c.segment.id),
                                         c.segment.direction * c.segment.speed_rad_s);
  }
  data.summary.emplace_back("baseline", baseline_path);
  data.summary.emplace_back("trained on", baseline.source);
  data.summary.emplace_back("configuration", config_path);
  data.order_domain = order;
  // The windows hold nothing above the resampler's pass band (their bins there are set to 0).
  if (order)
    data.spectrum_max_hz =
        dsp::AngleResampler::pass_order_of(config::angle_resampler_config(inputs.front().cfg));
  data.summary.emplace_back("sample rate", general(fs_hz, 10) + " Hz");
  if (order) {
    data.summary.emplace_back("domain", "order: resampled to " + std::to_string(baseline.samples_per_rev) +
                                            " samples per input-shaft revolution from the CAN angle "
                                            "(docs/method.md §9)");
    data.summary.emplace_back("window length", std::to_string(baseline.window_len) + " samples (" +
                                                   std::to_string(baseline.revolutions) +
                                                   " input-shaft revolutions)");
  } else {
    data.summary.emplace_back("window length", std::to_string(baseline.window_len) + " samples (" +
                                                   fixed(1000.0 * baseline.window_len / fs_hz, 1) + " ms)");
  }
  data.summary.emplace_back("segment classes", std::to_string(baseline.classes.size()));
  data.summary.emplace_back("alarm rule",
                            std::to_string(inputs.front().cfg.decision.k) + " abnormal of the last " +
                                std::to_string(inputs.front().cfg.decision.n) + " scored windows");
  data.summary.emplace_back("verdict method", verdict_name);
  data.summary.emplace_back("times", "seconds from the start of each recording");
  for (std::size_t i = 0; i < inputs.size(); ++i) {
    RecordingSummary r;
    r.label = labels[i];
    r.duration_s = inputs[i].rec.duration_s;
    data.recordings.push_back(std::move(r));
  }

  std::vector<RecordingEvidence> evidence(inputs.size());
  out << pad_right("recording", 18) << pad_right("method", 8) << pad_left("scored", 8)
      << pad_left("abnormal", 10) << pad_left("alarm at [s]", 14) << pad_left("mean rms_res", 14)
      << pad_left("mean entropy", 14) << "\n";
  for (const dsp::Method method : kMethods) {
    MethodTrend trend;
    trend.method = std::string(dsp::method_name(method));
    // Order domain: a window's duration depends on the speed; the shading uses the longest one seen.
    trend.window_s = order ? 0.0 : static_cast<double>(baseline.window_len) / fs_hz;
    for (const auto& c : baseline.classes) {
      trend.class_thresholds.emplace_back(static_cast<std::int32_t>(c.segment.id),
                                          c.thresholds[static_cast<std::size_t>(method)]);
    }
    for (std::size_t i = 0; i < inputs.size(); ++i) {
      const MonitorInputs& in = inputs[i];
      WindowObserver observer;
      if (method == verdict_method) {
        observer = [&ev = evidence[i]](const dsp::WindowResult& w, const dsp::MonitorEngine& engine) {
          if (w.status != dsp::WindowStatus::kScored) return;
          const double e = band_excess(w.features, w.thresholds);
          CapturedWindow& slot = w.verdict.abnormal() ? ev.most_abnormal : ev.closest_normal;
          if (slot.valid && !(e > slot.excess)) return;
          slot.valid = true;
          slot.excess = e;
          slot.result = w;
          slot.raw.assign(engine.last_window().begin(), engine.last_window().end());
        };
      }
      RunOptions opts;
      opts.progress_label = "report " + trend.method + " " + labels[i];
      opts.config_source = in.config_path;
      const MonitorResult r = monitor_recording(in.rec, in.cfg, baseline, method, fs_hz, observer, opts);
      const MonitorSummary s = summarize(r.windows, in.rec.t0_ns);
      for (const auto& w : r.windows) {
        if (w.status != dsp::WindowStatus::kScored) continue;
        TrendPoint p;
        p.t_s = ns_to_seconds(w.ref.t_start_ns - in.rec.t0_ns);
        p.window_seq = w.ref.seq;
        p.class_id = w.class_id;
        p.rms_res = w.features.rms_res;
        p.entropy_res = w.features.entropy_res;
        p.abnormal = w.verdict.abnormal();
        p.alarm = w.alarm;
        p.recording = labels[i];
        trend.points.push_back(std::move(p));
        if (order)
          trend.window_s = std::max(trend.window_s, ns_to_seconds(w.ref.t_end_ns - w.ref.t_start_ns));
      }
      const auto rel_s = [&](const dsp::WindowResult& w) {
        return ns_to_seconds(w.ref.t_start_ns - in.rec.t0_ns);
      };
      const std::string alarm_at = s.first_alarm ? fixed(rel_s(*s.first_alarm), 3) : "never";
      const double mean_rms = s.scored > 0 ? s.rms_sum / static_cast<double>(s.scored) : 0.0;
      const double mean_ent = s.scored > 0 ? s.entropy_sum / static_cast<double>(s.scored) : 0.0;
      out << pad_right(labels[i], 18) << pad_right(trend.method, 8) << pad_left(std::to_string(s.scored), 8)
          << pad_left(std::to_string(s.abnormal), 10) << pad_left(alarm_at, 14)
          << pad_left(general(mean_rms, 5), 14) << pad_left(fixed(mean_ent, 4), 14) << "\n";
      data.summary.emplace_back(
          labels[i] + " / " + trend.method,
          std::to_string(s.scored) + " scored, " + std::to_string(s.abnormal) + " abnormal, alarm " +
              (s.first_alarm ? "at " + report_time(rel_s(*s.first_alarm)) + " (window " +
                                   std::to_string(s.first_alarm->ref.seq) + ")"
                             : std::string("never")) +
              ", mean rms_res " + general(mean_rms, 5) + ", mean entropy_res " + fixed(mean_ent, 4));
      if (method != verdict_method) continue;
      RecordingSummary& rs = data.recordings[i];
      const std::string counts = std::to_string(s.abnormal) + " of " + std::to_string(s.scored) +
                                 " judged windows abnormal (rms " + std::to_string(s.rms_out) + ", entropy " +
                                 std::to_string(s.entropy_out) + ")";
      if (s.scored == 0) {
        rs.verdict = "NOT JUDGED: none of the " + std::to_string(s.windows) +
                     " windows matched a class of the baseline (check speeds and classes)";
      } else if (s.first_alarm) {
        rs.alarm = true;
        rs.verdict =
            "ALARM (" + verdict_name + ") first raised at " + report_time(rel_s(*s.first_alarm)) +
            " (window " + std::to_string(s.first_alarm->ref.seq) + ", " +
            utc_time(ns_to_seconds(s.first_alarm->ref.t_start_ns)) + "); " + counts +
            (s.first_abnormal ? ", first at " + report_time(rel_s(*s.first_abnormal)) : std::string());
      } else {
        rs.verdict = "no alarm (" + verdict_name + "); " + counts +
                     (s.abnormal > 0 ? ": isolated, below the " + std::to_string(in.cfg.decision.k) + "-of-" +
                                           std::to_string(in.cfg.decision.n) + " alarm rule"
                                     : std::string());
      }
      if (s.no_class > 0) {
        rs.verdict += "; " + std::to_string(s.no_class) + " window(s) matched no class";
      }
    }
    data.trends.push_back(std::move(trend));
  }

  // Example windows by evidence: per recording its most abnormal window and its normal window closest
  // to the band.
  dsp::WindowAnalyzer analyzer(baseline.window_len);
  const auto at_speed = [&](const dsp::WindowResult& w) {
    return order ? shaft_order_speed_rad_s(baseline) : w.ref.speed_rad_s;
  };
  const auto title_of = [&](std::size_t i, const CapturedWindow& c, const char* what) {
    const dsp::WindowResult& w = c.result;
    return labels[i] + ": " + what + ", window " + std::to_string(w.ref.seq) + " at " +
           report_time(ns_to_seconds(w.ref.t_start_ns - inputs[i].rec.t0_ns)) + " (class " +
           std::to_string(w.class_id) + ", " + fixed(w.ref.speed_rad_s, 3) + " rad/s)";
  };
  const CapturedWindow* band_window = nullptr;
  const CapturedWindow* band_reference = nullptr;
  for (std::size_t i = 0; i < inputs.size(); ++i) {
    const auto& ev = evidence[i];
    if (ev.most_abnormal.valid && (band_window == nullptr || ev.most_abnormal.excess > band_window->excess)) {
      band_window = &ev.most_abnormal;
    }
  }
  for (const auto& ev : evidence) {
    if (!ev.closest_normal.valid) continue;
    if (band_reference == nullptr ||
        (band_window != nullptr && ev.closest_normal.result.class_id == band_window->result.class_id &&
         band_reference->result.class_id != band_window->result.class_id)) {
      band_reference = &ev.closest_normal;
    }
  }
  for (std::size_t i = 0; i < inputs.size(); ++i) {
    const auto& ev = evidence[i];
    if (ev.most_abnormal.valid) {
      WindowExample ex = make_example(ev.most_abnormal, title_of(i, ev.most_abnormal, "most abnormal window"),
                                      baseline, example_rate, order, analyzer);
      ex.evidence = "Chosen as the window furthest outside its band (" + fixed(ev.most_abnormal.excess, 2) +
                    " band widths): " + feature_text(ev.most_abnormal.result) + ".";
      if (!data.recordings[i].alarm) {
        ex.note =
            "This recording raises no alarm, yet this window is judged abnormal. With a false-alarm "
            "budget per window, an isolated abnormal window is expected now and then on healthy data; "
            "compare its spectra with the normal example below before suspecting damage.";
      }
      data.examples.push_back(std::move(ex));
    }
    if (ev.closest_normal.valid) {
      WindowExample ex =
          make_example(ev.closest_normal, title_of(i, ev.closest_normal, "normal window closest to the band"),
                       baseline, example_rate, order, analyzer);
      ex.evidence = "Chosen as the judged-normal window closest to its band (" +
                    fixed(-ev.closest_normal.excess, 2) +
                    " band widths inside): " + feature_text(ev.closest_normal.result) + ".";
      data.examples.push_back(std::move(ex));
    }
  }
  // One envelope band for the whole report, so the examples compare directly.
  if (given_band) {
    data.envelope_band = *given_band;
  } else if (band_window != nullptr || band_reference != nullptr) {
    const CapturedWindow& w = band_window != nullptr ? *band_window : *band_reference;
    const CapturedWindow* ref = band_window != nullptr ? band_reference : nullptr;
    const dsp::ClassBaseline* cls = find_class(baseline, w.result.class_id);
    const double gmf = gear_orders(baseline.gearbox, at_speed(w.result)).gmf_hz;
    if (cls != nullptr) {
      (void)analyzer.analyze(w.raw, *cls, dsp::Method::kPtda);
      const std::vector<float> res(analyzer.residual().begin(), analyzer.residual().end());
      std::vector<float> ref_res;
      const dsp::ClassBaseline* rcls = ref != nullptr ? find_class(baseline, ref->result.class_id) : nullptr;
      if (rcls != nullptr) {
        (void)analyzer.analyze(ref->raw, *rcls, dsp::Method::kPtda);
        ref_res.assign(analyzer.residual().begin(), analyzer.residual().end());
      }
      data.envelope_band = choose_envelope_band(res, ref_res, example_rate, gmf);
      data.envelope_band.reason += band_window != nullptr
                                       ? "; PTDA residuals: the most abnormal window against the normal "
                                         "window closest to the band"
                                       : "; PTDA residual of the normal window closest to the band";
    }
  }
  data.notes.push_back(
      "Residuals: raw = the window itself; TDA = window minus the healthy time-domain mean (eq. 5); "
      "PTDA = window minus the IDFT of the healthy mean magnitude with the window's own phase "
      "(eqs. 7-9).");
  data.notes.push_back(
      "A window is abnormal when rms_res is above its band or entropy_res leaves its band; the alarm needs " +
      std::to_string(inputs.front().cfg.decision.k) + " abnormal windows among the last " +
      std::to_string(inputs.front().cfg.decision.n) +
      " scored ones. Verdicts and example windows use the "
      "configured method (" +
      verdict_name + ").");
  write_html_report(html_path, data);
  out << "report written to " << html_path << " (" << data.examples.size() << " example windows, "
      << data.trends.size() << " methods)\n";
  return kExitOk;
}

}  // namespace ptda::cli
