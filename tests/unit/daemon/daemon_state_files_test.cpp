// The daemon's state files under a hostile or failing file system (issue 14 items 2 and 6), through
// the real threads on the simulator backends: stale temporary files are removed at start, a failing
// metrics or status file shows in the other one with its errno and is written again once the cause is
// gone, and a deleted status directory is created again. Root ignores permission bits, so the faults
// are a path component that is a regular file (ENOTDIR) and a removed directory.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <string>

#include "daemon_test_support.hpp"

namespace ptda::daemon::test {
namespace {

class StateFiles : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { block_daemon_signals(); }
  drivers::MonotonicClock clock_;
};

std::string read_text(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

void touch(const fs::path& p) {
  std::ofstream out(p);
}

TEST_F(StateFiles, StaleTempFilesGoFailuresShowAndWritingResumes) {
  const fs::path dir = scratch("state_files");
  const fs::path status_dir = dir / "status";
  const fs::path blocker = dir / "metrics";  // a regular file where the metrics directory should be
  fs::create_directories(status_dir);
  write_sim_baseline(dir / "baseline.bin");
  // What a kill -9 of an older and of this version leaves behind, and files that are not ours to remove.
  for (const char* n : {"status.json.tmp", "status.json.tmp.4242", "status.json.tmp-abcdefghijkl"}) {
    touch(status_dir / n);
  }
  touch(dir / "baseline.bin.tmp.777");
  touch(dir / "baseline.bin.tmp-0123456789ab");
  touch(status_dir / "notes.tmp");
  touch(blocker);
  write_text(dir / "ptdad.toml", sim_config(dir / "baseline.bin", status_dir, "realtime",
                                            "metrics_path = \"" + (blocker / "ptda.prom").string() + "\"\n"));
  DaemonOptions opt;
  opt.config_file = dir / "ptdad.toml";
  opt.config_dir = fs::path();
  Daemon d(opt, clock_);
  d.configure();
  EXPECT_FALSE(fs::exists(status_dir / "status.json.tmp"));
  EXPECT_FALSE(fs::exists(status_dir / "status.json.tmp.4242"));
  EXPECT_FALSE(fs::exists(status_dir / "status.json.tmp-abcdefghijkl"));
  EXPECT_FALSE(fs::exists(dir / "baseline.bin.tmp.777"));
  EXPECT_FALSE(fs::exists(dir / "baseline.bin.tmp-0123456789ab"));
  EXPECT_TRUE(fs::exists(status_dir / "notes.tmp"));
  d.activate();
  DaemonRunThread runner(d);

  // 1. The metrics file cannot be written (ENOTDIR): status.json says so, with its errno.
  const fs::path status = status_dir / "status.json";
  std::string metrics;
  ASSERT_TRUE(wait_for([&] {
    metrics = state_file_json(read_text(status), "metrics");
    return metrics.find("\"failing\":true") != std::string::npos;
  })) << read_text(status);
  EXPECT_NE(metrics.find("\"last_errno\":20,"), std::string::npos) << metrics;
  EXPECT_NE(metrics.find("\"last_error\":\"open of the temporary file: ENOTDIR (Not a directory)\""),
            std::string::npos)
      << metrics;
  EXPECT_NE(state_file_json(read_text(status), "status").find("\"failing\":false"), std::string::npos);

  // 2. The cause removed: the metrics file appears (within the backoff) and reports the past failures.
  fs::remove(blocker);
  fs::create_directory(blocker);
  ASSERT_TRUE(wait_for([&] {
    metrics = state_file_json(read_text(status), "metrics");
    return metrics.find("\"failing\":false") != std::string::npos;
  })) << read_text(status);
  EXPECT_EQ(metrics.find("\"failures\":0,"), std::string::npos) << metrics;
  ASSERT_TRUE(wait_for([&] { return fs::exists(blocker / "ptda.prom"); }));

  // 3. The status directory deleted: created again, status.json written again.
  remove_dir_under_daemon(status_dir);
  ASSERT_TRUE(wait_for([&] { return read_text(status).find("\"state\":") != std::string::npos; }));
  EXPECT_EQ(fs::status(status_dir).permissions() & fs::perms::all,
            fs::perms::owner_all | fs::perms::group_read | fs::perms::group_exec | fs::perms::others_read |
                fs::perms::others_exec);

  // 4. The status directory replaced by a regular file: the metrics file shows the failure.
  remove_dir_under_daemon(status_dir);
  touch(status_dir);
  const fs::path prom = blocker / "ptda.prom";
  ASSERT_TRUE(wait_for([&] {
    return read_text(prom).find("ptda_state_write_failing{file=\"status\"} 1\n") != std::string::npos;
  })) << read_text(prom);
  EXPECT_NE(read_text(prom).find("ptda_state_write_last_errno{file=\"status\"} 20\n"), std::string::npos);
  fs::remove(status_dir);
  ASSERT_TRUE(wait_for([&] { return state_file_json(read_text(status), "status").size() > 0; }));
  const std::string st = state_file_json(read_text(status), "status");
  EXPECT_NE(st.find("\"last_errno\":20"), std::string::npos) << st;
  EXPECT_EQ(st.find("\"failures\":0,"), std::string::npos) << st;
  for (const auto& e : fs::directory_iterator(status_dir)) {
    EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos) << e.path();
  }
}

}  // namespace
}  // namespace ptda::daemon::test
