#include "ptda/cli/svg_plot.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <cstdio>
#include <limits>

#include "ptda/common/error.hpp"
#include "ptda/dsp/real_fft.hpp"

namespace ptda::cli::svg {
namespace {

constexpr double kTickTolerance = 1e-9;
constexpr double kCharWidthRatio = 0.6;  // average glyph width / font size for sans-serif
constexpr int kLegendRowPx = 14;
constexpr int kTitleBaselinePx = 14;
constexpr int kLegendSwatchPx = 14;
constexpr double kPadFraction = 0.05;
constexpr std::size_t kVLineTextRows = 3;

std::string px(double v) {
  return format_fixed(v, kPixelDecimals);
}

double text_width_px(std::string_view text, int font_px) {
  return static_cast<double>(text.size()) * font_px * kCharWidthRatio;
}

struct LegendEntry {
  enum class Kind { kLine, kMarker, kRing, kBand, kSpan };
  std::string label;
  std::string color;
  Kind kind;
};

std::vector<LegendEntry> legend_entries(const Plot& plot) {
  std::vector<LegendEntry> out;
  auto add = [&out](const std::string& label, const std::string& color, LegendEntry::Kind kind) {
    if (label.empty()) return;
    for (const auto& e : out) {
      if (e.label == label && e.color == color && e.kind == kind) return;
    }
    out.push_back({label, color, kind});
  };
  for (const auto& s : plot.series) {
    const auto kind = s.kind == Series::Kind::kLine      ? LegendEntry::Kind::kLine
                      : s.kind == Series::Kind::kMarkers ? LegendEntry::Kind::kMarker
                                                         : LegendEntry::Kind::kRing;
    add(s.label, s.color, kind);
  }
  for (const auto& b : plot.bands) add(b.label, b.color, LegendEntry::Kind::kBand);
  for (const auto& s : plot.spans) add(s.label, s.color, LegendEntry::Kind::kSpan);
  return out;
}

/// x offset (relative to the row start) and row of each legend entry; wraps at avail_px.
struct LegendPlacement {
  std::vector<std::pair<double, int>> pos;
  int rows = 0;
};

double legend_entry_width(const LegendEntry& e, int font_px) {
  return kLegendSwatchPx + 4.0 + text_width_px(e.label, font_px) + 12.0;
}

LegendPlacement place_legend(const std::vector<LegendEntry>& entries, double avail_px, int font_px) {
  LegendPlacement p;
  if (entries.empty()) return p;
  p.rows = 1;
  double x = 0.0;
  for (const auto& e : entries) {
    const double w = legend_entry_width(e, font_px);
    if (x > 0.0 && x + w > avail_px) {
      ++p.rows;
      x = 0.0;
    }
    p.pos.emplace_back(x, p.rows - 1);
    x += w;
  }
  return p;
}

int legend_font_px(const PlotStyle& style) {
  return std::max(8, style.font_px - 1);
}

void widen_if_degenerate(double& lo, double& hi) {
  if (hi - lo > std::abs(hi) * 1e-12 && hi > lo) return;
  const double d = lo == 0.0 ? 0.5 : std::abs(lo) * 0.1;
  lo -= d;
  hi += d;
}

}  // namespace

std::string escape_xml(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&#39;";
        break;
      default:
        out += c;
        break;
    }
  }
  return out;
}

std::string format_fixed(double v, int decimals) {
  if (!std::isfinite(v)) throw Error("svg::format_fixed: value is not finite");
  decimals = std::clamp(decimals, 0, 12);
  char buf[64];
  const int n = std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  if (n <= 0 || static_cast<std::size_t>(n) >= sizeof buf) {
    throw Error("svg::format_fixed: value out of printable range");
  }
  std::string s(buf, static_cast<std::size_t>(n));
  if (s.front() == '-' && s.find_first_not_of("-0.") == std::string::npos) s.erase(0, 1);
  return s;
}

