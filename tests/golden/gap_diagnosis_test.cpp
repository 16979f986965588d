// End to end: `ptda simulate` a machine with withheld effects (config/scenarios/effects_transfer_path.toml:
// a 4.2 kHz mount resonance and 50 Hz mains pickup), then `ptda gap` against the plain job scenario.
// The diagnosis must name the resonance, at the right frequency, then the pickup, and write the
// documented JSON/HTML.
#include <gtest/gtest.h>

#include "golden_support.hpp"

namespace ptda::golden {
namespace {

TEST(GapDiagnosis, NamesTheMountResonanceAndWritesTheSchema) {
  const fs::path dir = scratch_dir("gap_diagnosis");
  const fs::path rec = dir / "rec";
  ASSERT_EQ(run_ptda({"simulate", "--scenario",
                      (source_dir() / "config/scenarios/effects_transfer_path.toml").string(), "--out",
                      rec.string()},
                     dir, "simulate")
                .exit_code,
            0);
  // Two candidates keep the test short; the full catalog gives the same first choice (docs/gap.md).
  const RunResult r =
      run_ptda({"gap", "--scenario", (source_dir() / "config/scenarios/joint_rotation_healthy.toml").string(),
                "--real", rec.string(), "--json", (dir / "gap.json").string(), "--html",
                (dir / "gap.html").string(), "--effects", "transfer_path,electrical_interference", "--quiet"},
               dir, "gap");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const cli::JsonValue j = cli::parse_json(read_file(dir / "gap.json"), "gap.json");
  EXPECT_EQ(j.at("format").as_string(), "ptda-gap");
  EXPECT_EQ(j.at("version").as_number(), 1.0);
  EXPECT_EQ(j.at("split").at("cycles").as_number(), 8.0);
  EXPECT_EQ(j.at("split").at("fit_cycles").as_number(), 4.0);
  EXPECT_TRUE(j.at("gap_significant").as_bool());
  for (const char* k : {"by_probe", "by_band", "by_segment", "by_stage", "top"})
    EXPECT_NO_THROW((void)j.at("gap").at(k)) << k;
  const auto& chosen = j.at("chosen").array;
  ASSERT_GE(chosen.size(), 1U);
  EXPECT_EQ(chosen[0].at("effect").at("kind").as_string(), "transfer_path");
  const double f = chosen[0].at("effect").at("params").at("frequency_hz").as_number();
  EXPECT_NEAR(f / 4200.0, 1.0, 0.15);
  // Measured with this build (session 7: the floor's level and slope calibrated, model driven by the
  // measured CAN speed): 4157 Hz, held-out 60.7 -> 14.8 (75.6 %); round 2 then names the 50 Hz pickup
  // (49.96 Hz), 14.8 -> 3.05, total 95.0 % (issue-11 code before the slope: 58.4 -> 14.1 -> 2.07, 96.5 %).
  // Session 3 measured 84.7 -> 14.2 (83.3 %): the rest is the same, the starting gap is smaller because
  // the raw kurtosis/crest where the mesh runs (which depend on the unknown harmonic phases) are no
  // longer compared.
  EXPECT_GT(chosen[0].at("shrink_pct").as_number(), 70.0);
  EXPECT_EQ(j.at("motion").at("source").as_string(), "measured");
  EXPECT_EQ(j.at("split").at("period_units").as_number(), 1.0);
  ASSERT_EQ(chosen.size(), 2U);
  EXPECT_EQ(chosen[1].at("effect").at("kind").as_string(), "electrical_interference");
  EXPECT_NEAR(chosen[1].at("effect").at("params").at("frequency_hz").as_number(), 50.0, 1.0);
  EXPECT_GT(j.at("total_shrink_pct").as_number(), 94.0);
  const std::string html = read_file(dir / "gap.html");
  EXPECT_NE(html.find("<svg"), std::string::npos);
  EXPECT_NE(html.find("transfer_path"), std::string::npos);
}

TEST(GapDiagnosis, UsageErrors) {
  const fs::path dir = scratch_dir("gap_usage");
  EXPECT_EQ(run_ptda({"gap", "--real", "x"}, dir, "missing").exit_code, 2);
  const RunResult r =
      run_ptda({"gap", "--scenario", (source_dir() / "config/scenarios/gfd_like.toml").string(), "--real",
                "x", "--effects", "warp_drive"},
               dir, "bad_effect");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("unknown effect 'warp_drive'"), std::string::npos) << r.err;
  const RunResult m =
      run_ptda({"gap", "--scenario", (source_dir() / "config/scenarios/gfd_like.toml").string(), "--real",
                "x", "--motion", "sideways"},
               dir, "bad_motion");
  EXPECT_EQ(m.exit_code, 2);
  EXPECT_NE(m.err.find("--motion: 'sideways' is not measured or scenario"), std::string::npos) << m.err;
}

}  // namespace
}  // namespace ptda::golden
