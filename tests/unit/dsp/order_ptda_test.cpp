// Order-domain PTDA (issue 16): windows of whole input-shaft revolutions from the AngleResampler,
// analysed by the time domain's WindowAnalyzer and trained by build_class_baseline().
//  1. Constant speed, S f = fs: the order windows are the time windows (through the anti-alias kernel),
//     so their features agree with the time domain's within a tolerance computed from the kernel ripple.
//  2. A job with +-3 % speed ripple: trained on a healthy job without ripple, a fresh healthy job with
//     ripple keeps its order-domain PTDA residual at the healthy level while the time domain's grows
//     (computed from both pipelines, not hard-coded).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "ptda/common/error.hpp"
#include "ptda/dsp/analyzer.hpp"
#include "ptda/dsp/angle_resampler.hpp"
#include "ptda/dsp/order_windows.hpp"
#include "ptda/dsp/real_fft.hpp"
#include "ptda/dsp/training.hpp"

namespace ptda::dsp {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kFs = 25600.0;
constexpr std::int64_t kT0 = 1'700'000'000'000'000'000;
constexpr double kRatio = 1.0 + 23.0 / 28.0 * 40.0;
constexpr std::uint32_t kS = 1024;  // samples per input-shaft revolution
constexpr std::uint32_t kR = 8;     // revolutions per window
constexpr std::size_t kN = kS * kR;
constexpr double kF0 = 25.0;  // nominal shaft speed, Hz: S f0 = fs, one revolution = 1024 samples
constexpr std::size_t kFramePeriod = 100;  // CAN frame every 100 samples (3.906 ms)

struct Job {
  std::vector<float> x;
  std::vector<SpeedSample> frames;
  std::vector<std::pair<std::size_t, std::size_t>> plateau;  ///< sample ranges [begin, end) of plateaus
};

/// A job of `cycles` cycles: 0.2 s cosine ramp up to f0, `plateau_s` at f0 (1 + ripple sin(2 pi 3 Hz t +
/// psi_c)), 0.2 s ramp down, 0.3 s standstill. Vibration: GMF orders 28, 56, 84 (amplitudes 1, 0.5, 0.25,
/// a random phase per cycle) and shaft order 1 (0.1) on the shaft angle, plus Gaussian noise of rms
/// noise_rms, white, or low-passed to 0.3 fs when band_limited. continuous: one plateau with no ramps,
/// starting at speed f0 at t = 0 with angle 0 (so that the resampler's grid k falls on sample k).
Job make_job(std::uint32_t seed, std::uint32_t cycles, double ripple_rel, double plateau_s, double noise_rms,
             bool band_limited, bool continuous) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uni(0.0, 2.0 * kPi);
  const double ramp_s = continuous ? 0.0 : 0.2;
  const double stand_s = continuous ? 0.0 : 0.3;
  const double cycle_s = 2.0 * ramp_s + plateau_s + stand_s;
  const auto n_total = static_cast<std::size_t>(std::ceil(cycles * cycle_s * kFs / 1024.0) * 1024.0);
  const double w0 = 2.0 * kPi * kF0;
  std::vector<double> psi(cycles), ph1(cycles), ph2(cycles), ph3(cycles);
  for (std::uint32_t c = 0; c < cycles; ++c) {
    psi[c] = uni(rng);
    ph1[c] = uni(rng);
    ph2[c] = uni(rng);
    ph3[c] = uni(rng);
  }
  const auto speed = [&](double t, std::uint32_t& cyc) {
    cyc = std::min<std::uint32_t>(cycles - 1, static_cast<std::uint32_t>(t / cycle_s));
    const double tc = t - cyc * cycle_s;
    if (tc < ramp_s) return w0 * 0.5 * (1.0 - std::cos(kPi * tc / ramp_s));
    if (tc < ramp_s + plateau_s)
      return w0 * (1.0 + ripple_rel * std::sin(2.0 * kPi * 3.0 * (tc - ramp_s) + psi[cyc]));
    if (tc < 2.0 * ramp_s + plateau_s)
      return w0 * 0.5 * (1.0 + std::cos(kPi * (tc - ramp_s - plateau_s) / ramp_s));
    return 0.0;
  };
  Job job;
  job.x.resize(n_total);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::vector<float> noise(n_total);
  for (float& v : noise) v = static_cast<float>(gauss(rng));
  if (band_limited) {
    RealFft fft(n_total);
    std::vector<std::complex<float>> spec(fft.bins());
    fft.forward(noise, spec);
    for (std::size_t k = 0; k < spec.size(); ++k)
      if (static_cast<double>(k) > 0.3 * static_cast<double>(n_total)) spec[k] = 0.0F;
    fft.inverse(spec, noise);
  }
  double sq = 0.0;
  for (const float v : noise) sq += static_cast<double>(v) * v;
  const double noise_scale = noise_rms / std::sqrt(sq / static_cast<double>(n_total));
  double phi = 0.0;
  std::uint32_t cyc = 0;
  double w_prev = speed(0.0, cyc);
  for (std::size_t n = 0; n < n_total; ++n) {
    const double t = static_cast<double>(n) / kFs;
    const double w = speed(t, cyc);
    if (n > 0) phi += 0.5 * (w + w_prev) / kFs;  // trapezoid on the sample grid
    w_prev = w;
    if (n % kFramePeriod == 0)
      job.frames.push_back(SpeedSample{kT0 + std::llround(t * 1e9), w / kRatio, phi / kRatio, true});
    job.x[n] = static_cast<float>(std::cos(28.0 * phi + ph1[cyc]) + 0.5 * std::cos(56.0 * phi + ph2[cyc]) +
                                  0.25 * std::cos(84.0 * phi + ph3[cyc]) + 0.1 * std::cos(phi) +
                                  noise_scale * noise[n]);
  }
  for (std::uint32_t c = 0; c < cycles; ++c) {
    // Time windows from 0.05 s into the plateau (the time-domain slicer's guard) to its end.
    const auto b =
        static_cast<std::size_t>(std::ceil((c * cycle_s + ramp_s + (continuous ? 0.0 : 0.05)) * kFs));
    const auto e = std::min(n_total, static_cast<std::size_t>((c * cycle_s + ramp_s + plateau_s) * kFs));
    job.plateau.emplace_back(b, e);
  }
  return job;
}

