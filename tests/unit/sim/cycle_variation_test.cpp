// Cycle-to-cycle variation of the mesh amplitudes and the noise level ([vibration]
// cycle_amplitude_jitter_rel / cycle_noise_jitter_rel): measured on the plateaus it has the configured
// spread, it is recorded in truth.toml, it leaves the other random streams alone, and 0 changes nothing.
#include <gtest/gtest.h>
#include <toml++/toml.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <numbers>
#include <string>
#include <vector>

#include "ptda/common/error.hpp"
#include "ptda/sim/simulator.hpp"

namespace ptda::sim {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kSpeed = 3.49068;  // plateau speed = reference speed: speed factor 1 on the plateaus

// Joint-rotation motion with the paper's Table 1 amplitude pattern (6 non-zero entries out of 12).
Scenario job(std::uint32_t cycles) {
  Scenario s;
  s.source = "test";
  s.motion.via_points_rad = {0.0, kPi, 0.0};
  s.motion.segment_speeds_rad_s = {kSpeed, kSpeed};
  s.motion.accel_rad_s2 = 17.45;
  s.motion.cycles = cycles;
  s.motion.dwell_s = 0.1;
  s.motion.start_jitter_s = 0.05;
  s.motion.lead_in_s = 0.1;
  s.vibration.gmf_amplitudes = {0.43, 0.0, 0.0, 0.48, 1.40, 0.0, 1.10, 1.60, 0.0, 0.0, 0.0, 0.94};
  s.vibration.gmf_phases_rad = {0.3, 0.0, 0.0, 1.1, 2.0, 0.0, 0.7, 2.9, 0.0, 0.0, 0.0, 1.6};
  s.vibration.reference_speed_rad_s = kSpeed;
  s.vibration.noise_rms = 0.0;
  return s;
}

// Solves the normal equations a x = b (n x n, symmetric positive definite) by Gaussian elimination.
std::vector<double> solve(std::vector<std::vector<double>> a, std::vector<double> b) {
  const std::size_t n = b.size();
  for (std::size_t i = 0; i < n; ++i) {
    std::size_t p = i;
    for (std::size_t r = i + 1; r < n; ++r) {
      if (std::fabs(a[r][i]) > std::fabs(a[p][i])) p = r;
    }
    std::swap(a[i], a[p]);
    std::swap(b[i], b[p]);
    for (std::size_t r = i + 1; r < n; ++r) {
      const double f = a[r][i] / a[i][i];
      for (std::size_t c = i; c < n; ++c) a[r][c] -= f * a[i][c];
      b[r] -= f * b[i];
    }
  }
  std::vector<double> x(n);
  for (std::size_t i = n; i-- > 0;) {
    double v = b[i];
    for (std::size_t c = i + 1; c < n; ++c) v -= a[i][c] * x[c];
    x[i] = v / a[i][i];
  }
  return x;
}

// Amplitude of each non-zero GMF entry on one plateau: joint least-squares fit of sin/cos pairs at
// k * Z_in * R * |v| (the mesh is exactly these tones at constant speed).
std::vector<double> plateau_amplitudes(const Scenario& s, const MotionProfile& m, const Vibration& v,
                                       const Plateau& p) {
  const double ratio = reduction_ratio(s.gearbox);
  std::vector<double> w;  // rad/s per fitted entry
  for (std::size_t k = 0; k < s.vibration.gmf_amplitudes.size(); ++k) {
    if (s.vibration.gmf_amplitudes[k] > 0.0) {
      w.push_back(static_cast<double>(k + 1) * s.gearbox.z_in * ratio * std::fabs(p.speed_rad_s));
    }
  }
  const std::size_t nb = 2 * w.size();
  std::vector<std::vector<double>> a(nb, std::vector<double>(nb, 0.0));
  std::vector<double> b(nb, 0.0);
  std::vector<double> basis(nb);
  const auto i0 = static_cast<std::size_t>(std::ceil(p.t_start_s * m.fs_hz)) + 1;
  const auto i1 = static_cast<std::size_t>(std::floor(p.t_end_s * m.fs_hz));
  for (std::size_t i = i0; i < i1; ++i) {
    const double t = static_cast<double>(i) / m.fs_hz - p.t_start_s;
    for (std::size_t j = 0; j < w.size(); ++j) {
      basis[2 * j] = std::sin(w[j] * t);
      basis[2 * j + 1] = std::cos(w[j] * t);
    }
    for (std::size_t r = 0; r < nb; ++r) {
      b[r] += basis[r] * v.accel_ms2[i];
      for (std::size_t c = 0; c < nb; ++c) a[r][c] += basis[r] * basis[c];
    }
  }
  const std::vector<double> x = solve(a, b);
  std::vector<double> amp(w.size());
  for (std::size_t j = 0; j < w.size(); ++j) amp[j] = std::hypot(x[2 * j], x[2 * j + 1]);
  return amp;
}

std::vector<std::size_t> nonzero_entries(const Scenario& s) {
  std::vector<std::size_t> out;
  for (std::size_t k = 0; k < s.vibration.gmf_amplitudes.size(); ++k) {
    if (s.vibration.gmf_amplitudes[k] > 0.0) out.push_back(k);
  }
  return out;
}

TEST(CycleVariation, PlateauAmplitudesVaryWithTheConfiguredSpread) {
  constexpr std::uint32_t kCycles = 40;
  constexpr double kRel = 0.05;
  Scenario s = job(kCycles);
  s.vibration.cycle_amplitude_jitter_rel = kRel;
  const MotionProfile m = build_motion(s, 11);
  const Vibration v = synthesize_vibration(s, m, 11);
  const std::vector<std::size_t> entries = nonzero_entries(s);
  ASSERT_EQ(v.cycle_variation.amplitude_factors.size(), kCycles);
  ASSERT_EQ(v.cycle_variation.amplitude_factors[0].size(), s.vibration.gmf_amplitudes.size());
  EXPECT_TRUE(v.cycle_variation.noise_factors.empty());

  double sum = 0.0;
  double sum2 = 0.0;
  std::size_t n = 0;
  ASSERT_EQ(m.plateaus.size(), 2U * kCycles);
  for (const Plateau& p : m.plateaus) {
    const std::vector<double> amp = plateau_amplitudes(s, m, v, p);
    for (std::size_t j = 0; j < entries.size(); ++j) {
      const double log_factor = std::log(amp[j] / s.vibration.gmf_amplitudes[entries[j]]);
      // The fitted amplitude is the nominal one times the recorded factor of this cycle and entry
      // (noise-free: only the fit's rounding, far below 1e-6).
      EXPECT_NEAR(log_factor, std::log(v.cycle_variation.amplitude_factors[p.cycle][entries[j]]), 1e-6)
          << "cycle " << p.cycle << " entry " << entries[j];
      if (p.speed_rad_s > 0.0) {  // one value per cycle and entry (both plateaus share the factor)
        sum += log_factor;
        sum2 += log_factor * log_factor;
        ++n;
      }
    }
  }
  ASSERT_EQ(n, kCycles * entries.size());  // 240 independent draws
  const double nd = static_cast<double>(n);
  const double mean = sum / nd;
  const double sd = std::sqrt((sum2 - nd * mean * mean) / (nd - 1.0));
  // log factors ~ N(0, kRel^2): the mean is within 4 standard errors (4 kRel / sqrt(240) = 0.013) of 0
  // and the sample sd within 4 of its standard errors (kRel / sqrt(2 * 239) = 4.6 % of kRel) of kRel.
  EXPECT_NEAR(mean, 0.0, 4.0 * kRel / std::sqrt(nd));
  EXPECT_NEAR(sd, kRel, 4.0 * kRel / std::sqrt(2.0 * (nd - 1.0)));
  std::printf("log amplitude factors: mean %.5f sd %.5f (configured %.3f, n %zu)\n", mean, sd, kRel, n);
}

TEST(CycleVariation, NoiseLevelVariesWithTheConfiguredSpread) {
  constexpr std::uint32_t kCycles = 60;
  constexpr double kRel = 0.1;
  Scenario s = job(kCycles);
  s.vibration.gmf_amplitudes.clear();
  s.vibration.gmf_phases_rad.clear();
  s.vibration.noise_rms = 1.0;
  s.vibration.cycle_noise_jitter_rel = kRel;
  const MotionProfile m = build_motion(s, 12);
  const Vibration v = synthesize_vibration(s, m, 12);
  ASSERT_EQ(v.cycle_variation.noise_factors.size(), kCycles);
  EXPECT_TRUE(v.cycle_variation.amplitude_factors.empty());
  std::vector<double> power(kCycles, 0.0);
  std::vector<double> count(kCycles, 0.0);
  for (std::size_t i = 0; i < v.accel_ms2.size(); ++i) {
    power[m.cycle[i]] += v.accel_ms2[i] * v.accel_ms2[i];
    count[m.cycle[i]] += 1.0;
  }
  double sum = 0.0;
  double sum2 = 0.0;
  for (std::uint32_t c = 0; c < kCycles; ++c) {
    ASSERT_GT(count[c], 30000.0);
    const double log_rms = 0.5 * std::log(power[c] / count[c]);
    // Each cycle's rms over > 30000 samples estimates noise_rms * factor with relative standard error
    // 1/sqrt(2 * 30000) = 0.4 %: within 5 of those of the recorded factor.
    EXPECT_NEAR(log_rms, std::log(v.cycle_variation.noise_factors[c]), 5.0 / std::sqrt(2.0 * count[c])) << c;
    sum += log_rms;
    sum2 += log_rms * log_rms;
  }
  const double nd = kCycles;
  const double mean = sum / nd;
  const double sd = std::sqrt((sum2 - nd * mean * mean) / (nd - 1.0));
  // 60 draws: sample sd within 4 standard errors (kRel / sqrt(2 * 59) = 9.2 % of kRel) of kRel; the
  // measurement error (0.4 %) adds < 0.1 % of kRel in quadrature.
  EXPECT_NEAR(sd, kRel, 4.0 * kRel / std::sqrt(2.0 * (nd - 1.0)));
  EXPECT_NEAR(mean, 0.0, 4.0 * kRel / std::sqrt(nd));
}

TEST(CycleVariation, ZeroGivesIdenticalCyclesAndNoFactors) {
  Scenario s = job(6);
  const MotionProfile m = build_motion(s, 13);
  const Vibration v = synthesize_vibration(s, m, 13);
  EXPECT_TRUE(v.cycle_variation.amplitude_factors.empty());
  EXPECT_TRUE(v.cycle_variation.noise_factors.empty());
  const std::vector<double> first = plateau_amplitudes(s, m, v, m.plateaus.front());
  const std::vector<std::size_t> entries = nonzero_entries(s);
  for (const Plateau& p : m.plateaus) {
    const std::vector<double> amp = plateau_amplitudes(s, m, v, p);
    for (std::size_t j = 0; j < amp.size(); ++j) {
      EXPECT_NEAR(amp[j], first[j], 1e-9) << "cycle " << p.cycle;
      EXPECT_NEAR(amp[j], s.vibration.gmf_amplitudes[entries[j]], 1e-9);
    }
  }
}

TEST(CycleVariation, OtherRandomStreamsAreUnchanged) {
  Scenario off = job(4);
  off.vibration.noise_rms = 0.5;
  Scenario on = off;
  on.vibration.cycle_amplitude_jitter_rel = 0.05;
  on.vibration.cycle_noise_jitter_rel = 0.0;
  Scenario clean_off = off;
  clean_off.vibration.noise_rms = 0.0;
  Scenario clean_on = on;
  clean_on.vibration.noise_rms = 0.0;
  const MotionProfile m = build_motion(off, 21);
  const MotionProfile m_on = build_motion(on, 21);
  ASSERT_EQ(m.cycle_start_s, m_on.cycle_start_s);  // the start jitter stream is untouched
  const Vibration x_off = synthesize_vibration(off, m, 21);
  const Vibration x_on = synthesize_vibration(on, m, 21);
  const Vibration d_off = synthesize_vibration(clean_off, m, 21);
  const Vibration d_on = synthesize_vibration(clean_on, m, 21);
  // Switching the amplitude variation on changes the mesh only: the noise samples are the same draws.
  double max_dev = 0.0;
  double max_mesh_change = 0.0;
  for (std::size_t i = 0; i < x_off.accel_ms2.size(); ++i) {
    const double noise_off = x_off.accel_ms2[i] - d_off.accel_ms2[i];
    const double noise_on = x_on.accel_ms2[i] - d_on.accel_ms2[i];
    max_dev = std::max(max_dev, std::fabs(noise_on - noise_off));
    max_mesh_change = std::max(max_mesh_change, std::fabs(d_on.accel_ms2[i] - d_off.accel_ms2[i]));
  }
  EXPECT_LT(max_dev, 1e-12);
  EXPECT_GT(max_mesh_change, 0.01);  // and the mesh did change
  // The amplitude factors do not depend on whether the noise variation is on (own streams).
  VibrationSpec both = on.vibration;
  both.cycle_noise_jitter_rel = 0.05;
  const CycleVariation a = draw_cycle_variation(on.vibration, 4, 21);
  const CycleVariation b = draw_cycle_variation(both, 4, 21);
  EXPECT_EQ(a.amplitude_factors, b.amplitude_factors);
  EXPECT_EQ(b.noise_factors.size(), 4U);
  EXPECT_NE(draw_cycle_variation(on.vibration, 4, 22).amplitude_factors, a.amplitude_factors);
}

std::string scenario_text(const std::string& vibration_extra) {
  return "name = \"t\"\n[motion]\nvia_points_rad = [0.0, 3.14159265, 0.0]\nsegment_speeds_rad_s = [3.49068, "
         "3.49068]\naccel_rad_s2 = 17.45\ncycles = 3\n[vibration]\ngmf_amplitudes = [0.5, 1.0]\n"
         "reference_speed_rad_s = 3.49068\nnoise_rms = 0.2\n" +
         vibration_extra;
}

TEST(CycleVariation, ParsedKeysExplicitZeroIsTheDefault) {
  const Scenario absent = parse_scenario(scenario_text(""), "a.toml");
  const Scenario zero = parse_scenario(
      scenario_text("cycle_amplitude_jitter_rel = 0.0\ncycle_noise_jitter_rel = 0\n"), "z.toml");
  EXPECT_EQ(absent.vibration.cycle_amplitude_jitter_rel, 0.0);
  EXPECT_EQ(absent.vibration.cycle_noise_jitter_rel, 0.0);
  const MotionProfile m = build_motion(absent, 3);
  EXPECT_EQ(synthesize_vibration(absent, m, 3).accel_ms2, synthesize_vibration(zero, m, 3).accel_ms2);
  const Scenario set = parse_scenario(
      scenario_text("cycle_amplitude_jitter_rel = 0.03\ncycle_noise_jitter_rel = 0.04\n"), "s.toml");
  EXPECT_DOUBLE_EQ(set.vibration.cycle_amplitude_jitter_rel, 0.03);
  EXPECT_DOUBLE_EQ(set.vibration.cycle_noise_jitter_rel, 0.04);
  EXPECT_NE(synthesize_vibration(set, m, 3).accel_ms2, synthesize_vibration(absent, m, 3).accel_ms2);
}

TEST(CycleVariation, OutOfRangeIsAnErrorWithLocation) {
  for (const std::string key : {"cycle_amplitude_jitter_rel", "cycle_noise_jitter_rel"}) {
    for (const std::string value : {"-0.01", "1.5"}) {
      try {
        (void)parse_scenario(scenario_text(key + " = " + value + "\n"), "bad.toml");
        ADD_FAILURE() << key << " = " << value << " was accepted";
      } catch (const Error& e) {
        // The key is on line 11 of scenario_text; the message names file:line:column and the key.
        const std::string what = e.what();
        EXPECT_NE(what.find("bad.toml:11:"), std::string::npos) << what;
        EXPECT_NE(what.find("vibration." + key + ": must be in [0, 1]"), std::string::npos) << what;
      }
    }
  }
}

std::filesystem::path temp_dir(const std::string& name) {
  const char* env = std::getenv("PTDA_TEST_TMP");
  const std::filesystem::path base =
      env != nullptr ? std::filesystem::path(env) : std::filesystem::temp_directory_path();
  const std::filesystem::path dir = base / ("sim_cycle_variation_test_" + name);
  std::filesystem::remove_all(dir);
  return dir;
}

TEST(CycleVariation, TruthRecordsTheDrawnFactors) {
  Scenario s = job(3);
  s.vibration.noise_rms = 0.2;
  s.vibration.cycle_amplitude_jitter_rel = 0.03;
  s.vibration.cycle_noise_jitter_rel = 0.04;
  const auto dir = temp_dir("truth");
  (void)simulate_to_directory(s, dir, 31);
  const toml::table t = toml::parse_file((dir / "truth.toml").string());
  const CycleVariation cv = draw_cycle_variation(s.vibration, 3, 31);
  EXPECT_DOUBLE_EQ(t["vibration"]["cycle_amplitude_jitter_rel"].value_or(0.0), 0.03);
  EXPECT_DOUBLE_EQ(t["vibration"]["cycle_noise_jitter_rel"].value_or(0.0), 0.04);
  const toml::array* rows = t["vibration"]["cycle_amplitude_factors"].as_array();
  ASSERT_NE(rows, nullptr);
  ASSERT_EQ(rows->size(), 3U);
  for (std::size_t c = 0; c < 3; ++c) {
    const toml::array* row = rows->get(c)->as_array();
    ASSERT_NE(row, nullptr);
    ASSERT_EQ(row->size(), s.vibration.gmf_amplitudes.size());
    for (std::size_t k = 0; k < row->size(); ++k) {
      EXPECT_DOUBLE_EQ(row->get(k)->value_or(0.0), cv.amplitude_factors[c][k]) << c << " " << k;
    }
  }
  const toml::array* noise = t["vibration"]["cycle_noise_factors"].as_array();
  ASSERT_NE(noise, nullptr);
  ASSERT_EQ(noise->size(), 3U);
  for (std::size_t c = 0; c < 3; ++c) EXPECT_DOUBLE_EQ(noise->get(c)->value_or(0.0), cv.noise_factors[c]);

  // Off: truth.toml has none of the keys (it is what it was before the feature).
  Scenario off = job(3);
  const auto dir_off = temp_dir("truth_off");
  (void)simulate_to_directory(off, dir_off, 31);
  const toml::table t_off = toml::parse_file((dir_off / "truth.toml").string());
  for (const char* k : {"cycle_amplitude_jitter_rel", "cycle_amplitude_factors", "cycle_noise_jitter_rel",
                        "cycle_noise_factors"}) {
    EXPECT_FALSE(t_off["vibration"][k]) << k;
  }
  std::filesystem::remove_all(dir);
  std::filesystem::remove_all(dir_off);
}

}  // namespace
}  // namespace ptda::sim
