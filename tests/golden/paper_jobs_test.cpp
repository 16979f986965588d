// End-to-end replay of the paper's three job tasks through the built `ptda` binary:
//   simulate healthy-train (seed 1001), healthy-fresh (seed 2002) and faulty (seed 3003) recordings
//   with config/scenarios/<job>_{healthy,faulty}.toml, train on healthy-train with
//   config/examples/<job>.toml, monitor the two others with raw, TDA and PTDA and read the JSONL.
// Claims (paper sections 4.2-4.4): PTDA raises the alarm on the faulty recording and never on the
// fresh healthy one, and PTDA separates faulty from healthy better than raw and TDA: the ratio of
// mean residual RMS faulty/healthy is largest for PTDA, the RMS feature flags more faulty windows with
// PTDA than with raw or TDA, and so does the verdict (both features), except raw on spot welding.
// The job presets vary the mesh amplitudes (1.5 %) and the background (5 %) from cycle to cycle
// (docs/simulator.md, "Cycle-to-cycle variation"): without that the simulated healthy raw signal
// repeated so exactly that raw flagged every faulty window, like PTDA.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <string>
#include <vector>

#include "golden_support.hpp"

namespace ptda::golden {
namespace {

struct MonitorStats {
  std::size_t windows = 0, scored = 0, abnormal = 0, alarm_windows = 0;
  std::size_t rms_out = 0;  ///< windows whose RMS alone is above its band
  long first_alarm_n = -1;  ///< window sequence of the first alarm, -1: never
  double mean_rms = 0.0, mean_entropy = 0.0;
};

MonitorStats stats_of(const std::vector<cli::JsonValue>& rows, const std::string& method) {
  MonitorStats s;
  s.windows = rows.size();
  for (const auto& r : rows) {
    EXPECT_EQ(r.at("method").as_string(), method);
    EXPECT_LT(r.at("t_start").as_number(), r.at("t_end").as_number());
    if (r.at("status").as_string() != "scored") continue;
    ++s.scored;
    const double rms = r.at("rms_res").as_number();
    const double ent = r.at("entropy_res").as_number();
    s.mean_rms += rms;
    s.mean_entropy += ent;
    // The JSONL verdict must agree with the bands it reports. Issue 12: a residual RMS below its band is
    // a low residual (its own cause), not abnormal; above it, or entropy outside its band, is abnormal.
    const auto& rb = r.at("rms_band").array;
    const auto& eb = r.at("entropy_band").array;
    const bool out = rms > rb.at(1).as_number() || ent < eb.at(0).as_number() || ent > eb.at(1).as_number();
    EXPECT_EQ(r.at("abnormal").as_bool(), out) << "window " << r.at("n").as_number();
    if (out) ++s.abnormal;
    const bool rms_out = rms > rb.at(1).as_number();
    EXPECT_EQ(r.at("rms_out").as_bool(), rms_out) << "window " << r.at("n").as_number();
    EXPECT_EQ(r.at("rms_low").as_bool(), rms < rb.at(0).as_number()) << "window " << r.at("n").as_number();
    if (rms_out) ++s.rms_out;
    if (r.at("alarm").as_bool()) {
      ++s.alarm_windows;
      if (s.first_alarm_n < 0) s.first_alarm_n = static_cast<long>(r.at("n").as_number());
    }
  }
  if (s.scored > 0) {
    s.mean_rms /= static_cast<double>(s.scored);
    s.mean_entropy /= static_cast<double>(s.scored);
  }
  return s;
}

struct Pinned {
  // measured values, see the comment at kJobs
  std::size_t windows_fresh, windows_faulty;
  std::size_t ptda_abnormal_faulty, tda_abnormal_faulty, raw_abnormal_faulty;
  std::size_t ptda_rms_out_faulty, tda_rms_out_faulty, raw_rms_out_faulty;
  long ptda_first_alarm_n, tda_first_alarm_n, raw_first_alarm_n;
  double ptda_rms_fresh, ptda_rms_faulty, tda_rms_fresh, tda_rms_faulty, raw_rms_fresh, raw_rms_faulty;
};

struct Job {
  const char* name;
  /// Raw flags fewer faulty windows than PTDA (verdict from both features). Until session 7 not on spot
  /// welding (since the between-day widening raw flags 19 of its 20): its
  /// single class holds a strong defect (impulse 8 m/s^2 at the slow plateau) whose broadband ringing
  /// raises the raw spectral entropy (0.389 -> 0.423, band sd 0.008) in every faulty window, so raw
  /// flags all 20 windows like PTDA; raw's RMS alone still misses one and its RMS ratio is 1.04 vs 1.78.
  bool raw_fewer_abnormal;
  Pinned pinned;
};

// Pinned numbers: measured with these seeds by running this test's commands (ptda built RelWithDebInfo,
// GCC 12, x86-64; presets with cycle_amplitude_jitter_rel 0.015 / cycle_noise_jitter_rel 0.05, arc
// welding alarm 4 of 10). Everything is deterministic given the seeds; the relative tolerance 1e-4 on
// the mean residual RMS covers float32 FFT rounding differences between builds (FMA contraction, -O
// levels), which are ~1e-6 relative on a 0.5 s window, with room; counts are exact.
// Re-pinned for issue 12 (tolerance bands, one-sided RMS, CUSUM beside k-of-n; the features and mean
// RMS are unchanged): before, with Gaussian two-sided bands and k-of-n only, abnormal faulty windows
// ptda/tda/raw were 40/6/36, 40/0/32, 20/11/20, RMS out 40/0/25, 40/0/12, 20/0/19 and first alarms
// 2/-1/2, 8/-1/13, 2/3/2. Tolerance bands are wider for TDA and raw, whose leave-one-out features
// vary more; PTDA now alarms at the first faulty window, through the CUSUM.
// Re-pinned in session 5 for the PTDA line gain, now the default ([monitor] line_gain, docs/method.md
// §3): the PTDA mean rms_res fell by 0.5-1.2 % (the cycle-to-cycle amplitude jitter of the harmonics no
// longer shows), arc welding's faulty windows with RMS out went 39 -> 37; abnormal counts and first
// alarms unchanged. The paper's PTDA gave ptda rms fresh/faulty 0.256852705/0.441198798,
// 0.254059718/0.288964039, 0.261193089/0.46389865.
// Re-pinned in session 6 for the floor gain with the level-referred residual, now the default
// ([monitor] floor_gain, docs/method.md §2): PTDA mean rms_res fresh +2.6 to +3.1 % (the referred
// residual), faulty +0.2 / +1.8 / -2.4 %; arc welding's faulty windows with RMS out 37 -> 40; abnormal
// counts and first alarms unchanged. The line gain alone gave the session-5 numbers 0.255019669 /
// 0.439087525, 0.252584565 / 0.285625844, 0.259009661 / 0.461998417.
// Re-pinned in session 7 for the between-day spread (docs/method.md §5, §6: one training recording,
// bands sqrt(1 + 0.3^2) = 1.044 times wider, CUSUM allowance k + 3 x 0.3 x sqrt(2) / c_n): features and
// every PTDA count and first alarm unchanged; raw and TDA flag and alarm later. Before: abnormal faulty
// tda/raw 1/29, 0/22, 5/20; raw RMS out 15, 5, 17; first alarm tda/raw 14/3, -1/10, 4/1. Spot welding's
// raw now flags 19 of 20 faulty windows (PTDA 20), so raw_fewer_abnormal holds there too.
// Before the cycle-to-cycle variation (identical cycles) raw flagged 40/40, 49/101, 20/20 faulty
// windows (PTDA 40, 48, 20), raw RMS ratios 1.033, 1.011, 1.048.
// Re-pinned in session 38 for the feature CUSUM's step cap (2.5 per window, docs/method.md §6): arc
// welding's PTDA alarm comes at window 5 instead of 0 (its faulty windows are abnormal 40 times in 101,
// not in a row; one window can no longer take the CUSUM over cusum_alarm alone). Joint rotation and spot
// welding keep window 0 (the band CUSUM, uncapped, alarms there); every other number is unchanged.
constexpr Job kJobs[] = {
    // windows fresh/faulty, abnormal on faulty ptda/tda/raw, RMS out of band on faulty ptda/tda/raw,
    // first alarm window ptda/tda/raw, mean rms_res ptda fresh/faulty, tda fresh/faulty, raw fresh/faulty
    {"joint_rotation",
     true,
     {40, 40, 40, 1, 26, 40, 0, 13, 0, -1, 4, 0.262290756, 0.44012434, 2.00395427, 2.05173636, 1.94357524,
      2.000598}},
    {"arc_welding",
     true,
     {100, 101, 40, 0, 19, 40, 0, 4, 5, -1, 15, 0.25922925, 0.290818003, 1.04698794, 1.05729261, 1.03934736,
      1.04217004}},
    {"spot_welding",
     true,
     {20, 20, 20, 4, 19, 20, 0, 17, 0, 13, 2, 0.267151395, 0.450945793, 1.9517956, 2.05480079, 1.94241323,
      2.02733877}},
};

void PrintTo(const Job& job, std::ostream* os) {
  *os << job.name;
}

class PaperJob : public ::testing::TestWithParam<Job> {};

TEST_P(PaperJob, PtdaAlarmsOnFaultOnlyAndSeparatesBest) {
  const Job job = GetParam();
  const std::string name = job.name;
  const fs::path dir = scratch_dir("paper_" + name);
  const fs::path src = source_dir();
  const std::string healthy = (src / "config/scenarios" / (name + "_healthy.toml")).string();
  const std::string faulty = (src / "config/scenarios" / (name + "_faulty.toml")).string();
  const std::string config = (src / "config/examples" / (name + ".toml")).string();

  struct Sim {
    std::string scenario, seed, out;
  };
  const Sim sims[] = {{healthy, "1001", "train"}, {healthy, "2002", "fresh"}, {faulty, "3003", "faulty"}};
  for (const auto& s : sims) {
    const RunResult r =
        run_ptda({"simulate", "--scenario", s.scenario, "--out", (dir / s.out).string(), "--seed", s.seed},
                 dir, "simulate_" + s.out);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.out.find("(seed " + s.seed + ")"), std::string::npos) << r.out;
  }
  const std::string baseline = (dir / "baseline.bin").string();
  const RunResult t =
      run_ptda({"train", "--recording", (dir / "train").string(), "--config", config, "--out", baseline}, dir,
               "train");
  ASSERT_EQ(t.exit_code, 0) << t.err;
  EXPECT_NE(t.out.find("class 0: direction"), std::string::npos) << t.out;

