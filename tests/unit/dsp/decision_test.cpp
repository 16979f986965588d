// Window verdicts and k-of-n debouncing on sequences with known outcomes.
#include "ptda/dsp/decision.hpp"

#include <gtest/gtest.h>

#include <limits>
#include <string>
#include <vector>

#include "alloc_counter.hpp"
#include "ptda/common/error.hpp"

namespace ptda::dsp {
namespace {

std::vector<bool> run(KOfNDebouncer& d, const std::vector<int>& seq) {
  std::vector<bool> out;
  for (const int v : seq) out.push_back(d.push(v != 0));
  return out;
}

TEST(Judge, EitherFeatureOutOfItsBandIsAbnormal) {
  const FeatureThresholds t{Band{1.0, 2.0}, Band{0.5, 0.9}};
  EXPECT_FALSE(judge(Features{1.5, 0.7}, t).abnormal());
  EXPECT_FALSE(judge(Features{1.0, 0.9}, t).abnormal());  // closed interval
  const Verdict hi_rms = judge(Features{2.01, 0.7}, t);
  EXPECT_TRUE(hi_rms.rms_out);
  EXPECT_FALSE(hi_rms.entropy_out);
  EXPECT_TRUE(hi_rms.abnormal());
  const Verdict lo_ent = judge(Features{1.5, 0.49}, t);
  EXPECT_FALSE(lo_ent.rms_out);
  EXPECT_TRUE(lo_ent.entropy_out);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const Verdict bad = judge(Features{nan, nan}, t);  // NaN (size mismatch) is never healthy
  EXPECT_TRUE(bad.rms_out && bad.entropy_out);
}

TEST(KOfN, ThreeOfFiveKnownSequence) {
  KOfNDebouncer d(3, 5);
  // history (last 5)            count  alarm
  // 1                           1      0
  // 1 0                         1      0
  // 1 0 1                       2      0
  // 1 0 1 1                     3      1
  // 1 0 1 1 0                   3      1
  // 0 1 1 0 0   (first 1 out)   2      0
  // 1 1 0 0 1                   3      1
  // 1 0 0 1 0                   2      0
  // 0 0 1 0 0                   1      0
  const std::vector<bool> got = run(d, {1, 0, 1, 1, 0, 0, 1, 0, 0});
  const std::vector<bool> want = {false, false, false, true, true, false, true, false, false};
  EXPECT_EQ(got, want);
  EXPECT_EQ(d.abnormal_in_window(), 1U);
  EXPECT_FALSE(d.active());
}

TEST(KOfN, OneOfOneFollowsTheInput) {
  KOfNDebouncer d(1, 1);
  EXPECT_EQ(run(d, {0, 1, 1, 0, 1, 0}), (std::vector<bool>{false, true, true, false, true, false}));
}

TEST(KOfN, NOfNNeedsAnUnbrokenRun) {
  KOfNDebouncer d(4, 4);
  EXPECT_EQ(run(d, {1, 1, 1, 0, 1, 1, 1, 1, 1, 0}),
            (std::vector<bool>{false, false, false, false, false, false, false, true, true, false}));
}

TEST(KOfN, WindowSlidesOverTheFullCapacity) {
  KOfNDebouncer d(2, KOfNDebouncer::kMaxN);
  EXPECT_FALSE(d.push(true));
  for (std::uint32_t i = 1; i < KOfNDebouncer::kMaxN - 1; ++i) EXPECT_FALSE(d.push(false));
  EXPECT_TRUE(d.push(true));    // both abnormal windows are within the last 64
  EXPECT_FALSE(d.push(false));  // the first one just slid out
  EXPECT_EQ(d.abnormal_in_window(), 1U);
}

TEST(KOfN, ResetForgetsHistory) {
  KOfNDebouncer d(2, 3);
  EXPECT_TRUE(run(d, {1, 1}).back());
  d.reset();
  EXPECT_FALSE(d.active());
  EXPECT_EQ(d.abnormal_in_window(), 0U);
  EXPECT_FALSE(d.push(true));
  EXPECT_FALSE(d.push(false));
  EXPECT_TRUE(d.push(true));
  EXPECT_FALSE(d.push(false));  // the first 1 after reset slid out of 3
}

TEST(KOfN, PushDoesNotAllocate) {
  KOfNDebouncer d(3, 10);
  test::AllocScope scope;
  for (int i = 0; i < 1000; ++i) (void)d.push(i % 3 == 0);
  EXPECT_EQ(scope.count(), 0U);
}

TEST(KOfN, InvalidKOrNRejected) {
  for (const auto& [k, n] :
       std::vector<std::pair<std::uint32_t, std::uint32_t>>{{0, 5}, {6, 5}, {1, 0}, {3, 65}}) {
    try {
      KOfNDebouncer d(k, n);
      FAIL() << k << " of " << n << " accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(std::to_string(k) + " of " + std::to_string(n)), std::string::npos)
          << e.what();
    }
  }
  EXPECT_NO_THROW(KOfNDebouncer(64, 64));
}

}  // namespace
}  // namespace ptda::dsp
