// End-to-end checks of the `ptda` binary on an imported constant-speed recording: the import -> train ->
// monitor path with --windows, and every error path giving exit code 1 (data) or 2 (usage) with a
// message naming the file at fault: missing recording, missing/corrupt/truncated baseline, malformed
// candump line, malformed CSV cell, baseline/config and baseline/recording mismatches.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <fstream>
#include <string>
#include <vector>

#include "golden_support.hpp"

namespace ptda::golden {
namespace {

// Pipeline configuration for the imported recording: N = 1000 (2^3 5^3) samples = 0.1 s at 10 kHz,
// one constant-speed region (the whole file), so one class from one region.
constexpr const char* kConfig = R"(
[acquisition]
fs_hz = 0
[extraction]
window_len = 1000
min_duration_s = 0.1
max_speed_rad_s = 1000.0
[classes]
min_regions = 1
[thresholds]
method = "gaussian"
false_alarm_rate = 1e-3
[decision]
k = 3
n = 5
)";

class CliEnd2End : public ::testing::Test {
 protected:
  // ctest runs every TEST of this file as its own process, possibly in parallel: each process gets its
  // own directory (by pid) and removes it at the end.
  static void SetUpTestSuite() {
    dir_ = scratch_dir("cli_errors_" + std::to_string(::getpid()));
    // 6.4 s at 10 kHz: a 100 Hz and a 230 Hz tone plus deterministic pseudo-random noise (LCG).
    std::ofstream csv(dir_ / "signal.csv");
    csv << "time,accel\n";
    std::uint32_t state = 12345;
    for (int i = 0; i < 64000; ++i) {
      state = state * 1664525U + 1013904223U;
      const double noise = (static_cast<double>(state >> 8) / 16777216.0 - 0.5) * 0.4;
      const double t = i / 10000.0;
      const double v =
          std::sin(2.0 * M_PI * 100.0 * t) + 0.5 * std::sin(2.0 * M_PI * 230.0 * t + 1.0) + noise;
      csv << t << "," << v << "\n";
    }
    csv.close();
    std::ofstream(dir_ / "config.toml") << kConfig;
    const RunResult imp =
        run_ptda({"import", "--csv", (dir_ / "signal.csv").string(), "--column", "accel", "--rate", "10000",
                  "--shaft-speed", "10Hz", "--out", (dir_ / "rec").string(), "--start-time", "1700000000"},
                 dir_, "import");
    ASSERT_EQ(imp.exit_code, 0) << imp.err;
    const RunResult tr = run_ptda({"train", "--recording", (dir_ / "rec").string(), "--config", config(),
                                   "--out", baseline(), "--windows", "0:0.5"},
                                  dir_, "train");
    ASSERT_EQ(tr.exit_code, 0) << tr.err;
    train_out_ = tr.out;
  }

  static void TearDownTestSuite() {
    if (!::testing::Test::HasFailure()) fs::remove_all(dir_);
  }

  static std::string config() { return (dir_ / "config.toml").string(); }
  static std::string baseline() { return (dir_ / "baseline.bin").string(); }
  static std::string rec() { return (dir_ / "rec").string(); }

