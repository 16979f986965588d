// `ptda evaluate`: the Mann-Whitney ROC AUC (hand-computed cases with ties and perfect separation),
// reading monitor JSONL written by window_json, the evaluation of two sets, its JSON round trip, the
// markdown row, the AUC plot and every error (missing file, malformed line, no scored windows...).
#include "ptda/cli/evaluate.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "ptda/cli/args.hpp"
#include "ptda/cli/commands.hpp"
#include "ptda/cli/monitor_output.hpp"
#include "ptda/common/error.hpp"

namespace ptda::cli {
namespace {

namespace fs = std::filesystem;

fs::path scratch(const std::string& name) {
  const char* env = std::getenv("PTDA_TEST_TMP");
  const fs::path base = env != nullptr ? fs::path(env) : fs::temp_directory_path();
  const fs::path dir = base / "cli_evaluate" / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

fs::path write_text(const fs::path& p, const std::string& text) {
  std::ofstream f(p, std::ios::binary);
  f << text;
  return p;
}

// A monitor line as `ptda monitor --jsonl` writes it.
std::string line(std::uint64_t n, double rms, double entropy, bool abnormal, bool alarm,
                 dsp::Method method = dsp::Method::kPtda) {
  dsp::WindowResult w;
  w.ref.seq = n;
  w.ref.t_start_ns = static_cast<std::int64_t>(n) * 1'000'000;
  w.ref.t_end_ns = w.ref.t_start_ns + 1'000'000;
  w.status = dsp::WindowStatus::kScored;
  w.class_id = 0;
  w.features.rms_res = rms;
  w.features.entropy_res = entropy;
  w.thresholds.rms = {0.0, 10.0};
  w.thresholds.entropy = {0.0, 1.0};
  w.verdict.rms_out = abnormal;
  w.alarm = alarm;
  return window_json(w, method) + "\n";
}

std::string no_class_line(std::uint64_t n) {
  dsp::WindowResult w;
  w.ref.seq = n;
  w.status = dsp::WindowStatus::kNoClass;
  return window_json(w, dsp::Method::kPtda) + "\n";
}

std::string error_of(const auto& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

// ---- roc_auc -------------------------------------------------------------------------------------------

TEST(RocAuc, PerfectSeparationEitherWay) {
  const std::vector<double> lo = {1.0, 2.0, 2.5};
  const std::vector<double> hi = {3.0, 4.0};
  EXPECT_EQ(roc_auc(lo, hi), 1.0);  // every faulty value above every healthy one
  EXPECT_EQ(roc_auc(hi, lo), 0.0);  // every faulty value below
}

TEST(RocAuc, HandComputedWithoutTies) {
  // healthy {0.1, 0.35, 0.4, 0.8}, faulty {0.3, 0.9}: 0.3 beats 1 healthy value, 0.9 beats 4:
  // U = 5 of 4 * 2 = 8 pairs -> 0.625.
  EXPECT_EQ(roc_auc(std::vector<double>{0.1, 0.4, 0.35, 0.8}, std::vector<double>{0.3, 0.9}), 0.625);
}

TEST(RocAuc, TiesCountOneHalf) {
  // healthy {1, 2, 3}, faulty {2, 3, 4}: faulty 2 beats 1 and ties 1 (1.5), 3 beats 2 and ties 1
  // (2.5), 4 beats 3 (3): U = 7 of 9 pairs.
  EXPECT_EQ(roc_auc(std::vector<double>{1, 2, 3}, std::vector<double>{2, 3, 4}), 7.0 / 9.0);
  // All equal: every pair is a tie -> 1/2.
  EXPECT_EQ(roc_auc(std::vector<double>{5, 5}, std::vector<double>{5, 5, 5}), 0.5);
  // Duplicates inside one set: healthy {1, 1, 2}, faulty {1}: ties with two 1s, below 2: U = 1 of 3.
  EXPECT_EQ(roc_auc(std::vector<double>{1, 1, 2}, std::vector<double>{1}), 1.0 / 3.0);
}

TEST(RocAuc, SymmetricUnderSwap) {
  const std::vector<double> a = {0.3, 1.2, 0.7, 0.7, 2.0};
  const std::vector<double> b = {0.7, 0.1, 1.5};
  EXPECT_DOUBLE_EQ(roc_auc(a, b) + roc_auc(b, a), 1.0);
  // Hand count for faulty = b: 0.7 beats 0.3, ties two 0.7 (2); 0.1 beats none (0); 1.5 beats
  // 0.3, 0.7, 0.7, 1.2 (4): U = 6 of 15.
  EXPECT_EQ(roc_auc(a, b), 6.0 / 15.0);
}

TEST(RocAuc, RejectsEmptyAndNaN) {
  const std::vector<double> one = {1.0};
  const std::vector<double> none;
  const std::vector<double> nan = {std::numeric_limits<double>::quiet_NaN()};
  EXPECT_NE(error_of([&] { (void)roc_auc(none, one); }).find("at least one"), std::string::npos);
  EXPECT_NE(error_of([&] { (void)roc_auc(one, none); }).find("at least one"), std::string::npos);
  EXPECT_NE(error_of([&] { (void)roc_auc(nan, one); }).find("healthy value is NaN"), std::string::npos);
  EXPECT_NE(error_of([&] { (void)roc_auc(one, nan); }).find("faulty value is NaN"), std::string::npos);
}

// ---- reading JSONL and evaluating ---------------------------------------------------------------------

TEST(ReadMonitorJsonl, KeepsScoredWindowsAndCounts) {
  const fs::path dir = scratch("read");
  const fs::path p =
      write_text(dir / "h.jsonl", line(0, 1.0, 0.9, false, false) + no_class_line(1) + "\n" +
                                      line(2, 2.0, 0.8, true, false) + line(3, 3.0, 0.7, true, true));
  MonitorWindows w;
  read_monitor_jsonl(p.string(), w);
  EXPECT_EQ(w.method, "ptda");
  EXPECT_EQ(w.windows, 4u);  // the blank line is skipped, the no_class window counted but not scored
  EXPECT_EQ(w.scored(), 3u);
  EXPECT_EQ(w.rms_res, (std::vector<double>{1.0, 2.0, 3.0}));
  EXPECT_EQ(w.entropy_res, (std::vector<double>{0.9, 0.8, 0.7}));
  EXPECT_EQ(w.abnormal, 2u);
  EXPECT_EQ(w.alarm_windows, 1u);
  // A second file appends.
  read_monitor_jsonl(p.string(), w);
  EXPECT_EQ(w.scored(), 6u);
}

TEST(ReadMonitorJsonl, ErrorsNameFileAndLine) {
  const fs::path dir = scratch("errors");
  MonitorWindows w;
  const std::string missing = (dir / "missing.jsonl").string();
  EXPECT_EQ(error_of([&] { read_monitor_jsonl(missing, w); }), missing + ": cannot open");

  const fs::path bad = write_text(dir / "bad.jsonl", line(0, 1.0, 0.9, false, false) + "{\"n\":1,\n");
  const std::string e1 = error_of([&] {
    MonitorWindows x;
    read_monitor_jsonl(bad.string(), x);
  });
  EXPECT_EQ(e1.rfind(bad.string() + ":2: column ", 0), 0u) << e1;

  const fs::path no_status = write_text(dir / "no_status.jsonl", "{\"method\":\"ptda\"}\n");
  EXPECT_EQ(error_of([&] {
              MonitorWindows x;
              read_monitor_jsonl(no_status.string(), x);
            }),
            no_status.string() + ":1: missing field \"status\"");

  const fs::path not_obj = write_text(dir / "array.jsonl", "[1,2]\n");
  EXPECT_EQ(error_of([&] {
              MonitorWindows x;
              read_monitor_jsonl(not_obj.string(), x);
            }),
            not_obj.string() + ":1: not a JSON object");

  // A scored window whose feature was NaN (written as null).
  const fs::path nan_rms =
      write_text(dir / "nan.jsonl", line(0, std::numeric_limits<double>::quiet_NaN(), 0.9, true, false));
  EXPECT_EQ(error_of([&] {
              MonitorWindows x;
              read_monitor_jsonl(nan_rms.string(), x);
            }),
            nan_rms.string() + ":1: scored window without a finite \"rms_res\"");

  const fs::path mixed =
      write_text(dir / "mixed.jsonl",
                 line(0, 1.0, 0.9, false, false) + line(1, 1.0, 0.9, false, false, dsp::Method::kTda));
  EXPECT_EQ(error_of([&] {
              MonitorWindows x;
              read_monitor_jsonl(mixed.string(), x);
            }),
            mixed.string() +
                ":2: method \"tda\" differs from \"ptda\" of the windows read before (evaluate one "
                "method at a time)");
}

TEST(EvaluateSeparation, HandComputedCase) {
  MonitorWindows h;
  h.method = "ptda";
  h.windows = 5;
  h.rms_res = {1.0, 2.0, 3.0, 2.0};
  h.entropy_res = {0.9, 0.8, 0.85, 0.95};
  h.abnormal = 1;
  MonitorWindows f;
  f.method = "ptda";
  f.windows = 3;
  f.rms_res = {2.0, 5.0, 6.0};
  f.entropy_res = {0.7, 0.9, 0.6};
  f.abnormal = 3;
  f.alarm_windows = 1;
  const Evaluation e = evaluate_separation(h, f, "h.jsonl", "f.jsonl");
  EXPECT_EQ(e.method, "ptda");
  EXPECT_EQ(e.healthy.windows, 5u);
  EXPECT_EQ(e.healthy.scored, 4u);
  EXPECT_EQ(e.healthy.detection_rate(), 0.25);
  EXPECT_FALSE(e.healthy.alarm());
  EXPECT_EQ(e.faulty.detection_rate(), 1.0);
  EXPECT_TRUE(e.faulty.alarm());
  const FeatureSeparation& rms = e.features[0];
  EXPECT_EQ(rms.feature, "rms_res");
  EXPECT_EQ(rms.mean_healthy, 2.0);
  EXPECT_EQ(rms.mean_faulty, 13.0 / 3.0);
  EXPECT_EQ(rms.ratio, (13.0 / 3.0) / 2.0);
  // faulty 2 beats 1, ties two 2s (2); 5 and 6 beat all 4 (8): U = 10 of 12.
  EXPECT_EQ(rms.auc, 10.0 / 12.0);
  EXPECT_EQ(rms.separability, 10.0 / 12.0);
  EXPECT_EQ(rms.direction, Direction::kHigher);
  const FeatureSeparation& ent = e.features[1];
  EXPECT_EQ(ent.feature, "entropy_res");
  // faulty 0.7 beats none; 0.9 beats 0.8, 0.85 and ties 0.9 (2.5); 0.6 none: U = 2.5 of 12.
  EXPECT_EQ(ent.auc, 2.5 / 12.0);
  EXPECT_EQ(ent.separability, 1.0 - 2.5 / 12.0);
  EXPECT_EQ(ent.direction, Direction::kLower);
  EXPECT_STREQ(direction_name(ent.direction), "lower");
}

TEST(EvaluateSeparation, ErrorsNameTheFiles) {
  MonitorWindows scored;
  scored.method = "ptda";
  scored.windows = 1;
  scored.rms_res = {1.0};
  scored.entropy_res = {0.5};
  MonitorWindows empty;
  empty.method = "ptda";
  empty.windows = 2;
  EXPECT_EQ(error_of([&] { (void)evaluate_separation(empty, scored, "h.jsonl", "f.jsonl"); }),
            "h.jsonl: no scored windows in the healthy set (2 windows read)");
  EXPECT_EQ(error_of([&] { (void)evaluate_separation(scored, empty, "h.jsonl", "f.jsonl"); }),
            "f.jsonl: no scored windows in the faulty set (2 windows read)");
  MonitorWindows raw = scored;
  raw.method = "raw";
  EXPECT_EQ(error_of([&] { (void)evaluate_separation(scored, raw, "h.jsonl", "f.jsonl"); }),
            "method mismatch: h.jsonl holds \"ptda\" windows but f.jsonl holds \"raw\"");
}

// ---- the command
// -------------------------------------------------------------------------------------------

struct Files {
  fs::path healthy, faulty;
};

Files write_case(const std::string& name) {
  const fs::path dir = scratch(name);
  // healthy rms {1, 2, 3}, faulty {2.5, 4}: U = 2 + 3 = 5 of 6; entropy healthy {0.9, 0.8, 0.85},
  // faulty {0.8, 0.5}: 0.8 ties one (0.5), 0.5 none: U = 0.5 of 6.
  Files f;
  f.healthy = write_text(dir / "h.jsonl", line(0, 1.0, 0.9, false, false) + line(1, 2.0, 0.8, false, false) +
                                              line(2, 3.0, 0.85, true, false));
  f.faulty = write_text(dir / "f.jsonl",
                        no_class_line(0) + line(1, 2.5, 0.8, true, false) + line(2, 4.0, 0.5, true, true));
  return f;
}

int run(const std::vector<std::string>& args, std::string& out) {
  std::ostringstream s;
  const int rc = cmd_evaluate(args, s);
  out = s.str();
  return rc;
}

TEST(CmdEvaluate, TextJsonAndMarkdown) {
  const Files f = write_case("cmd");
  std::string out;
  ASSERT_EQ(run({"--healthy", f.healthy.string(), "--faulty", f.faulty.string()}, out), kExitOk);
  EXPECT_EQ(
      out,
      "evaluate (ptda): healthy 3 scored of 3 windows, faulty 2 scored of 3\n"
      "  rms_res     mean healthy 2, faulty 3.25, ratio 1.625, AUC 0.8333 (separability 0.8333, faulty "
      "higher)\n"
      "  entropy_res mean healthy 0.85, faulty 0.65, ratio 0.76471, AUC 0.0833 (separability 0.9167, faulty "
      "lower)\n"
      "  healthy     abnormal 1 of 3 (33.3 %), alarm never raised\n"
      "  faulty      abnormal 2 of 2 (100.0 %), alarm raised in 1 windows\n");

  const fs::path json = f.healthy.parent_path() / "eval.json";
  ASSERT_EQ(run({"--healthy", f.healthy.string(), "--faulty", f.faulty.string(), "--json", json.string(),
                 "--markdown", "--label", "0 %, a1", "--x", "20"},
                out),
            kExitOk);
  EXPECT_EQ(
      out,
      evaluation_markdown_header() +
          "| 0 %, a1 | ptda | 3 / 2 | 1.6250 | 0.833 | 0.7647 | 0.083 | 33.3 % | 100.0 % | no / yes |\n");
  std::ifstream in(json);
  std::string text;
  std::getline(in, text);
  const Evaluation e = parse_evaluation_json(text, json.string());
  EXPECT_EQ(e.label, "0 %, a1");
  ASSERT_TRUE(e.x.has_value());
  EXPECT_EQ(*e.x, 20.0);
  EXPECT_EQ(e.method, "ptda");
  EXPECT_EQ(e.healthy.scored, 3u);
  EXPECT_EQ(e.faulty.windows, 3u);
  EXPECT_EQ(e.faulty.alarm_windows, 1u);
  EXPECT_EQ(e.features[0].auc, 5.0 / 6.0);
  EXPECT_EQ(e.features[0].ratio, 3.25 / 2.0);
  EXPECT_EQ(e.features[1].auc, 0.5 / 6.0);
  EXPECT_EQ(e.features[1].mean_faulty, 0.65);
  EXPECT_EQ(e.features[1].direction, Direction::kLower);

  ASSERT_EQ(
      run({"--healthy", f.healthy.string(), "--faulty", f.faulty.string(), "--markdown", "--no-header"}, out),
      kExitOk);
  EXPECT_EQ(out, "|  | ptda | 3 / 2 | 1.6250 | 0.833 | 0.7647 | 0.083 | 33.3 % | 100.0 % | no / yes |\n");
}

TEST(CmdEvaluate, PoolsRepeatedFiles) {
  const Files f = write_case("pool");
  std::string out;
  const fs::path json = f.healthy.parent_path() / "pooled.json";
  ASSERT_EQ(run({"--healthy", f.healthy.string(), "--healthy", f.healthy.string(), "--faulty",
                 f.faulty.string(), "--json", json.string()},
                out),
            kExitOk);
  std::ifstream in(json);
  std::string text;
  std::getline(in, text);
  const Evaluation e = parse_evaluation_json(text, json.string());
  EXPECT_EQ(e.healthy.scored, 6u);
  EXPECT_EQ(e.features[0].auc, 10.0 / 12.0);  // every pair counted twice: same AUC
}

TEST(CmdEvaluate, UsageAndDataErrors) {
  const Files f = write_case("cmd_errors");
  std::string out;
  EXPECT_THROW(run({"--healthy", f.healthy.string()}, out), UsageError);
  EXPECT_THROW(run({"--faulty", f.faulty.string()}, out), UsageError);
  EXPECT_THROW(run({"--healthy", f.healthy.string(), "--faulty", f.faulty.string(), "--no-header"}, out),
               UsageError);
  EXPECT_THROW(run({"--healthy", f.healthy.string(), "--faulty", f.faulty.string(), "--x", "abc"}, out),
               UsageError);
  const fs::path only_no_class = write_text(f.healthy.parent_path() / "nc.jsonl", no_class_line(0));
  EXPECT_EQ(error_of([&] {
              run({"--healthy", only_no_class.string(), "--faulty", f.faulty.string()}, out);
            }),
            only_no_class.string() + ": no scored windows in the healthy set (1 windows read)");
}

TEST(CmdEvaluate, PlotsAucAgainstX) {
  const Files f = write_case("plot");
  const fs::path dir = f.healthy.parent_path();
  std::string out;
  const fs::path results = dir / "results.jsonl";
  for (const char* x : {"0", "40"}) {
    ASSERT_EQ(run({"--healthy", f.healthy.string(), "--faulty", f.faulty.string(), "--json",
                   (dir / (std::string("r") + x + ".json")).string(), "--x", x},
                  out),
              kExitOk);
  }
  {
    std::ofstream r(results, std::ios::binary);
    r << std::ifstream(dir / "r0.json").rdbuf() << std::ifstream(dir / "r40.json").rdbuf();
  }
  const fs::path svg = dir / "auc.svg";
  ASSERT_EQ(run({"--plot", svg.string(), "--results", results.string(), "--title", "AUC & more", "--x-label",
                 "load [%]"},
                out),
            kExitOk);
  EXPECT_EQ(out, "wrote " + svg.string() + " (2 results)\n");
  std::ifstream in(svg);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(text.rfind("<svg xmlns=\"http://www.w3.org/2000/svg\"", 0), 0u);
  EXPECT_NE(text.find("AUC &amp; more"), std::string::npos);
  EXPECT_NE(text.find("PTDA"), std::string::npos);
  EXPECT_NE(text.find("rms_res ROC AUC"), std::string::npos);
  EXPECT_EQ(text.find(">TDA<"), std::string::npos);  // only the methods present are drawn

  // A result without x cannot be placed.
  Evaluation no_x;
  no_x.label = "case";
  no_x.method = "raw";
  EXPECT_EQ(error_of([&] { (void)auc_plot_svg(std::span<const Evaluation>(&no_x, 1), "rms_res", "t", "x"); }),
            "AUC plot: result 'case' (raw) has no x value");
  EXPECT_EQ(
      error_of([&] { (void)auc_plot_svg(std::span<const Evaluation>(&no_x, 1), "kurtosis", "t", "x"); }),
      "AUC plot: unknown feature 'kurtosis' (rms_res or entropy_res)");
  EXPECT_THROW(run({"--plot", svg.string()}, out), UsageError);
  const fs::path bad = write_text(dir / "bad.json", "{\"label\":\"a\"}\n");
  EXPECT_EQ(error_of([&] {
              run({"--plot", svg.string(), "--results", bad.string()}, out);
            }),
            bad.string() + ":1: missing field \"x\"");
}

}  // namespace
}  // namespace ptda::cli