/// Time-domain windows: consecutive N-sample windows inside each plateau (whatever the speed tolerance:
/// this favours the time domain, whose slicer would cut few of them under ripple). Group = window.
OrderWindows time_windows(const Job& job) {
  OrderWindows w;
  for (const auto& [b, e] : job.plateau) {
    for (std::size_t s = b; s + kN <= e; s += kN) {
      OrderWindowRef r;
      r.seq = w.refs.size();
      r.segment = r.seq;
      r.joint_speed_rad_s = 2.0 * kPi * kF0 / kRatio;
      w.refs.push_back(r);
      w.windows.emplace_back(job.x.begin() + static_cast<std::ptrdiff_t>(s),
                             job.x.begin() + static_cast<std::ptrdiff_t>(s + kN));
    }
  }
  return w;
}

/// Order windows: the job through AngleResampler and OrderWindowCutter (band-limited to the resampler's
/// pass band unless band_limit is false), blocks of 512 samples with the frames interleaved in time order.
OrderWindows order_windows(const Job& job, bool band_limit = true) {
  AngleResamplerConfig rc;
  rc.samples_per_rev = kS;
  rc.ratio = kRatio;
  AngleResampler res(rc, kFs, kT0);
  OrderWindowCutter cut(OrderWindowConfig{kS, kR, kRatio, band_limit ? res.pass_order() : 0.0});
  OrderWindows w;
  std::vector<float> buf(kN);
  OrderWindowRef ref;
  OrderSample o;
  std::size_t f = 0;
  for (std::size_t pos = 0; pos < job.x.size(); pos += 512) {
    const std::size_t m = std::min<std::size_t>(512, job.x.size() - pos);
    const std::int64_t t_end = kT0 + std::llround(static_cast<double>(pos + m) / kFs * 1e9);
    while (f < job.frames.size() && job.frames[f].t_ns < t_end) res.push_speed(job.frames[f++]);
    res.push_samples(std::span<const float>(job.x.data() + pos, m));
    while (res.pop(o)) {
      if (cut.push(o, ref, buf)) {
        w.refs.push_back(ref);
        w.windows.push_back(buf);
      }
    }
  }
  return w;
}

