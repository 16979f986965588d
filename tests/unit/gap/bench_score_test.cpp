// The bench's "named and located" score: the true effect anywhere in the explanation, at its place.
#include <gtest/gtest.h>

#include <vector>

#include "ptda/gap/bench.hpp"

namespace ptda::gap {
namespace {

sim::EffectSpec effect(sim::EffectKind k, const char* param, double value) {
  sim::EffectSpec e = sim::EffectSpec::with_defaults(k);
  e.set(param, value);
  return e;
}

TEST(BenchScore, TheTrueEffectCountsWhereverItIsNamedButOnlyAtItsPlace) {
  const std::vector<sim::EffectSpec> truth{effect(sim::EffectKind::kAdcClipping, "level_ms2", 10.0)};
  const sim::EffectSpec ripple = effect(sim::EffectKind::kSpeedRipple, "jitter_rad", 0.2);
  // Named second, behind the recording's own gap, 2 % off: counts.
  EXPECT_TRUE(named_and_located(truth, {ripple, effect(sim::EffectKind::kAdcClipping, "level_ms2", 10.2)}));
  // Named first and at its place: counts too.
  EXPECT_TRUE(named_and_located(truth, {effect(sim::EffectKind::kAdcClipping, "level_ms2", 9.6)}));
  // Named, but 8 % off (location_matches allows 5 % for a clipping level): does not.
  EXPECT_FALSE(named_and_located(truth, {ripple, effect(sim::EffectKind::kAdcClipping, "level_ms2", 10.8)}));
  // Another kind only, or nothing.
  EXPECT_FALSE(named_and_located(truth, {ripple}));
  EXPECT_FALSE(named_and_located(truth, {}));
  // A control has no truth: nothing named can count.
  EXPECT_FALSE(named_and_located({}, {ripple}));
}

}  // namespace
}  // namespace ptda::gap