Ticks nice_ticks(double lo, double hi, int target_count) {
  if (!std::isfinite(lo) || !std::isfinite(hi)) throw Error("svg::nice_ticks: axis range is not finite");
  if (target_count < 1) throw Error("svg::nice_ticks: target_count must be >= 1");
  if (lo > hi) std::swap(lo, hi);
  widen_if_degenerate(lo, hi);
  const double raw = (hi - lo) / target_count;
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  const double norm = raw / mag;
  double nice = 10.0;
  bool two_and_half = false;
  if (norm <= 1.0 + kTickTolerance) {
    nice = 1.0;
  } else if (norm <= 2.0 + kTickTolerance) {
    nice = 2.0;
  } else if (norm <= 2.5 + kTickTolerance) {
    nice = 2.5;
    two_and_half = true;
  } else if (norm <= 5.0 + kTickTolerance) {
    nice = 5.0;
  }
  Ticks t;
  t.step = nice * mag;
  t.decimals = std::max(
      0, -static_cast<int>(std::floor(std::log10(t.step) + kTickTolerance)) + (two_and_half ? 1 : 0));
  const auto k_lo = static_cast<long long>(std::ceil(lo / t.step - kTickTolerance));
  const auto k_hi = static_cast<long long>(std::floor(hi / t.step + kTickTolerance));
  for (long long k = k_lo; k <= k_hi; ++k) {
    double v = static_cast<double>(k) * t.step;
    if (std::abs(v) < t.step * kTickTolerance) v = 0.0;
    t.values.push_back(v);
  }
  return t;
}

std::vector<std::pair<double, double>> min_max_envelope(std::span<const double> x, std::span<const double> y,
                                                        double x_lo, double x_hi, std::size_t columns) {
  if (x.size() != y.size()) throw Error("svg::min_max_envelope: x and y differ in size");
  if (columns == 0) throw Error("svg::min_max_envelope: columns must be > 0");
  if (!(x_hi > x_lo)) throw Error("svg::min_max_envelope: x_hi must be > x_lo");
  std::vector<std::pair<double, double>> out;
  const double scale = static_cast<double>(columns) / (x_hi - x_lo);
  std::size_t col = 0, count = 0, first = 0, second = 0, i_min = 0, i_max = 0;
  auto flush = [&]() {
    if (count == 0) return;
    if (count == 1) {
      out.emplace_back(x[first], y[first]);
    } else if (count == 2) {
      out.emplace_back(x[first], y[first]);
      out.emplace_back(x[second], y[second]);
    } else {
      const std::size_t a = std::min(i_min, i_max), b = std::max(i_min, i_max);
      out.emplace_back(x[a], y[a]);
      if (b != a) out.emplace_back(x[b], y[b]);
    }
    count = 0;
  };
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (!std::isfinite(x[i]) || !std::isfinite(y[i]) || x[i] < x_lo || x[i] > x_hi) continue;
    const auto c = std::min(columns - 1, static_cast<std::size_t>((x[i] - x_lo) * scale));
    if (count > 0 && c != col) flush();
    if (count == 0) {
      col = c;
      first = i_min = i_max = i;
    } else {
      if (count == 1) second = i;
      if (y[i] < y[i_min]) i_min = i;
      if (y[i] > y[i_max]) i_max = i;
    }
    ++count;
  }
  flush();
  return out;
}

Spectrum amplitude_spectrum(std::span<const float> x, double fs_hz) {
  if (!(fs_hz > 0.0) || !std::isfinite(fs_hz)) throw Error("svg::amplitude_spectrum: fs_hz must be > 0");
  if (!dsp::RealFft::supported_length(x.size())) {
    throw Error("svg::amplitude_spectrum: length " + std::to_string(x.size()) +
                " is not supported by RealFft (even, >= 4, prime factors 2, 3, 5 only)");
  }
  dsp::RealFft fft(x.size());
  std::vector<std::complex<float>> bins(fft.bins());
  fft.forward(x, bins);
  const auto n = static_cast<double>(x.size());
  Spectrum s;
  s.freq_hz.resize(bins.size());
  s.amplitude.resize(bins.size());
  for (std::size_t k = 0; k < bins.size(); ++k) {
    const bool edge = k == 0 || k == bins.size() - 1;
    s.freq_hz[k] = static_cast<double>(k) * fs_hz / n;
    s.amplitude[k] = (edge ? 1.0 : 2.0) * std::abs(std::complex<double>(bins[k])) / n;
  }
  return s;
}

