// `ptda gap` on measured data (docs/gap.md, "Real data"): the healthy 0 % load GFD file, accelerometer
// a1, imported at the assumed 64.5 kHz with the CAN carrying the assumed output-shaft speed (12 Hz), against
// config/scenarios/gfd_gap.toml (one 30-tooth mesh on the 30 Hz shaft, shaft-order lines, a white floor).
// Pins what the tool concludes there: the rig's coloured floor is calibration (level and slope), no library
// effect is named, and the large rest (transients, floor, residual) is reported as unexplained with where it
// lies. Without the data: GTEST_SKIP naming the path, or a failure when PTDA_REQUIRE_SHARED_DATA=1 (CI).
// About 17 s wall on the shared 2-core machine.
#include <gtest/gtest.h>

#include <cstdlib>
#include <string>

#include "golden_support.hpp"

namespace ptda::golden {
namespace {

fs::path gfd_dir() {
  return fs::path(PTDA_SHARED_DIR) / "data" / "gfd";
}

TEST(GapGfd, HealthyRigFloorIsCalibrationAndTheRestIsUnexplained) {
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
  // Measured with this build (session 9: the speed frames' scale read off the lines, the rig's lines up
  // to 19.2 kHz in the nominal; session 7: the floor's level and slope and the nominal's shaft-order
  // lines are calibration): 6 blocks of 0.2 s (3 fit / 3 held out); the lines sit -428 ppm (+- 0.3, 17
  // lines) against the imported 12 Hz; held-out gap of the calibrated nominal 72.7 against 3.43 +- 1.5
  // expected from sampling; 44 % `transients` (the rig's own impulsiveness), 23 % floor (its top band
  // falls below the sloped model), 21 % residual, 9 % lines. No candidate is accepted (the best, a
  // 0.15 rad mesh phase wander, 72.7 -> 65.3, is not significant). Calibration: noise level -18.7 dB
  // (+- 0.3), slope +14.2 dB/decade (+- 0.3), order 4 -20.2 dB (+- 0.8); orders 1-3 and the shaft-order
  // lines read off this file within their uncertainty except 155, 160, 320 (-4.9, -1.5, +1.3 dB).
  // Session 7 (no scale, lines up to order 160): 78.0, 13 % lines. The issue-11 code without the slope
  // named a transfer_path at 14.7 kHz, Q 1.5 (the floor's tilt as a "resonance"), then a second at
  // 21.7 kHz: 330.5 -> 107.2; the same "effect" was named on every GFD recording, injected or not
  // (docs/gap.md).
  EXPECT_EQ(j.at("split").at("cycles").as_number(), 6.0);
  EXPECT_EQ(j.at("motion").at("source").as_string(), "measured");
  EXPECT_TRUE(j.at("gap_significant").as_bool());
  EXPECT_NEAR(j.at("gap").at("total").as_number(), 72.7, 2.0);
  EXPECT_NEAR(j.at("noise_gap").as_number(), 3.43, 0.05);
  EXPECT_NEAR(j.at("gap").at("by_probe").at("lines").at("share").as_number(), 0.092, 0.02);
  EXPECT_NEAR(j.at("gap").at("by_probe").at("transients").at("share").as_number(), 0.435, 0.02);
  EXPECT_TRUE(j.at("chosen").array.empty());
  EXPECT_EQ(j.at("verdict").as_string().rfind("unexplained:", 0), 0U) << j.at("verdict").as_string();
  EXPECT_NE(j.at("verdict").as_string().find("'transients' probe"), std::string::npos)
      << j.at("verdict").as_string();
  // Calibration is reported apart: the rig's floor is below the nominal's white floor and rises with f.
  EXPECT_TRUE(j.at("calibration").at("recalibrated").as_bool());
  EXPECT_NEAR(j.at("calibration").at("noise_tilt_db_per_decade").as_number(), 14.2, 0.5);
  // The slip at 0 % load, applied to the frames (within the nominal's 1 %).
  EXPECT_NEAR(j.at("calibration").at("speed_scale").at("applied_ppm").as_number(), -428.0, 30.0);
  EXPECT_GE(j.at("calibration").at("speed_scale").at("lines").as_number(), 10.0);
  int seen = 0;
  for (const cli::JsonValue& p : j.at("calibration").at("params").array) {
    const std::string name = p.at("name").as_string();
    if (name == "noise_rms") {
      ++seen;
      EXPECT_NEAR(p.at("offset_db").as_number(), -18.7, 0.5);
      EXPECT_TRUE(p.at("significant").as_bool());
    } else if (name == "noise_tilt_db_per_decade") {
      ++seen;
      EXPECT_NEAR(p.at("offset_db").as_number(), 14.2, 0.5);
      EXPECT_TRUE(p.at("significant").as_bool());
    } else if (name == "gmf_order_1" || name == "shaft_order_15") {
      ++seen;
      EXPECT_FALSE(p.at("significant").as_bool());
    }
  }
  EXPECT_EQ(seen, 4);
  EXPECT_NE(j.at("verdict").as_string().find("nominal re-calibrated"), std::string::npos)
      << j.at("verdict").as_string();
}

}  // namespace
}  // namespace ptda::golden