  static inline fs::path dir_;
  static inline std::string train_out_;
};

bool has(const std::string& text, const std::string& needle) {
  return text.find(needle) != std::string::npos;
}

// ptda doctor in the order domain on the imported recording: the import writes the joint angle modulo
// 2 pi (a whole-turn step every 0.1 s at 10 Hz), as many controllers do. The doctor unwraps it, says so
// in a note, and finds the angle consistent with the speed (no PROBLEM). A parallel stage with z_in = 10,
// z_spur = 23 puts the GMF at 230 Hz, the file's second tone.
TEST_F(CliEnd2End, OrderDoctorUnwrapsAModuloTwoPiAngle) {
  const std::string cfg = (dir_ / "order.toml").string();
  std::ofstream(cfg)
      << "[acquisition]\nfs_hz = 0\n[extraction]\ndomain = \"order\"\nsamples_per_rev = 256\n"
         "revolutions = 8\nmax_speed_rad_s = 1000.0\n[gearbox]\nkind = \"parallel\"\nz_in = 10\n"
         "z_spur = 23\n";
  const RunResult r = run_ptda({"doctor", "--recording", rec(), "--config", cfg}, dir_, "doctor_order_wrap");
  // (The file's two tones are no GMF comb, so the speed-scale check reports a problem of its own: exit 4.
  // It is not this test's subject.)
  EXPECT_EQ(r.exit_code, 4) << r.out << r.err;
  EXPECT_TRUE(
      has(r.out, "ok (angle): the CAN angle follows the integrated CAN speed: the CAN angle moves 1.0"))
      << r.out;
  // 1601 frames over 6.4 s at 10 rev/s: a whole-turn step every 0.1 s, 64 of them.
  EXPECT_TRUE(has(r.out, "note (angle): the angle wraps modulo 2 pi (64 whole-turn steps between frames)"))
      << r.out;
  EXPECT_FALSE(has(r.out, "PROBLEM (angle)")) << r.out;
  EXPECT_TRUE(has(r.out, "ok (windows): [extraction] revolutions = 8 x samples_per_rev = 256: 17 windows"))
      << r.out;
}

TEST_F(CliEnd2End, ImportTrainMonitorOnImportedData) {
  const std::string import_out = read_file(dir_ / "import.out");
  // 64000 rows at 10 kHz = 6.4 s; 6.4 s / 4 ms = 1600 periods + the frame at t = 0.
  EXPECT_NE(import_out.find("samples      64000 at 10000 Hz = 6.400 s"), std::string::npos) << import_out;
  EXPECT_NE(import_out.find("in 1601 CAN frames (id 0x184 every 4.0 ms)"), std::string::npos) << import_out;
  // One region from sample 0 to the last frame at 6.4 s, so the 0.1 s windows tile the whole file:
  // 64 windows, the first half (32) kept for training.
  EXPECT_NE(train_out_.find("1 constant-speed regions, 64 windows"), std::string::npos) << train_out_;
  EXPECT_NE(train_out_.find("windows 0:0.5: kept 32 of 64 windows (1 regions)"), std::string::npos)
      << train_out_;
  EXPECT_NE(train_out_.find("class 0: direction +, speed 62.8319"), std::string::npos)
      << train_out_;  // 10 Hz

  const fs::path jsonl = dir_ / "second_half.jsonl";
  const RunResult m = run_ptda({"monitor", "--recording", rec(), "--config", config(), "--baseline",
                                baseline(), "--windows", "0.5:1", "--jsonl", jsonl.string()},
                               dir_, "monitor_second_half");
  ASSERT_EQ(m.exit_code, 0) << m.err;
  const auto rows = read_jsonl(jsonl);
  ASSERT_EQ(rows.size(), 32U);  // 64 - floor(0.5 * 64)
  EXPECT_EQ(rows.front().at("n").as_number(), 32.0);
  int alarms = 0;
  for (const auto& r : rows) {
    EXPECT_EQ(r.at("status").as_string(), "scored");
    EXPECT_EQ(r.at("segment").as_number(), 0.0);
    EXPECT_NEAR(r.at("speed_rad_s").as_number(), 62.83185307179586, 1e-4);
    // UNIX seconds near 1.7e9 are doubles spaced 2^-22 s = 2.4e-7 s apart: the difference of two of
    // them is 0.1 s within that spacing.
    EXPECT_NEAR(r.at("t_end").as_number() - r.at("t_start").as_number(), 0.1, 2.4e-7);
    alarms += r.at("alarm").as_bool() ? 1 : 0;
  }
  EXPECT_EQ(alarms, 0) << "healthy second half of the training recording";
  EXPECT_NE(m.out.find("alarm      never raised"), std::string::npos) << m.out;
}

TEST_F(CliEnd2End, MissingRecordingIsExitOneNamingIt) {
  const std::string missing = (dir_ / "no_such_recording").string();
  const RunResult r = run_ptda(
      {"monitor", "--recording", missing, "--config", config(), "--baseline", baseline()}, dir_, "missing");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err, "ptda monitor: " + missing + ": recording directory does not exist\n");
  EXPECT_TRUE(r.out.empty()) << r.out;
}

