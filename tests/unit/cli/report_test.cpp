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
  for (int k = 1; k <= 4; ++k) d.marker_freqs_hz.push_back(k * kGmfHz);
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
    Lcg rng{7};
    int run = 0;
    for (std::uint32_t w = 0; w < 300; ++w) {
      TrendPoint p;
      p.window_seq = w;
      p.t_s = 0.8 * w;
      p.class_id = static_cast<std::int32_t>(w % 2);
      const bool faulty = w >= 150;
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
  // Every plot is an outer <svg> with a nested plot-area <svg>: 6 trend plots + 3 examples x 10.
  EXPECT_EQ(count(html, "<svg "), 2U * (6U + 30U));
  EXPECT_EQ(count(html, "</svg>"), 2U * (6U + 30U));
  for (const char* id :
       {"id=\"summary\">Summary", "id=\"how-to-read\">How to read this report",
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
  const svg::Plot plot = trend_plot(ptda, TrendFeature::kRms, d.signal_unit);
  EXPECT_EQ(plot.spans.size(), alarm_runs);
  ASSERT_EQ(plot.vlines.size(), 2U);
  EXPECT_DOUBLE_EQ(plot.vlines[1].x, 149.5);
  EXPECT_EQ(plot.vlines[1].text, "faulty");
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
  d.spectrum_max_hz = 2500.0;
  const std::string zoom = render_html_report(d);
  EXPECT_EQ(zoom.find(">10000</text>"), std::string::npos);
  EXPECT_EQ(count(full, ">2000</text>"), 0U);
  EXPECT_EQ(count(zoom, ">2000</text>"), 5U);  // 0..2500 Hz: ticks every 1000 Hz in each of the 5 spectra
  EXPECT_EQ(count(zoom, ">4\xC3\x97</text>"), 5U);  // 4 x GMF = 2107 Hz still marked
}

TEST(Report, EmptyPartsAndErrors) {
  ReportData d;
  d.title = "empty";
  d.examples.push_back(WindowExample{"nothing here", 0.0, {}, {}, {}, {}, {}, {}});
  const std::string html = render_html_report(d);
  EXPECT_NE(html.find("No feature trends in this report."), std::string::npos);
  EXPECT_EQ(count(html, "no data: signal not provided"), 10U);

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
