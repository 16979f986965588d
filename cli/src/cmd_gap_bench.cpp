// ptda gap-bench [--cases N --seed S] [--corpus DIR ...] [--json OUT] [--markdown OUT] [--jobs A.toml,B.toml]
//                [--cycles N] [--work DIR]
#include <fstream>
#include <functional>
#include <iostream>
#include <ostream>
#include <sstream>

#include "ptda/cli/args.hpp"
#include "ptda/cli/commands.hpp"
#include "ptda/cli/gap_corpus.hpp"
#include "ptda/common/error.hpp"
#include "ptda/gap/bench.hpp"

namespace ptda::cli {
namespace {

void write_text(const std::string& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  if (!f) throw Error(path + ": cannot open for writing");
  f << text;
  if (!f.flush()) throw Error(path + ": write failed");
}

void print_table(std::ostream& out, const gap::BenchResult& r) {
  out << "corpus          " << r.corpus << "\n";
  out << "cases           " << r.effect_cases << " with effects, " << r.none_cases << " controls, "
      << r.ool_cases << " out of library"
      << (r.errors ? ", " + std::to_string(r.errors) + " failed" : std::string()) << "\n";
  out << "top-1 accuracy  " << 100.0 * r.top1_accuracy << " %\n";
  out << "location        " << 100.0 * r.location_accuracy << " % of the correct top-1\n";
  out << "named, located  " << (r.effect_cases ? 100.0 * r.named_located / r.effect_cases : 0.0)
      << " % of the effect cases (the true effect anywhere in the explanation, at its place)\n";
  out << "false attrib.   " << 100.0 * r.false_attribution_rate << " % of the no-effect cases\n";
  if (r.ool_cases)
    out << "false attrib.   " << 100.0 * r.ool_false_attribution_rate << " % of the out-of-library cases\n";
  out << "median shrink   " << r.median_shrink_pct << " %\n";
  out << "time per case   " << r.median_case_runtime_s << " s median, " << r.max_case_runtime_s << " s max\n";
  out << "CPU per case    " << r.max_case_cpu_s << " s max (diagnosis process, all threads)\n";
  out << "peak memory     " << r.max_peak_rss_mib << " MiB (largest case)\n";
  out << "runtime         " << r.runtime_s << " s\n";
}

}  // namespace

int cmd_gap_bench(std::span<const std::string> args, std::ostream& out) {
  ArgParser parser(
      "gap-bench",
      "[--cases N --seed S] [--corpus DIR]... [--json OUT] [--markdown OUT] [--jobs A.toml,B.toml] [--cycles "
      "N]",
      "Scores `ptda gap`. With --cases/--seed on simulated cases (the \"project simulator\" corpus): each\n"
      "case's recording carries one withheld effect (or a pair, or none) with randomised parameters; the\n"
      "diagnosis sees only the recording and the nominal job scenario. With --corpus DIR (repeatable) on\n"
      "the cases listed in DIR/corpus.json (recording, nominal scenario, truth; tests/gen2 writes them).\n"
      "Reports per corpus top-1 accuracy, location accuracy, false attributions on controls and on\n"
      "out-of-library cases, the median held-out shrink, a confusion matrix, time and peak memory per\n"
      "case (docs/gap.md \"Bench\").");
  parser.option("cases", "N", "number of simulated cases (they cycle: each effect alone, none, a pair)")
      .option("seed", "S", "bench seed (case parameters, amplitudes, noise and recording seeds)")
      .option("corpus", "DIR", "score the cases of corpus directory DIR (repeatable: one table each)", false,
              true)
      .option("json", "OUT",
              "write the per-case results and confusion matrices as JSON (one bench: format ptda-gap-bench; "
              "several: ptda-gap-bench-set)")
      .option("markdown", "OUT", "write the summary, confusion matrices and per-case tables as markdown")
      .option("jobs", "LIST",
              "comma-separated job scenarios, used in turn (default: config/scenarios/"
              "spot_welding_healthy.toml,config/scenarios/arc_welding_healthy.toml)")
      .option("cycles", "N", "job cycles per simulated recording (default 6)")
      .option("only", "LIST", "comma-separated simulated case indices to run (default: all)")
      .option("only-case", "LIST", "comma-separated corpus case names to run (default: all)")
      .option("sim-seed", "N", "model simulation seed for corpus cases (default 424242)")
      .option("work", "DIR", "directory for the temporary recordings (default: system temp)")
      .option("threads", "N",
              "fitting threads per diagnosis (default: one per CPU; results do not depend on it)")
      .flag("keep", "keep the simulated case recordings in the work directory (WORK/caseN)")
      .flag("quiet", "no per-case lines on stderr");
  const ParsedArgs a = parser.parse(args);
  if (a.help()) {
    out << parser.help_text();
    return kExitOk;
  }
  const std::vector<std::string> corpora = a.values("corpus");
  const bool simulated = a.has("cases") || a.has("seed");
  if (simulated && !(a.has("cases") && a.has("seed"))) throw UsageError("--cases and --seed go together");
  if (!simulated && corpora.empty()) throw UsageError("give --cases N --seed S, or --corpus DIR, or both");
  unsigned threads = 0;
  if (a.has("threads")) threads = static_cast<unsigned>(parse_u64_arg(a.value("threads"), "threads"));
  std::function<void(const std::string&)> log;
  if (!a.has("quiet")) log = [](const std::string& s) { std::cerr << "ptda gap-bench: " << s << "\n"; };

  // Read every corpus first so that a broken manifest fails before hours of diagnosis.
  std::vector<gap::Corpus> loaded;
  for (const std::string& dir : corpora) loaded.push_back(load_gap_corpus(dir));

  std::vector<gap::BenchResult> results;
  if (simulated) {
    gap::BenchOptions opt;
    opt.cases = static_cast<std::uint32_t>(parse_u64_arg(a.value("cases"), "cases"));
    opt.seed = parse_u64_arg(a.value("seed"), "seed");
    if (a.has("cycles")) opt.cycles = static_cast<std::uint32_t>(parse_u64_arg(a.value("cycles"), "cycles"));
    if (opt.cycles < 4) throw UsageError("--cycles: needs at least 4 (half are held out)");
    std::string jobs = a.has("jobs") ? a.value("jobs")
                                     : "config/scenarios/spot_welding_healthy.toml,config/scenarios/"
                                       "arc_welding_healthy.toml";
    std::stringstream ss(jobs);
    for (std::string j; std::getline(ss, j, ',');) opt.jobs.emplace_back(j);
    if (a.has("only")) {
      std::stringstream os(a.value("only"));
      for (std::string j; std::getline(os, j, ',');)
        opt.only.push_back(static_cast<std::uint32_t>(parse_u64_arg(j, "only")));
    }
    opt.work_dir = a.has("work") ? std::filesystem::path(a.value("work"))
                                 : std::filesystem::temp_directory_path() /
                                       ("ptda-gap-bench-" + std::to_string(opt.seed));
    opt.keep_recordings = a.has("keep");
    opt.threads = threads;
    opt.log = log;
    results.push_back(gap::run_bench(opt));
  }
  for (const gap::Corpus& c : loaded) {
    gap::CorpusBenchOptions opt;
    opt.threads = threads;
    opt.log = log;
    if (a.has("sim-seed")) opt.sim_seed = parse_u64_arg(a.value("sim-seed"), "sim-seed");
    if (a.has("only-case")) {
      std::stringstream os(a.value("only-case"));
      for (std::string j; std::getline(os, j, ',');) opt.only.push_back(j);
    }
    results.push_back(gap::run_corpus_bench(c, opt));
  }
  if (a.has("json")) {
    write_text(a.value("json"),
               results.size() == 1 ? gap::bench_json(results[0]) : gap::bench_set_json(results));
  }
  if (a.has("markdown")) write_text(a.value("markdown"), gap::bench_markdown(results));
  for (std::size_t i = 0; i < results.size(); ++i) {
    if (i) out << "\n";
    print_table(out, results[i]);
  }
  return kExitOk;
}

}  // namespace ptda::cli
