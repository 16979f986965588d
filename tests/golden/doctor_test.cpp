// Commissioning mistakes (issue 17): a simulated 12/36/40 cycloidal joint at +-1.5 rad/s, speed on CAN
// 0x184, and the mistakes a new user makes. For each, `ptda doctor` names the cause and the fix and
// exits 4, and `ptda train` / `ptda monitor` fail with the same words and a documented exit status;
// the correct commissioning gives a clean summary and exit 0.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <string>

#include "golden_support.hpp"

namespace ptda::golden {
namespace {

// A short job: out 1.5 rad and back at 1.5 rad/s (plateaus ~0.85 s), 6 cycles, ~12 s.
std::string scenario(double speed_rad_s, double back_speed_rad_s) {
  return R"(name = "commissioning"
seed = 17
[motion]
kind = "lspb"
via_points_rad = [0.0, 1.5, 0.0]
segment_speeds_rad_s = [)" +
         std::to_string(speed_rad_s) + ", " + std::to_string(back_speed_rad_s) + R"(]
accel_rad_s2 = 15.0
dwell_s = 0.3
cycles = 6
start_jitter_s = 0.02
lead_in_s = 0.2
[gearbox]
kind = "cycloidal"
z_in = 12
z_spur = 36
z_pin = 40
[vibration]
gmf_amplitudes = [0.43, 0.0, 0.0, 0.48, 1.40, 0.0, 1.10, 1.60]
reference_speed_rad_s = 1.5
noise_rms = 0.5
[can]
other_frames_per_s = 20
)";
}

// The pipeline configuration of this joint; `speed_block` replaces [can.speed_frame].
std::string config(const std::string& speed_block, std::uint32_t window_len = 12800,
                   double min_duration_s = 0.55) {
  return speed_block + R"(
[extraction]
window_len = )" +
         std::to_string(window_len) +
         R"(
min_duration_s = )" +
         std::to_string(min_duration_s) +
         R"(
guard_s = 0.02
max_windows_per_region = 1
[classes]
min_regions = 3
[gearbox]
kind = "cycloidal"
z_in = 12
z_spur = 36
z_pin = 40
)";
}

std::string speed_frame(const std::string& id, const std::string& scale) {
  return "[can.speed_frame]\nid = " + id + "\n[can.speed_frame.speed]\nscale = " + scale + "\n";
}

class Commissioning : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = scratch_dir("doctor_" + std::to_string(::getpid()));
    std::ofstream(dir_ / "job.toml") << scenario(1.5, 1.5);
    std::ofstream(dir_ / "mixed.toml") << scenario(1.5, 3.0);
    std::ofstream(dir_ / "other_job.toml") << scenario(0.8, 0.8);
    for (const char* s : {"job", "mixed", "other_job"}) {
      const RunResult r = run_ptda({"simulate", "--scenario", (dir_ / (std::string(s) + ".toml")).string(),
                                    "--out", (dir_ / s).string()},
                                   dir_, std::string("sim_") + s);
      ASSERT_EQ(r.exit_code, 0) << r.err;
    }
    std::ofstream(dir_ / "good.toml") << config(speed_frame("0x184", "1e-4"));
  }
  static void TearDownTestSuite() {
    if (std::getenv("PTDA_KEEP") == nullptr) fs::remove_all(dir_);
  }

  static std::string write(const std::string& name, const std::string& text) {
    std::ofstream(dir_ / name) << text;
    return (dir_ / name).string();
  }
  static std::string rec(const char* name) { return (dir_ / name).string(); }
  static RunResult ptda(const std::vector<std::string>& args, const std::string& tag) {
    return run_ptda(args, dir_, tag);
  }
  static fs::path dir_;
};
fs::path Commissioning::dir_;