std::vector<double> amplitude_db(std::span<const double> amplitude, double floor_db) {
  if (!std::isfinite(floor_db)) throw Error("svg::amplitude_db: floor_db must be finite");
  std::vector<double> out(amplitude.size());
  const double floor_amp = std::pow(10.0, floor_db / 20.0);
  for (std::size_t k = 0; k < amplitude.size(); ++k) {
    const double a = amplitude[k];
    if (std::isnan(a)) {
      out[k] = a;
    } else if (!(a > floor_amp)) {
      out[k] = floor_db;
    } else {
      out[k] = 20.0 * std::log10(a);
    }
  }
  return out;
}

Spectrum envelope_spectrum(std::span<const float> x, double fs_hz, double f_lo_hz, double f_hi_hz) {
  if (!(fs_hz > 0.0) || !std::isfinite(fs_hz)) throw Error("svg::envelope_spectrum: fs_hz must be > 0");
  if (!dsp::RealFft::supported_length(x.size())) {
    throw Error("svg::envelope_spectrum: length " + std::to_string(x.size()) +
                " is not supported by RealFft (even, >= 4, prime factors 2, 3, 5 only)");
  }
  if (!std::isfinite(f_lo_hz) || !std::isfinite(f_hi_hz) || !(f_lo_hz < f_hi_hz) || f_lo_hz < 0.0 ||
      f_hi_hz > fs_hz / 2.0) {
    throw Error("svg::envelope_spectrum: band " + format_fixed(std::isfinite(f_lo_hz) ? f_lo_hz : 0.0, 1) +
                ".." + format_fixed(std::isfinite(f_hi_hz) ? f_hi_hz : 0.0, 1) +
                " Hz must satisfy 0 <= low < high <= fs/2 = " + format_fixed(fs_hz / 2.0, 1) + " Hz");
  }
  dsp::RealFft fft(x.size());
  const std::size_t n_bins = fft.bins();
  std::vector<std::complex<float>> bins(n_bins), band(n_bins), hilbert(n_bins);
  fft.forward(x, bins);
  const double df = fs_hz / static_cast<double>(x.size());
  std::size_t kept = 0;
  for (std::size_t k = 1; k + 1 < n_bins; ++k) {
    const double f = static_cast<double>(k) * df;
    if (f < f_lo_hz || f > f_hi_hz) continue;
    band[k] = bins[k];
    hilbert[k] = std::complex<float>(bins[k].imag(), -bins[k].real());  // -j X[k]
    ++kept;
  }
  if (kept == 0) {
    throw Error("svg::envelope_spectrum: band " + format_fixed(f_lo_hz, 1) + ".." + format_fixed(f_hi_hz, 1) +
                " Hz holds no frequency bin (resolution " + format_fixed(df, 3) + " Hz)");
  }
  std::vector<float> b(x.size()), h(x.size());
  fft.inverse(band, b);
  fft.inverse(hilbert, h);
  double mean = 0.0;
  std::vector<double> env(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) {
    // sqrt, not std::hypot: floats squared in double cannot overflow, and hypot is versioned GLIBC_2.35,
    // above the packages' libc6 (>= 2.34) (scripts/package_test.sh checks the symbol versions).
    const double re = b[i];
    const double im = h[i];
    env[i] = std::sqrt(re * re + im * im);
    mean += env[i];
  }
  mean /= static_cast<double>(x.size());
  std::vector<float> centred(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) centred[i] = static_cast<float>(env[i] - mean);
  return amplitude_spectrum(centred, fs_hz);
}

