#include "training/field_trainer.hpp"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <numbers>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "alloc_counter.hpp"
#include "ptda/common/error.hpp"
#include "ptda/formats/baseline_file.hpp"

namespace fs = std::filesystem;

namespace ptda::daemon {
namespace {

constexpr std::uint32_t kLen = 64;
constexpr double kFs = 1000.0;
constexpr double kFwd = 0.5;    // rad/s, class 0
constexpr double kBack = -0.3;  // rad/s, class 1

fs::path scratch(const std::string& name) {
  const char* base = std::getenv("PTDA_TEST_TMP");
  fs::path dir = fs::path(base != nullptr ? base : "/tmp") / "field_trainer_test" / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

FieldTrainerConfig config() {
  FieldTrainerConfig c;
  // Per test: ctest runs the tests of this file in parallel processes, and scratch() clears its directory.
  c.spill_dir =
      scratch(std::string("spill_") + ::testing::UnitTest::GetInstance()->current_test_info()->name());
  c.fs_hz = kFs;
  c.window_len = kLen;
  c.max_windows = 100;
  c.max_regions = 50;
  c.target_cycles = 4;
  c.classes.min_regions = 3;
  c.source = "test";
  return c;
}

/// Feeds cycles like the processing thread would: per cycle one region with `windows` disjoint
/// windows (a healthy sine plus noise), then the region once it ended.
class Feeder {
 public:
  explicit Feeder(FieldTrainer& t) : t_(t) {}
  void cycle(double speed_rad_s, int windows = 2) {
    const std::uint64_t region = next_region_++;
    const std::int64_t first = static_cast<std::int64_t>(region) * 1000;
    for (int k = 0; k < windows; ++k) {
      dsp::WindowRef ref;
      ref.seq = next_window_++;
      ref.region_seq = region;
      ref.index_in_region = static_cast<std::uint32_t>(k);
      ref.first_sample = first + k * static_cast<std::int64_t>(kLen);
      ref.t_start_ns = ref.first_sample * 1'000'000;
      ref.t_end_ns = ref.t_start_ns + kLen * 1'000'000;
      ref.speed_rad_s = speed_rad_s;
      std::vector<float> x(kLen);
      std::normal_distribution<float> noise(0.0F, 0.05F);
      for (std::uint32_t n = 0; n < kLen; ++n) {
        x[n] = static_cast<float>(std::sin(2.0 * std::numbers::pi * 8.0 * n / kLen)) + noise(rng_);
      }
      EXPECT_TRUE(t_.add_window(ref, x));
      t_.flush();  // as the writer thread would (these tests do not start it)
    }
    dsp::RegionInfo r;
    r.seq = region;
    r.t_begin_ns = first * 1'000'000;
    r.t_end_ns = r.t_begin_ns + 500'000'000;
    r.mean_speed_rad_s = speed_rad_s;
    r.direction = speed_rad_s < 0 ? -1 : 1;
    EXPECT_TRUE(t_.add_region(r));
  }

 private:
  FieldTrainer& t_;
  std::mt19937 rng_{42};
  std::uint64_t next_region_ = 0;
  std::uint64_t next_window_ = 0;
};

std::string what_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no exception)";
}

TEST(FieldTrainer, ProgressCountsCyclesAndWindowsPerClass) {
  FieldTrainer t(config());
  Feeder f(t);
  TrainingProgress p = t.progress();
  EXPECT_TRUE(p.classes.empty());
  EXPECT_FALSE(p.ready);
  EXPECT_FALSE(p.can_finish);
  EXPECT_EQ(p.window_capacity, 100U);

  f.cycle(kFwd, 3);
  f.cycle(kBack, 2);
  f.cycle(kFwd, 3);
  p = t.progress();
  ASSERT_EQ(p.classes.size(), 2U);
  EXPECT_EQ(p.target_cycles, 4U);
  EXPECT_EQ(p.windows, 8U);
  EXPECT_EQ(p.regions, 3U);
  // Forward classes first.
  EXPECT_EQ(p.classes[0].segment.direction, 1);
  EXPECT_DOUBLE_EQ(p.classes[0].segment.speed_rad_s, 0.5);
  EXPECT_EQ(p.classes[0].cycles, 2U);
  EXPECT_EQ(p.classes[0].windows, 6U);
  EXPECT_EQ(p.classes[0].groups, 6U);
  EXPECT_FALSE(p.classes[0].trainable);  // 2 < min_regions 3
  EXPECT_EQ(p.classes[1].segment.direction, -1);
  EXPECT_EQ(p.classes[1].cycles, 1U);
  EXPECT_EQ(p.classes[1].windows, 2U);
  EXPECT_EQ(p.classes_trainable, 0U);
  EXPECT_FALSE(p.can_finish);

  f.cycle(kFwd, 1);
  p = t.progress();
  EXPECT_EQ(p.classes[0].cycles, 3U);
  EXPECT_TRUE(p.classes[0].trainable);
  EXPECT_FALSE(p.classes[0].complete);  // 3 < target 4
  EXPECT_TRUE(p.can_finish);
  EXPECT_FALSE(p.ready);

  // A window whose speed matches no class seen so far; queued, it is not counted before it is written.
  dsp::WindowRef stray;
  stray.speed_rad_s = 2.0;
  EXPECT_TRUE(t.add_window(stray, std::vector<float>(kLen, 0.0F)));
  EXPECT_EQ(t.progress().windows_queued, 1U);
  EXPECT_EQ(t.progress().windows_unmatched, 0U);
  t.flush();
  EXPECT_EQ(t.progress().windows_queued, 0U);
  EXPECT_EQ(t.progress().windows_unmatched, 1U);
}

TEST(FieldTrainer, ReadyWhenEveryClassHasItsCyclesAndTheBaselineReadsBack) {
  FieldTrainer t(config());
  Feeder f(t);
  for (int c = 0; c < 4; ++c) {
    f.cycle(kFwd);
    ASSERT_FALSE(t.progress().ready);
    f.cycle(kBack);
  }
  const TrainingProgress p = t.progress();
  EXPECT_TRUE(p.ready);
  EXPECT_EQ(p.classes_complete, 2U);

  const fs::path path = scratch("ready") / "baseline.bin";
  const dsp::Baseline b = t.finish(path);
  ASSERT_TRUE(fs::exists(path));
  const dsp::Baseline r = formats::read_baseline(path);
  EXPECT_EQ(r.window_len, kLen);
  EXPECT_DOUBLE_EQ(r.fs_hz, kFs);
  ASSERT_EQ(r.classes.size(), 2U);
  EXPECT_EQ(r.classes[0].segment.direction, 1);
  EXPECT_EQ(r.classes[0].segment.regions, 4U);
  EXPECT_EQ(r.classes[0].n_windows, 8U);
  EXPECT_EQ(r.classes[1].segment.direction, -1);
  EXPECT_DOUBLE_EQ(r.classes[1].segment.speed_rad_s, 0.3);
  EXPECT_EQ(r.source, "test: 8 regions, 16 windows");
  EXPECT_EQ(b.source, r.source);
  EXPECT_EQ(r.classes[0].mean_magnitude, b.classes[0].mean_magnitude);
  // A healthy window of the training shape is inside its own class's bands.
  EXPECT_GT(r.classes[0].thresholds[static_cast<std::size_t>(dsp::Method::kRaw)].rms.hi, 0.6);
}

TEST(FieldTrainer, FinishWithWhatIsThereTrainsTheClassesThatHaveEnough) {
  FieldTrainer t(config());
  Feeder f(t);
  for (int c = 0; c < 3; ++c) f.cycle(kFwd);
  f.cycle(kBack);
  const fs::path path = scratch("partial") / "baseline.bin";
  const std::string msg = what_of([&] { (void)t.finish(path); });
  EXPECT_NE(msg.find("field training: not ready: 0 of 2 classes complete"), std::string::npos) << msg;
  EXPECT_NE(msg.find("3/4 cycles, 6 windows in 6 groups"), std::string::npos) << msg;
  EXPECT_NE(msg.find("1/4 cycles, 2 windows in 2 groups"), std::string::npos) << msg;
  EXPECT_FALSE(fs::exists(path));

  const dsp::Baseline b = t.finish(path, FinishMode::kWhatIsThere);
  ASSERT_EQ(b.classes.size(), 1U);
  EXPECT_EQ(b.classes[0].segment.direction, 1);
  EXPECT_EQ(formats::read_baseline(path).classes.size(), 1U);
}

TEST(FieldTrainer, NotEnoughDataIsAClearError) {
  FieldTrainer t(config());
  const fs::path path = scratch("empty") / "baseline.bin";
  EXPECT_EQ(what_of([&] { (void)t.finish(path, FinishMode::kWhatIsThere); }),
            "field training: no constant-speed cycle seen yet (0 regions, 0 windows)");
  Feeder f(t);
  f.cycle(kFwd);
  f.cycle(kFwd);
  const std::string msg = what_of([&] { (void)t.finish(path, FinishMode::kWhatIsThere); });
  EXPECT_EQ(msg,
            "field training: not enough data: no class has enough (a class needs >= 3 cycles and >= 3 "
            "non-overlapping windows to train, 4 cycles to be complete); class 0 (+0.5 rad/s): 2/4 cycles, "
            "4 windows in 4 groups");
  EXPECT_FALSE(fs::exists(path));
}

TEST(FieldTrainer, FullPoolIsCountedAndRejectedWindowsToo) {
  FieldTrainerConfig c = config();
  c.max_windows = 5;
  c.max_regions = 2;
  FieldTrainer t(c);
  const std::vector<float> x(kLen, 0.25F);
  dsp::WindowRef ref;
  for (int i = 0; i < 7; ++i) t.add_window(ref, x);
  EXPECT_FALSE(t.add_window(ref, x));
  t.flush();
  dsp::RegionInfo r;
  r.mean_speed_rad_s = 0.5;
  EXPECT_TRUE(t.add_region(r));
  EXPECT_TRUE(t.add_region(r));
  EXPECT_FALSE(t.add_region(r));
  r.mean_speed_rad_s = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(t.add_region(r));
  const TrainingProgress p = t.progress();
  EXPECT_EQ(p.windows, 5U);
  EXPECT_EQ(p.windows_dropped, 3U);
  EXPECT_EQ(t.counters().windows_dropped, 3U);
  EXPECT_EQ(t.counters().windows_queue_full, 0U);
  EXPECT_EQ(p.regions_dropped, 1U);
  EXPECT_EQ(p.windows_rejected, 1U);  // the NaN region

  std::vector<float> bad(kLen, 0.0F);
  bad[10] = std::numeric_limits<float>::infinity();
  FieldTrainer u(c);
  EXPECT_FALSE(u.add_window(ref, bad));
  EXPECT_FALSE(u.add_window(ref, std::vector<float>(kLen - 1, 0.0F)));
  EXPECT_TRUE(u.add_window(ref, x));
  u.flush();
  const FieldTrainerCounters k = u.counters();
  EXPECT_EQ(k.windows, 1U);
  EXPECT_EQ(k.windows_rejected, 2U);
  EXPECT_EQ(u.progress().windows, 1U);
}

// The windows live on disk, not in RAM: a writer that falls behind costs windows (counted), never
// memory, and the processing thread never waits for it.
TEST(FieldTrainer, AFullQueueIsCountedAndTheSpillFileLeavesNothingBehind) {
  const FieldTrainerConfig c = config();
  FieldTrainer t(c);
  // The spill file is anonymous: nothing in the directory, during training or after.
  EXPECT_TRUE(fs::is_empty(c.spill_dir));
  const std::vector<float> x(kLen, 0.5F);
  dsp::WindowRef ref;
  int accepted = 0;
  for (std::size_t i = 0; i < FieldTrainer::kSpillSlots + 3; ++i) accepted += t.add_window(ref, x) ? 1 : 0;
  EXPECT_EQ(accepted, static_cast<int>(FieldTrainer::kSpillSlots));
  EXPECT_EQ(t.free_slots(), 0U);
  EXPECT_EQ(t.counters().windows_queue_full, 3U);
  EXPECT_EQ(t.progress().windows_dropped, 3U);
  t.flush();
  EXPECT_EQ(t.free_slots(), FieldTrainer::kSpillSlots);
  EXPECT_EQ(t.progress().windows, FieldTrainer::kSpillSlots);
  EXPECT_TRUE(t.add_window(ref, x));
  EXPECT_TRUE(fs::is_empty(c.spill_dir));
}

// Configure checks the room for the spill file: a warning (not an error: the windows that fit still
// train) naming the directory, the sizes and the fix.
TEST(FieldTrainer, TooLittleRoomForTheSpillFileIsSaid) {
  EXPECT_EQ(
      FieldTrainer::spill_space_text("/var/lib/ptda", std::uint64_t{200} << 20, std::uint64_t{150} << 20),
      "field training: the spill file in /var/lib/ptda may grow to 200 MiB ([training] max_windows x "
      "window_len x 4 bytes) but 150 MiB are free there: windows that do not fit will be dropped "
      "(training.dropped); lower [training] max_windows or set [training] spill_dir");
  EXPECT_EQ(FieldTrainer::spill_space_text("/x", 100, 100), "");
  const FieldTrainer t(config());  // 100 windows of 64 samples: 25 KiB
  EXPECT_EQ(t.max_spill_bytes(), 100U * 64U * 4U);
  EXPECT_EQ(t.spill_space_warning(), "");
}

// A failing disk: the window is counted as a failed write with its errno and not published; the
// windows before it still train.
TEST(FieldTrainer, AFailedSpillWriteIsCountedWithItsErrorAndTheWindowIsNotKept) {
  FieldTrainer t(config());
  Feeder f(t);
  for (int k = 0; k < 3; ++k) f.cycle(kFwd);
  const int full = ::open("/dev/full", O_WRONLY | O_CLOEXEC);
  ASSERT_GE(full, 0);
  const int saved = ::dup(t.spill_fd_for_test());
  ASSERT_EQ(::dup2(full, t.spill_fd_for_test()), t.spill_fd_for_test());
  const std::vector<float> x(kLen, 0.5F);
  dsp::WindowRef ref;
  ref.speed_rad_s = kFwd;
  EXPECT_TRUE(t.add_window(ref, x));  // queued: the write fails later, on the writer
  t.flush();
  const FieldTrainerCounters k = t.counters();
  EXPECT_EQ(k.windows_write_failed, 1U);
  EXPECT_EQ(k.last_write_errno, ENOSPC);
  EXPECT_EQ(k.windows, 6U);
  EXPECT_EQ(t.progress().windows_dropped, 1U);
  ASSERT_EQ(::dup2(saved, t.spill_fd_for_test()), t.spill_fd_for_test());
  ::close(saved);
  ::close(full);
  const dsp::Baseline b = t.finish(scratch("failed_write") / "baseline.bin", FinishMode::kWhatIsThere);
  ASSERT_EQ(b.classes.size(), 1U);
  EXPECT_EQ(b.classes[0].n_windows, 6U);
}

// The writer thread against the in-memory training: the spill file round trip changes no byte.
TEST(FieldTrainer, TheWriterThreadsWindowsTrainTheSameBaselineAsTheWindowsInMemory) {
  FieldTrainer t(config());
  t.start(nullptr);
  dsp::CollectedWindows mem;
  std::mt19937 rng(7);
  std::normal_distribution<float> noise(0.0F, 0.05F);
  std::uint64_t seq = 0;
  for (int cycle = 0; cycle < 8; ++cycle) {
    const double speed = cycle % 2 == 0 ? kFwd : kBack;
    for (int k = 0; k < 3; ++k) {
      dsp::WindowRef ref;
      ref.seq = seq++;
      ref.region_seq = static_cast<std::uint64_t>(cycle);
      ref.index_in_region = static_cast<std::uint32_t>(k);
      ref.first_sample = cycle * 1000 + k * static_cast<std::int64_t>(kLen);
      ref.t_start_ns = ref.first_sample * 1'000'000;
      ref.t_end_ns = ref.t_start_ns + kLen * 1'000'000;
      ref.speed_rad_s = speed;
      std::vector<float> x(kLen);
      for (std::uint32_t n = 0; n < kLen; ++n) {
        x[n] =
            static_cast<float>(std::sin(2.0 * std::numbers::pi * (cycle % 2 == 0 ? 8.0 : 5.0) * n / kLen)) +
            noise(rng);
      }
      // The processing thread never waits: a full queue here would be a drop (not expected at this pace).
      while (t.free_slots() == 0) std::this_thread::yield();
      ASSERT_TRUE(t.add_window(ref, x));
      mem.refs.push_back(ref);
      mem.windows.push_back(x);
    }
    dsp::RegionInfo r;
    r.seq = static_cast<std::uint64_t>(cycle);
    r.t_begin_ns = cycle * 1'000'000'000LL;
    r.t_end_ns = r.t_begin_ns + 500'000'000;
    r.mean_speed_rad_s = speed;
    r.direction = speed < 0 ? -1 : 1;
    ASSERT_TRUE(t.add_region(r));
    mem.regions.push_back(r);
  }
  t.stop();
  EXPECT_EQ(t.progress().windows, 24U);
  const fs::path dir = scratch("writer");
  const dsp::Baseline spilled = t.finish(dir / "spilled.bin");
  dsp::Baseline direct = dsp::train_baseline(mem, t.config().classes, t.config().thresholds, kFs, {});
  direct.source = spilled.source;
  formats::write_baseline(dir / "direct.bin", direct);
  ASSERT_EQ(spilled.classes.size(), 2U);
  std::ifstream a(dir / "spilled.bin", std::ios::binary), b(dir / "direct.bin", std::ios::binary);
  const std::string sa((std::istreambuf_iterator<char>(a)), std::istreambuf_iterator<char>());
  const std::string sb((std::istreambuf_iterator<char>(b)), std::istreambuf_iterator<char>());
  EXPECT_GT(sa.size(), 1000U);
  EXPECT_TRUE(sa == sb) << "the baseline trained from the spill file differs from the in-memory one";
}

// CI aarch64 run of session 33: under qemu the writer found the queue empty, the test then queued
// its windows and stopped, and the writer saw the stop and returned without writing them. Here the
// writer is held right after an empty drain until the window is queued and stop() asked for.
TEST(FieldTrainer, StopWritesEveryWindowQueuedBeforeIt) {
  FieldTrainer t(config());
  struct Hold {
    FieldTrainer* t;
    std::atomic<int> entered{0};
  } hold{&t};
  t.set_idle_hook_for_test(
      [](void* ctx) {
        auto* h = static_cast<Hold*>(ctx);
        if (h->entered.fetch_add(1) != 0) return;  // hold only the first idle pass
        while (!h->t->stop_requested_for_test()) std::this_thread::yield();
      },
      &hold);
  t.start(nullptr);
  while (hold.entered.load() == 0) std::this_thread::yield();
  const std::vector<float> x(kLen, 0.5F);
  ASSERT_TRUE(t.add_window(dsp::WindowRef{}, x));
  t.stop();
  EXPECT_EQ(t.progress().windows, 1U) << "the window queued before stop() was lost";
}

TEST(FieldTrainer, AddingMakesNoAllocations) {
  FieldTrainer t(config());
  const std::vector<float> x(kLen, 0.5F);
  dsp::WindowRef ref;
  dsp::RegionInfo r;
  r.mean_speed_rad_s = 0.5;
  int accepted = 0;
  {
    test::AllocScope scope;
    for (int i = 0; i < 150; ++i) {
      ref.seq = static_cast<std::uint64_t>(i);
      accepted += t.add_window(ref, x) ? 1 : 0;
      accepted += t.add_region(r) ? 1 : 0;
      if (i % 16 == 15) t.flush();  // the writer's side allocates nothing either
    }
    EXPECT_EQ(scope.count(), 0U);
  }
  EXPECT_EQ(accepted, 150);  // 100 windows + 50 regions
}

// Issue 14 item 5: a reload during field training hands the old pool to the new pipeline's trainer.
TEST(FieldTrainer, TakeOverKeepsThePoolAndNumbersNewWindowsAfterIt) {
  FieldTrainer old(config());
  Feeder f(old);
  f.cycle(kFwd, 3);
  f.cycle(kFwd, 3);
  FieldTrainerConfig next = config();
  next.target_cycles = 5;  // applies at finish: compatible
  FieldTrainer fresh(next);
  const TrainingCarryOver c = fresh.take_over(old);
  EXPECT_TRUE(c.kept);
  EXPECT_EQ(c.windows, 6U);
  EXPECT_EQ(c.regions, 2U);
  EXPECT_EQ(c.windows_lost + c.regions_lost, 0U);
  // The new pipeline's slicer numbers regions and samples from 0 again: the same numbers as the
  // copied cycle 0. Without the offset its windows would overlap cycle 0's and merge into its groups.
  Feeder g(fresh);
  g.cycle(kFwd, 3);
  const TrainingProgress p = fresh.progress();
  ASSERT_EQ(p.classes.size(), 1U);
  EXPECT_EQ(p.classes[0].cycles, 3U);
  EXPECT_EQ(p.classes[0].windows, 9U);
  EXPECT_EQ(p.classes[0].groups, 9U);
  EXPECT_EQ(p.target_cycles, 5U);
  EXPECT_EQ(fresh.counters().windows, 9U);

  // A smaller pool: what does not fit is counted as dropped.
  FieldTrainerConfig small = config();
  small.max_windows = 4;
  FieldTrainer smaller(small);
  const TrainingCarryOver s = smaller.take_over(fresh);
  EXPECT_TRUE(s.kept);
  EXPECT_EQ(s.windows, 4U);
  EXPECT_EQ(s.windows_lost, 5U);
  EXPECT_EQ(smaller.progress().windows, 4U);
  EXPECT_EQ(smaller.progress().windows_dropped, 5U);

  // Another window length or sample rate: nothing is copied, and why is said.
  FieldTrainerConfig shorter = config();
  shorter.window_len = kLen / 2;
  FieldTrainer other(shorter);
  const TrainingCarryOver o = other.take_over(fresh);
  EXPECT_FALSE(o.kept);
  EXPECT_EQ(o.why, "window_len 64 -> 32 samples");
  EXPECT_EQ(o.windows_lost, 9U);
  EXPECT_EQ(other.progress().windows, 0U);
  FieldTrainerConfig faster = config();
  faster.fs_hz = 2 * kFs;
  FieldTrainer rate(faster);
  EXPECT_EQ(rate.take_over(fresh).why, "sample rate 1000 -> 2000 Hz");
}

TEST(FieldTrainer, RejectsBadConfiguration) {
  FieldTrainerConfig c = config();
  c.window_len = 0;
  EXPECT_NE(what_of([&] { FieldTrainer t(c); }).find("training.window_len"), std::string::npos);
  c = config();
  c.fs_hz = 0.0;
  EXPECT_NE(what_of([&] { FieldTrainer t(c); }).find("training.fs_hz"), std::string::npos);
  c = config();
  c.target_cycles = 2;  // below min_regions 3
  EXPECT_NE(what_of([&] { FieldTrainer t(c); }).find("training.target_cycles"), std::string::npos);
  c = config();
  c.max_windows = 1'000'000;
  c.window_len = 32768;  // 122 GiB of disk
  EXPECT_NE(what_of([&] { FieldTrainer t(c); }).find("training.max_windows"), std::string::npos);
  c = config();
  c.spill_dir = scratch("spill_missing") / "missing";
  EXPECT_EQ(what_of([&] { FieldTrainer t(c); })
                .rfind("training.spill_dir: cannot create the field-training "
                       "spill file in " +
                           c.spill_dir.string() + ": ",
                       0),
            0U);
}

}  // namespace
}  // namespace ptda::daemon
