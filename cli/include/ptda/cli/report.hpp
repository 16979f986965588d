// The self-contained HTML report of `ptda report`: one file, inline SVG plots, no external resources.
// The CLI fills a ReportData (plain data) and calls write_html_report; nothing here runs real-time.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "ptda/cli/svg_plot.hpp"
#include "ptda/dsp/baseline.hpp"

namespace ptda::cli {

/// One analysed window shown like the paper's Figs. 8-11: raw, then deterministic and residual
/// parts for TDA and for PTDA, each in time and in frequency. Empty vectors are drawn as
/// "no data" plots. Lengths supported by ptda::dsp::RealFft get spectra; others throw.
struct WindowExample {
  std::string title;                      ///< e.g. "faulty recording, window 12 (class 0, 3.49 rad/s)"
  double fs_hz = 0.0;                     ///< sampling rate of the samples below
  std::vector<float> raw;                 ///< x[n]
  std::vector<float> det_tda, res_tda;    ///< TDA deterministic and residual
  std::vector<float> det_ptda, res_ptda;  ///< PTDA deterministic and residual
  std::vector<double> marker_freqs_hz;    ///< GMF and harmonics of this window; empty: ReportData's
};

/// Features of one judged window.
struct TrendPoint {
  double t_s = 0.0;              ///< window start, seconds from the first recording's start
  std::uint32_t window_seq = 0;  ///< running window number (x axis of the trend plots)
  std::int32_t class_id = -1;    ///< segment class; -1 when unclassified
  double rms_res = 0.0;          ///< eq. 14
  double entropy_res = 0.0;      ///< eqs. 15-16, normalised to [0, 1]
  bool abnormal = false;         ///< outside a band of its class
  bool alarm = false;            ///< k-of-n alarm active after this window
  std::string recording;         ///< label, e.g. "healthy" / "faulty"
};

/// Feature trend of one method with the bands each class was judged against.
struct MethodTrend {
  std::string method;  ///< "raw", "tda", "ptda"
  std::vector<TrendPoint> points;
  std::vector<std::pair<std::int32_t, ptda::dsp::FeatureThresholds>> class_thresholds;
};

struct ReportData {
  std::string title;
  std::vector<std::pair<std::string, std::string>> summary;  ///< key/value facts, shown in order
  std::vector<double> marker_freqs_hz;                       ///< GMF and harmonics to mark on spectra
  std::vector<WindowExample> examples;
  std::vector<MethodTrend> trends;  ///< raw, tda, ptda
  std::vector<std::string> notes;
  std::string signal_unit = "m/s^2";  ///< unit of the vibration samples
  double spectrum_max_hz = 0.0;       ///< upper limit of the spectra; <= 0: fs/2
};

/// The whole HTML document. Deterministic: same data -> same bytes. Thread: any. Allocates.
/// Throws ptda::Error when an example has a non-empty signal of a length RealFft does not support
/// or a non-positive fs_hz.
[[nodiscard]] std::string render_html_report(const ReportData& data);

/// Renders and writes the report to out (parent directory must exist).
/// Throws ptda::Error naming the path on I/O failure. Thread: any. Allocates, blocks on I/O.
void write_html_report(const std::filesystem::path& out, const ReportData& data);

// ---- building blocks of the report (exposed for tests and other front ends) ----

enum class TrendFeature { kRms, kEntropy };

/// Size of each feature-trend plot in the report.
inline constexpr svg::PlotStyle kTrendPlotStyle{560, 250, 62, 12, 38, 40, 11};

/// Feature trend of one method as a plot: x = window_seq, points coloured by class, abnormal
/// windows ringed in red, each class's band drawn as a dashed pair of lines with a light fill,
/// alarm-active windows shaded, and a dotted line where the recording label changes.
[[nodiscard]] svg::Plot trend_plot(const MethodTrend& trend, TrendFeature feature,
                                   const std::string& signal_unit);

}  // namespace ptda::cli