TEST_F(Commissioning, CorrectCommissioningPrintsACleanSummary) {
  const RunResult d =
      ptda({"doctor", "--recording", rec("job"), "--config", (dir_ / "good.toml").string()}, "ok");
  EXPECT_EQ(d.exit_code, 0) << d.out << d.err;
  EXPECT_EQ(d.out.find("PROBLEM"), std::string::npos) << d.out;
  EXPECT_NE(d.out.find("decoded as speed with id 0x184"), std::string::npos) << d.out;
  EXPECT_NE(d.out.find("matches the CAN speed and [gearbox]"), std::string::npos) << d.out;
  EXPECT_NE(d.out.find("fits every plateau"), std::string::npos) << d.out;
  EXPECT_NE(d.out.find("doctor: no problem found"), std::string::npos) << d.out;
  // With the baseline trained on it: its classes match the speeds.
  const RunResult t = ptda({"train", "--recording", rec("job"), "--config", (dir_ / "good.toml").string(),
                            "--out", (dir_ / "job.bin").string()},
                           "train_ok");
  ASSERT_EQ(t.exit_code, 0) << t.out << t.err;
  EXPECT_EQ(t.out.find("warning: " + rec("job")), std::string::npos) << t.out;
  const RunResult b = ptda({"doctor", "--recording", rec("job"), "--config", (dir_ / "good.toml").string(),
                            "--baseline", (dir_ / "job.bin").string()},
                           "ok_baseline");
  EXPECT_EQ(b.exit_code, 0) << b.out;
  EXPECT_NE(b.out.find("every plateau speed of the recording matches a class"), std::string::npos) << b.out;
}

TEST_F(Commissioning, WrongCanIdNamesTheIdSeenAndTheKeyToSet) {
  const std::string cfg = write("wrong_id.toml", config(speed_frame("0x185", "1e-4")));
  const RunResult d = ptda({"doctor", "--recording", rec("job"), "--config", cfg}, "wrong_id");
  EXPECT_EQ(d.exit_code, 4) << d.out << d.err;
  EXPECT_NE(d.out.find("PROBLEM (can): "), std::string::npos) << d.out;
  EXPECT_NE(d.out.find("no frame with id 0x185 in the CAN log"), std::string::npos) << d.out;
  EXPECT_NE(d.out.find("The most likely speed frame is 0x184"), std::string::npos) << d.out;
  EXPECT_NE(d.out.find("set id = 0x184 in [can.speed_frame]"), std::string::npos) << d.out;
  const RunResult t =
      ptda({"train", "--recording", rec("job"), "--config", cfg, "--out", (dir_ / "x.bin").string()},
           "wrong_id_train");
  EXPECT_EQ(t.exit_code, 1) << t.out;
  EXPECT_NE(t.err.find("no frame with id 0x185"), std::string::npos) << t.err;
  EXPECT_NE(t.err.find("Set id (and extended) in [can.speed_frame] of " + cfg), std::string::npos) << t.err;
  EXPECT_FALSE(fs::exists(dir_ / "x.bin"));
}

TEST_F(Commissioning, SpeedScaleTimesTenIsFoundFromTheVibrationAndTrainingRefuses) {
  // The scale 10 times too small: the CAN says 0.15 rad/s, the GMF comb says 1.5.
  const std::string cfg = write("scale.toml", config(speed_frame("0x184", "1e-5")));
  const RunResult d = ptda({"doctor", "--recording", rec("job"), "--config", cfg}, "scale");
  EXPECT_EQ(d.exit_code, 4) << d.out << d.err;
  EXPECT_NE(d.out.find("PROBLEM (scale): "), std::string::npos) << d.out;
  EXPECT_NE(d.out.find("the speed scale is off by a factor 10."), std::string::npos) << d.out;
  EXPECT_NE(d.out.find("set [can.speed_frame.speed] scale = 0.0001 (now 1e-05)"), std::string::npos) << d.out;
  const RunResult t =
      ptda({"train", "--recording", rec("job"), "--config", cfg, "--out", (dir_ / "scale.bin").string()},
           "scale_train");
  EXPECT_EQ(t.exit_code, 4) << t.out << t.err;
  EXPECT_NE(t.out.find("not training on a wrong speed scale"), std::string::npos) << t.out;
  EXPECT_NE(t.out.find("scale = 0.0001"), std::string::npos) << t.out;
  EXPECT_FALSE(fs::exists(dir_ / "scale.bin"));
}

