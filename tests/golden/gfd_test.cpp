// The measured-data study of docs/results-gfd.md through the built `ptda` binary: SpectraQuest gearbox
// (PTDA_SHARED_DIR/data/gfd), healthy h30hz<load> against one broken tooth b30hz<load>, loads 0-80 %,
// accelerometers a1-a4. Per load and channel (as scripts/gfd_study.sh): `ptda import` both files
// (--rate 64500 --shaft-speed 30Hz), `ptda train` on the healthy windows 0:0.5 with
// config/examples/gfd.toml, `ptda monitor` the healthy windows 0.5:1 and every broken-tooth window with
// raw, TDA and PTDA, `ptda evaluate --json`. Pins per load/channel/method the ratios and ROC AUCs of
// both features and the alarms, and the counts behind the claims of docs/results-gfd.md.
// Without the data: GTEST_SKIP naming the path, or a failure when PTDA_REQUIRE_SHARED_DATA=1 (CI).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cstdlib>
#include <map>
#include <string>
#include <vector>

#include "golden_support.hpp"
#include "ptda/cli/evaluate.hpp"

namespace ptda::golden {
namespace {

struct Pinned {
  int load_percent;
  const char* channel;
  const char* method;
  std::size_t scored_healthy, scored_faulty;
  double rms_ratio;
  std::uint64_t rms_twice_u;  ///< 2 U of the Mann-Whitney statistic: AUC = 2U / (2 n_h n_f)
  double entropy_ratio;
  std::uint64_t entropy_twice_u;
  bool alarm_healthy, alarm_faulty;
};

// Measured with this test's commands (= scripts/gfd_study.sh build/h-gfd), ptda built with GCC 12
// (PTDA rows re-pinned in session 5 for the line gain, the default, with scripts/gfd_pins.py from the
// test's own scratch outputs; the raw and TDA rows it printed were unchanged to the last digit)
// (PTDA rows re-pinned in session 6 for the floor gain with the level-referred residual, the default,
// the same way; raw and TDA rows unchanged)
// (alarms re-measured for issue 12's tolerance bands and CUSUM with scripts/gfd_study.sh; the ratios
// and AUCs do not depend on the bands)
// (alarms re-measured in session 7 for the between-day spread, docs/method.md §5-6: one training half,
// so bands 1.044 times wider and the CUSUM allowance k + 3 x 0.3 x sqrt(2) / c_n: 0 % a1 TDA no longer
// alarms on its healthy half; PTDA loses the broken tooth at 20 % a4, 40 % a4, 60 % a3, 80 % a3, TDA at
// 80 % a3; a1 and a2 still alarm at every load)
// (RelWithDebInfo, x86-64), from `ptda evaluate --json`: ratios printed to 9 significant digits, AUCs
// as the integer 2U = AUC * 2 n_h n_f (every AUC here is such a fraction exactly).
// Tolerances: the AUC is a rank statistic, exact given the features; it could only move if a build's
// float32 FFT rounding (~1e-6 relative) swapped a healthy and a faulty value closer than that, so it is
// compared to 1e-6 (i.e. exactly: a swap moves it by at least 1/(2 n_h n_f) > 1e-3). The ratios of
// means carry that rounding, so they are compared to 1e-4 relative, as in paper_jobs_test.cpp.
constexpr Pinned kPinned[] = {
    // load, channel, method, scored healthy/faulty, RMS ratio, RMS 2U, entropy ratio, entropy 2U,
    // alarm healthy, alarm faulty
    {0, "a1", "raw", 11, 21, 0.590304578, 0, 0.938043402, 0, false, true},
    {0, "a1", "tda", 11, 21, 0.632146592, 0, 0.97734476, 46, false, true},
    {0, "a1", "ptda", 11, 21, 2.04511757, 462, 0.956525076, 6, false, true},
    {0, "a2", "raw", 11, 21, 0.937983914, 56, 0.859703612, 0, false, true},
    {0, "a2", "tda", 11, 21, 0.941555669, 66, 0.897791504, 0, false, true},
    {0, "a2", "ptda", 11, 21, 3.11566673, 462, 0.982244423, 70, false, true},
    {0, "a3", "raw", 11, 21, 0.942832295, 68, 0.958603641, 2, false, true},
    {0, "a3", "tda", 11, 21, 0.947283889, 60, 0.966466078, 2, false, true},
    {0, "a3", "ptda", 11, 21, 1.32776005, 462, 0.982474608, 24, false, true},
    {0, "a4", "raw", 11, 21, 0.976548113, 172, 0.972711392, 26, false, false},
    {0, "a4", "tda", 11, 21, 0.972200249, 136, 0.981053649, 60, false, false},
    {0, "a4", "ptda", 11, 21, 1.06265388, 328, 0.987852404, 146, false, true},
    {20, "a1", "raw", 13, 27, 0.62372523, 0, 0.929466893, 0, false, true},
    {20, "a1", "tda", 13, 27, 0.65876641, 0, 0.96350469, 2, false, true},
    {20, "a1", "ptda", 13, 27, 2.25535886, 702, 0.924109866, 2, false, true},
    {20, "a2", "raw", 13, 27, 0.952886541, 110, 0.884942428, 0, false, true},
    {20, "a2", "tda", 13, 27, 0.955132757, 102, 0.914523453, 0, false, true},
    {20, "a2", "ptda", 13, 27, 2.54933595, 702, 1.01917945, 616, false, true},
    {20, "a3", "raw", 13, 27, 0.991531618, 316, 0.959920517, 0, false, true},
    {20, "a3", "tda", 13, 27, 0.986388556, 278, 0.975057445, 38, true, true},
    {20, "a3", "ptda", 13, 27, 1.40015437, 702, 0.975698474, 2, false, true},
    {20, "a4", "raw", 13, 27, 1.00448364, 386, 0.969880888, 80, false, false},
    {20, "a4", "tda", 13, 27, 1.00558261, 400, 0.972220653, 106, false, false},
    {20, "a4", "ptda", 13, 27, 1.12752415, 676, 0.960100345, 6, false, true},
    {40, "a1", "raw", 12, 23, 0.597059432, 0, 0.948319188, 0, false, true},
    {40, "a1", "tda", 12, 23, 0.629345313, 0, 0.984088119, 76, false, false},
    {40, "a1", "ptda", 12, 23, 2.17203561, 552, 0.972542112, 84, false, true},
    {40, "a2", "raw", 12, 23, 0.93916314, 48, 0.912061085, 0, false, true},
    {40, "a2", "tda", 12, 23, 0.93984127, 42, 0.939333016, 0, false, true},
    {40, "a2", "ptda", 12, 23, 2.06832813, 552, 1.03742709, 552, false, true},
    {40, "a3", "raw", 12, 23, 0.912883319, 0, 0.961426136, 0, false, true},
    {40, "a3", "tda", 12, 23, 0.918084443, 2, 0.969029503, 42, false, false},
    {40, "a3", "ptda", 12, 23, 1.2995212, 552, 0.984012045, 52, false, true},
    {40, "a4", "raw", 12, 23, 0.961286238, 122, 0.990006817, 198, false, false},
    {40, "a4", "tda", 12, 23, 0.959564558, 114, 0.995331417, 260, false, false},
    {40, "a4", "ptda", 12, 23, 1.07653947, 404, 0.979817092, 126, false, true},
    {60, "a1", "raw", 12, 23, 0.623057248, 0, 0.917009367, 0, false, true},
    {60, "a1", "tda", 12, 23, 0.667353206, 0, 0.958969837, 4, false, true},
    {60, "a1", "ptda", 12, 23, 2.1696797, 552, 0.938054086, 22, false, true},
    {60, "a2", "raw", 12, 23, 0.990926927, 200, 0.932312054, 0, false, true},
    {60, "a2", "tda", 12, 23, 0.995870029, 238, 0.945878904, 2, false, true},
    {60, "a2", "ptda", 12, 23, 1.79446452, 552, 1.04181163, 552, false, true},
    {60, "a3", "raw", 12, 23, 0.913757581, 0, 0.955588528, 0, false, true},
    {60, "a3", "tda", 12, 23, 0.927758651, 10, 0.956065116, 0, false, true},
    {60, "a3", "ptda", 12, 23, 1.24368933, 552, 0.982366018, 72, false, true},
    {60, "a4", "raw", 12, 23, 0.952311096, 66, 0.994528908, 222, false, false},
    {60, "a4", "tda", 12, 23, 0.969494709, 130, 0.983133177, 122, false, false},
    {60, "a4", "ptda", 12, 23, 1.05929618, 398, 0.992747386, 248, false, true},
    {80, "a1", "raw", 12, 26, 0.639110198, 0, 0.906467271, 0, false, true},
    {80, "a1", "tda", 12, 26, 0.669548553, 0, 0.956459631, 16, false, true},
    {80, "a1", "ptda", 12, 26, 2.2329911, 624, 0.930141759, 18, false, true},
    {80, "a2", "raw", 12, 26, 1.05713009, 602, 0.95341701, 0, false, true},
    {80, "a2", "tda", 12, 26, 1.05176399, 596, 0.966796306, 0, false, true},
    {80, "a2", "ptda", 12, 26, 1.74274993, 624, 1.01679832, 566, false, true},
    {80, "a3", "raw", 12, 26, 0.922632386, 24, 0.946550715, 0, false, true},
    {80, "a3", "tda", 12, 26, 0.924970444, 40, 0.95839854, 38, false, false},
    {80, "a3", "ptda", 12, 26, 1.31686459, 624, 0.975899909, 64, false, true},
    {80, "a4", "raw", 12, 26, 0.976255059, 178, 0.996396334, 262, false, false},
    {80, "a4", "tda", 12, 26, 0.964971483, 176, 1.01321256, 376, false, false},
    {80, "a4", "ptda", 12, 26, 1.15110054, 518, 0.963508707, 120, false, true},
};

constexpr std::array<int, 5> kLoads = {0, 20, 40, 60, 80};
constexpr std::array<const char*, 4> kChannels = {"a1", "a2", "a3", "a4"};
constexpr std::array<const char*, 3> kMethods = {"raw", "tda", "ptda"};
// The rate is assumed (--rate 64500): the data set does not state it (README). The windows are counted
// in samples, so the features do not depend on it; only the speed labels do.

fs::path data_dir() {
  return fs::path(PTDA_SHARED_DIR) / "data" / "gfd";
}

// Brute-force Mann-Whitney 2U over all pairs, independent of ptda evaluate's sorted counting.
std::uint64_t brute_twice_u(const std::vector<double>& h, const std::vector<double>& f) {
  std::uint64_t u = 0;
  for (const double x : f) {
    for (const double y : h) u += x > y ? 2 : (x == y ? 1 : 0);
  }
  return u;
}

std::vector<double> scored_feature(const std::vector<cli::JsonValue>& rows, const char* key) {
  std::vector<double> v;
  for (const auto& r : rows) {
    if (r.at("status").as_string() == "scored") v.push_back(r.at(key).as_number());
  }
  return v;
}

double separability(double auc) {
  return std::max(auc, 1.0 - auc);
}

struct Measured {
  cli::Evaluation e;
  std::uint64_t rms_twice_u = 0, entropy_twice_u = 0;
};

class GfdStudy : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!fs::is_directory(data_dir())) return;
    // Per process: ctest runs this suite's tests as parallel processes, each with its own SetUpTestSuite.
    const fs::path dir = scratch_dir("gfd_" + std::to_string(::getpid()));
    const std::string config = (source_dir() / "config/examples/gfd.toml").string();
    for (const int load : kLoads) {
      for (const char* ch : kChannels) {
        const std::string key = std::to_string(load) + "_" + ch;
        const fs::path c = dir / key;
        fs::create_directories(c);
        const auto run = [&](const std::vector<std::string>& args, const std::string& tag) {
          const RunResult r = run_ptda(args, c, tag);
          ASSERT_EQ(r.exit_code, 0) << key << " " << tag << ": " << r.err;
        };
        for (const char* cond : {"h", "b"}) {
          run({"import", "--csv",
               (data_dir() / (std::string(cond) + "30hz" + std::to_string(load) + ".csv.gz")).string(),
               "--column", ch, "--rate", "64500", "--shaft-speed", "30Hz", "--out", (c / cond).string()},
              std::string("import_") + cond);
        }
        run({"train", "--recording", (c / "h").string(), "--config", config, "--out",
             (c / "base.bin").string(), "--windows", "0:0.5"},
            "train");
        for (const char* m : kMethods) {
          const std::string hj = (c / (std::string("h.") + m + ".jsonl")).string();
          const std::string bj = (c / (std::string("b.") + m + ".jsonl")).string();
          const std::string ej = (c / (std::string("eval.") + m + ".json")).string();
          run({"monitor", "--recording", (c / "h").string(), "--config", config, "--baseline",
               (c / "base.bin").string(), "--method", m, "--windows", "0.5:1", "--quiet", "--jsonl", hj},
              std::string("monitor_h_") + m);
          run({"monitor", "--recording", (c / "b").string(), "--config", config, "--baseline",
               (c / "base.bin").string(), "--method", m, "--quiet", "--jsonl", bj},
              std::string("monitor_b_") + m);
          run({"evaluate", "--healthy", hj, "--faulty", bj, "--json", ej, "--label",
               std::to_string(load) + " %, " + ch, "--x", std::to_string(load)},
              std::string("evaluate_") + m);
          Measured meas;
          std::string text = read_file(ej);
          if (!text.empty() && text.back() == '\n') text.pop_back();
          meas.e = cli::parse_evaluation_json(text, ej);
          const auto hrows = read_jsonl(hj);
          const auto brows = read_jsonl(bj);
          meas.rms_twice_u =
              brute_twice_u(scored_feature(hrows, "rms_res"), scored_feature(brows, "rms_res"));
          meas.entropy_twice_u =
              brute_twice_u(scored_feature(hrows, "entropy_res"), scored_feature(brows, "entropy_res"));
          results_[key + "_" + m] = meas;
        }
      }
    }
  }

  void SetUp() override {
    if (!fs::is_directory(data_dir())) {
      const char* req = std::getenv("PTDA_REQUIRE_SHARED_DATA");
      if (req != nullptr && std::string(req) == "1") {
        FAIL() << "PTDA_REQUIRE_SHARED_DATA=1 but the GFD data directory " << data_dir() << " is missing";
      }
      GTEST_SKIP() << "GFD data directory " << data_dir()
                   << " not found (set PTDA_REQUIRE_SHARED_DATA=1 to fail)";
    }
    ASSERT_EQ(results_.size(), kLoads.size() * kChannels.size() * kMethods.size())
        << "the study did not complete";
  }

  static const Measured& get(int load, const char* ch, const char* m) {
    return results_.at(std::to_string(load) + "_" + ch + "_" + m);
  }

  static std::map<std::string, Measured> results_;
};

