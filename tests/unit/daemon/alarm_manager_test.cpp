#include "alarm/alarm_manager.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>

#include "alloc_counter.hpp"
#include "ptda/common/error.hpp"

namespace ptda::daemon {
namespace {

using drivers::AlarmLevel;

constexpr std::int64_t kS = 1'000'000'000;

/// A scored window as MonitorEngine::poll() hands it out.
dsp::WindowResult win(bool rms_out, bool entropy_out, bool alarm, std::uint32_t abnormal_in_last_n,
                      std::int32_t cls = 1, double rms = 0.5, double entropy = 0.75) {
  dsp::WindowResult w;
  w.status = dsp::WindowStatus::kScored;
  w.class_id = cls;
  w.features.rms_res = rms;
  w.features.entropy_res = entropy;
  w.thresholds.rms = {0.1, 0.4};
  w.thresholds.entropy = {0.6, 0.9};
  w.verdict.rms_out = rms_out;
  w.verdict.entropy_out = entropy_out;
  w.alarm = alarm;
  w.abnormal_in_last_n = abnormal_in_last_n;
  return w;
}
dsp::WindowResult ok(std::uint32_t abnormal_in_last_n = 0) {
  return win(false, false, false, abnormal_in_last_n);
}

AlarmManagerConfig latched_cfg() {
  AlarmManagerConfig c;
  c.warning_enabled = true;
  c.warning_k = 1;
  c.warning_hold_s = 0.0;
  c.min_hold_s = 10.0;
  c.latch = true;
  return c;
}

TEST(AlarmManager, StartsInFaultWithoutCausesUntilJudged) {
  AlarmManager m(latched_cfg(), 0);
  EXPECT_EQ(m.level(), AlarmLevel::kFault);
  EXPECT_EQ(m.tick(5 * kS), AlarmLevel::kFault);
  const drivers::AlarmReport r = m.report();
  EXPECT_EQ(r.level, AlarmLevel::kFault);
  EXPECT_EQ(r.causes, 0);
  EXPECT_EQ(r.segment_class, drivers::kNoSegmentClass);
  // The first scored window says monitoring works.
  EXPECT_EQ(m.on_window(ok(), 6 * kS), AlarmLevel::kNormal);
  EXPECT_EQ(m.state().since_ns, 6 * kS);
}

// Monitoring possible (no fault cause) is not a verdict: the level stays kFault with no cause ("not
// judged yet", docs/daemon.md) until a window was scored, whatever kNoClass windows pass meanwhile.
TEST(AlarmManager, NoFaultCauseIsNotNormalBeforeTheFirstScoredWindow) {
  AlarmManager m(latched_cfg(), 0);
  EXPECT_EQ(m.set_faults(0, 1 * kS), AlarmLevel::kFault);
  EXPECT_EQ(m.report().causes, 0);
  dsp::WindowResult unmatched = ok();
  unmatched.status = dsp::WindowStatus::kNoClass;
  EXPECT_EQ(m.on_window(unmatched, 2 * kS), AlarmLevel::kFault);
  EXPECT_EQ(m.tick(3 * kS), AlarmLevel::kFault);
  EXPECT_EQ(m.on_window(ok(), 4 * kS), AlarmLevel::kNormal);
  // Coverage lost later: a fault with its own cause, never kNormal; judged windows bring normal back.
  EXPECT_EQ(m.set_faults(drivers::kCauseCoverage, 5 * kS), AlarmLevel::kFault);
  EXPECT_EQ(m.report().causes, drivers::kCauseCoverage);
  EXPECT_EQ(m.on_window(ok(), 6 * kS), AlarmLevel::kFault);  // the cause is the pipeline's to clear
  EXPECT_EQ(m.set_faults(0, 7 * kS), AlarmLevel::kNormal);
}

TEST(AlarmManager, LatchedSequenceWithHoldAndClear) {
  AlarmManager m(latched_cfg(), 0);
  EXPECT_EQ(m.set_faults(0, 1 * kS), AlarmLevel::kFault);  // not judged yet
  EXPECT_EQ(m.on_window(ok(), 2 * kS), AlarmLevel::kNormal);
  // One abnormal window: warning (warning_k = 1), rms tripped.
  EXPECT_EQ(m.on_window(win(true, false, false, 1), 3 * kS), AlarmLevel::kWarning);
  EXPECT_EQ(m.report().causes, drivers::kCauseRms);
  EXPECT_EQ(m.on_window(win(true, false, false, 2), 4 * kS), AlarmLevel::kWarning);
  // Third of the last n: k-of-n confirms; entropy joins the causes.
  EXPECT_EQ(m.on_window(win(false, true, true, 3, 2, 0.3, 0.95), 5 * kS), AlarmLevel::kAlarm);
  EXPECT_EQ(m.report().causes, drivers::kCauseRms | drivers::kCauseEntropy);
  EXPECT_EQ(m.state().trip.class_id, 2);
  EXPECT_DOUBLE_EQ(m.state().trip.entropy_res, 0.95);
  EXPECT_EQ(m.state().alarm_raised_ns, 5 * kS);
  EXPECT_TRUE(m.state().latched);
  // Condition drops: the alarm stays (latched, and within the hold).
  EXPECT_EQ(m.on_window(ok(2), 6 * kS), AlarmLevel::kAlarm);
  EXPECT_FALSE(m.state().condition);
  EXPECT_EQ(m.request_clear(ClearSource::kLocal, 7 * kS), ClearResult::kRefusedHold);
  EXPECT_EQ(m.request_clear(ClearSource::kLocal, 15 * kS - 1), ClearResult::kRefusedHold);
  EXPECT_EQ(m.level(), AlarmLevel::kAlarm);
  // Hold over, still latched.
  EXPECT_EQ(m.tick(15 * kS), AlarmLevel::kAlarm);
  EXPECT_EQ(m.tick(100 * kS), AlarmLevel::kAlarm);
  // Condition returns: clear refused.
  EXPECT_EQ(m.on_window(win(true, false, true, 3), 101 * kS), AlarmLevel::kAlarm);
  EXPECT_EQ(m.request_clear(ClearSource::kCan, 102 * kS), ClearResult::kRefusedCondition);
  EXPECT_EQ(m.level(), AlarmLevel::kAlarm);
  // Healthy again, abnormal count 0: the clear is accepted and the level goes straight to normal.
  EXPECT_EQ(m.on_window(ok(0), 103 * kS), AlarmLevel::kAlarm);
  EXPECT_EQ(m.request_clear(ClearSource::kCan, 104 * kS), ClearResult::kCleared);
  EXPECT_EQ(m.level(), AlarmLevel::kNormal);
  EXPECT_EQ(m.state().since_ns, 104 * kS);
  EXPECT_EQ(m.report().causes, 0);
  EXPECT_FALSE(m.state().latched);
  EXPECT_EQ(m.state().last_clear_source, ClearSource::kCan);
  EXPECT_EQ(m.request_clear(ClearSource::kCan, 105 * kS), ClearResult::kNothingToClear);

  const AlarmCounters c = m.counters();
  EXPECT_EQ(c.windows_scored, 7U);
  EXPECT_EQ(c.windows_abnormal, 4U);
  EXPECT_EQ(c.alarms_raised, 1U);
  EXPECT_EQ(c.warnings_raised, 1U);
  EXPECT_EQ(c.clears_refused, 3U);
  EXPECT_EQ(c.clears_accepted, 1U);
  EXPECT_EQ(c.clears_nothing, 1U);
  // fault -> normal -> warning -> alarm -> normal
  EXPECT_EQ(c.level_changes, 4U);
}

TEST(AlarmManager, ClearWithRemainingAbnormalWindowsFallsBackToWarning) {
  AlarmManager m(latched_cfg(), 0);
  m.set_faults(0, 0);
  EXPECT_EQ(m.on_window(win(true, false, true, 3), 1 * kS), AlarmLevel::kAlarm);
  EXPECT_EQ(m.on_window(win(true, false, false, 2), 12 * kS), AlarmLevel::kAlarm);
  EXPECT_EQ(m.request_clear(ClearSource::kLocal, 12 * kS), ClearResult::kCleared);
  EXPECT_EQ(m.level(), AlarmLevel::kWarning);
  EXPECT_EQ(m.report().causes, drivers::kCauseRms);
  EXPECT_EQ(m.on_window(ok(0), 13 * kS), AlarmLevel::kNormal);
}

TEST(AlarmManager, UnlatchedAlarmEndsAfterHoldWhenConditionIsOff) {
  AlarmManagerConfig cfg = latched_cfg();
  cfg.latch = false;
  AlarmManager m(cfg, 0);
  m.set_faults(0, 0);
  EXPECT_EQ(m.on_window(win(true, true, true, 3), 5 * kS), AlarmLevel::kAlarm);
  EXPECT_FALSE(m.state().latched);
  EXPECT_EQ(m.on_window(win(true, false, true, 4), 6 * kS), AlarmLevel::kAlarm);
  EXPECT_EQ(m.on_window(ok(2), 7 * kS), AlarmLevel::kAlarm);  // hold until 15 s
  EXPECT_EQ(m.tick(15 * kS - 1), AlarmLevel::kAlarm);
  // Hold over; 2 abnormal of the last n still warn.
  EXPECT_EQ(m.tick(15 * kS), AlarmLevel::kWarning);
  EXPECT_EQ(m.state().since_ns, 15 * kS);
  EXPECT_EQ(m.on_window(ok(0), 16 * kS), AlarmLevel::kNormal);
  EXPECT_EQ(m.request_clear(ClearSource::kLocal, 17 * kS), ClearResult::kNothingToClear);
  EXPECT_EQ(m.counters().alarms_raised, 1U);
}

TEST(AlarmManager, UnlatchedAlarmOutlivesHoldWhileConditionHolds) {
  AlarmManagerConfig cfg = latched_cfg();
  cfg.latch = false;
  cfg.min_hold_s = 2.0;
  AlarmManager m(cfg, 0);
  m.set_faults(0, 0);
  EXPECT_EQ(m.on_window(win(true, false, true, 3), 1 * kS), AlarmLevel::kAlarm);
  EXPECT_EQ(m.tick(50 * kS), AlarmLevel::kAlarm);  // condition still on at the last window
  EXPECT_EQ(m.on_window(win(true, false, true, 3), 51 * kS), AlarmLevel::kAlarm);
  EXPECT_EQ(m.on_window(ok(0), 52 * kS), AlarmLevel::kNormal);
  // A second episode is a second alarm.
  EXPECT_EQ(m.on_window(win(true, false, true, 3), 53 * kS), AlarmLevel::kAlarm);
  EXPECT_EQ(m.counters().alarms_raised, 2U);
}

TEST(AlarmManager, WarningLevelOptions) {
  {  // disabled: abnormal windows below k stay normal
    AlarmManagerConfig cfg = latched_cfg();
    cfg.warning_enabled = false;
    AlarmManager m(cfg, 0);
    m.set_faults(0, 0);
    EXPECT_EQ(m.on_window(win(true, false, false, 1), 1 * kS), AlarmLevel::kNormal);
    EXPECT_EQ(m.on_window(win(true, false, false, 2), 2 * kS), AlarmLevel::kNormal);
    EXPECT_EQ(m.report().causes, 0);  // no episode: no feature causes published
    EXPECT_EQ(m.report().abnormal_windows, 2);
    EXPECT_EQ(m.on_window(win(true, false, true, 3), 3 * kS), AlarmLevel::kAlarm);
  }
  {  // warning_k = 2
    AlarmManagerConfig cfg = latched_cfg();
    cfg.warning_k = 2;
    AlarmManager m(cfg, 0);
    m.set_faults(0, 0);
    EXPECT_EQ(m.on_window(win(true, false, false, 1), 1 * kS), AlarmLevel::kNormal);
    EXPECT_EQ(m.on_window(win(false, true, false, 2), 2 * kS), AlarmLevel::kWarning);
    // Both features seen during the run-up count (the first window was within the last n).
    EXPECT_EQ(m.report().causes, drivers::kCauseEntropy | drivers::kCauseRms);
    EXPECT_EQ(m.on_window(ok(1), 3 * kS), AlarmLevel::kNormal);
  }
  {  // warning hold
    AlarmManagerConfig cfg = latched_cfg();
    cfg.warning_hold_s = 5.0;
    AlarmManager m(cfg, 0);
    m.set_faults(0, 0);
    EXPECT_EQ(m.on_window(win(true, false, false, 1), 3 * kS), AlarmLevel::kWarning);
    EXPECT_EQ(m.on_window(ok(0), 4 * kS), AlarmLevel::kWarning);
    EXPECT_EQ(m.tick(8 * kS - 1), AlarmLevel::kWarning);
    EXPECT_EQ(m.tick(8 * kS), AlarmLevel::kNormal);
    EXPECT_EQ(m.counters().warnings_raised, 1U);
  }
}

TEST(AlarmManager, FaultNeverRaisesAnAlarm) {
  AlarmManager m(latched_cfg(), 0);
  EXPECT_EQ(m.set_faults(drivers::kCauseBaseline, 1 * kS), AlarmLevel::kFault);
  for (std::int64_t t = 2; t < 1000; t += 7) {
    EXPECT_EQ(m.tick(t * kS), AlarmLevel::kFault);
    m.set_faults(static_cast<std::uint8_t>(t % 2 == 0 ? drivers::kCauseSensor : drivers::kCauseSpeed),
                 t * kS);
    ASSERT_EQ(m.level(), AlarmLevel::kFault);
  }
  // Feature bits are not fault bits: only speed stays.
  m.set_faults(drivers::kCauseRms | drivers::kCauseSpeed, 1000 * kS);
  EXPECT_EQ(m.state().fault_causes, drivers::kCauseSpeed);
  EXPECT_EQ(m.report().causes, drivers::kCauseSpeed);
  EXPECT_EQ(m.report().level, AlarmLevel::kFault);
  const AlarmCounters c = m.counters();
  EXPECT_EQ(c.alarms_raised, 0U);
  EXPECT_EQ(c.faults_entered, 1U);
  EXPECT_FALSE(m.state().alarm_active);
  // Fault masks a warning; clearing the fault reveals it.
  EXPECT_EQ(m.on_window(win(true, false, false, 1), 1001 * kS), AlarmLevel::kFault);
  EXPECT_EQ(m.set_faults(0, 1002 * kS), AlarmLevel::kWarning);
  EXPECT_EQ(m.request_clear(ClearSource::kLocal, 1003 * kS), ClearResult::kNothingToClear);
}

TEST(AlarmManager, LatchedAlarmSurvivesAFault) {
  AlarmManager m(latched_cfg(), 0);
  m.set_faults(0, 0);
  EXPECT_EQ(m.on_window(win(true, false, true, 3), 1 * kS), AlarmLevel::kAlarm);
  EXPECT_EQ(m.set_faults(drivers::kCauseSensor, 2 * kS), AlarmLevel::kAlarm);
  EXPECT_EQ(m.report().causes, drivers::kCauseRms | drivers::kCauseSensor);
  EXPECT_EQ(m.tick(60 * kS), AlarmLevel::kAlarm);
  EXPECT_EQ(m.set_faults(0, 61 * kS), AlarmLevel::kAlarm);
  // Cleared during a fault: the fault shows next.
  EXPECT_EQ(m.set_faults(drivers::kCauseSpeed, 62 * kS), AlarmLevel::kAlarm);
  m.on_window(ok(0), 63 * kS);
  EXPECT_EQ(m.request_clear(ClearSource::kLocal, 64 * kS), ClearResult::kCleared);
  EXPECT_EQ(m.level(), AlarmLevel::kFault);
  EXPECT_EQ(m.report().causes, drivers::kCauseSpeed);
}

TEST(AlarmManager, UnclassifiedWindowsAreCountedNotJudged) {
  AlarmManager m(latched_cfg(), 0);
  m.set_faults(0, 0);
  dsp::WindowResult w = win(true, true, true, 5);
  w.status = dsp::WindowStatus::kNoClass;
  EXPECT_EQ(m.on_window(w, 1 * kS), AlarmLevel::kFault);  // still not judged
  EXPECT_FALSE(m.state().have_window);
  EXPECT_EQ(m.counters().windows_unclassified, 1U);
  EXPECT_EQ(m.counters().windows_scored, 0U);
}

TEST(AlarmManager, PostedClearIsAppliedByTheOwner) {
  AlarmManager m(latched_cfg(), 0);
  m.set_faults(0, 0);
  m.on_window(win(true, false, true, 3), 1 * kS);
  m.on_window(ok(0), 2 * kS);
  m.post_clear_request(ClearSource::kCan);
  EXPECT_EQ(m.tick(3 * kS), AlarmLevel::kAlarm);  // refused: hold until 11 s
  EXPECT_EQ(m.last_clear_result(), ClearResult::kRefusedHold);
  EXPECT_EQ(m.tick(20 * kS), AlarmLevel::kAlarm);  // nothing posted: still latched
  m.post_clear_request(ClearSource::kCan);
  m.post_clear_request(ClearSource::kCan);  // coalesced
  EXPECT_EQ(m.tick(21 * kS), AlarmLevel::kNormal);
  EXPECT_EQ(m.last_clear_result(), ClearResult::kCleared);
  EXPECT_EQ(m.state().last_clear_ns, 21 * kS);
  EXPECT_EQ(m.counters().clears_accepted, 1U);
  EXPECT_EQ(m.counters().clears_refused, 1U);
}

TEST(AlarmManager, ReportCarriesTheLastWindow) {
  AlarmManager m(latched_cfg(), 0);
  m.set_faults(0, 0);
  m.on_window(win(true, false, false, 2, 7, 1.25, 0.875), 1 * kS);
  drivers::AlarmReport r = m.report();
  EXPECT_EQ(r.level, AlarmLevel::kWarning);
  EXPECT_EQ(r.segment_class, 7);
  EXPECT_EQ(r.abnormal_windows, 2);
  EXPECT_FLOAT_EQ(r.rms, 1.25F);
  EXPECT_FLOAT_EQ(r.entropy, 0.875F);
  m.on_window(win(false, false, false, 300, 300), 2 * kS);
  r = m.report();
  EXPECT_EQ(r.segment_class, drivers::kNoSegmentClass);
  EXPECT_EQ(r.abnormal_windows, 255);
}

// An alarm by the band CUSUM alone (both features in their bands) carries the band cause, so the CAN
// frame and status.json never read "alarm" without a cause.
TEST(AlarmManager, ABandAlarmCarriesTheBandCause) {
  AlarmManager m(latched_cfg(), 0);
  m.set_faults(0, 0);
  dsp::WindowResult w = win(false, false, true, 0);
  w.band_on = true;
  w.band_alarm = true;
  w.detector = dsp::AlarmDetector::kSequentialBand;
  EXPECT_EQ(m.on_window(w, 1 * kS), AlarmLevel::kAlarm);
  EXPECT_EQ(m.report().causes, drivers::kCauseBand);
  EXPECT_EQ(m.state().trip.causes, drivers::kCauseBand);
  // A later window out of the RMS band adds its cause to the episode's.
  m.on_window(win(true, false, true, 1), 2 * kS);
  EXPECT_EQ(m.report().causes, drivers::kCauseBand | drivers::kCauseRms);
}

TEST(AlarmManager, RunStateMakesNoAllocations) {
  AlarmManager m(latched_cfg(), 0);
  const dsp::WindowResult bad = win(true, true, true, 3);
  const dsp::WindowResult good = ok(0);
  test::AllocScope scope;
  std::uint64_t sum = 0;
  for (int i = 0; i < 1000; ++i) {
    const std::int64_t t = i * kS;
    m.set_faults(i % 50 == 0 ? drivers::kCauseSpeed : 0, t);
    m.on_window(i % 7 == 0 ? bad : good, t);
    m.tick(t + kS / 2);
    if (i % 13 == 0) m.request_clear(ClearSource::kLocal, t);
    if (i % 17 == 0) m.post_clear_request(ClearSource::kCan);
    sum += static_cast<std::uint64_t>(m.report().level);
  }
  EXPECT_EQ(scope.count(), 0U);
  EXPECT_GT(sum, 0U);
}

TEST(AlarmManager, RejectsBadConfiguration) {
  AlarmManagerConfig cfg = latched_cfg();
  cfg.warning_k = 0;
  EXPECT_THROW(AlarmManager(cfg, 0), Error);
  cfg = latched_cfg();
  cfg.min_hold_s = -1.0;
  try {
    AlarmManager m(cfg, 0);
    FAIL() << "no throw";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("alarm.min_hold_s"), std::string::npos) << e.what();
  }
  cfg = latched_cfg();
  cfg.warning_hold_s = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(AlarmManager(cfg, 0), Error);
}

}  // namespace
}  // namespace ptda::daemon

