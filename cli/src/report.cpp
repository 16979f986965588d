#include "ptda/cli/report.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <numbers>
#include <optional>
#include <set>
#include <tuple>

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

const char* const kInColor = "#7f7f7f";
const char* const kSpurColor = "#2ca02c";
const char* const kDmfColor = "#9467bd";

struct Panel {
  const char* name;
  const char* color;
  const std::vector<float>* x;
  std::size_t scale_group;  ///< panels of a group share their y scales (0: raw and deterministic,
                            ///< 1: TDA residual, 2: PTDA residual)
};
constexpr std::size_t kScaleGroups = 3;

/// Top of a dB axis: the largest level rounded up to 10 dB.
double db_top(double max_amplitude) {
  if (!(max_amplitude > 0.0) || !std::isfinite(max_amplitude)) return 0.0;
  return std::ceil(20.0 * std::log10(max_amplitude) / 10.0 - 1e-9) * 10.0;
}

/// The example panels' axes: seconds and Hz, or (order domain) input-shaft revolutions and orders.
struct Axes {
  bool order = false;
  [[nodiscard]] const char* freq_label() const {
    return order ? "order [per input-shaft revolution]" : "frequency [Hz]";
  }
  [[nodiscard]] const char* time_label() const {
    return order ? "angle [input-shaft revolutions]" : "time [s]";
  }
  /// "12.5 Hz" / "order 12.50".
  [[nodiscard]] std::string freq(double f) const {
    return order ? "order " + svg::format_fixed(f, 2) : svg::format_fixed(f, f < 100.0 ? 2 : 1) + " Hz";
  }
  /// A band "2000-4000 Hz" / "orders 26.0-78.0".
  [[nodiscard]] std::string band(double lo, double hi) const {
    return order ? "orders " + svg::format_fixed(lo, 1) + "-" + svg::format_fixed(hi, 1)
                 : svg::format_fixed(lo, 0) + "-" + svg::format_fixed(hi, 0) + " Hz";
  }
};

svg::Plot db_plot(const std::string& title, const std::string& unit, const svg::Spectrum& sp,
                  const char* color, double f_lo, double f_hi, double top_db, const Axes& axes) {
  svg::Plot fp;
  fp.title = title;
  fp.x_label = axes.freq_label();
  fp.y_label = "level [dB re 1 " + unit + "]";
  fp.empty_message = "no data: signal not provided";
  if (sp.amplitude.empty()) return fp;
  svg::Series fs;
  fs.color = color;
  fs.x = sp.freq_hz;
  fs.y = svg::amplitude_db(sp.amplitude, top_db - kSpectrumRangeDb);
  fp.series.push_back(std::move(fs));
  fp.x_min = f_lo;
  fp.x_max = f_hi;
  fp.y_min = top_db - kSpectrumRangeDb;
  fp.y_max = top_db;
  return fp;
}

