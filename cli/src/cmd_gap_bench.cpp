// ptda gap-bench --cases N --seed S --json OUT [--jobs A.toml,B.toml] [--cycles N] [--work DIR]
#include <fstream>
#include <iostream>
#include <ostream>
#include <sstream>

#include "ptda/cli/args.hpp"
#include "ptda/cli/commands.hpp"
#include "ptda/common/error.hpp"
#include "ptda/gap/bench.hpp"

namespace ptda::cli {

int cmd_gap_bench(std::span<const std::string> args, std::ostream& out) {
  ArgParser parser(
      "gap-bench", "--cases N --seed S [--json OUT] [--jobs A.toml,B.toml] [--cycles N] [--work DIR]",
      "Scores `ptda gap` on simulated cases: each case's recording carries one withheld effect (or a\n"
      "pair, or none) with randomised parameters; the diagnosis sees only the recording and the\n"
      "nominal job scenario. Reports top-1 accuracy, location accuracy, false attributions on\n"
      "no-effect cases and the median held-out shrink (docs/gap.md).");
  parser.option("cases", "N", "number of cases (they cycle: each effect alone, none, a pair)", true)
      .option("seed", "S", "bench seed (case parameters, amplitudes, noise and recording seeds)", true)
      .option("json", "OUT", "write the per-case results and confusion matrix as JSON")
      .option("jobs", "LIST",
              "comma-separated job scenarios, used in turn (default: config/scenarios/"
              "spot_welding_healthy.toml,config/scenarios/arc_welding_healthy.toml)")
      .option("cycles", "N", "job cycles per recording (default 6)")
      .option("only", "LIST", "comma-separated case indices to run (default: all); for reproducing a case")
      .option("work", "DIR", "directory for the temporary recordings (default: system temp)")
      .option("threads", "N",
              "fitting threads per diagnosis (default: one per CPU; results do not depend on it)")
      .flag("keep", "keep the case recordings in the work directory (WORK/caseN)")
      .flag("quiet", "no per-case lines on stderr");
  const ParsedArgs a = parser.parse(args);
  if (a.help()) {
    out << parser.help_text();
    return kExitOk;
  }
  gap::BenchOptions opt;
  opt.cases = static_cast<std::uint32_t>(parse_u64_arg(a.value("cases"), "cases"));
  opt.seed = parse_u64_arg(a.value("seed"), "seed");
  if (a.has("cycles")) opt.cycles = static_cast<std::uint32_t>(parse_u64_arg(a.value("cycles"), "cycles"));
  if (opt.cycles < 4) throw UsageError("--cycles: needs at least 4 (half are held out)");
  std::string jobs =
      a.has("jobs") ? a.value("jobs")
                    : "config/scenarios/spot_welding_healthy.toml,config/scenarios/arc_welding_healthy.toml";
  std::stringstream ss(jobs);
  for (std::string j; std::getline(ss, j, ',');) opt.jobs.emplace_back(j);
  if (a.has("only")) {
    std::stringstream os(a.value("only"));
    for (std::string j; std::getline(os, j, ',');)
      opt.only.push_back(static_cast<std::uint32_t>(parse_u64_arg(j, "only")));
  }
  opt.work_dir =
      a.has("work") ? std::filesystem::path(a.value("work"))
                    : std::filesystem::temp_directory_path() / ("ptda-gap-bench-" + std::to_string(opt.seed));
  opt.keep_recordings = a.has("keep");
  if (a.has("threads")) opt.threads = static_cast<unsigned>(parse_u64_arg(a.value("threads"), "threads"));
  if (!a.has("quiet")) opt.log = [](const std::string& s) { std::cerr << "ptda gap-bench: " << s << "\n"; };
  const gap::BenchResult r = gap::run_bench(opt);
  if (a.has("json")) {
    std::ofstream f(a.value("json"), std::ios::binary | std::ios::trunc);
    if (!f) throw Error(a.value("json") + ": cannot open for writing");
    f << gap::bench_json(r);
    if (!f.flush()) throw Error(a.value("json") + ": write failed");
  }
  out << "cases           " << r.effect_cases << " with effects, " << r.none_cases << " without\n";
  out << "top-1 accuracy  " << 100.0 * r.top1_accuracy << " %\n";
  out << "location        " << 100.0 * r.location_accuracy << " % of the correct top-1\n";
  out << "false attrib.   " << 100.0 * r.false_attribution_rate << " % of the no-effect cases\n";
  out << "median shrink   " << r.median_shrink_pct << " %\n";
  out << "runtime         " << r.runtime_s << " s\n";
  return kExitOk;
}

}  // namespace ptda::cli