namespace ptda::daemon {
namespace {

// The end of a replay: no verdict (kFault) with no cause bit of its own, but a raised alarm stays.
TEST(AlarmManager, InputEndedIsFaultWithoutCauseAndKeepsAnAlarm) {
  constexpr std::int64_t kSec = 1'000'000'000;
  AlarmManagerConfig cfg;
  cfg.min_hold_s = 10.0;
  cfg.latch = true;
  AlarmManager healthy(cfg, 0);
  dsp::WindowResult w;
  w.status = dsp::WindowStatus::kScored;
  w.class_id = 0;
  ASSERT_EQ(healthy.on_window(w, 1 * kSec), drivers::AlarmLevel::kNormal);
  EXPECT_EQ(healthy.set_input_ended(2 * kSec), drivers::AlarmLevel::kFault);
  EXPECT_EQ(healthy.report().causes, 0);
  EXPECT_EQ(healthy.state().since_ns, 2 * kSec);
  EXPECT_EQ(healthy.tick(3 * kSec), drivers::AlarmLevel::kFault);  // for good

  AlarmManager alarmed(cfg, 0);
  w.verdict.rms_out = true;
  w.alarm = true;
  w.abnormal_in_last_n = 3;
  ASSERT_EQ(alarmed.on_window(w, 1 * kSec), drivers::AlarmLevel::kAlarm);
  EXPECT_EQ(alarmed.set_input_ended(2 * kSec), drivers::AlarmLevel::kAlarm);
  EXPECT_EQ(alarmed.report().causes, drivers::kCauseRms);
}

}  // namespace
}  // namespace ptda::daemon

