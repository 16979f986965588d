// The event history (daemon/status/history_log.hpp): JSON Lines, size-bounded rotation, appending
// across restarts, located errors.
#include "status/history_log.hpp"

#include <gtest/gtest.h>

#include <cerrno>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "alloc_counter.hpp"
#include "ptda/common/error.hpp"
#include "status_text.hpp"

namespace fs = std::filesystem;

namespace ptda::daemon {
namespace {

fs::path scratch(const std::string& name) {
  const char* base = std::getenv("PTDA_TEST_TMP");
  const fs::path dir = fs::path(base != nullptr ? base : "/tmp") / "history_log_test" / name;
  fs::remove_all(dir);
  fs::create_directories(dir.parent_path());
  return dir;
}

std::vector<std::string> lines_of(const fs::path& p) {
  std::ifstream in(p);
  std::vector<std::string> out;
  for (std::string l; std::getline(in, l);) out.push_back(l);
  return out;
}

/// The unsigned value after "key": in a line.
std::uint64_t u64_of(const std::string& line, const std::string& key) {
  const auto at = line.find("\"" + key + "\":");
  if (at == std::string::npos) return ~0ULL;
  return std::strtoull(line.c_str() + at + key.size() + 3, nullptr, 10);
}

dsp::WindowResult scored_window(std::uint64_t n) {
  dsp::WindowResult w;
  w.ref.seq = n;
  w.ref.region_seq = n / 2;
  w.ref.t_start_ns = 1'000'000'000 + static_cast<std::int64_t>(n) * 125'000'000;
  w.ref.t_end_ns = w.ref.t_start_ns + 125'000'000;
  w.ref.speed_rad_s = -1.2;
  w.status = dsp::WindowStatus::kScored;
  w.class_id = 3;
  w.features.rms_res = 0.25;
  w.features.entropy_res = 0.875;
  w.thresholds.rms = {0.2, 0.3};
  w.thresholds.entropy = {0.8, 0.9};
  w.abnormal_in_last_n = 1;
  w.z_rms = 0.5;
  w.z_entropy = -0.25;
  return w;
}

TEST(HistoryLog, WindowAndStateLinesAreTheMonitorFieldsAsJsonLines) {
  const fs::path dir = scratch("format");
  HistoryConfig c;
  c.dir = dir;
  c.joint = "joint4";
  c.method = "ptda";
  {
    HistoryLog h(c);
    dsp::WindowResult w = scored_window(7);
    w.verdict.rms_out = true;
    h.window(w, 1700000000123456789);
    dsp::WindowResult u = scored_window(8);
    u.status = dsp::WindowStatus::kNoClass;
    u.class_id = -1;
    h.window(u, 0);
    h.state(1700000001000000000, "running", "monitoring", "alarm", "rms", "class 3, rms \"high\"");
    EXPECT_EQ(h.counters().lines, 3U);
    EXPECT_EQ(h.counters().write_failures, 0U);
  }
  EXPECT_EQ(fs::status(dir).permissions() & fs::perms::all, fs::perms(0750));
  const std::vector<std::string> lines = lines_of(dir / "history.jsonl");
  ASSERT_EQ(lines.size(), 3U);
  for (const std::string& l : lines) EXPECT_TRUE(test::JsonChecker(l).valid()) << l;
  EXPECT_EQ(
      lines[0],
      R"({"type":"window","joint":"joint4","t_utc":"2023-11-14T22:13:20.123Z","n":7,"t_start":1.875,)"
      R"("t_end":2,"segment":3,"region":3,"speed_rad_s":-1.2,"status":"scored","method":"ptda",)"
      R"("rms_res":0.25,"entropy_res":0.875,"rms_band":[0.2,0.3],"entropy_band":[0.8,0.9],"rms_out":true,)"
      R"("entropy_out":false,"abnormal":true,"alarm":false,"abnormal_in_last_n":1,"rms_low":false,)"
      R"("detector":"none","kofn_alarm":false,"seq_alarm":false,"seq_warn":false,"z_rms":0.5,)"
      R"("z_entropy":-0.25,"cusum":0,"cusum_feature":"none","cusum_max":0})");
  // Not scored: the features are null, never stale numbers; no wall time known: null.
  EXPECT_NE(lines[1].find(R"("t_utc":null,"n":8,)"), std::string::npos) << lines[1];
  EXPECT_NE(lines[1].find(R"("segment":null,)"), std::string::npos) << lines[1];
  EXPECT_NE(lines[1].find(R"("status":"no_class","method":"ptda","rms_res":null,"entropy_res":null,)"),
            std::string::npos)
      << lines[1];
  EXPECT_EQ(lines[2],
            R"({"type":"state","joint":"joint4","t_utc":"2023-11-14T22:13:21.000Z","state":"running",)"
            R"("phase":"monitoring","level":"alarm","causes":"rms","reason":"class 3, rms \"high\""})");
}

// With the band CUSUM on, window lines end with its evidence, as `ptda monitor --jsonl` writes it
// (tests/unit/cli/jsonl_test.cpp pins the same text); without it nothing changes (test above).
TEST(HistoryLog, BandCusumEvidenceEndsTheWindowLine) {
  const fs::path dir = scratch("band");
  HistoryConfig c;
  c.dir = dir;
  c.method = "ptda";
  {
    HistoryLog h(c);
    dsp::WindowResult w = scored_window(7);
    w.band_on = true;
    w.band_alarm = true;
    w.band_z_max = 3.5;
    w.band_statistic = 12.0;
    w.band_index = 7;
    w.band_max_statistic = 12.0;
    w.band_max_index = 7;
    w.band_lo_hz = 2802.5;
    w.band_hi_hz = 3200.0;
    h.window(w, 1700000000123456789);
    dsp::WindowResult u = scored_window(8);
    u.status = dsp::WindowStatus::kNoClass;
    u.band_on = true;
    h.window(u, 0);
  }
  const std::vector<std::string> lines = lines_of(dir / "history.jsonl");
  ASSERT_EQ(lines.size(), 2U);
  for (const std::string& l : lines) EXPECT_TRUE(test::JsonChecker(l).valid()) << l;
  const std::string tail =
      R"("cusum_max":0,"band_alarm":true,"band_z_max":3.5,"band_cusum":12,"band_cusum_band":7,)"
      R"("band_cusum_max":12,"band":7,"band_hz":[2802.5,3200]})";
  EXPECT_EQ(lines[0].substr(lines[0].size() - tail.size()), tail) << lines[0];
  const std::string unscored =
      R"("band_alarm":false,"band_z_max":null,"band_cusum":null,"band_cusum_band":null,"band_cusum_max":0,)"
      R"("band":null,"band_hz":null})";
  EXPECT_EQ(lines[1].substr(lines[1].size() - unscored.size()), unscored) << lines[1];
}

TEST(HistoryLog, RotationBoundsTheHistoryAndKeepsTheNewestInOrder) {
  const fs::path dir = scratch("rotation");
  HistoryConfig c;
  c.dir = dir;
  c.method = "ptda";
  c.max_file_bytes = 4096;
  c.files = 3;
  HistoryLog h(c);
  const std::uint64_t total = 60;
  {
    // Writing a line allocates nothing (the supervisor's buffers are made at construction).
    ptda::test::AllocScope alloc;
    for (std::uint64_t n = 0; n < total; ++n) h.window(scored_window(n), 1700000000000000000);
    EXPECT_EQ(alloc.count(), 0U);
  }
  const HistoryCounters k = h.counters();
  EXPECT_EQ(k.lines, total);
  EXPECT_EQ(k.write_failures, 0U);
  EXPECT_GE(k.rotations, 2U);
  EXPECT_FALSE(fs::exists(dir / "history.3.jsonl"));
  std::uint64_t bytes = 0;
  std::vector<std::uint64_t> seqs;  // oldest file first
  for (const char* name : {"history.2.jsonl", "history.1.jsonl", "history.jsonl"}) {
    ASSERT_TRUE(fs::exists(dir / name)) << name;
    EXPECT_LE(fs::file_size(dir / name), c.max_file_bytes) << name;
    bytes += fs::file_size(dir / name);
    for (const std::string& l : lines_of(dir / name)) {
      EXPECT_TRUE(test::JsonChecker(l).valid()) << name << ": " << l;
      seqs.push_back(u64_of(l, "n"));
    }
  }
  EXPECT_LE(bytes, c.files * c.max_file_bytes);
  // The newest windows, contiguous and in order, ending with the last one written.
  ASSERT_FALSE(seqs.empty());
  EXPECT_EQ(seqs.back(), total - 1);
  for (std::size_t i = 1; i < seqs.size(); ++i) EXPECT_EQ(seqs[i], seqs[i - 1] + 1);
  EXPECT_LT(seqs.size(), total);  // the oldest were dropped with the oldest file
}

TEST(HistoryLog, ARestartAppendsToTheCurrentFile) {
  const fs::path dir = scratch("restart");
  HistoryConfig c;
  c.dir = dir;
  c.method = "tda";
  { HistoryLog(c).window(scored_window(1), 1700000000000000000); }
  { HistoryLog(c).window(scored_window(2), 1700000000000000000); }
  const std::vector<std::string> lines = lines_of(dir / "history.jsonl");
  ASSERT_EQ(lines.size(), 2U);
  EXPECT_EQ(u64_of(lines[0], "n"), 1U);
  EXPECT_EQ(u64_of(lines[1], "n"), 2U);
  EXPECT_NE(lines[0].find("\"method\":\"tda\""), std::string::npos);
}

TEST(HistoryLog, APartialLastLineIsCutBeforeTheNextOne) {
  // A power loss in the middle of a line: the next start must not glue its first line onto it.
  const fs::path dir = scratch("partial");
  HistoryConfig c;
  c.dir = dir;
  c.method = "ptda";
  { HistoryLog(c).window(scored_window(1), 1700000000000000000); }
  const std::string fragment = "{\"type\":\"window\",\"t_ut";
  std::ofstream(dir / "history.jsonl", std::ios::app) << fragment;
  {
    HistoryLog h(c);
    EXPECT_EQ(h.counters().cut_bytes, fragment.size());
    h.window(scored_window(2), 1700000000000000000);
  }
  const std::vector<std::string> lines = lines_of(dir / "history.jsonl");
  ASSERT_EQ(lines.size(), 2U);
  for (const std::string& l : lines) EXPECT_TRUE(test::JsonChecker(l).valid()) << l;
  EXPECT_EQ(u64_of(lines[1], "n"), 2U);
}

TEST(HistoryLog, ADirectoryThatCannotBeMadeIsAnErrorNamingIt) {
  const fs::path dir = scratch("blocked");
  fs::create_directories(dir);
  std::ofstream(dir / "file") << "x";
  HistoryConfig c;
  c.dir = dir / "file" / "history";
  try {
    HistoryLog h(c);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("[history] dir " + c.dir.string() + ": cannot create"),
              std::string::npos)
        << e.what();
  }
  c.dir = dir;
  c.files = 1;
  EXPECT_THROW(HistoryLog{c}, Error);
}

}  // namespace
}  // namespace ptda::daemon