ClassBaseline train(const OrderWindows& w) {
  std::vector<std::uint64_t> groups;
  for (const OrderWindowRef& r : w.refs) groups.push_back(r.seq);
  SegmentClass c;
  c.speed_rad_s = 2.0 * kPi * kF0 / kRatio;
  return build_class_baseline(c, w.windows, groups, ThresholdPolicy{});
}

/// Windows whose mean shaft speed is within 5 % of f0 (the plateau class).
OrderWindows plateau_only(const OrderWindows& w) {
  OrderWindows out;
  for (std::size_t i = 0; i < w.refs.size(); ++i) {
    if (std::fabs(w.refs[i].shaft_speed_rad_s / (2.0 * kPi * kF0) - 1.0) > 0.05) continue;
    out.refs.push_back(w.refs[i]);
    out.refs.back().seq = out.refs.size() - 1;
    out.windows.push_back(w.windows[i]);
  }
  return out;
}

/// The same band limit as the cutter's, on a time window: bins above floor(max_order R) set to 0.
std::vector<float> band_limited(const std::vector<float>& x, double max_order) {
  RealFft fft(x.size());
  std::vector<std::complex<float>> spec(fft.bins());
  fft.forward(x, spec);
  const auto keep = static_cast<std::size_t>(std::floor(max_order * kR)) + 1;
  std::fill(spec.begin() + static_cast<std::ptrdiff_t>(keep), spec.end(), std::complex<float>{});
  std::vector<float> out(x.size());
  fft.inverse(spec, out);
  return out;
}

struct Agreement {
  double rms_rel = 0.0, ent_abs = 0.0, raw_rel = 0.0;
};

/// Largest differences of PTDA and raw features between paired time and order windows, each domain
/// trained on its own windows (each window its own leave-out group).
Agreement agreement(const std::vector<std::vector<float>>& t, const std::vector<std::vector<float>>& o) {
  std::vector<std::uint64_t> groups(t.size());
  for (std::size_t i = 0; i < groups.size(); ++i) groups[i] = i;
  const ClassBaseline tb = build_class_baseline(SegmentClass{}, t, groups, ThresholdPolicy{});
  const ClassBaseline ob = build_class_baseline(SegmentClass{}, o, groups, ThresholdPolicy{});
  WindowAnalyzer a(kN);
  Agreement g;
  for (std::size_t i = 0; i < t.size(); ++i) {
    const Features ft = a.analyze(t[i], tb, Method::kPtda);
    const Features fo = a.analyze(o[i], ob, Method::kPtda);
    g.rms_rel = std::max(g.rms_rel, std::fabs(fo.rms_res / ft.rms_res - 1.0));
    g.ent_abs = std::max(g.ent_abs, std::fabs(fo.entropy_res - ft.entropy_res));
    const Features rt = a.analyze(t[i], tb, Method::kRaw);
    const Features ro = a.analyze(o[i], ob, Method::kRaw);
    g.raw_rel = std::max(g.raw_rel, std::fabs(ro.rms_res / rt.rms_res - 1.0));
  }
  return g;
}