std::string example_section(const WindowExample& ex, const ReportData& data, std::size_t index) {
  const std::string& unit = data.signal_unit;
  const Axes axes{data.order_domain};
  const std::array<Panel, 5> panels = {{
      {"raw x[n]", kRawColor, &ex.raw, 0},
      {"TDA deterministic", kDetColor, &ex.det_tda, 0},
      {"TDA residual", kResColor, &ex.res_tda, 1},
      {"PTDA deterministic", kDetColor, &ex.det_ptda, 0},
      {"PTDA residual", kResColor, &ex.res_ptda, 2},
  }};
  const std::string where = "report: example " + std::to_string(index + 1) + " '" + ex.title + "'";
  bool any = false;
  for (const auto& p : panels) any = any || !p.x->empty();
  if (any && (!(ex.fs_hz > 0.0) || !std::isfinite(ex.fs_hz))) {
    throw Error(where + ": fs_hz must be > 0, got " + std::to_string(ex.fs_hz));
  }
  double f_top_hz = any ? ex.fs_hz / 2.0 : 1.0;
  if (data.spectrum_max_hz > 0.0) f_top_hz = std::min(f_top_hz, data.spectrum_max_hz);
  const double gmf = ex.orders.gmf_hz;
  const double zoom_hz = gmf > 0.0 ? std::min(f_top_hz, 4.5 * gmf) : f_top_hz / 8.0;

  // Spectra first: they validate the lengths.
  std::array<svg::Spectrum, 5> spectra;
  constexpr double kInf = std::numeric_limits<double>::infinity();
  std::array<double, kScaleGroups> t_lo{kInf, kInf, kInf}, t_hi{-kInf, -kInf, -kInf}, a_hi{0.0, 0.0, 0.0};
  for (std::size_t i = 0; i < panels.size(); ++i) {
    const auto& x = *panels[i].x;
    if (x.empty()) continue;
    const std::size_t g = panels[i].scale_group;
    try {
      spectra[i] = svg::amplitude_spectrum(x, ex.fs_hz);
    } catch (const Error& e) {
      throw Error(where + ", " + panels[i].name + ": " + e.what());
    }
    for (std::size_t k = 0; k < spectra[i].amplitude.size(); ++k) {
      const double a = spectra[i].amplitude[k];
      if (std::isfinite(a) && spectra[i].freq_hz[k] <= f_top_hz) a_hi[g] = std::max(a_hi[g], a);
    }
    for (const float v : x) {
      if (!std::isfinite(v)) continue;
      t_lo[g] = std::min(t_lo[g], static_cast<double>(v));
      t_hi[g] = std::max(t_hi[g], static_cast<double>(v));
    }
  }
  // Envelope band: the report's, else chosen from this window's PTDA residual.
  EnvelopeBand band = data.envelope_band;
  const std::vector<float>& env_src = ex.res_ptda.empty() ? ex.raw : ex.res_ptda;
  if (!(band.hi_hz > 0.0) && !env_src.empty()) {
    band = choose_envelope_band(env_src, {}, ex.fs_hz, gmf);
  }
  std::array<svg::Spectrum, 2> envelopes;
  const std::array<const std::vector<float>*, 2> env_inputs = {&ex.raw, &ex.res_ptda};
  for (std::size_t i = 0; i < env_inputs.size(); ++i) {
    if (env_inputs[i]->empty()) continue;
    try {
      envelopes[i] =
          svg::envelope_spectrum(*env_inputs[i], ex.fs_hz, band.lo_hz, std::min(band.hi_hz, ex.fs_hz / 2.0));
    } catch (const Error& e) {
      throw Error(where + ", envelope spectrum: " + e.what());
    }
  }
  const double env_hi_hz = gmf > 0.0 ? std::min((band.hi_hz - band.lo_hz) / 2.0,
                                                8.0 * std::max(ex.orders.f_in_hz, ex.orders.f_spur_hz))
                                     : (band.hi_hz - band.lo_hz) / 2.0;

  const auto full_markers = order_markers(ex.orders, f_top_hz, false);
  const auto zoom_markers = order_markers(ex.orders, zoom_hz, false);
  std::vector<svg::VLine> env_markers;
  for (auto& m : order_markers(ex.orders, env_hi_hz, true)) {
    if (m.x <= env_hi_hz) env_markers.push_back(std::move(m));
  }

  std::string o;
  o += "<section class=\"example\">\n<h3>" + svg::escape_xml(ex.title) + "</h3>\n";
  if (!ex.evidence.empty()) o += "<p class=\"evidence\">" + svg::escape_xml(ex.evidence) + "</p>\n";
  if (!ex.note.empty()) o += "<p class=\"note\">" + svg::escape_xml(ex.note) + "</p>\n";
  if (any) {
    const double span = static_cast<double>(ex.raw.size()) / ex.fs_hz;
    const double resolution = ex.fs_hz / static_cast<double>(std::max<std::size_t>(1, ex.raw.size()));
    o += axes.order
             ? "<p class=\"meta\">Order domain: resampled to " + svg::format_fixed(ex.fs_hz, 0) +
                   " samples per input-shaft revolution, " + std::to_string(ex.raw.size()) + " samples (" +
                   svg::format_fixed(span, 3) + " revolutions), resolution " +
                   svg::format_fixed(resolution, 3) +
                   " orders. Left: on the shaft's angle axis; right: one-sided amplitude spectrum over "
                   "input-shaft orders in dB re 1 " +
                   svg::escape_xml(unit)
             : "<p class=\"meta\">fs = " + svg::format_fixed(ex.fs_hz, 1) + " Hz, " +
                   std::to_string(ex.raw.size()) + " samples (" + svg::format_fixed(span, 3) +
                   " s), resolution " + svg::format_fixed(resolution, 3) +
                   " Hz. Left: time domain; right: one-sided amplitude spectrum in dB re 1 " +
                   svg::escape_xml(unit);
    o += " (" + svg::format_fixed(kSpectrumRangeDb, 0) +
         " dB shown; lower levels sit on the floor). Raw and deterministic panels share one y scale; each "
         "residual has its own, so a small PTDA residual stays visible.";
    if (gmf > 0.0) {
      o += " Orange: GMF " + axes.freq(gmf) + " and its harmonics; grey: input shaft " +
           axes.freq(ex.orders.f_in_hz) + "; green: spur shaft " + axes.freq(ex.orders.f_spur_hz) +
           (ex.orders.dmf_hz > 0.0 ? "; purple: DMF " + axes.freq(ex.orders.dmf_hz) : std::string()) + ".";
    }
    o += "</p>\n";
  }
  o += "<div class=\"grid\">\n";
  std::array<std::optional<std::pair<double, double>>, kScaleGroups> t_range;
  std::array<double, kScaleGroups> top_db{0.0, 0.0, 0.0};
  for (std::size_t g = 0; g < kScaleGroups; ++g) {
    if (std::isfinite(t_lo[g]) && std::isfinite(t_hi[g])) t_range[g] = nice_range(t_lo[g], t_hi[g]);
    top_db[g] = db_top(a_hi[g]);
  }
  for (std::size_t i = 0; i < panels.size(); ++i) {
    const auto& x = *panels[i].x;
    svg::Plot tp;
    tp.title = std::string(panels[i].name) +
               (x.empty() ? "" : " (RMS " + svg::format_fixed(rms_of(x), 4) + " " + unit + ")");
    tp.x_label = axes.time_label();
    tp.y_label = "amplitude [" + unit + "]";
    tp.empty_message = "no data: signal not provided";
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
    }
    svg::Plot fp = db_plot(std::string(panels[i].name) + ": spectrum", unit, spectra[i], panels[i].color, 0.0,
                           f_top_hz, top_db[panels[i].scale_group], axes);
    if (!x.empty()) fp.vlines = full_markers;
    o += "<div class=\"cell\">" + svg::render_svg(tp, kExamplePlotStyle) + "</div>\n";
    o += "<div class=\"cell\">" + svg::render_svg(fp, kExamplePlotStyle) + "</div>\n";
  }
  // Zoom on the low GMF harmonics (the shaft orders are marked on the envelope spectra).
  for (const std::size_t i : {std::size_t{0}, std::size_t{4}}) {
    svg::Plot zp =
        db_plot(std::string(panels[i].name) + ": zoom on the GMF harmonics, " + axes.band(0.0, zoom_hz), unit,
                spectra[i], panels[i].color, 0.0, zoom_hz, top_db[panels[i].scale_group], axes);
    if (!panels[i].x->empty()) zp.vlines = zoom_markers;
    o += "<div class=\"cell zoom\">" + svg::render_svg(zp, kExamplePlotStyle) + "</div>\n";
  }
  // Envelope spectra.
  for (std::size_t i = 0; i < envelopes.size(); ++i) {
    svg::Plot ep;
    ep.title = std::string(i == 0 ? "raw x[n]" : "PTDA residual") + ": envelope spectrum, band " +
               axes.band(band.lo_hz, band.hi_hz);
    ep.x_label = axes.freq_label();
    ep.y_label = "envelope amplitude [" + unit + "]";
    ep.empty_message = "no data: signal not provided";
    if (!envelopes[i].amplitude.empty()) {
      svg::Series es;
      es.color = i == 0 ? kRawColor : kResColor;
      es.x = std::move(envelopes[i].freq_hz);
      es.y = std::move(envelopes[i].amplitude);
      double hi = 0.0;
      for (std::size_t k = 0; k < es.x.size(); ++k) {
        if (es.x[k] <= env_hi_hz && std::isfinite(es.y[k])) hi = std::max(hi, es.y[k]);
      }
      ep.series.push_back(std::move(es));
      ep.x_min = 0.0;
      ep.x_max = env_hi_hz;
      ep.y_min = 0.0;
      if (hi > 0.0) ep.y_max = nice_range(0.0, hi).second;
      ep.vlines = env_markers;
    }
    o += "<div class=\"cell envelope\">" + svg::render_svg(ep, kExamplePlotStyle) + "</div>\n";
  }
  o += "</div>\n";
  if (any) {
    o += "<p class=\"meta\">Envelope: band-pass " + axes.band(band.lo_hz, band.hi_hz) + " (" +
         svg::escape_xml(band.reason) +
         "), Hilbert envelope via the FFT, mean removed, amplitude spectrum. A localised defect that "
         "strikes once per revolution shows as a line at that shaft's rate and its harmonics.</p>\n";
  }
  o += "</section>\n";
  return o;
}

