// `ptda import` and an existing or failed output (issue 14 item 9): it refuses an existing --out
// unless --force, replaces it only once the import succeeded, and leaves nothing behind on failure.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "ptda/cli/commands.hpp"
#include "ptda/common/error.hpp"
#include "ptda/formats/wav.hpp"

namespace fs = std::filesystem;

namespace {

class ImportCmdTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const char* env = std::getenv("PTDA_TEST_TMP");
    dir_ = fs::path(env != nullptr ? env : "/tmp") /
           ("cli_import_cmd_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) +
            "_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    write(dir_ / "good.csv", "v\n0.5\n-0.25\n0.125\n");
    write(dir_ / "good4.csv", "v\n1\n2\n3\n4\n");
    write(dir_ / "bad.csv", "v\n0.5\nnot-a-number\n");
  }
  void TearDown() override { fs::remove_all(dir_); }

  static void write(const fs::path& p, const std::string& text) {
    std::ofstream(p, std::ios::binary) << text;
  }

  /// Runs `ptda import` on csv into out; returns "" on success or the error text.
  std::string import(const std::string& csv, const fs::path& out, bool force) const {
    std::vector<std::string> args = {"--csv", (dir_ / csv).string(), "--column", "v",     "--rate",
                                     "1000",  "--shaft-speed",       "30Hz",     "--out", out.string()};
    if (force) args.emplace_back("--force");
    std::ostringstream text;
    try {
      EXPECT_EQ(ptda::cli::cmd_import(args, text), ptda::cli::kExitOk);
    } catch (const ptda::Error& e) {
      return e.what();
    }
    return "";
  }

  static std::uint64_t frames(const fs::path& rec) {
    ptda::formats::WavReader r(rec / "vibration.wav");
    return r.info().frames;
  }

  /// Entries of dir_ (to see leftovers).
  std::size_t entries() const {
    std::size_t n = 0;
    for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir_)) ++n;
    return n;
  }

  fs::path dir_;
};

TEST_F(ImportCmdTest, RefusesAnExistingOutputUnlessForced) {
  const fs::path out = dir_ / "rec";
  ASSERT_EQ(import("good.csv", out, false), "");
  EXPECT_EQ(frames(out), 3U);
  EXPECT_EQ(import("good4.csv", out, false), out.string() + ": already exists; pass --force to replace it");
  EXPECT_EQ(frames(out), 3U);  // untouched
  ASSERT_EQ(import("good4.csv", out, true), "");
  EXPECT_EQ(frames(out), 4U);
  EXPECT_EQ(entries(), 4U);  // the three CSVs and rec: no temporary directory left
}

TEST_F(ImportCmdTest, AFailedImportLeavesNothingBehind) {
  const fs::path out = dir_ / "rec";
  const std::string err = import("bad.csv", out, false);
  EXPECT_NE(err.find("bad.csv:3"), std::string::npos) << err;
  EXPECT_FALSE(fs::exists(out));
  EXPECT_EQ(entries(), 3U);  // only the CSVs
}

TEST_F(ImportCmdTest, AFailedForcedImportKeepsTheExistingOutput) {
  const fs::path out = dir_ / "rec";
  ASSERT_EQ(import("good.csv", out, false), "");
  EXPECT_NE(import("bad.csv", out, true), "");
  EXPECT_EQ(frames(out), 3U);
  EXPECT_EQ(entries(), 4U);
}

}  // namespace
