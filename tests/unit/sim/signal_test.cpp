// Motion (LSPB), vibration synthesis (mesh phase, tooth impacts, AM), sensor quantisation, CAN frames.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include "ptda/common/time.hpp"
#include "ptda/config/speed_codec.hpp"
#include "ptda/sim/random.hpp"
#include "ptda/sim/simulator.hpp"

namespace ptda::sim {
namespace {

constexpr double kPi = std::numbers::pi;

double wrap(double a) {
  return std::remainder(a, 2.0 * kPi);
}

Scenario reciprocating(std::uint32_t cycles) {
  Scenario s;
  s.source = "test";
  s.motion.via_points_rad = {0.0, kPi, 0.0};
  s.motion.segment_speeds_rad_s = {3.49068, 3.49068};
  s.motion.accel_rad_s2 = 17.45;
  s.motion.cycles = cycles;
  s.motion.dwell_s = 0.4;
  s.motion.start_jitter_s = 0.05;
  s.motion.lead_in_s = 0.2;
  s.vibration.noise_rms = 0.0;
  s.vibration.reference_speed_rad_s = 3.49068;
  return s;
}

Scenario constant_speed(double shaft_hz, double duration_s) {
  Scenario s;
  s.source = "test";
  s.motion.kind = MotionKind::kConstant;
  s.motion.shaft_speed_hz = shaft_hz;
  s.motion.duration_s = duration_s;
  s.motion.cycles = 1;
  s.vibration.noise_rms = 0.0;
  return s;
}

// Least-squares phase psi of x[n] ~ c sin(w (t_n - t0) + psi) over samples [i0, i1).
double fit_phase(const std::vector<double>& x, double fs, std::size_t i0, std::size_t i1, double w,
                 double t0) {
  double ss = 0, sc = 0, cc = 0, xs = 0, xc = 0;
  for (std::size_t i = i0; i < i1; ++i) {
    const double tau = static_cast<double>(i) / fs - t0;
    const double s = std::sin(w * tau);
    const double c = std::cos(w * tau);
    ss += s * s;
    sc += s * c;
    cc += c * c;
    xs += x[i] * s;
    xc += x[i] * c;
  }
  // x = a s + b c; a = cos(psi), b = sin(psi)
  const double det = ss * cc - sc * sc;
  const double a = (xs * cc - xc * sc) / det;
  const double b = (xc * ss - xs * sc) / det;
  return std::atan2(b, a);
}

TEST(Rng, DeterministicAndRoughlyNormal) {
  Rng a(42, 2);
  Rng b(42, 2);
  Rng c(42, 3);
  EXPECT_EQ(a.next_u64(), b.next_u64());
  EXPECT_NE(Rng(42, 2).next_u64(), c.next_u64());
  Rng r(7);
  double sum = 0, sum2 = 0;
  const int n = 200000;
  for (int i = 0; i < n; ++i) {
    const double v = r.normal();
    sum += v;
    sum2 += v * v;
  }
  // Mean within 4 standard errors (4/sqrt(n) = 0.009), variance within 2 %.
  EXPECT_NEAR(sum / n, 0.0, 0.009);
  EXPECT_NEAR(sum2 / n, 1.0, 0.02);
}

// Rng::turn() (the normals' cos/sin of 2 pi u, series instead of libm) against std::cos/std::sin of
// 2 pi u: over a million uniforms and the quarter-turn edges, within 2e-15 (libm's own argument
// 2 pi u is rounded to about 7e-16). And exactly the unit circle's values at the quarter turns.
TEST(Rng, TurnMatchesLibmCosAndSinOfTwoPiU) {
  Rng r(99);
  double worst = 0.0;
  std::vector<double> us = {0.0,
                            0.125,
                            0.25,
                            0.375,
                            0.5,
                            0.625,
                            0.75,
                            0.875,
                            std::nextafter(1.0, 0.0),
                            std::nextafter(0.25, 0.0),
                            std::nextafter(0.25, 1.0),
                            1e-300};
  for (int i = 0; i < 1000000; ++i) us.push_back(r.uniform());
  for (const double u : us) {
    double c = 0.0, s = 0.0;
    Rng::turn(u, c, s);
    const double a = 2.0 * kPi * u;
    worst = std::max({worst, std::fabs(c - std::cos(a)), std::fabs(s - std::sin(a))});
  }
  EXPECT_LT(worst, 2e-15);
  double c = 0.0, s = 0.0;
  Rng::turn(0.25, c, s);
  EXPECT_EQ(c, 0.0);
  EXPECT_EQ(s, 1.0);
  Rng::turn(0.5, c, s);
  EXPECT_EQ(c, -1.0);
  EXPECT_EQ(s, 0.0);
}

TEST(Motion, LspbIsContinuousAndRespectsTheAccelerationLimit) {
  Scenario s = reciprocating(4);
  const MotionProfile m = build_motion(s, 5);
  ASSERT_GT(m.pieces.size(), 4U);
  const double a_max = s.motion.accel_rad_s2;
  for (std::size_t i = 0; i < m.pieces.size(); ++i) {
    const MotionPiece& p = m.pieces[i];
    EXPECT_LE(std::fabs(p.accel_rad_s2), a_max * (1.0 + 1e-9)) << "piece " << i;
    EXPECT_GT(p.t1_s, p.t0_s);
    if (i == 0) continue;
    const MotionPiece& q = m.pieces[i - 1];
    const double dt = q.t1_s - q.t0_s;
    EXPECT_DOUBLE_EQ(q.t1_s, p.t0_s);
    EXPECT_NEAR(q.angle0_rad + q.speed0_rad_s * dt + 0.5 * q.accel_rad_s2 * dt * dt, p.angle0_rad, 1e-12);
    EXPECT_NEAR(q.speed0_rad_s + q.accel_rad_s2 * dt, p.speed0_rad_s, 1e-12);
  }
  // Sampled: the speed never steps more than a/fs, the angle more than v_max/fs.
  for (std::size_t i = 1; i < m.speed_rad_s.size(); ++i) {
    ASSERT_LE(std::fabs(m.speed_rad_s[i] - m.speed_rad_s[i - 1]), a_max / m.fs_hz * (1.0 + 1e-6)) << i;
    ASSERT_LE(std::fabs(m.angle_rad[i] - m.angle_rad[i - 1]), 3.49068 / m.fs_hz * (1.0 + 1e-6)) << i;
  }
  // At rest at both ends, back at via point 0 after every cycle.
  EXPECT_EQ(m.speed_rad_s.front(), 0.0);
  EXPECT_NEAR(m.speed_rad_s.back(), 0.0, 1e-12);
  EXPECT_NEAR(m.angle_rad.back(), 0.0, 1e-9);
  // Two plateaus per cycle (out at +v, back at -v), 0.600 s each: pi/v - 3 v/(2 a).
  ASSERT_EQ(m.plateaus.size(), 8U);
  const double expected_s = kPi / 3.49068 - 1.5 * 3.49068 / 17.45;
  for (std::size_t i = 0; i < m.plateaus.size(); ++i) {
    EXPECT_NEAR(m.plateaus[i].t_end_s - m.plateaus[i].t_start_s, expected_s, 1e-9);
    EXPECT_NEAR(m.plateaus[i].speed_rad_s, i % 2 == 0 ? 3.49068 : -3.49068, 1e-12);
    EXPECT_EQ(m.plateaus[i].cycle, i / 2);
  }
  EXPECT_NEAR(expected_s, 0.6, 1e-3);
  // Cycle starts: lead-in + jitter, then one cycle (2 * (pi/v + v/(2a))) + dwell + next jitter apart.
  ASSERT_EQ(m.cycle_start_s.size(), 4U);
  const double cycle_s = 2.0 * (kPi / 3.49068 + 3.49068 / (2.0 * 17.45));
  for (std::size_t c = 1; c < 4; ++c) {
    const double gap = m.cycle_start_s[c] - m.cycle_start_s[c - 1] - cycle_s - s.motion.dwell_s;
    EXPECT_GE(gap, 0.0);
    EXPECT_LT(gap, s.motion.start_jitter_s);
  }
  EXPECT_NEAR(m.duration_s, m.cycle_start_s.back() + cycle_s + s.motion.dwell_s, 1e-9);
  EXPECT_EQ(m.angle_rad.size(), static_cast<std::size_t>(std::llround(m.duration_s * m.fs_hz)));
}

TEST(Motion, MultiViaWithDurationsFollowsCraig) {
  // Craig, interior segment speed = delta / t_d; blend at via k lasts |v_k - v_{k-1}| / a.
  Scenario s = reciprocating(1);
  s.motion.via_points_rad = {0.0, 1.0, 3.0, 2.0};
  s.motion.segment_speeds_rad_s.clear();
  s.motion.segment_durations_s = {1.0, 1.0, 1.0};
  s.motion.accel_rad_s2 = 20.0;
  s.motion.start_jitter_s = 0.0;
  const MotionProfile m = build_motion(s, 1);
  ASSERT_EQ(m.plateaus.size(), 3U);
  // First segment: tau0 = 1 - sqrt(1 - 2/20) = 0.0513167; v0 = 1 / (1 - tau0/2) = 1.026334.
  const double tau0 = 1.0 - std::sqrt(0.9);
  EXPECT_NEAR(m.plateaus[0].speed_rad_s, 1.0 / (1.0 - tau0 / 2.0), 1e-12);
  EXPECT_NEAR(m.plateaus[1].speed_rad_s, 2.0, 1e-12);
  EXPECT_LT(m.plateaus[2].speed_rad_s, 0.0);
  // The motion ends at rest exactly at the last via point (end-segment formula).
  const MotionState end = motion_at(m, m.cycle_start_s[0] + 3.0);
  EXPECT_NEAR(end.angle_rad, 2.0, 1e-12);
  EXPECT_NEAR(end.speed_rad_s, 0.0, 1e-12);
  // The interior line of segment 1 passes through via 1 at t = 1 and via 2 at t = 2 (Craig).
  const Plateau& p1 = m.plateaus[1];
  const MotionState mid = motion_at(m, 0.5 * (p1.t_start_s + p1.t_end_s));
  const double t_mid = 0.5 * (p1.t_start_s + p1.t_end_s) - m.cycle_start_s[0];
  EXPECT_NEAR(mid.angle_rad, 1.0 + 2.0 * (t_mid - 1.0), 1e-12);
}

TEST(Motion, ConstantSpeedBlocks) {
  Scenario s = constant_speed(30.0, 2.0);
  s.gearbox = GearboxSpec{GearboxKind::kParallel, 32, 80, 0};
  s.motion.cycles = 4;
  s.sensor.fs_hz = 64500.0;
  const MotionProfile m = build_motion(s, 1);
  ASSERT_EQ(m.plateaus.size(), 4U);
  EXPECT_NEAR(m.plateaus[3].t_start_s, 1.5, 1e-12);
  EXPECT_EQ(m.angle_rad.size(), 129000U);
  EXPECT_EQ(m.cycle[64499], 1U);
  EXPECT_EQ(m.cycle[64500 + 32250], 3U);
  const double w = 2.0 * kPi * 30.0 / 2.5;
  EXPECT_NEAR(m.angle_rad[1000], w * 1000.0 / 64500.0, 1e-12);
}

TEST(Vibration, MeshPhaseFollowsTheIntegratedInputAngle) {
  Scenario s = reciprocating(3);
  s.vibration.gmf_amplitudes = {1.0};
  s.vibration.gmf_phases_rad = {0.7};
  const MotionProfile m = build_motion(s, 11);
  const Vibration v = synthesize_vibration(s, m, 11);
  ASSERT_EQ(v.accel_ms2.size(), m.angle_rad.size());
  const double zr = 28.0 * reduction_ratio(s.gearbox);  // mesh phase per output radian (948)
  const double vp = 3.49068;
  const double a = 17.45;
  std::vector<double> phase_at_sample_start;
  for (const Plateau& p : m.plateaus) {
    // Prediction from the LSPB geometry alone: the outbound plateau starts at angle v^2/(2a) (blend
    // from rest); the return plateau starts v/a after the reversal time on the line through pi,
    // i.e. at angle pi - v^2/a.
    const bool out = p.speed_rad_s > 0.0;
    const double angle0 = out ? vp * vp / (2.0 * a) : kPi - vp * vp / a;
    const double predicted = zr * angle0 + 0.7;
    const auto i0 = static_cast<std::size_t>(std::ceil((p.t_start_s + 0.05) * m.fs_hz));
    const auto i1 = static_cast<std::size_t>(std::floor((p.t_end_s - 0.05) * m.fs_hz));
    const double w = zr * p.speed_rad_s;
    const double fitted = fit_phase(v.accel_ms2, m.fs_hz, i0, i1, w, p.t_start_s);
    EXPECT_NEAR(wrap(fitted - predicted), 0.0, 1e-6) << "plateau of cycle " << p.cycle;
    if (out) {
      // What a window cut on the sample clock sees: the phase at its first sample differs per cycle.
      phase_at_sample_start.push_back(
          fit_phase(v.accel_ms2, m.fs_hz, i0, i1, w, static_cast<double>(i0) / m.fs_hz));
    }
  }
  ASSERT_EQ(phase_at_sample_start.size(), 3U);
  EXPECT_GT(std::fabs(wrap(phase_at_sample_start[1] - phase_at_sample_start[0])), 1e-3);
  EXPECT_GT(std::fabs(wrap(phase_at_sample_start[2] - phase_at_sample_start[1])), 1e-3);
  // At standstill (exponent 1) the mesh is silent.
  EXPECT_EQ(v.accel_ms2[10], 0.0);
}

TEST(Vibration, HarmonicsAtOrAboveNyquistAreOmittedAndCounted) {
  Scenario s = reciprocating(1);
  // GMF at 3.49068 rad/s = 526.67 Hz; order 24 = 12640 Hz < 12800, order 25 = 13167 Hz > 12800.
  s.vibration.gmf_amplitudes.assign(26, 0.0);
  s.vibration.gmf_amplitudes[23] = 1.0;
  s.vibration.gmf_amplitudes[24] = 1.0;
  s.vibration.gmf_amplitudes[25] = 1.0;
  const MotionProfile m = build_motion(s, 1);
  const Vibration v = synthesize_vibration(s, m, 1);
  EXPECT_EQ(v.harmonics_above_nyquist, 2U);
}

TEST(Vibration, ToothImpactsOncePerSpurRevolutionRingingAtTheResonance) {
  Scenario s = constant_speed(20.0, 1.0);  // input shaft 20 Hz
  s.sensor.fs_hz = 102400.0;
  FaultSpec f;
  f.kind = FaultKind::kSpurTooth;
  f.impulse_amplitude_ms2 = 2.0;
  f.resonance_hz = 3000.0;
  f.damping_ratio = 0.05;
  f.am_depth = 0.0;
  s.faults.push_back(f);
  s.vibration.amplitude_speed_exponent = 0.0;
  const MotionProfile m = build_motion(s, 1);
  const Vibration v = synthesize_vibration(s, m, 1);
  // Spur gear speed = f_in * Z_in / Z_spur = 20 * 28 / 23 Hz: period 23 / 560 s = 41.07 ms.
  const double period_s = 23.0 / 560.0;
  ASSERT_EQ(v.impulse_times_s.size(), 24U);  // floor(1 s / 41.07 ms)
  EXPECT_NEAR(v.impulse_times_s[0], period_s, 1e-9);
  for (std::size_t i = 1; i < v.impulse_times_s.size(); ++i) {
    EXPECT_NEAR(v.impulse_times_s[i] - v.impulse_times_s[i - 1], period_s, 1e-9);
    EXPECT_DOUBLE_EQ(v.impulse_amplitudes_ms2[i], 2.0);
  }
  // Ringing frequency from zero crossings over 4 ms after an impact: the damped natural frequency
  // f_n sqrt(1 - zeta^2) = 3000 * sqrt(0.9975) = 2996.25 Hz.
  const double fs = m.fs_hz;
  const double t_imp = v.impulse_times_s[5];
  const auto i0 = static_cast<std::size_t>(std::ceil(t_imp * fs)) + 1;
  const auto i1 = static_cast<std::size_t>((t_imp + 0.004) * fs);
  std::vector<double> crossings;
  for (std::size_t i = i0; i < i1; ++i) {
    const double x0 = v.accel_ms2[i - 1];
    const double x1 = v.accel_ms2[i];
    if ((x0 < 0.0) != (x1 < 0.0)) crossings.push_back((static_cast<double>(i - 1) + x0 / (x0 - x1)) / fs);
  }
  ASSERT_GE(crossings.size(), 20U);
  const double f_est =
      static_cast<double>(crossings.size() - 1) / (2.0 * (crossings.back() - crossings.front()));
  EXPECT_NEAR(f_est, 3000.0 * std::sqrt(1.0 - 0.0025), 0.002 * 3000.0);
  // Envelope: peak near a quarter period, about A exp(-zeta wn / (4 fd)) = 2 * 0.924.
  double peak = 0.0;
  for (std::size_t i = i0; i < i1; ++i) peak = std::max(peak, std::fabs(v.accel_ms2[i]));
  EXPECT_NEAR(peak, 2.0 * std::exp(-0.05 * 2.0 * kPi * 3000.0 / (4.0 * 2996.25)), 0.02);
  // Nothing between impacts once the ringing has died out (no mesh, no noise).
  const auto quiet = static_cast<std::size_t>((t_imp + 0.9 * period_s) * fs);
  EXPECT_LT(std::fabs(v.accel_ms2[quiet]), 1e-6);
}

TEST(Vibration, SpurDefectModulatesTheMeshAtTheSpurRate) {
  Scenario s = constant_speed(20.0, 0.5);
  s.vibration.gmf_amplitudes = {1.0};
  s.vibration.amplitude_speed_exponent = 0.0;
  FaultSpec f;
  f.impulse_amplitude_ms2 = 0.0;
  f.am_depth = 0.2;
  s.faults.push_back(f);
  const MotionProfile m = build_motion(s, 1);
  const Vibration v = synthesize_vibration(s, m, 1);
  // Around spur angle 0 (t = k * 23/560 s) the envelope is 1.2, around spur angle pi it is 0.8.
  auto envelope = [&](double t) {
    const auto c = static_cast<std::size_t>(t * m.fs_hz);
    double e = 0.0;
    for (std::size_t i = c - 30; i < c + 30; ++i) e = std::max(e, std::fabs(v.accel_ms2[i]));
    return e;  // 60 samples = 2.3 ms > one mesh period (1/560 s)
  };
  EXPECT_NEAR(envelope(2.0 * 23.0 / 560.0), 1.2, 0.01);
  EXPECT_NEAR(envelope(2.5 * 23.0 / 560.0), 0.8, 0.01);
}

TEST(Vibration, DistributedWearRaisesHarmonicsAndNoise) {
  Scenario s = constant_speed(20.0, 1.0);
  s.motion.cycles = 2;
  s.vibration.noise_rms = 0.0;
  s.vibration.gmf_amplitudes = {1.0};
  s.vibration.amplitude_speed_exponent = 0.0;
  FaultSpec f;
  f.kind = FaultKind::kDistributedWear;
  f.onset_cycle = 1;
  f.harmonic_gain = 0.5;
  s.faults.push_back(f);
  const MotionProfile m = build_motion(s, 1);
  const Vibration v = synthesize_vibration(s, m, 1);
  auto rms = [&](std::size_t a, std::size_t b) {
    double e = 0;
    for (std::size_t i = a; i < b; ++i) e += v.accel_ms2[i] * v.accel_ms2[i];
    return std::sqrt(e / static_cast<double>(b - a));
  };
  // 560 Hz over 0.5 s blocks (280 whole periods): rms = A / sqrt(2), then 1.5 A / sqrt(2).
  EXPECT_NEAR(rms(0, 12800), 1.0 / std::sqrt(2.0), 1e-3);
  EXPECT_NEAR(rms(12800, 25600), 1.5 / std::sqrt(2.0), 1e-3);

  s.vibration.gmf_amplitudes.clear();
  s.vibration.noise_rms = 0.2;
  s.faults[0].noise_gain = 1.0;
  const Vibration n = synthesize_vibration(s, m, 3);
  double e0 = 0, e1 = 0;
  for (std::size_t i = 0; i < 12800; ++i) e0 += n.accel_ms2[i] * n.accel_ms2[i];
  for (std::size_t i = 12800; i < 25600; ++i) e1 += n.accel_ms2[i] * n.accel_ms2[i];
  // The rms estimate over 12800 samples has a relative sd of 1/sqrt(2 * 12800) = 0.6 %: 4 sd = 2.5 %.
  EXPECT_NEAR(std::sqrt(e0 / 12800), 0.2, 0.2 * 0.025);
  EXPECT_NEAR(std::sqrt(e1 / 12800), 0.4, 0.4 * 0.025);
}

TEST(Sensor, QuantisesToTheBitDepthAndClipsAtRange) {
  SensorSpec pcm16;
  pcm16.range_ms2 = 1.0;
  pcm16.format = formats::WavSampleFormat::kPcm16;
  EXPECT_DOUBLE_EQ(sensor_scale(pcm16), 1.0 / 32768.0);
  std::uint64_t clipped = 99;
  const std::vector<float> c = quantize(
      pcm16, {0.5, -0.25, 1.0 / 65536.0 * 0.9, 3.0 / 32768.0 + 0.49 / 32768.0, 1.0, 1.7, -1.0, -2.0, 0.99999},
      &clipped);
  ASSERT_EQ(c.size(), 9U);
  EXPECT_EQ(c[0], 16384.0F);  // 0.5 / 2^-15
  EXPECT_EQ(c[1], -8192.0F);
  EXPECT_EQ(c[2], 0.0F);      // 0.45 lsb rounds to 0
  EXPECT_EQ(c[3], 3.0F);      // 3.49 lsb rounds to 3
  EXPECT_EQ(c[4], 32767.0F);  // +range saturates to the top code
  EXPECT_EQ(c[5], 32767.0F);  // clipped
  EXPECT_EQ(c[6], -32768.0F);
  EXPECT_EQ(c[7], -32768.0F);  // clipped
  EXPECT_EQ(c[8], 32767.0F);   // 0.99999 * 32768 = 32767.67 -> 32768 -> saturates
  EXPECT_EQ(clipped, 2U);

  SensorSpec pcm24;
  pcm24.range_ms2 = 50.0;
  pcm24.format = formats::WavSampleFormat::kPcm24;
  const double lsb = 50.0 / 8388608.0;
  EXPECT_DOUBLE_EQ(sensor_scale(pcm24), lsb);
  const std::vector<float> d = quantize(pcm24, {1.2345, -60.0});
  EXPECT_EQ(d[0], static_cast<float>(std::round(1.2345 / lsb)));
  EXPECT_LE(std::fabs(d[0] * lsb - 1.2345), lsb / 2);
  EXPECT_EQ(d[1], -8388608.0F);

  SensorSpec f32;
  f32.range_ms2 = 10.0;
  f32.format = formats::WavSampleFormat::kFloat32;
  EXPECT_DOUBLE_EQ(sensor_scale(f32), 1.0);
  const std::vector<float> e = quantize(f32, {1.2345, 11.0, -12.0}, &clipped);
  EXPECT_EQ(e[0], 1.2345F);
  EXPECT_EQ(e[1], 10.0F);
  EXPECT_EQ(e[2], -10.0F);
  EXPECT_EQ(clipped, 2U);
}

TEST(Can, SpeedFramesDecodeBackToTheProfileWithinQuantisation) {
  Scenario s = reciprocating(2);
  s.can.other_frames_per_s = 30;
  const MotionProfile m = build_motion(s, 9);
  const std::vector<SimCanFrame> frames = generate_can(s, m, 9);
  const std::int64_t start_ns = seconds_to_ns(s.start_time_s);
  std::size_t speed = 0;
  std::size_t other = 0;
  double prev_true = -1.0;
  std::int64_t prev_ns = 0;
  double max_speed = 0.0;
  for (const SimCanFrame& f : frames) {
    ASSERT_GE(f.frame.t_ns, prev_ns) << "log not in time order";
    prev_ns = f.frame.t_ns;
    config::DecodedSpeed d;
    const config::DecodeResult r = config::decode_speed(f.frame, s.can.speed_frame, d);
    if (!f.is_speed) {
      ++other;
      EXPECT_EQ(r, config::DecodeResult::kOtherId);
      continue;
    }
    ASSERT_EQ(r, config::DecodeResult::kOk);
    const MotionState st = motion_at(m, f.true_time_s);
    EXPECT_NEAR(d.speed_rad_s, st.speed_rad_s, 0.5e-4 + 1e-12);  // speed lsb 1e-4 rad/s
    ASSERT_TRUE(d.has_angle);
    EXPECT_NEAR(d.angle_rad, st.angle_rad, 0.5e-5 + 1e-12);  // angle lsb 1e-5 rad
    max_speed = std::max(max_speed, std::fabs(d.speed_rad_s));
    // Free-running controller clock: true times are offset + k * period.
    EXPECT_NEAR(f.true_time_s, s.can.clock_offset_s + static_cast<double>(speed) * s.can.period_s, 1e-9);
    if (prev_true >= 0.0) {
      EXPECT_NEAR(f.true_time_s - prev_true, s.can.period_s, 1e-12);
    }
    prev_true = f.true_time_s;
    // Log time = true time + delay + [0, jitter), rounded to the log's microseconds.
    const double lag = ns_to_seconds(f.frame.t_ns - start_ns) - f.true_time_s - s.can.delay_s;
    EXPECT_GE(lag, -0.5e-6);
    EXPECT_LE(lag, s.can.jitter_s + 0.5e-6);
    EXPECT_EQ(f.frame.t_ns % 1000, 0);
    ++speed;
  }
  EXPECT_EQ(speed,
            static_cast<std::size_t>(std::floor((m.duration_s - s.can.clock_offset_s) / s.can.period_s)) + 1);
  EXPECT_EQ(other, static_cast<std::size_t>(std::floor(30.0 * m.duration_s)));
  EXPECT_NEAR(max_speed, 3.49068, 0.5e-4);
}

TEST(Can, SpeedTimestampsIncreaseWithThePeriod) {
  Scenario s = reciprocating(1);
  s.can.period_s = 0.01;
  s.can.jitter_s = 0.002;
  s.can.clock_drift_ppm = 100.0;
  const MotionProfile m = build_motion(s, 4);
  const std::vector<SimCanFrame> frames = generate_can(s, m, 4);
  ASSERT_GT(frames.size(), 100U);
  const double period = 0.01 * (1.0 + 100e-6);
  for (std::size_t i = 1; i < frames.size(); ++i) {
    const double dt = ns_to_seconds(frames[i].frame.t_ns - frames[i - 1].frame.t_ns);
    EXPECT_GT(dt, period - 0.002 - 1e-6);
    EXPECT_LT(dt, period + 0.002 + 1e-6);
  }
  // Drift accumulates: frame k is sampled at offset + k * period * (1 + drift).
  EXPECT_NEAR(frames.back().true_time_s,
              s.can.clock_offset_s + static_cast<double>(frames.size() - 1) * period, 1e-9);
}

}  // namespace
}  // namespace ptda::sim

