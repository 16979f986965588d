// IioSampleSource against a fake sysfs tree (regular files in a temp dir) and a regular file or FIFO
// standing in for /dev/iio:deviceN. The real kernel ABI differs only in that sysfs attributes validate
// what is written; what we write and in which order is checked here.
#include "adc/iio_sample_source.hpp"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "alloc_counter.hpp"
#include "ptda/common/error.hpp"

namespace fs = std::filesystem;

namespace ptda::drivers {
namespace {

fs::path make_temp_dir() {
  const char* base = std::getenv("PTDA_TEST_TMP");
  const fs::path root = base != nullptr ? fs::path(base) : fs::temp_directory_path();
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const fs::path dir = root / ("iio_" + std::string(info->test_suite_name()) + "_" + info->name() + "_" +
                               std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

void put(const fs::path& p, const std::string& text) {
  fs::create_directories(p.parent_path());
  std::ofstream(p) << text;
}

std::string get(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

constexpr std::int64_t kPeriodNs = 1'000'000;  // 1 kHz

/// A device with accel_x, accel_y (le:s24/32, indices 0 and 1) and a timestamp (index 2), as a
/// 24-bit 3-axis accelerometer driver exposes them; accel_y starts enabled so we see it switched off.
class FakeIio : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = make_temp_dir();
    sys_ = dir_ / "iio:device0";
    put(sys_ / "sampling_frequency", "4000\n");
    put(sys_ / "current_timestamp_clock", "realtime\n");
    put(sys_ / "buffer" / "enable", "1\n");  // left on by a previous run
    put(sys_ / "buffer" / "length", "128\n");
    put(sys_ / "buffer" / "watermark", "1\n");
    put(sys_ / "trigger" / "current_trigger", "\n");
    for (const auto& [name, index, type, en] :
         std::vector<std::tuple<std::string, int, std::string, std::string>>{
             {"accel_x", 0, "le:s24/32>>0", "0"},
             {"accel_y", 1, "le:s24/32>>0", "1"},
             {"timestamp", 2, "le:s64/64>>0", "0"}}) {
      put(sys_ / "scan_elements" / ("in_" + name + "_en"), en + "\n");
      put(sys_ / "scan_elements" / ("in_" + name + "_index"), std::to_string(index) + "\n");
      put(sys_ / "scan_elements" / ("in_" + name + "_type"), type + "\n");
    }
    dev_ = dir_ / "dev_iio_device0";
    put(dev_, "");
    cfg_.sysfs_dir = sys_;
    cfg_.dev_path = dev_;
    cfg_.channel = "accel_x";
    cfg_.fs_hz = 1000.0;
    cfg_.buffer_length = 512;
    cfg_.block_len = 4;
  }
  void TearDown() override { fs::remove_all(dir_); }

  /// Scans of the configured layout (accel_x + timestamp: 16 bytes), x = values[i], t = stamps[i].
  static std::vector<std::uint8_t> scans(const IioScanLayout& l, const std::vector<std::int64_t>& values,
                                         const std::vector<std::int64_t>& stamps) {
    std::vector<std::uint8_t> out(values.size() * l.scan_bytes, 0xEE);  // padding is garbage on purpose
    const int x = l.find("accel_x");
    for (std::size_t i = 0; i < values.size(); ++i) {
      std::uint8_t* s = out.data() + i * l.scan_bytes;
      encode_iio_value(s, l.elements[static_cast<std::size_t>(x)], values[i]);
      if (l.timestamp_element >= 0)
        encode_iio_value(s, l.elements[static_cast<std::size_t>(l.timestamp_element)], stamps[i]);
    }
    return out;
  }
  void append_dev(const std::vector<std::uint8_t>& bytes) {
    std::ofstream f(dev_, std::ios::binary | std::ios::app);
    f.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  }

  fs::path dir_, sys_, dev_;
  IioSourceConfig cfg_;
  ManualClock clock_{0};
};

TEST_F(FakeIio, ConfigureAndActivateWriteTheSetupSequence) {
  cfg_.trigger = "hrtimer-ptda";
  cfg_.watermark = 64;
  IioSampleSource src(cfg_, clock_);
  src.configure();
  EXPECT_EQ(get(sys_ / "buffer" / "enable"), "0\n");
  EXPECT_EQ(get(sys_ / "sampling_frequency"), "1000\n");
  EXPECT_DOUBLE_EQ(src.fs_hz(), 1000.0);
  EXPECT_EQ(get(sys_ / "current_timestamp_clock"), "monotonic\n");
  EXPECT_EQ(get(sys_ / "scan_elements" / "in_accel_x_en"), "1\n");
  EXPECT_EQ(get(sys_ / "scan_elements" / "in_accel_y_en"), "0\n");
  EXPECT_EQ(get(sys_ / "scan_elements" / "in_timestamp_en"), "1\n");
  EXPECT_EQ(get(sys_ / "trigger" / "current_trigger"), "hrtimer-ptda\n");
  EXPECT_EQ(get(sys_ / "buffer" / "length"), "512\n");
  EXPECT_EQ(get(sys_ / "buffer" / "watermark"), "64\n");
  // accel_x at 0 (4 bytes), timestamp at 8: 16-byte scans.
  ASSERT_EQ(src.layout().elements.size(), 2u);
  EXPECT_EQ(src.layout().scan_bytes, 16u);
  EXPECT_EQ(src.layout().elements[1].offset, 8u);

  SampleBlock b;
  EXPECT_EQ(src.read(b, 0), SourceStatus::kNotActive);
  src.activate();
  EXPECT_EQ(get(sys_ / "buffer" / "enable"), "1\n");
  src.deactivate();
  EXPECT_EQ(get(sys_ / "buffer" / "enable"), "0\n");
}

TEST_F(FakeIio, RateIsReadBackFromTheDriver) {
  cfg_.fs_hz = 0.0;  // keep the device's rate
  IioSampleSource src(cfg_, clock_);
  src.configure();
  EXPECT_DOUBLE_EQ(src.fs_hz(), 4000.0);
  EXPECT_EQ(get(sys_ / "sampling_frequency"), "4000\n");
}

TEST_F(FakeIio, ReadsDecodesScalesAndStampsBlocks) {
  cfg_.scale = 0.5F;
  auto src = std::make_unique<IioSampleSource>(cfg_, clock_);
  src->configure();
  const std::int64_t t0 = 5'000'000'000;
  std::vector<std::int64_t> v, t;
  for (int i = 0; i < 10; ++i) {
    v.push_back(-1000 * i - 3);
    t.push_back(t0 + i * kPeriodNs);
  }
  v[9] = -8388608;  // most negative 24-bit code
  append_dev(scans(src->layout(), v, t));
  src->activate();

  auto b = std::make_unique<SampleBlock>();
  ASSERT_EQ(src->read(*b, 0), SourceStatus::kOk);
  EXPECT_EQ(b->count, 4u);
  EXPECT_EQ(b->first_index, 0u);
  EXPECT_EQ(b->t_mono_ns, t0);
  EXPECT_EQ(b->flags, 0u);
  EXPECT_FLOAT_EQ(b->samples[0], -1.5F);
  EXPECT_FLOAT_EQ(b->samples[3], -1501.5F);
  ASSERT_EQ(src->read(*b, 0), SourceStatus::kOk);
  EXPECT_EQ(b->count, 4u);
  EXPECT_EQ(b->first_index, 4u);
  EXPECT_EQ(b->t_mono_ns, t0 + 4 * kPeriodNs);
  ASSERT_EQ(src->read(*b, 0), SourceStatus::kOk);
  EXPECT_EQ(b->count, 2u);
  EXPECT_EQ(b->first_index, 8u);
  EXPECT_FLOAT_EQ(b->samples[1], -4194304.0F);
  EXPECT_EQ(src->read(*b, 0), SourceStatus::kEndOfStream);  // a regular file ends

  const SampleSourceCounters c = src->counters();
  EXPECT_EQ(c.blocks, 3u);
  EXPECT_EQ(c.samples, 10u);
  EXPECT_EQ(c.gaps, 0u);
  EXPECT_EQ(c.end_of_stream, 1u);
}

TEST_F(FakeIio, TimestampGapStartsANewFlaggedBlockAndAdvancesTheIndex) {
  cfg_.block_len = 8;
  IioSampleSource src(cfg_, clock_);
  src.configure();
  std::vector<std::int64_t> v, t;
  for (int i = 0; i < 10; ++i) {
    v.push_back(i);
    // Scans 5.. arrive 4 periods after scan 4: three scans were lost in between.
    t.push_back(i < 5 ? i * kPeriodNs : (i + 3) * kPeriodNs);
  }
  append_dev(scans(src.layout(), v, t));
  src.activate();
  auto b = std::make_unique<SampleBlock>();
  ASSERT_EQ(src.read(*b, 0), SourceStatus::kOk);
  EXPECT_EQ(b->count, 5u);  // cut at the discontinuity although 8 were available
  EXPECT_EQ(b->flags, 0u);
  ASSERT_EQ(src.read(*b, 0), SourceStatus::kOk);
  EXPECT_EQ(b->count, 5u);
  EXPECT_EQ(b->flags, static_cast<std::uint32_t>(kBlockGap));
  EXPECT_EQ(b->gap_samples, 3u);
  EXPECT_EQ(b->first_index, 8u);  // 5 delivered + 3 lost
  EXPECT_EQ(b->t_mono_ns, 8 * kPeriodNs);
  EXPECT_FLOAT_EQ(b->samples[0], 5.0F);
  const SampleSourceCounters c = src.counters();
  EXPECT_EQ(c.gaps, 1u);
  EXPECT_EQ(c.lost_samples, 3u);
}

// Found by fuzz_iio_sysfs: t - last_ts overflowed int64 (UB) for far-apart garbage timestamps, and
// the wrapped difference made a forward jump look like a step backwards.
TEST_F(FakeIio, TimestampJumpBeyondInt64IsAGapNotUb) {
  IioSampleSource src(cfg_, clock_);
  src.configure();
  append_dev(scans(src.layout(), {1, 2}, {-6'836'464'234'348'412'928, 8'192'047'722'186'932'224}));
  src.activate();
  auto b = std::make_unique<SampleBlock>();
  ASSERT_EQ(src.read(*b, 0), SourceStatus::kOk);
  EXPECT_EQ(b->count, 1u);
  ASSERT_EQ(src.read(*b, 0), SourceStatus::kOk);
  EXPECT_EQ(b->count, 1u);
  EXPECT_EQ(b->flags, static_cast<std::uint32_t>(kBlockGap));
  EXPECT_EQ(b->gap_samples, 4'000'000'000u);  // the lost-sample estimate is capped
  const SampleSourceCounters c = src.counters();
  EXPECT_EQ(c.gaps, 1u);
  EXPECT_EQ(c.time_back, 0u);
}

TEST_F(FakeIio, JitterWithinToleranceIsNotAGap) {
  IioSampleSource src(cfg_, clock_);
  src.configure();
  // 1.4 periods (below the 1.5 limit) between scans 1 and 2, 0.6 between 2 and 3.
  append_dev(scans(src.layout(), {1, 2, 3, 4}, {0, kPeriodNs, 2'400'000, 3'000'000}));
  src.activate();
  SampleBlock b;
  ASSERT_EQ(src.read(b, 0), SourceStatus::kOk);
  EXPECT_EQ(b.count, 4u);
  EXPECT_EQ(b.flags, 0u);
}

TEST_F(FakeIio, TimestampGoingBackwardsIsFlaggedAndCounted) {
  IioSampleSource src(cfg_, clock_);
  src.configure();
  append_dev(
      scans(src.layout(), {1, 2, 3, 4}, {10 * kPeriodNs, 11 * kPeriodNs, 3 * kPeriodNs, 4 * kPeriodNs}));
  src.activate();
  SampleBlock b;
  ASSERT_EQ(src.read(b, 0), SourceStatus::kOk);
  EXPECT_EQ(b.count, 2u);
  ASSERT_EQ(src.read(b, 0), SourceStatus::kOk);
  EXPECT_EQ(b.count, 2u);
  EXPECT_EQ(b.flags, static_cast<std::uint32_t>(kBlockTimeBack));
  EXPECT_EQ(b.first_index, 2u);
  EXPECT_EQ(src.counters().time_back, 1u);
}

TEST_F(FakeIio, WithoutTimestampChannelTheClockStampsTheBlock) {
  cfg_.timestamp = false;
  IioSampleSource src(cfg_, clock_);
  src.configure();
  EXPECT_EQ(get(sys_ / "scan_elements" / "in_timestamp_en"), "0\n");
  EXPECT_EQ(src.layout().scan_bytes, 4u);
  EXPECT_EQ(src.layout().timestamp_element, -1);
  append_dev(scans(src.layout(), {7, 8, 9}, {}));
  src.activate();
  clock_.set_ns(10'000'000'000);
  SampleBlock b;
  ASSERT_EQ(src.read(b, 0), SourceStatus::kOk);
  EXPECT_EQ(b.count, 3u);
  EXPECT_EQ(b.t_mono_ns, 10'000'000'000 - 3 * kPeriodNs);  // read time minus the block's duration
  EXPECT_EQ(b.flags, static_cast<std::uint32_t>(kBlockClockTime));
}

TEST_F(FakeIio, PartialScansFromAFifoAreCompletedCountedAndFlagged) {
  fs::remove(dev_);
  ASSERT_EQ(::mkfifo(dev_.c_str(), 0600), 0);
  IioSampleSource src(cfg_, clock_);
  src.configure();  // opens the read end non-blocking
  const int w = ::open(dev_.c_str(), O_WRONLY | O_NONBLOCK | O_CLOEXEC);
  ASSERT_GE(w, 0);
  src.activate();
  SampleBlock b;
  EXPECT_EQ(src.read(b, 0), SourceStatus::kTimeout);  // nothing written yet: poll times out

  const auto bytes = scans(src.layout(), {11, 12, 13}, {0, kPeriodNs, 2 * kPeriodNs});
  ASSERT_EQ(::write(w, bytes.data(), 24), 24);  // one and a half scans
  ASSERT_EQ(src.read(b, 0), SourceStatus::kOk);
  EXPECT_EQ(b.count, 1u);
  EXPECT_FLOAT_EQ(b.samples[0], 11.0F);
  EXPECT_EQ(b.flags, static_cast<std::uint32_t>(kBlockShortRead));
  EXPECT_EQ(src.counters().short_reads, 1u);

  EXPECT_EQ(src.read(b, 0), SourceStatus::kTimeout);  // only half a scan buffered
  ASSERT_EQ(::write(w, bytes.data() + 24, 24), 24);   // the rest of scan 2 and scan 3
  ASSERT_EQ(src.read(b, 0), SourceStatus::kOk);
  EXPECT_EQ(b.count, 2u);
  EXPECT_EQ(b.first_index, 1u);
  EXPECT_EQ(b.t_mono_ns, kPeriodNs);
  EXPECT_FLOAT_EQ(b.samples[0], 12.0F);
  EXPECT_FLOAT_EQ(b.samples[1], 13.0F);
  EXPECT_EQ(b.flags, 0u);
  EXPECT_EQ(src.counters().short_reads, 1u);
  EXPECT_EQ(src.counters().timeouts, 0u);  // reads with timeout 0 poll: not counted as timeouts
  EXPECT_EQ(src.read(b, 1'000'000), SourceStatus::kTimeout);  // a read that waited in vain counts
  EXPECT_EQ(src.counters().timeouts, 1u);
  ::close(w);
  EXPECT_EQ(src.read(b, 0), SourceStatus::kEndOfStream);  // writer gone
}

TEST_F(FakeIio, UnknownChannelNamesTheAvailableOnes) {
  cfg_.channel = "accel_q";
  IioSampleSource src(cfg_, clock_);
  try {
    src.configure();
    FAIL() << "expected ptda::Error";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("no channel 'accel_q'"), std::string::npos) << what;
    EXPECT_NE(what.find("accel_x, accel_y, timestamp"), std::string::npos) << what;
  }
}

TEST_F(FakeIio, MissingAttributeOrDeviceIsAnErrorNamingTheFile) {
  fs::remove(sys_ / "buffer" / "length");
  {
    IioSampleSource src(cfg_, clock_);
    try {
      src.configure();
      FAIL() << "expected ptda::Error";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("buffer/length"), std::string::npos) << e.what();
    }
  }
  put(sys_ / "buffer" / "length", "0\n");
  fs::remove(dev_);
  IioSampleSource src(cfg_, clock_);
  EXPECT_THROW(src.configure(), Error);
  cfg_.sysfs_dir = dir_ / "iio:device9";
  IioSampleSource none(cfg_, clock_);
  EXPECT_THROW(none.configure(), Error);
}

TEST_F(FakeIio, BadTypeOrRateIsAnError) {
  put(sys_ / "scan_elements" / "in_accel_x_type", "le:s24/24>>0\n");
  IioSampleSource src(cfg_, clock_);
  EXPECT_THROW(src.configure(), Error);
  put(sys_ / "scan_elements" / "in_accel_x_type", "le:s24/32>>0\n");
  cfg_.fs_hz = 0;
  put(sys_ / "sampling_frequency", "fast\n");
  IioSampleSource src2(cfg_, clock_);
  EXPECT_THROW(src2.configure(), Error);
}

// strtod/stoul used to take "4000 Hz" as 4000 and "-1" as index 4294967295 (wrapped).
TEST_F(FakeIio, SysfsValuesAreParsedStrictly) {
  cfg_.fs_hz = 0;
  put(sys_ / "sampling_frequency", "4000 Hz\n");
  IioSampleSource src(cfg_, clock_);
  EXPECT_THROW(src.configure(), Error);
  put(sys_ / "sampling_frequency", "4000\n");
  put(sys_ / "scan_elements" / "in_accel_x_index", "-1\n");
  IioSampleSource src2(cfg_, clock_);
  try {
    src2.configure();
    ADD_FAILURE() << "index -1 accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("in_accel_x_index: not a scan index: '-1'"), std::string::npos)
        << e.what();
  }
}

TEST_F(FakeIio, ReadNeverAllocates) {
  cfg_.block_len = 64;
  IioSampleSource src(cfg_, clock_);
  src.configure();
  std::vector<std::int64_t> v(1000), t(1000);
  for (int i = 0; i < 1000; ++i) {
    v[static_cast<std::size_t>(i)] = i;
    t[static_cast<std::size_t>(i)] = (i < 500 ? i : i + 10) * kPeriodNs;  // one gap on the way
  }
  append_dev(scans(src.layout(), v, t));
  src.activate();
  auto b = std::make_unique<SampleBlock>();
  std::uint64_t total = 0;
  test::AllocScope scope;
  while (src.read(*b, 0) == SourceStatus::kOk) total += b->count;
  EXPECT_EQ(scope.count(), 0u);
  EXPECT_EQ(total, 1000u);
  EXPECT_EQ(src.counters().lost_samples, 10u);
}

}  // namespace
}  // namespace ptda::drivers