TEST_F(CliEnd2End, MissingCorruptAndTruncatedBaselineAreExitOneNamingTheFile) {
  const std::string missing = (dir_ / "none.bin").string();
  RunResult r = run_ptda({"monitor", "--recording", rec(), "--config", config(), "--baseline", missing}, dir_,
                         "baseline_missing");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err.rfind("ptda monitor: ", 0), 0U) << r.err;
  EXPECT_NE(r.err.find(missing), std::string::npos) << r.err;

  std::string bytes = read_file(baseline());
  ASSERT_GT(bytes.size(), 200U);
  std::string corrupt = bytes;
  corrupt[bytes.size() / 2] = static_cast<char>(corrupt[bytes.size() / 2] ^ 0x5A);
  const fs::path corrupt_path = dir_ / "corrupt.bin";
  std::ofstream(corrupt_path, std::ios::binary) << corrupt;
  r = run_ptda({"monitor", "--recording", rec(), "--config", config(), "--baseline", corrupt_path.string()},
               dir_, "baseline_corrupt");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err.rfind("ptda monitor: ", 0), 0U) << r.err;
  EXPECT_NE(r.err.find(corrupt_path.string()), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("CRC"), std::string::npos) << r.err;

  const fs::path short_path = dir_ / "truncated.bin";
  std::ofstream(short_path, std::ios::binary) << bytes.substr(0, bytes.size() - 7);
  r = run_ptda({"monitor", "--recording", rec(), "--config", config(), "--baseline", short_path.string()},
               dir_, "baseline_truncated");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find(short_path.string()), std::string::npos) << r.err;
}

TEST_F(CliEnd2End, MalformedCandumpLineIsExitOneWithFileAndLine) {
  const fs::path bad = dir_ / "rec_bad_can";
  fs::remove_all(bad);
  fs::copy(dir_ / "rec", bad);
  // Replace line 801 (the middle of the 1601 frames) by a malformed one.
  std::ifstream in(bad / "can.log");
  std::string text, line;
  int n = 0;
  while (std::getline(in, line)) {
    ++n;
    text += (n == 801 ? std::string("(1700000003.200000) can0 184#ZZ00000000000000") : line) + "\n";
  }
  in.close();
  ASSERT_EQ(n, 1601);
  std::ofstream(bad / "can.log", std::ios::trunc) << text;
  for (const std::string cmd : {"train", "monitor"}) {
    std::vector<std::string> args = {cmd, "--recording", bad.string(), "--config", config()};
    if (cmd == "train") {
      args.insert(args.end(), {"--out", (dir_ / "never.bin").string()});
    } else {
      args.insert(args.end(), {"--baseline", baseline()});
    }
    const RunResult r = run_ptda(args, dir_, "bad_can_" + cmd);
    EXPECT_EQ(r.exit_code, 1) << cmd;
    EXPECT_EQ(r.err.rfind("ptda " + cmd + ": " + (bad / "can.log").string() + ":801", 0), 0U) << r.err;
  }
  EXPECT_FALSE(fs::exists(dir_ / "never.bin")) << "no baseline is written from a broken recording";
}

// Runs train (to dir_/never.bin) and monitor on a recording with config cfg.
std::vector<RunResult> train_and_monitor(const fs::path& dir, const fs::path& recording,
                                         const std::string& cfg, const std::string& baseline,
                                         const std::string& tag) {
  std::vector<RunResult> out;
  out.push_back(run_ptda(
      {"train", "--recording", recording.string(), "--config", cfg, "--out", (dir / "never.bin").string()},
      dir, tag + "_train"));
  out.push_back(
      run_ptda({"monitor", "--recording", recording.string(), "--config", cfg, "--baseline", baseline}, dir,
               tag + "_monitor"));
  return out;
}