std::string detection_table(const std::vector<MethodTrend>& trends) {
  std::string o;
  o += "<table class=\"detect\">\n<tr><th>method</th><th>recording</th><th>windows</th><th>abnormal</th>"
       "<th>abnormal [%]</th><th>windows with alarm active</th><th>first alarm (time in the recording)</th>"
       "</tr>\n";
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
           (c.first_alarm
                ? "<span class=\"alarm-time\">" +
                      (tr.time_axis_label.empty() ? report_time(c.first_alarm->first)
                                                  : svg::format_fixed(c.first_alarm->first, 3) + " h") +
                      "</span> (window " + std::to_string(c.first_alarm->second) + ")"
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
.verdict.alarm{color:#b00000}.note{background:#fff3e0;border-left:4px solid #e07000;padding:.3em .8em}
.evidence{margin:.2em 0}
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
<p><b>Feature trends.</b> Each dot is one window (x: its start in seconds from the start of its own
recording, the recordings side by side; colour: its class). RMS_res is the
energy left in the residual; Entropy_res (0 to 1) is how spread out its spectrum is. The dashed lines with
a light fill are the healthy band of each class. A dot outside its class's band is an <em>abnormal
window</em> (red ring). An alarm is raised only when enough recent windows are abnormal (k of n); the red
shading marks where the alarm was active. Thin vertical lines mark where each recording starts.
Every time in this report counts from the start of the recording it belongs to.</p>
<p><b>What to look for.</b> In a healthy recording few dots leave their band and no alarm is shown.
A developing gearbox fault lifts RMS_res and usually changes Entropy_res; it is most visible in the PTDA
rows. If the raw and TDA rows alarm but PTDA does not, suspect a change of operating condition (payload,
speed) rather than damage. In the example windows, the PTDA residual spectrum should show little left at
the GMF marks; fault energy appears between and around them (sidebands at the shaft rates, a raised
resonance band). The envelope spectrum shows how often something strikes: a damaged spur tooth gives
lines at the spur shaft rate and its harmonics.</p>
</div>
)";

std::string gearbox_section(const ReportData& data) {
  const auto& g = data.gearbox;
  std::string o = "<h2 id=\"gearbox\">Gearbox and orders</h2>\n";
  if (g.kind == dsp::GearboxInfo::Kind::kUnknown || g.z_in == 0) {
    o += "<p>No [gearbox] in the configuration: no order markers.</p>\n";
    return o;
  }
  const bool cyc = g.kind == dsp::GearboxInfo::Kind::kCycloidal;
  o += "<p class=\"gearbox\">" + std::string(cyc ? "Cycloidal" : "Parallel") +
       " gearbox: z_in = " + std::to_string(g.z_in) + ", z_spur = " + std::to_string(g.z_spur) +
       (cyc ? ", z_pin = " + std::to_string(g.z_pin) : std::string()) +
       "; reduction ratio R = " + svg::format_fixed(g.ratio, 4) +
       (cyc ? " (1 + z_spur / z_in &#215; z_pin, eq. 1)" : std::string(" (z_spur / z_in)")) + ".</p>\n";
  if (data.class_speeds_rad_s.empty()) return o;
  o += "<table class=\"orders\">\n<tr><th>class</th><th>joint speed [rad/s]</th><th>output [Hz]</th>"
       "<th>input shaft [Hz]</th><th>spur shaft [Hz]</th><th>GMF [Hz]</th>" +
       std::string(cyc ? "<th>DMF [Hz]</th>" : "") + "</tr>\n";
  for (const auto& [c, w] : data.class_speeds_rad_s) {
    const GearOrders f = gear_orders(g, w);
    o += "<tr><td>" + class_name(c) + "</td><td>" + svg::format_fixed(w, 3) + "</td><td>" +
         svg::format_fixed(f.f_out_hz, 3) + "</td><td>" + svg::format_fixed(f.f_in_hz, 2) + "</td><td>" +
         svg::format_fixed(f.f_spur_hz, 2) + "</td><td>" + svg::format_fixed(f.gmf_hz, 2) + "</td>" +
         (cyc ? "<td>" + svg::format_fixed(f.dmf_hz, 2) + "</td>" : std::string()) + "</tr>\n";
  }
  o += "</table>\n<p class=\"meta\">GMF = z_in &#215; input shaft (eq. 3); spur shaft = GMF / z_spur" +
       std::string(cyc ? "; DMF = z_pin &#215; output (eq. 4)" : "") + ".</p>\n";
  return o;
}

}  // namespace

svg::Plot trend_plot(const MethodTrend& trend, TrendFeature feature, const std::string& signal_unit,
                     const std::vector<RecordingSummary>& recordings) {
  const bool rms = feature == TrendFeature::kRms;
  svg::Plot p;
  p.title = method_display_name(trend.method) + (rms ? ": RMS_res" : ": Entropy_res");
  p.x_label =
      trend.time_axis_label.empty() ? std::string("time in the recording [s]") : trend.time_axis_label;
  p.y_label = rms ? "RMS_res [" + signal_unit + "]" : "Entropy_res [-]";
  p.empty_message = "no data: no windows judged";

  // Recordings side by side: order, durations, offsets on the plot's x axis.
  std::vector<std::string> order;
  std::map<std::string, double> duration;
  for (const auto& r : recordings) {
    if (duration.emplace(r.label, r.duration_s).second) order.push_back(r.label);
  }
  for (const auto& pt : trend.points) {
    if (duration.find(pt.recording) == duration.end()) {
      order.push_back(pt.recording);
      duration[pt.recording] = 0.0;
    }
  }
  for (const auto& pt : trend.points) {
    auto& d = duration[pt.recording];
    d = std::max(d, pt.t_s + trend.window_s);
  }
  double total = 0.0;
  for (const auto& r : order) total += duration[r];
  const double gap = order.size() > 1 ? 0.02 * total : 0.0;
  std::map<std::string, double> offset;
  double at = 0.0;
  for (const auto& r : order) {
    offset[r] = at;
    at += duration[r] + gap;
  }
  const double x_end = at - gap;
  auto x_of = [&](const TrendPoint& pt) { return offset[pt.recording] + pt.t_s; };

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
      s.x.push_back(x_of(pt));
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
    ab.x.push_back(x_of(pt));
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

  if (x_end > 0.0) {
    p.x_min = 0.0;
    p.x_max = x_end;
  }
  // Alarm shading: a run of alarm-active windows of one recording, to the end of its last window.
  for (std::size_t i = 0; i < trend.points.size(); ++i) {
    const auto& pt = trend.points[i];
    if (!pt.alarm) continue;
    std::size_t j = i;
    while (j + 1 < trend.points.size() && trend.points[j + 1].alarm &&
           trend.points[j + 1].recording == pt.recording) {
      ++j;
    }
    p.spans.push_back({x_of(pt), x_of(trend.points[j]) + trend.window_s, "alarm active", kAlarmColor});
    i = j;
  }
  // Per recording: a labelled line at its start and time ticks from 0 s.
  const double width_px =
      kTrendPlotStyle.width_px - kTrendPlotStyle.margin_left_px - kTrendPlotStyle.margin_right_px;
  for (const auto& r : order) {
    if (order.size() > 1 || !recordings.empty()) p.vlines.push_back({offset[r], r, kRecordingLineColor});
    const double d = duration[r];
    if (!(d > 0.0) || !(x_end > 0.0)) continue;
    const int n_ticks = std::max(1, static_cast<int>(width_px * d / x_end / 70.0));
    const auto ticks = svg::nice_ticks(0.0, d, n_ticks);
    for (const double v : ticks.values) {
      if (v > d - 0.3 * ticks.step && v > 0.0 && order.size() > 1) continue;  // keep clear of the next start
      p.x_tick_labels.emplace_back(offset[r] + v, svg::format_fixed(v, ticks.decimals));
    }
  }
  return p;
}

std::string report_time(double t_s) {
  return svg::format_fixed(t_s, 3) + " s";
}

GearOrders gear_orders(const dsp::GearboxInfo& g, double speed_rad_s) noexcept {
  GearOrders o;
  if (g.kind == dsp::GearboxInfo::Kind::kUnknown || g.z_in == 0 || !(g.ratio > 0.0) ||
      !std::isfinite(speed_rad_s)) {
    return o;
  }
  o.f_out_hz = std::abs(speed_rad_s) / (2.0 * std::numbers::pi);
  o.f_in_hz = g.ratio * o.f_out_hz;
  o.gmf_hz = static_cast<double>(g.z_in) * o.f_in_hz;  // eq. 3
  o.f_spur_hz = g.z_spur > 0 ? o.gmf_hz / static_cast<double>(g.z_spur) : 0.0;
  if (g.kind == dsp::GearboxInfo::Kind::kCycloidal)
    o.dmf_hz = static_cast<double>(g.z_pin) * o.f_out_hz;  // eq. 4
  return o;
}

std::vector<svg::VLine> order_markers(const GearOrders& o, double f_hi_hz, bool shaft_orders) {
  std::vector<svg::VLine> v;
  if (!(o.gmf_hz > 0.0)) return v;
  if (shaft_orders) {
    const std::array<std::tuple<double, const char*, const char*>, 3> shafts = {{
        {o.f_in_hz, "in", kInColor},
        {o.f_spur_hz, "spur", kSpurColor},
        {o.dmf_hz, "DMF", kDmfColor},
    }};
    for (const auto& [f, name, color] : shafts) {
      if (!(f > 0.0)) continue;
      for (int k = 1; k <= 3 && k * f <= f_hi_hz; ++k) {
        v.push_back({k * f, (k == 1 ? std::string() : std::to_string(k)) + name, color});
      }
    }
  }
  for (int k = 1; k * o.gmf_hz <= f_hi_hz; ++k) {
    v.push_back({k * o.gmf_hz, k == 1 ? std::string("GMF") : std::to_string(k) + "\xC3\x97", kMarkerColor});
  }
  std::stable_sort(v.begin(), v.end(), [](const svg::VLine& a, const svg::VLine& b) { return a.x < b.x; });
  return v;
}

EnvelopeBand choose_envelope_band(std::span<const float> x, std::span<const float> reference, double fs_hz,
                                  double gmf_hz) {
  const svg::Spectrum sx = svg::amplitude_spectrum(x, fs_hz);
  std::optional<svg::Spectrum> sr;
  if (!reference.empty()) {
    if (reference.size() != x.size()) {
      throw Error("report: envelope band reference has " + std::to_string(reference.size()) +
                  " samples, the window " + std::to_string(x.size()));
    }
    sr = svg::amplitude_spectrum(reference, fs_hz);
  }
  const double nyquist = fs_hz / 2.0;
  const double width = std::min(gmf_hz > 0.0 ? 2.0 * gmf_hz : fs_hz / 16.0, fs_hz / 4.0);
  const double lowest = std::min(gmf_hz > 0.0 ? gmf_hz : fs_hz / 32.0, nyquist - width);
  EnvelopeBand best;
  double best_score = -1.0;
  for (double lo = lowest; lo + width <= nyquist + 1e-9; lo += width / 4.0) {
    double ex = 0.0, er = 0.0;
    for (std::size_t k = 1; k + 1 < sx.freq_hz.size(); ++k) {
      if (sx.freq_hz[k] < lo || sx.freq_hz[k] > lo + width) continue;
      ex += sx.amplitude[k] * sx.amplitude[k];
      if (sr) er += sr->amplitude[k] * sr->amplitude[k];
    }
    const double score = sr ? ex / std::max(er, 1e-30) : ex;
    if (score > best_score) {
      best_score = score;
      best.lo_hz = lo;
      best.hi_hz = std::min(lo + width, nyquist);
    }
  }
  const std::string w = gmf_hz > 0.0 ? "2 GMF wide" : "fs/16 wide";
  best.reason = sr ? w + ", where the chosen window has the most energy relative to the reference window (" +
                         svg::format_fixed(10.0 * std::log10(std::max(best_score, 1e-30)), 1) + " dB more)"
                   : w + ", where the window has the most energy";
  return best;
}

double band_excess(const dsp::Features& f, const dsp::FeatureThresholds& t) noexcept {
  constexpr double kMinWidth = 1e-12;
  const double wr = std::max(t.rms.hi - t.rms.lo, kMinWidth);
  const double we = std::max(t.entropy.hi - t.entropy.lo, kMinWidth);
  const double e_rms = (f.rms_res - t.rms.hi) / wr;
  const double e_ent = std::max(f.entropy_res - t.entropy.hi, t.entropy.lo - f.entropy_res) / we;
  if (std::isnan(e_rms) || std::isnan(e_ent)) return std::numeric_limits<double>::infinity();
  return std::max(e_rms, e_ent);
}

std::string render_html_report(const ReportData& data) {
  const std::string title = data.title.empty() ? std::string("PTDA gearbox condition report") : data.title;
  std::string o;
  o.reserve(1 << 20);
  o += "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>" +
       svg::escape_xml(title) + "</title>\n<style>\n" + kCss + "</style>\n</head>\n<body>\n<h1>" +
       svg::escape_xml(title) + "</h1>\n";

  o += "<h2 id=\"verdicts\">Verdict per recording</h2>\n";
  if (data.recordings.empty()) {
    o += "<p>No recordings in this report.</p>\n";
  } else {
    o += "<ul class=\"verdicts\">\n";
    for (const auto& r : data.recordings) {
      o += std::string("<li class=\"") + (r.alarm ? "verdict alarm" : "verdict") + "\"><b>" +
           svg::escape_xml(r.label) + "</b>: " + svg::escape_xml(r.verdict) + "</li>\n";
    }
    o += "</ul>\n";
  }
  if (!data.from_history) o += gearbox_section(data);

  o += "<h2 id=\"summary\">Summary</h2>\n<table class=\"summary\">\n";
  for (const auto& [k, v] : data.summary) {
    o += "<tr><th>" + svg::escape_xml(k) + "</th><td>" + svg::escape_xml(v) + "</td></tr>\n";
  }
  o += "</table>\n";
  if (!data.trends.empty()) o += detection_table(data.trends);

  o += "<h2 id=\"how-to-read\">How to read this report</h2>\n";
  if (data.from_history) {
    o += "<p class=\"meta\">This report is built from a daemon's event history: each dot is a window the "
         "daemon judged, placed at the wall time of its end (hours since the history's first line), against "
         "the band it was judged with. The history keeps features, not samples, so there are no example "
         "windows. The notes list the state and alarm-level changes.</p>\n";
  }
  if (data.order_domain) {
    o += "<p class=\"howto\"><b>Order domain.</b> Unlike the time-domain description below, this baseline "
         "judges windows on the input shaft's angle, "
         "not on time: the vibration was resampled to equal steps of shaft angle from the joint angle the "
         "controller sends over CAN, so a window is a fixed number of shaft revolutions and the gear mesh "
         "stays at the same <em>order</em> (lines per revolution) whatever the speed. The speed need not be "
         "constant: classes are a direction and a speed band. In the example windows the horizontal axis is "
         "shaft revolutions and the spectra are over input-shaft orders (GMF = z_in).</p>\n";
  }
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
        o += "<div class=\"cell\">" +
             svg::render_svg(trend_plot(tr, f, data.signal_unit, data.recordings), kTrendPlotStyle) +
             "</div>\n";
      }
    }
    o += "</div>\n";
  }

  if (!data.from_history) o += "<h2 id=\"examples\">Example windows</h2>\n";
  if (data.examples.empty() && !data.from_history) o += "<p>No example windows in this report.</p>\n";
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