namespace ptda::daemon {
namespace {

TEST(HistoryLog, ARotationThatCannotMoveTheCurrentFileStopsAtTheBoundInsteadOfShiftingAgain) {
  // history.1.jsonl is a non-empty directory: renaming history.jsonl onto it fails (EISDIR). Shifting
  // the older files again at every line would lose them; the history stops at its size bound and every
  // line from then on is a counted failure.
  const fs::path dir = scratch("rotation_fails");
  fs::create_directories(dir / "history.1.jsonl");
  std::ofstream(dir / "history.1.jsonl" / "keep") << "x\n";
  HistoryConfig c;
  c.dir = dir;
  c.method = "ptda";
  c.max_file_bytes = 4096;
  c.files = 2;
  HistoryLog h(c);
  for (std::uint64_t n = 0; n < 60; ++n) h.window(scored_window(n), 1700000000000000000);
  const HistoryCounters k = h.counters();
  EXPECT_EQ(k.rotation_failures, 1U);
  EXPECT_EQ(k.rotations, 0U);
  EXPECT_EQ(k.last_errno, EISDIR);
  EXPECT_GT(k.write_failures, 0U);
  EXPECT_EQ(k.lines + k.write_failures, 60U);  // every window is written or counted
  EXPECT_LE(fs::file_size(dir / "history.jsonl"), c.max_file_bytes);
  EXPECT_TRUE(fs::exists(dir / "history.1.jsonl" / "keep"));
  for (const std::string& l : lines_of(dir / "history.jsonl")) EXPECT_TRUE(test::JsonChecker(l).valid()) << l;
}

}  // namespace
}  // namespace ptda::daemon