// Issue 14 item 7: a file that is not a candump log used to give 0 windows (train: "no constant-speed
// windows", monitor: exit 3 or 0). Now exit 1 naming the file and its first line.
TEST_F(CliEnd2End, NotACandumpLogIsExitOneWithFileAndLine) {
  const fs::path bad = dir_ / "rec_not_candump";
  fs::remove_all(bad);
  fs::copy(dir_ / "rec", bad);
  std::ofstream(bad / "can.log", std::ios::trunc) << "\ntime,speed\n0.0,62.8\n0.004,62.8\n";
  const std::vector<RunResult> r = train_and_monitor(dir_, bad, config(), baseline(), "not_candump");
  for (std::size_t i = 0; i < 2; ++i) {
    const std::string cmd = i == 0 ? "train" : "monitor";
    EXPECT_EQ(r[i].exit_code, 1) << cmd << r[i].out;
    EXPECT_EQ(r[i].err,
              "ptda " + cmd + ": " + (bad / "can.log").string() +
                  ":2: not a candump log: none of its 3 non-blank lines is a frame \"(seconds.fraction) "
                  "iface ID#DATA\" (lines not starting with '(' are comments); point can_file in " +
                  (bad / "recording.toml").string() + " at the `candump -l` log\n");
  }
  EXPECT_EQ(r[1].out.find("alarm      never raised"), std::string::npos) << r[1].out;
  std::ofstream(bad / "can.log", std::ios::trunc) << "\n\n";
  const RunResult empty =
      run_ptda({"monitor", "--recording", bad.string(), "--config", config(), "--baseline", baseline()}, dir_,
               "empty_can");
  EXPECT_EQ(empty.exit_code, 1);
  EXPECT_EQ(empty.err,
            "ptda monitor: " + (bad / "can.log").string() +
                ": the CAN log has no frames (empty or blank): no joint speed, so no window can be cut\n");
  EXPECT_FALSE(fs::exists(dir_ / "never.bin"));
}

// Issue 14 item 9 / issue 17: a wrong speed id named with the ids that are in the log and the fix.
TEST_F(CliEnd2End, WrongSpeedIdNamesTheIdsSeenAndTheKeyToSet) {
  const fs::path cfg = dir_ / "config_id185.toml";
  std::ofstream(cfg) << kConfig << "[can.speed_frame]\nid = 0x185\n";
  const std::vector<RunResult> r =
      train_and_monitor(dir_, dir_ / "rec", cfg.string(), baseline(), "wrong_id");
  for (std::size_t i = 0; i < 2; ++i) {
    const std::string cmd = i == 0 ? "train" : "monitor";
    EXPECT_EQ(r[i].exit_code, 1) << cmd << r[i].out;
    EXPECT_EQ(r[i].err,
              "ptda " + cmd + ": " + (dir_ / "rec" / "can.log").string() +
                  ": no frame with id 0x185 in the CAN log (1601 frames); ids seen: 0x184 (1601 frames). "
                  "Set id (and extended) in [can.speed_frame] of " +
                  cfg.string() + " to the joint's speed frame\n");
  }
  EXPECT_EQ(r[1].out.find("alarm      never raised"), std::string::npos) << r[1].out;
  EXPECT_FALSE(fs::exists(dir_ / "never.bin"));
}