  std::map<std::string, MonitorStats> fresh, fault;
  for (const std::string method : {"raw", "tda", "ptda"}) {
    for (const std::string rec : {"fresh", "faulty"}) {
      const fs::path jsonl = dir / (rec + "." + method + ".jsonl");
      const RunResult m = run_ptda({"monitor", "--recording", (dir / rec).string(), "--config", config,
                                    "--baseline", baseline, "--method", method, "--jsonl", jsonl.string()},
                                   dir, "monitor_" + rec + "_" + method);
      ASSERT_EQ(m.exit_code, 0) << m.err;
      EXPECT_NE(m.out.find("summary (" + method + ")"), std::string::npos) << m.out;
      const MonitorStats s = stats_of(read_jsonl(jsonl), method);
      (rec == "fresh" ? fresh : fault)[method] = s;
      std::printf(
          "%-14s %-6s %-4s windows %zu scored %zu abnormal %zu (rms %zu) alarm windows %zu first alarm n "
          "%ld mean rms %.9g mean entropy %.6f\n",
          name.c_str(), rec.c_str(), method.c_str(), s.windows, s.scored, s.abnormal, s.rms_out,
          s.alarm_windows, s.first_alarm_n, s.mean_rms, s.mean_entropy);
    }
  }

  // The paper's claims.
  EXPECT_GT(fault["ptda"].alarm_windows, 0U) << "PTDA must raise the alarm on the faulty recording";
  EXPECT_EQ(fresh["ptda"].alarm_windows, 0U) << "PTDA must never alarm on the fresh healthy recording";
  EXPECT_EQ(fresh["ptda"].scored, fresh["ptda"].windows) << "every healthy window belongs to a trained class";
  const double ratio_ptda = fault["ptda"].mean_rms / fresh["ptda"].mean_rms;
  const double ratio_tda = fault["tda"].mean_rms / fresh["tda"].mean_rms;
  const double ratio_raw = fault["raw"].mean_rms / fresh["raw"].mean_rms;
  std::printf("%-14s rms ratio faulty/healthy: raw %.4f tda %.4f ptda %.4f\n", name.c_str(), ratio_raw,
              ratio_tda, ratio_ptda);
  EXPECT_GT(ratio_ptda, ratio_tda);
  EXPECT_GT(ratio_ptda, ratio_raw);
  // TDA, smeared by the phase differences between cycles, flags fewer faulty windows than PTDA. Raw's
  // healthy RMS varies with the mesh amplitudes from cycle to cycle, so the few percent the fault adds
  // to it stay inside its band more often: its RMS flags fewer faulty windows than PTDA's, and so does
  // its verdict except on spot welding (see Job::raw_fewer_abnormal).
  EXPECT_GT(fault["ptda"].abnormal, fault["tda"].abnormal);
  EXPECT_GT(fault["ptda"].rms_out, fault["tda"].rms_out);
  EXPECT_GT(fault["ptda"].rms_out, fault["raw"].rms_out);
  if (job.raw_fewer_abnormal) {
    EXPECT_GT(fault["ptda"].abnormal, fault["raw"].abnormal);
  } else {
    EXPECT_EQ(fault["ptda"].abnormal, fault["raw"].abnormal);
  }
  // Neither raw nor TDA raises the alarm earlier than PTDA.
  for (const char* m : {"raw", "tda"}) {
    EXPECT_TRUE(fault[m].first_alarm_n < 0 || fault[m].first_alarm_n >= fault["ptda"].first_alarm_n) << m;
  }