namespace ptda::daemon {
namespace {

// Every level change goes into the ring where it happens, with what the supervisor reports: two
// changes between two looks stay two records; a full ring counts what it could not hold.
TEST(AlarmManager, EveryLevelChangeIsRecordedInTheChangeRing) {
  AlarmManagerConfig c;
  c.warning_enabled = false;
  c.min_hold_s = 0.0;
  c.latch = false;
  AlarmManager m(c, 0);
  LevelChangeRing ring;
  m.set_change_ring(&ring);
  m.on_window(ok(), 1 * kS);                                     // fault -> normal
  m.on_window(win(true, false, true, 3, 2, 0.55, 0.7), 2 * kS);  // normal -> alarm
  m.on_window(ok(), 3 * kS);                                     // alarm -> normal (no hold)
  m.set_faults(drivers::kCauseSpeed, 4 * kS);                    // normal -> fault
  LevelChange r;
  ASSERT_TRUE(ring.try_pop(r));
  EXPECT_EQ(r.from, AlarmLevel::kFault);
  EXPECT_EQ(r.to, AlarmLevel::kNormal);
  EXPECT_EQ(r.t_ns, 1 * kS);
  EXPECT_EQ(r.number, 1U);
  EXPECT_TRUE(r.have_window);
  EXPECT_EQ(r.window.thresholds.rms.hi, 0.4);  // the last scored window's band
  ASSERT_TRUE(ring.try_pop(r));
  EXPECT_EQ(r.from, AlarmLevel::kNormal);
  EXPECT_EQ(r.to, AlarmLevel::kAlarm);
  EXPECT_EQ(r.number, 2U);
  EXPECT_TRUE(r.have_window);
  EXPECT_EQ(r.window.class_id, 2);  // the window that raised it
  EXPECT_EQ(r.window.rms_res, 0.55);
  EXPECT_EQ(r.causes, drivers::kCauseRms);
  ASSERT_TRUE(ring.try_pop(r));
  EXPECT_EQ(r.to, AlarmLevel::kNormal);
  EXPECT_EQ(r.t_ns, 3 * kS);
  ASSERT_TRUE(ring.try_pop(r));
  EXPECT_EQ(r.to, AlarmLevel::kFault);
  EXPECT_FALSE(r.have_window);
  EXPECT_EQ(r.causes, drivers::kCauseSpeed);
  EXPECT_EQ(r.number, 4U);
  EXPECT_FALSE(ring.try_pop(r));
  EXPECT_EQ(m.counters().level_changes_dropped, 0U);
  // Nobody drains: after 64 held, the rest are counted.
  for (int i = 0; i < 40; ++i) {
    m.set_faults(0, (10 + 2 * i) * kS);
    m.set_faults(drivers::kCauseSpeed, (11 + 2 * i) * kS);
  }
  EXPECT_EQ(m.counters().level_changes, 84U);
  EXPECT_EQ(m.counters().level_changes_dropped, 80U - LevelChangeRing::kCapacity);
}

}  // namespace
}  // namespace ptda::daemon
