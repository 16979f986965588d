// Symlink-safe replacement of state files (common/include/ptda/common/atomic_file.hpp; issue 14
// item 2): planted symlinks are never followed, the mode is what the caller asked for, a failure leaves
// neither the target changed nor a temporary file, and stale temporary files are removed.
#include "ptda/common/atomic_file.hpp"

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "alloc_counter.hpp"

namespace fs = std::filesystem;

namespace {

fs::path scratch(const std::string& name) {
  const char* env = std::getenv("PTDA_TEST_TMP");
  const fs::path dir = fs::path(env != nullptr ? env : "/tmp") / "atomic_file_test" / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

void put(const fs::path& p, const std::string& text) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out << text;
}

mode_t mode_of(const fs::path& p) {
  struct stat st {};
  EXPECT_EQ(::lstat(p.c_str(), &st), 0) << p;
  return st.st_mode & 07777;
}

/// Sets the umask for the scope (restored after).
class UmaskScope {
 public:
  explicit UmaskScope(mode_t m) : old_(::umask(m)) {}
  ~UmaskScope() { ::umask(old_); }
  UmaskScope(const UmaskScope&) = delete;
  UmaskScope& operator=(const UmaskScope&) = delete;

 private:
  mode_t old_;
};

std::size_t entries(const fs::path& dir) {
  std::size_t n = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir)) ++n;
  return n;
}

ptda::AtomicWriteResult write(const fs::path& p, const std::string& text, ptda::AtomicWriteOptions opt = {}) {
  return ptda::write_file_atomic(p.c_str(), text.data(), text.size(), opt);
}

TEST(AtomicFile, WritesAndReplacesLeavingNoTemporaryFile) {
  const fs::path dir = scratch("write");
  ASSERT_TRUE(write(dir / "state.json", "first").ok());
  EXPECT_EQ(slurp(dir / "state.json"), "first");
  ASSERT_TRUE(write(dir / "state.json", "second, longer").ok());
  EXPECT_EQ(slurp(dir / "state.json"), "second, longer");
  EXPECT_EQ(entries(dir), 1U);
}

TEST(AtomicFile, ModeIsExactOrUmaskedAsAsked) {
  const fs::path dir = scratch("mode");
  const UmaskScope mask(077);  // ptdad's UMask=0077
  ptda::AtomicWriteOptions exact;
  exact.mode = 0644;
  exact.exact_mode = true;
  exact.durable = false;
  ASSERT_TRUE(write(dir / "status.json", "x", exact).ok());
  EXPECT_EQ(mode_of(dir / "status.json"), 0644U);  // node_exporter (another user) reads it
  ptda::AtomicWriteOptions umasked;
  umasked.mode = 0644;
  ASSERT_TRUE(write(dir / "baseline.bin", "x", umasked).ok());
  EXPECT_EQ(mode_of(dir / "baseline.bin"), 0600U);  // private under the service's umask
}

// The attack the old writers allowed: a symlink at the predictable temporary name. The old status
// writer opened "<name>.tmp" O_CREAT|O_TRUNC (following the link: the victim was truncated and
// overwritten) and fchmod'ed it 0644; the old baseline writer did the same with "<name>.tmp.<pid>".
TEST(AtomicFile, SymlinkAtTheOldTemporaryNamesIsNotFollowed) {
  const fs::path dir = scratch("symlink_tmp");
  const fs::path victim = scratch("symlink_tmp_victim") / "shadow";
  put(victim, "root:secret\n");
  fs::permissions(victim, fs::perms::owner_read | fs::perms::owner_write);
  fs::create_symlink(victim, dir / "status.json.tmp");
  fs::create_symlink(victim, dir / ("baseline.bin.tmp." + std::to_string(::getpid())));
  ptda::AtomicWriteOptions opt;
  opt.exact_mode = true;
  ASSERT_TRUE(write(dir / "status.json", "{}", opt).ok());
  ASSERT_TRUE(write(dir / "baseline.bin", "PTDABASE", opt).ok());
  EXPECT_EQ(slurp(victim), "root:secret\n");
  EXPECT_EQ(mode_of(victim), 0600U);
  EXPECT_EQ(slurp(dir / "status.json"), "{}");
  EXPECT_TRUE(fs::is_symlink(dir / "status.json.tmp"));  // left alone
}

