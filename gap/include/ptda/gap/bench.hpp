// gap-bench: cases made with the simulator (one withheld effect, a pair, or none, with randomised
// parameters, amplitudes, noise level and seed), or read from a corpus directory (recordings made by
// other generators or real recordings with injected effects, each with its nominal scenario and truth),
// diagnosed from the recording and the nominal scenario only, and scored (docs/gap.md "Bench").
// Offline: call from one thread at a time (a case's diagnosis runs in a forked child process so that
// its peak memory is measured alone), allocates, writes temporary recordings.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "ptda/gap/diagnose.hpp"
#include "ptda/sim/effects.hpp"

namespace ptda::gap {

struct BenchOptions {
  std::uint32_t cases = 13;
  std::uint64_t seed = 1;
  std::uint32_t cycles = 6;                 ///< job cycles per recording (short: the bench must be fast)
  std::vector<std::filesystem::path> jobs;  ///< job presets (scenario files), used in turn
  std::filesystem::path work_dir;           ///< temporary recordings go here (created)
  bool keep_recordings = false;             ///< leave work_dir/caseN in place (for `ptda gap` on them)
  unsigned threads = 0;                     ///< fitting threads per diagnosis (0: one per hardware thread)
  std::vector<std::uint32_t> only;          ///< run only these case indices (empty: 0 .. cases-1)
  std::function<void(const std::string&)> log;
};

/// What a case holds: one or more library effects, nothing unmodelled (a control: no effect, or a
/// nominal that is off only in its own free parameters), or an effect outside the library.
enum class CaseCategory : std::uint8_t { kEffect, kControl, kOutOfLibrary };
/// "effect", "control", "out_of_library". Any thread; no allocation.
[[nodiscard]] const char* case_category_name(CaseCategory c) noexcept;

struct BenchCaseResult {
  std::uint32_t index = 0;
  std::string name;  ///< corpus case name (built-in bench: "caseN")
  CaseCategory category = CaseCategory::kEffect;
  std::string description;  ///< corpus truth's description (built-in: empty)
  std::string job;
  std::uint64_t seed = 0;
  std::vector<sim::EffectSpec> truth;   ///< withheld effects (empty: none)
  std::vector<sim::EffectSpec> chosen;  ///< what the diagnosis named
  bool top1_correct = false;            ///< first named effect is a true one (none case: nothing named)
  bool location_ok = false;             ///< the named true effect sits where the truth does (see docs/gap.md)
  /// Some named effect, first or later, is a true one at the truth's place: issue 11's criterion for
  /// real recordings with an injected effect, where the recording's own gap may be named beside it.
  bool named_located = false;
  bool false_attribution = false;  ///< control or out-of-library case: something was named
  double shrink_pct = 0.0;         ///< held-out shrink with the chosen effects
  double gap_heldout = 0.0;        ///< calibrated nominal
  double noise_gap = 0.0;          ///< held-out gap expected from sampling
  double noise_gap_sd = 0.0;       ///< its standard deviation
  double runtime_s = 0.0;
  double peak_rss_mib = 0.0;     ///< peak resident memory of the diagnosis process (0: not measured)
  double cpu_s = 0.0;            ///< CPU time (user + system) of the diagnosis process, all its threads
  std::string remaining_probe;   ///< probe holding most of the remaining (unexplained) held-out gap
  double remaining_share = 0.0;  ///< its share of the remaining gap
  std::string verdict;
  std::string error;  ///< the diagnosis failed with this message (scored as wrong; the bench goes on)
};

struct BenchResult {
  std::string corpus = "project simulator";  ///< corpus name
  std::vector<BenchCaseResult> cases;
  double top1_accuracy = 0.0;               ///< over cases with effects
  double location_accuracy = 0.0;           ///< over cases with a correct top-1
  double false_attribution_rate = 0.0;      ///< over control (no-effect) cases
  double ool_false_attribution_rate = 0.0;  ///< over out-of-library cases (anything named is false)
  double median_shrink_pct = 0.0;           ///< over cases with effects
  std::uint32_t effect_cases = 0;
  std::uint32_t none_cases = 0;  ///< control cases
  std::uint32_t ool_cases = 0;   ///< out-of-library cases
  std::uint32_t top1_correct = 0;
  std::uint32_t located = 0;
  std::uint32_t named_located = 0;           ///< effect cases whose true effect is named anywhere, located
  std::uint32_t false_attributions = 0;      ///< on controls
  std::uint32_t ool_false_attributions = 0;  ///< on out-of-library cases
  std::uint32_t errors = 0;                  ///< cases whose diagnosis failed
  double median_case_runtime_s = 0.0;
  double max_case_runtime_s = 0.0;
  double max_case_cpu_s = 0.0;
  double max_peak_rss_mib = 0.0;
  double runtime_s = 0.0;
  /// confusion[truth][named]: truth index kEffectKinds = control (none), kEffectKinds + 1 = out of
  /// library; named kEffectKinds = nothing named.
  std::vector<std::vector<std::uint32_t>> confusion;
};

/// One case of a corpus directory (paths absolute or relative to the working directory).
struct CorpusCase {
  std::string name;
  std::filesystem::path recording;  ///< recording directory (docs/recording-format.md)
  std::filesystem::path nominal;    ///< nominal scenario
  CaseCategory category = CaseCategory::kControl;
  std::vector<sim::EffectSpec> truth;  ///< library effects (category kEffect only)
  std::string description;
};

struct Corpus {
  std::string name;
  std::filesystem::path dir;
  std::vector<CorpusCase> cases;
};

struct CorpusBenchOptions {
  std::uint64_t sim_seed = 424242;  ///< DiagnoseOptions::sim_seed for every case
  unsigned threads = 0;             ///< fitting threads per diagnosis (0: one per hardware thread)
  std::vector<std::string> only;    ///< run only these case names (empty: all)
  std::function<void(const std::string&)> log;
};

/// Truth of case `index` of a bench with `seed`: which effects, with randomised parameters (the rest of
/// the case is drawn in run_bench). Cases cycle through: each effect alone, none, a pair. Deterministic.
[[nodiscard]] std::vector<sim::EffectSpec> bench_case_effects(std::uint32_t index, std::uint64_t seed,
                                                              double fs_hz, double peak_ms2,
                                                              const sim::Scenario& job);

/// Whether `fitted` sits where `truth` does (same kind): resonance within 15 %, modulation rate within
/// 0.15 orders, interference fundamental within 2 %, clock within max(100, 20 %) ppm, latency within
/// 5 ms, other axis ratio within 2 %, clipping level within 5 %, direction gain of the same sign, noise
/// corner within a factor 2, jitter within a factor 2.
[[nodiscard]] bool location_matches(const sim::EffectSpec& truth, const sim::EffectSpec& fitted);

/// Whether some effect of `chosen` (first or later) is of a kind in `truth` and sits where that truth
/// does (location_matches): issue 11's criterion on real recordings with an injected effect, where the
/// recording's own gap may be named beside it.
[[nodiscard]] bool named_and_located(const std::vector<sim::EffectSpec>& truth,
                                     const std::vector<sim::EffectSpec>& chosen);

[[nodiscard]] BenchResult run_bench(const BenchOptions& opt);
/// Diagnoses every case of `corpus` against its own nominal and scores it like run_bench. A case whose
/// nominal or recording cannot be read, or whose diagnosis throws, is reported (`error`) and scored
/// as wrong; the other cases still run.
[[nodiscard]] BenchResult run_corpus_bench(const Corpus& corpus, const CorpusBenchOptions& opt);
[[nodiscard]] std::string bench_json(const BenchResult& r);
/// JSON of several benches: {"format": "ptda-gap-bench-set", "version": 1, "corpora": [bench_json...]}.
[[nodiscard]] std::string bench_set_json(const std::vector<BenchResult>& r);
/// Markdown: summary row per bench, then per bench its confusion matrix and per-case table.
[[nodiscard]] std::string bench_markdown(const std::vector<BenchResult>& r);

}  // namespace ptda::gap
