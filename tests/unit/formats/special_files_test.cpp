// Issue 14 item 3: the readers must refuse FIFOs, devices and directories with an error naming the
// path, before reading. Before the fix a FIFO blocked open() until a writer came (configure hung)
// and /dev/zero was read until memory ran out.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <string>
#include <thread>

#include "ptda/common/error.hpp"
#include "ptda/formats/baseline_file.hpp"
#include "ptda/formats/candump.hpp"
#include "ptda/formats/recording.hpp"
#include "ptda/formats/wav.hpp"

namespace fs = std::filesystem;

namespace {

class SpecialFilesTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const char* env = std::getenv("PTDA_TEST_TMP");
    dir_ = fs::path(env != nullptr ? env : "/tmp") /
           ("formats_special_" + std::to_string(static_cast<long>(::getpid())));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path make_fifo(const std::string& name) const {
    const fs::path p = dir_ / name;
    EXPECT_EQ(::mkfifo(p.c_str(), 0600), 0);
    return p;
  }

  /// The error `read` throws for the FIFO at p. A watchdog thread opens the FIFO's write end (that
  /// only succeeds while a reader is blocked in open) and closes it at once, so an unfixed reader
  /// gets EOF and fails the message check instead of hanging the test. Gives up after 2 s.
  static std::string fifo_error(const fs::path& p, const std::function<void()>& read) {
    std::atomic<bool> done{false};
    std::thread watchdog([&] {
      for (int i = 0; i < 200 && !done.load(); ++i) {
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
        const int fd = ::open(p.c_str(), O_WRONLY | O_NONBLOCK);  // ENXIO while no reader waits
        if (fd >= 0) {
          ::close(fd);
          return;
        }
      }
    });
    std::string what = "(no error)";
    try {
      read();
    } catch (const ptda::Error& e) {
      what = e.what();
    }
    done = true;
    watchdog.join();
    return what;
  }

  fs::path dir_;
};

TEST_F(SpecialFilesTest, BaselineFifoIsRefusedWithoutBlocking) {
  const fs::path p = make_fifo("baseline.bin");
  EXPECT_EQ(fifo_error(p, [&] { (void)ptda::formats::read_baseline(p); }),
            p.string() + ": is a FIFO, not a baseline file");
}

TEST_F(SpecialFilesTest, BaselineDevZeroIsRefusedBeforeReading) {
  try {
    (void)ptda::formats::read_baseline("/dev/zero");
    FAIL() << "accepted /dev/zero";
  } catch (const ptda::Error& e) {
    EXPECT_EQ(std::string(e.what()), "/dev/zero: is a character device, not a baseline file");
  }
}

TEST_F(SpecialFilesTest, RecordingTomlFifoIsRefused) {
  const fs::path p = make_fifo("recording.toml");
  EXPECT_EQ(fifo_error(p, [&] { (void)ptda::formats::read_recording_meta(dir_); }),
            p.string() + ": is a FIFO, not a recording.toml");
}

TEST_F(SpecialFilesTest, WavFifoIsRefused) {
  const fs::path p = make_fifo("vibration.wav");
  EXPECT_EQ(fifo_error(p, [&] { ptda::formats::WavReader r(p); }),
            p.string() + ": is a FIFO, not a WAV file");
}

TEST_F(SpecialFilesTest, CandumpFifoAndDevZeroAreRefused) {
  const fs::path p = make_fifo("can.log");
  EXPECT_EQ(fifo_error(p, [&] { ptda::formats::CandumpReader r(p); }),
            p.string() + ": is a FIFO, not a candump log");
  try {
    (void)ptda::formats::read_candump("/dev/zero");
    FAIL() << "accepted /dev/zero";
  } catch (const ptda::Error& e) {
    EXPECT_EQ(std::string(e.what()), "/dev/zero: is a character device, not a candump log");
  }
}

}  // namespace