TEST(OrderPtda, ConstantSpeedAgreesWithTimeDomain) {
  // One plateau of 40 windows (327680 samples, an FFT length for the noise filter) at f0 = 25 Hz from
  // t = 0 with angle 0: order sample k is at sample k. Noise low-passed to 0.3 fs = order 307 (inside the
  // resampler's pass band up to order 369), so the order windows equal the time windows within the
  // kernel's pass-band ripple (<= 1e-4 of the signal). The features are compared with the cutter's band
  // limit (orders above the pass band set to 0) applied to both: it changes the features of a window
  // whose content is not periodic in it (the edges' leakage above the pass band is removed), in both
  // domains alike.
  const Job job = make_job(11, 1, 0.0, 40.0 * kN / kFs, 0.3, true, true);
  const OrderWindows tw = time_windows(job);
  const OrderWindows ow = order_windows(job, false);
  const OrderWindows owb = order_windows(job, true);
  ASSERT_GE(ow.windows.size(), 38U);
  ASSERT_EQ(owb.windows.size(), ow.windows.size());
  AngleResamplerConfig rc;
  rc.samples_per_rev = kS;
  rc.ratio = kRatio;
  const double pass = AngleResampler(rc, kFs, kT0).pass_order();
  // Pair order window k_start = m N with time window m (time windows start at sample 0).
  std::vector<std::vector<float>> tpaired, opaired;
  double max_diff = 0.0;
  for (std::size_t i = 0; i < ow.refs.size(); ++i) {
    const auto m = static_cast<std::size_t>(ow.refs[i].k_start / static_cast<std::int64_t>(kN));
    ASSERT_LT(m, tw.windows.size());
    ASSERT_NEAR(ow.refs[i].shaft_speed_rad_s, 2.0 * kPi * kF0, 1e-6 * 2.0 * kPi * kF0);
    for (std::size_t n = 0; n < kN; ++n)
      max_diff = std::max(max_diff, static_cast<double>(std::fabs(tw.windows[m][n] - ow.windows[i][n])));
    tpaired.push_back(band_limited(tw.windows[m], pass));
    opaired.push_back(owb.windows[i]);
  }
  // Features without the band limit (the resampler alone) and with it on both sides.
  std::vector<std::vector<float>> traw, oraw;
  for (std::size_t i = 0; i < ow.refs.size(); ++i) {
    traw.push_back(tw.windows[static_cast<std::size_t>(ow.refs[i].k_start / static_cast<std::int64_t>(kN))]);
    oraw.push_back(ow.windows[i]);
  }
  const Agreement unbanded = agreement(traw, oraw);
  const Agreement banded = agreement(tpaired, opaired);
  std::printf(
      "max |sample diff| %.3g; PTDA rms_res rel %.3g, entropy abs %.3g, raw rms rel %.3g; band-limited: "
      "PTDA rms_res rel %.3g, entropy abs %.3g\n",
      max_diff, unbanded.rms_rel, unbanded.ent_abs, unbanded.raw_rel, banded.rms_rel, banded.ent_abs);
  // Tolerance: a sample differs by at most the kernel ripple times the signal's peak (about 2.2 here),
  // so 2.2e-4 absolute; the PTDA residual (about 0.47 x the 0.3 noise rms, docs/method.md §2) is 0.14,
  // so its rms can move by up to 2.2e-4 / 0.14 = 1.6e-3 relative. Measured (x86-64, GCC 12, release):
  // samples 8.0e-5, PTDA rms_res 1.4e-4 relative, entropy 4.6e-6, raw rms 1.5e-5.
  EXPECT_LT(max_diff, 2.2e-4);
  EXPECT_LT(unbanded.raw_rel, 2e-4);
  EXPECT_LT(unbanded.rms_rel, 1.6e-3);
  EXPECT_LT(unbanded.ent_abs, 1e-3);
  // With the band limit on both sides the agreement is looser: measured PTDA rms_res 1.6e-2 relative,
  // entropy 1.4e-3. Not derived: PTDA's line groups (4 x a local median) and floor gain (a median) are
  // discrete decisions that the small differences can flip once the top bins hold only the windows'
  // edge leakage (docs/method.md §9 lists this as open). Pinned at about twice the measured values.
  EXPECT_LT(banded.rms_rel, 0.03);
  EXPECT_LT(banded.ent_abs, 3e-3);
}

