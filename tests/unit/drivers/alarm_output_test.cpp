#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "alarm/can_alarm_output.hpp"
#include "alarm/gpiod_output.hpp"
#include "alarm/recording_alarm_output.hpp"
#include "alloc_counter.hpp"
#include "can/candump_replay_channel.hpp"
#include "ptda/common/error.hpp"

namespace fs = std::filesystem;

namespace ptda::drivers {
namespace {

// ---- fail-safe polarity ------------------------------------------------------------------------

TEST(GpioPolarity, OnlyLevelsBelowTheTripLevelEnergiseTheLine) {
  EXPECT_EQ(gpio_logical_value(AlarmLevel::kNormal, AlarmLevel::kAlarm), 1);
  EXPECT_EQ(gpio_logical_value(AlarmLevel::kWarning, AlarmLevel::kAlarm), 1);
  EXPECT_EQ(gpio_logical_value(AlarmLevel::kAlarm, AlarmLevel::kAlarm), 0);
  EXPECT_EQ(gpio_logical_value(AlarmLevel::kFault, AlarmLevel::kAlarm), 0);
  EXPECT_EQ(gpio_logical_value(AlarmLevel::kNormal, AlarmLevel::kWarning), 1);
  EXPECT_EQ(gpio_logical_value(AlarmLevel::kWarning, AlarmLevel::kWarning), 0);
  EXPECT_EQ(gpio_logical_value(AlarmLevel::kAlarm, AlarmLevel::kFault), 1);
  EXPECT_EQ(gpio_logical_value(AlarmLevel::kFault, AlarmLevel::kFault), 0);
}

TEST(GpiodOutput, BuiltAgainstTheLibgpiodTheBuildFound) {
  // Debian 12 ships libgpiod 1.6.3; a libgpiod 2 build would report "libgpiod v2".
  EXPECT_STREQ(GpiodOutput::api_name(), "libgpiod v1");
}

TEST(GpiodOutput, RejectsATripLevelThatCouldNeverSignalHealthy) {
  GpiodOutputConfig c;
  c.trip_level = AlarmLevel::kNormal;
  EXPECT_THROW(GpiodOutput{c}, Error);
  c.trip_level = AlarmLevel::kAlarm;
  c.consumer.clear();
  EXPECT_THROW(GpiodOutput{c}, Error);
}

TEST(GpiodOutput, MissingChipIsAConfigureErrorNamingIt) {
  GpiodOutputConfig c;
  c.chip = "/dev/ptda-no-such-gpiochip";
  GpiodOutput out(c);
  try {
    out.configure();
    FAIL() << "expected ptda::Error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("/dev/ptda-no-such-gpiochip"), std::string::npos) << e.what();
  }
  EXPECT_THROW(out.activate(), Error);
  EXPECT_EQ(out.set(AlarmLevel::kNormal), OutputStatus::kNotActive);
  out.deactivate();  // harmless
}

bool any_gpiochip() {
  std::error_code ec;
  for (const auto& e : fs::directory_iterator("/dev", ec))
    if (e.path().filename().string().rfind("gpiochip", 0) == 0) return true;
  return false;
}

// Drives a real line. Opt-in only: toggling an arbitrary pin on real hardware is not safe, so the test
// needs PTDA_TEST_GPIO=<chip path>:<free line offset> (e.g. the PL061 of a qemu -M virt guest).
TEST(GpiodOutputLive, DrivesTheLineFailSafe) {
  if (!any_gpiochip()) GTEST_SKIP() << "no /dev/gpiochip* (kernel without GPIOLIB / GPIO_CDEV)";
  const char* spec = std::getenv("PTDA_TEST_GPIO");
  if (spec == nullptr) GTEST_SKIP() << "set PTDA_TEST_GPIO=/dev/gpiochipN:<free line> to drive a real line";
  const std::string s(spec);
  const auto colon = s.rfind(':');
  ASSERT_NE(colon, std::string::npos) << "PTDA_TEST_GPIO must be <chip>:<line>";
  GpiodOutputConfig c;
  c.chip = s.substr(0, colon);
  c.line = static_cast<unsigned>(std::stoul(s.substr(colon + 1)));
  c.consumer = "ptda-unit-test";
  GpiodOutput out(c);
  out.configure();
  out.activate();
  EXPECT_EQ(out.driven_value(), 0);  // tripped until the first verdict
  EXPECT_EQ(out.set(AlarmLevel::kNormal), OutputStatus::kOk);
  EXPECT_EQ(out.driven_value(), 1);
  EXPECT_EQ(out.set(AlarmLevel::kAlarm), OutputStatus::kOk);
  EXPECT_EQ(out.driven_value(), 0);
  EXPECT_EQ(out.set(AlarmLevel::kNormal), OutputStatus::kOk);
  out.deactivate();
  EXPECT_EQ(out.driven_value(), -1);
}

// ---- CAN alarm frame -----------------------------------------------------------------------------

TEST(CanAlarmFrame, LayoutIsPinned) {
  AlarmReport r;
  r.level = AlarmLevel::kAlarm;
  r.causes = kCauseRms | kCauseEntropy;
  r.segment_class = 3;
  r.abnormal_windows = 4;
  r.rms = 1.25F;
  r.entropy = 0.875F;
  const CanAlarmConfig c;  // id 0x3A0, rms lsb 1e-3, entropy lsb 1e-4
  const CanFrame f = encode_alarm_frame(r, c, 1);
  EXPECT_EQ(f.id, 0x3A0u);
  EXPECT_EQ(f.flags, 0);
  ASSERT_EQ(f.len, 8);
  EXPECT_EQ(f.data[0], 0x12);  // alive 1, level 2
  EXPECT_EQ(f.data[1], 0x03);
  EXPECT_EQ(f.data[2], 3);
  EXPECT_EQ(f.data[3], 4);
  EXPECT_EQ(f.data[4], 0xE2);  // 1250 = 0x04E2
  EXPECT_EQ(f.data[5], 0x04);
  EXPECT_EQ(f.data[6], 0x2E);  // 8750 = 0x222E
  EXPECT_EQ(f.data[7], 0x22);

  AlarmReport back;
  std::uint8_t alive = 0;
  ASSERT_TRUE(decode_alarm_frame(f, c, back, alive));
  EXPECT_EQ(alive, 1);
  EXPECT_EQ(back.level, AlarmLevel::kAlarm);
  EXPECT_EQ(back.causes, r.causes);
  EXPECT_EQ(back.segment_class, 3);
  EXPECT_EQ(back.abnormal_windows, 4);
  EXPECT_FLOAT_EQ(back.rms, 1.25F);
  EXPECT_FLOAT_EQ(back.entropy, 0.875F);

  // The band CUSUM's cause is bit 7 of byte 1 (session 13), alone here: 3A0#1280030400000000 with the
  // values zeroed.
  r.causes = kCauseBand;
  r.rms = 0.0F;
  r.entropy = 0.0F;
  const CanFrame fb = encode_alarm_frame(r, c, 1);
  EXPECT_EQ(fb.data[1], 0x80);
  ASSERT_TRUE(decode_alarm_frame(fb, c, back, alive));
  EXPECT_EQ(back.causes, kCauseBand);
}

TEST(CanAlarmFrame, SaturatesMarksUnavailableAndRejectsForeignFrames) {
  AlarmReport r;
  r.level = AlarmLevel::kFault;
  r.rms = 1000.0F;  // beyond 65.534
  r.entropy = std::nanf("");
  CanAlarmConfig c;
  c.id = 0x18FFA001;
  c.extended = true;
  const CanFrame f = encode_alarm_frame(r, c, 0x1F);  // alive keeps 4 bits
  EXPECT_TRUE(f.extended());
  EXPECT_EQ(f.data[0], 0xF3);
  EXPECT_EQ(f.data[2], kNoSegmentClass);
  EXPECT_EQ(f.data[4], 0xFE);
  EXPECT_EQ(f.data[5], 0xFF);
  EXPECT_EQ(f.data[6], 0xFF);
  EXPECT_EQ(f.data[7], 0xFF);
  AlarmReport back;
  std::uint8_t alive = 0;
  ASSERT_TRUE(decode_alarm_frame(f, c, back, alive));
  EXPECT_TRUE(std::isnan(back.entropy));
  EXPECT_FLOAT_EQ(back.rms, 65.534F);

  CanFrame other = f;
  other.id = 0x18FFA002;
  EXPECT_FALSE(decode_alarm_frame(other, c, back, alive));
  other = f;
  other.len = 7;
  EXPECT_FALSE(decode_alarm_frame(other, c, back, alive));
  other = f;
  other.data[0] |= 0x04;  // reserved bit
  EXPECT_FALSE(decode_alarm_frame(other, c, back, alive));
}

TEST(CanAlarmFrame, ConfigValidation) {
  CanAlarmConfig c;
  EXPECT_NO_THROW(validate(c));
  c.id = 0x800;
  EXPECT_THROW(validate(c), Error);
  c.extended = true;
  EXPECT_NO_THROW(validate(c));
  c.rms_lsb = 0;
  EXPECT_THROW(validate(c), Error);
  c.rms_lsb = 1e-3;
  c.entropy_lsb = -1;
  EXPECT_THROW(validate(c), Error);
}

/// A replay channel over an empty log: a CanChannel whose sent frames can be inspected.
class CanAlarmOutputTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const char* base = std::getenv("PTDA_TEST_TMP");
    const fs::path root = base != nullptr ? fs::path(base) : fs::temp_directory_path();
    dir_ = root / ("alarm_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) +
                   "_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    std::ofstream(dir_ / "empty.log") << "# nothing\n";
    CandumpReplayConfig rc;
    rc.path = dir_ / "empty.log";
    rc.tx_capacity = 64;
    channel_ = std::make_unique<CandumpReplayChannel>(rc, clock_);
    channel_->configure();
    channel_->activate();
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path dir_;
  ManualClock clock_{0};
  std::unique_ptr<CandumpReplayChannel> channel_;
};

TEST_F(CanAlarmOutputTest, StartsAndEndsInFaultAndCountsAlive) {
  CanAlarmOutput out(CanAlarmConfig{}, *channel_);
  out.configure();
  out.activate();
  ASSERT_EQ(channel_->sent_frames().size(), 1u);
  EXPECT_EQ(channel_->sent_frames()[0].data[0], 0x03);  // alive 0, fault
  EXPECT_EQ(channel_->sent_frames()[0].data[1], 0x00);

  for (int i = 0; i < 17; ++i) ASSERT_EQ(out.set(AlarmLevel::kNormal), OutputStatus::kOk);
  ASSERT_EQ(channel_->sent_frames().size(), 18u);
  EXPECT_EQ(channel_->sent_frames()[1].data[0], 0x10);   // alive 1, normal
  EXPECT_EQ(channel_->sent_frames()[15].data[0], 0xF0);  // alive 15
  EXPECT_EQ(channel_->sent_frames()[16].data[0], 0x00);  // wrapped to 0
  out.deactivate();
  ASSERT_EQ(channel_->sent_frames().size(), 19u);
  EXPECT_EQ(channel_->sent_frames()[18].data[0] & 0x03, 3);
  EXPECT_EQ(channel_->sent_frames()[18].data[1], kCauseInternal);
  EXPECT_EQ(out.set(AlarmLevel::kNormal), OutputStatus::kNotActive);
  EXPECT_EQ(out.counters().sets, 18u);
  EXPECT_EQ(out.counters().errors, 1u);
}

TEST_F(CanAlarmOutputTest, ChannelRefusalIsCountedNotThrown) {
  CanAlarmOutput out(CanAlarmConfig{}, *channel_);
  out.configure();
  out.activate();
  for (int i = 0; i < 63; ++i) ASSERT_EQ(out.set(AlarmLevel::kWarning), OutputStatus::kOk);
  EXPECT_EQ(out.set(AlarmLevel::kAlarm), OutputStatus::kError);  // the channel's tx buffer is full
  EXPECT_EQ(out.last_send_status(), CanStatus::kTxFull);
  EXPECT_EQ(out.counters().errors, 1u);
  EXPECT_EQ(out.counters().level_changes, 2u);  // fault -> warning -> alarm
}

TEST_F(CanAlarmOutputTest, SetNeverAllocates) {
  CanAlarmOutput out(CanAlarmConfig{}, *channel_);
  out.configure();
  out.activate();
  AlarmReport r;
  r.level = AlarmLevel::kAlarm;
  r.rms = 2.0F;
  test::AllocScope scope;
  for (int i = 0; i < 20; ++i) (void)out.set(r);
  EXPECT_EQ(scope.count(), 0u);
}

// ---- the kernel timer (CAN_BCM; here the replay channel's emulation of it) -------------------------

class CanAlarmKernelTimerTest : public CanAlarmOutputTest {
 protected:
  void SetUp() override {
    CanAlarmOutputTest::SetUp();
    CandumpReplayConfig rc;
    rc.path = dir_ / "empty.log";
    rc.tx_capacity = 256;
    rc.cyclic = true;
    channel_ = std::make_unique<CandumpReplayChannel>(rc, clock_);
    channel_->configure();
    channel_->activate();
    cfg_.kernel_timer = true;
    cfg_.period_ns = 100;
    cfg_.lease_ns = 500;  // 5 frames
  }
  CanAlarmConfig cfg_;
};

TEST_F(CanAlarmKernelTimerTest, TheKernelResendsWithAliveCountersAndStopsWhenTheLeaseIsNotRenewed) {
  CanAlarmOutput out(cfg_, *channel_, &clock_);
  out.configure();
  out.activate();
  ASSERT_TRUE(out.kernel_timed());
  EXPECT_EQ(out.refresh_period_ns(), 250);
  ASSERT_EQ(channel_->sent_frames().size(), 1U);
  EXPECT_EQ(channel_->sent_frames()[0].data[0], 0x03);  // alive 0, fault "not judged yet"
  AlarmReport r;
  r.level = AlarmLevel::kNormal;
  r.rms = 0.25F;
  clock_.set_ns(50);
  ASSERT_EQ(out.set(r), OutputStatus::kOk);  // level change: one frame at once
  // Renewed every 250 (the pipeline's cadence) with the same verdict: no frame of its own.
  for (std::int64_t t = 300; t <= 2'050; t += 250) {
    clock_.set_ns(t);
    ASSERT_EQ(out.set(r), OutputStatus::kOk);
  }
  // No renewal after 2050 (a hung daemon): the lease of 5 frames runs out.
  clock_.set_ns(5'000);
  out.deactivate();  // the final frame: cause internal, then nothing
  channel_->deactivate();
  const auto s = channel_->sent_frames();
  // 0: activate, 50: the change, then the timer's frames at 100, 200, ... while renewed.
  ASSERT_GE(s.size(), 24U);
  EXPECT_EQ(s[1].t_ns, 50);
  for (std::size_t i = 0; i < s.size(); ++i) {
    EXPECT_EQ(s[i].data[0] >> 4, static_cast<int>(i % 16)) << "alive counter of frame " << i;
    if (i > 0 && i + 1 < s.size()) {
      EXPECT_LE(s[i].t_ns - s[i - 1].t_ns, 100) << "gap before frame " << i;
    }
  }
  EXPECT_EQ(s[2].t_ns, 100);  // the timer's phase is kept by the level change (announce)
  // 0, 50, the timer's 100..2500 (25: after the last renewal at 2050 the lease allows 5 more,
  // 2100..2500), then silence until the final frame at 5000.
  ASSERT_EQ(s.size(), 28U);
  EXPECT_EQ(s[s.size() - 2].t_ns, 2'500);
  EXPECT_EQ(s.back().t_ns, 5'000);
  EXPECT_EQ(s.back().data[1], kCauseInternal);
  EXPECT_EQ(s.back().data[0] & 0x03, 3);
  EXPECT_EQ(s[s.size() - 3].data[4], 250 & 0xFF);  // rms 0.25 in 1e-3 steps
}

TEST_F(CanAlarmKernelTimerTest, ANewValueGoesIntoTheFramesAndALateRenewalRestartsTheTimer) {
  CanAlarmOutput out(cfg_, *channel_, &clock_);
  out.configure();
  out.activate();  // t 0
  AlarmReport r;
  r.level = AlarmLevel::kFault;  // same level and causes as activate(): no frame at once
  r.rms = 1.0F;
  clock_.set_ns(120);
  ASSERT_EQ(out.set(r), OutputStatus::kOk);
  EXPECT_EQ(channel_->sent_frames().size(), 2U);  // 0 and the timer's 100 only
  clock_.set_ns(150);
  (void)out.set(r);
  EXPECT_EQ(channel_->sent_frames().size(), 2U);
  // Renewed (5 - 1) periods after the last set-up at 150: the timer may have stopped, so it restarts
  // (one frame now).
  clock_.set_ns(150 + 400);
  ASSERT_EQ(out.set(r), OutputStatus::kOk);
  const auto s = channel_->sent_frames();
  ASSERT_GE(s.size(), 3U);
  EXPECT_EQ(s.back().t_ns, 550);
  EXPECT_EQ(s[2].t_ns, 200);
  EXPECT_EQ(s[2].data[4] | (s[2].data[5] << 8), 1000);  // the new value from the next frame on
}

TEST_F(CanAlarmKernelTimerTest, WithoutAKernelTimerTheDaemonSendsEveryFrame) {
  CandumpReplayConfig rc;
  rc.path = dir_ / "empty.log";
  rc.pace = ReplayPace::kAsFastAsPossible;  // the emulation needs real-time pace
  rc.cyclic = true;
  CandumpReplayChannel fast(rc, clock_);
  fast.configure();
  fast.activate();
  CanAlarmOutput out(cfg_, fast, &clock_);
  out.configure();
  out.activate();
  EXPECT_FALSE(out.kernel_timed());
  EXPECT_EQ(out.refresh_period_ns(), 100);
  (void)out.set(AlarmLevel::kNormal);
  (void)out.set(AlarmLevel::kNormal);
  EXPECT_EQ(fast.sent_frames().size(), 3U);
  CanAlarmOutput no_clock(cfg_, *channel_);  // the kernel timer needs a clock for the lease
  no_clock.configure();
  no_clock.activate();
  EXPECT_FALSE(no_clock.kernel_timed());
  CanAlarmConfig bad = cfg_;
  bad.lease_ns = 150;
  EXPECT_THROW(validate(bad), Error);
}

TEST_F(CanAlarmKernelTimerTest, SetNeverAllocates) {
  CanAlarmOutput out(cfg_, *channel_, &clock_);
  out.configure();
  out.activate();
  AlarmReport r;
  r.level = AlarmLevel::kAlarm;
  test::AllocScope scope;
  for (int i = 0; i < 20; ++i) {
    r.rms = static_cast<float>(i);
    clock_.advance_ns(60);
    (void)out.set(r);
  }
  EXPECT_EQ(scope.count(), 0U);
}

// ---- recording fake ------------------------------------------------------------------------------

TEST(RecordingAlarmOutput, RecordsTheSequenceAndShowsFaultWhenInactive) {
  RecordingAlarmOutput out(3);
  out.configure();
  EXPECT_EQ(out.set(AlarmLevel::kNormal), OutputStatus::kNotActive);
  EXPECT_EQ(out.shown(), AlarmLevel::kFault);
  out.activate();
  EXPECT_EQ(out.shown(), AlarmLevel::kFault);
  EXPECT_EQ(out.set(AlarmLevel::kNormal), OutputStatus::kOk);
  EXPECT_EQ(out.set(AlarmLevel::kWarning), OutputStatus::kOk);
  AlarmReport r;
  r.level = AlarmLevel::kAlarm;
  r.causes = kCauseEntropy;
  EXPECT_EQ(out.set(r), OutputStatus::kOk);
  EXPECT_EQ(out.set(AlarmLevel::kNormal), OutputStatus::kOk);  // beyond capacity: dropped, still shown
  EXPECT_EQ(out.shown(), AlarmLevel::kNormal);
  ASSERT_EQ(out.reports().size(), 3u);
  EXPECT_EQ(out.reports()[0].level, AlarmLevel::kNormal);
  EXPECT_EQ(out.reports()[1].level, AlarmLevel::kWarning);
  EXPECT_EQ(out.reports()[2].causes, kCauseEntropy);
  EXPECT_EQ(out.dropped(), 1u);
  out.fail_writes(true);
  EXPECT_EQ(out.set(AlarmLevel::kAlarm), OutputStatus::kError);
  out.deactivate();
  EXPECT_EQ(out.shown(), AlarmLevel::kFault);
  const AlarmOutputCounters c = out.counters();
  EXPECT_EQ(c.sets, 6u);
  EXPECT_EQ(c.errors, 2u);
  EXPECT_EQ(c.level_changes, 5u);  // fault->normal (refused)->warning->alarm->normal->alarm (failed)
  EXPECT_EQ(out.last_level(), AlarmLevel::kAlarm);
}

}  // namespace
}  // namespace ptda::drivers
