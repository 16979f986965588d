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
  // Measured with this build (issue-11 code: model driven by the imported CAN speed, phase-invariant
  // amplitude and transient statistics, calibration reported, local acceptance): 6 blocks of 0.2 s
  // (period 1 block; 3 fit / 3 held out); held-out gap 330.5 (328.4 against the second model
  // realisation) against 3.76 +- 1.51 expected from sampling; 55 % in the PTDA residual features, 17 %
  // floor, 15 % transients, 12 % lines (session 3: 385.9, 47 % residual; the difference is the raw
  // kurtosis/crest where the mesh runs, no longer compared); transfer_path at 14.7 kHz, Q 1.5, +20 dB
  // (a broad tilt of the floor), 330.5 -> 121.1 (63 %), then a second transfer_path at 21.7 kHz, Q 3,
  // +13.8 dB, 121.1 -> 107.2, accepted by the local rule (its own octave); total 67.6 %. Calibration:
  // noise level 13.0 dB below the nominal (+- 0.2), order 4 12.3 dB below (+- 0.8).
  EXPECT_EQ(j.at("split").at("cycles").as_number(), 6.0);
  EXPECT_EQ(j.at("motion").at("source").as_string(), "measured");
  EXPECT_TRUE(j.at("gap_significant").as_bool());
  EXPECT_NEAR(j.at("gap").at("total").as_number(), 330.5, 3.0);
  EXPECT_NEAR(j.at("noise_gap").as_number(), 3.76, 0.05);
  EXPECT_NEAR(j.at("gap").at("by_probe").at("residual").at("share").as_number(), 0.55, 0.02);
  const auto& chosen = j.at("chosen").array;
  ASSERT_EQ(chosen.size(), 2U);
  EXPECT_EQ(chosen[0].at("effect").at("kind").as_string(), "transfer_path");
  EXPECT_NEAR(chosen[0].at("effect").at("params").at("frequency_hz").as_number(), 14711.0, 200.0);
  EXPECT_EQ(chosen[1].at("effect").at("kind").as_string(), "transfer_path");
  EXPECT_NEAR(chosen[1].at("effect").at("params").at("frequency_hz").as_number(), 21650.0, 300.0);
  EXPECT_TRUE(chosen[1].at("accepted_locally").as_bool());
  EXPECT_NEAR(j.at("total_shrink_pct").as_number(), 67.6, 1.0);
  // Calibration is reported apart from the effect: the rig's floor is far below the nominal's white floor.
  EXPECT_TRUE(j.at("calibration").at("recalibrated").as_bool());
  bool noise_seen = false;
  for (const cli::JsonValue& p : j.at("calibration").at("params").array) {
    if (p.at("name").as_string() != "noise_rms") continue;
    noise_seen = true;
    EXPECT_NEAR(p.at("offset_db").as_number(), -13.0, 0.5);
    EXPECT_TRUE(p.at("significant").as_bool());
  }
  EXPECT_TRUE(noise_seen);
  EXPECT_NE(j.at("verdict").as_string().find("nominal re-calibrated"), std::string::npos)
      << j.at("verdict").as_string();
  EXPECT_NE(j.at("verdict").as_string().find("is not explained"), std::string::npos)
      << j.at("verdict").as_string();
}

}  // namespace
}  // namespace ptda::golden
