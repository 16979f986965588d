// Smoke test of the gap-bench corpora (docs/gap.md "Bench"): one short case of the second, independently
// written generator (tests/gen2, Python 3 + NumPy from scripts/bootstrap.sh) is generated, loaded and
// scored by `ptda gap-bench --corpus`; and broken corpus manifests/truth files are clear errors. The
// diagnosis outcome itself is not pinned here (the gap method is being reworked against these corpora;
// the benches with their numbers are in docs/gap.md): the test checks that the case loads, runs without
// error, and that its score is consistent with what was named.
#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>

#include "golden_support.hpp"

namespace ptda::golden {
namespace {

// Debian's interpreter (scripts/bootstrap.sh installs python3-numpy for it); PTDA_PYTHON overrides.
std::string python() {
  if (const char* p = std::getenv("PTDA_PYTHON"); p != nullptr && *p != '\0') return p;
  if (fs::exists("/usr/bin/python3")) return "/usr/bin/python3";
  return "python3";
}

int run_shell(const std::string& cmd) {
  const int status = std::system(cmd.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

void write(const fs::path& p, const std::string& text) {
  fs::create_directories(p.parent_path());
  std::ofstream f(p, std::ios::binary | std::ios::trunc);
  f << text;
}

TEST(GapCorpus, ShortGen2CaseLoadsAndIsScored) {
  const fs::path dir = scratch_dir("gap_corpus_gen2");
  const fs::path corpus = dir / "corpus";
  ASSERT_EQ(run_shell(shell_quote(python()) + " -c 'import numpy' 2>/dev/null"), 0)
      << python() << " has no numpy: run scripts/bootstrap.sh (python3-numpy)";
  // Development seed 1005: a 20480 Hz machine, back-and-forth program; 2 program cycles (--short).
  const std::string gen =
      shell_quote(python()) + " " + shell_quote((source_dir() / "tests/gen2/make_corpus.py").string()) +
      " gen2 --seeds 1005 --kinds electrical_interference --short --out " + shell_quote(corpus.string()) +
      " >" + shell_quote((dir / "gen.out").string()) + " 2>&1";
  ASSERT_EQ(run_shell(gen), 0) << read_file(dir / "gen.out");
  const cli::JsonValue truth = cli::parse_json(read_file(corpus / "gen2-1005/truth.json"), "truth.json");
  ASSERT_EQ(truth.at("category").as_string(), "effect");
  const double mains_hz = truth.at("effects").array.at(0).at("params").at("frequency_hz").as_number();
  EXPECT_TRUE(mains_hz == 50.0 || mains_hz == 60.0) << mains_hz;

  const RunResult r = run_ptda({"gap-bench", "--corpus", corpus.string(), "--threads", "2", "--json",
                                (dir / "bench.json").string(), "--markdown", (dir / "bench.md").string()},
                               dir, "bench");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const cli::JsonValue j = cli::parse_json(read_file(dir / "bench.json"), "bench.json");
  EXPECT_EQ(j.at("format").as_string(), "ptda-gap-bench");
  EXPECT_EQ(j.at("corpus").as_string(), "gen2");
  EXPECT_EQ(j.at("effect_cases").as_number(), 1.0);
  EXPECT_EQ(j.at("none_cases").as_number(), 0.0);
  EXPECT_EQ(j.at("errors").as_number(), 0.0);
  const auto& cases = j.at("cases").array;
  ASSERT_EQ(cases.size(), 1U);
  const cli::JsonValue& c = cases[0];
  EXPECT_EQ(c.at("name").as_string(), "gen2-1005");
  EXPECT_EQ(c.at("category").as_string(), "effect");
  EXPECT_EQ(c.at("error").as_string(), "");
  EXPECT_EQ(c.at("truth").array.at(0).at("kind").as_string(), "electrical_interference");
  EXPECT_EQ(c.at("truth").array.at(0).at("params").at("frequency_hz").as_number(), mains_hz);
  // The diagnosis ran on the loaded recording: a held-out gap and its sampling expectation exist.
  EXPECT_GT(c.at("gap_heldout").as_number(), 0.0);
  EXPECT_GT(c.at("noise_gap").as_number(), 0.0);
  EXPECT_GT(c.at("runtime_s").as_number(), 0.0);
  EXPECT_GT(c.at("cpu_s").as_number(), 0.0);  // wait4 rusage of the diagnosis child
  // Peak RSS is measured in the diagnosis child (more than the recording's samples). Its bound belongs to
  // the bench (docs/gap.md), not to a test: ASan's shadow memory alone took it to 376 MiB here.
  EXPECT_GT(c.at("peak_rss_mib").as_number(), 1.0);
  // The score agrees with what was named.
  const auto& chosen = c.at("chosen").array;
  const bool named_right = !chosen.empty() && chosen[0].at("kind").as_string() == "electrical_interference";
  EXPECT_EQ(c.at("top1_correct").as_bool(), named_right);
  EXPECT_EQ(j.at("top1_accuracy").as_number(), named_right ? 1.0 : 0.0);
  if (!named_right) {
    EXPECT_FALSE(c.at("location_ok").as_bool());
  }
  const auto& row = j.at("confusion").array.at(4).array;  // electrical_interference
  double sum = 0.0;
  for (const auto& v : row) sum += v.as_number();
  EXPECT_EQ(sum, 1.0);
  EXPECT_EQ(j.at("row_labels").array.at(4).as_string(), "electrical_interference");
  EXPECT_NE(read_file(dir / "bench.md").find("| gen2 |"), std::string::npos);
}

TEST(GapCorpus, BrokenManifestsAreClearErrors) {
  const fs::path dir = scratch_dir("gap_corpus_errors");
  write(dir / "c/a/nominal.toml", "name = \"x\"\n");
  fs::create_directories(dir / "c/a/rec");
  const std::string manifest =
      R"({"format": "ptda-gap-corpus", "version": 1, "name": "t", "cases": [{"name": "a", "recording": "a/rec",
          "nominal": "a/nominal.toml", "truth": "a/truth.json"}]})";
  write(dir / "c/corpus.json", manifest);
  struct Bad {
    std::string truth;
    std::string message;
  };
  const std::vector<Bad> bad = {
      {R"({"format": "ptda-gap-truth", "version": 1, "category": "effect", "effects": [{"kind": "gremlins",
          "params": {}}]})",
       "effects[0]: unknown effect kind \"gremlins\""},
      {R"({"format": "ptda-gap-truth", "version": 1, "category": "effect", "effects": [{"kind": "adc_clipping",
          "params": {"level": 3}}]})",
       "adc_clipping has no parameter \"level\""},
      {R"({"format": "ptda-gap-truth", "version": 1, "category": "effect", "effects": []})",
       "category \"effect\" needs at least one entry"},
      {R"({"format": "ptda-gap-truth", "version": 1, "category": "maybe", "effects": []})",
       "\"category\" must be effect, control or out_of_library"},
      {R"({"format": "ptda-gap-truth", "version": 1, "category": "control", "effects": [{"kind": "noise_color",
          "params": {}}]})",
       "must not list library effects"},
  };
  for (std::size_t i = 0; i < bad.size(); ++i) {
    write(dir / "c/a/truth.json", bad[i].truth);
    const RunResult r =
        run_ptda({"gap-bench", "--corpus", (dir / "c").string()}, dir, "bad" + std::to_string(i));
    EXPECT_EQ(r.exit_code, 1) << i;
    EXPECT_NE(r.err.find(bad[i].message), std::string::npos) << i << ": " << r.err;
    EXPECT_NE(r.err.find("truth.json"), std::string::npos) << i << ": " << r.err;
  }
  // A case whose recording directory is missing names the case and the path.
  write(dir / "c/a/truth.json",
        R"({"format": "ptda-gap-truth", "version": 1, "category": "control", "effects": []})");
  fs::remove_all(dir / "c/a/rec");
  const RunResult r = run_ptda({"gap-bench", "--corpus", (dir / "c").string()}, dir, "norec");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("cases[0]: recording directory"), std::string::npos) << r.err;
  // Neither a corpus nor a simulated bench: a usage error.
  EXPECT_EQ(run_ptda({"gap-bench"}, dir, "none").exit_code, 2);
}

}  // namespace
}  // namespace ptda::golden
