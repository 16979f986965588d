// The self-contained HTML report of `ptda report`: one file, inline SVG plots, no external resources.
// The CLI fills a ReportData (plain data) and calls write_html_report; nothing here runs real-time.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "ptda/cli/svg_plot.hpp"
#include "ptda/dsp/baseline.hpp"

namespace ptda::cli {

/// Frequencies of the gearbox at one joint speed (paper eqs. 1, 3, 4); all 0 when the gearbox is
/// unknown. The spur shaft turns at GMF / z_spur (cycloidal: the crankshafts; parallel: the output).
struct GearOrders {
  double f_out_hz = 0.0;   ///< joint (output) speed |w| / 2 pi
  double f_in_hz = 0.0;    ///< input shaft: R f_out
  double f_spur_hz = 0.0;  ///< spur gear shaft: GMF / z_spur
  double gmf_hz = 0.0;     ///< gear mesh frequency z_in f_in (eq. 3)
  double dmf_hz = 0.0;     ///< disk mesh frequency z_pin f_out (eq. 4); cycloidal only, else 0
};
/// Thread: any. Never allocates or throws.
[[nodiscard]] GearOrders gear_orders(const ptda::dsp::GearboxInfo& g, double speed_rad_s) noexcept;

/// Marker lines for a spectrum shown up to f_hi_hz: every GMF harmonic up to f_hi_hz ("GMF", "2×",
/// ...), and with shaft_orders also the input shaft, spur shaft and DMF and their 2nd and 3rd
/// harmonics ("in", "spur", "DMF", "2in", ...). Empty when o.gmf_hz is 0. Thread: any. Allocates.
[[nodiscard]] std::vector<svg::VLine> order_markers(const GearOrders& o, double f_hi_hz, bool shaft_orders);

/// Band of the envelope spectrum and why it was chosen (shown in the report).
struct EnvelopeBand {
  double lo_hz = 0.0, hi_hz = 0.0;
  std::string reason;
};
/// Picks the demodulation band: width 2 GMF (fs/16 when the GMF is unknown, at most fs/4), slid in
/// quarter-width steps with the low edge at or above the GMF (fs/32 when unknown) and the high edge
/// at or below fs/2; the band where x has the most energy, relative to `reference` when that is
/// given (same length; e.g. a healthy window's residual: the band where x gained most). Throws
/// ptda::Error on lengths RealFft does not support or a non-positive fs. Thread: any. Allocates.
[[nodiscard]] EnvelopeBand choose_envelope_band(std::span<const float> x, std::span<const float> reference,
                                                double fs_hz, double gmf_hz);

/// Where a window's features sit relative to its class band, in band widths: rms_res above the top
/// edge ((rms - hi) / (hi - lo); the residual RMS band is one-sided, paper section 3.4 as judged by
/// dsp::judge) and entropy_res outside either edge; the larger of the two. > 0: outside (abnormal);
/// <= 0: inside, 0 at an edge, so the largest value among normal windows is the one closest to its
/// band. A degenerate band (hi <= lo) counts as width 1e-12. Thread: any. Never allocates.
[[nodiscard]] double band_excess(const ptda::dsp::Features& f,
                                 const ptda::dsp::FeatureThresholds& t) noexcept;

/// One analysed window shown like the paper's Figs. 8-11: raw, then deterministic and residual
/// parts for TDA and for PTDA, each in time and as a dB spectrum; then a zoom on the low GMF
/// harmonics and the envelope spectra of raw and PTDA residual. Empty vectors are drawn as
/// "no data" plots. Lengths supported by ptda::dsp::RealFft get spectra; others throw.
struct WindowExample {
  std::string title;                      ///< e.g. "faulty, window 12 at 24.500 s (class 0, 3.49 rad/s)"
  double fs_hz = 0.0;                     ///< sampling rate of the samples below
  std::vector<float> raw;                 ///< x[n]
  std::vector<float> det_tda, res_tda;    ///< TDA deterministic and residual
  std::vector<float> det_ptda, res_ptda;  ///< PTDA deterministic and residual
  GearOrders orders;                      ///< at this window's speed; gmf_hz 0: no order markers
  std::string evidence;                   ///< why this window was chosen (features against its band)
  std::string note;                       ///< a caution shown highlighted; empty: none
};

/// Features of one judged window.
struct TrendPoint {
  double t_s = 0.0;              ///< window start, seconds from the start of its own recording
  std::uint32_t window_seq = 0;  ///< window number within its recording
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
  double window_s = 0.0;  ///< window duration (alarm shading extends to the end of the last window)
  /// The time axis's label; "" = "time in the recording [s]" (a history: hours since its first line).
  std::string time_axis_label;
};

/// One recording of the report, in --recording order.
struct RecordingSummary {
  std::string label;
  double duration_s = 0.0;
  std::string verdict;  ///< one line, e.g. "ALARM at 25.762 s (...)"
  bool alarm = false;   ///< the verdict is an alarm (shown in red)
};

/// Formats a time within a recording the one way the report prints it everywhere: "25.762 s".
[[nodiscard]] std::string report_time(double t_s);

struct ReportData {
  std::string title;
  std::vector<std::pair<std::string, std::string>> summary;         ///< key/value facts, shown in order
  std::vector<RecordingSummary> recordings;                         ///< verdicts and trend time axis
  ptda::dsp::GearboxInfo gearbox;                                   ///< tooth counts and R for the header
  std::vector<std::pair<std::int32_t, double>> class_speeds_rad_s;  ///< GMF per speed class
  std::vector<WindowExample> examples;
  std::vector<MethodTrend> trends;  ///< raw, tda, ptda
  std::vector<std::string> notes;
  std::string signal_unit = "m/s^2";  ///< unit of the vibration samples
  double spectrum_max_hz = 0.0;       ///< upper limit of the full spectra; <= 0: fs/2
  EnvelopeBand envelope_band;         ///< hi_hz <= 0: chosen per example from its PTDA residual
  /// A daemon's event history (ptda report --history): no gearbox header, no example windows; times
  /// in hours since the history's first line.
  bool from_history = false;
  /// Order domain (docs/method.md §9): the example windows are on the input shaft's angle axis, so
  /// WindowExample::fs_hz is samples per input-shaft revolution, the spectra's axis is input-shaft
  /// orders, the time panels' axis is revolutions, and EnvelopeBand and GearOrders are in orders.
  bool order_domain = false;
};

/// Dynamic range of the dB spectra: the floor is this far below the top of each plot's scale.
inline constexpr double kSpectrumRangeDb = 80.0;

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

/// Feature trend of one method as a plot on a time axis: the recordings side by side (in the order
/// of `recordings`, else of first appearance), each with its own time ticks starting at 0 s and a
/// dotted line with its label at its start; points coloured by class, abnormal windows ringed in red,
/// each class's band drawn as a dashed pair of lines with a light fill, alarm-active time shaded.
[[nodiscard]] svg::Plot trend_plot(const MethodTrend& trend, TrendFeature feature,
                                   const std::string& signal_unit,
                                   const std::vector<RecordingSummary>& recordings = {});

}  // namespace ptda::cli
