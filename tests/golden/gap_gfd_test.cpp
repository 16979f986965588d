// `ptda gap` on measured data (docs/gap.md, "Real data"): the healthy 0 % load GFD file, accelerometer
// a1, imported at the assumed 64.5 kHz with the CAN carrying the assumed output-shaft speed (12 Hz), against
// config/scenarios/gfd_gap.toml (one 30-tooth mesh on the 30 Hz shaft, white noise). Pins what the tool
// concludes there: a large, significant gap, a broad resonance named first, a significant rest left
// unexplained. Without the data: GTEST_SKIP naming the path, or a failure when
// PTDA_REQUIRE_SHARED_DATA=1 (CI). About 17 s wall on the shared 2-core machine.
#include <gtest/gtest.h>

#include <cstdlib>
#include <string>

#include "golden_support.hpp"

namespace ptda::golden {
namespace {

fs::path gfd_dir() {
  return fs::path(PTDA_SHARED_DIR) / "data" / "gfd";
}

TEST(GapGfd, HealthyRigHasALargeGapPartlyABroadResonance) {
  if (!fs::is_directory(gfd_dir())) {
    const char* req = std::getenv("PTDA_REQUIRE_SHARED_DATA");
    if (req != nullptr && std::string(req) == "1")
      FAIL() << "GFD data directory " << gfd_dir() << " is missing";
    GTEST_SKIP() << "GFD data directory " << gfd_dir()
                 << " not found (set PTDA_REQUIRE_SHARED_DATA=1 to fail)";
  }
  const fs::path dir = scratch_dir("gap_gfd");
  const fs::path rec = dir / "h0_a1";
  ASSERT_EQ(run_ptda({"import", "--csv", (gfd_dir() / "h30hz0.csv.gz").string(), "--column", "a1", "--rate",
                      "64500", "--shaft-speed", "12Hz", "--out", rec.string()},
                     dir, "import")
                .exit_code,
            0);
  const RunResult r =
      run_ptda({"gap", "--scenario", (source_dir() / "config/scenarios/gfd_gap.toml").string(), "--real",
                rec.string(), "--json", (dir / "gap.json").string(), "--quiet"},
               dir, "gap");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const cli::JsonValue j = cli::parse_json(read_file(dir / "gap.json"), "gap.json");
  // Measured with this build (session 3 code): 6 blocks of 0.2 s (3 fit / 3 held out); held-out gap
  // 385.9 (382.8 against the second model realisation) against 3.80 +- 1.50 expected from sampling; 47 %
  // in the PTDA residual features, the rest in transients, the floor shape, kurtosis and off-order
  // lines; transfer_path named at 15.5 kHz with Q 1.5 (a broad tilt of the floor), 385.9 -> 173.7
  // (55.0 %); round 2's best (electrical_interference, 165.3) is not significant; the rest is still far
  // above the sampling level and the verdict says so.
  EXPECT_EQ(j.at("split").at("cycles").as_number(), 6.0);
  EXPECT_TRUE(j.at("gap_significant").as_bool());
  EXPECT_NEAR(j.at("gap").at("total").as_number(), 385.9, 3.0);
  EXPECT_NEAR(j.at("noise_gap").as_number(), 3.80, 0.05);
  EXPECT_NEAR(j.at("gap").at("by_probe").at("residual").at("share").as_number(), 0.47, 0.02);
  const auto& chosen = j.at("chosen").array;
  ASSERT_EQ(chosen.size(), 1U);
  EXPECT_EQ(chosen[0].at("effect").at("kind").as_string(), "transfer_path");
  EXPECT_NEAR(chosen[0].at("effect").at("params").at("frequency_hz").as_number(), 15547.0, 200.0);
  EXPECT_NEAR(j.at("total_shrink_pct").as_number(), 55.0, 1.0);
  EXPECT_NE(j.at("verdict").as_string().find("is not explained"), std::string::npos)
      << j.at("verdict").as_string();
}

}  // namespace
}  // namespace ptda::golden
