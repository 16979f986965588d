// Smoke version of the 24-hour drift soak (scripts/drift_soak.sh, docs/benchmarks.md "Drift soak"):
// three simulated minutes in 10-minute-style pieces of 36 cycles, through the real `ptdad` binary and
// `ptda monitor`. Checks the streaming mechanics (pieces continue the drift, the daemon judges the same
// windows as the monitor, memory is measured), and that without drift a healthy run raises no alarm
// while a full-severity tooth defect does. The long run's numbers are in the docs, not pinned here.
#include <gtest/gtest.h>

#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include "golden_support.hpp"

namespace ptda::golden {
namespace {

// build/<preset>/cli/ptda -> build/<preset>
fs::path build_dir() {
  return fs::path(PTDA_CLI_BINARY).parent_path().parent_path();
}

struct Piece {
  double t0_h = 0.0, t1_h = 0.0;
  std::string coldness;  ///< "-" without drift
  std::string pause;
  long windows = 0, scored = 0, abnormal = 0, ptdad_alarms = 0, monitor_alarm_windows = 0;
  double ptdad_rss_kb = 0.0;
};

std::vector<Piece> run_soak(const std::string& name, const std::string& env, const std::string& mode) {
  const fs::path out = scratch_dir("drift_soak_" + name);
  const std::string cmd = env + " PTDA_SOAK_CHUNK_CYCLES=36 " +
                          shell_quote((source_dir() / "scripts" / "drift_soak.sh").string()) + " 0.05 " +
                          mode + " " + shell_quote(build_dir().string()) + " " + shell_quote(out.string()) +
                          " >" + shell_quote((out.parent_path() / (name + ".log")).string()) + " 2>&1";
  const int status = std::system(cmd.c_str());
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0)
      << cmd << "\n"
      << read_file(out.parent_path() / (name + ".log"));
  std::istringstream tsv(read_file(out / "pieces.tsv"));
  std::string line;
  std::getline(tsv, line);  // header
  std::vector<Piece> pieces;
  while (std::getline(tsv, line)) {
    std::istringstream f(line);
    Piece p;
    std::string piece, load, severity, first_abn, first_alarm, sim_s, ptdad_s, sim_rss;
    f >> piece >> p.t0_h >> p.t1_h >> load >> p.coldness >> p.pause >> severity >> p.windows >> p.scored >>
        p.abnormal >> p.ptdad_alarms >> p.monitor_alarm_windows >> first_abn >> first_alarm >> sim_s >>
        ptdad_s >> p.ptdad_rss_kb >> sim_rss;
    EXPECT_FALSE(f.fail()) << line;
    pieces.push_back(p);
  }
  EXPECT_TRUE(fs::exists(out / "summary.md"));
  // The default baseline recipe (PTDA_SOAK_TRAIN=day): 8 pieces of another simulated day, seeds from
  // 900001 (never the evaluation's 1, 2, ...), the first at the cold start.
  std::istringstream train(read_file(out / "train_pieces.tsv"));
  std::getline(train, line);  // header
  int train_pieces = 0;
  while (std::getline(train, line)) {
    std::istringstream f(line);
    std::string idx, drift_h, load, coldness, pause;
    long seed = 0;
    f >> idx >> drift_h >> load >> coldness >> pause >> seed;
    EXPECT_EQ(seed, 900001 + train_pieces) << line;
    if (train_pieces == 0) {
      EXPECT_EQ(coldness, "1.000000") << line;
    }
    ++train_pieces;
  }
  EXPECT_EQ(train_pieces, 8);
  return pieces;
}

TEST(DriftSoakSmoke, PiecesContinueTheDriftAndTheDaemonJudgesEveryWindow) {
  const std::vector<Piece> pieces = run_soak("drift", "", "healthy");
  // 0.05 h = 180 s of ~2.5 s cycles in pieces of 36: at least two pieces.
  ASSERT_GE(pieces.size(), 2U);
  double t_h = 0.0;
  for (const Piece& p : pieces) {
    EXPECT_DOUBLE_EQ(p.t0_h, t_h);  // each piece starts where the previous ended
    t_h = p.t1_h;
    // Cold start, no pause in these pieces: c(t) = e^{-t / 900 s} (drift_soak.toml warmup_tau_s).
    EXPECT_NEAR(std::stod(p.coldness), std::exp(-p.t0_h * 3600.0 / 900.0), 1e-4);
    EXPECT_EQ(p.pause, "no");
    EXPECT_GT(p.windows, 0);
    EXPECT_EQ(p.scored, p.windows);  // both plateau classes were trained
    EXPECT_GT(p.ptdad_rss_kb, 1000.0);
    EXPECT_LT(p.ptdad_rss_kb, 200000.0);  // tens of MB: the replay streams from disk
  }
  // Two windows per cycle (one per direction) and the simulated time adds up to ~3 minutes.
  EXPECT_EQ(pieces[0].windows, 72);
  EXPECT_NEAR(t_h, 0.05, 2.6 / 3600.0);
}

TEST(DriftSoakSmoke, WithoutDriftHealthyIsQuietAndAFullDefectAlarms) {
  const std::vector<Piece> healthy = run_soak("nodrift_healthy", "PTDA_SOAK_NO_DRIFT=1", "healthy");
  const std::vector<Piece> faulty = run_soak(
      "nodrift_fault", "PTDA_SOAK_NO_DRIFT=1 PTDA_SOAK_FAULT_ONSET_H=0 PTDA_SOAK_FAULT_FULL_H=0", "fault");
  ASSERT_FALSE(healthy.empty());
  ASSERT_EQ(faulty.size(), healthy.size());
  for (std::size_t i = 0; i < healthy.size(); ++i) {
    EXPECT_EQ(healthy[i].coldness, "-");  // the drift was off
    EXPECT_EQ(healthy[i].ptdad_alarms, 0) << "piece " << i;
    EXPECT_EQ(healthy[i].monitor_alarm_windows, 0) << "piece " << i;
    EXPECT_EQ(faulty[i].ptdad_alarms, 1) << "piece " << i;
    EXPECT_GT(faulty[i].abnormal, faulty[i].scored / 2) << "piece " << i;
  }
}

}  // namespace
}  // namespace ptda::golden