Layout compute_layout(const Plot& plot, const PlotStyle& style) {
  Layout l;
  double x_lo = std::numeric_limits<double>::infinity(), x_hi = -x_lo;
  double y_lo = x_lo, y_hi = -x_lo;
  for (const auto& s : plot.series) {
    if (s.x.size() != s.y.size()) {
      throw Error("svg::compute_layout: series '" + s.label + "' has x and y of different sizes");
    }
    for (std::size_t i = 0; i < s.x.size(); ++i) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) continue;
      if (plot.x_min && s.x[i] < *plot.x_min) continue;
      if (plot.x_max && s.x[i] > *plot.x_max) continue;
      l.empty = false;
      x_lo = std::min(x_lo, s.x[i]);
      x_hi = std::max(x_hi, s.x[i]);
      y_lo = std::min(y_lo, s.y[i]);
      y_hi = std::max(y_hi, s.y[i]);
    }
  }
  for (const auto& sp : plot.spans) {
    if (!std::isfinite(sp.x_lo) || !std::isfinite(sp.x_hi)) continue;
    x_lo = std::min(x_lo, std::min(sp.x_lo, sp.x_hi));
    x_hi = std::max(x_hi, std::max(sp.x_lo, sp.x_hi));
  }
  for (const auto& b : plot.bands) {
    for (const double v : {b.lo, b.hi}) {
      if (!std::isfinite(v)) continue;
      y_lo = std::min(y_lo, v);
      y_hi = std::max(y_hi, v);
    }
  }
  if ((plot.x_min && plot.x_max && *plot.x_min > *plot.x_max) ||
      (plot.y_min && plot.y_max && *plot.y_min > *plot.y_max)) {
    throw Error("svg::compute_layout: plot '" + plot.title + "' has a fixed axis minimum above its maximum");
  }
  if (plot.x_min) x_lo = *plot.x_min;
  if (plot.x_max) x_hi = *plot.x_max;
  if (!std::isfinite(x_lo) || !std::isfinite(x_hi)) {
    x_lo = 0.0;
    x_hi = 1.0;
  }
  widen_if_degenerate(x_lo, x_hi);
  if (!std::isfinite(y_lo) || !std::isfinite(y_hi)) {
    y_lo = 0.0;
    y_hi = 1.0;
  }
  // y: pad, then widen to multiples of the tick step (fixed limits are kept as given).
  const double pad = (y_hi - y_lo) * kPadFraction;
  double py_lo = y_lo - pad, py_hi = y_hi + pad;
  if (y_lo >= 0.0 && py_lo < 0.0) py_lo = 0.0;
  if (plot.y_min) py_lo = *plot.y_min;
  if (plot.y_max) py_hi = *plot.y_max;
  widen_if_degenerate(py_lo, py_hi);
  const Ticks yt = nice_ticks(py_lo, py_hi, 5);
  l.y_lo = plot.y_min ? py_lo : std::floor(py_lo / yt.step + kTickTolerance) * yt.step;
  l.y_hi = plot.y_max ? py_hi : std::ceil(py_hi / yt.step - kTickTolerance) * yt.step;
  if (std::abs(l.y_lo) < yt.step * kTickTolerance) l.y_lo = 0.0;
  if (std::abs(l.y_hi) < yt.step * kTickTolerance) l.y_hi = 0.0;
  l.y_ticks = nice_ticks(l.y_lo, l.y_hi, 5);
  l.x_lo = x_lo;
  l.x_hi = x_hi;

  const auto legend = legend_entries(plot);
  const double avail = style.width_px - style.margin_left_px - style.margin_right_px;
  const int rows = place_legend(legend, avail, legend_font_px(style)).rows;
  l.left_px = style.margin_left_px;
  l.top_px = style.margin_top_px + std::max(0, rows - 1) * kLegendRowPx;
  l.width_px = std::max(10.0, avail);
  l.height_px = std::max(10.0, static_cast<double>(style.height_px) - l.top_px - style.margin_bottom_px);
  l.x_ticks = nice_ticks(l.x_lo, l.x_hi, std::max(2, static_cast<int>(l.width_px / 80.0)));
  return l;
}

