#include "adc/wav_replay_source.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "alloc_counter.hpp"
#include "ptda/common/error.hpp"
#include "ptda/formats/wav.hpp"

namespace fs = std::filesystem;

namespace ptda::drivers {
namespace {

class WavReplay : public ::testing::Test {
 protected:
  void SetUp() override {
    const char* base = std::getenv("PTDA_TEST_TMP");
    const fs::path root = base != nullptr ? fs::path(base) : fs::temp_directory_path();
    dir_ =
        root / ("wavreplay_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) +
                "_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    // 1000 samples at 1 kHz, two channels: ch0 = i, ch1 = -i (PCM16 codes).
    std::vector<float> a(1000), b(1000);
    for (int i = 0; i < 1000; ++i) {
      a[static_cast<std::size_t>(i)] = static_cast<float>(i);
      b[static_cast<std::size_t>(i)] = static_cast<float>(-i);
    }
    wav_ = dir_ / "vibration.wav";
    formats::write_wav(wav_, 1000, formats::WavSampleFormat::kPcm16, {a, b});
    cfg_.path = wav_;
    cfg_.block_len = 256;
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path dir_, wav_;
  WavReplayConfig cfg_;
};

TEST_F(WavReplay, AsFastAsPossibleDeliversEverySampleWithSyntheticTimes) {
  cfg_.pace = ReplayPace::kAsFastAsPossible;
  cfg_.channel = 1;
  cfg_.scale = 0.5F;
  cfg_.timeline.origin_mono_ns = 1'000'000'000;
  ManualClock clock(0);
  WavReplaySource src(cfg_, clock);
  src.configure();
  EXPECT_DOUBLE_EQ(src.fs_hz(), 1000.0);
  EXPECT_EQ(src.total_samples(), 1000u);
  src.activate();
  auto b = std::make_unique<SampleBlock>();
  const std::uint32_t expected_counts[] = {256, 256, 256, 232};
  for (int k = 0; k < 4; ++k) {
    ASSERT_EQ(src.read(*b, 0), SourceStatus::kOk) << k;
    EXPECT_EQ(b->count, expected_counts[k]);
    EXPECT_EQ(b->first_index, 256u * static_cast<unsigned>(k));
    EXPECT_EQ(b->t_mono_ns, 1'000'000'000 + 256'000'000LL * k);
    EXPECT_EQ(b->flags, 0u);
    EXPECT_FLOAT_EQ(b->samples[1], -0.5F * static_cast<float>(256 * k + 1));
  }
  EXPECT_EQ(src.read(*b, 0), SourceStatus::kEndOfStream);
  EXPECT_EQ(clock.now_ns(), 0);  // never waited
  EXPECT_EQ(src.counters().samples, 1000u);
  // activate() rewinds.
  src.activate();
  ASSERT_EQ(src.read(*b, 0), SourceStatus::kOk);
  EXPECT_EQ(b->first_index, 0u);
  EXPECT_FLOAT_EQ(b->samples[255], -127.5F);
}

TEST_F(WavReplay, RealTimeReleasesABlockWhenItsLastSampleIsDue) {
  ManualClock clock(50'000'000'000);
  WavReplaySource src(cfg_, clock);
  src.configure();
  src.activate();  // sample 0 at the clock's 50 s
  auto b = std::make_unique<SampleBlock>();
  // The first block's last sample (255) is due at 50.255 s: a 10 ms timeout is not enough.
  EXPECT_EQ(src.read(*b, 10'000'000), SourceStatus::kTimeout);
  EXPECT_EQ(clock.now_ns(), 50'010'000'000);  // slept the whole timeout
  ASSERT_EQ(src.read(*b, 1'000'000'000), SourceStatus::kOk);
  EXPECT_EQ(clock.now_ns(), 50'255'000'000);  // woke exactly when due
  EXPECT_EQ(b->t_mono_ns, 50'000'000'000);
  EXPECT_EQ(b->count, 256u);
  ASSERT_EQ(src.read(*b, 1'000'000'000), SourceStatus::kOk);
  EXPECT_EQ(clock.now_ns(), 50'511'000'000);
  EXPECT_EQ(b->t_mono_ns, 50'256'000'000);
  EXPECT_EQ(src.counters().timeouts, 1u);
}

// ptdad reads real-time sources in bursts after its own burst timer: a zero timeout polls, never
// sleeps and is not a timeout.
TEST_F(WavReplay, ZeroTimeoutPollsWithoutSleepingOrCounting) {
  ManualClock clock(50'000'000'000);
  WavReplaySource src(cfg_, clock);
  src.configure();
  src.activate();
  auto b = std::make_unique<SampleBlock>();
  EXPECT_EQ(src.read(*b, 0), SourceStatus::kTimeout);  // block 0 is due at 50.255 s
  EXPECT_EQ(clock.sleeps(), 0u);
  EXPECT_EQ(clock.now_ns(), 50'000'000'000);
  EXPECT_EQ(src.counters().timeouts, 0u);
  // A burst timer 0.6 s later: the two blocks due by then come out back to back, then a poll.
  clock.advance_ns(600'000'000);
  ASSERT_EQ(src.read(*b, 0), SourceStatus::kOk);
  EXPECT_EQ(b->first_index, 0u);
  ASSERT_EQ(src.read(*b, 0), SourceStatus::kOk);
  EXPECT_EQ(b->first_index, 256u);
  EXPECT_EQ(src.read(*b, 0), SourceStatus::kTimeout);
  EXPECT_EQ(clock.sleeps(), 0u);
  EXPECT_EQ(src.counters().timeouts, 0u);
  EXPECT_EQ(src.counters().blocks, 2u);
}

TEST_F(WavReplay, TimelineAlignsSampleZeroWithTheRecordingStart) {
  cfg_.pace = ReplayPace::kAsFastAsPossible;
  cfg_.start_unix_ns = 1'700'000'010'000'000'000;            // WAV starts 10 s after ...
  cfg_.timeline.origin_unix_ns = 1'700'000'000'000'000'000;  // ... the shared origin (e.g. the CAN log's)
  cfg_.timeline.origin_mono_ns = 3'000'000'000;
  ManualClock clock(0);
  WavReplaySource src(cfg_, clock);
  src.configure();
  src.activate();
  SampleBlock b;
  ASSERT_EQ(src.read(b, 0), SourceStatus::kOk);
  EXPECT_EQ(b.t_mono_ns, 13'000'000'000);
  EXPECT_EQ(src.sample_time_ns(1000), 14'000'000'000);
}

TEST_F(WavReplay, SampleTimesStayExactOverHours) {
  std::vector<float> x(25600, 0.0F);
  formats::write_wav(dir_ / "fast.wav", 25600, formats::WavSampleFormat::kFloat32, {x});
  cfg_.path = dir_ / "fast.wav";
  cfg_.timeline.origin_mono_ns = 0;
  ManualClock clock(0);
  WavReplaySource src(cfg_, clock);
  src.configure();
  src.activate();
  EXPECT_EQ(src.sample_time_ns(25600ULL * 3600), 3600LL * 1'000'000'000);
  EXPECT_EQ(src.sample_time_ns(25600ULL * 3600 + 1), 3600LL * 1'000'000'000 + 39063);  // 39062.5 rounded
}

TEST_F(WavReplay, ConfigureErrorsNameTheFile) {
  ManualClock clock(0);
  cfg_.channel = 2;
  WavReplaySource bad_channel(cfg_, clock);
  EXPECT_THROW(bad_channel.configure(), Error);
  cfg_.channel = 0;
  cfg_.block_len = kMaxBlock + 1;
  WavReplaySource bad_block(cfg_, clock);
  EXPECT_THROW(bad_block.configure(), Error);
  cfg_.block_len = 16;
  cfg_.path = dir_ / "missing.wav";
  WavReplaySource missing(cfg_, clock);
  try {
    missing.configure();
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("missing.wav"), std::string::npos) << e.what();
  }
  SampleBlock b;
  EXPECT_EQ(missing.read(b, 0), SourceStatus::kNotActive);
}

// The file is read kReadAheadBlocks blocks at a time; the blocks that come out are the ones a
// block-by-block read gives: the same boundaries (the last one short), samples and timestamps.
TEST_F(WavReplay, ReadsSeveralBlocksPerFileReadWithTheSameBlocks) {
  cfg_.pace = ReplayPace::kAsFastAsPossible;
  cfg_.channel = 1;
  cfg_.scale = 0.5F;
  cfg_.block_len = 32;  // 1000 samples: 31 blocks of 32 and one of 8, 512 samples per file read
  cfg_.timeline.origin_mono_ns = 1'000'000'000;
  ManualClock clock(0);
  WavReplaySource src(cfg_, clock);
  src.configure();
  src.activate();
  const std::vector<float> file = formats::read_wav_channel(wav_, 1);
  ASSERT_EQ(file.size(), 1000u);
  auto b = std::make_unique<SampleBlock>();
  std::uint64_t next = 0;
  for (std::uint64_t k = 0; k < 32; ++k) {
    ASSERT_EQ(src.read(*b, 0), SourceStatus::kOk) << k;
    EXPECT_EQ(b->first_index, next) << k;
    EXPECT_EQ(b->count, k < 31 ? 32u : 8u) << k;
    EXPECT_EQ(b->t_mono_ns, 1'000'000'000 + static_cast<std::int64_t>(next) * 1'000'000) << k;
    for (std::uint32_t i = 0; i < b->count; ++i)
      ASSERT_EQ(b->samples[i], file[next + i] * 0.5F) << "block " << k << " sample " << i;
    next += b->count;
  }
  EXPECT_EQ(next, 1000u);
  EXPECT_EQ(src.read(*b, 0), SourceStatus::kEndOfStream);
  EXPECT_EQ(src.counters().blocks, 32u);
  EXPECT_EQ(src.counters().samples, 1000u);
  // Two file reads (512 + 488 samples) instead of 32.
  EXPECT_EQ(src.file_reads(), 2u);
  // activate() rewinds and reads ahead again from sample 0.
  src.activate();
  ASSERT_EQ(src.read(*b, 0), SourceStatus::kOk);
  EXPECT_EQ(b->first_index, 0u);
  EXPECT_EQ(b->samples[31], file[31] * 0.5F);
  EXPECT_EQ(src.file_reads(), 1u);
}

// A block read ahead is still released only when its last sample is due: the pacing is the one of
// a block-by-block read, and a poll before that time finds nothing even with the block in memory.
TEST_F(WavReplay, BlocksReadAheadAreReleasedOnTheirOwnTime) {
  cfg_.block_len = 32;
  ManualClock clock(50'000'000'000);
  WavReplaySource src(cfg_, clock);
  src.configure();
  src.activate();  // sample 0 at the clock's 50 s; block k's last sample at 50 s + (32 k + 31) ms
  auto b = std::make_unique<SampleBlock>();
  EXPECT_EQ(src.read(*b, 0), SourceStatus::kTimeout);  // block 0 is read ahead, due at 50.031 s
  EXPECT_EQ(src.file_reads(), 1u);
  clock.set_ns(50'031'000'000);
  ASSERT_EQ(src.read(*b, 0), SourceStatus::kOk);
  EXPECT_EQ(b->first_index, 0u);
  // Block 1 is in memory but due at 50.063 s: a poll returns nothing, a short wait times out.
  EXPECT_EQ(src.read(*b, 0), SourceStatus::kTimeout);
  clock.set_ns(50'062'000'000);
  EXPECT_EQ(src.read(*b, 999'999), SourceStatus::kTimeout);  // wakes 1 ns before it is due
  EXPECT_EQ(clock.now_ns(), 50'062'999'999);
  EXPECT_EQ(src.counters().timeouts, 1u);
  EXPECT_EQ(src.read(*b, 0), SourceStatus::kTimeout);
  clock.advance_ns(1);
  ASSERT_EQ(src.read(*b, 0), SourceStatus::kOk);
  EXPECT_EQ(b->first_index, 32u);
  EXPECT_EQ(b->t_mono_ns, 50'032'000'000);
  // The rest with waits: each block wakes the reader exactly at its due time.
  for (std::uint64_t k = 2; k < 32; ++k) {
    const std::uint32_t count = k < 31 ? 32u : 8u;
    ASSERT_EQ(src.read(*b, 1'000'000'000), SourceStatus::kOk) << k;
    EXPECT_EQ(b->first_index, 32 * k) << k;
    EXPECT_EQ(b->count, count) << k;
    EXPECT_EQ(b->t_mono_ns, 50'000'000'000 + static_cast<std::int64_t>(32 * k) * 1'000'000) << k;
    EXPECT_EQ(clock.now_ns(), 50'000'000'000 + static_cast<std::int64_t>(32 * k + count - 1) * 1'000'000)
        << k;
  }
  EXPECT_EQ(src.read(*b, 1'000'000'000), SourceStatus::kEndOfStream);
  EXPECT_EQ(src.file_reads(), 2u);
  EXPECT_EQ(src.counters().blocks, 32u);
}

// A file cut short while it is replayed (the reader refuses one already cut at open): the
// multi-block read that meets the cut fails, and the source falls back to block by block from where
// it started, so every complete block before the cut still comes out, then the read error of a
// block-by-block replay.
TEST_F(WavReplay, ATruncatedFileDeliversTheBlocksBeforeTheCut) {
  cfg_.pace = ReplayPace::kAsFastAsPossible;
  cfg_.block_len = 32;  // reads of 512: the second one (512..999) meets the cut, in block 21 (672..703)
  ManualClock clock(0);
  WavReplaySource src(cfg_, clock);
  src.configure();
  EXPECT_EQ(src.total_samples(), 1000u);  // the header's count
  // Cut the data chunk (the file's last chunk; 2 x PCM16 = 4 bytes a frame) after frame 700.
  fs::resize_file(wav_, fs::file_size(wav_) - 300 * 4);
  src.activate();
  auto b = std::make_unique<SampleBlock>();
  std::uint64_t next = 0;
  SourceStatus s = SourceStatus::kOk;
  while ((s = src.read(*b, 0)) == SourceStatus::kOk) {
    ASSERT_EQ(b->first_index, next);
    ASSERT_EQ(b->count, 32u);
    for (std::uint32_t i = 0; i < b->count; ++i)
      ASSERT_EQ(b->samples[i], static_cast<float>(next + i)) << next + i;
    next += b->count;
  }
  EXPECT_EQ(s, SourceStatus::kError);
  EXPECT_EQ(next, 21u * 32u);  // blocks 0..20: all that end before frame 700
  EXPECT_EQ(src.counters().read_errors, 1u);
  EXPECT_EQ(src.read(*b, 0), SourceStatus::kError);  // and stays in error, as before
  EXPECT_EQ(src.counters().blocks, 21u);
}

TEST_F(WavReplay, ReadNeverAllocates) {
  cfg_.pace = ReplayPace::kAsFastAsPossible;
  ManualClock clock(0);
  WavReplaySource src(cfg_, clock);
  src.configure();
  src.activate();
  auto b = std::make_unique<SampleBlock>();
  std::uint64_t n = 0;
  test::AllocScope scope;
  while (src.read(*b, 0) == SourceStatus::kOk) n += b->count;
  EXPECT_EQ(scope.count(), 0u);
  EXPECT_EQ(n, 1000u);
}

}  // namespace
}  // namespace ptda::drivers