namespace ptda::sim {
namespace {

TEST(Vibration, ShaftOrderLinesFollowTheInputAngle) {
  // Input shaft 20 Hz (z_in 28 by default: GMF 560 Hz); shaft orders 5 and 15 at 0.6 and 0.2 m/s^2.
  Scenario s = constant_speed(20.0, 1.0);
  s.vibration.noise_rms = 0.0;
  s.vibration.amplitude_speed_exponent = 0.0;
  s.vibration.shaft_orders = {15, 5};
  s.vibration.shaft_order_amplitudes = {0.2, 0.6};
  const MotionProfile m = build_motion(s, 1);
  const Vibration v = synthesize_vibration(s, m, 1);
  const double fs = m.fs_hz;
  // Least-squares amplitude of sin/cos pairs at 100 Hz and 300 Hz over the whole second (whole periods).
  auto amplitude = [&](double hz) {
    double a = 0, b = 0;
    for (std::size_t i = 0; i < v.accel_ms2.size(); ++i) {
      const double t = static_cast<double>(i) / fs;
      a += v.accel_ms2[i] * std::sin(2.0 * std::numbers::pi * hz * t);
      b += v.accel_ms2[i] * std::cos(2.0 * std::numbers::pi * hz * t);
    }
    const double n = static_cast<double>(v.accel_ms2.size());
    return 2.0 * std::sqrt(a * a + b * b) / n;
  };
  EXPECT_NEAR(amplitude(100.0), 0.6, 1e-3);
  EXPECT_NEAR(amplitude(300.0), 0.2, 1e-3);
  EXPECT_LT(amplitude(200.0), 1e-3);  // order 10 is not listed
  // Same phase law as the mesh: sin(order * theta_in), theta_in = 2 pi 20 t from 0.
  EXPECT_NEAR(fit_phase(v.accel_ms2, fs, 0, v.accel_ms2.size(), 2.0 * std::numbers::pi * 100.0, 0.0), 0.0,
              0.01);
}

// Every sample of the mesh against the closed form, over a reciprocating job (blends, rests, reversals:
// the per-sample phase step goes from 0 to its largest and changes sign). The synthesis turns the
// previous sample's cos/sin by the step (PhaseRotor, sim/src/vibration.cpp) instead of calling sin/cos;
// the difference must stay at rounding level (the noise-free accelerations are about 1-3 m/s^2).
TEST(Vibration, RotatedPhasesEqualTheClosedFormAtEverySample) {
  Scenario s = reciprocating(4);
  s.vibration.amplitude_speed_exponent = 0.0;  // the mesh sounds at rest too: every step size is tried
  s.vibration.gmf_amplitudes = {1.0, 0.0, 0.5, 0.25};
  s.vibration.gmf_phases_rad = {0.7, 0.0, -1.1, 2.5};
  s.vibration.dmf_amplitudes = {0.3, 0.2};
  s.vibration.shaft_orders = {2, 6};
  s.vibration.shaft_order_amplitudes = {0.4, 0.1};
  const MotionProfile m = build_motion(s, 5);
  const Vibration v = synthesize_vibration(s, m, 5);
  ASSERT_EQ(v.accel_ms2.size(), m.angle_rad.size());
  const double ratio = reduction_ratio(s.gearbox);
  const double z_in = s.gearbox.z_in;
  const double z_pin = s.gearbox.z_pin;
  double worst = 0.0;
  double largest_step = 0.0;
  for (std::size_t i = 0; i < m.angle_rad.size(); ++i) {
    const double theta_out = m.angle_rad[i];
    const double theta_in = ratio * theta_out;
    double x = 0.0;
    for (std::size_t k = 0; k < s.vibration.gmf_amplitudes.size(); ++k) {
      x += s.vibration.gmf_amplitudes[k] *
           std::sin(static_cast<double>(k + 1) * z_in * theta_in + s.vibration.gmf_phases_rad[k]);
    }
    for (std::size_t k = 0; k < s.vibration.dmf_amplitudes.size(); ++k) {
      x += s.vibration.dmf_amplitudes[k] * std::sin(static_cast<double>(k + 1) * z_pin * theta_out);
    }
    for (std::size_t r = 0; r < s.vibration.shaft_orders.size(); ++r) {
      x += s.vibration.shaft_order_amplitudes[r] * std::sin(s.vibration.shaft_orders[r] * theta_in);
    }
    worst = std::max(worst, std::fabs(v.accel_ms2[i] - x));
    if (i > 0)
      largest_step = std::max(largest_step, std::fabs(z_in * ratio * (theta_out - m.angle_rad[i - 1])));
  }
  EXPECT_LT(worst, 1e-9);
  // The job's fastest GMF step is well inside the rotor's series range (0.8 rad), so the series is what
  // was compared, not the exact fallback.
  EXPECT_GT(largest_step, 0.05);
  EXPECT_LT(largest_step, 0.8);
}

}  // namespace
}  // namespace ptda::sim
