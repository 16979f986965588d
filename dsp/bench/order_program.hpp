// Shared by order_bench and tests/unit/dsp/order_program_test.cpp: the bench's constants, fault and
// the synthetic jobs without a 0.2 s plateau (--program short|accel|long), with the two ways of cutting
// them (the product's time-domain WindowSlicer at its default tolerance, and the order-domain cutter).
// Header-only; see order_bench.cpp for the model.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "ptda/common/error.hpp"
#include "ptda/dsp/angle_resampler.hpp"
#include "ptda/dsp/order_windows.hpp"
#include "ptda/dsp/window_slicer.hpp"

namespace ptda::order_bench {

using namespace ptda::dsp;

inline constexpr double kPi = std::numbers::pi;
inline constexpr double kFs = 25600.0;
inline constexpr std::int64_t kT0 = 1'700'000'000'000'000'000;
inline constexpr double kRatio = 1.0 + 23.0 / 28.0 * 40.0;
inline constexpr std::uint32_t kS = 1024;
inline constexpr std::uint32_t kR = 8;
inline constexpr std::size_t kN = kS * kR;
inline constexpr double kF0 = 25.0;
inline constexpr std::size_t kFramePeriod = 100;

struct Fault {
  double impulse = 0.0;
  double am = 0.0;
};

// ---- Programs without a 0.2 s plateau (issue 16 item 4; --program short|accel) ----------------------
// A cycle is a list of speed segments (shaft speed as a fraction of f0). short: cosine ramps of 0.2 s
// between plateaus of 0.15 s at f0, 0.7 f0, f0, then down and 0.3 s standstill. accel: triangular,
// linear 0 -> f0 in 0.8 s and back to 0 in 0.8 s, 0.3 s standstill (no plateau at all). long: a
// control with one 1.0 s plateau at f0 between 0.2 s ramps, where the time-domain slicer can cut. The ripple
// multiplies the whole motion profile: v (1 + ripple sin(2 pi 3 Hz t + psi_cycle)). Vibration, CAN
// frames and fault are those of make_job(); `severity` scales both fault terms.
struct Segment {
  double dur_s, v0, v1;
  bool linear;
};

std::vector<Segment> program_cycle(const std::string& program) {
  if (program == "short")
    return {{0.2, 0.0, 1.0, false}, {0.15, 1.0, 1.0, false}, {0.2, 1.0, 0.7, false}, {0.15, 0.7, 0.7, false},
            {0.2, 0.7, 1.0, false}, {0.15, 1.0, 1.0, false}, {0.2, 1.0, 0.0, false}, {0.3, 0.0, 0.0, false}};
  if (program == "long")  // control: same ramps, one plateau of 1.0 s at f0 (the slicer must cut here)
    return {{0.2, 0.0, 1.0, false}, {1.0, 1.0, 1.0, false}, {0.2, 1.0, 0.0, false}, {0.3, 0.0, 0.0, false}};
  if (program == "accel") return {{0.8, 0.0, 1.0, true}, {0.8, 1.0, 0.0, true}, {0.3, 0.0, 0.0, true}};
  throw ptda::Error("order_bench: --program must be plateau, short, accel or long, not " + program);
}

struct ProgJob {
  std::vector<float> x;
  std::vector<SpeedSample> frames;
  double motion_s = 0.0;  ///< time with the shaft turning
};

/// The vibration and CAN frames along a shaft speed law `speed(t)` [rad/s] (shared by every program of
/// order_bench): GMF orders 28/56/84 with the per-cycle phases ph1..ph3, shaft order 1, white noise from
/// `rng`, and the fault's mesh AM and spur-rate ring. Draws from `rng` only inside the sample loop.
/// amp_law P: the mesh lines' amplitude grows as (shaft speed / f0)^P (0: independent of speed).
template <class Speed>
ProgJob synthesize_job(const Speed& speed, std::size_t n_total, std::uint32_t cycles, double cycle_s,
                       const std::vector<double>& ph1, const std::vector<double>& ph2,
                       const std::vector<double>& ph3, const Fault& fault, std::mt19937_64& rng,
                       double amp_law = 0.0) {
  std::normal_distribution<double> gauss(0.0, 1.0);
  const double w0 = 2.0 * kPi * kF0;
  ProgJob job;
  job.x.resize(n_total);
  double phi = 0.0;
  double w_prev = speed(0.0);
  const double spur_per_shaft = 28.0 / 23.0;
  double next_impact = 2.0 * kPi;
  double ring_t = -1.0;
  double ring_amp = 0.0;
  const double zeta = 0.05, f_res = 3000.0;
  const double wn = 2.0 * kPi * f_res;
  const double wd = wn * std::sqrt(1.0 - zeta * zeta);
  for (std::size_t n = 0; n < n_total; ++n) {
    const double t = static_cast<double>(n) / kFs;
    const double w = speed(t);
    if (w > 0.0) job.motion_s += 1.0 / kFs;
    if (n > 0) phi += 0.5 * (w + w_prev) / kFs;
    w_prev = w;
    const auto cyc = std::min<std::uint32_t>(cycles - 1, static_cast<std::uint32_t>(t / cycle_s));
    if (n % kFramePeriod == 0)
      job.frames.push_back(SpeedSample{kT0 + std::llround(t * 1e9), w / kRatio, phi / kRatio, true});
    const double spur = phi * spur_per_shaft;
    const double am =
        (1.0 + fault.am * std::cos(spur)) * (amp_law != 0.0 && w > 0.0 ? std::pow(w / w0, amp_law) : 1.0);
    double v = am * (std::cos(28.0 * phi + ph1[cyc]) + 0.5 * std::cos(56.0 * phi + ph2[cyc]) +
                     0.25 * std::cos(84.0 * phi + ph3[cyc])) +
               0.1 * std::cos(phi) + 0.2 * gauss(rng);
    if (fault.impulse > 0.0) {
      if (spur >= next_impact) {
        ring_t = t;
        ring_amp = fault.impulse * (w / w0);
        next_impact += 2.0 * kPi;
      }
      if (ring_t >= 0.0) {
        const double tau = t - ring_t;
        v += ring_amp * std::exp(-zeta * wn * tau) * std::sin(wd * tau);
      }
    }
    job.x[n] = static_cast<float>(v);
  }
  return job;
}

inline ProgJob make_program_job(std::uint64_t seed, std::uint32_t cycles, const std::string& program,
                                double ripple, const Fault& fault, double amp_law = 0.0) {
  const std::vector<Segment> seg = program_cycle(program);
  double cycle_s = 0.0;
  for (const Segment& s : seg) cycle_s += s.dur_s;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uni(0.0, 2.0 * kPi);
  const auto n_total = static_cast<std::size_t>(cycles * cycle_s * kFs);
  const double w0 = 2.0 * kPi * kF0;
  std::vector<double> psi(cycles), ph1(cycles), ph2(cycles), ph3(cycles);
  for (std::uint32_t c = 0; c < cycles; ++c) {
    psi[c] = uni(rng);
    ph1[c] = uni(rng);
    ph2[c] = uni(rng);
    ph3[c] = uni(rng);
  }
  const auto speed = [&](double t) {
    const auto cyc = std::min<std::uint32_t>(cycles - 1, static_cast<std::uint32_t>(t / cycle_s));
    double tc = t - cyc * cycle_s;
    for (const Segment& s : seg) {
      if (tc < s.dur_s) {
        const double u = tc / s.dur_s;
        const double a = s.linear ? u : 0.5 * (1.0 - std::cos(kPi * u));
        const double v = s.v0 + (s.v1 - s.v0) * a;
        return w0 * v * (1.0 + ripple * std::sin(2.0 * kPi * 3.0 * (t - cyc * cycle_s) + psi[cyc]));
      }
      tc -= s.dur_s;
    }
    return 0.0;
  };
  return synthesize_job(speed, n_total, cycles, cycle_s, ph1, ph2, ph3, fault, rng, amp_law);
}

/// Judged windows of one job with their end time (s from the job start) and span (s).
struct Cut {
  std::vector<std::vector<float>> w;
  std::vector<double> t_end_s;
  std::vector<double> speed_rad_s;  ///< order domain: each window's mean joint speed
  double judged_s = 0.0;
};

/// Time domain as the product cuts it: the real WindowSlicer with the default [extraction] speed
/// tolerance (ExtractionConfig{}: 2 % / 0.005 rad/s, min_duration 0.1 s, no guard), N = 8192, fed the
/// same CAN frames (joint speed) and samples in blocks of 512.
inline Cut time_cut(const ProgJob& job) {
  ExtractionConfig cfg;
  cfg.window_len = kN;
  WindowSlicer sl(cfg, kFs, kT0);
  Cut c;
  std::vector<float> buf(kN);
  WindowRef ref;
  std::size_t f = 0;
  const auto drain = [&] {
    while (sl.pop(ref, buf)) {
      c.w.push_back(buf);
      c.t_end_s.push_back(static_cast<double>(ref.t_end_ns - kT0) * 1e-9);
      c.judged_s += static_cast<double>(ref.t_end_ns - ref.t_start_ns) * 1e-9;
    }
  };
  for (std::size_t pos = 0; pos < job.x.size(); pos += 512) {
    const std::size_t m = std::min<std::size_t>(512, job.x.size() - pos);
    const std::int64_t t_end = kT0 + std::llround(static_cast<double>(pos + m) / kFs * 1e9);
    while (f < job.frames.size() && job.frames[f].t_ns < t_end) sl.push_speed(job.frames[f++]);
    sl.push_samples(std::span<const float>(job.x.data() + pos, m));
    drain();
  }
  sl.finish();
  drain();
  return c;
}

/// Order domain, one class = forward motion in the speed band [0.4 f0, 1.07 f0] (every sample of the
/// window), so windows across ramps are judged; no speed normalisation of the amplitude.
inline Cut order_cut(const ProgJob& job) {
  AngleResamplerConfig rc;
  rc.samples_per_rev = kS;
  rc.ratio = kRatio;
  AngleResampler res(rc, kFs, kT0);
  OrderWindowCutter cut(OrderWindowConfig{kS, kR, kRatio, res.pass_order()});
  Cut c;
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
      if (cut.push(o, ref, buf) && ref.min_shaft_speed_rad_s >= 0.4 * 2.0 * kPi * kF0 &&
          ref.max_shaft_speed_rad_s <= 1.07 * 2.0 * kPi * kF0) {
        c.w.push_back(buf);
        c.t_end_s.push_back(static_cast<double>(ref.t_end_ns - kT0) * 1e-9);
        c.speed_rad_s.push_back(ref.joint_speed_rad_s);
        c.judged_s += static_cast<double>(ref.t_end_ns - ref.t_start_ns) * 1e-9;
      }
    }
  }
  return c;
}

/// The speed law of train_order_baseline on one cut (one class: the bench's band), and the windows of
/// `cuts` normalised with it to the class's mean training speed. Returns the fit.
inline SpeedLawFit normalise_speed_law(Cut& train, std::vector<Cut*> others) {
  SegmentClass c;
  c.direction = 1;
  for (const double v : train.speed_rad_s) c.speed_rad_s += v / static_cast<double>(train.speed_rad_s.size());
  c.speed_tol_rad_s = 1e9;  // every window of the band
  std::vector<OrderWindowRef> refs(train.w.size());
  for (std::size_t i = 0; i < refs.size(); ++i) refs[i].joint_speed_rad_s = train.speed_rad_s[i];
  const SpeedLawFit f = fit_speed_law(refs, train.w, {c});
  others.push_back(&train);
  for (Cut* cut : others) {
    for (std::size_t i = 0; i < cut->w.size(); ++i) {
      const auto g = static_cast<float>(speed_law_gain(c.speed_rad_s, cut->speed_rad_s[i], f.applied));
      for (float& x : cut->w[i]) x *= g;
    }
  }
  return f;
}

}  // namespace ptda::order_bench
