// ptda evaluate --healthy A.jsonl [--healthy ...] --faulty B.jsonl [--faulty ...] [--json OUT] [--markdown]
// ptda evaluate --plot OUT.svg --results R.json [--results ...] [--feature F] [--title T] [--x-label L]
#include <fstream>
#include <ostream>

#include "ptda/cli/args.hpp"
#include "ptda/cli/commands.hpp"
#include "ptda/cli/evaluate.hpp"
#include "ptda/common/error.hpp"

namespace ptda::cli {

namespace {

std::string joined(const std::vector<std::string>& paths) {
  std::string s;
  for (const auto& p : paths) s += (s.empty() ? "" : ", ") + p;
  return s;
}

void write_text_file(const std::string& path, const std::string& text, std::ostream& out) {
  if (path == "-") {
    out << text;
    return;
  }
  std::ofstream f(path, std::ios::out | std::ios::trunc | std::ios::binary);
  if (!f) throw Error(path + ": cannot open for writing");
  f << text;
  f.flush();
  if (!f) throw Error(path + ": write failed");
}

int plot_mode(const ParsedArgs& a, std::ostream& out) {
  const std::vector<std::string> files = a.values("results");
  if (files.empty()) throw UsageError("--plot needs at least one --results FILE (written by --json)");
  std::vector<Evaluation> results;
  for (const auto& path : files) {
    std::ifstream f(path, std::ios::binary);
    if (!f) throw Error(path + ": cannot open");
    std::string line;
    std::size_t line_no = 0;
    while (std::getline(f, line)) {
      ++line_no;
      if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
      results.push_back(parse_evaluation_json(line, path + ":" + std::to_string(line_no)));
    }
  }
  const std::string feature = a.value_or("feature", "rms_res");
  if (feature != "rms_res" && feature != "entropy_res") {
    throw UsageError("--feature: expected rms_res or entropy_res, got '" + feature + "'");
  }
  const std::string svg =
      auc_plot_svg(results, feature, a.value_or("title", feature + " ROC AUC"), a.value_or("x-label", "x"));
  write_text_file(a.value("plot"), svg + "\n", out);
  if (a.value("plot") != "-") out << "wrote " << a.value("plot") << " (" << results.size() << " results)\n";
  return kExitOk;
}

}  // namespace

int cmd_evaluate(std::span<const std::string> args, std::ostream& out) {
  ArgParser parser(
      "evaluate",
      "--healthy A.jsonl [--healthy ...] --faulty B.jsonl [--faulty ...] [--json OUT] [--markdown]\n"
      "       ptda evaluate --plot OUT.svg --results R.json [--results ...] [--feature F]",
      "Reads `ptda monitor --jsonl` output of healthy and faulty recordings (one method) and reports, for\n"
      "the scored windows and each feature (rms_res, entropy_res): the mean on each set, the ratio\n"
      "faulty/healthy and the ROC AUC = P(faulty value > healthy value) + P(equal)/2 (Mann-Whitney), with\n"
      "the separability max(AUC, 1 - AUC) and its direction; and per set the abnormal fraction and whether\n"
      "the alarm was raised. With --plot, draws the AUC of --json results against their --x as an SVG.");
  parser.option("healthy", "FILE", "monitor JSONL of healthy windows (repeat to pool files)", false, true)
      .option("faulty", "FILE", "monitor JSONL of faulty windows (repeat to pool files)", false, true)
      .option("json", "OUT", "write the result as one JSON line to OUT ('-' = stdout)")
      .flag("markdown", "print a markdown table row (with header unless --no-header) instead of the text")
      .flag("no-header", "with --markdown: only the row")
      .option("label", "TEXT", "name of this case in the outputs (e.g. '0 %, a1')")
      .option("x", "NUMBER", "numeric position of this case for --plot (e.g. the load in %)")
      .option("plot", "OUT.svg", "plot mode: draw the AUC of --results files against their x")
      .option("results", "FILE", "plot mode: a file written by --json (one JSON line per result)", false,
              true)
      .option("feature", "F", "plot mode: rms_res (default) or entropy_res")
      .option("title", "TEXT", "plot mode: plot title")
      .option("x-label", "TEXT", "plot mode: x axis label");
  const ParsedArgs a = parser.parse(args);
  if (a.help()) {
    out << parser.help_text();
    return kExitOk;
  }
  if (a.has("plot")) {
    if (a.has("healthy") || a.has("faulty")) throw UsageError("--plot does not take --healthy/--faulty");
    return plot_mode(a, out);
  }
  if (a.has("results")) throw UsageError("--results is only for --plot");
  const std::vector<std::string> healthy_files = a.values("healthy");
  const std::vector<std::string> faulty_files = a.values("faulty");
  if (healthy_files.empty()) throw UsageError("missing --healthy FILE");
  if (faulty_files.empty()) throw UsageError("missing --faulty FILE");
  if (a.has("no-header") && !a.has("markdown")) throw UsageError("--no-header needs --markdown");

  MonitorWindows healthy;
  for (const auto& p : healthy_files) read_monitor_jsonl(p, healthy);
  MonitorWindows faulty;
  for (const auto& p : faulty_files) read_monitor_jsonl(p, faulty);
  Evaluation e = evaluate_separation(healthy, faulty, joined(healthy_files), joined(faulty_files));
  e.label = a.value_or("label", "");
  if (a.has("x")) e.x = parse_double_arg(a.value("x"), "x");

  const std::string json_path = a.value_or("json", "");
  if (!json_path.empty()) write_text_file(json_path, evaluation_json(e) + "\n", out);
  if (json_path == "-") return kExitOk;
  if (a.has("markdown")) {
    if (!a.has("no-header")) out << evaluation_markdown_header();
    out << evaluation_markdown_row(e);
  } else {
    out << evaluation_text(e);
  }
  return kExitOk;
}

}  // namespace ptda::cli
