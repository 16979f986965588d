// The CI bench of `ptda gap`: 3 cases (cases 0-2 of the cycle: transfer_path, speed_ripple,
// mesh_modulation alone, randomised parameters) on the spot-welding job, 4 cycles each. The job preset
// and seed differ from the joint-rotation cases used while developing. Numbers measured with this build
// (about 50 s of CPU); docs/gap.md has the larger runs and the failures.
#include <gtest/gtest.h>

#include "golden_support.hpp"

namespace ptda::golden {
namespace {

TEST(GapBench, SmallBenchOnAWithheldJob) {
  const fs::path dir = scratch_dir("gap_bench");
  const RunResult r =
      run_ptda({"gap-bench", "--cases", "3", "--seed", "2024", "--cycles", "4", "--jobs",
                (source_dir() / "config/scenarios/spot_welding_healthy.toml").string(), "--json",
                (dir / "bench.json").string(), "--work", (dir / "work").string(), "--quiet"},
               dir, "bench");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const cli::JsonValue j = cli::parse_json(read_file(dir / "bench.json"), "bench.json");
  EXPECT_EQ(j.at("format").as_string(), "ptda-gap-bench");
  EXPECT_EQ(j.at("effect_cases").as_number(), 3.0);
  EXPECT_EQ(j.at("none_cases").as_number(), 0.0);
  // Measured: all three named first and located (resonance 845 Hz for 831 Hz; jitter 0.8 rad for 0.48;
  // sidebands every 1.92 for 1.906 input-shaft orders); held-out shrink 70.7, 98.9, 84.3 % (with the
  // preset's cycle-to-cycle variation, 1.5 % amplitudes / 5 % noise; before it: 67.3, 98.8, 84.8 %).
  EXPECT_EQ(j.at("top1_accuracy").as_number(), 1.0);
  EXPECT_EQ(j.at("location_accuracy").as_number(), 1.0);
  EXPECT_NEAR(j.at("median_shrink_pct").as_number(), 84.29, 1.0);
  const auto& cases = j.at("cases").array;
  ASSERT_EQ(cases.size(), 3U);
  EXPECT_EQ(cases[0].at("truth").array.at(0).at("kind").as_string(), "transfer_path");
  EXPECT_EQ(cases[0].at("chosen").array.at(0).at("kind").as_string(), "transfer_path");
  EXPECT_NEAR(cases[0].at("shrink_pct").as_number(), 70.67, 1.0);
  EXPECT_EQ(cases[2].at("chosen").array.at(0).at("kind").as_string(), "mesh_modulation");
}

}  // namespace
}  // namespace ptda::golden
