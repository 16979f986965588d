// A small plotting module for the HTML report: inline SVG strings for time signals, spectra and
// feature trends. Deterministic (same input -> same bytes; numbers printed with fixed precision),
// self-contained (no fonts, scripts or links), all text XML-escaped. Offline code: allocates, may throw.
#pragma once

#include <cstddef>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace ptda::cli::svg {

/// Escapes & < > " ' for XML text and attribute values.
[[nodiscard]] std::string escape_xml(std::string_view text);

/// Formats v with `decimals` digits after the point, "C" locale style, no "-0".
[[nodiscard]] std::string format_fixed(double v, int decimals);

/// "Nice" axis ticks (steps 1, 2, 2.5 or 5 times a power of ten) covering [lo, hi] with about
/// target_count intervals. values are the multiples of step inside [lo, hi] (with a tolerance of
/// 1e-9 step); decimals is what printing them needs.
struct Ticks {
  std::vector<double> values;
  double step = 1.0;
  int decimals = 0;
};
/// Throws ptda::Error when lo or hi is not finite or target_count < 1. lo == hi gets a unit range
/// around the value; lo > hi is swapped.
[[nodiscard]] Ticks nice_ticks(double lo, double hi, int target_count = 5);

/// Min/max envelope of a polyline for display: points (x sorted ascending) are binned into
/// `columns` equal columns over [x_lo, x_hi]; a column with more than two points is replaced by its
/// minimum and maximum points, in the order they occur (so shape and peaks are kept). Columns with
/// one or two points keep them. Points outside [x_lo, x_hi] or not finite are dropped.
/// Throws ptda::Error when x and y differ in size, columns == 0, or x_hi <= x_lo.
[[nodiscard]] std::vector<std::pair<double, double>> min_max_envelope(std::span<const double> x,
                                                                      std::span<const double> y, double x_lo,
                                                                      double x_hi, std::size_t columns);

/// One-sided amplitude spectrum of a real signal via ptda::dsp::RealFft: amplitude[k] = 2|X[k]|/N
/// (|X[0]|/N at DC and Nyquist), so a sine of amplitude A shows a peak of A; freq_hz[k] = k fs / N.
/// Throws ptda::Error when fs_hz <= 0 or the length is not supported by RealFft.
struct Spectrum {
  std::vector<double> freq_hz;
  std::vector<double> amplitude;
};
[[nodiscard]] Spectrum amplitude_spectrum(std::span<const float> x, double fs_hz);

/// Amplitudes in dB re 1 unit: 20 log10(a). Values below floor_db (zeros and negatives included)
/// are set to floor_db, so a spectrum with exact zeros still plots; NaN stays NaN (not drawn).
/// Throws ptda::Error when floor_db is not finite. Thread: any. Allocates the result.
[[nodiscard]] std::vector<double> amplitude_db(std::span<const double> amplitude, double floor_db);

/// Envelope spectrum (demodulation): the FFT of x is band-passed to [f_lo_hz, f_hi_hz] (bins outside
/// set to zero, DC and Nyquist always removed), the band signal b[n] and its Hilbert transform h[n]
/// (the band bins times -j) come back by two inverse real FFTs, the envelope is
/// e[n] = sqrt(b^2 + h^2) = |analytic signal|, and the result is amplitude_spectrum(e - mean(e)).
/// For x = A (1 + m cos 2 pi fm t) cos 2 pi fc t with the band around fc +- fm, the line at fm has
/// amplitude A m. Throws ptda::Error when fs_hz <= 0, the length is not supported by RealFft, or the
/// band is empty or not inside (0, fs/2). Thread: any. Allocates.
[[nodiscard]] Spectrum envelope_spectrum(std::span<const float> x, double fs_hz, double f_lo_hz,
                                         double f_hi_hz);

/// A data series. kLine draws a polyline (decimated by min_max_envelope to the pixel columns);
/// kMarkers draws a circle per point; kRings an open circle per point (e.g. abnormal windows).
struct Series {
  enum class Kind { kLine, kMarkers, kRings };
  std::string label;  ///< legend text; empty: not in the legend
  std::string color = "#1f77b4";
  Kind kind = Kind::kLine;
  std::vector<double> x, y;
  double width_px = 1.0;  ///< line width, or marker radius for kMarkers / kRings
};

/// Horizontal band [lo, hi] over the full x range: light fill and dashed lines at both edges.
struct HBand {
  double lo = 0.0, hi = 0.0;
  std::string label;
  std::string color = "#2ca02c";
};

/// Shaded vertical span [x_lo, x_hi] (e.g. where the alarm is active).
struct VSpan {
  double x_lo = 0.0, x_hi = 0.0;
  std::string label;
  std::string color = "#d62728";
};

/// Vertical dashed marker line (e.g. GMF harmonics); text (may be empty) is written at its top, on
/// one of three staggered rows so close markers stay readable (left out when no row has room).
struct VLine {
  double x = 0.0;
  std::string text;
  std::string color = "#7f7f7f";
};

struct Plot {
  std::string title;
  std::string x_label;  ///< with unit, e.g. "time [s]"
  std::string y_label;  ///< with unit
  std::vector<Series> series;
  std::vector<HBand> bands;
  std::vector<VSpan> spans;
  std::vector<VLine> vlines;
  std::string legend_span_label;  ///< unused unless non-empty: legend entry for the spans' color
  std::optional<double> x_min, x_max, y_min, y_max;  ///< fixed axis limits; unset: from the data
  /// Custom x ticks (position, text), e.g. times that restart at 0 for each recording of a trend;
  /// empty: automatic nice ticks. Ticks outside the x range are not drawn.
  std::vector<std::pair<double, std::string>> x_tick_labels;
  std::string empty_message = "no data";  ///< shown when there is nothing to draw
};

struct PlotStyle {
  int width_px = 460;
  int height_px = 210;
  int margin_left_px = 62;
  int margin_right_px = 12;
  int margin_top_px = 38;  ///< title and legend
  int margin_bottom_px = 40;
  int font_px = 11;
};

/// Axis limits and pixel mapping chosen for a plot: x limits are the data range (or the fixed
/// ones); y limits are the data range including bands, padded by 5 % and widened to tick multiples.
struct Layout {
  double x_lo = 0.0, x_hi = 1.0, y_lo = 0.0, y_hi = 1.0;
  Ticks x_ticks, y_ticks;
  double left_px = 0.0, top_px = 0.0, width_px = 1.0, height_px = 1.0;  ///< plot area
  bool empty = true;                                                    ///< nothing finite to draw
  [[nodiscard]] double x_px(double x) const noexcept {
    return left_px + (x - x_lo) / (x_hi - x_lo) * width_px;
  }
  [[nodiscard]] double y_px(double y) const noexcept {
    return top_px + (y_hi - y) / (y_hi - y_lo) * height_px;
  }
};
[[nodiscard]] Layout compute_layout(const Plot& plot, const PlotStyle& style = {});

/// Pixel coordinates are printed with this many decimals.
inline constexpr int kPixelDecimals = 1;

/// The plot as one <svg> element (no XML declaration), sized style.width_px x style.height_px.
[[nodiscard]] std::string render_svg(const Plot& plot, const PlotStyle& style = {});

}  // namespace ptda::cli::svg
