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

// Issue 14 item 8: running as root, a configuration or baseline file others can write is refused with
// the fix. euid is injected, so both sides are tested whoever runs the test.
TEST_F(FileCheckTest, GroupOrWorldWritableFilesAreRefusedOnlyForRoot) {
  const fs::path p = dir_ / "ptdad.toml";
  std::ofstream(p) << "x = 1\n";
  ASSERT_EQ(::chmod(p.c_str(), 0664), 0);
  EXPECT_EQ(
      error_of([&] { ptda::require_trusted_file(p, 100, "configuration file", 0); }),
      p.string() +
          ": configuration file is group-writable (mode 0664) and ptda runs as root: another user could "
          "change what it does. Fix: chmod go-w " +
          p.string());
  EXPECT_EQ(error_of([&] { (void)ptda::read_regular_file(p, 100, "configuration file", 0); }),
            error_of([&] { ptda::require_trusted_file(p, 100, "configuration file", 0); }));
  EXPECT_NO_THROW(ptda::require_trusted_file(p, 100, "configuration file", 1000));  // not root: allowed
  EXPECT_EQ(ptda::read_regular_file(p, 100, "configuration file", 1000), "x = 1\n");
  EXPECT_EQ(ptda::read_regular_file(p, 100, "configuration file"), "x = 1\n");  // no euid: no check
  ASSERT_EQ(::chmod(p.c_str(), 0602), 0);
  EXPECT_NE(error_of([&] {
              ptda::require_trusted_file(p, 100, "baseline file", 0);
            }).find(": baseline file is world-writable (mode 0602) and ptda runs as root"),
            std::string::npos);
  ASSERT_EQ(::chmod(p.c_str(), 0644), 0);
  EXPECT_NO_THROW(ptda::require_trusted_file(p, 100, "configuration file", 0));
  EXPECT_EQ(ptda::read_regular_file(p, 100, "configuration file", 0), "x = 1\n");
  // The default euid is the process's own: as root (the test machine) the 0664 file is refused.
  ASSERT_EQ(::chmod(p.c_str(), 0664), 0);
  if (::geteuid() == 0) {
    EXPECT_THROW(ptda::require_trusted_file(p, 100, "configuration file"), ptda::Error);
  } else {
    EXPECT_NO_THROW(ptda::require_trusted_file(p, 100, "configuration file"));
  }
}

// The directories too: a group-writable parent (not sticky) lets another user replace the file, so it
// is refused for root, naming the directory and the fix; a sticky world-writable one (/tmp) is not.
TEST_F(FileCheckTest, WritableParentDirectoriesAreRefusedOnlyForRoot) {
  const fs::path sub = dir_ / "etc";
  fs::create_directories(sub);
  const fs::path p = sub / "ptdad.toml";
  std::ofstream(p) << "x = 1\n";
  ASSERT_EQ(::chmod(p.c_str(), 0644), 0);
  ASSERT_EQ(::chmod(sub.c_str(), 0775), 0);
  EXPECT_EQ(error_of([&] { ptda::require_trusted_file(p, 100, "configuration file", 0); }),
            sub.string() + ": directory holding the configuration file " + p.string() +
                " is group-writable (mode 0775) and ptda runs as root: another user could replace the file. "
                "Fix: chmod go-w " +
                sub.string());
  EXPECT_EQ(error_of([&] { (void)ptda::read_regular_file(p, 100, "configuration file", 0); }),
            error_of([&] { ptda::require_trusted_file(p, 100, "configuration file", 0); }));
  EXPECT_NO_THROW(ptda::require_trusted_file(p, 100, "configuration file", 1000));  // not root
  // Reached through a symlink from a safe directory: the real directory is still checked.
  const fs::path link = dir_ / "link.toml";
  fs::create_symlink(p, link);
  EXPECT_NE(error_of([&] {
              ptda::require_trusted_file(link, 100, "baseline file", 0);
            }).find(sub.string() + ": directory holding the baseline file"),
            std::string::npos);
  // Sticky and world-writable (like /tmp): only the owner may rename the file, accepted.
  ASSERT_EQ(::chmod(sub.c_str(), 01777), 0);
  EXPECT_NO_THROW(ptda::require_trusted_file(p, 100, "configuration file", 0));
  ASSERT_EQ(::chmod(sub.c_str(), 0755), 0);
  EXPECT_NO_THROW(ptda::require_trusted_file(link, 100, "configuration file", 0));
}

TEST(StringValueProblem, NulAndLength) {
  EXPECT_EQ(ptda::string_value_problem("/etc/ptda/ptdad.toml"), "");
  EXPECT_EQ(ptda::string_value_problem(std::string("/etc/a\0b", 8)),
            "contains a NUL byte (\\u0000) at byte 6; paths and names cannot");
  EXPECT_EQ(ptda::string_value_problem(std::string(4096, 'x')), "");
  EXPECT_EQ(ptda::string_value_problem(std::string(4097, 'x')), "is 4097 bytes long, at most 4096 allowed");
  EXPECT_EQ(ptda::string_value_problem("can0123456789abc", ptda::kMaxInterfaceNameBytes),
            "is 16 bytes long, at most 15 allowed");
}
