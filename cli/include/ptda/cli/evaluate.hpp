// Separation of healthy and faulty windows, computed from `ptda monitor --jsonl` output: per feature the
// means, the ratio faulty/healthy and the ROC AUC (Mann-Whitney form), plus detection rates and alarms
// per set. Used by `ptda evaluate` and the measured-data study (docs/results-gfd.md).
// Thread: any (offline tool). Allocates; bad input throws ptda::Error naming file and line.
#pragma once

#include <array>
#include <cstddef>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace ptda::cli {

/// The scored windows of one monitor JSONL file (or several, appended).
struct MonitorWindows {
  std::string method;           ///< "raw", "tda" or "ptda"; empty when no line was read
  std::size_t windows = 0;      ///< every line (scored or not)
  std::vector<double> rms_res;  ///< of the scored windows, in file order
  std::vector<double> entropy_res;
  std::size_t abnormal = 0;       ///< scored windows judged abnormal
  std::size_t alarm_windows = 0;  ///< windows with the k-of-n alarm active
  [[nodiscard]] std::size_t scored() const noexcept { return rms_res.size(); }
};

/// Reads one monitor JSONL file and appends its windows to `into`. Every line must be a JSON object
/// with the monitor fields; a scored window needs finite rms_res and entropy_res. All lines (and what
/// `into` already holds) must have one method. Blank lines are skipped. Throws ptda::Error
/// "<path>:<line>: <what>" (or "<path>: cannot open").
void read_monitor_jsonl(const std::string& path, MonitorWindows& into);

/// ROC AUC in the Mann-Whitney form: the probability that a faulty value exceeds a healthy one,
/// ties counting 1/2, i.e. U / (n_h n_f) with U = #{f > h} + #{f == h}/2 over all pairs. Exact: the
/// pair counts are integers and only the final division rounds. Throws ptda::Error when a set is
/// empty or holds a NaN.
[[nodiscard]] double roc_auc(std::span<const double> healthy, std::span<const double> faulty);

/// Which way a feature moves with the fault, from the AUC.
enum class Direction { kHigher, kLower, kNone };
[[nodiscard]] const char* direction_name(Direction d) noexcept;  ///< "higher", "lower", "none"

struct FeatureSeparation {
  std::string feature;  ///< "rms_res" or "entropy_res"
  double mean_healthy = 0.0;
  double mean_faulty = 0.0;
  double ratio = 0.0;                      ///< mean_faulty / mean_healthy (inf/NaN when mean_healthy == 0)
  double auc = 0.5;                        ///< P(faulty > healthy) + P(equal)/2
  double separability = 0.5;               ///< max(auc, 1 - auc): 1 = perfectly separated either way
  Direction direction = Direction::kNone;  ///< kHigher when auc > 0.5, kLower when < 0.5
};

/// Detection on one set (healthy or faulty).
struct SetSummary {
  std::size_t windows = 0;
  std::size_t scored = 0;
  std::size_t abnormal = 0;
  std::size_t alarm_windows = 0;
  [[nodiscard]] double detection_rate() const noexcept {
    return scored == 0 ? 0.0 : static_cast<double>(abnormal) / static_cast<double>(scored);
  }
  [[nodiscard]] bool alarm() const noexcept { return alarm_windows > 0; }
};

struct Evaluation {
  std::string label;        ///< free text naming the case (may be empty)
  std::optional<double> x;  ///< numeric position for plots (e.g. the load in %)
  std::string method;
  SetSummary healthy, faulty;
  std::array<FeatureSeparation, 2> features;  ///< rms_res, entropy_res
};

/// Evaluates the scored windows. Throws ptda::Error when the methods differ (naming both) or a set has no
/// scored window (`healthy_source`/`faulty_source` name the files in the message).
[[nodiscard]] Evaluation evaluate_separation(const MonitorWindows& healthy, const MonitorWindows& faulty,
                                             const std::string& healthy_source,
                                             const std::string& faulty_source);

/// One-line JSON object of the evaluation (numbers round-trip; non-finite as null).
[[nodiscard]] std::string evaluation_json(const Evaluation& e);
/// Reads back evaluation_json's output (the fields plots need: label, x, method, features).
/// Throws ptda::Error naming `source`.
[[nodiscard]] Evaluation parse_evaluation_json(const std::string& text, const std::string& source);

/// Human-readable summary (several lines).
[[nodiscard]] std::string evaluation_text(const Evaluation& e);
/// Markdown table header (two lines) and one row per evaluation.
[[nodiscard]] std::string evaluation_markdown_header();
[[nodiscard]] std::string evaluation_markdown_row(const Evaluation& e);

/// SVG line chart of one feature's AUC against x, one series per method (raw, tda, ptda in that order;
/// points sorted by x), y fixed to [-0.05, 1.05] with a dashed line at 0.5. Throws ptda::Error when `feature`
/// is not rms_res/entropy_res or an evaluation has no x.
[[nodiscard]] std::string auc_plot_svg(std::span<const Evaluation> results, const std::string& feature,
                                       const std::string& title, const std::string& x_label);

}  // namespace ptda::cli
