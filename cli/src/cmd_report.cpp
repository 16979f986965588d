// ptda report --recording DIR [...] --config FILE --baseline BASELINE --html OUT [--label NAME ...]
#include <cmath>
#include <numbers>
#include <ostream>

#include "ptda/cli/args.hpp"
#include "ptda/cli/commands.hpp"
#include "ptda/cli/monitor_output.hpp"
#include "ptda/cli/pipeline_runner.hpp"
#include "ptda/cli/report.hpp"
#include "ptda/cli/text.hpp"
#include "ptda/common/error.hpp"
#include "ptda/common/time.hpp"
#include "ptda/config/pipeline_config.hpp"
#include "ptda/dsp/analyzer.hpp"
#include "ptda/formats/baseline_file.hpp"

namespace ptda::cli {

namespace {

constexpr std::array<dsp::Method, 3> kMethods = {dsp::Method::kRaw, dsp::Method::kTda, dsp::Method::kPtda};

/// GMF (eq. 3) and its harmonics below Nyquist for a joint speed; empty when the gearbox is unknown.
std::vector<double> gmf_markers(const dsp::GearboxInfo& g, double speed_rad_s, double fs_hz) {
  std::vector<double> f;
  if (g.kind == dsp::GearboxInfo::Kind::kUnknown || g.z_in == 0 || g.ratio <= 0.0) return f;
  const double f_in = g.ratio * std::abs(speed_rad_s) / (2.0 * std::numbers::pi);
  const double gmf = static_cast<double>(g.z_in) * f_in;
  for (int k = 1; k <= 8 && k * gmf < fs_hz / 2.0; ++k) f.push_back(k * gmf);
  return f;
}

/// A window captured during the PTDA run for the report's example plots.
struct CapturedWindow {
  std::string title;
  std::vector<float> raw;
  std::int32_t class_id = -1;
  double speed_rad_s = 0.0;
};

WindowExample make_example(const CapturedWindow& c, const dsp::Baseline& baseline, double fs_hz,
                           dsp::WindowAnalyzer& analyzer) {
  WindowExample ex;
  ex.title = c.title;
  ex.fs_hz = fs_hz;
  ex.raw = c.raw;
  const dsp::ClassBaseline* cls = nullptr;
  for (const auto& k : baseline.classes) {
    if (static_cast<std::int32_t>(k.segment.id) == c.class_id) cls = &k;
  }
  if (cls == nullptr) return ex;
  (void)analyzer.analyze(c.raw, *cls, dsp::Method::kTda);
  ex.det_tda.assign(analyzer.deterministic().begin(), analyzer.deterministic().end());
  ex.res_tda.assign(analyzer.residual().begin(), analyzer.residual().end());
  (void)analyzer.analyze(c.raw, *cls, dsp::Method::kPtda);
  ex.det_ptda.assign(analyzer.deterministic().begin(), analyzer.deterministic().end());
  ex.res_ptda.assign(analyzer.residual().begin(), analyzer.residual().end());
  ex.marker_freqs_hz = gmf_markers(baseline.gearbox, c.speed_rad_s, fs_hz);
  return ex;
}

}  // namespace

int cmd_report(std::span<const std::string> args, std::ostream& out) {
  ArgParser parser(
      "report",
      "--recording DIR [--recording DIR ...] --config FILE --baseline BASELINE --html OUT [--label NAME ...]",
      "Monitors each recording with raw, TDA and PTDA residuals and writes one self-contained HTML file:\n"
      "example windows (raw, deterministic and residual parts in time and frequency, like the paper's\n"
      "Figs. 8-11), the feature trends against the class bands, and the counts per method.");
  parser.option("recording", "DIR", "recording directory (e.g. a healthy and a faulty one)", true, true)
      .option("config", "FILE", "pipeline configuration TOML", true)
      .option("baseline", "BASELINE", "baseline file written by ptda train", true)
      .option("html", "OUT", "HTML file to write", true)
      .option("label", "NAME", "name of each recording in the report, in --recording order", false, true);
  const ParsedArgs a = parser.parse(args);
  if (a.help()) {
    out << parser.help_text();
    return kExitOk;
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

  ReportData data;
  data.title = "PTDA condition monitoring report";
  data.signal_unit = inputs.front().rec.meta.unit;
  if (!baseline.classes.empty()) {
    data.marker_freqs_hz = gmf_markers(baseline.gearbox, baseline.classes.front().segment.speed_rad_s, fs_hz);
  }
  data.summary.emplace_back("baseline", baseline_path);
  data.summary.emplace_back("trained on", baseline.source);
  data.summary.emplace_back("configuration", config_path);
  data.summary.emplace_back("sample rate", general(fs_hz, 10) + " Hz");
  data.summary.emplace_back("window length", std::to_string(baseline.window_len) + " samples (" +
                                                 fixed(1000.0 * baseline.window_len / fs_hz, 1) + " ms)");
  data.summary.emplace_back("segment classes", std::to_string(baseline.classes.size()));
  data.summary.emplace_back("alarm rule",
                            std::to_string(inputs.front().cfg.decision.k) + " abnormal of the last " +
                                std::to_string(inputs.front().cfg.decision.n) + " scored windows");

  std::vector<CapturedWindow> captured;
  out << pad_right("recording", 18) << pad_right("method", 8) << pad_left("scored", 8)
      << pad_left("abnormal", 10) << pad_left("alarm at [s]", 14) << pad_left("mean rms_res", 14)
      << pad_left("mean entropy", 14) << "\n";
  for (const dsp::Method method : kMethods) {
    MethodTrend trend;
    trend.method = std::string(dsp::method_name(method));
    for (const auto& c : baseline.classes) {
      trend.class_thresholds.emplace_back(static_cast<std::int32_t>(c.segment.id),
                                          c.thresholds[static_cast<std::size_t>(method)]);
    }
    double t_offset_s = 0.0;
    std::uint32_t seq = 0;
    for (std::size_t i = 0; i < inputs.size(); ++i) {
      const MonitorInputs& in = inputs[i];
      bool have_first = false;
      bool have_abnormal = false;
      WindowObserver observer;
      if (method == dsp::Method::kPtda) {
        observer = [&](const dsp::WindowResult& w, const dsp::MonitorEngine& engine) {
          if (w.status != dsp::WindowStatus::kScored) return;
          const bool first = !have_first;
          const bool abnormal = !have_abnormal && w.verdict.abnormal();
          if (!first && !abnormal) return;
          CapturedWindow c;
          c.title = labels[i] + ", window " + std::to_string(w.ref.seq) + " at " +
                    fixed(ns_to_seconds(w.ref.t_start_ns - in.rec.t0_ns), 3) + " s (class " +
                    std::to_string(w.class_id) + ", " + fixed(w.ref.speed_rad_s, 3) + " rad/s)" +
                    (w.verdict.abnormal() ? ", abnormal by PTDA" : ", first scored");
          c.raw.assign(engine.last_window().begin(), engine.last_window().end());
          c.class_id = w.class_id;
          c.speed_rad_s = w.ref.speed_rad_s;
          captured.push_back(std::move(c));
          have_first = true;
          if (w.verdict.abnormal()) have_abnormal = true;
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
        p.t_s = t_offset_s + ns_to_seconds(w.ref.t_start_ns - in.rec.t0_ns);
        p.window_seq = seq++;
        p.class_id = w.class_id;
        p.rms_res = w.features.rms_res;
        p.entropy_res = w.features.entropy_res;
        p.abnormal = w.verdict.abnormal();
        p.alarm = w.alarm;
        p.recording = labels[i];
        trend.points.push_back(std::move(p));
      }
      t_offset_s += in.rec.duration_s;
      const std::string alarm_at =
          s.first_alarm ? fixed(ns_to_seconds(s.first_alarm->ref.t_start_ns - in.rec.t0_ns), 3) : "never";
      const double mean_rms = s.scored > 0 ? s.rms_sum / static_cast<double>(s.scored) : 0.0;
      const double mean_ent = s.scored > 0 ? s.entropy_sum / static_cast<double>(s.scored) : 0.0;
      out << pad_right(labels[i], 18) << pad_right(trend.method, 8) << pad_left(std::to_string(s.scored), 8)
          << pad_left(std::to_string(s.abnormal), 10) << pad_left(alarm_at, 14)
          << pad_left(general(mean_rms, 5), 14) << pad_left(fixed(mean_ent, 4), 14) << "\n";
      data.summary.emplace_back(labels[i] + " / " + trend.method,
                                std::to_string(s.scored) + " scored, " + std::to_string(s.abnormal) +
                                    " abnormal, alarm " +
                                    (s.first_alarm ? "at " + alarm_at + " s" : "never") + ", mean rms_res " +
                                    general(mean_rms, 5) + ", mean entropy_res " + fixed(mean_ent, 4));
    }
    data.trends.push_back(std::move(trend));
  }

  dsp::WindowAnalyzer analyzer(baseline.window_len);
  for (const auto& c : captured) data.examples.push_back(make_example(c, baseline, fs_hz, analyzer));
  data.notes.push_back(
      "Residuals: raw = the window itself; TDA = window minus the healthy time-domain mean (eq. 5); "
      "PTDA = window minus the IDFT of the healthy mean magnitude with the window's own phase "
      "(eqs. 7-9).");
  data.notes.push_back(
      "A window is abnormal when rms_res or entropy_res leaves its class band; the alarm needs " +
      std::to_string(inputs.front().cfg.decision.k) + " abnormal windows among the last " +
      std::to_string(inputs.front().cfg.decision.n) + " scored ones.");
  write_html_report(html_path, data);
  out << "report written to " << html_path << " (" << data.examples.size() << " example windows, "
      << data.trends.size() << " methods)\n";
  return kExitOk;
}

}  // namespace ptda::cli