TEST_F(Commissioning, WindowLongerThanThePlateausGivesTheirLengthsAndTheWindowThatFits) {
  // 1 s windows, plateaus of ~0.85 s.
  const std::string cfg = write("long.toml", config(speed_frame("0x184", "1e-4"), 25600, 1.05));
  const RunResult d = ptda({"doctor", "--recording", rec("job"), "--config", cfg}, "long");
  EXPECT_EQ(d.exit_code, 4) << d.out << d.err;
  // Parsed by hand, not with std::regex: GCC 12's -Wmaybe-uninitialized fires inside <regex> in the
  // ASan build (-Werror), a known false positive.
  const std::size_t at = d.out.find("+1.5 rad/s: 6 plateaus of ");
  ASSERT_NE(at, std::string::npos) << d.out;
  double shortest_s = 0.0, longest_s = 0.0;
  ASSERT_EQ(
      std::sscanf(d.out.c_str() + at, "+1.5 rad/s: 6 plateaus of %lf .. %lf s", &shortest_s, &longest_s), 2)
      << d.out;
  EXPECT_GE(shortest_s, 0.8);
  EXPECT_LT(longest_s, 0.9);
  EXPECT_NE(d.out.find("window_len = 25600 (1.000 s), min_duration_s = 1.05 is longer than every plateau"),
            std::string::npos)
      << d.out;
  const std::size_t fix_at = d.out.find("Fix: window_len = ");
  ASSERT_NE(fix_at, std::string::npos) << d.out;
  unsigned fit = 0;
  double fit_s = 0.0, fit_min_duration_s = 0.0;
  ASSERT_EQ(std::sscanf(d.out.c_str() + fix_at, "Fix: window_len = %u (%lf s) with min_duration_s = %lf",
                        &fit, &fit_s, &fit_min_duration_s),
            3)
      << d.out;
  EXPECT_LT(fit_s, 1.0);
  EXPECT_NE(d.out.find(" fits every plateau", fix_at), std::string::npos) << d.out;
  const RunResult t =
      ptda({"train", "--recording", rec("job"), "--config", cfg, "--out", (dir_ / "long.bin").string()},
           "long_train");
  EXPECT_EQ(t.exit_code, 3) << t.out << t.err;
  EXPECT_NE(t.out.find("is longer than every plateau"), std::string::npos) << t.out;
  EXPECT_NE(t.out.find("error: no constant-speed windows"), std::string::npos) << t.out;
  // The suggested window does fit: doctor is clean with it.
  const std::string fixed_cfg =
      write("long_fixed.toml", config(speed_frame("0x184", "1e-4"), fit, fit_min_duration_s));
  const RunResult again = ptda({"doctor", "--recording", rec("job"), "--config", fixed_cfg}, "long_fixed");
  EXPECT_EQ(again.exit_code, 0) << again.out;
}

