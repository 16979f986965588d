// The shared regular-file check (common/include/ptda/common/file_check.hpp; issue 14 item 3).
#include "ptda/common/file_check.hpp"

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>

namespace fs = std::filesystem;

namespace {

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const ptda::Error& e) {
    return e.what();
  }
  return "(no error)";
}

class FileCheckTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const char* env = std::getenv("PTDA_TEST_TMP");
    dir_ = fs::path(env != nullptr ? env : "/tmp") / ("common_file_check_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(FileCheckTest, ReadsARegularFileWhole) {
  const fs::path p = dir_ / "a.toml";
  std::ofstream(p) << "x = 1\n";
  EXPECT_EQ(ptda::read_regular_file(p, 6, "configuration file"), "x = 1\n");
  EXPECT_NO_THROW(ptda::require_regular_file(p, 6, "configuration file"));
}

TEST_F(FileCheckTest, RefusesTooLargeMissingAndSpecialFiles) {
  const fs::path p = dir_ / "a.toml";
  std::ofstream(p) << "x = 1\n";
  EXPECT_EQ(error_of([&] { (void)ptda::read_regular_file(p, 5, "configuration file"); }),
            p.string() + ": configuration file is too large (6 bytes, at most 5)");
  EXPECT_EQ(error_of([&] { ptda::require_regular_file(dir_ / "none", 5, "baseline file"); }),
            (dir_ / "none").string() + ": cannot open baseline file: No such file or directory");
  EXPECT_EQ(error_of([&] { (void)ptda::read_regular_file(dir_, 5, "configuration file"); }),
            dir_.string() + ": is a directory, not a configuration file");
  // A FIFO without a writer: read_regular_file opens it non-blocking, so this returns at once.
  const fs::path fifo = dir_ / "fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  EXPECT_EQ(error_of([&] { (void)ptda::read_regular_file(fifo, 5, "configuration file"); }),
            fifo.string() + ": is a FIFO, not a configuration file");
  EXPECT_EQ(error_of([&] { (void)ptda::read_regular_file("/dev/zero", 5, "configuration file"); }),
            "/dev/zero: is a character device, not a configuration file");
}

}  // namespace