double mean_ptda_rms(const ClassBaseline& cls, const OrderWindows& w) {
  WindowAnalyzer a(kN);
  double s = 0.0;
  for (const auto& x : w.windows) s += a.analyze(x, cls, Method::kPtda).rms_res;
  return s / static_cast<double>(w.windows.size());
}

double abnormal_share(const ClassBaseline& cls, const OrderWindows& w) {
  WindowAnalyzer a(kN);
  const FeatureThresholds& th = cls.thresholds[static_cast<std::size_t>(Method::kPtda)];
  std::size_t bad = 0;
  for (const auto& x : w.windows) {
    const Features f = a.analyze(x, cls, Method::kPtda);
    if (!th.rms.contains(f.rms_res) || !th.entropy.contains(f.entropy_res)) ++bad;
  }
  return static_cast<double>(bad) / static_cast<double>(w.windows.size());
}

TEST(OrderPtda, SpeedRippleSmearsTheTimeDomainNotTheOrderDomain) {
  // Training: healthy job, no ripple (seed 21). Reference: a fresh healthy job, no ripple (seed 22).
  // Judged: a fresh healthy job with +-3 % speed ripple at 3 Hz (seed 23). 12 cycles of 2.6 s plateaus.
  const Job train_job = make_job(21, 12, 0.0, 2.6, 0.2, false, false);
  const Job ref_job = make_job(22, 12, 0.0, 2.6, 0.2, false, false);
  const Job rip_job = make_job(23, 12, 0.03, 2.6, 0.2, false, false);
  const ClassBaseline tb = train(time_windows(train_job));
  const ClassBaseline ob = train(plateau_only(order_windows(train_job)));
  const OrderWindows t_ref = time_windows(ref_job), t_rip = time_windows(rip_job);
  const OrderWindows o_ref = plateau_only(order_windows(ref_job)),
                     o_rip = plateau_only(order_windows(rip_job));
  ASSERT_GE(o_rip.windows.size(), 60U);
  ASSERT_GE(t_rip.windows.size(), 60U);
  const double t_ratio = mean_ptda_rms(tb, t_rip) / mean_ptda_rms(tb, t_ref);
  const double o_ratio = mean_ptda_rms(ob, o_rip) / mean_ptda_rms(ob, o_ref);
  const double t_bad = abnormal_share(tb, t_rip), o_bad = abnormal_share(ob, o_rip);
  const double t_bad_ref = abnormal_share(tb, t_ref), o_bad_ref = abnormal_share(ob, o_ref);
  std::printf(
      "ripple 3 %%: PTDA rms_res / healthy no-ripple level: time %.3f, order %.3f; abnormal windows "
      "time %.3f (no ripple %.3f), order %.3f (no ripple %.3f); windows time %zu, order %zu\n",
      t_ratio, o_ratio, t_bad, t_bad_ref, o_bad, o_bad_ref, t_rip.windows.size(), o_rip.windows.size());
  // Measured (x86-64, GCC 12, release): time 7.95, order 1.004; abnormal time 100 %, order 0 % (0 % and
  // 0 % without ripple); 84 time and 90 order windows.
  // The order domain stays at the healthy level (the residual's floor moves with the speed: the noise per
  // order bin scales with the shaft speed, which the floor gain refers away), the time domain smears.
  EXPECT_LT(std::fabs(o_ratio - 1.0), 0.05);
  EXPECT_GT(t_ratio, 2.0);
  EXPECT_LE(o_bad, 0.05);
  EXPECT_GE(t_bad, 0.9);
}

