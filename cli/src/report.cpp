#include "ptda/cli/report.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <set>

#include "ptda/common/error.hpp"

namespace ptda::cli {
namespace {

constexpr std::array<const char*, 8> kClassPalette = {"#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd",
                                                      "#8c564b", "#e377c2", "#17becf", "#bcbd22"};
constexpr const char* kUnclassifiedColor = "#7f7f7f";
constexpr const char* kAbnormalColor = "#d62728";
constexpr const char* kAlarmColor = "#d62728";
constexpr const char* kRecordingLineColor = "#555555";
constexpr const char* kRawColor = "#1f77b4";
constexpr const char* kDetColor = "#2ca02c";
constexpr const char* kResColor = "#9467bd";
constexpr const char* kMarkerColor = "#e07000";
constexpr svg::PlotStyle kExamplePlotStyle{470, 210, 62, 12, 38, 40, 11};
constexpr double kHarmonicTolerance = 0.02;

std::string class_color(std::int32_t class_id) {
  if (class_id < 0) return kUnclassifiedColor;
  return kClassPalette[static_cast<std::size_t>(class_id) % kClassPalette.size()];
}

std::string class_name(std::int32_t class_id) {
  return class_id < 0 ? std::string("unclassified") : "class " + std::to_string(class_id);
}

std::string method_display_name(const std::string& method) {
  if (method == "raw") return "Raw (extracted signal)";
  if (method == "tda") return "TDA residual";
  if (method == "ptda") return "PTDA residual";
  return method;
}

/// Widens [lo, hi] to multiples of a nice tick step (5 % padding first).
std::pair<double, double> nice_range(double lo, double hi) {
  const double pad = (hi - lo) * 0.05;
  const auto t = svg::nice_ticks(lo - pad, hi + pad, 5);
  return {std::floor((lo - pad) / t.step + 1e-9) * t.step, std::ceil((hi + pad) / t.step - 1e-9) * t.step};
}

double rms_of(const std::vector<float>& x) {
  if (x.empty()) return 0.0;
  double s = 0.0;
  for (const float v : x) s += static_cast<double>(v) * v;
  return std::sqrt(s / static_cast<double>(x.size()));
}

std::string marker_text(double f, double f0, std::size_t index) {
  if (index == 0) return "GMF";
  if (f0 > 0.0) {
    const double r = f / f0;
    const double k = std::round(r);
    if (k >= 1.0 && std::abs(r - k) < kHarmonicTolerance) return svg::format_fixed(k, 0) + "\xC3\x97";
  }
  return svg::format_fixed(f, 0) + " Hz";
}

struct Panel {
  const char* name;
  const char* color;
  const std::vector<float>* x;
  std::size_t
      scale_group;  ///< panels of a group share their y scales (0: raw and deterministic, 1: residuals)
};

std::string example_section(const WindowExample& ex, const ReportData& data, std::size_t index) {
  const auto& default_markers = data.marker_freqs_hz;
  const std::string& unit = data.signal_unit;
  const std::array<Panel, 5> panels = {{
      {"raw x[n]", kRawColor, &ex.raw, 0},
      {"TDA deterministic", kDetColor, &ex.det_tda, 0},
      {"TDA residual", kResColor, &ex.res_tda, 1},
      {"PTDA deterministic", kDetColor, &ex.det_ptda, 0},
      {"PTDA residual", kResColor, &ex.res_ptda, 1},
  }};
  const std::string where = "report: example " + std::to_string(index + 1) + " '" + ex.title + "'";
  bool any = false;
  for (const auto& p : panels) any = any || !p.x->empty();
  if (any && (!(ex.fs_hz > 0.0) || !std::isfinite(ex.fs_hz))) {
    throw Error(where + ": fs_hz must be > 0, got " + std::to_string(ex.fs_hz));
  }

  // Spectra first: they validate the lengths.
  std::array<svg::Spectrum, 5> spectra;
  constexpr double kInf = std::numeric_limits<double>::infinity();
  std::array<double, 2> t_lo = {kInf, kInf}, t_hi = {-kInf, -kInf}, a_hi = {0.0, 0.0};
  for (std::size_t i = 0; i < panels.size(); ++i) {
    const auto& x = *panels[i].x;
    if (x.empty()) continue;
    const std::size_t g = panels[i].scale_group;
    try {
      spectra[i] = svg::amplitude_spectrum(x, ex.fs_hz);
    } catch (const Error& e) {
      throw Error(where + ", " + panels[i].name + ": " + e.what());
    }
    const double f_show_hz = data.spectrum_max_hz > 0.0 ? data.spectrum_max_hz : ex.fs_hz;
    for (std::size_t k = 0; k < spectra[i].amplitude.size(); ++k) {
      const double a = spectra[i].amplitude[k];
      if (std::isfinite(a) && spectra[i].freq_hz[k] <= f_show_hz) a_hi[g] = std::max(a_hi[g], a);
    }
    for (const float v : x) {
      if (!std::isfinite(v)) continue;
      t_lo[g] = std::min(t_lo[g], static_cast<double>(v));
      t_hi[g] = std::max(t_hi[g], static_cast<double>(v));
    }
  }
  const auto& markers = ex.marker_freqs_hz.empty() ? default_markers : ex.marker_freqs_hz;

  std::string o;
  o += "<section class=\"example\">\n<h3>" + svg::escape_xml(ex.title) + "</h3>\n";
  if (any) {
    o +=
        "<p class=\"meta\">fs = " + svg::format_fixed(ex.fs_hz, 1) + " Hz, " + std::to_string(ex.raw.size()) +
        " samples (" + svg::format_fixed(static_cast<double>(ex.raw.size()) / ex.fs_hz, 3) +
        " s). Left: time domain; right: one-sided amplitude spectrum. Raw and deterministic panels share "
        "one y scale, the two residuals another, so TDA and PTDA compare directly." +
        std::string(markers.empty() ? "" : " Dashed orange lines: gear mesh frequency (GMF) and harmonics.") +
        "</p>\n";
  }
  o += "<div class=\"grid\">\n";
  double f_top_hz = any ? ex.fs_hz / 2.0 : 1.0;
  if (data.spectrum_max_hz > 0.0) f_top_hz = std::min(f_top_hz, data.spectrum_max_hz);
  std::array<std::optional<std::pair<double, double>>, 2> t_range;
  std::array<double, 2> a_top = {1.0, 1.0};
  for (std::size_t g = 0; g < 2; ++g) {
    if (std::isfinite(t_lo[g]) && std::isfinite(t_hi[g])) t_range[g] = nice_range(t_lo[g], t_hi[g]);
    if (a_hi[g] > 0.0) a_top[g] = nice_range(0.0, a_hi[g]).second;
  }
  for (std::size_t i = 0; i < panels.size(); ++i) {
    const auto& x = *panels[i].x;
    svg::Plot tp;
    tp.title = std::string(panels[i].name) +
               (x.empty() ? "" : " (RMS " + svg::format_fixed(rms_of(x), 4) + " " + unit + ")");
    tp.x_label = "time [s]";
    tp.y_label = "amplitude [" + unit + "]";
    tp.empty_message = "no data: signal not provided";
    svg::Plot fp;
    fp.title = std::string(panels[i].name) + ": spectrum";
    fp.x_label = "frequency [Hz]";
    fp.y_label = "amplitude [" + unit + "]";
    fp.empty_message = "no data: signal not provided";
    if (!x.empty()) {
      svg::Series ts;
      ts.color = panels[i].color;
      ts.x.resize(x.size());
      ts.y.resize(x.size());
      for (std::size_t n = 0; n < x.size(); ++n) {
        ts.x[n] = static_cast<double>(n) / ex.fs_hz;
        ts.y[n] = x[n];
      }
      tp.series.push_back(std::move(ts));
      tp.x_min = 0.0;
      tp.x_max = static_cast<double>(x.size()) / ex.fs_hz;
      if (const auto& r = t_range[panels[i].scale_group]) {
        tp.y_min = r->first;
        tp.y_max = r->second;
      }
      svg::Series fs;
      fs.color = panels[i].color;
      fs.x = std::move(spectra[i].freq_hz);
      fs.y = std::move(spectra[i].amplitude);
      fp.series.push_back(std::move(fs));
      fp.x_min = 0.0;
      fp.x_max = f_top_hz;
      fp.y_min = 0.0;
      fp.y_max = a_top[panels[i].scale_group];
      for (std::size_t m = 0; m < markers.size(); ++m) {
        fp.vlines.push_back({markers[m], marker_text(markers[m], markers.front(), m), kMarkerColor});
      }
    }
    o += "<div class=\"cell\">" + svg::render_svg(tp, kExamplePlotStyle) + "</div>\n";
    o += "<div class=\"cell\">" + svg::render_svg(fp, kExamplePlotStyle) + "</div>\n";
  }
  o += "</div>\n</section>\n";
  return o;
}

std::string detection_table(const std::vector<MethodTrend>& trends) {
  std::string o;
  o += "<table class=\"detect\">\n<tr><th>method</th><th>recording</th><th>windows</th><th>abnormal</th>"
       "<th>abnormal [%]</th><th>windows with alarm active</th><th>first alarm</th></tr>\n";
  for (const auto& tr : trends) {
    std::vector<std::string> order;
    struct Count {
      std::size_t windows = 0, abnormal = 0, alarm = 0;
      std::optional<std::pair<double, std::uint32_t>> first_alarm;
    };
    std::map<std::string, Count> counts;
    for (const auto& p : tr.points) {
      if (counts.find(p.recording) == counts.end()) order.push_back(p.recording);
      auto& c = counts[p.recording];
      ++c.windows;
      if (p.abnormal) ++c.abnormal;
      if (p.alarm) {
        ++c.alarm;
        if (!c.first_alarm) c.first_alarm = std::make_pair(p.t_s, p.window_seq);
      }
    }
    for (const auto& rec : order) {
      const auto& c = counts[rec];
      const double pct =
          c.windows ? 100.0 * static_cast<double>(c.abnormal) / static_cast<double>(c.windows) : 0.0;
      o += "<tr><td>" + svg::escape_xml(method_display_name(tr.method)) + "</td><td>" + svg::escape_xml(rec) +
           "</td><td>" + std::to_string(c.windows) + "</td><td>" + std::to_string(c.abnormal) + "</td><td>" +
           svg::format_fixed(pct, 1) + "</td><td>" + std::to_string(c.alarm) + "</td><td>" +
           (c.first_alarm ? "t = " + svg::format_fixed(c.first_alarm->first, 2) + " s (window " +
                                std::to_string(c.first_alarm->second) + ")"
                          : std::string("none")) +
           "</td></tr>\n";
    }
  }
  o += "</table>\n";
  return o;
}

constexpr const char* kCss =
    R"(body{font-family:sans-serif;margin:1.5em auto;max-width:1200px;color:#222;line-height:1.4}
h1{font-size:1.5em}h2{border-bottom:1px solid #bbb;margin-top:1.6em}h3{font-size:1.05em;margin-bottom:.2em}
table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ccc;padding:.2em .6em;text-align:left}
th{background:#f0f0f0}.grid{display:grid;grid-template-columns:repeat(2,max-content);gap:4px}
.cell svg{display:block;border:1px solid #eee}.meta{color:#555;font-size:.9em;margin:.2em 0 .5em}
.howto{background:#f7f7f2;border-left:4px solid #c9c28a;padding:.5em 1em}
)";

constexpr const char* kHowToRead = R"(<div class="howto">
<p>The monitor cuts the vibration signal into windows recorded while the joint turns at a constant speed.
Each window is compared only with healthy windows of the same motion segment (its <em>class</em>).
The regular gear-mesh vibration (the <em>deterministic</em> part, at the gear mesh frequency GMF and its
harmonics) is estimated from healthy recordings and subtracted; what is left is the <em>residual</em>, where
a damaged tooth, pin or bearing shows up. TDA averages the healthy windows in time, which smears the
gear-mesh pattern because each window starts at a different gear position; PTDA averages only the
magnitudes and re-uses each window's own phase, so its deterministic estimate fits and its residual is
cleaner.</p>
<p><b>Feature trends.</b> Each dot is one window (x: window number; colour: its class). RMS_res is the
energy left in the residual; Entropy_res (0 to 1) is how spread out its spectrum is. The dashed lines with
a light fill are the healthy band of each class. A dot outside its class's band is an <em>abnormal
window</em> (red ring). An alarm is raised only when enough recent windows are abnormal (k of n); the red
shading marks where the alarm was active. Thin vertical lines separate recordings.</p>
<p><b>What to look for.</b> In a healthy recording few dots leave their band and no alarm is shown.
A developing gearbox fault lifts RMS_res and usually changes Entropy_res; it is most visible in the PTDA
rows. If the raw and TDA rows alarm but PTDA does not, suspect a change of operating condition (payload,
speed) rather than damage. In the example windows, the PTDA residual spectrum should show little left at
the GMF marks; fault energy appears between and around them.</p>
</div>
)";

}  // namespace

svg::Plot trend_plot(const MethodTrend& trend, TrendFeature feature, const std::string& signal_unit) {
  const bool rms = feature == TrendFeature::kRms;
  svg::Plot p;
  p.title = method_display_name(trend.method) + (rms ? ": RMS_res" : ": Entropy_res");
  p.x_label = "window #";
  p.y_label = rms ? "RMS_res [" + signal_unit + "]" : "Entropy_res [-]";
  p.empty_message = "no data: no windows judged";

  std::set<std::int32_t> classes;
  for (const auto& pt : trend.points) classes.insert(pt.class_id);
  for (const std::int32_t c : classes) {
    svg::Series s;
    s.label = class_name(c);
    s.color = class_color(c);
    s.kind = svg::Series::Kind::kMarkers;
    s.width_px = 2.5;
    for (const auto& pt : trend.points) {
      if (pt.class_id != c) continue;
      s.x.push_back(pt.window_seq);
      s.y.push_back(rms ? pt.rms_res : pt.entropy_res);
    }
    p.series.push_back(std::move(s));
  }
  svg::Series ab;
  ab.label = "abnormal window";
  ab.color = kAbnormalColor;
  ab.kind = svg::Series::Kind::kRings;
  ab.width_px = 4.5;
  for (const auto& pt : trend.points) {
    if (!pt.abnormal) continue;
    ab.x.push_back(pt.window_seq);
    ab.y.push_back(rms ? pt.rms_res : pt.entropy_res);
  }
  if (!ab.x.empty()) p.series.push_back(std::move(ab));

  auto sorted = trend.class_thresholds;
  std::stable_sort(sorted.begin(), sorted.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  for (const auto& [c, th] : sorted) {
    const auto& band = rms ? th.rms : th.entropy;
    p.bands.push_back({band.lo, band.hi, class_name(c) + " band", class_color(c)});
  }

  if (!trend.points.empty()) {
    std::uint32_t lo = trend.points.front().window_seq, hi = lo;
    for (const auto& pt : trend.points) {
      lo = std::min(lo, pt.window_seq);
      hi = std::max(hi, pt.window_seq);
    }
    p.x_min = lo - 0.5;
    p.x_max = hi + 0.5;
  }
  for (std::size_t i = 0; i < trend.points.size(); ++i) {
    const auto& pt = trend.points[i];
    if (pt.alarm) {
      std::size_t j = i;
      while (j + 1 < trend.points.size() && trend.points[j + 1].alarm) ++j;
      p.spans.push_back({pt.window_seq - 0.5, trend.points[j].window_seq + 0.5, "alarm active", kAlarmColor});
      i = j;
    }
  }
  for (std::size_t i = 0; i < trend.points.size(); ++i) {
    if (i == 0 || trend.points[i].recording != trend.points[i - 1].recording) {
      p.vlines.push_back({trend.points[i].window_seq - 0.5, trend.points[i].recording, kRecordingLineColor});
    }
  }
  return p;
}

std::string render_html_report(const ReportData& data) {
  const std::string title = data.title.empty() ? std::string("PTDA gearbox condition report") : data.title;
  std::string o;
  o.reserve(1 << 20);
  o += "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>" +
       svg::escape_xml(title) + "</title>\n<style>\n" + kCss + "</style>\n</head>\n<body>\n<h1>" +
       svg::escape_xml(title) + "</h1>\n";

  o += "<h2 id=\"summary\">Summary</h2>\n<table class=\"summary\">\n";
  for (const auto& [k, v] : data.summary) {
    o += "<tr><th>" + svg::escape_xml(k) + "</th><td>" + svg::escape_xml(v) + "</td></tr>\n";
  }
  o += "</table>\n";
  if (!data.trends.empty()) o += detection_table(data.trends);

  o += "<h2 id=\"how-to-read\">How to read this report</h2>\n";
  o += kHowToRead;

  o += "<h2 id=\"trends\">Feature trends</h2>\n";
  if (data.trends.empty()) {
    o += "<p>No feature trends in this report.</p>\n";
  } else {
    o += "<p class=\"meta\">Rows: raw signal, TDA residual, PTDA residual. Columns: RMS_res, "
         "Entropy_res.</p>\n";
    o += "<div class=\"grid\">\n";
    for (const auto& tr : data.trends) {
      for (const auto f : {TrendFeature::kRms, TrendFeature::kEntropy}) {
        o += "<div class=\"cell\">" + svg::render_svg(trend_plot(tr, f, data.signal_unit), kTrendPlotStyle) +
             "</div>\n";
      }
    }
    o += "</div>\n";
  }

  o += "<h2 id=\"examples\">Example windows</h2>\n";
  if (data.examples.empty()) o += "<p>No example windows in this report.</p>\n";
  for (std::size_t i = 0; i < data.examples.size(); ++i) {
    o += example_section(data.examples[i], data, i);
  }

  o += "<h2 id=\"notes\">Notes</h2>\n";
  if (data.notes.empty()) {
    o += "<p>None.</p>\n";
  } else {
    o += "<ul>\n";
    for (const auto& n : data.notes) o += "<li>" + svg::escape_xml(n) + "</li>\n";
    o += "</ul>\n";
  }
  o += "</body>\n</html>\n";
  return o;
}

void write_html_report(const std::filesystem::path& out, const ReportData& data) {
  const std::string html = render_html_report(data);
  std::ofstream f(out, std::ios::binary | std::ios::trunc);
  if (!f) throw Error(out.string(), 0, 0, "cannot open the report for writing");
  f.write(html.data(), static_cast<std::streamsize>(html.size()));
  f.flush();
  if (!f) throw Error(out.string(), 0, 0, "cannot write the report (disk full?)");
}

}  // namespace ptda::cli
