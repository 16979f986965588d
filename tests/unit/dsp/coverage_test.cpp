// dsp::CoverageTracker on hand-made speed samples and window results: motion time, the levels, the
// unmatched reasons and speed bins, and the one-line description (exact text).
#include "ptda/dsp/coverage.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "ptda/common/error.hpp"

namespace ptda::dsp {
namespace {

constexpr std::int64_t kMs = 1'000'000;

// Classes +1.05 and -1.05 rad/s (both directions at one speed) and +2.10 rad/s.
Baseline three_classes() {
  Baseline b;
  const auto add = [&](std::int8_t dir, double speed) {
    ClassBaseline c;
    c.segment.id = static_cast<std::uint32_t>(b.classes.size());
    c.segment.direction = dir;
    c.segment.speed_rad_s = speed;
    c.segment.speed_tol_rad_s = 0.05 * speed;
    b.classes.push_back(c);
  };
  add(1, 1.05);
  add(1, 2.10);
  add(-1, 1.05);
  return b;
}

CoverageConfig cfg_5s() {
  CoverageConfig c;
  c.timeout_s = 5.0;
  c.moving_speed_rad_s = 0.05;
  c.max_speed_gap_s = 0.05;
  return c;
}

WindowResult window(std::int64_t t_end_ns, double speed, std::int32_t cls) {
  WindowResult w;
  w.ref.t_end_ns = t_end_ns;
  w.ref.speed_rad_s = speed;
  w.status = cls >= 0 ? WindowStatus::kScored : WindowStatus::kNoClass;
  w.class_id = cls;
  return w;
}

/// Speed samples every 4 ms in [from, to) at `speed`.
void move(CoverageTracker& t, std::int64_t from_ns, std::int64_t to_ns, double speed) {
  for (std::int64_t x = from_ns; x < to_ns; x += 4 * kMs) t.on_speed(SpeedSample{x, speed, 0.0, false});
}

std::string text(const CoverageTracker& t, const Baseline& b) {
  char buf[200];
  describe_coverage(t.state(), b, t.timeout_s(), buf, sizeof buf);
  return buf;
}

TEST(Coverage, UnmatchedSpeedGoesNotJudgingAfterTheTimeoutOfMotion) {
  const Baseline b = three_classes();
  CoverageTracker t(b, cfg_5s());
  EXPECT_EQ(t.state().level, CoverageLevel::kWaiting);
  EXPECT_EQ(text(t, b), "not judged yet");
  // 4 s at 2.50 rad/s with a window every 0.5 s: no class, still within the timeout.
  for (int i = 0; i < 8; ++i) {
    move(t, i * 500 * kMs, (i + 1) * 500 * kMs, 2.5);
    t.on_window(window((i + 1) * 500 * kMs, 2.5, -1));
  }
  EXPECT_EQ(t.state().level, CoverageLevel::kWaiting);
  // 4 s standing still: no motion, still waiting.
  move(t, 4000 * kMs, 8000 * kMs, 0.0);
  EXPECT_EQ(t.state().level, CoverageLevel::kWaiting);
  // Moving again at 2.50 rad/s: 1 s more motion reaches 5 s.
  move(t, 8000 * kMs, 9100 * kMs, 2.5);
  const CoverageState& s = t.state();
  EXPECT_EQ(s.level, CoverageLevel::kNotJudging);
  EXPECT_EQ(s.unmatched[static_cast<std::size_t>(UnmatchedReason::kSpeed)], 8U);
  EXPECT_EQ(s.judged, 0U);
  ASSERT_EQ(s.speed_bins, 1U);
  EXPECT_DOUBLE_EQ(s.speeds[0].speed_rad_s, 2.5);
  EXPECT_EQ(s.speeds[0].count, 8U);
  // Motion: 4 s + 1.1 s less the first step of each moving stretch (4 ms from standstill to motion and
  // the first sample of the run): samples 4 ms apart, both moving.
  EXPECT_EQ(s.moving_ns, 4000 * kMs - 4 * kMs + 1100 * kMs - 4 * kMs);
  EXPECT_NEAR(s.last_judged_age_s(), 9.096, 1e-9);  // since the first sample (t = 0)
  EXPECT_EQ(text(t, b),
            "not judging: no window matches a trained class (seen 2.50 rad/s; trained \u00b11.05, +2.10)");
}

TEST(Coverage, DirectionInvalidAndSilenceAreToldApart) {
  Baseline fwd;
  fwd.classes = {three_classes().classes[0]};  // only +1.05
  CoverageTracker t(fwd, cfg_5s());
  t.on_window(window(100 * kMs, -1.05, -1));  // no backward class at all
  t.on_window(window(200 * kMs, 1.50, -1));
  t.on_discarded_total(3);
  t.on_discarded_total(3);  // cumulative: no change
  t.on_discarded_total(5);
  const CoverageState& s = t.state();
  EXPECT_EQ(s.unmatched[static_cast<std::size_t>(UnmatchedReason::kDirection)], 1U);
  EXPECT_EQ(s.unmatched[static_cast<std::size_t>(UnmatchedReason::kSpeed)], 1U);
  EXPECT_EQ(s.unmatched[static_cast<std::size_t>(UnmatchedReason::kInvalid)], 5U);
  // Speed samples more than max_speed_gap_s apart are silence, not motion.
  for (int i = 0; i < 100; ++i) t.on_speed(SpeedSample{i * 100 * kMs, 1.0, 0.0, false});
  EXPECT_EQ(t.state().moving_ns, 0);
  EXPECT_EQ(t.state().level, CoverageLevel::kWaiting);
  // A finished run that moved and judged nothing is not judging even before the timeout.
  move(t, 20'000 * kMs, 21'000 * kMs, 1.0);
  t.finish();
  EXPECT_EQ(t.state().level, CoverageLevel::kNotJudging);
  EXPECT_EQ(text(t, fwd),
            "not judging: no window matches a trained class (seen -1.05, 1.50 rad/s; trained +1.05); windows "
            "with invalid samples discarded");
}

TEST(Coverage, PartialThenFullThenRecoveredFromNotJudging) {
  const Baseline b = three_classes();
  CoverageTracker t(b, cfg_5s());
  move(t, 0, 6000 * kMs, 1.05);
  t.on_window(window(6000 * kMs, 1.05, 0));  // class 0 judged; 1 and 2 not in 6 s of motion
  EXPECT_EQ(t.state().level, CoverageLevel::kPartial);
  EXPECT_FALSE(t.state().class_current(1, 5.0));
  EXPECT_EQ(text(t, b),
            "partial coverage: class 1 (+2.10 rad/s) never judged in 6 s of motion, class 2 (-1.05 rad/s) "
            "never judged in 6 s of motion");
  t.on_window(window(6100 * kMs, 2.10, 1));
  t.on_window(window(6200 * kMs, -1.05, 2));
  EXPECT_EQ(t.state().level, CoverageLevel::kFull);
  EXPECT_EQ(text(t, b), "");
  // 5 s of motion with no judged window: not judging; one judged window recovers (the others are
  // stale then: partial).
  move(t, 6200 * kMs, 11'300 * kMs, 3.0);
  EXPECT_EQ(t.state().level, CoverageLevel::kNotJudging);
  EXPECT_EQ(text(t, b),
            "not judging: no constant-speed window for 5 s of motion (trained \u00b11.05, +2.10)");
  t.on_window(window(11'300 * kMs, 1.05, 0));
  EXPECT_EQ(t.state().level, CoverageLevel::kPartial);
  EXPECT_EQ(t.state().classes[0].judged, 2U);
  EXPECT_EQ(t.state().judged, 4U);
  EXPECT_NEAR(t.state().moving_since_judged_s(), 0.0, 1e-12);
}

TEST(Coverage, AJudgedWindowCountsMotionFromItsOwnEndNotFromWhenItWasJudged) {
  // A window is judged when the caller drains it: after a whole WAV block (ptda monitor) or a processing
  // period (ptdad), by which time later speed samples are in. The motion since it must not depend on
  // that lag. Samples every 4 ms from 0 to 9996 ms at +1.05 rad/s: 9996 ms of motion in all.
  const Baseline b = three_classes();
  CoverageTracker late(b, cfg_5s());
  move(late, 0, 10'000 * kMs, 1.05);
  ASSERT_EQ(late.state().moving_ns, 9996 * kMs);
  late.on_window(window(6002 * kMs, 1.05, 0));  // between the samples at 6000 and 6004 ms
  EXPECT_EQ(late.state().moving_at_last_judged_ns, 6002 * kMs);
  EXPECT_NEAR(late.state().moving_since_judged_s(), 3.994, 1e-12);  // before the fix: 0
  EXPECT_EQ(late.state().classes[0].moving_at_last_ns, 6002 * kMs);

  // The same input judged as soon as the window ended gives the same state.
  CoverageTracker prompt(b, cfg_5s());
  move(prompt, 0, 6004 * kMs, 1.05);  // up to the sample at 6000 ms
  move(prompt, 6004 * kMs, 6008 * kMs, 1.05);
  prompt.on_window(window(6002 * kMs, 1.05, 0));
  move(prompt, 6008 * kMs, 10'000 * kMs, 1.05);
  EXPECT_EQ(prompt.state().moving_at_last_judged_ns, late.state().moving_at_last_judged_ns);
  EXPECT_EQ(prompt.state().level, late.state().level);

  // A window that ended before the oldest kept sample (1024 samples: 5904 ms on) counts from that
  // sample, and an older window never moves the count back.
  late.on_window(window(4000 * kMs, 1.05, 0));
  EXPECT_EQ(late.state().moving_at_last_judged_ns, 6002 * kMs);
  CoverageTracker old(b, cfg_5s());
  move(old, 0, 10'000 * kMs, 1.05);
  old.on_window(window(1000 * kMs, 1.05, 0));
  EXPECT_EQ(old.state().moving_at_last_judged_ns, 5904 * kMs);

  // Late judging cannot hide blindness: a window judged after 5.49 s more of motion leaves the state
  // not judging (samples every 10 ms: 800 samples, all kept).
  CoverageTracker blind(b, cfg_5s());
  for (std::int64_t x = 0; x < 8000 * kMs; x += 10 * kMs) blind.on_speed(SpeedSample{x, 1.05, 0.0, false});
  blind.on_window(window(2500 * kMs, 1.05, 0));
  EXPECT_NEAR(blind.state().moving_since_judged_s(), 5.49, 1e-12);
  EXPECT_EQ(blind.state().level, CoverageLevel::kNotJudging);
}

TEST(Coverage, RejectsABadTimeout) {
  CoverageConfig c = cfg_5s();
  c.timeout_s = 0.0;
  EXPECT_THROW(CoverageTracker(three_classes(), c), Error);
  c.timeout_s = std::nan("");
  EXPECT_THROW(CoverageTracker(three_classes(), c), Error);
}

}  // namespace
}  // namespace ptda::dsp