TEST(OrderPtda, TrainedClassesMatchTheirWindows) {
  // Order windows of a whole job (ramps included) with +-3 % ripple: the plateau windows form one class
  // per direction and speed band, and every plateau window of a fresh job matches it.
  const Job job = make_job(31, 6, 0.03, 2.6, 0.2, false, false);
  const OrderWindows w = order_windows(job);
  std::vector<std::string> dropped;
  const Baseline b = train_order_baseline(w, OrderWindowConfig{kS, kR, kRatio}, 0.1, ThresholdPolicy{},
                                          GearboxInfo{}, &dropped);
  EXPECT_EQ(b.fs_hz, static_cast<double>(kS));
  EXPECT_EQ(b.window_len, kN);
  const double joint = 2.0 * kPi * kF0 / kRatio;
  const ClassBaseline* c = b.match(joint);
  ASSERT_NE(c, nullptr);
  EXPECT_NEAR(c->segment.speed_rad_s, joint, 0.01 * joint);
  EXPECT_EQ(c->segment.regions, 6U);
  const OrderWindows fresh = plateau_only(order_windows(make_job(32, 4, 0.03, 2.6, 0.2, false, false)));
  ASSERT_FALSE(fresh.refs.empty());
  for (const OrderWindowRef& r : fresh.refs) EXPECT_EQ(b.match(r.joint_speed_rad_s), c);
  EXPECT_THROW((void)train_order_baseline(OrderWindows{}, OrderWindowConfig{kS, kR, kRatio}, 0.1,
                                          ThresholdPolicy{}, GearboxInfo{}),
               Error);
}

TEST(OrderPtda, StreamedTrainingWithSpilledListsMatchesTheWindowsHeld) {
  // `ptda train` in the order domain streams its windows (train_order_baseline_streamed). With 64 bytes
  // per list every per-window list spills (the index, the classes' speeds and segments, the
  // leave-one-out features): the classes, counts, means and the speed law are the same as with the
  // windows held, the thresholds agree to rounding; a spill directory that does not exist is named.
  const Job job = make_job(34, 8, 0.03, 2.6, 0.2, false, false);
  const OrderWindows w = order_windows(job);
  const OrderWindowConfig cfg{kS, kR, kRatio};
  const Baseline held = train_order_baseline(w, cfg, 0.1, ThresholdPolicy{}, GearboxInfo{}, nullptr, true);
  ASSERT_FALSE(held.classes.empty());
  EXPECT_NE(held.speed_law_fit, 0.0);
  const auto index_with = [&](const SpillConfig& spill) {
    OrderTrainingIndex index(spill);
    for (std::size_t i = 0; i < w.refs.size(); ++i) {
      index.refs.push_back(w.refs[i]);
      index.recording.push_back(0U);
      index.mean_square.push_back(window_mean_square(w.windows[i]));
    }
    return index;
  };
  int passes = 0;
  const TrainingWindowPass pass = [&](const TrainingWindowVisitor& visit) {
    ++passes;
    for (std::size_t i = 0; i < w.windows.size(); ++i) visit(i, w.windows[i]);
  };
  SpillConfig tiny;
  tiny.memory_bytes = 64;
  const Baseline s = train_order_baseline_streamed(index_with(tiny), pass, cfg, 0.1, ThresholdPolicy{},
                                                   GearboxInfo{}, nullptr, true);
  EXPECT_EQ(passes, 2);
  EXPECT_EQ(s.speed_law_fit, held.speed_law_fit);
  EXPECT_EQ(s.speed_law_exponent, held.speed_law_exponent);
  ASSERT_EQ(s.classes.size(), held.classes.size());
  const auto rel = [](double a, double b) {
    return std::fabs(a - b) / std::max(1e-300, std::max(std::fabs(a), std::fabs(b)));
  };
  for (std::size_t k = 0; k < held.classes.size(); ++k) {
    EXPECT_EQ(s.classes[k].segment.speed_rad_s, held.classes[k].segment.speed_rad_s);
    EXPECT_EQ(s.classes[k].segment.regions, held.classes[k].segment.regions);
    EXPECT_EQ(s.classes[k].n_windows, held.classes[k].n_windows);
    EXPECT_EQ(s.classes[k].mean_magnitude, held.classes[k].mean_magnitude);
    for (std::size_t m = 0; m < kMethodCount; ++m) {
      EXPECT_LT(rel(s.classes[k].thresholds[m].rms.hi, held.classes[k].thresholds[m].rms.hi), 1e-12);
      EXPECT_LT(rel(s.classes[k].thresholds[m].entropy.lo, held.classes[k].thresholds[m].entropy.lo), 1e-12);
    }
  }
  SpillConfig nowhere = tiny;
  nowhere.dir = "/nonexistent-ptda-order-spill";
  try {
    (void)train_order_baseline_streamed(index_with(nowhere), pass, cfg, 0.1, ThresholdPolicy{},
                                        GearboxInfo{});
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent-ptda-order-spill"), std::string::npos) << e.what();
  }
}

