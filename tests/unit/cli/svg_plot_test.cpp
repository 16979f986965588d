#include "ptda/cli/svg_plot.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

#include "ptda/common/error.hpp"

namespace ptda::cli::svg {
namespace {

std::size_t count(const std::string& hay, const std::string& needle) {
  std::size_t n = 0;
  for (auto p = hay.find(needle); p != std::string::npos; p = hay.find(needle, p + needle.size())) ++n;
  return n;
}

TEST(SvgNiceTicks, ZeroToPointNineThreeGivesStepsOfPointTwo) {
  const Ticks t = nice_ticks(0.0, 0.93, 5);
  EXPECT_DOUBLE_EQ(t.step, 0.2);
  EXPECT_EQ(t.decimals, 1);
  ASSERT_EQ(t.values.size(), 5U);
  const std::vector<double> expected = {0.0, 0.2, 0.4, 0.6, 0.8};
  for (std::size_t i = 0; i < expected.size(); ++i) EXPECT_NEAR(t.values[i], expected[i], 1e-12) << i;
  EXPECT_EQ(format_fixed(t.values[3], t.decimals), "0.6");
}

TEST(SvgNiceTicks, OtherRanges) {
  const Ticks a = nice_ticks(0.0, 12800.0, 5);  // raw step 2560 -> 5000
  EXPECT_DOUBLE_EQ(a.step, 5000.0);
  EXPECT_EQ(a.decimals, 0);
  EXPECT_EQ(a.values, (std::vector<double>{0.0, 5000.0, 10000.0}));

  const Ticks b = nice_ticks(-3.0, 7.0, 5);  // raw step 2
  EXPECT_DOUBLE_EQ(b.step, 2.0);
  EXPECT_EQ(b.values, (std::vector<double>{-2.0, 0.0, 2.0, 4.0, 6.0}));

  const Ticks c = nice_ticks(0.0, 1.2, 5);  // raw step 0.24 -> 0.25, needs two decimals
  EXPECT_DOUBLE_EQ(c.step, 0.25);
  EXPECT_EQ(c.decimals, 2);
  EXPECT_EQ(c.values.size(), 5U);
  EXPECT_EQ(format_fixed(c.values[1], c.decimals), "0.25");

  const Ticks d = nice_ticks(7.0, 3.0, 4);  // swapped
  EXPECT_DOUBLE_EQ(d.step, 1.0);
  EXPECT_DOUBLE_EQ(d.values.front(), 3.0);
  EXPECT_DOUBLE_EQ(d.values.back(), 7.0);

  const Ticks e = nice_ticks(2.0, 2.0, 5);  // degenerate: widened around the value
  ASSERT_FALSE(e.values.empty());
  EXPECT_LE(e.values.front(), 2.0);
  EXPECT_GE(e.values.back(), 2.0);

  EXPECT_THROW((void)nice_ticks(0.0, std::nan(""), 5), ptda::Error);
  EXPECT_THROW((void)nice_ticks(0.0, 1.0, 0), ptda::Error);
}

TEST(SvgFormat, FixedPrecisionAndNoNegativeZero) {
  EXPECT_EQ(format_fixed(1.23456, 2), "1.23");
  EXPECT_EQ(format_fixed(-0.00001, 1), "0.0");
  EXPECT_EQ(format_fixed(-2.5, 1), "-2.5");
  EXPECT_THROW((void)format_fixed(std::nan(""), 1), ptda::Error);
}

TEST(SvgEscape, EscapesMarkupCharacters) {
  EXPECT_EQ(escape_xml("a<b & \"c\" 'd'>"), "a&lt;b &amp; &quot;c&quot; &#39;d&#39;&gt;");
  EXPECT_EQ(escape_xml("plain"), "plain");
  Plot p;
  p.title = "<script>&";
  p.x_label = "x <unit>";
  const std::string s = render_svg(p);
  EXPECT_NE(s.find("&lt;script&gt;&amp;"), std::string::npos);
  EXPECT_NE(s.find("x &lt;unit&gt;"), std::string::npos);
  EXPECT_EQ(s.find("<script>"), std::string::npos);
}

TEST(SvgEnvelope, KeepsSingleSpikeAndDecimates) {
  const std::size_t n = 12800;
  std::vector<double> x(n), y(n, 0.0);
  for (std::size_t i = 0; i < n; ++i) x[i] = static_cast<double>(i) / 12800.0;
  y[7777] = 5.0;
  y[3001] = -4.0;
  const auto env = min_max_envelope(x, y, 0.0, x.back(), 400);
  EXPECT_LE(env.size(), 800U);
  EXPECT_GE(env.size(), 400U);
  const auto has = [&env](double xv, double yv) {
    return std::any_of(env.begin(), env.end(),
                       [&](const auto& p) { return p.first == xv && p.second == yv; });
  };
  EXPECT_TRUE(has(x[7777], 5.0));
  EXPECT_TRUE(has(x[3001], -4.0));
  EXPECT_TRUE(
      std::is_sorted(env.begin(), env.end(), [](const auto& a, const auto& b) { return a.first < b.first; }));
}

TEST(SvgEnvelope, KeepsMinAndMaxOfEveryColumn) {
  const std::size_t n = 5000, columns = 37;
  std::vector<double> x(n), y(n);
  std::uint32_t state = 12345;
  for (std::size_t i = 0; i < n; ++i) {
    state = state * 1664525U + 1013904223U;
    x[i] = static_cast<double>(i);
    y[i] = static_cast<double>(state >> 8) / 16777216.0 - 0.5;
  }
  const double x_lo = 0.0, x_hi = static_cast<double>(n - 1);
  const auto env = min_max_envelope(x, y, x_lo, x_hi, columns);
  EXPECT_EQ(env.size(), 2 * columns);
  for (std::size_t c = 0; c < columns; ++c) {
    double mn = 1e9, mx = -1e9, emn = 1e9, emx = -1e9;
    for (std::size_t i = 0; i < n; ++i) {
      const auto col =
          std::min(columns - 1, static_cast<std::size_t>((x[i] - x_lo) * columns / (x_hi - x_lo)));
      if (col != c) continue;
      mn = std::min(mn, y[i]);
      mx = std::max(mx, y[i]);
    }
    for (const auto& [ex, ey] : env) {
      const auto col = std::min(columns - 1, static_cast<std::size_t>((ex - x_lo) * columns / (x_hi - x_lo)));
      if (col != c) continue;
      emn = std::min(emn, ey);
      emx = std::max(emx, ey);
    }
    EXPECT_EQ(mn, emn) << "column " << c;
    EXPECT_EQ(mx, emx) << "column " << c;
  }
  EXPECT_THROW((void)min_max_envelope(x, std::vector<double>(3), 0.0, 1.0, 5), ptda::Error);
  EXPECT_THROW((void)min_max_envelope(x, y, 0.0, 1.0, 0), ptda::Error);
  EXPECT_THROW((void)min_max_envelope(x, y, 1.0, 1.0, 5), ptda::Error);
}

TEST(SvgRender, SpikeReachesItsPixelAndPlotIsSmall) {
  const std::size_t n = 12800;
  Series s;
  s.x.resize(n);
  s.y.assign(n, 0.0);
  for (std::size_t i = 0; i < n; ++i) s.x[i] = static_cast<double>(i) / 25600.0;
  s.y[6000] = 3.0;
  Plot p;
  p.title = "spike";
  p.series.push_back(s);
  p.y_min = -4.0;
  p.y_max = 4.0;
  const PlotStyle style;
  const Layout l = compute_layout(p, style);
  // Fixed limits are kept: y = 3 lies at 1/8 of the height below the top.
  EXPECT_DOUBLE_EQ(l.y_lo, -4.0);
  EXPECT_DOUBLE_EQ(l.y_hi, 4.0);
  EXPECT_DOUBLE_EQ(l.top_px, style.margin_top_px);
  const double plot_h = style.height_px - style.margin_top_px - style.margin_bottom_px;
  EXPECT_DOUBLE_EQ(l.y_px(3.0), style.margin_top_px + plot_h / 8.0);
  const std::string svg = render_svg(p, style);
  const std::string spike_point = "," + format_fixed(l.y_px(3.0), kPixelDecimals);
  EXPECT_NE(svg.find(spike_point), std::string::npos) << spike_point;
  EXPECT_LT(svg.size(), 20000U);
  EXPECT_EQ(count(svg, "<svg"), count(svg, "</svg>"));
}

TEST(SvgRender, EmptySeriesShowsMessage) {
  Plot p;
  p.title = "nothing";
  p.series.push_back(Series{});
  p.empty_message = "no data: signal not provided";
  const std::string svg = render_svg(p);
  EXPECT_NE(svg.find("no data: signal not provided"), std::string::npos);
  EXPECT_EQ(svg.find("<polyline"), std::string::npos);
  EXPECT_EQ(count(svg, "<svg"), 2U);
  EXPECT_EQ(count(svg, "</svg>"), 2U);
  EXPECT_TRUE(compute_layout(p).empty);

  Plot nan_only;
  nan_only.series.push_back(
      Series{"", "#000000", Series::Kind::kLine, {0.0, 1.0}, {std::nan(""), std::nan("")}, 1.0});
  EXPECT_NE(render_svg(nan_only).find("no data"), std::string::npos);
}

TEST(SvgRender, DeterministicAndBandsAtExpectedPixels) {
  Plot p;
  p.title = "trend";
  p.series.push_back(
      Series{"class 0", "#1f77b4", Series::Kind::kMarkers, {0, 1, 2, 3}, {0.1, 0.5, 0.3, 0.9}, 2.5});
  p.bands.push_back(HBand{0.25, 0.75, "band", "#2ca02c"});
  p.spans.push_back(VSpan{2.5, 3.5, "alarm", "#d62728"});
  p.vlines.push_back(VLine{1.5, "faulty", "#555555"});
  const std::string a = render_svg(p);
  const std::string b = render_svg(p);
  EXPECT_EQ(a, b);
  const Layout l = compute_layout(p);
  // Data 0.1..0.9 padded by 5 % -> 0.06..0.94, step 0.2 -> axis 0..1.
  EXPECT_NEAR(l.y_lo, 0.0, 1e-12);
  EXPECT_NEAR(l.y_hi, 1.0, 1e-12);
  EXPECT_DOUBLE_EQ(l.x_lo, 0.0);
  EXPECT_DOUBLE_EQ(l.x_hi, 3.5);  // the span widens x
  const std::string right = format_fixed(l.left_px + l.width_px, kPixelDecimals);
  for (const double frac : {0.25, 0.75}) {  // band edges 0.75 and 0.25 on a 0..1 axis
    const std::string yp = format_fixed(l.top_px + frac * l.height_px, kPixelDecimals);
    const std::string line = "y1=\"" + yp + "\" x2=\"" + right + "\" y2=\"" + yp + "\" stroke=\"#2ca02c\"";
    EXPECT_NE(a.find(line), std::string::npos) << line;
  }
  EXPECT_EQ(count(a, "<circle"), 4U + 1U);  // 4 points + legend swatch
  EXPECT_NE(a.find(">faulty</text>"), std::string::npos);

  p.series[0].y[3] = 0.91;
  EXPECT_NE(render_svg(p), a);
  p.y_min = 2.0;
  p.y_max = 1.0;
  EXPECT_THROW((void)render_svg(p), ptda::Error);
}

TEST(SvgRender, CloseMarkerTextsAreStaggered) {
  Plot p;
  p.series.push_back(Series{"", "#000000", Series::Kind::kLine, {0.0, 1000.0}, {0.0, 1.0}, 1.0});
  for (int k = 1; k <= 3; ++k) p.vlines.push_back(VLine{10.0 * k, "m" + std::to_string(k), "#e07000"});
  p.vlines.push_back(VLine{5000.0, "outside", "#e07000"});
  const std::string s = render_svg(p);
  const Layout l = compute_layout(p);
  // The markers are ~4 px apart: each text needs its own row, 10 px below the top and then one
  // (font - 2) px row further each.
  const int vfpx = PlotStyle{}.font_px - 2;
  for (int k = 1; k <= 3; ++k) {
    const std::string text = "<text x=\"" + format_fixed(l.x_px(10.0 * k) + 2.0, kPixelDecimals) + "\" y=\"" +
                             format_fixed(l.top_px + 10.0 + (k - 1) * vfpx, kPixelDecimals) + "\"";
    EXPECT_NE(s.find(text), std::string::npos) << text;
    EXPECT_NE(s.find(">m" + std::to_string(k) + "</text>"), std::string::npos);
  }
  EXPECT_EQ(s.find("outside"), std::string::npos);  // beyond the x range
}

TEST(SvgEnvelope, AmSignalGivesTheModulationLine) {
  // x = A (1 + m cos 2 pi fm t) cos 2 pi fc t: the envelope is A (1 + m cos 2 pi fm t), so the
  // envelope spectrum has one line at fm of amplitude A m. Frequencies on bins (fs / N = 2 Hz).
  const std::size_t n = 12800;
  const double fs = 25600.0, fc = 3000.0, fm = 24.0, a = 1.5, m = 0.4;
  std::vector<float> x(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double t = static_cast<double>(i) / fs;
    x[i] = static_cast<float>(a * (1.0 + m * std::cos(2.0 * std::numbers::pi * fm * t)) *
                              std::cos(2.0 * std::numbers::pi * fc * t));
  }
  const Spectrum e = envelope_spectrum(x, fs, 2500.0, 3500.0);
  ASSERT_EQ(e.freq_hz.size(), n / 2 + 1);
  const std::size_t k_fm = 12;  // 24 Hz / 2 Hz
  EXPECT_DOUBLE_EQ(e.freq_hz[k_fm], fm);
  EXPECT_NEAR(e.amplitude[k_fm], a * m, 1e-4);
  EXPECT_NEAR(e.amplitude[0], 0.0, 1e-4);  // mean removed
  std::size_t k_max = 1;
  for (std::size_t k = 1; k < e.amplitude.size(); ++k) {
    if (e.amplitude[k] > e.amplitude[k_max]) k_max = k;
  }
  EXPECT_EQ(k_max, k_fm);
  for (std::size_t k = 1; k < e.amplitude.size(); ++k) {
    if (k != k_fm) {
      EXPECT_LT(e.amplitude[k], 1e-3) << k;  // no other line (m < 1: no harmonics)
    }
  }
  // A band that misses the carrier and both sidebands sees nothing.
  const Spectrum off = envelope_spectrum(x, fs, 5000.0, 6000.0);
  EXPECT_LT(off.amplitude[k_fm], 1e-4);
  // Errors: band outside (0, fs/2], empty band, unsupported length.
  EXPECT_THROW((void)envelope_spectrum(x, fs, 3500.0, 2500.0), ptda::Error);
  EXPECT_THROW((void)envelope_spectrum(x, fs, 2500.0, 13000.0), ptda::Error);
  EXPECT_THROW((void)envelope_spectrum(x, fs, 3000.5, 3001.5), ptda::Error);
  EXPECT_THROW((void)envelope_spectrum(std::vector<float>(1001), fs, 100.0, 200.0), ptda::Error);
}

TEST(SvgDb, ConversionAndFloor) {
  const std::vector<double> a = {1.0, 10.0, 0.1, 1e-3, 1e-5, 0.0, -1.0, std::nan("")};
  const std::vector<double> db = amplitude_db(a, -80.0);
  ASSERT_EQ(db.size(), a.size());
  EXPECT_NEAR(db[0], 0.0, 1e-12);
  EXPECT_NEAR(db[1], 20.0, 1e-12);
  EXPECT_NEAR(db[2], -20.0, 1e-12);
  EXPECT_NEAR(db[3], -60.0, 1e-12);
  EXPECT_EQ(db[4], -80.0);  // -100 dB: on the floor
  EXPECT_EQ(db[5], -80.0);  // zero: on the floor, not -inf
  EXPECT_EQ(db[6], -80.0);
  EXPECT_TRUE(std::isnan(db[7]));  // not drawn
  EXPECT_THROW((void)amplitude_db(a, -std::numeric_limits<double>::infinity()), ptda::Error);
}

TEST(SvgRender, CustomXTickLabels) {
  Plot p;
  Series s;
  s.x = {0.0, 10.0, 20.0};
  s.y = {1.0, 2.0, 3.0};
  p.series.push_back(s);
  p.x_tick_labels = {{0.0, "0"}, {12.0, "0"}, {20.0, "8"}, {25.0, "outside"}};
  const std::string svg = render_svg(p);
  const Layout l = compute_layout(p);
  EXPECT_NE(svg.find("x=\"" + format_fixed(l.x_px(12.0), kPixelDecimals) + "\" y=\""), std::string::npos);
  EXPECT_NE(svg.find("text-anchor=\"middle\">8</text>"), std::string::npos);
  EXPECT_EQ(svg.find(">outside</text>"), std::string::npos);
  EXPECT_EQ(svg.find(">10</text>"), std::string::npos);  // no automatic ticks
}

TEST(SvgSpectrum, SineAmplitudeAndUnsupportedLength) {
  const std::size_t n = 1000;
  const double fs = 1000.0;
  std::vector<float> x(n);
  for (std::size_t i = 0; i < n; ++i) {
    x[i] =
        static_cast<float>(0.5 + 2.0 * std::sin(2.0 * std::numbers::pi * 40.0 * static_cast<double>(i) / fs));
  }
  const Spectrum s = amplitude_spectrum(x, fs);
  ASSERT_EQ(s.freq_hz.size(), n / 2 + 1);
  EXPECT_DOUBLE_EQ(s.freq_hz[40], 40.0);
  EXPECT_NEAR(s.amplitude[40], 2.0, 1e-3);
  EXPECT_NEAR(s.amplitude[0], 0.5, 1e-3);
  EXPECT_NEAR(s.amplitude[41], 0.0, 1e-3);
  EXPECT_THROW((void)amplitude_spectrum(std::vector<float>(1001), fs), ptda::Error);
  EXPECT_THROW((void)amplitude_spectrum(x, 0.0), ptda::Error);
}

}  // namespace
}  // namespace ptda::cli::svg
