// End-to-end replay of the paper's three job tasks through the built `ptda` binary:
//   simulate healthy-train (seed 1001), healthy-fresh (seed 2002) and faulty (seed 3003) recordings
//   with config/scenarios/<job>_{healthy,faulty}.toml, train on healthy-train with
//   config/examples/<job>.toml, monitor the two others with raw, TDA and PTDA and read the JSONL.
// Claims (paper sections 4.2-4.4): PTDA raises the alarm on the faulty recording and never on the
// fresh healthy one, and PTDA separates faulty from healthy better than raw and TDA: the ratio of
// mean residual RMS faulty/healthy is largest for PTDA.
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
    // The JSONL verdict must agree with the bands it reports.
    const auto& rb = r.at("rms_band").array;
    const auto& eb = r.at("entropy_band").array;
    const bool out = rms < rb.at(0).as_number() || rms > rb.at(1).as_number() || ent < eb.at(0).as_number() ||
                     ent > eb.at(1).as_number();
    EXPECT_EQ(r.at("abnormal").as_bool(), out) << "window " << r.at("n").as_number();
    if (out) ++s.abnormal;
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
  long ptda_first_alarm_n;
  double ptda_rms_fresh, ptda_rms_faulty, tda_rms_fresh, tda_rms_faulty, raw_rms_fresh, raw_rms_faulty;
};

struct Job {
  const char* name;
  Pinned pinned;
};

// Pinned numbers: measured with these seeds by running this test's commands (ptda built RelWithDebInfo,
// GCC 12, x86-64). Everything is deterministic given the seeds; the relative tolerance 1e-4 on the
// mean residual RMS covers float32 FFT rounding differences between builds (FMA contraction, -O
// levels), which are ~1e-6 relative on a 0.5 s window, with room; counts are exact.
constexpr Job kJobs[] = {
    // windows fresh/faulty, abnormal on faulty ptda/tda/raw, first PTDA alarm window,
    // mean rms_res ptda fresh/faulty, tda fresh/faulty, raw fresh/faulty
    {"joint_rotation",
     {40, 40, 40, 9, 40, 2, 0.248427403, 0.440055326, 1.99884122, 2.0553525, 1.94013282, 2.00482264}},
    {"arc_welding",
     {100, 101, 48, 0, 49, 4, 0.246696563, 0.287182804, 1.03954384, 1.05832681, 1.03152445, 1.04313936}},
    {"spot_welding",
     {20, 20, 20, 10, 20, 2, 0.252638396, 0.462824731, 1.94788509, 2.05848901, 1.93896574, 2.03144928}},
};

void PrintTo(const Job& job, std::ostream* os) { *os << job.name; }

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
        run_ptda({"simulate", "--scenario", s.scenario, "--out", (dir / s.out).string(), "--seed", s.seed}, dir,
                 "simulate_" + s.out);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.out.find("(seed " + s.seed + ")"), std::string::npos) << r.out;
  }
  const std::string baseline = (dir / "baseline.bin").string();
  const RunResult t =
      run_ptda({"train", "--recording", (dir / "train").string(), "--config", config, "--out", baseline}, dir, "train");
  ASSERT_EQ(t.exit_code, 0) << t.err;
  EXPECT_NE(t.out.find("class 0: direction"), std::string::npos) << t.out;

  std::map<std::string, MonitorStats> fresh, fault;
  for (const std::string method : {"raw", "tda", "ptda"}) {
    for (const std::string rec : {"fresh", "faulty"}) {
      const fs::path jsonl = dir / (rec + "." + method + ".jsonl");
      const RunResult m = run_ptda({"monitor", "--recording", (dir / rec).string(), "--config", config, "--baseline",
                                    baseline, "--method", method, "--jsonl", jsonl.string()},
                                   dir, "monitor_" + rec + "_" + method);
      ASSERT_EQ(m.exit_code, 0) << m.err;
      EXPECT_NE(m.out.find("summary (" + method + ")"), std::string::npos) << m.out;
      const MonitorStats s = stats_of(read_jsonl(jsonl), method);
      (rec == "fresh" ? fresh : fault)[method] = s;
      std::printf("%-14s %-6s %-4s windows %zu scored %zu abnormal %zu alarm windows %zu first alarm n %ld "
                  "mean rms %.9g mean entropy %.6f\n",
                  name.c_str(), rec.c_str(), method.c_str(), s.windows, s.scored, s.abnormal, s.alarm_windows,
                  s.first_alarm_n, s.mean_rms, s.mean_entropy);
    }
  }

  // The paper's claims.
  EXPECT_GT(fault["ptda"].alarm_windows, 0U) << "PTDA must raise the alarm on the faulty recording";
  EXPECT_EQ(fresh["ptda"].alarm_windows, 0U) << "PTDA must never alarm on the fresh healthy recording";
  EXPECT_EQ(fresh["ptda"].scored, fresh["ptda"].windows) << "every healthy window belongs to a trained class";
  const double ratio_ptda = fault["ptda"].mean_rms / fresh["ptda"].mean_rms;
  const double ratio_tda = fault["tda"].mean_rms / fresh["tda"].mean_rms;
  const double ratio_raw = fault["raw"].mean_rms / fresh["raw"].mean_rms;
  std::printf("%-14s rms ratio faulty/healthy: raw %.4f tda %.4f ptda %.4f\n", name.c_str(), ratio_raw, ratio_tda,
              ratio_ptda);
  EXPECT_GT(ratio_ptda, ratio_tda);
  EXPECT_GT(ratio_ptda, ratio_raw);
  // TDA, smeared by the phase differences between cycles, flags fewer faulty windows than PTDA. (Raw
  // flags about as many here: the simulated healthy raw signal is very repeatable, so its bands are
  // tight; what raw lacks is the margin, see the RMS ratio above.)
  EXPECT_GT(fault["ptda"].abnormal, fault["tda"].abnormal);

  // Pinned measurements.
  const Pinned& p = job.pinned;
  EXPECT_EQ(fresh["ptda"].windows, p.windows_fresh);
  EXPECT_EQ(fault["ptda"].windows, p.windows_faulty);
  EXPECT_EQ(fault["ptda"].abnormal, p.ptda_abnormal_faulty);
  EXPECT_EQ(fault["tda"].abnormal, p.tda_abnormal_faulty);
  EXPECT_EQ(fault["raw"].abnormal, p.raw_abnormal_faulty);
  EXPECT_EQ(fault["ptda"].first_alarm_n, p.ptda_first_alarm_n);
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