TEST(OrderPtda, MinSegmentsIsTheConfiguredMinRegions) {
  // The plateau windows of two cycles are two resampler segments: a class needs 3 by default
  // ([classes] min_regions = 3), so training fails naming why; with min_segments 2 (or 1) it trains.
  const Job job = make_job(33, 2, 0.0, 2.6, 0.2, false, false);
  const OrderWindows w = plateau_only(order_windows(job));
  ASSERT_FALSE(w.refs.empty());
  try {
    (void)train_order_baseline(w, OrderWindowConfig{kS, kR, kRatio}, 0.1, ThresholdPolicy{}, GearboxInfo{});
    ADD_FAILURE() << "trained with 2 segments and min_segments 3";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("2 segment(s), fewer than 3"), std::string::npos) << e.what();
  }
  const Baseline b = train_order_baseline(w, OrderWindowConfig{kS, kR, kRatio}, 0.1, ThresholdPolicy{},
                                          GearboxInfo{}, nullptr, false, 2);
  ASSERT_EQ(b.classes.size(), 1U);
  EXPECT_EQ(b.classes[0].segment.regions, 2U);
}

TEST(OrderPtda, CutterDropsAPartialWindowAtAGap) {
  OrderWindowCutter cut(OrderWindowConfig{16, 2, 1.0});  // N = 32
  std::vector<float> out(32);
  OrderWindowRef ref;
  int windows = 0;
  for (std::int64_t k = 0; k < 200; ++k) {
    if (k == 70) continue;  // a gap inside the window [64, 96)
    OrderSample s;
    s.k = k;
    s.t_ns = k * 1'000'000;
    s.shaft_speed_rad_s = 2.0 * kPi * 16.0 / 16.0 / 1e-3 / 16.0;
    if (cut.push(s, ref, out)) {
      ++windows;
      EXPECT_EQ(ref.k_start % 32, 0);
      EXPECT_NE(ref.k_start, 64);
    }
  }
  EXPECT_EQ(windows, 5);  // [0,32) [32,64) [96,128) [128,160) [160,192)
  EXPECT_THROW(OrderWindowCutter(OrderWindowConfig{16, 7, 1.0}), Error);  // 112 = 2^4 7
}

TEST(OrderPtda, CutterBandLimitsTheWindowToMaxOrder) {
  // N = 64 samples over R = 4 revolutions (S = 16): orders 1 and 5 in, max_order 3: order 5 (bin 20)
  // must vanish, order 1 (bin 4) stay.
  OrderWindowCutter cut(OrderWindowConfig{16, 4, 1.0, 3.0});
  std::vector<float> out(64);
  OrderWindowRef ref;
  bool got = false;
  for (std::int64_t k = 0; k < 64; ++k) {
    OrderSample s;
    s.k = k;
    s.t_ns = k;
    const double a = 2.0 * kPi * static_cast<double>(k) / 16.0;
    s.value = static_cast<float>(std::cos(a) + std::cos(5.0 * a));
    got = cut.push(s, ref, out);
  }
  ASSERT_TRUE(got);
  for (std::int64_t k = 0; k < 64; ++k)
    EXPECT_NEAR(out[static_cast<std::size_t>(k)], std::cos(2.0 * kPi * static_cast<double>(k) / 16.0), 1e-5);
}

