// gap-bench: cases made with the simulator (one withheld effect, a pair, or none, with randomised
// parameters, amplitudes, noise level and seed), diagnosed from the recording and the nominal scenario
// only, and scored (docs/gap.md "Bench"). Offline: any thread, allocates, writes temporary recordings.
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

struct BenchCaseResult {
  std::uint32_t index = 0;
  std::string job;
  std::uint64_t seed = 0;
  std::vector<sim::EffectSpec> truth;   ///< withheld effects (empty: none)
  std::vector<sim::EffectSpec> chosen;  ///< what the diagnosis named
  bool top1_correct = false;            ///< first named effect is a true one (none case: nothing named)
  bool location_ok = false;             ///< the named true effect sits where the truth does (see docs/gap.md)
  bool false_attribution = false;       ///< none case: something was named
  double shrink_pct = 0.0;              ///< held-out shrink with the chosen effects
  double gap_heldout = 0.0;             ///< calibrated nominal
  double noise_gap = 0.0;               ///< held-out gap expected from sampling
  double noise_gap_sd = 0.0;            ///< its standard deviation
  double runtime_s = 0.0;
  std::string verdict;
};

struct BenchResult {
  std::vector<BenchCaseResult> cases;
  double top1_accuracy = 0.0;           ///< over cases with effects
  double location_accuracy = 0.0;       ///< over cases with a correct top-1
  double false_attribution_rate = 0.0;  ///< over no-effect cases
  double median_shrink_pct = 0.0;       ///< over cases with effects
  std::uint32_t effect_cases = 0;
  std::uint32_t none_cases = 0;
  double runtime_s = 0.0;
  /// confusion[truth][named]: truth index kEffectKinds = none; named kEffectKinds = nothing named.
  std::vector<std::vector<std::uint32_t>> confusion;
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

[[nodiscard]] BenchResult run_bench(const BenchOptions& opt);
[[nodiscard]] std::string bench_json(const BenchResult& r);

}  // namespace ptda::gap
