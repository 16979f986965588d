// WindowSlicer: region detection on hand-made speed profiles, window cutting, invalid samples,
// history overrun and independence from how the two input streams are interleaved.
#include "ptda/dsp/window_slicer.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "alloc_counter.hpp"
#include "ptda/common/error.hpp"

namespace ptda::dsp {
namespace {

constexpr std::int64_t kMs = 1'000'000;
constexpr std::int64_t kT0 = 1'700'000'000'000'000'000;  // UNIX-epoch-like sample-0 time
constexpr double kFs = 2000.0;                           // 0.5 ms per sample, 8 samples per speed period
constexpr std::uint32_t kN = 200;                        // 0.1 s windows
constexpr std::int64_t kSpeedPeriodNs = 4 * kMs;

/// Linear speed segment: from the previous end speed to v_end over duration_ms (hold when equal).
struct Seg {
  std::int64_t duration_ms;
  double v_end;
};

/// Speed samples every 4 ms from kT0 + 1 ms (not aligned to the vibration samples), starting at 0 rad/s.
/// Knots are at multiples of 4 ms, so a plateau's first and last samples carry exactly its speed.
std::vector<SpeedSample> make_profile(const std::vector<Seg>& segs) {
  std::vector<SpeedSample> out;
  std::int64_t seg_start_ns = 0;
  double v0 = 0.0;
  std::int64_t tau = 0;
  for (const Seg& s : segs) {
    const std::int64_t d_ns = s.duration_ms * kMs;
    for (; tau < seg_start_ns + d_ns; tau += kSpeedPeriodNs) {
      const double f = static_cast<double>(tau - seg_start_ns) / static_cast<double>(d_ns);
      out.push_back(SpeedSample{kT0 + kMs + tau, v0 + f * (s.v_end - v0), 0.0, false});
    }
    seg_start_ns += d_ns;
    v0 = s.v_end;
  }
  out.push_back(SpeedSample{kT0 + kMs + tau, v0, 0.0, false});
  return out;
}

/// Profile time (ms after the first speed sample) -> absolute ns.
std::int64_t at_ms(std::int64_t ms) {
  return kT0 + kMs + ms * kMs;
}

/// Sample i carries its own index (exact in float below 2^24) so window content is checkable.
std::vector<float> ramp_samples(std::size_t n) {
  std::vector<float> x(n);
  for (std::size_t i = 0; i < n; ++i) x[i] = static_cast<float>(i % 1'000'000);
  return x;
}

std::size_t samples_to_cover(const std::vector<SpeedSample>& speed) {
  return static_cast<std::size_t>((speed.back().t_ns - kT0) / 500'000 + 10);
}

ExtractionConfig base_config() {
  ExtractionConfig c;
  c.window_len = kN;
  c.hop = 0;
  c.speed_tol_rel = 0.02;
  c.speed_tol_abs_rad_s = 0.005;
  c.min_speed_rad_s = 0.05;
  c.min_duration_s = 0.1;
  c.max_speed_gap_s = 0.05;
  return c;
}

struct Cut {
  WindowRef ref;
  std::vector<float> x;
};

struct Output {
  std::vector<Cut> cuts;
  std::vector<RegionInfo> regions;
};

void drain(WindowSlicer& s, Output& o) {
  std::vector<float> buf(s.config().window_len);
  WindowRef ref;
  while (s.pop(ref, buf)) o.cuts.push_back(Cut{ref, buf});
  RegionInfo r;
  while (s.pop_region(r)) o.regions.push_back(r);
}

/// Time-ordered feeding: blocks of `block` samples, each preceded by the speed samples up to its end.
Output run_in_time_order(WindowSlicer& s, const std::vector<SpeedSample>& speed, const std::vector<float>& x,
                         std::size_t block = 100) {
  Output o;
  std::size_t k = 0;
  for (std::size_t i = 0; i < x.size(); i += block) {
    const std::size_t len = std::min(block, x.size() - i);
    const std::int64_t t_end = kT0 + static_cast<std::int64_t>(static_cast<double>(i + len) / kFs * 1e9);
    for (; k < speed.size() && speed[k].t_ns <= t_end; ++k) s.push_speed(speed[k]);
    s.push_samples(std::span<const float>(x).subspan(i, len));
    drain(s, o);
  }
  for (; k < speed.size(); ++k) s.push_speed(speed[k]);
  s.finish();
  drain(s, o);
  return o;
}

void expect_window_inside_region(const Cut& c, const std::vector<RegionInfo>& regions) {
  const auto it = std::find_if(regions.begin(), regions.end(),
                               [&](const RegionInfo& r) { return r.seq == c.ref.region_seq; });
  ASSERT_NE(it, regions.end()) << "window " << c.ref.seq << " names unknown region " << c.ref.region_seq;
  EXPECT_GE(c.ref.t_start_ns, it->t_begin_ns) << "window " << c.ref.seq;
  EXPECT_LE(c.ref.t_end_ns, it->t_end_ns) << "window " << c.ref.seq;
  EXPECT_EQ(c.ref.speed_rad_s < 0 ? -1 : 1, it->direction) << "window " << c.ref.seq;
  // Content: sample i carries value i.
  for (std::size_t k = 0; k < c.x.size(); ++k) {
    ASSERT_EQ(c.x[k], static_cast<float>((c.ref.first_sample + static_cast<std::int64_t>(k)) % 1'000'000));
  }
}

/// Independent count of windows a region yields: window j = [ceil(fs*(t_begin+guard-t0)) + j*hop, +N)
/// must end (time of its last sample + 1/fs) no later than the region's last speed sample.
std::uint32_t expected_windows(const RegionInfo& r, std::uint32_t hop, double guard_s = 0.0) {
  const double first0 = std::ceil((static_cast<double>(r.t_begin_ns - kT0) * 1e-9 + guard_s) * kFs - 1e-9);
  std::uint32_t n = 0;
  while ((first0 + static_cast<double>(n) * hop + kN) / kFs * 1e9 <=
         static_cast<double>(r.t_end_ns - kT0) + 0.5)
    ++n;
  return n;
}

TEST(WindowSlicerConfig, RejectsBadKeysByName) {
  const auto expect_error = [](ExtractionConfig c, const std::string& key, double fs = kFs,
                               std::size_t hist = 0) {
    try {
      WindowSlicer s(c, fs, kT0, hist);
      ADD_FAILURE() << "no error for " << key;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
    }
  };
  ExtractionConfig c = base_config();
  c.window_len = 1001;  // odd
  expect_error(c, "extraction.window_len");
  c.window_len = 2 * 7 * 16;  // prime factor 7
  expect_error(c, "extraction.window_len");
  c = base_config();
  c.speed_tol_rel = -0.1;
  expect_error(c, "extraction.speed_tol_rel");
  c = base_config();
  c.speed_tol_abs_rad_s = std::numeric_limits<double>::quiet_NaN();
  expect_error(c, "extraction.speed_tol_abs_rad_s");
  c = base_config();
  c.max_speed_rad_s = 0.01;  // below min_speed
  expect_error(c, "extraction.max_speed_rad_s");
  c = base_config();
  c.max_speed_gap_s = 0.0;
  expect_error(c, "extraction.max_speed_gap_s");
  c = base_config();
  c.guard_s = -1.0;
  expect_error(c, "extraction.guard_s");
  c = base_config();
  c.min_duration_s = -0.5;
  expect_error(c, "extraction.min_duration_s");
  c = base_config();
  c.clip_abs = -3.0;
  expect_error(c, "extraction.clip_abs");
  expect_error(base_config(), "fs_hz", 25600.00001);  // not a multiple of 1 mHz
  expect_error(base_config(), "fs_hz", 0.0);
  expect_error(base_config(), "history_len", kFs, kN - 1);
  EXPECT_NO_THROW(WindowSlicer(base_config(), 25600.0, kT0));
}

TEST(WindowSlicer, TrapezoidPlateausAreRegionsWithinOneSpeedPeriod) {
  // 0.2 s still, ramp 0.252 s to 3.5 rad/s (dv = 0.0556 per 4 ms < tol = 0.07), plateau 1.0 s, ramp
  // down, a 60 ms plateau at 1.0 rad/s (shorter than min_duration: no region), still, ramp 0.208 s
  // to -2 rad/s (dv = 0.0385 < tol = 0.04), plateau 0.8 s, ramp down.
  const auto speed = make_profile({{200, 0.0},
                                   {252, 3.5},
                                   {1000, 3.5},
                                   {252, 1.0},
                                   {60, 1.0},
                                   {100, 0.0},
                                   {200, 0.0},
                                   {208, -2.0},
                                   {800, -2.0},
                                   {208, 0.0},
                                   {100, 0.0}});
  const auto x = ramp_samples(samples_to_cover(speed));
  WindowSlicer s(base_config(), kFs, kT0);
  const Output o = run_in_time_order(s, speed, x);

  ASSERT_EQ(o.regions.size(), 2U);
  const RegionInfo& a = o.regions[0];
  const RegionInfo& b = o.regions[1];
  // Plateau A holds from 452 ms to 1452 ms, plateau B from 2272 ms to 3072 ms (profile time). The
  // last ramp sample before a plateau and the first after it are within tolerance, so a region may
  // begin / end one speed period outside its plateau, never more.
  EXPECT_GE(a.t_begin_ns, at_ms(452) - kSpeedPeriodNs);
  EXPECT_LE(a.t_begin_ns, at_ms(452));
  EXPECT_GE(a.t_end_ns, at_ms(1452));
  EXPECT_LE(a.t_end_ns, at_ms(1452) + kSpeedPeriodNs);
  EXPECT_GE(b.t_begin_ns, at_ms(2272) - kSpeedPeriodNs);
  EXPECT_LE(b.t_begin_ns, at_ms(2272));
  EXPECT_GE(b.t_end_ns, at_ms(3072));
  EXPECT_LE(b.t_end_ns, at_ms(3072) + kSpeedPeriodNs);
  EXPECT_EQ(a.direction, 1);
  EXPECT_EQ(b.direction, -1);
  EXPECT_NEAR(a.mean_speed_rad_s, 3.5, 0.01);
  EXPECT_NEAR(b.mean_speed_rad_s, -2.0, 0.01);
  EXPECT_EQ(a.seq, 0U);
  EXPECT_EQ(b.seq, 1U);

  const std::uint32_t na = expected_windows(a, kN);
  const std::uint32_t nb = expected_windows(b, kN);
  EXPECT_EQ(na, 10U);  // a ~1.004 s long region holds ten 0.1 s windows
  EXPECT_EQ(nb, 8U);
  ASSERT_EQ(o.cuts.size(), na + nb);
  for (std::size_t i = 0; i < o.cuts.size(); ++i) {
    const Cut& c = o.cuts[i];
    EXPECT_EQ(c.ref.seq, i);
    EXPECT_EQ(c.ref.region_seq, i < na ? 0U : 1U);
    EXPECT_EQ(c.ref.index_in_region, i < na ? i : i - na);
    EXPECT_EQ(c.ref.t_end_ns - c.ref.t_start_ns, 100 * kMs);  // 200 samples at 2 kHz
    expect_window_inside_region(c, o.regions);
  }
  // first_sample = ceil((t_begin - t0) * fs), here in integer ns arithmetic.
  EXPECT_EQ(o.cuts.front().ref.first_sample, ((a.t_begin_ns - kT0) * 2000 + 999'999'999) / 1'000'000'000);
  EXPECT_EQ(s.counters().regions, 2U);
  EXPECT_EQ(s.counters().windows, na + nb);
  EXPECT_EQ(s.counters().speed_samples, speed.size());
  EXPECT_EQ(s.counters().windows_invalid + s.counters().windows_lost + s.counters().windows_overflow, 0U);
}

TEST(WindowSlicer, SlowRampIntoPlateauDoesNotDelayTheRegionStart) {
  // Ramp of 0.02 rad/s per speed period into 3.5 rad/s (tol 0.07): a run that began on the ramp must
  // not break inside the plateau and restart late. The region may begin on the last ramp samples
  // within tolerance of the plateau (3.44, 3.46, 3.48 at 888..896 ms), never after the plateau start.
  const auto speed = make_profile({{200, 0.0}, {700, 3.5}, {1000, 3.5}, {700, 0.0}});
  const auto x = ramp_samples(samples_to_cover(speed));
  WindowSlicer s(base_config(), kFs, kT0);
  const Output o = run_in_time_order(s, speed, x);
  ASSERT_EQ(o.regions.size(), 1U);
  EXPECT_GE(o.regions[0].t_begin_ns, at_ms(888));
  EXPECT_LE(o.regions[0].t_begin_ns, at_ms(900));
  EXPECT_GE(o.regions[0].t_end_ns, at_ms(1900));
  EXPECT_LE(o.regions[0].t_end_ns, at_ms(1912));
  EXPECT_EQ(o.cuts.size(), 10U);
  for (const Cut& c : o.cuts) expect_window_inside_region(c, o.regions);
}

TEST(WindowSlicer, DirectionFlipEndsRegionAndNoWindowStraddlesIt) {
  // Instant reversal +1.2 -> -1.2 rad/s with no standstill between.
  std::vector<SpeedSample> speed;
  for (int k = 0; k <= 150; ++k) speed.push_back({at_ms(4 * k), 1.2, 0.0, false});
  for (int k = 151; k <= 300; ++k) speed.push_back({at_ms(4 * k), -1.2, 0.0, false});
  const auto x = ramp_samples(samples_to_cover(speed));
  ExtractionConfig cfg = base_config();
  cfg.hop = kN / 4;  // dense windows: any straddling window would be cut
  WindowSlicer s(cfg, kFs, kT0);
  const Output o = run_in_time_order(s, speed, x);
  ASSERT_EQ(o.regions.size(), 2U);
  EXPECT_EQ(o.regions[0].t_end_ns, at_ms(600));
  EXPECT_EQ(o.regions[1].t_begin_ns, at_ms(604));
  // Sums are kept relative to the run's first speed, so identical samples give their exact value.
  EXPECT_EQ(o.regions[0].mean_speed_rad_s, 1.2);
  EXPECT_EQ(o.regions[1].mean_speed_rad_s, -1.2);
  std::uint32_t per_region[2] = {0, 0};
  for (const Cut& c : o.cuts) {
    expect_window_inside_region(c, o.regions);
    ASSERT_LT(c.ref.region_seq, 2U);
    ++per_region[c.ref.region_seq];
    EXPECT_EQ(c.ref.speed_rad_s, c.ref.region_seq == 0 ? 1.2 : -1.2);
  }
  EXPECT_EQ(per_region[0], expected_windows(o.regions[0], kN / 4));
  EXPECT_EQ(per_region[1], expected_windows(o.regions[1], kN / 4));
  EXPECT_EQ(per_region[0], 21U);  // (0.6 s - 0.1 s) / 25 ms + 1
}

TEST(WindowSlicer, SpeedNoiseWithinToleranceKeepsRegionAStepBeyondBreaksIt) {
  // 2.0 rad/s (tol = max(0.02 * 2, 0.005) >= 0.0394) with uniform noise of +-0.015 (so no sample can
  // be more than 0.03 from the mean) for 1.2 s, then a step to 2.1 rad/s (0.1 > tol) for 0.6 s.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> noise(-0.015, 0.015);
  std::vector<SpeedSample> speed;
  for (int k = 0; k <= 300; ++k) speed.push_back({at_ms(4 * k), 2.0 + noise(rng), 0.0, false});
  for (int k = 301; k <= 450; ++k) speed.push_back({at_ms(4 * k), 2.1, 0.0, false});
  const auto x = ramp_samples(samples_to_cover(speed));
  WindowSlicer s(base_config(), kFs, kT0);
  const Output o = run_in_time_order(s, speed, x);
  ASSERT_EQ(o.regions.size(), 2U);
  EXPECT_EQ(o.regions[0].t_begin_ns, at_ms(0));
  EXPECT_EQ(o.regions[0].t_end_ns, at_ms(1200));
  EXPECT_EQ(o.regions[1].t_begin_ns, at_ms(1204));
  EXPECT_EQ(o.regions[1].t_end_ns, at_ms(1800));
  EXPECT_NEAR(o.regions[0].mean_speed_rad_s, 2.0, 0.005);
  EXPECT_NEAR(o.regions[1].mean_speed_rad_s, 2.1, 1e-12);
  for (const Cut& c : o.cuts) expect_window_inside_region(c, o.regions);
  EXPECT_EQ(o.cuts.size(), expected_windows(o.regions[0], kN) + expected_windows(o.regions[1], kN));
  EXPECT_EQ(o.cuts.size(), 12U + 5U);
}

TEST(WindowSlicer, CanGapBreaksRegion) {
  // 1.5 rad/s for 1.4 s but no speed frame between 600 ms and 700 ms (100 ms > max_speed_gap 50 ms).
  std::vector<SpeedSample> speed;
  for (int k = 0; k <= 350; ++k) {
    if (4 * k > 600 && 4 * k < 700) continue;
    speed.push_back({at_ms(4 * k), 1.5, 0.0, false});
  }
  const auto x = ramp_samples(samples_to_cover(speed));
  WindowSlicer s(base_config(), kFs, kT0);
  const Output o = run_in_time_order(s, speed, x);
  EXPECT_EQ(s.counters().speed_gaps, 1U);
  ASSERT_EQ(o.regions.size(), 2U);
  EXPECT_EQ(o.regions[0].t_end_ns, at_ms(600));
  EXPECT_EQ(o.regions[1].t_begin_ns, at_ms(700));
  for (const Cut& c : o.cuts) {
    expect_window_inside_region(c, o.regions);
    EXPECT_TRUE(c.ref.t_end_ns <= at_ms(600) || c.ref.t_start_ns >= at_ms(700)) << "window over the gap";
  }
  EXPECT_EQ(o.cuts.size(), 6U + 7U);
}

TEST(WindowSlicer, OutOfOrderSpeedIsDroppedCountedAndEndsTheRun) {
  std::vector<SpeedSample> speed;
  for (int k = 0; k <= 300; ++k) {
    speed.push_back({at_ms(4 * k), 1.0, 0.0, false});
    if (k == 100) speed.push_back({at_ms(4 * k), 1.0, 0.0, false});       // duplicate timestamp
    if (k == 200) speed.push_back({at_ms(4 * k - 40), 1.0, 0.0, false});  // clock 40 ms backwards
  }
  const auto x = ramp_samples(samples_to_cover(speed));
  WindowSlicer s(base_config(), kFs, kT0);
  const Output o = run_in_time_order(s, speed, x);
  EXPECT_EQ(s.counters().speed_out_of_order, 2U);
  EXPECT_EQ(s.counters().speed_samples, speed.size());
  ASSERT_EQ(o.regions.size(), 3U);
  EXPECT_EQ(o.regions[0].t_end_ns, at_ms(400));
  EXPECT_EQ(o.regions[1].t_begin_ns, at_ms(404));
  EXPECT_EQ(o.regions[1].t_end_ns, at_ms(800));
  EXPECT_EQ(o.regions[2].t_begin_ns, at_ms(804));
  for (const Cut& c : o.cuts) expect_window_inside_region(c, o.regions);
}

TEST(WindowSlicer, SpeedOutOfRangeIsCountedAndNeverARegion) {
  ExtractionConfig cfg = base_config();
  cfg.max_speed_rad_s = 3.0;
  // Plateau at 3.5 (above max) for 0.4 s, a NaN sample, a short standstill, then 2.0 for 0.5 s.
  std::vector<SpeedSample> speed;
  int k = 0;
  for (; k <= 100; ++k) speed.push_back({at_ms(4 * k), 3.5, 0.0, false});
  speed.push_back({at_ms(4 * k++), std::numeric_limits<double>::quiet_NaN(), 0.0, false});
  for (int j = 0; j < 5; ++j) speed.push_back({at_ms(4 * k++), 0.0, 0.0, false});
  for (int j = 0; j <= 125; ++j) speed.push_back({at_ms(4 * k++), 2.0, 0.0, false});
  const auto x = ramp_samples(samples_to_cover(speed));
  WindowSlicer s(cfg, kFs, kT0);
  const Output o = run_in_time_order(s, speed, x);
  EXPECT_EQ(s.counters().speed_out_of_range, 101U + 1U);  // 101 samples at 3.5 and the NaN
  ASSERT_EQ(o.regions.size(), 1U);
  EXPECT_EQ(o.regions[0].mean_speed_rad_s, 2.0);
  EXPECT_EQ(o.regions[0].t_begin_ns, at_ms(4 * 107));
  for (const Cut& c : o.cuts) {
    expect_window_inside_region(c, o.regions);
    EXPECT_EQ(c.ref.speed_rad_s, 2.0);
  }
  EXPECT_EQ(o.cuts.size(), 5U);
}

TEST(WindowSlicer, NanClippedAndGapSamplesDiscardExactlyTheirWindows) {
  // One plateau at 1.0 rad/s from 0 to 2.0 s; windows of 0.1 s with hop N/2, so each sample after the
  // first half window lies in exactly two windows.
  std::vector<SpeedSample> speed;
  for (int k = 0; k <= 500; ++k) speed.push_back({at_ms(4 * k), 1.0, 0.0, false});
  ExtractionConfig cfg = base_config();
  cfg.hop = kN / 2;
  cfg.clip_abs = 5e5;  // the ramp content reaches 4000: only the planted value clips
  std::vector<float> x = ramp_samples(samples_to_cover(speed));

  // Reference run without defects: the window list to compare against.
  WindowSlicer ref_slicer(cfg, kFs, kT0);
  const Output ref = run_in_time_order(ref_slicer, speed, x);
  ASSERT_EQ(ref.cuts.size(), 39U);  // starts 1 ms + 50 ms * j, ends <= 2001 ms: j = 0..38
  const std::int64_t f0 = ref.cuts[0].ref.first_sample;
  EXPECT_EQ(f0, 2);  // region starts 1 ms after sample 0: ceil(1e-3 * 2000)

  // Plant a NaN, a clipped value and a 10-sample gap; the windows containing them are worked out
  // independently below.
  const std::int64_t hop = kN / 2;
  const std::int64_t nan_at = f0 + 3 * hop + 10;     // in windows 2 and 3
  const std::int64_t clip_at = f0 + 11 * hop + 150;  // in windows 11 and 12
  const std::int64_t gap_at = f0 + 21 * hop + 95;    // gap [gap_at, gap_at + 10): windows 20, 21, 22
  x[static_cast<std::size_t>(nan_at)] = std::numeric_limits<float>::quiet_NaN();
  x[static_cast<std::size_t>(clip_at)] = -6e5F;

  auto contains = [&](std::int64_t w, std::int64_t i) { return i >= f0 + w * hop && i < f0 + w * hop + kN; };
  std::vector<std::uint64_t> expect_missing;
  for (std::int64_t w = 0; w < 39; ++w) {
    bool hit = contains(w, nan_at) || contains(w, clip_at);
    for (std::int64_t g = gap_at; g < gap_at + 10; ++g) hit = hit || contains(w, g);
    if (hit) expect_missing.push_back(static_cast<std::uint64_t>(w));
  }
  EXPECT_EQ(expect_missing, (std::vector<std::uint64_t>{2, 3, 11, 12, 20, 21, 22}));

  // Feed: samples before the gap, mark_gap(10), then the rest (skipping the gap's samples).
  WindowSlicer s(cfg, kFs, kT0);
  Output o;
  for (const auto& sp : speed) s.push_speed(sp);
  s.push_samples(std::span<const float>(x).subspan(0, static_cast<std::size_t>(gap_at)));
  drain(s, o);
  s.mark_gap(10);
  s.push_samples(std::span<const float>(x).subspan(static_cast<std::size_t>(gap_at + 10)));
  s.finish();
  drain(s, o);

  std::vector<std::uint64_t> got;
  for (const Cut& c : o.cuts) got.push_back(c.ref.seq);
  std::vector<std::uint64_t> expect_got;
  for (std::uint64_t w = 0; w < 39; ++w) {
    if (std::find(expect_missing.begin(), expect_missing.end(), w) == expect_missing.end())
      expect_got.push_back(w);
  }
  EXPECT_EQ(got, expect_got);
  for (const Cut& c : o.cuts) expect_window_inside_region(c, o.regions);
  EXPECT_EQ(s.counters().windows_invalid, 7U);
  EXPECT_EQ(s.counters().windows, 32U);
  EXPECT_EQ(s.counters().samples_nonfinite, 1U);
  EXPECT_EQ(s.counters().samples_clipped, 1U);
  EXPECT_EQ(s.counters().samples_missing, 10U);
  EXPECT_EQ(s.counters().samples, x.size() - 10);
}

TEST(WindowSlicer, HistoryOverrunCountsLostWindows) {
  std::vector<SpeedSample> speed;
  for (int k = 0; k <= 250; ++k) speed.push_back({at_ms(4 * k), 1.0, 0.0, false});  // 1 s plateau
  const auto x = ramp_samples(samples_to_cover(speed));
  // Samples arrive 0.35 s before the speed that confirms them; the history holds only 0.2 s.
  WindowSlicer s(base_config(), kFs, kT0, 2 * kN);
  Output o;
  std::size_t k = 0;
  for (std::size_t i = 0; i < x.size(); i += 50) {
    s.push_samples(std::span<const float>(x).subspan(i, std::min<std::size_t>(50, x.size() - i)));
    const std::int64_t t_lag =
        kT0 + static_cast<std::int64_t>(static_cast<double>(i + 50) / kFs * 1e9) - 350 * kMs;
    for (; k < speed.size() && speed[k].t_ns <= t_lag; ++k) s.push_speed(speed[k]);
    drain(s, o);
  }
  for (; k < speed.size(); ++k) s.push_speed(speed[k]);
  s.finish();
  drain(s, o);
  // 10 windows are cut from the region (1..101 ms, ..., 901..1001 ms). Windows 0..8 are confirmed
  // 0.35 s after their samples arrived, when their first sample is already more than 2N = 0.2 s back:
  // lost. Window 9 (samples 1802..2001) is confirmed after the last sample (2011) was pushed and is
  // still in the history (>= 2012 - 400).
  EXPECT_EQ(s.counters().regions, 1U);
  EXPECT_EQ(s.counters().windows_lost, 9U);
  EXPECT_EQ(s.counters().windows, 1U);
  ASSERT_EQ(o.cuts.size(), 1U);
  EXPECT_EQ(o.cuts[0].ref.index_in_region, 9U);
  for (const Cut& c : o.cuts) expect_window_inside_region(c, o.regions);

  // With everything pushed before the speed and a history of exactly N (samples 1812..2011), every
  // window is lost.
  WindowSlicer t(base_config(), kFs, kT0, kN);
  Output p;
  t.push_samples(x);
  for (const auto& sp : speed) t.push_speed(sp);
  t.finish();
  drain(t, p);
  EXPECT_EQ(t.counters().windows_lost, 10U);
  EXPECT_TRUE(p.cuts.empty());
}

TEST(WindowSlicer, GuardCapAndExactSampleTimesAt25600Hz) {
  // fs = 25.6 kHz: sample i is at t0 + ceil(i * 39062.5) ns. Region from 1 ms after t0; guard 30 ms.
  constexpr double fs = 25600.0;
  ExtractionConfig cfg = base_config();
  cfg.window_len = 2560;  // 0.1 s
  cfg.guard_s = 0.03;
  cfg.max_windows_per_region = 3;
  std::vector<SpeedSample> speed;
  for (int k = 0; k <= 250; ++k) speed.push_back({at_ms(4 * k) + 123, 1.0, 0.0, false});
  WindowSlicer s(cfg, fs, kT0);
  for (const auto& sp : speed) s.push_speed(sp);
  std::vector<float> x(30000, 0.25F);
  s.push_samples(x);
  s.finish();
  std::vector<float> buf(2560);
  WindowRef ref;
  std::vector<WindowRef> refs;
  while (s.pop(ref, buf)) refs.push_back(ref);
  ASSERT_EQ(refs.size(), 3U);  // capped (the 1 s region would give 9)
  // first = ceil((1 ms + 123 ns + 30 ms) * 25600 / 1e9) = ceil(793.6031488) = 794 (integer arithmetic).
  const std::int64_t d_ns = 31 * kMs + 123;
  EXPECT_EQ(refs[0].first_sample, (d_ns * 256 + 9'999'999) / 10'000'000);
  EXPECT_EQ(refs[0].first_sample, 794);
  for (std::size_t j = 0; j < refs.size(); ++j) {
    const std::int64_t first = 794 + static_cast<std::int64_t>(j) * 2560;
    EXPECT_EQ(refs[j].first_sample, first);
    EXPECT_EQ(refs[j].t_start_ns, kT0 + (first * 78125 + 1) / 2);  // ceil(first * 39062.5)
    EXPECT_EQ(refs[j].t_end_ns, kT0 + ((first + 2560) * 78125 + 1) / 2);
    EXPECT_EQ(refs[j].index_in_region, j);
  }
  EXPECT_EQ(buf[0], 0.25F);
}

TEST(WindowSlicer, RegionReportedOnlyWhenEndedOrFinished) {
  std::vector<SpeedSample> speed;
  for (int k = 0; k <= 100; ++k) speed.push_back({at_ms(4 * k), -0.8, 0.0, false});
  WindowSlicer s(base_config(), kFs, kT0);
  for (const auto& sp : speed) s.push_speed(sp);
  RegionInfo r;
  EXPECT_FALSE(s.pop_region(r));
  EXPECT_EQ(s.counters().regions, 1U);  // reached min_duration, still open
  s.finish();
  ASSERT_TRUE(s.pop_region(r));
  EXPECT_EQ(r.t_begin_ns, at_ms(0));
  EXPECT_EQ(r.t_end_ns, at_ms(400));
  EXPECT_EQ(r.direction, -1);
  EXPECT_EQ(r.mean_speed_rad_s, -0.8);
  EXPECT_FALSE(s.pop_region(r));
  std::vector<float> small(kN - 1);
  WindowRef ref;
  EXPECT_FALSE(s.pop(ref, small));  // wrong buffer size: refused, nothing consumed
}

// --- order / block-size independence -------------------------------------------------------------

std::vector<SpeedSample> busy_profile() {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> noise(-0.01, 0.01);
  auto speed = make_profile({{100, 0.0},
                             {100, 1.5},
                             {700, 1.5},
                             {100, 0.0},
                             {48, 0.0},
                             {200, -2.5},
                             {900, -2.5},
                             {120, -1.0},
                             {500, -1.0},
                             {200, 0.8},
                             {600, 0.8},
                             {100, 0.0}});
  for (auto& s : speed) s.speed_rad_s += s.speed_rad_s != 0.0 ? noise(rng) : 0.0;
  return speed;
}

std::vector<float> noise_samples(std::size_t n) {
  std::mt19937 rng(5);
  std::normal_distribution<float> g(0.0F, 1.0F);
  std::vector<float> x(n);
  for (auto& v : x) v = g(rng);
  return x;
}

void expect_identical(const Output& a, const Output& b, const char* what) {
  ASSERT_EQ(a.cuts.size(), b.cuts.size()) << what;
  for (std::size_t i = 0; i < a.cuts.size(); ++i) {
    const WindowRef& p = a.cuts[i].ref;
    const WindowRef& q = b.cuts[i].ref;
    EXPECT_EQ(p.seq, q.seq) << what << " window " << i;
    EXPECT_EQ(p.region_seq, q.region_seq) << what;
    EXPECT_EQ(p.index_in_region, q.index_in_region) << what;
    EXPECT_EQ(p.first_sample, q.first_sample) << what;
    EXPECT_EQ(p.t_start_ns, q.t_start_ns) << what;
    EXPECT_EQ(p.t_end_ns, q.t_end_ns) << what;
    EXPECT_EQ(std::memcmp(&p.speed_rad_s, &q.speed_rad_s, sizeof(double)), 0) << what;
    ASSERT_EQ(std::memcmp(a.cuts[i].x.data(), b.cuts[i].x.data(), a.cuts[i].x.size() * sizeof(float)), 0)
        << what << " window " << i;
  }
  ASSERT_EQ(a.regions.size(), b.regions.size()) << what;
  for (std::size_t i = 0; i < a.regions.size(); ++i) {
    EXPECT_EQ(a.regions[i].t_begin_ns, b.regions[i].t_begin_ns) << what;
    EXPECT_EQ(a.regions[i].t_end_ns, b.regions[i].t_end_ns) << what;
    EXPECT_EQ(std::memcmp(&a.regions[i].mean_speed_rad_s, &b.regions[i].mean_speed_rad_s, sizeof(double)), 0);
  }
}

TEST(WindowSlicer, InterleavingAndBlockSizeDoNotChangeWindows) {
  const auto speed = busy_profile();
  const auto x = noise_samples(samples_to_cover(speed));
  ExtractionConfig cfg = base_config();
  cfg.hop = 60;
  cfg.guard_s = 0.012;

  WindowSlicer s_ref(cfg, kFs, kT0, x.size());
  const Output ref = run_in_time_order(s_ref, speed, x, 100);
  ASSERT_EQ(ref.regions.size(), 4U);
  ASSERT_GE(ref.cuts.size(), 60U);

  {  // all speed first, then all samples in one block
    WindowSlicer s(cfg, kFs, kT0, x.size());
    Output o;
    for (const auto& sp : speed) s.push_speed(sp);
    s.push_samples(x);
    s.finish();
    drain(s, o);
    expect_identical(ref, o, "speed first");
  }
  {  // all samples first (sample by sample), then speed
    WindowSlicer s(cfg, kFs, kT0, x.size());
    Output o;
    for (const float v : x) s.push_samples(std::span<const float>(&v, 1));
    for (const auto& sp : speed) {
      s.push_speed(sp);
      drain(s, o);
    }
    s.finish();
    drain(s, o);
    expect_identical(ref, o, "samples first");
  }
  for (unsigned seed = 1; seed <= 4; ++seed) {  // random block sizes and a random lead of either stream
    std::mt19937 rng(seed);
    std::uniform_int_distribution<std::size_t> block(1, 333);
    std::uniform_int_distribution<int> lead_ms(-300, 300);
    WindowSlicer s(cfg, kFs, kT0);  // default history (4 N + 1 s) is enough for a 0.3 s lag
    Output o;
    std::size_t i = 0;
    std::size_t k = 0;
    while (i < x.size()) {
      const std::size_t len = std::min(block(rng), x.size() - i);
      s.push_samples(std::span<const float>(x).subspan(i, len));
      i += len;
      const std::int64_t t =
          kT0 + static_cast<std::int64_t>(static_cast<double>(i) / kFs * 1e9) + lead_ms(rng) * kMs;
      for (; k < speed.size() && speed[k].t_ns <= t; ++k) s.push_speed(speed[k]);
      if (block(rng) % 3 == 0) drain(s, o);  // poll irregularly too
    }
    for (; k < speed.size(); ++k) s.push_speed(speed[k]);
    s.finish();
    drain(s, o);
    expect_identical(ref, o, "random interleaving");
    EXPECT_EQ(s.counters().windows_lost, 0U);
  }
}

TEST(WindowSlicer, NoAllocationAfterConstruction) {
  const auto speed = busy_profile();
  const auto x = noise_samples(samples_to_cover(speed));
  WindowSlicer r_ref(base_config(), kFs, kT0);
  const Output ref_out = run_in_time_order(r_ref, speed, x);
  const std::size_t expect_windows = ref_out.cuts.size();
  std::size_t by_formula = 0;
  for (const RegionInfo& r : ref_out.regions) by_formula += expected_windows(r, kN);
  EXPECT_EQ(expect_windows, by_formula);
  EXPECT_EQ(ref_out.regions.size(), 4U);
  WindowSlicer s(base_config(), kFs, kT0);
  std::vector<float> buf(kN);
  WindowRef ref;
  RegionInfo r;
  std::size_t windows = 0;
  std::size_t k = 0;
  const test::AllocScope scope;
  for (std::size_t i = 0; i < x.size(); i += 64) {
    s.push_samples(std::span<const float>(x).subspan(i, std::min<std::size_t>(64, x.size() - i)));
    const std::int64_t t = kT0 + static_cast<std::int64_t>(static_cast<double>(i) / kFs * 1e9);
    for (; k < speed.size() && speed[k].t_ns <= t; ++k) s.push_speed(speed[k]);
    while (s.pop(ref, buf)) ++windows;
    while (s.pop_region(r)) {
    }
  }
  for (; k < speed.size(); ++k) s.push_speed(speed[k]);
  s.finish();
  while (s.pop(ref, buf)) ++windows;
  s.mark_gap(3);
  EXPECT_EQ(scope.count(), 0U);
  EXPECT_EQ(windows, expect_windows);
}

// push_samples() copies whole blocks into the ring and classifies them branch-free (issue 13): every
// kind of float must be counted as std::isfinite() and the clip test in double say, also in blocks
// that wrap around the end of the history ring.
TEST(WindowSlicer, SampleValidityCountsEveryFloatKindAcrossRingWrap) {
  constexpr float kInf = std::numeric_limits<float>::infinity();
  const float snan = std::numeric_limits<float>::signaling_NaN();
  float neg_nan_payload = 0.0F;
  const std::uint32_t bits = 0xFFC12345U;  // negative quiet NaN with a payload
  std::memcpy(&neg_nan_payload, &bits, sizeof bits);
  const std::vector<float> kinds = {0.0F,
                                    -0.0F,
                                    1.0F,
                                    -2.5F,
                                    std::numeric_limits<float>::denorm_min(),
                                    std::numeric_limits<float>::min(),
                                    std::numeric_limits<float>::max(),
                                    -std::numeric_limits<float>::max(),
                                    1e38F,
                                    -1e38F,
                                    9.99e37F,
                                    kInf,
                                    -kInf,
                                    std::numeric_limits<float>::quiet_NaN(),
                                    snan,
                                    neg_nan_payload};
  std::vector<float> x;
  std::mt19937 rng(5);
  for (int i = 0; i < 5000; ++i) x.push_back(kinds[rng() % kinds.size()]);

  for (const double clip_abs : {0.0, 1e38}) {
    std::uint64_t want_nonfinite = 0;
    std::uint64_t want_clipped = 0;
    for (const float v : x) {
      if (!std::isfinite(v)) {
        ++want_nonfinite;
      } else if (clip_abs > 0.0 && std::fabs(static_cast<double>(v)) >= clip_abs) {
        ++want_clipped;
      }
    }
    ExtractionConfig cfg = base_config();
    cfg.clip_abs = clip_abs;
    WindowSlicer s(cfg, kFs, kT0, kN + 13);  // a ring of 213: the blocks below wrap around it often
    for (std::size_t pos = 0; pos < x.size();) {
      const std::size_t n = std::min<std::size_t>(1 + rng() % 300, x.size() - pos);
      s.push_samples(std::span<const float>(x).subspan(pos, n));
      pos += n;
    }
    EXPECT_EQ(s.counters().samples, x.size());
    EXPECT_EQ(s.counters().samples_nonfinite, want_nonfinite) << "clip_abs " << clip_abs;
    EXPECT_EQ(s.counters().samples_clipped, want_clipped) << "clip_abs " << clip_abs;
    EXPECT_GT(want_nonfinite, 1000U);
    if (clip_abs > 0.0) {
      EXPECT_GT(want_clipped, 500U);  // at least +-FLT_MAX; 1e38F is 9.99999968e37, below
    }
  }
}

}  // namespace
}  // namespace ptda::dsp

namespace ptda::dsp {
namespace {

// next_close_ns() is what ptdad sleeps until (docs/daemon.md, "Sleeping until a window can close"). It
// must be a lower bound (a window handed out before its speed confirmation reached it would be a verdict
// the daemon slept through), and exact where the design says so: the next window of an open region
// closes at its own end, the first window of a run at max(its end, the run's start + min_duration).
TEST(WindowSlicerNextClose, IsALowerBoundAndExactInsideARunAndAfterIt) {
  const auto speed = make_profile({{200, 0.0},
                                   {252, 3.5},
                                   {1000, 3.5},
                                   {252, 1.0},
                                   {60, 1.0},
                                   {100, 0.0},
                                   {200, 0.0},
                                   {208, -2.0},
                                   {800, -2.0},
                                   {208, 0.0},
                                   {100, 0.0}});
  const auto x = ramp_samples(samples_to_cover(speed));
  ExtractionConfig cfg = base_config();
  cfg.hop = kN / 2;     // 50 ms between the windows of a region, 0.1 s long each
  cfg.guard_s = 0.003;  // the first window starts 3 ms into its region
  WindowSlicer s(cfg, kFs, kT0);
  // 0.1 s min_duration against 3 ms guard + 0.1 s window: the window decides.
  EXPECT_EQ(s.new_run_close_ns(), 103 * kMs - 1);
  EXPECT_EQ(s.hop_samples(), static_cast<std::int64_t>(kN / 2));

  struct Seen {
    WindowRef ref;
    std::int64_t newest_speed_ns;  // when it was handed out
    std::int64_t max_due_ns;       // largest next_close_ns() since the previous window
    std::int64_t due_before_ns;    // next_close_ns() just before the step that handed it out
  };
  std::vector<Seen> seen;
  std::vector<float> buf(kN);
  std::int64_t newest_speed = 0;
  std::int64_t max_due = std::numeric_limits<std::int64_t>::min();
  std::size_t k = 0;
  constexpr std::size_t kBlock = 8;  // 4 ms: one speed sample per step
  for (std::size_t i = 0; i < x.size(); i += kBlock) {
    const std::int64_t due = s.next_close_ns();
    max_due = std::max(max_due, due);
    const std::size_t len = std::min(kBlock, x.size() - i);
    const std::int64_t t_end = kT0 + static_cast<std::int64_t>(static_cast<double>(i + len) / kFs * 1e9);
    for (; k < speed.size() && speed[k].t_ns <= t_end; ++k) {
      s.push_speed(speed[k]);
      newest_speed = speed[k].t_ns;
    }
    s.push_samples(std::span<const float>(x).subspan(i, len));
    WindowRef ref;
    while (s.pop(ref, buf)) {
      seen.push_back(Seen{ref, newest_speed, max_due, due});
      max_due = std::numeric_limits<std::int64_t>::min();
    }
  }
  std::vector<RegionInfo> regions;
  s.finish();
  RegionInfo r;
  while (s.pop_region(r)) regions.push_back(r);
  ASSERT_EQ(regions.size(), 2U);
  // Every window the two regions hold (counted independently of the slicer) was handed out.
  ASSERT_EQ(seen.size(),
            expected_windows(regions[0], kN / 2, 0.003) + expected_windows(regions[1], kN / 2, 0.003));
  for (const Seen& w : seen) {
    // Lower bound: the speed timeline had reached every due time given out before the window.
    EXPECT_GE(w.newest_speed_ns, w.max_due_ns) << "window " << w.ref.seq;
    EXPECT_GE(w.newest_speed_ns, w.ref.t_end_ns) << "window " << w.ref.seq;
    const RegionInfo& reg = regions[w.ref.region_seq];
    const std::int64_t close =
        w.ref.index_in_region == 0 ? std::max(w.ref.t_end_ns, reg.t_begin_ns + 100 * kMs) : w.ref.t_end_ns;
    // Exact: the step before the window was handed out already named its closing time.
    EXPECT_EQ(w.due_before_ns, close) << "window " << w.ref.seq << " (index " << w.ref.index_in_region << ")";
  }
}

TEST(WindowSlicerNextClose, WithoutARunItIsOneNewRunCloseAfterTheNewestSpeed) {
  ExtractionConfig cfg = base_config();
  cfg.min_duration_s = 0.25;  // longer than the 0.1 s window: the region's age decides
  WindowSlicer s(cfg, kFs, kT0);
  EXPECT_EQ(s.new_run_close_ns(), 250 * kMs);
  // No speed yet: from t0.
  EXPECT_EQ(s.next_close_ns(), kT0 + 1 + 250 * kMs);
  // Standstill: no run opens; the bound follows the newest speed sample.
  s.push_speed(SpeedSample{kT0 + 40 * kMs, 0.0, 0.0, false});
  EXPECT_EQ(s.next_close_ns(), kT0 + 40 * kMs + 1 + 250 * kMs);
  // A run opens at 44 ms: its first window can close at 44 ms + 0.25 s, no earlier.
  s.push_speed(SpeedSample{kT0 + 44 * kMs, 2.0, 0.0, false});
  EXPECT_EQ(s.next_close_ns(), kT0 + 44 * kMs + 250 * kMs);
  s.push_speed(SpeedSample{kT0 + 48 * kMs, 2.0, 0.0, false});
  EXPECT_EQ(s.next_close_ns(), kT0 + 44 * kMs + 250 * kMs);
  // The speed leaves the tolerance (a ramp): the run restarts at 52 ms.
  s.push_speed(SpeedSample{kT0 + 52 * kMs, 3.0, 0.0, false});
  EXPECT_EQ(s.next_close_ns(), kT0 + 52 * kMs + 250 * kMs);
}

}  // namespace
}  // namespace ptda::dsp
