// `ptda train` streams (issue 13 item 4): a first pass keeps only the windows' places and the regions,
// two more passes over each recording hand the windows to dsp::train_baseline_streamed. The baseline it
// writes must be the one dsp::train_baseline gives on the same windows held in memory (as `ptda train`
// did before): two recordings (two days), --windows cutting into both, overlapping windows (groups of
// several windows) and a hold-out. The in-memory side is built here from the same cli helpers.
#include <gtest/gtest.h>

#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include "golden_support.hpp"
#include "ptda/cli/pipeline_runner.hpp"
#include "ptda/config/pipeline_config.hpp"
#include "ptda/dsp/baseline_training.hpp"
#include "ptda/formats/baseline_file.hpp"

namespace ptda::golden {
namespace {

TEST(TrainStream, StreamedTrainingWritesTheBaselineOfTheWindowsHeldInMemory) {
  const fs::path dir = scratch_dir("train_stream");
  const fs::path src = source_dir();
  for (const std::string seed : {"1001", "2002"}) {
    const RunResult r =
        run_ptda({"simulate", "--scenario", (src / "config/scenarios/arc_welding_healthy.toml").string(),
                  "--out", (dir / ("h" + seed)).string(), "--seed", seed},
                 dir, "simulate_" + seed);
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
  // The job's configuration with overlapping windows (1600 samples, hop 400, any number per plateau)
  // and a 30 % hold-out.
  std::string text = read_file(src / "config/examples/arc_welding.toml");
  for (const auto& [from, to] :
       {std::pair<std::string, std::string>{"window_len = 3200", "window_len = 1600"},
        {"hop = 3200", "hop = 400"},
        {"max_windows_per_region = 1", "max_windows_per_region = 0"}}) {
    ASSERT_NE(text.find(from), std::string::npos) << from;
    text.replace(text.find(from), from.size(), to);
  }
  const std::string thresholds = "[thresholds]\n";
  ASSERT_NE(text.find(thresholds), std::string::npos);
  text.insert(text.find(thresholds) + thresholds.size(), "holdout_fraction = 0.3\n");
  const fs::path config = dir / "config.toml";
  std::ofstream(config) << text;

  const fs::path out = dir / "baseline.bin";
  const RunResult t =
      run_ptda({"train", "--recording", (dir / "h1001").string(), "--recording", (dir / "h2002").string(),
                "--config", config.string(), "--out", out.string(), "--windows", "0.2:0.9"},
               dir, "train");
  ASSERT_EQ(t.exit_code, 0) << t.err;
  const dsp::Baseline streamed = formats::read_baseline(out);

  const config::PipelineConfig cfg = config::load_pipeline_config(config);
  dsp::CollectedWindows all;
  double fs_hz = 0.0;
  for (const char* r : {"h1001", "h2002"}) {
    const cli::RecordingInfo rec = cli::open_recording(dir / r);
    fs_hz = cli::pipeline_fs_hz(rec, cfg, config.string());
    cli::RunOptions opts;
    opts.progress = false;
    cli::append_collected(all, cli::collect_windows(rec, cfg, fs_hz, opts).data);
  }
  ASSERT_EQ(all.windows.size(), all.refs.size());
  const dsp::CollectedWindows kept = cli::select_windows(all, cli::FractionRange{0.2, 0.9});
  const dsp::Baseline held = dsp::train_baseline(kept, cfg.classes, cfg.thresholds, fs_hz, cfg.gearbox);

  ASSERT_EQ(streamed.classes.size(), held.classes.size());
  ASSERT_GE(held.classes.size(), 1U);
  std::size_t overlapping = 0;
  for (std::size_t k = 0; k < held.classes.size(); ++k) {
    const dsp::ClassBaseline& a = held.classes[k];
    const dsp::ClassBaseline& b = streamed.classes[k];
    EXPECT_EQ(a.n_windows, b.n_windows) << k;
    EXPECT_EQ(a.mean_magnitude, b.mean_magnitude) << k;
    EXPECT_EQ(a.tda_mean, b.tda_mean) << k;
    EXPECT_EQ(a.windows_per_hour, b.windows_per_hour) << k;
    for (std::size_t m = 0; m < dsp::kMethodCount; ++m) {
      EXPECT_EQ(a.thresholds[m].rms.lo, b.thresholds[m].rms.lo) << k << " " << m;
      EXPECT_EQ(a.thresholds[m].rms.hi, b.thresholds[m].rms.hi) << k << " " << m;
      EXPECT_EQ(a.thresholds[m].entropy.lo, b.thresholds[m].entropy.lo) << k << " " << m;
      EXPECT_EQ(a.thresholds[m].entropy.hi, b.thresholds[m].entropy.hi) << k << " " << m;
      EXPECT_EQ(a.rms_stats[m].mean, b.rms_stats[m].mean) << k << " " << m;
      EXPECT_EQ(a.entropy_stats[m].stddev, b.entropy_stats[m].stddev) << k << " " << m;
      EXPECT_EQ(a.day_spread[m].recordings, 2U) << k << " " << m;
      EXPECT_EQ(a.day_spread[m].log_rms_between_sd, b.day_spread[m].log_rms_between_sd) << k << " " << m;
      EXPECT_EQ(a.holdout[m].windows, b.holdout[m].windows) << k << " " << m;
      EXPECT_EQ(a.holdout[m].abnormal, b.holdout[m].abnormal) << k << " " << m;
      EXPECT_EQ(a.holdout[m].z_rms_mean, b.holdout[m].z_rms_mean) << k << " " << m;
    }
    EXPECT_GT(a.holdout[0].windows, 0U) << k;
  }
  // The case is the one it claims: some class has more windows than regions (overlap groups of several).
  for (const dsp::ClassBaseline& c : held.classes) overlapping += c.n_windows > c.segment.regions ? 1U : 0U;
  EXPECT_GT(overlapping, 0U);
}

}  // namespace
}  // namespace ptda::golden