TEST_F(Commissioning, WindowThatFitsOnlySomePlateausSaysHowManyItDropped) {
  // Out at 1.5 rad/s (~0.85 s plateaus), back at 3 rad/s (~0.35 s): a 0.5 s window fits only the first.
  const RunResult d =
      ptda({"doctor", "--recording", rec("mixed"), "--config", (dir_ / "good.toml").string()}, "mixed");
  EXPECT_EQ(d.exit_code, 4) << d.out << d.err;
  EXPECT_NE(d.out.find("fits only some plateaus: 6 of 12 give no window"), std::string::npos) << d.out;
  EXPECT_NE(d.out.find("+1.5 rad/s: 6 plateaus"), std::string::npos) << d.out;
  EXPECT_NE(d.out.find("6 windows from 6"), std::string::npos) << d.out;
  EXPECT_NE(d.out.find("0 windows from 0"), std::string::npos) << d.out;
  // Training still works on what fits, and says what it dropped.
  const RunResult t = ptda({"train", "--recording", rec("mixed"), "--config", (dir_ / "good.toml").string(),
                            "--out", (dir_ / "mixed.bin").string()},
                           "mixed_train");
  EXPECT_EQ(t.exit_code, 0) << t.out << t.err;
  EXPECT_NE(t.out.find("warning: " + rec("mixed") + ": [extraction] window_len = 12800"), std::string::npos)
      << t.out;
  EXPECT_NE(t.out.find("6 of 12 give no window"), std::string::npos) << t.out;
}

TEST_F(Commissioning, BaselineOfAnotherJobIsNotASilentExitZero) {
  const std::string good = (dir_ / "good.toml").string();
  const RunResult t = ptda(
      {"train", "--recording", rec("other_job"), "--config", good, "--out", (dir_ / "other.bin").string()},
      "other_train");
  ASSERT_EQ(t.exit_code, 0) << t.out << t.err;
  const RunResult m = ptda({"monitor", "--recording", rec("job"), "--config", good, "--baseline",
                            (dir_ / "other.bin").string(), "--quiet"},
                           "other_monitor");
  EXPECT_EQ(m.exit_code, 3) << m.out << m.err;
  EXPECT_NE(m.out.find("diagnosis: none of the recording's plateau speeds (-1.5, +1.5 rad/s)"),
            std::string::npos)
      << m.out;
  EXPECT_NE(m.out.find("matches a class of " + (dir_ / "other.bin").string() + " (+0.8"), std::string::npos)
      << m.out;
  EXPECT_NE(m.out.find("train a baseline on this job"), std::string::npos) << m.out;
  const RunResult d = ptda(
      {"doctor", "--recording", rec("job"), "--config", good, "--baseline", (dir_ / "other.bin").string()},
      "other");
  EXPECT_EQ(d.exit_code, 4) << d.out;
  EXPECT_NE(d.out.find("PROBLEM (baseline): none of the recording's plateau speeds"), std::string::npos)
      << d.out;
}

TEST_F(Commissioning, ScenarioCanBlockCopiedIntoThePipelineConfigWorks) {
  // The [can.speed_frame] block of a scenario written before issue 17 (little_endian = true).
  const std::string block =
      "[can.speed_frame]\nid = 0x184\nextended = false\ndlc = 8\nhas_angle = true\n"
      "[can.speed_frame.speed]\nstart_byte = 0\nlength = 4\nlittle_endian = true\nsigned = true\n"
      "scale = 1e-4\noffset = 0.0\n"
      "[can.speed_frame.angle]\nstart_byte = 4\nlength = 4\nlittle_endian = true\nsigned = true\n"
      "scale = 1e-5\noffset = 0.0\n";
  const std::string cfg = write("copied.toml", config(block));
  const RunResult t =
      ptda({"train", "--recording", rec("job"), "--config", cfg, "--out", (dir_ / "copied.bin").string()},
           "copied");
  EXPECT_EQ(t.exit_code, 0) << t.out << t.err;
  EXPECT_NE(t.err.find("warning: " + cfg + ":9:1: can.speed_frame.speed.little_endian = true is deprecated"),
            std::string::npos)
      << t.err;
  EXPECT_NE(t.err.find("write byte_order = \"little\" instead"), std::string::npos) << t.err;
  const RunResult d = ptda({"doctor", "--recording", rec("job"), "--config", cfg}, "copied_doctor");
  EXPECT_EQ(d.exit_code, 0) << d.out;
  EXPECT_NE(d.out.find("note (config): " + cfg + ":9:1"), std::string::npos) << d.out;
}

}  // namespace
}  // namespace ptda::golden
