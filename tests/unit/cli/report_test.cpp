#include "ptda/cli/report.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#include "ptda/common/error.hpp"

namespace ptda::cli {
namespace {

std::size_t count(const std::string& hay, const std::string& needle) {
  std::size_t n = 0;
  for (auto p = hay.find(needle); p != std::string::npos; p = hay.find(needle, p + needle.size())) ++n;
  return n;
}

constexpr double kFsHz = 25600.0;
constexpr std::size_t kWindowLen = 12800;  // 2^9 * 5^2: supported by RealFft
constexpr double kGmfHz = 526.67;
constexpr double kSpeedRadS = 3.49068;  // GMF = 28 * 33.857 * 3.49068 / 2 pi = 526.67 Hz
const dsp::GearboxInfo kGearbox{dsp::GearboxInfo::Kind::kCycloidal, 28, 23, 40, 1.0 + 23.0 / 28.0 * 40.0};

struct Lcg {
  std::uint32_t s = 1;
  double uniform() {  // [-1, 1)
    s = s * 1664525U + 1013904223U;
    return static_cast<double>(s >> 8) / 8388608.0 - 1.0;
  }
};

WindowExample make_example(const std::string& title, bool faulty, std::uint32_t seed) {
  WindowExample ex;
  ex.title = title;
  ex.fs_hz = kFsHz;
  ex.orders = gear_orders(kGearbox, kSpeedRadS);
  Lcg rng{seed};
  const double phase = 0.7 * seed;
  for (std::size_t n = 0; n < kWindowLen; ++n) {
    const double t = static_cast<double>(n) / kFsHz;
    double det = 0.0, det_tda = 0.0;
    for (int k = 1; k <= 4; ++k) {
      const double a = 1.0 / k;
      det += a * std::sin(2.0 * std::numbers::pi * k * kGmfHz * t + k * phase);
      det_tda += 0.3 * a * std::sin(2.0 * std::numbers::pi * k * kGmfHz * t);
    }
    double fault = 0.0;
    if (faulty && n % 900 < 20) fault = 1.5 * std::exp(-static_cast<double>(n % 900) / 4.0);
    const double noise = 0.2 * rng.uniform();
    const double raw = det + fault + noise;
    ex.raw.push_back(static_cast<float>(raw));
    ex.det_tda.push_back(static_cast<float>(det_tda));
    ex.res_tda.push_back(static_cast<float>(raw - det_tda));
    ex.det_ptda.push_back(static_cast<float>(det * 0.98));
    ex.res_ptda.push_back(static_cast<float>(raw - det * 0.98));
  }
  return ex;
}

/// Healthy windows 0..149, faulty 150..299; two classes alternating. PTDA: faulty rms in 0.7..0.9,
/// healthy 0.1..0.5; band [0.2, 0.6] for class 0 and [0.15, 0.55] for class 1.
ReportData make_data() {
  ReportData d;
  d.title = "Joint 4 <cycloidal> & friends";
  d.summary = {{"recordings", "healthy.wav, faulty.wav"}, {"fs", "25600 Hz"}, {"window", "12800 samples"}};
  d.gearbox = kGearbox;
  d.class_speeds_rad_s = {{0, kSpeedRadS}, {1, -kSpeedRadS}};
  d.recordings = {{"healthy", 120.0, "no alarm", false}, {"faulty", 120.0, "ALARM at 1.600 s", true}};
  d.examples.push_back(make_example("healthy recording, window 3 (class 0, 3.49 rad/s)", false, 3));
  d.examples.push_back(make_example("faulty recording, window 160 (class 0, 3.49 rad/s)", true, 160));
  d.examples.push_back(make_example("faulty recording, window 161 (class 1, -3.49 rad/s)", true, 161));
  for (const char* method : {"raw", "tda", "ptda"}) {
    MethodTrend tr;
    tr.method = method;
    dsp::FeatureThresholds t0, t1;
    t0.rms = {0.2, 0.6};
    t0.entropy = {0.3, 0.5};
    t1.rms = {0.15, 0.55};
    t1.entropy = {0.32, 0.52};
    tr.class_thresholds = {{1, t1}, {0, t0}};
    tr.window_s = 0.5;
    Lcg rng{7};
    int run = 0;
    for (std::uint32_t w = 0; w < 300; ++w) {
      TrendPoint p;
      const bool faulty = w >= 150;
      p.window_seq = faulty ? w - 150 : w;  // numbered and timed within each recording
      p.t_s = 0.8 * p.window_seq;
      p.class_id = static_cast<std::int32_t>(w % 2);
      p.recording = faulty ? "faulty" : "healthy";
      const bool ptda = std::string(method) == "ptda";
      p.rms_res = faulty && ptda ? 0.8 + 0.1 * rng.uniform() : 0.3 + 0.2 * rng.uniform();
      if (!faulty) p.rms_res = std::max(0.1, p.rms_res);
      p.entropy_res = 0.4 + 0.05 * rng.uniform();
      const auto& th = p.class_id == 0 ? t0 : t1;
      p.abnormal = !th.rms.contains(p.rms_res) || !th.entropy.contains(p.entropy_res);
      run = p.abnormal ? run + 1 : 0;
      p.alarm = run >= 3;
      tr.points.push_back(p);
    }
    d.trends.push_back(std::move(tr));
  }
  d.notes = {"Synthetic data for the unit test; x < y & z."};
  return d;
}

std::filesystem::path test_tmp_dir() {
  const char* env = std::getenv("PTDA_TEST_TMP");
  std::filesystem::path dir =
      env ? std::filesystem::path(env) : std::filesystem::temp_directory_path() / "ptda-test";
  std::filesystem::create_directories(dir);
  return dir;
}

TEST(Report, StructureSectionsAndEscaping) {
  const ReportData d = make_data();
  const std::string html = render_html_report(d);
  EXPECT_EQ(html.rfind("<!DOCTYPE html>", 0), 0U);
  EXPECT_NE(html.find("</html>"), std::string::npos);
  // Every plot is an outer <svg> with a nested plot-area <svg>: 6 trend plots + 3 examples x 14
  // (5 time plots, 5 dB spectra, 2 zooms on the GMF harmonics, 2 envelope spectra).
  EXPECT_EQ(count(html, "<svg "), 2U * (6U + 42U));
  EXPECT_EQ(count(html, "</svg>"), 2U * (6U + 42U));
  EXPECT_EQ(count(html, "level [dB re 1 m/s^2]"), 3U * 7U);
  EXPECT_EQ(count(html, ": envelope spectrum, band "), 3U * 2U);
  for (const char* id :
       {"id=\"verdicts\">Verdict per recording", "id=\"gearbox\">Gearbox and orders",
        "id=\"summary\">Summary", "id=\"how-to-read\">How to read this report",
        "id=\"trends\">Feature trends", "id=\"examples\">Example windows", "id=\"notes\">Notes"}) {
    EXPECT_NE(html.find(id), std::string::npos) << id;
  }
  EXPECT_NE(html.find("<h1>Joint 4 &lt;cycloidal&gt; &amp; friends</h1>"), std::string::npos);
  EXPECT_NE(html.find("<title>Joint 4 &lt;cycloidal&gt; &amp; friends</title>"), std::string::npos);
  EXPECT_EQ(html.find("<cycloidal>"), std::string::npos);
  EXPECT_NE(html.find("x &lt; y &amp; z."), std::string::npos);
  EXPECT_NE(html.find("PTDA residual: RMS_res"), std::string::npos);
  EXPECT_NE(html.find("TDA residual: Entropy_res"), std::string::npos);
  EXPECT_NE(html.find(">GMF</text>"), std::string::npos);
  EXPECT_NE(html.find(">3\xC3\x97</text>"), std::string::npos);
  // Verdicts (the alarm in red), gearbox header with R and the GMF of each class.
  EXPECT_NE(html.find("<li class=\"verdict\"><b>healthy</b>: no alarm</li>"), std::string::npos);
  EXPECT_NE(html.find("<li class=\"verdict alarm\"><b>faulty</b>: ALARM at 1.600 s</li>"), std::string::npos);
  EXPECT_NE(html.find("z_in = 28, z_spur = 23, z_pin = 40; reduction ratio R = 33.8571"), std::string::npos);
  EXPECT_EQ(count(html, "<td>526.67</td>"), 2U);
  // No external resources.
  EXPECT_EQ(html.find("<script"), std::string::npos);
  EXPECT_EQ(count(html, "http"), count(html, "http://www.w3.org/2000/svg"));  // only the SVG namespace
  EXPECT_EQ(html.find("https:"), std::string::npos);
  EXPECT_LT(html.size(), 2U * 1024U * 1024U);
  EXPECT_EQ(render_html_report(d), html);  // deterministic
}

TEST(Report, ThresholdBandDrawnAtExpectedPixel) {
  const ReportData d = make_data();
  const MethodTrend& ptda = d.trends[2];
  const svg::Plot plot = trend_plot(ptda, TrendFeature::kRms, d.signal_unit);
  const svg::Layout l = svg::compute_layout(plot, kTrendPlotStyle);
  // PTDA rms spans ~0.1..~0.9 (bands 0.15..0.6 inside): padded and widened to a 0..1 axis.
  EXPECT_NEAR(l.y_lo, 0.0, 1e-12);
  EXPECT_NEAR(l.y_hi, 1.0, 1e-12);
  const std::string html = render_html_report(d);
  const std::string right = svg::format_fixed(l.left_px + l.width_px, svg::kPixelDecimals);
  // Class 0 band hi = 0.6 -> 40 % of the height below the top; class 1 lo = 0.15 -> 85 %.
  const struct {
    double frac;
    const char* color;
  } edges[] = {{0.4, "#1f77b4"}, {0.8, "#1f77b4"}, {0.45, "#ff7f0e"}, {0.85, "#ff7f0e"}};
  for (const auto& e : edges) {
    const std::string yp = svg::format_fixed(l.top_px + e.frac * l.height_px, svg::kPixelDecimals);
    const std::string line =
        "y1=\"" + yp + "\" x2=\"" + right + "\" y2=\"" + yp + "\" stroke=\"" + e.color + "\"";
    EXPECT_NE(html.find(line), std::string::npos) << line;
  }
}

TEST(Report, TrendPlotMarksAbnormalWindowsAndAlarm) {
  const ReportData d = make_data();
  const MethodTrend& ptda = d.trends[2];
  std::size_t abnormal = 0, alarm_runs = 0;
  for (std::size_t i = 0; i < ptda.points.size(); ++i) {
    abnormal += ptda.points[i].abnormal ? 1 : 0;
    if (ptda.points[i].alarm && (i == 0 || !ptda.points[i - 1].alarm)) ++alarm_runs;
  }
  ASSERT_GT(abnormal, 100U);  // the faulty half is out of band
  ASSERT_GE(alarm_runs, 1U);
  const svg::Plot plot = trend_plot(ptda, TrendFeature::kRms, d.signal_unit, d.recordings);
  EXPECT_EQ(plot.spans.size(), alarm_runs);
  // Time axis: the recordings side by side, 120 s each with a 2 % gap (4.8 s) between them.
  ASSERT_EQ(plot.vlines.size(), 2U);
  EXPECT_DOUBLE_EQ(plot.vlines[0].x, 0.0);
  EXPECT_DOUBLE_EQ(plot.vlines[1].x, 124.8);
  EXPECT_EQ(plot.vlines[1].text, "faulty");
  EXPECT_EQ(plot.x_label, "time in the recording [s]");
  ASSERT_EQ(plot.series.front().x.size(), 150U);       // class 0: 75 healthy + 75 faulty windows
  EXPECT_DOUBLE_EQ(plot.series.front().x[75], 124.8);  // faulty window 0 at t = 0 s of its recording
  // Each recording's ticks restart at 0 s.
  std::size_t zeros = 0;
  for (const auto& [x, text] : plot.x_tick_labels) zeros += text == "0" ? 1 : 0;
  EXPECT_EQ(zeros, 2U);
  EXPECT_EQ(plot.x_tick_labels.front().first, 0.0);
  const std::string s = svg::render_svg(plot, kTrendPlotStyle);
  // Rings of abnormal windows plus the legend's ring.
  EXPECT_EQ(count(s, "fill=\"none\" stroke=\"#d62728\" stroke-width=\"1.5\"/>"), abnormal + 1);
  EXPECT_EQ(count(s, "fill=\"#d62728\" fill-opacity=\"0.2\"/>"), alarm_runs + 1);  // spans + legend

  // Detection table: PTDA faulty row counts its abnormal windows.
  std::size_t faulty_abnormal = 0;
  for (const auto& p : ptda.points) faulty_abnormal += (p.abnormal && p.recording == "faulty") ? 1 : 0;
  const std::string html = render_html_report(d);
  const std::string row =
      "<tr><td>PTDA residual</td><td>faulty</td><td>150</td><td>" + std::to_string(faulty_abnormal) + "</td>";
  EXPECT_NE(html.find(row), std::string::npos) << row;
}

TEST(Report, SpectrumUpperLimit) {
  ReportData d = make_data();
  d.trends.clear();
  d.examples.resize(1);
  const std::string full = render_html_report(d);
  EXPECT_NE(full.find(">10000</text>"), std::string::npos);  // 0..12800 Hz: ticks every 5000 Hz
  // GMF harmonics are marked up to the band edge, not only to 8 x: 24 x 526.67 = 12640 Hz < 12800 Hz.
  EXPECT_EQ(count(full, ">24\xC3\x97</text>"), 5U);
  EXPECT_EQ(count(full, ">4\xC3\x97</text>"), 7U);  // 5 full spectra + 2 zooms on 0..4.5 GMF
  d.spectrum_max_hz = 2500.0;
  const std::string zoom = render_html_report(d);
  EXPECT_EQ(zoom.find(">10000</text>"), std::string::npos);
  EXPECT_EQ(count(zoom, ">24\xC3\x97</text>"), 0U);
  EXPECT_EQ(count(full, ">2000</text>"), 2U);       // only the two zooms (0..2370 Hz, ticks every 500 Hz)
  EXPECT_EQ(count(zoom, ">2000</text>"), 7U);       // and now each of the 5 spectra (ticks every 1000 Hz)
  EXPECT_EQ(count(zoom, ">4\xC3\x97</text>"), 7U);  // 4 x GMF = 2107 Hz still marked
}

TEST(Report, EmptyPartsAndErrors) {
  ReportData d;
  d.title = "empty";
  WindowExample nothing;
  nothing.title = "nothing here";
  d.examples.push_back(nothing);
  const std::string html = render_html_report(d);
  EXPECT_NE(html.find("No feature trends in this report."), std::string::npos);
  EXPECT_EQ(count(html, "no data: signal not provided"), 14U);

  ReportData bad;
  WindowExample ex;
  ex.title = "odd length";
  ex.fs_hz = 1000.0;
  ex.raw.assign(1001, 0.0F);
  bad.examples.push_back(ex);
  try {
    (void)render_html_report(bad);
    FAIL() << "expected ptda::Error";
  } catch (const ptda::Error& e) {
    EXPECT_NE(std::string(e.what()).find("odd length"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("1001"), std::string::npos) << e.what();
  }
  bad.examples[0].raw.assign(1000, 0.0F);
  bad.examples[0].fs_hz = 0.0;
  EXPECT_THROW((void)render_html_report(bad), ptda::Error);
}

TEST(ReportOrders, FrequenciesFromToothCounts) {
  // Paper Table 2 joint: R = 1 + 23/28 * 40 (eq. 1); at 3.49068 rad/s the output turns at w / 2 pi.
  const double f_out = 3.49068 / (2.0 * std::numbers::pi);
  const double r = 1.0 + 23.0 / 28.0 * 40.0;
  const GearOrders o = gear_orders(kGearbox, -3.49068);  // the direction does not change frequencies
  EXPECT_NEAR(r, 33.857142857142854, 1e-12);
  EXPECT_NEAR(o.f_out_hz, 0.555559, 1e-6);
  EXPECT_NEAR(o.f_in_hz, r * f_out, 1e-12);
  EXPECT_NEAR(o.f_in_hz, 18.8096, 1e-4);
  EXPECT_NEAR(o.gmf_hz, 28.0 * r * f_out, 1e-12);  // eq. 3
  EXPECT_NEAR(o.gmf_hz, 526.670, 1e-3);
  EXPECT_NEAR(o.f_spur_hz, o.gmf_hz / 23.0, 1e-12);
  EXPECT_NEAR(o.f_spur_hz, 22.8987, 1e-4);
  EXPECT_NEAR(o.dmf_hz, 40.0 * f_out, 1e-12);  // eq. 4
  EXPECT_NEAR(o.dmf_hz, 22.2224, 1e-4);

  // Parallel gearbox: no DMF; unknown gearbox: nothing.
  const dsp::GearboxInfo par{dsp::GearboxInfo::Kind::kParallel, 20, 60, 0, 3.0};
  const GearOrders p = gear_orders(par, 2.0 * std::numbers::pi);  // 1 rev/s at the output
  EXPECT_DOUBLE_EQ(p.f_in_hz, 3.0);
  EXPECT_DOUBLE_EQ(p.gmf_hz, 60.0);
  EXPECT_DOUBLE_EQ(p.f_spur_hz, 1.0);  // the driven gear turns with the output
  EXPECT_EQ(p.dmf_hz, 0.0);
  EXPECT_EQ(gear_orders(dsp::GearboxInfo{}, 3.0).gmf_hz, 0.0);
  EXPECT_TRUE(order_markers(gear_orders(dsp::GearboxInfo{}, 3.0), 1000.0, true).empty());
}

TEST(ReportOrders, MarkersUpToTheBandEdge) {
  const GearOrders o = gear_orders(kGearbox, kSpeedRadS);
  // GMF harmonics only: every k GMF <= 12800 Hz, i.e. k = 1..24 (24 x 526.670 = 12640 Hz).
  const auto gmf_only = order_markers(o, 12800.0, false);
  ASSERT_EQ(gmf_only.size(), 24U);
  EXPECT_EQ(gmf_only.front().text, "GMF");
  EXPECT_EQ(gmf_only[8].text, "9\xC3\x97");
  EXPECT_NEAR(gmf_only.back().x, 24.0 * o.gmf_hz, 1e-9);
  // With shaft orders, up to 70 Hz: in 18.81, 2in 37.62, 3in 56.43; spur 22.90, 2spur 45.80,
  // 3spur 68.70; DMF 22.22, 2DMF 44.45, 3DMF 66.67; sorted by frequency. No GMF below 70 Hz.
  const auto low = order_markers(o, 70.0, true);
  ASSERT_EQ(low.size(), 9U);
  const char* expected[] = {"in", "DMF", "spur", "2in", "2DMF", "2spur", "3in", "3DMF", "3spur"};
  for (std::size_t i = 0; i < low.size(); ++i) {
    EXPECT_EQ(low[i].text, expected[i]) << i;
    if (i > 0) {
      EXPECT_LT(low[i - 1].x, low[i].x);
    }
  }
  EXPECT_NEAR(low[8].x, 3.0 * o.f_spur_hz, 1e-12);
}

TEST(ReportEvidence, BandExcessInBandWidths) {
  dsp::FeatureThresholds t;
  t.rms = {0.2, 0.3};
  t.entropy = {0.8, 0.9};
  EXPECT_NEAR(band_excess({0.35, 0.85}, t), 0.5, 1e-12);     // rms half a band width above
  EXPECT_NEAR(band_excess({0.25, 0.70}, t), 1.0, 1e-12);     // entropy a band width below
  EXPECT_NEAR(band_excess({0.29, 0.85}, t), -0.1, 1e-12);    // inside: 0.1 widths below the rms top
  EXPECT_NEAR(band_excess({0.21, 0.895}, t), -0.05, 1e-12);  // inside: entropy 0.05 widths from its top
  // rms below its band (-2 widths) is not abnormal; the entropy's -0.5 is the larger of the two.
  EXPECT_NEAR(band_excess({0.10, 0.85}, t), -0.5, 1e-12);
  EXPECT_TRUE(std::isinf(band_excess({std::nan(""), 0.85}, t)));
  EXPECT_EQ(report_time(28.2744), "28.274 s");
  EXPECT_EQ(report_time(0.0), "0.000 s");
}

TEST(ReportEvidence, EnvelopeBandFindsTheResonance) {
  // White noise everywhere; in the "faulty" window a 3 kHz ringing burst every 1/23 s on top.
  constexpr std::size_t n = 12800;
  std::vector<float> healthy(n), faulty(n);
  Lcg rng{11};
  for (std::size_t i = 0; i < n; ++i) {
    const double t = static_cast<double>(i) / kFsHz;
    const double since = std::fmod(t, 1.0 / 23.0);
    const double ring = 2.0 * std::exp(-since * 300.0) * std::sin(2.0 * std::numbers::pi * 3000.0 * since);
    healthy[i] = static_cast<float>(0.5 * rng.uniform());
    faulty[i] = static_cast<float>(0.5 * rng.uniform() + ring);
  }
  const EnvelopeBand b = choose_envelope_band(faulty, healthy, kFsHz, kGmfHz);
  EXPECT_NEAR(b.hi_hz - b.lo_hz, 2.0 * kGmfHz, 1e-9);
  EXPECT_LT(b.lo_hz, 3000.0);
  EXPECT_GT(b.hi_hz, 3000.0);
  EXPECT_GE(b.lo_hz, kGmfHz);
  EXPECT_NE(b.reason.find("relative to the reference"), std::string::npos);
  EXPECT_THROW((void)choose_envelope_band(faulty, std::vector<float>(100), kFsHz, kGmfHz), ptda::Error);
}

TEST(Report, WritesSampleReportFile) {
  const ReportData d = make_data();
  const auto path = test_tmp_dir() / "sample_report.html";
  write_html_report(path, d);
  std::ifstream f(path, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  EXPECT_EQ(ss.str(), render_html_report(d));
  EXPECT_GT(std::filesystem::file_size(path), 100000U);
  EXPECT_LT(std::filesystem::file_size(path), 2U * 1024U * 1024U);
  EXPECT_THROW(write_html_report(test_tmp_dir() / "no-such-dir" / "r.html", d), ptda::Error);
}

}  // namespace
}  // namespace ptda::cli
