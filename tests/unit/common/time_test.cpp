// Checked seconds-to-ns conversion (common/include/ptda/common/time.hpp; issue 14 item 1: llround of
// a start_time >= 9.22e9 s overflowed, which is undefined behaviour).
#include "ptda/common/time.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <limits>

namespace {

constexpr std::int64_t kMax = std::numeric_limits<std::int64_t>::max();
constexpr std::int64_t kMin = std::numeric_limits<std::int64_t>::min();

TEST(Time, ConvertsInRangeRoundingToNearest) {
  EXPECT_EQ(ptda::checked_seconds_to_ns(0.0), 0);
  EXPECT_EQ(ptda::checked_seconds_to_ns(1.5), 1'500'000'000);
  EXPECT_EQ(ptda::checked_seconds_to_ns(-2.25), -2'250'000'000);
  EXPECT_EQ(ptda::checked_seconds_to_ns(1.4e-9), 1);
  // 1700000000.5 s is exactly representable, so is its ns value.
  EXPECT_EQ(ptda::seconds_to_ns(1700000000.5), 1'700'000'000'500'000'000);
  EXPECT_EQ(ptda::seconds_to_ns(ptda::kMaxUnixTimeS), 4'000'000'000'000'000'000);
}

TEST(Time, OutOfRangeIsReportedNotUndefined) {
  EXPECT_FALSE(ptda::checked_seconds_to_ns(9.3e9).has_value());
  EXPECT_FALSE(ptda::checked_seconds_to_ns(-9.3e9).has_value());
  // 2^63 ns exactly (9.223372036854775808e9 s) is one past the largest int64.
  EXPECT_FALSE(ptda::checked_seconds_to_ns(9.223372036854775808e9).has_value());
  EXPECT_FALSE(ptda::checked_seconds_to_ns(std::numeric_limits<double>::infinity()).has_value());
  EXPECT_FALSE(ptda::checked_seconds_to_ns(std::numeric_limits<double>::quiet_NaN()).has_value());
  // The largest double below 2^63 ns converts.
  const auto near = ptda::checked_seconds_to_ns(9.2233720368547e9);
  ASSERT_TRUE(near.has_value());
  EXPECT_GT(*near, 9'223'372'036'854'000'000);
}

TEST(Time, UncheckedSaturates) {
  EXPECT_EQ(ptda::seconds_to_ns(9.3e9), kMax);
  EXPECT_EQ(ptda::seconds_to_ns(1e300), kMax);
  EXPECT_EQ(ptda::seconds_to_ns(-1e300), kMin);
  EXPECT_EQ(ptda::seconds_to_ns(-std::numeric_limits<double>::infinity()), kMin);
  EXPECT_EQ(ptda::seconds_to_ns(std::numeric_limits<double>::quiet_NaN()), 0);
}

}  // namespace