// The speed law's fit (fit_speed_law): three classes at 1, 2 and 3 rad/s with windows spread +-5 % in
// speed, each a line of amplitude c_k |v|^1.5 (its own level per class) plus white noise. The pooled
// within-class slope recovers 1.5; with amplitude independent of speed nothing significant is applied.
TEST(SpeedLaw, FitRecoversAKnownExponentAndAppliesOnlyASignificantOne) {
  std::mt19937_64 rng(2026);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_real_distribution<double> spread(-0.05, 0.05), phase(0.0, 2.0 * kPi);
  std::vector<SegmentClass> classes;
  for (int k = 0; k < 3; ++k) {
    SegmentClass c;
    c.id = static_cast<std::uint32_t>(k);
    c.direction = 1;
    c.speed_rad_s = 1.0 + k;
    c.speed_tol_rad_s = 0.06 * c.speed_rad_s;
    classes.push_back(c);
  }
  const auto make = [&](double exponent, std::vector<OrderWindowRef>& refs,
                        std::vector<std::vector<float>>& w) {
    for (int k = 0; k < 3; ++k) {
      for (int i = 0; i < 40; ++i) {
        OrderWindowRef r;
        r.direction = 1;
        r.joint_speed_rad_s = (1.0 + k) * (1.0 + spread(rng));
        const double a = (1.0 + 0.5 * k) * std::pow(r.joint_speed_rad_s, exponent);
        const double ph = phase(rng);
        std::vector<float> x(256);
        for (std::size_t n = 0; n < x.size(); ++n)
          x[n] = static_cast<float>(a * std::cos(2.0 * kPi * 8.0 * n / 256.0 + ph) + 0.02 * gauss(rng));
        refs.push_back(r);
        w.push_back(std::move(x));
      }
    }
  };
  std::vector<OrderWindowRef> refs;
  std::vector<std::vector<float>> w;
  make(1.5, refs, w);
  // A window of no class (-2 rad/s) is left out of the fit.
  OrderWindowRef stray;
  stray.direction = -1;
  stray.joint_speed_rad_s = -2.0;
  refs.push_back(stray);
  w.emplace_back(256, 5.0F);
  const SpeedLawFit f = fit_speed_law(refs, w, classes);
  EXPECT_EQ(f.windows, 120U);
  EXPECT_NEAR(f.exponent, 1.5, 0.05);
  EXPECT_GT(f.se, 0.0);
  EXPECT_LT(f.se, 0.05);
  EXPECT_EQ(f.applied, f.exponent);

  std::vector<OrderWindowRef> refs0;
  std::vector<std::vector<float>> w0;
  make(0.0, refs0, w0);
  const SpeedLawFit f0 = fit_speed_law(refs0, w0, classes);
  EXPECT_LT(std::fabs(f0.exponent), 2.0 * f0.se) << f0.exponent << " +- " << f0.se;
  EXPECT_EQ(f0.applied, 0.0);
  // Too few windows for a slope with 3 residual degrees of freedom: nothing fitted.
  const std::vector<OrderWindowRef> few(refs.begin(), refs.begin() + 4);
  const std::vector<std::vector<float>> few_w(w.begin(), w.begin() + 4);
  const SpeedLawFit none = fit_speed_law(few, few_w, classes);
  EXPECT_EQ(none.exponent, 0.0);
  EXPECT_EQ(none.applied, 0.0);
}

}  // namespace
}  // namespace ptda::dsp
