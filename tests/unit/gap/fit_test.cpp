// The calibration's least-squares speed law (gap/src/fit.cpp).
#include "ptda/gap/fit.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <vector>

namespace ptda::gap {
namespace {

// d = a_order + g_direction + b * 20 log10 |speed| + noise(class, order).
std::vector<LevelObservation> make(const std::vector<double>& speeds, const std::vector<int>& orders,
                                   double b, double reverse_level_db, double noise_db) {
  std::vector<LevelObservation> obs;
  int i = 0;
  for (double w : speeds) {
    for (int k : orders) {
      // A fixed, deterministic "noise" pattern (not symmetric, so that it does not cancel).
      const double e = noise_db * std::sin(1.7 * i + 0.3 * k * k);
      const double d =
          0.8 * k - 2.0 + (w < 0 ? reverse_level_db : 0.0) + b * 20.0 * std::log10(std::fabs(w)) + e;
      obs.push_back({k, w, d});
      ++i;
    }
  }
  return obs;
}

// The pooled within-direction regression of the class means on 20 log10 |speed|: the estimator the
// calibration used before the least-squares fit, written out here as the reference for complete data.
double class_mean_regression(const std::vector<LevelObservation>& obs) {
  std::map<double, std::pair<double, int>> per_class;
  for (const auto& o : obs) {
    per_class[o.speed_rad_s].first += o.diff_db;
    per_class[o.speed_rad_s].second += 1;
  }
  double sxy = 0.0, sxx = 0.0;
  for (const double sign : {1.0, -1.0}) {
    std::vector<std::pair<double, double>> xy;
    for (const auto& [w, a] : per_class)
      if (w * sign > 0.0) xy.push_back({20.0 * std::log10(std::fabs(w)), a.first / a.second});
    if (xy.size() < 2) continue;
    double mx = 0.0, my = 0.0;
    for (const auto& [x, y] : xy) {
      mx += x;
      my += y;
    }
    mx /= static_cast<double>(xy.size());
    my /= static_cast<double>(xy.size());
    for (const auto& [x, y] : xy) {
      sxy += (x - mx) * (y - my);
      sxx += (x - mx) * (x - mx);
    }
  }
  return sxy / sxx;
}

TEST(SpeedLawFit, RecoversTheSlopeExactlyWithOrderAndDirectionLevels) {
  const auto obs = make({0.5, 1.0, 2.0, -0.7, -1.4}, {1, 2, 3}, 0.35, 4.0, 0.0);
  const SpeedLawFit f = fit_speed_law(obs);
  ASSERT_TRUE(f.identifiable);
  EXPECT_NEAR(f.exponent_step, 0.35, 1e-12);
}

TEST(SpeedLawFit, EqualsTheClassMeanRegressionWhenEveryClassHasEveryOrder) {
  const auto obs = make({0.5, 1.0, 2.0, 2.6, -0.7, -1.4, -2.8}, {1, 2, 3, 4}, -0.2, -3.0, 1.5);
  const SpeedLawFit f = fit_speed_law(obs);
  ASSERT_TRUE(f.identifiable);
  const double ref = class_mean_regression(obs);
  EXPECT_NEAR(f.exponent_step, ref, 1e-12 * std::fabs(ref) + 1e-14);
  // The noise moves it away from the true -0.2 (so the comparison above is not of two exact fits).
  EXPECT_GT(std::fabs(f.exponent_step + 0.2), 1e-3);
}

TEST(SpeedLawFit, MissingCellsDoNotBiasTheSlopeAsClassMeansDo) {
  // Order 3 sits 2.4 dB above order 1 (0.8 dB per order); the fastest class lacks it, the slowest has
  // only it and order 1. Class means then mix order levels into the speed term; least squares does not.
  auto obs = make({0.5, 1.0, 2.0, 4.0}, {1, 2, 3}, 0.5, 0.0, 0.0);
  std::vector<LevelObservation> kept;
  for (const auto& o : obs) {
    if (o.speed_rad_s == 4.0 && o.order == 3) continue;
    if (o.speed_rad_s == 0.5 && o.order == 2) continue;
    kept.push_back(o);
  }
  const SpeedLawFit f = fit_speed_law(kept);
  ASSERT_TRUE(f.identifiable);
  EXPECT_NEAR(f.exponent_step, 0.5, 1e-12);
  EXPECT_GT(std::fabs(class_mean_regression(kept) - 0.5), 0.01);
}

TEST(SpeedLawFit, ALevelThatDiffersBetweenDirectionsIsNotASpeedLaw) {
  // One speed per direction: the direction level and a slope cannot be told apart.
  const SpeedLawFit one = fit_speed_law(make({1.0, -2.0}, {1, 2, 3}, 0.0, 6.0, 0.0));
  EXPECT_FALSE(one.identifiable);
  EXPECT_EQ(one.exponent_step, 0.0);
  EXPECT_EQ(one.speed_ss_db2, 0.0);
  // Two speeds per direction, no speed law, a 6 dB direction level: slope 0.
  const SpeedLawFit two = fit_speed_law(make({1.0, 2.0, -1.5, -3.0}, {1, 2}, 0.0, 6.0, 0.0));
  ASSERT_TRUE(two.identifiable);
  EXPECT_NEAR(two.exponent_step, 0.0, 1e-12);
}

TEST(SpeedLawFit, IgnoresUnusableObservationsAndTooFewPoints) {
  auto obs = make({0.5, 1.0, 2.0}, {1, 2}, 0.25, 0.0, 0.0);
  obs.push_back({1, 0.0, 50.0});           // standstill: no speed
  obs.push_back({2, 3.0, std::nan("")});   // no difference
  obs.push_back({2, std::nan(""), 10.0});  // no speed
  const SpeedLawFit f = fit_speed_law(obs);
  ASSERT_TRUE(f.identifiable);
  EXPECT_NEAR(f.exponent_step, 0.25, 1e-12);
  EXPECT_FALSE(fit_speed_law({{1, 1.0, 0.0}, {1, 2.0, 1.0}}).identifiable);
  EXPECT_FALSE(fit_speed_law({}).identifiable);
}

}  // namespace
}  // namespace ptda::gap