std::string render_svg(const Plot& plot, const PlotStyle& style) {
  const Layout l = compute_layout(plot, style);
  const int fpx = style.font_px;
  const int lfpx = legend_font_px(style);
  const double right = l.left_px + l.width_px, bottom = l.top_px + l.height_px;
  std::vector<std::pair<double, std::string>> x_ticks;
  if (plot.x_tick_labels.empty()) {
    for (const double v : l.x_ticks.values) x_ticks.emplace_back(v, format_fixed(v, l.x_ticks.decimals));
  } else {
    const double tol = (l.x_hi - l.x_lo) * kTickTolerance;
    for (const auto& t : plot.x_tick_labels) {
      if (std::isfinite(t.first) && t.first >= l.x_lo - tol && t.first <= l.x_hi + tol) x_ticks.push_back(t);
    }
  }
  std::string o;
  o.reserve(4096);
  o += "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" + std::to_string(style.width_px) +
       "\" height=\"" + std::to_string(style.height_px) + "\" viewBox=\"0 0 " +
       std::to_string(style.width_px) + " " + std::to_string(style.height_px) +
       "\" font-family=\"sans-serif\" font-size=\"" + std::to_string(fpx) + "\">\n";
  o += "<rect x=\"0\" y=\"0\" width=\"" + std::to_string(style.width_px) + "\" height=\"" +
       std::to_string(style.height_px) + "\" fill=\"#ffffff\"/>\n";
  o += "<text x=\"" + px(style.width_px / 2.0) + "\" y=\"" + std::to_string(kTitleBaselinePx) +
       "\" text-anchor=\"middle\" font-weight=\"bold\">" + escape_xml(plot.title) + "</text>\n";

  // Legend.
  const auto legend = legend_entries(plot);
  const auto placement = place_legend(legend, l.width_px, lfpx);
  for (std::size_t i = 0; i < legend.size(); ++i) {
    const auto& e = legend[i];
    const double x0 = l.left_px + placement.pos[i].first;
    const double yc = kTitleBaselinePx + 11.0 + placement.pos[i].second * kLegendRowPx;
    const std::string col = escape_xml(e.color);
    switch (e.kind) {
      case LegendEntry::Kind::kLine:
        o += "<line x1=\"" + px(x0) + "\" y1=\"" + px(yc) + "\" x2=\"" + px(x0 + kLegendSwatchPx) +
             "\" y2=\"" + px(yc) + "\" stroke=\"" + col + "\" stroke-width=\"2\"/>";
        break;
      case LegendEntry::Kind::kMarker:
        o += "<circle cx=\"" + px(x0 + kLegendSwatchPx / 2.0) + "\" cy=\"" + px(yc) + "\" r=\"3\" fill=\"" +
             col + "\"/>";
        break;
      case LegendEntry::Kind::kRing:
        o += "<circle cx=\"" + px(x0 + kLegendSwatchPx / 2.0) + "\" cy=\"" + px(yc) +
             "\" r=\"4\" fill=\"none\" stroke=\"" + col + "\" stroke-width=\"1.5\"/>";
        break;
      case LegendEntry::Kind::kBand:
        o += "<rect x=\"" + px(x0) + "\" y=\"" + px(yc - 4.0) + "\" width=\"" +
             std::to_string(kLegendSwatchPx) + "\" height=\"8\" fill=\"" + col +
             "\" fill-opacity=\"0.15\" stroke=\"" + col + "\" stroke-dasharray=\"3,2\"/>";
        break;
      case LegendEntry::Kind::kSpan:
        o += "<rect x=\"" + px(x0) + "\" y=\"" + px(yc - 4.0) + "\" width=\"" +
             std::to_string(kLegendSwatchPx) + "\" height=\"8\" fill=\"" + col + "\" fill-opacity=\"0.2\"/>";
        break;
    }
    o += "<text x=\"" + px(x0 + kLegendSwatchPx + 4.0) + "\" y=\"" + px(yc + 4.0) + "\" font-size=\"" +
         std::to_string(lfpx) + "\">" + escape_xml(e.label) + "</text>\n";
  }

  // Plot area: a nested <svg> with a viewBox in document coordinates clips what is drawn inside.
  o += "<svg x=\"" + px(l.left_px) + "\" y=\"" + px(l.top_px) + "\" width=\"" + px(l.width_px) +
       "\" height=\"" + px(l.height_px) + "\" viewBox=\"" + px(l.left_px) + " " + px(l.top_px) + " " +
       px(l.width_px) + " " + px(l.height_px) + "\" overflow=\"hidden\">\n";
  if (!l.empty) {
    for (const double v : l.y_ticks.values) {
      o += "<line x1=\"" + px(l.left_px) + "\" y1=\"" + px(l.y_px(v)) + "\" x2=\"" + px(right) + "\" y2=\"" +
           px(l.y_px(v)) + "\" stroke=\"#e6e6e6\"/>";
    }
    for (const auto& [v, text] : x_ticks) {
      o += "<line x1=\"" + px(l.x_px(v)) + "\" y1=\"" + px(l.top_px) + "\" x2=\"" + px(l.x_px(v)) +
           "\" y2=\"" + px(bottom) + "\" stroke=\"#e6e6e6\"/>";
    }
    o += "\n";
    for (const auto& sp : plot.spans) {
      if (!std::isfinite(sp.x_lo) || !std::isfinite(sp.x_hi)) continue;
      const double a = std::clamp(l.x_px(std::min(sp.x_lo, sp.x_hi)), l.left_px, right);
      const double b = std::clamp(l.x_px(std::max(sp.x_lo, sp.x_hi)), l.left_px, right);
      o += "<rect x=\"" + px(a) + "\" y=\"" + px(l.top_px) + "\" width=\"" + px(b - a) + "\" height=\"" +
           px(l.height_px) + "\" fill=\"" + escape_xml(sp.color) + "\" fill-opacity=\"0.2\"/>\n";
    }
    for (const auto& b : plot.bands) {
      if (!std::isfinite(b.lo) || !std::isfinite(b.hi)) continue;
      const std::string col = escape_xml(b.color);
      const double y_top = l.y_px(std::max(b.lo, b.hi)), y_bot = l.y_px(std::min(b.lo, b.hi));
      o += "<rect x=\"" + px(l.left_px) + "\" y=\"" + px(y_top) + "\" width=\"" + px(l.width_px) +
           "\" height=\"" + px(y_bot - y_top) + "\" fill=\"" + col + "\" fill-opacity=\"0.08\"/>\n";
      for (const double yv : {y_top, y_bot}) {
        o += "<line x1=\"" + px(l.left_px) + "\" y1=\"" + px(yv) + "\" x2=\"" + px(right) + "\" y2=\"" +
             px(yv) + "\" stroke=\"" + col + "\" stroke-width=\"1.2\" stroke-dasharray=\"6,3\"/>\n";
      }
    }
    // Marker texts go on up to kVLineTextRows staggered rows; a text that fits on no row is left out.
    std::array<double, kVLineTextRows> row_end;
    row_end.fill(-std::numeric_limits<double>::infinity());
    const int vfpx = lfpx - 1;
    for (const auto& v : plot.vlines) {
      if (!std::isfinite(v.x) || v.x < l.x_lo || v.x > l.x_hi) continue;
      const std::string col = escape_xml(v.color);
      const double xp = l.x_px(v.x);
      o += "<line x1=\"" + px(xp) + "\" y1=\"" + px(l.top_px) + "\" x2=\"" + px(xp) + "\" y2=\"" +
           px(bottom) + "\" stroke=\"" + col + "\" stroke-dasharray=\"3,3\"/>";
      if (!v.text.empty()) {
        const double x_text = xp + 2.0;
        for (std::size_t r = 0; r < kVLineTextRows; ++r) {
          if (x_text < row_end[r] + 3.0) continue;
          row_end[r] = x_text + text_width_px(v.text, vfpx);
          o += "<text x=\"" + px(x_text) + "\" y=\"" + px(l.top_px + 10.0 + static_cast<double>(r) * vfpx) +
               "\" font-size=\"" + std::to_string(vfpx) + "\" fill=\"" + col + "\">" + escape_xml(v.text) +
               "</text>";
          break;
        }
      }
      o += "\n";
    }
    const auto columns = static_cast<std::size_t>(std::max(1.0, std::round(l.width_px)));
    for (const auto& s : plot.series) {
      const std::string col = escape_xml(s.color);
      if (s.kind == Series::Kind::kLine) {
        const auto pts = min_max_envelope(s.x, s.y, l.x_lo, l.x_hi, columns);
        if (pts.empty()) continue;
        o += "<polyline fill=\"none\" stroke=\"" + col + "\" stroke-width=\"" + format_fixed(s.width_px, 2) +
             "\" stroke-linejoin=\"round\" points=\"";
        for (std::size_t i = 0; i < pts.size(); ++i) {
          if (i > 0) o += ' ';
          o += px(l.x_px(pts[i].first));
          o += ',';
          o += px(l.y_px(pts[i].second));
        }
        o += "\"/>\n";
      } else {
        const bool ring = s.kind == Series::Kind::kRings;
        for (std::size_t i = 0; i < s.x.size(); ++i) {
          if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i]) || s.x[i] < l.x_lo || s.x[i] > l.x_hi)
            continue;
          o += "<circle cx=\"" + px(l.x_px(s.x[i])) + "\" cy=\"" + px(l.y_px(s.y[i])) + "\" r=\"" +
               format_fixed(s.width_px, 2) + "\"";
          o += ring ? " fill=\"none\" stroke=\"" + col + "\" stroke-width=\"1.5\"/>"
                    : " fill=\"" + col + "\"/>";
        }
        o += "\n";
      }
    }
  }
  o += "</svg>\n";

  // Frame, ticks, labels.
  o += "<rect x=\"" + px(l.left_px) + "\" y=\"" + px(l.top_px) + "\" width=\"" + px(l.width_px) +
       "\" height=\"" + px(l.height_px) + "\" fill=\"none\" stroke=\"#333333\"/>\n";
  if (l.empty) {
    o += "<text x=\"" + px(l.left_px + l.width_px / 2.0) + "\" y=\"" + px(l.top_px + l.height_px / 2.0) +
         "\" text-anchor=\"middle\" fill=\"#777777\" font-style=\"italic\">" +
         escape_xml(plot.empty_message) + "</text>\n";
  } else {
    for (const double v : l.y_ticks.values) {
      const double yp = l.y_px(v);
      o += "<line x1=\"" + px(l.left_px - 4.0) + "\" y1=\"" + px(yp) + "\" x2=\"" + px(l.left_px) +
           "\" y2=\"" + px(yp) + "\" stroke=\"#333333\"/><text x=\"" + px(l.left_px - 6.0) + "\" y=\"" +
           px(yp + fpx * 0.35) + "\" text-anchor=\"end\">" + format_fixed(v, l.y_ticks.decimals) +
           "</text>\n";
    }
    for (const auto& [v, text] : x_ticks) {
      const double xp = l.x_px(v);
      o += "<line x1=\"" + px(xp) + "\" y1=\"" + px(bottom) + "\" x2=\"" + px(xp) + "\" y2=\"" +
           px(bottom + 4.0) + "\" stroke=\"#333333\"/><text x=\"" + px(xp) + "\" y=\"" +
           px(bottom + 6.0 + fpx) + "\" text-anchor=\"middle\">" + escape_xml(text) + "</text>\n";
    }
  }
  if (!plot.x_label.empty()) {
    o += "<text x=\"" + px(l.left_px + l.width_px / 2.0) + "\" y=\"" + px(style.height_px - 6.0) +
         "\" text-anchor=\"middle\">" + escape_xml(plot.x_label) + "</text>\n";
  }
  if (!plot.y_label.empty()) {
    o += "<text transform=\"translate(" + px(fpx + 1.0) + "," + px(l.top_px + l.height_px / 2.0) +
         ") rotate(-90)\" text-anchor=\"middle\">" + escape_xml(plot.y_label) + "</text>\n";
  }
  o += "</svg>\n";
  return o;
}

}  // namespace ptda::cli::svg