std::map<std::string, Measured> GfdStudy::results_;

TEST_F(GfdStudy, PinnedRatiosAndAucs) {
  ASSERT_EQ(std::size(kPinned), results_.size());
  for (const auto& p : kPinned) {
    SCOPED_TRACE(std::to_string(p.load_percent) + " % " + p.channel + " " + p.method);
    const Measured& m = get(p.load_percent, p.channel, p.method);
    const cli::Evaluation& e = m.e;
    EXPECT_EQ(e.method, p.method);
    EXPECT_EQ(e.healthy.scored, p.scored_healthy);
    EXPECT_EQ(e.faulty.scored, p.scored_faulty);
    EXPECT_EQ(e.healthy.windows, e.healthy.scored);  // one class: every window is scored
    EXPECT_EQ(e.faulty.windows, e.faulty.scored);
    const double pairs2 = 2.0 * static_cast<double>(p.scored_healthy * p.scored_faulty);
    EXPECT_NEAR(e.features[0].auc, static_cast<double>(p.rms_twice_u) / pairs2, 1e-6);
    EXPECT_NEAR(e.features[1].auc, static_cast<double>(p.entropy_twice_u) / pairs2, 1e-6);
    // ptda evaluate's AUC equals the brute-force pair count over the monitor JSONL.
    EXPECT_EQ(e.features[0].auc, static_cast<double>(m.rms_twice_u) / pairs2);
    EXPECT_EQ(e.features[1].auc, static_cast<double>(m.entropy_twice_u) / pairs2);
    EXPECT_NEAR(e.features[0].ratio, p.rms_ratio, 1e-4 * p.rms_ratio);
    EXPECT_NEAR(e.features[1].ratio, p.entropy_ratio, 1e-4 * p.entropy_ratio);
    EXPECT_EQ(e.healthy.alarm(), p.alarm_healthy);
    EXPECT_EQ(e.faulty.alarm(), p.alarm_faulty);
  }
}