// A symlink at the target itself is replaced by the file (rename never follows it).
TEST(AtomicFile, SymlinkAtTheTargetIsReplacedNotFollowed) {
  const fs::path dir = scratch("symlink_target");
  const fs::path victim = scratch("symlink_target_victim") / "passwd";
  put(victim, "unchanged");
  fs::create_symlink(victim, dir / "status.json");
  ASSERT_TRUE(write(dir / "status.json", "{}").ok());
  EXPECT_FALSE(fs::is_symlink(dir / "status.json"));
  EXPECT_EQ(slurp(dir / "status.json"), "{}");
  EXPECT_EQ(slurp(victim), "unchanged");
}

TEST(AtomicFile, FailureNamesTheStepAndLeavesTheTargetAlone) {
  const fs::path dir = scratch("fail");
  const ptda::AtomicWriteResult missing = write(dir / "gone" / "status.json", "x");
  EXPECT_EQ(missing.err, ENOENT);
  EXPECT_STREQ(missing.step, "open of the temporary file");
  put(dir / "file", "");
  const ptda::AtomicWriteResult not_dir = write(dir / "file" / "status.json", "x");
  EXPECT_EQ(not_dir.err, ENOTDIR);
  // The target is a directory: the rename fails, the temporary file is removed.
  fs::create_directory(dir / "target");
  const ptda::AtomicWriteResult is_dir = write(dir / "target", "x");
  EXPECT_EQ(is_dir.err, EISDIR);
  EXPECT_STREQ(is_dir.step, "rename");
  EXPECT_EQ(entries(dir), 2U);  // "file" and "target": no temporary file
  EXPECT_EQ(write(fs::path(std::string(5000, 'a')), "x").err, ENAMETOOLONG);
}

TEST(AtomicFile, WriteMakesNoAllocations) {
  const fs::path dir = scratch("alloc");
  const std::string path = (dir / "ptda.prom").string();
  const std::string text(3000, 'x');
  ptda::AtomicWriteOptions opt;
  opt.exact_mode = true;
  opt.durable = false;
  int failures = 0;
  {
    ptda::test::AllocScope scope;
    for (int i = 0; i < 20; ++i) {
      if (!ptda::write_file_atomic(path.c_str(), text.data(), text.size(), opt).ok()) ++failures;
    }
    EXPECT_EQ(scope.count(), 0U);
  }
  EXPECT_EQ(failures, 0);
}

TEST(AtomicFile, StaleTemporaryFilesAreRemoved) {
  const fs::path dir = scratch("stale");
  const fs::path victim = scratch("stale_victim") / "keep";
  put(victim, "keep");
  // What killed writers leave: the old status name, the old baseline name, the current name.
  for (const char* n : {"status.json.tmp", "status.json.tmp.4242", "status.json.tmp-0123456789az"}) {
    put(dir / n, "stale");
  }
  // Not ours to remove: other targets, other patterns, a symlink, a directory, the target itself.
  for (const char* n : {"status.json", "other.json.tmp", "status.json.tmpx", "status.json.tmp-SHORT",
                        "status.json.tmp-0123456789AZ", "status.json.tmp.12a", "xstatus.json.tmp"}) {
    put(dir / n, "keep");
  }
  fs::create_symlink(victim, dir / "status.json.tmp.7");
  fs::create_directory(dir / "status.json.tmp.8");
  EXPECT_EQ(ptda::remove_stale_temp_files(dir.c_str(), "status.json"), 3U);
  EXPECT_FALSE(fs::exists(dir / "status.json.tmp"));
  EXPECT_FALSE(fs::exists(dir / "status.json.tmp.4242"));
  EXPECT_FALSE(fs::exists(dir / "status.json.tmp-0123456789az"));
  EXPECT_EQ(entries(dir), 9U);
  EXPECT_TRUE(fs::is_symlink(dir / "status.json.tmp.7"));
  EXPECT_EQ(slurp(victim), "keep");
  EXPECT_EQ(ptda::remove_stale_temp_files((dir / "missing").c_str(), "status.json"), 0U);
}

TEST(AtomicFile, ErrnoNames) {
  EXPECT_STREQ(ptda::errno_name(ENOENT), "ENOENT");
  EXPECT_STREQ(ptda::errno_text(ENOSPC), "No space left on device");
  EXPECT_STREQ(ptda::errno_name(0), "");
}

}  // namespace