// Issue 14 item 7: vibration and CAN timelines that do not overlap (start_time 1000 s too late).
TEST_F(CliEnd2End, NonOverlappingTimelinesAreExitOneWithBothRanges) {
  const fs::path late = dir_ / "rec_late";
  fs::remove_all(late);
  fs::copy(dir_ / "rec", late);
  std::string toml = read_file(late / "recording.toml");
  const std::size_t at = toml.find("start_time = ");
  ASSERT_NE(at, std::string::npos) << toml;
  toml.replace(at, toml.find('\n', at) - at, "start_time = 1700001000.0");
  std::ofstream(late / "recording.toml", std::ios::trunc) << toml;
  const std::vector<RunResult> r = train_and_monitor(dir_, late, config(), baseline(), "late");
  for (std::size_t i = 0; i < 2; ++i) {
    const std::string cmd = i == 0 ? "train" : "monitor";
    EXPECT_EQ(r[i].exit_code, 1) << cmd << r[i].out;
    EXPECT_EQ(r[i].err, "ptda " + cmd + ": " + (late / "can.log").string() +
                            ": the CAN speed frames (-1000.000 to -993.600 s) do not overlap the vibration "
                            "recording " +
                            (late / "vibration.wav").string() +
                            " (0.000 to 6.400 s); times in seconds from start_time 1700001000 of " +
                            (late / "recording.toml").string() + ": check start_time and the log's clock\n");
  }
  EXPECT_FALSE(fs::exists(dir_ / "never.bin"));
}

TEST_F(CliEnd2End, MismatchesAreExitOneNamingBothSides) {
  // Window length: config says 1200, baseline has 1000.
  std::string other = kConfig;
  other.replace(other.find("window_len = 1000"), 17, "window_len = 1200");
  const fs::path other_cfg = dir_ / "config_1200.toml";
  std::ofstream(other_cfg) << other;
  RunResult r =
      run_ptda({"monitor", "--recording", rec(), "--config", other_cfg.string(), "--baseline", baseline()},
               dir_, "mismatch_window");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err, "ptda monitor: " + baseline() + ": baseline window length is 1000 samples but " +
                       other_cfg.string() + " sets [extraction] window_len = 1200\n");

  // Sample rate: the same CSV imported at 20 kHz.
  r = run_ptda({"import", "--csv", (dir_ / "signal.csv").string(), "--column", "1", "--rate", "20000",
                "--shaft-speed", "600rpm", "--out", (dir_ / "rec20k").string()},
               dir_, "import20k");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run_ptda(
      {"monitor", "--recording", (dir_ / "rec20k").string(), "--config", config(), "--baseline", baseline()},
      dir_, "mismatch_rate");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err, "ptda monitor: " + baseline() + ": baseline was trained at 10000 Hz but recording " +
                       (dir_ / "rec20k" / "vibration.wav").string() + " is sampled at 20000 Hz\n");

  // Training recordings of two rates (cmd_train's take_rate(), shared by the time and order domains).
  r = run_ptda({"train", "--recording", rec(), "--recording", (dir_ / "rec20k").string(), "--config",
                config(), "--out", (dir_ / "never.bin").string()},
               dir_, "mixed_rates");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err, "ptda train: " + (dir_ / "rec20k" / "vibration.wav").string() +
                       ": sampled at 20000 Hz but " + rec() +
                       " at 10000 Hz (all training recordings need one rate)\n");
  EXPECT_FALSE(fs::exists(dir_ / "never.bin"));
}

TEST_F(CliEnd2End, MalformedCsvIsExitOneWithLineAndColumnAndUsageErrorsExitTwo) {
  const fs::path csv = dir_ / "bad.csv";
  std::ofstream(csv) << "a,b\n1,2\n3,4\n5,abc\n";
  RunResult r = run_ptda({"import", "--csv", csv.string(), "--column", "a", "--rate", "1000", "--shaft-speed",
                          "5Hz", "--out", (dir_ / "never_rec").string()},
                         dir_, "bad_csv");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err, "ptda import: " + csv.string() + ":4:2: not a number 'abc' in column 'b'\n");
  EXPECT_FALSE(fs::exists(dir_ / "never_rec" / "recording.toml"));

  r = run_ptda(
      {"monitor", "--recording", rec(), "--config", config(), "--baseline", baseline(), "--frobnicate"}, dir_,
      "usage");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, "ptda monitor: unknown option --frobnicate\n(try 'ptda monitor --help')\n");
  r = run_ptda({}, dir_, "no_command");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("usage: ptda <command>"), std::string::npos);
}

}  // namespace
}  // namespace ptda::golden