  // Pinned measurements.
  const Pinned& p = job.pinned;
  EXPECT_EQ(fresh["ptda"].windows, p.windows_fresh);
  EXPECT_EQ(fault["ptda"].windows, p.windows_faulty);
  EXPECT_EQ(fault["ptda"].abnormal, p.ptda_abnormal_faulty);
  EXPECT_EQ(fault["tda"].abnormal, p.tda_abnormal_faulty);
  EXPECT_EQ(fault["raw"].abnormal, p.raw_abnormal_faulty);
  EXPECT_EQ(fault["ptda"].rms_out, p.ptda_rms_out_faulty);
  EXPECT_EQ(fault["tda"].rms_out, p.tda_rms_out_faulty);
  EXPECT_EQ(fault["raw"].rms_out, p.raw_rms_out_faulty);
  EXPECT_EQ(fault["ptda"].first_alarm_n, p.ptda_first_alarm_n);
  EXPECT_EQ(fault["tda"].first_alarm_n, p.tda_first_alarm_n);
  EXPECT_EQ(fault["raw"].first_alarm_n, p.raw_first_alarm_n);
  constexpr double kRel = 1e-4;
  EXPECT_NEAR(fresh["ptda"].mean_rms, p.ptda_rms_fresh, kRel * p.ptda_rms_fresh);
  EXPECT_NEAR(fault["ptda"].mean_rms, p.ptda_rms_faulty, kRel * p.ptda_rms_faulty);
  EXPECT_NEAR(fresh["tda"].mean_rms, p.tda_rms_fresh, kRel * p.tda_rms_fresh);
  EXPECT_NEAR(fault["tda"].mean_rms, p.tda_rms_faulty, kRel * p.tda_rms_faulty);
  EXPECT_NEAR(fresh["raw"].mean_rms, p.raw_rms_fresh, kRel * p.raw_rms_fresh);
  EXPECT_NEAR(fault["raw"].mean_rms, p.raw_rms_faulty, kRel * p.raw_rms_faulty);
}

INSTANTIATE_TEST_SUITE_P(Jobs, PaperJob, ::testing::ValuesIn(kJobs),
                         [](const ::testing::TestParamInfo<Job>& p) { return std::string(p.param.name); });

}  // namespace
}  // namespace ptda::golden
