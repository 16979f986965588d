// The live simulator backends: exact sample times, the loop seam, CAN frames on the same anchor,
// real-time pacing on a ManualClock.
#include <gtest/gtest.h>

#include "alloc_counter.hpp"
#include "daemon_test_support.hpp"
#include "ptda/common/error.hpp"

namespace ptda::daemon::test {
namespace {

TEST(SimBackends, RecordingMatchesTheScenario) {
  const auto rec = make_sim_recording(arc_scenario(), 7);
  EXPECT_EQ(rec->fs_hz, 25600.0);
  EXPECT_EQ(rec->fs_mhz, 25'600'000);
  EXPECT_EQ(rec->samples.size(), 1'626'483U);  // pinned: the scenario's duration at 25.6 kHz
  EXPECT_EQ(rec->seed, 7U);
  EXPECT_EQ(rec->loop_ns, rec->sample_offset_ns(rec->samples.size()));
  EXPECT_EQ(rec->sample_offset_ns(25600), 1'000'000'000);
  EXPECT_EQ(rec->sample_offset_ns(1), 39'063);  // ceil(1e9 / 25600) = ceil(39062.5)
  ASSERT_GT(rec->frames.size(), 15000U);
  for (std::size_t i = 1; i < rec->frames.size(); ++i)
    ASSERT_GE(rec->frames[i].t_ns, rec->frames[i - 1].t_ns);
  EXPECT_LT(rec->frames.back().t_ns, rec->loop_ns);
  EXPECT_THROW((void)make_sim_recording(source_dir() / "no_such.toml", 0), Error);
}

TEST(SimBackends, SharedAnchorLoopsAndPaces) {
  const auto rec = make_sim_recording(arc_scenario(), 7);
  drivers::ManualClock clock(5'000'000'000);
  SimAnchor anchor;
  SimSampleSource src(rec, anchor, clock, SimSourceConfig{1000, false, true});
  SimCanChannel can(rec, anchor, clock, SimCanConfig{false, true, 16});
  src.configure();
  can.configure();
  src.activate();
  clock.advance_ns(123);  // the CAN side activates later but shares the anchor
  can.activate();
  EXPECT_EQ(anchor.t0_mono_ns, 5'000'000'000);

  drivers::SampleBlock b;
  // Real-time: the first block is due when its last sample is (index 999).
  ASSERT_EQ(src.read(b, 0), drivers::SourceStatus::kTimeout);
  ASSERT_EQ(src.read(b, 1'000'000'000), drivers::SourceStatus::kOk);  // ManualClock jumps forward
  EXPECT_EQ(b.t_mono_ns, 5'000'000'000);
  EXPECT_EQ(b.count, 1000U);
  EXPECT_EQ(clock.now_ns(), 5'000'000'000 + rec->sample_offset_ns(999));
  EXPECT_EQ(b.samples[17], rec->samples[17]);

  std::array<CanFrame, 8> frames{};
  std::size_t n = 0;
  ASSERT_EQ(can.receive(frames, n, 0), drivers::CanStatus::kOk);  // frames up to now are due
  EXPECT_EQ(frames[0].t_ns, 5'000'000'000 + rec->frames[0].t_ns);

  // Read to the loop seam: blocks never cross it, the index and the times continue.
  const std::uint64_t total = rec->samples.size();
  std::uint64_t last_end = 1000;
  std::int64_t last_t = b.t_mono_ns;
  while (last_end < total) {
    ASSERT_EQ(src.read(b, 1'000'000'000'000), drivers::SourceStatus::kOk);
    ASSERT_EQ(b.first_index, last_end);
    ASSERT_GT(b.t_mono_ns, last_t);
    last_end += b.count;
    last_t = b.t_mono_ns;
  }
  EXPECT_EQ(last_end, total);
  ASSERT_EQ(src.read(b, 1'000'000'000'000), drivers::SourceStatus::kOk);
  EXPECT_EQ(b.first_index, total);
  EXPECT_EQ(b.t_mono_ns, 5'000'000'000 + rec->loop_ns);
  EXPECT_EQ(b.samples[0], rec->samples[0]);

  // The CAN side after its own seam: frame 0 of loop 1 is loop_ns after frame 0 of loop 0.
  SimCanChannel fast(rec, anchor, clock, SimCanConfig{true, true, 16});
  fast.configure();
  fast.activate();
  std::vector<CanFrame> all(rec->frames.size() + 1);
  std::size_t got = 0;
  while (got < all.size()) {
    std::size_t k = 0;
    ASSERT_EQ(fast.receive(std::span<CanFrame>(all.data() + got, all.size() - got), k, 0),
              drivers::CanStatus::kOk);
    got += k;
  }
  EXPECT_EQ(all.back().t_ns - all.front().t_ns, rec->loop_ns);
  EXPECT_EQ(all.back().id, all.front().id);
}

TEST(SimBackends, ReadAndReceiveDoNotAllocate) {
  const auto rec = make_sim_recording(arc_scenario(), 7);
  drivers::ManualClock clock(0);
  SimAnchor anchor;
  SimSampleSource src(rec, anchor, clock, SimSourceConfig{256, true, true});
  SimCanChannel can(rec, anchor, clock, SimCanConfig{true, true, 16});
  src.configure();
  can.configure();
  src.activate();
  can.activate();
  drivers::SampleBlock b;
  std::array<CanFrame, 64> frames{};
  ptda::test::AllocScope scope;
  for (int i = 0; i < 20000; ++i) {  // > 3 loops of the recording
    (void)src.read(b, 0);
    std::size_t n = 0;
    (void)can.receive(frames, n, 0);
    (void)can.send(frames[0]);
  }
  EXPECT_EQ(scope.count(), 0U);
  EXPECT_EQ(can.sent_count(), 20000U);
}

TEST(SimBackends, SampleTimesStayExactPastAThousandSeconds) {
  SimRecording rec;
  rec.fs_hz = 25600.0;
  rec.fs_mhz = 25'600'000;
  // fs_mhz samples are 1000 s: where the 64-bit arithmetic splits the index (it once added 1 s there).
  EXPECT_EQ(rec.sample_offset_ns(25'599'999), 999'999'960'938);  // ceil(999'999'960'937.5)
  EXPECT_EQ(rec.sample_offset_ns(25'600'000), 1'000'000'000'000);
  EXPECT_EQ(rec.sample_offset_ns(25'600'001), 1'000'000'039'063);
  EXPECT_EQ(rec.sample_offset_ns(25'600ULL * 86'400), 86'400'000'000'000);  // a day
}

}  // namespace
}  // namespace ptda::daemon::test
