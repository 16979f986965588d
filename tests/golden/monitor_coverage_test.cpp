// `ptda monitor` on coverage and in-sample data, through the built binary:
//   - a recording of the arc-welding job whose plateau speeds are all 1.5 times the trained ones judges
//     nothing: exit status 3, the summary's coverage block says "not judging" with the speeds seen,
//     and a warning says so;
//   - the same job at the trained speeds: exit 0, coverage full, no warning;
//   - monitoring the training recording warns "in-sample"; monitoring its held-out half does not.
#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>
#include <string>

#include "golden_support.hpp"

namespace ptda::golden {
namespace {

bool has(const std::string& text, const std::string& needle) {
  return text.find(needle) != std::string::npos;
}

struct Prepared {
  fs::path dir, healthy, other, fast, baseline, half_baseline;
  std::string config;
};

const Prepared& prepared() {
  static const Prepared p = [] {
    Prepared q;
    // One directory per process: ctest runs this file's tests as parallel processes.
    q.dir = scratch_dir("monitor_coverage_" + std::to_string(::getpid()));
    const fs::path scen = source_dir() / "config" / "scenarios" / "arc_welding_healthy.toml";
    q.config = (source_dir() / "config" / "examples" / "arc_welding.toml").string();
    q.healthy = q.dir / "healthy";
    q.other = q.dir / "other";
    q.fast = q.dir / "fast";
    q.baseline = q.dir / "base.bin";
    q.half_baseline = q.dir / "half.bin";
    std::string text = read_file(scen);
    const std::string speeds = "segment_speeds_rad_s = [4.1015, 1.0, 0.5, 2.5, 1.2]";
    const std::size_t at = text.find(speeds);
    EXPECT_NE(at, std::string::npos) << "the arc-welding scenario's speeds changed";
    if (at != std::string::npos)
      text.replace(at, speeds.size(), "segment_speeds_rad_s = [6.15, 1.5, 0.75, 3.75, 1.8]");
    std::ofstream(q.dir / "fast.toml") << text;
    EXPECT_EQ(run_ptda({"simulate", "--scenario", scen.string(), "--out", q.healthy.string(), "--seed", "11"},
                       q.dir, "sim_healthy")
                  .exit_code,
              0);
    EXPECT_EQ(run_ptda({"simulate", "--scenario", scen.string(), "--out", q.other.string(), "--seed", "12"},
                       q.dir, "sim_other")
                  .exit_code,
              0);
    EXPECT_EQ(run_ptda({"simulate", "--scenario", (q.dir / "fast.toml").string(), "--out", q.fast.string(),
                        "--seed", "13"},
                       q.dir, "sim_fast")
                  .exit_code,
              0);
    EXPECT_EQ(run_ptda({"train", "--recording", q.healthy.string(), "--config", q.config, "--out",
                        q.baseline.string()},
                       q.dir, "train")
                  .exit_code,
              0);
    EXPECT_EQ(run_ptda({"train", "--recording", q.healthy.string(), "--config", q.config, "--out",
                        q.half_baseline.string(), "--windows", "0:0.5"},
                       q.dir, "train_half")
                  .exit_code,
              0);
    return q;
  }();
  return p;
}

RunResult monitor(const fs::path& recording, const fs::path& baseline, const std::string& tag,
                  std::vector<std::string> extra = {}) {
  const Prepared& p = prepared();
  std::vector<std::string> args = {"monitor", "--recording", recording.string(), "--config",
                                   p.config,  "--baseline",  baseline.string(),  "--quiet"};
  args.insert(args.end(), extra.begin(), extra.end());
  return run_ptda(args, p.dir, tag);
}

TEST(MonitorCoverage, SpeedsMatchingNoClassJudgeNothingAndExit3) {
  const Prepared& p = prepared();
  const fs::path jsonl = p.dir / "fast.jsonl";
  const RunResult r =
      monitor(p.fast, p.baseline, "fast", {"--jsonl", jsonl.string(), "--coverage-timeout", "5"});
  EXPECT_EQ(r.exit_code, 3) << r.out << r.err;
  const std::vector<cli::JsonValue> windows = read_jsonl(jsonl);
  ASSERT_GT(windows.size(), 10U);
  for (const auto& w : windows) EXPECT_EQ(w.at("status").as_string(), "no_class");
  const std::string n = std::to_string(windows.size());
  EXPECT_TRUE(has(r.out, "  coverage   0 windows judged, " + n + " cut but not judged (speed " + n +
                             ", direction 0, invalid 0)"))
      << r.out;
  EXPECT_TRUE(has(r.out, "  state      not judging: no window matches a trained class (seen ")) << r.out;
  EXPECT_TRUE(has(r.out, "; trained +0.50, +1.00, +4.10, -1.20, -2.50) (timeout 5 s of motion)")) << r.out;
  EXPECT_TRUE(has(r.out, "warning: judged nothing: no window matched a class of the baseline")) << r.out;
  EXPECT_TRUE(has(r.out, "  class 0    +0.500 rad/s: 0 judged  (NOT JUDGED RECENTLY)")) << r.out;
  EXPECT_TRUE(has(r.out, "  unmatched  speeds seen: ")) << r.out;
  // With the JSONL on stdout the warning goes to stderr; the exit status is the same.
  const RunResult j = monitor(p.fast, p.baseline, "fast_stdout", {"--jsonl", "-"});
  EXPECT_EQ(j.exit_code, 3);
  EXPECT_TRUE(has(j.err, "warning: judged nothing")) << j.err;
  EXPECT_FALSE(has(j.out, "warning")) << j.out;
}

TEST(MonitorCoverage, TrainedSpeedsAreFullyCoveredAndOutOfSample) {
  const Prepared& p = prepared();
  const RunResult r = monitor(p.other, p.baseline, "other");
  EXPECT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_TRUE(has(r.out, "  state      full (timeout 60 s of motion)")) << r.out;
  EXPECT_FALSE(has(r.out, "warning")) << r.out;
  EXPECT_FALSE(has(r.out, "training recording")) << r.out;  // another run: not in-sample
}

TEST(MonitorCoverage, MonitoringTheTrainingDataWarnsInSample) {
  const Prepared& p = prepared();
  const RunResult same = monitor(p.healthy, p.baseline, "same");
  EXPECT_EQ(same.exit_code, 0);
  EXPECT_TRUE(has(same.out, "warning: in-sample: this recording is the baseline's training recording " +
                                p.healthy.string() + " (id wav:"))
      << same.out;
  // Trained on the first half: the second half is held out (a note), the first half is in-sample.
  const RunResult held = monitor(p.healthy, p.half_baseline, "held", {"--windows", "0.5:1"});
  EXPECT_EQ(held.exit_code, 0);
  EXPECT_FALSE(has(held.out, "warning: in-sample")) << held.out;
  EXPECT_TRUE(has(held.out, "note: this recording is the baseline's training recording")) << held.out;
  EXPECT_TRUE(has(held.out, "a held-out part")) << held.out;
  const RunResult first = monitor(p.healthy, p.half_baseline, "first", {"--windows", "0:0.5"});
  EXPECT_TRUE(has(first.out, "warning: in-sample")) << first.out;
}

// arc_welding.toml with `line` added at the top of its [decision] table, written to p.dir / name.
fs::path config_with_decision(const std::string& line, const std::string& name) {
  const Prepared& p = prepared();
  std::string text = read_file(p.config);
  const std::size_t at = text.find("[decision]\n");
  EXPECT_NE(at, std::string::npos) << "arc_welding.toml has no [decision] table";
  if (at != std::string::npos) text.insert(at + 11, line + "\n");
  const fs::path path = p.dir / name;
  std::ofstream(path) << text;
  return path;
}

// The band detector is on by default since session 13. A baseline trained with it off (as every
// baseline before session 13) still monitors: the band detector is off with a note that says why, and
// the windows are judged as before. Said explicitly (`band_cusum = true`), the same baseline is an error.
TEST(MonitorCoverage, ABaselineWithoutBandStatisticsMonitorsWithANoteUnlessTheBandDetectorIsRequired) {
  const Prepared& p = prepared();
  const fs::path off_cfg = config_with_decision("band_cusum = false", "band_off.toml");
  const fs::path on_cfg = config_with_decision("band_cusum = true", "band_on.toml");
  const fs::path old_base = p.dir / "no_bands.bin";
  ASSERT_EQ(run_ptda({"train", "--recording", p.healthy.string(), "--config", off_cfg.string(), "--out",
                      old_base.string()},
                     p.dir, "train_band_off")
                .exit_code,
            0);
  // Default configuration, old-style baseline: runs, says why the band detector is off.
  const RunResult def = monitor(p.other, old_base, "band_default_old");
  EXPECT_EQ(def.exit_code, 0) << def.err;
  EXPECT_TRUE(has(def.err, "note: band detector off: the baseline has no band statistics")) << def.err;
  // The default-trained baseline has them: no note.
  const RunResult fresh = monitor(p.other, p.baseline, "band_default_new");
  EXPECT_EQ(fresh.exit_code, 0) << fresh.err;
  EXPECT_FALSE(has(fresh.err, "band detector off")) << fresh.err;
  // Explicitly on, the old baseline is refused with the reason.
  const RunResult req = run_ptda({"monitor", "--recording", p.other.string(), "--config", on_cfg.string(),
                                  "--baseline", old_base.string(), "--quiet"},
                                 p.dir, "band_required_old");
  EXPECT_NE(req.exit_code, 0);
  EXPECT_TRUE(has(req.err, "retrain it with [decision] band_cusum = true")) << req.err;
  // Explicitly off: no note either.
  const RunResult off = run_ptda({"monitor", "--recording", p.other.string(), "--config", off_cfg.string(),
                                  "--baseline", old_base.string(), "--quiet"},
                                 p.dir, "band_off_old");
  EXPECT_EQ(off.exit_code, 0) << off.err;
  EXPECT_FALSE(has(off.err, "band detector off")) << off.err;
}

// The mesh detector is on by default since session 37 where the gearbox's teeth are given (arc_welding.toml
// gives them). The default-trained baseline carries its statistics and every judged window its record; a
// baseline trained with it off (as every baseline before session 37) still monitors, with a note that
// says why, and is an error only when `mesh_cusum = true` is said explicitly.
TEST(MonitorCoverage, TheMeshDetectorRunsByDefaultWithTeethAndAnOldBaselineMonitorsWithANote) {
  const Prepared& p = prepared();
  ASSERT_NE(read_file(p.config).find("z_in"), std::string::npos) << "arc_welding.toml gives no teeth";
  const fs::path off_cfg = config_with_decision("mesh_cusum = false", "mesh_off.toml");
  const fs::path on_cfg = config_with_decision("mesh_cusum = true", "mesh_on.toml");
  // Default: the windows carry the mesh detector's record, and there is no note.
  const fs::path jsonl = p.dir / "mesh_default.jsonl";
  const RunResult fresh = monitor(p.other, p.baseline, "mesh_default_new", {"--jsonl", jsonl.string()});
  EXPECT_EQ(fresh.exit_code, 0) << fresh.err;
  EXPECT_FALSE(has(fresh.err, "mesh detector off")) << fresh.err;
  const std::string lines = read_file(jsonl);
  EXPECT_TRUE(has(lines, "\"mesh_cusum_max\":")) << lines.substr(0, 400);
  const fs::path old_base = p.dir / "no_mesh.bin";
  const RunResult trained = run_ptda(
      {"train", "--recording", p.healthy.string(), "--config", off_cfg.string(), "--out", old_base.string()},
      p.dir, "train_mesh_off");
  ASSERT_EQ(trained.exit_code, 0) << trained.err;
  EXPECT_FALSE(has(trained.out, "mesh CUSUM:")) << trained.out;
  // Default configuration, old-style baseline: runs, says why the mesh detector is off, no mesh record.
  const fs::path old_jsonl = p.dir / "mesh_default_old.jsonl";
  const RunResult def = monitor(p.other, old_base, "mesh_default_old", {"--jsonl", old_jsonl.string()});
  EXPECT_EQ(def.exit_code, 0) << def.err;
  EXPECT_TRUE(has(def.err, "note: mesh detector off: the baseline has no mesh statistics")) << def.err;
  EXPECT_FALSE(has(read_file(old_jsonl), "\"mesh_cusum_max\":"));
  // Explicitly on, the old baseline is refused with the reason.
  const RunResult req = run_ptda({"monitor", "--recording", p.other.string(), "--config", on_cfg.string(),
                                  "--baseline", old_base.string(), "--quiet"},
                                 p.dir, "mesh_required_old");
  EXPECT_NE(req.exit_code, 0);
  EXPECT_TRUE(has(req.err, "retrain it with [decision] mesh_cusum = true")) << req.err;
  // Explicitly off: no note either.
  const RunResult off = run_ptda({"monitor", "--recording", p.other.string(), "--config", off_cfg.string(),
                                  "--baseline", old_base.string(), "--quiet"},
                                 p.dir, "mesh_off_old");
  EXPECT_EQ(off.exit_code, 0) << off.err;
  EXPECT_FALSE(has(off.err, "mesh detector off")) << off.err;
}

}  // namespace
}  // namespace ptda::golden
