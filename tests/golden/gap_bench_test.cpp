// The CI bench of `ptda gap`: cases 0, 2 and 11 of the 13-case cycle with bench seed 2024 on the
// spot-welding job, 4 cycles each: transfer_path alone, mesh_modulation alone (randomised parameters)
// and a recording without any effect (`--only 0,2,11`). The job preset and seed differ from the
// joint-rotation cases used while developing. Numbers measured with this build: `ptda gap-bench --cases 13
// --seed 2024 --cycles 4 --jobs config/scenarios/spot_welding_healthy.toml --only 0,2,11` (about 70 s wall
// on the shared 2-core machine with two other benches running); docs/gap.md has the larger runs and the
// failures.
#include <gtest/gtest.h>

#include "golden_support.hpp"

namespace ptda::golden {
namespace {

TEST(GapBench, SmallBenchOnAWithheldJob) {
  const fs::path dir = scratch_dir("gap_bench");
  const RunResult r =
      run_ptda({"gap-bench", "--cases", "13", "--seed", "2024", "--cycles", "4", "--only", "0,2,11", "--jobs",
                (source_dir() / "config/scenarios/spot_welding_healthy.toml").string(), "--json",
                (dir / "bench.json").string(), "--work", (dir / "work").string(), "--quiet"},
               dir, "bench");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const cli::JsonValue j = cli::parse_json(read_file(dir / "bench.json"), "bench.json");
  EXPECT_EQ(j.at("format").as_string(), "ptda-gap-bench");
  EXPECT_EQ(j.at("effect_cases").as_number(), 2.0);
  EXPECT_EQ(j.at("none_cases").as_number(), 1.0);
  // Measured (session 7 code: the issue-11 diagnosis with the noise floor's slope calibrated): both
  // effects named first and located (resonance 743 Hz for 831 Hz, within the 15 % criterion; sidebands
  // every 1.92 for 1.906 input-shaft orders, now without the spurious second other_axis); held-out
  // shrink 73.4 and 89.2 % (median 81.3 %; before the slope 64.7 and 92.1 %, median 78.4 %; session 3:
  // 73.3 and 82.4 %); the recording without effects has a held-out gap of 1.387 against 1.428 +- 0.27
  // expected from sampling (1.100 before the slope): nothing significant, nothing named. Session 37 (the
  // harmonics' phases read off the measurement, docs/gap.md step 1c): the path case's shrink 73.4 -> 79.1 %
  // (median 81.3 -> 84.2 %); the other cases unchanged.
  EXPECT_EQ(j.at("top1_accuracy").as_number(), 1.0);
  EXPECT_EQ(j.at("location_accuracy").as_number(), 1.0);
  EXPECT_EQ(j.at("named_located_rate").as_number(), 1.0);
  EXPECT_EQ(j.at("false_attribution_rate").as_number(), 0.0);
  EXPECT_NEAR(j.at("median_shrink_pct").as_number(), 84.17, 1.0);
  const auto& cases = j.at("cases").array;
  ASSERT_EQ(cases.size(), 3U);
  EXPECT_EQ(cases[0].at("truth").array.at(0).at("kind").as_string(), "transfer_path");
  EXPECT_EQ(cases[0].at("chosen").array.at(0).at("kind").as_string(), "transfer_path");
  EXPECT_NEAR(cases[0].at("shrink_pct").as_number(), 79.12, 1.0);
  EXPECT_EQ(cases[1].at("chosen").array.at(0).at("kind").as_string(), "mesh_modulation");
  EXPECT_NEAR(cases[1].at("shrink_pct").as_number(), 89.22, 1.0);
  EXPECT_TRUE(cases[2].at("truth").array.empty());
  EXPECT_TRUE(cases[2].at("chosen").array.empty());
  EXPECT_TRUE(cases[0].at("named_located").as_bool());
  EXPECT_FALSE(cases[2].at("named_located").as_bool());
  EXPECT_NEAR(cases[2].at("gap_heldout").as_number(), 1.387, 0.01);
  EXPECT_NEAR(cases[2].at("noise_gap").as_number(), 1.428, 0.01);
}

}  // namespace
}  // namespace ptda::golden