// The counts of the summary table in docs/results-gfd.md (also printed by scripts/gfd_study.sh).
TEST_F(GfdStudy, SummaryClaims) {
  int ptda_rms_auc_best = 0, ptda_rms_sep_best = 0, ptda_ent_auc_best = 0, ptda_ent_sep_best = 0;
  std::map<std::string, int> rms_higher, rms_auc_09, rms_sep_09, ent_sep_09, clean_alarm;
  for (const int load : kLoads) {
    for (const char* ch : kChannels) {
      const auto& raw = get(load, ch, "raw").e.features;
      const auto& tda = get(load, ch, "tda").e.features;
      const auto& ptda = get(load, ch, "ptda").e.features;
      if (ptda[0].auc >= tda[0].auc && ptda[0].auc >= raw[0].auc) ++ptda_rms_auc_best;
      if (ptda[0].separability >= tda[0].separability && ptda[0].separability >= raw[0].separability) {
        ++ptda_rms_sep_best;
      }
      if (ptda[1].auc >= tda[1].auc && ptda[1].auc >= raw[1].auc) ++ptda_ent_auc_best;
      if (ptda[1].separability >= tda[1].separability && ptda[1].separability >= raw[1].separability) {
        ++ptda_ent_sep_best;
      }
      for (const char* m : kMethods) {
        const cli::Evaluation& e = get(load, ch, m).e;
        EXPECT_EQ(e.features[0].separability, separability(e.features[0].auc));
        if (e.features[0].auc > 0.5) ++rms_higher[m];
        if (e.features[0].auc >= 0.9) ++rms_auc_09[m];
        if (e.features[0].separability >= 0.9) ++rms_sep_09[m];
        if (e.features[1].separability >= 0.9) ++ent_sep_09[m];
        if (!e.healthy.alarm() && e.faulty.alarm()) ++clean_alarm[m];
      }
    }
  }
  // PTDA's residual RMS is higher on the broken tooth in every pair, and its AUC is never below raw's
  // or TDA's; raw and TDA RMS mostly *drop* on the broken-tooth file.
  EXPECT_EQ(ptda_rms_auc_best, 20);
  EXPECT_EQ(rms_higher["raw"], 2);
  EXPECT_EQ(rms_higher["tda"], 2);
  // With the floor gain and level-referred residual (the default since session 6) PTDA's RMS is higher
  // on the broken tooth in all 20 pairs (line gain alone: 18, the paper's PTDA: 20).
  EXPECT_EQ(rms_higher["ptda"], 20);
  EXPECT_EQ(rms_auc_09["raw"], 1);
  EXPECT_EQ(rms_auc_09["tda"], 1);
  EXPECT_EQ(rms_auc_09["ptda"], 16);  // line gain alone: 15
  // Counting separation either way, PTDA's RMS is best or tied in 18 of 20 pairs (line gain alone: 15).
  EXPECT_EQ(ptda_rms_sep_best, 18);
  EXPECT_EQ(rms_sep_09["raw"], 10);
  EXPECT_EQ(rms_sep_09["tda"], 10);
  EXPECT_EQ(rms_sep_09["ptda"], 16);  // line gain alone: 15
  // Entropy: raw's (lower on the broken tooth) separates better than PTDA's.
  // The level-referred entropy is lower on the broken tooth in most pairs now (line gain alone: higher).
  EXPECT_EQ(ptda_ent_auc_best, 15);  // line gain alone: 16, paper's PTDA: 15
  EXPECT_EQ(ptda_ent_sep_best, 5);   // line gain alone: 7
  EXPECT_EQ(ent_sep_09["raw"], 16);
  EXPECT_EQ(ent_sep_09["tda"], 14);
  EXPECT_EQ(ent_sep_09["ptda"], 11);  // line gain alone: 13, paper's PTDA: 8
  // With the trained bands, the 3-of-5 alarm and the CUSUM: alarm on the broken tooth and none on the
  // held-out healthy half. Re-pinned for tolerance bands + CUSUM (issue 12; before: Gaussian bands,
  // k-of-n only: raw 15, TDA 14, PTDA 14). PTDA gains 60 % a3 (the CUSUM accumulates its 21.7 %
  // abnormal windows); TDA's wider tolerance bands lose 20 % a4, 40 % a1 and 40 % a3.
  EXPECT_EQ(clean_alarm["raw"], 15);
  EXPECT_EQ(clean_alarm["tda"], 11);
  // Line gain: 14 (the paper's PTDA 15). It no longer alarms on the healthy half of 40 % a1 and on the
  // broken tooth of 0 % a4 (AUCs 0.42/0.40: no separation) and 60 % a3; it gains 40 % a1.
  // Floor gain, level-referred (session 6): 17; it gains a3 at 60 and 80 % and a4 at 40 %.
  // Between-day allowance (session 7): 13; it loses a4 at 20 and 40 %, a3 at 60 and 80 %.
  // Session 13: the band CUSUM is on by default; it alarms on the broken tooth in all 20 pairs and on no
  // healthy half (k-of-n and the feature CUSUM alone: 13 of 20; docs/results-gfd.md).
  EXPECT_EQ(clean_alarm["ptda"], 20);
}

// a4 is the hard channel: no method reaches an RMS separability of 0.9 at any load, except PTDA with
// the level-referred residual at 20 % (AUC 676/702 = 0.963; line gain alone 482/702 = 0.687).
TEST_F(GfdStudy, ChannelA4IsTheHardOne) {
  for (const int load : kLoads) {
    for (const char* m : kMethods) {
      if (load == 20 && std::string(m) == "ptda") {
        EXPECT_GT(get(load, "a4", m).e.features[0].separability, 0.9);
        continue;
      }
      EXPECT_LT(get(load, "a4", m).e.features[0].separability, 0.9) << load << " % " << m;
    }
  }
}

}  // namespace
}  // namespace ptda::golden
