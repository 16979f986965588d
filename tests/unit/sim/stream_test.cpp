// Streaming simulation (sim/include/ptda/sim/stream.hpp): block by block it writes the same bytes as the
// whole-signal functions, for every effect kind, the drift model and the faults, at block sizes that cut
// through knocks, ringing tails and cycles.
#include "ptda/sim/stream.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "ptda/common/error.hpp"
#include "ptda/formats/candump.hpp"
#include "ptda/formats/wav.hpp"
#include "ptda/sim/simulator.hpp"

namespace ptda::sim {
namespace {

std::filesystem::path temp_dir(const std::string& name) {
  const char* env = std::getenv("PTDA_TEST_TMP");
  const std::filesystem::path base =
      env != nullptr ? std::filesystem::path(env) : std::filesystem::temp_directory_path();
  const std::filesystem::path dir = base / ("sim_stream_test_" + name);
  std::filesystem::remove_all(dir);
  return dir;
}

std::filesystem::path source_path(const std::string& rel) {
  return std::filesystem::path(PTDA_SOURCE_DIR) / rel;
}

std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::uint64_t fnv1a(const std::string& bytes) {
  std::uint64_t h = 0xcbf29ce484222325ULL;
  for (const char c : bytes) {
    h ^= static_cast<unsigned char>(c);
    h *= 0x100000001b3ULL;
  }
  return h;
}

// The scenarios: every effect kind (several knocks' ringing tails over a second long, random knocks, two
// tooth faults, wear), the drift model with pauses, and the effects example of config/scenarios.
struct Case {
  const char* file;
  const char* source;  // Scenario::source as `ptda simulate --scenario` sets it (pinned hashes below)
};
constexpr Case kCases[] = {
    {"tests/data/sim/every_effect.toml", "every_effect.toml"},
    {"tests/data/sim/drift_pauses.toml", "drift_pauses.toml"},
    {"config/scenarios/effects_all_kinds.toml", "effects_all_kinds.toml"},
};

Scenario load_case(const Case& c) {
  Scenario s = load_scenario(source_path(c.file));
  s.source = c.source;
  return s;
}

/// What simulate_to_directory wrote before it streamed: every file from the whole-signal functions.
struct WholeFiles {
  std::string wav;
  std::string can;
  std::string truth;
};

WholeFiles whole_signal_files(const Scenario& s, const std::filesystem::path& dir) {
  std::filesystem::create_directories(dir);
  const SimulatedSignals sig = simulate_signals(s, s.seed);
  formats::write_wav(dir / "whole.wav", static_cast<std::uint32_t>(s.sensor.fs_hz), s.sensor.format,
                     {sig.codes});
  std::vector<formats::CandumpRecord> records;
  std::uint64_t speed = 0;
  for (const SimCanFrame& f : sig.can) {
    records.push_back(formats::CandumpRecord{f.frame, s.can.iface, 0});
    speed += f.is_speed ? 1U : 0U;
  }
  formats::write_candump(dir / "whole.log", records);
  SimulationSummary sum;
  sum.seed = s.seed;
  sum.samples = sig.motion.angle_rad.size();
  sum.speed_frames = speed;
  sum.clipped_samples = sig.clipped_samples + sig.vibration.effect_clipped_samples;
  WholeFiles out;
  out.wav = slurp(dir / "whole.wav");
  out.can = slurp(dir / "whole.log");
  out.truth =
      "# Ground truth written by the ptda simulator: what was simulated (faults, severities per cycle,\n"
      "# plateaus, seeds, parameters). No analysis command reads this file; tests and reports may.\n" +
      truth_toml_whole(s, sig.motion, sig.vibration, sig.can.size() - speed, sum) + "\n";
  return out;
}

TEST(SimulateStreaming, WritesTheWholeSignalBytesAtAnyBlockSize) {
  for (const Case& c : kCases) {
    SCOPED_TRACE(c.file);
    const Scenario s = load_case(c);
    const auto dir = temp_dir("blocks");
    const WholeFiles whole = whole_signal_files(s, dir / "whole");
    // 997 samples (39 ms at 25.6 kHz: cuts every knock's ringing and every cycle), 1 sample, and the
    // default; CAN windows of 7 frames (many passes over the unrelated frames) and the default.
    for (const SimulateOptions opt :
         {SimulateOptions{997, 7}, SimulateOptions{1, 65536}, SimulateOptions{65536, 65536}}) {
      if (opt.block_samples == 1 && std::string(c.file).find("every_effect") == std::string::npos) continue;
      SCOPED_TRACE("block " + std::to_string(opt.block_samples));
      const auto out = dir / ("b" + std::to_string(opt.block_samples));
      simulate_to_directory(s, out, std::nullopt, opt);
      EXPECT_TRUE(slurp(out / "vibration.wav") == whole.wav);
      EXPECT_TRUE(slurp(out / "can.log") == whole.can);
      EXPECT_EQ(slurp(out / "truth.toml"), whole.truth);
    }
    std::filesystem::remove_all(dir);
  }
}

TEST(SimulateStreaming, MatchesTheWholeSignalImplementationItReplaced) {
#if !defined(__x86_64__)
  // The pins are x86-64 bytes: libm's sin/cos/exp and the compiler's FMA contraction differ on other
  // targets in the last bit, which changes float samples. The streamed-against-whole tests above hold
  // on every target; this one pins the history on the reference target only.
  GTEST_SKIP() << "hashes pinned from the x86-64 build of b614402";
#endif
  // FNV-1a 64 of the files `ptda simulate --scenario <file>` wrote at commit b614402 (the whole-signal
  // implementation, before the streaming one), run in the scenario's directory so that truth.toml's
  // `source` is the bare file name. A deliberate change of the synthesis changes these: re-pin them then.
  // Session 7 re-pinned the truth.toml of cases 0 and 2 only: their noise_color effect now lists its
  // `poles` parameter (default 1, the same noise); the WAV and CAN bytes are still those of b614402.
  // Session 12 re-pinned case 0's truth.toml only: its electrical_interference lists `odd_only` (default
  // 0, the same lines). Session 14 re-pinned case 0's truth.toml only: its other_axis lists
  // `own_frequency_hz`, `duty` and `harmonic2` (defaults 0, 1, 0: the same lagged mesh). Session 27
  // re-pinned case 0's truth.toml only: its adc_clipping lists `sim_level_ms2` (default 0: the same clamp).
  // Session 31 re-pinned the truth.toml of cases 0 and 1 only: the normals' cos/sin come from
  // Rng::turn() instead of libm, and one printed cycle-variation factor of each (17 digits) moved by one
  // unit in the last place; the WAV and CAN bytes of all three are unchanged.
  struct Pin {
    std::uint64_t wav, can, truth;
  };
  constexpr Pin kPins[] = {
      {0x21d34dd1673a2adfULL, 0x800996445d5dfd5bULL, 0xcf90f6bf9c1b4b2aULL},
      {0x8ebce2dce7d2389cULL, 0xc604fb348f9cc8f9ULL, 0x902ac1eed4d43d22ULL},
      {0x70de9e2f4e1459c1ULL, 0x9fb1248ec3780492ULL, 0xd819ba862cf057b4ULL},
  };
  for (std::size_t k = 0; k < std::size(kCases); ++k) {
    SCOPED_TRACE(kCases[k].file);
    const auto dir = temp_dir("pinned");
    simulate_to_directory(load_case(kCases[k]), dir, std::nullopt, SimulateOptions{4093, 1000});
    EXPECT_EQ(fnv1a(slurp(dir / "vibration.wav")), kPins[k].wav);
    EXPECT_EQ(fnv1a(slurp(dir / "can.log")), kPins[k].can);
    EXPECT_EQ(fnv1a(slurp(dir / "truth.toml")), kPins[k].truth);
    std::filesystem::remove_all(dir);
  }
}

TEST(VibrationStream, BlocksGiveTheWholeSignalsBitsAndTruth) {
  const Scenario s = load_case(kCases[0]);
  Scenario for_motion;
  Scenario for_can;
  timing_scenarios(s, for_motion, for_can);
  const MotionProfile whole_motion = build_motion(for_motion, s.seed);
  const Vibration whole = synthesize_vibration(for_motion, whole_motion, s.seed);
  ASSERT_GT(whole.impulse_times_s.size(), 10U);
  ASSERT_GT(whole.effect_impacts, 10U);
  ASSERT_GT(whole.effect_clipped_samples, 0U);

  // The lazy plan (pieces regenerated cycle by cycle, what simulate_to_directory streams from).
  const MotionProfile plan = build_motion_lazy(for_motion, s.seed);
  EXPECT_TRUE(plan.angle_rad.empty());
  EXPECT_TRUE(plan.pieces.empty());
  ASSERT_NE(plan.lazy, nullptr);
  EXPECT_EQ(plan.pause_start_s, whole_motion.pause_start_s);
  EXPECT_EQ(plan.duration_s, whole_motion.duration_s);
  VibrationStream stream(for_motion, plan, s.seed, true);
  ASSERT_EQ(stream.samples(), whole.accel_ms2.size());
  std::vector<double> got;
  std::vector<double> block(613);
  for (std::size_t n = 0; (n = stream.next(block)) > 0;)
    got.insert(got.end(), block.begin(), block.begin() + n);
  ASSERT_EQ(got.size(), whole.accel_ms2.size());
  EXPECT_EQ(std::memcmp(got.data(), whole.accel_ms2.data(), got.size() * sizeof(double)), 0);
  Vibration truth;
  stream.take_truth(truth);
  EXPECT_EQ(truth.impulse_times_s, whole.impulse_times_s);
  EXPECT_EQ(truth.impulse_amplitudes_ms2, whole.impulse_amplitudes_ms2);
  EXPECT_EQ(truth.effect_impacts, whole.effect_impacts);
  EXPECT_EQ(truth.effect_clipped_samples, whole.effect_clipped_samples);
  EXPECT_EQ(truth.harmonics_above_nyquist, whole.harmonics_above_nyquist);
}

TEST(VibrationStream, TiltedNoiseAndShaftOrderLinesCarryAcrossBlocks) {
  // The tilted background makes its noise in blocks of its own (8192 at 25.6 kHz) and the shaft-order
  // lines follow the input angle: streamed in blocks of 613 they give the whole signal's bits.
  Scenario s = load_case(kCases[0]);
  s.vibration.noise_tilt_db_per_decade = 9.0;
  s.vibration.shaft_orders = {3, 5};
  s.vibration.shaft_order_amplitudes = {0.4, 0.2};
  Scenario for_motion;
  Scenario for_can;
  timing_scenarios(s, for_motion, for_can);
  const MotionProfile whole_motion = build_motion(for_motion, s.seed);
  const Vibration whole = synthesize_vibration(for_motion, whole_motion, s.seed);
  const MotionProfile plan = build_motion_plan(for_motion, s.seed);
  VibrationStream stream(for_motion, plan, s.seed, true);
  std::vector<double> got;
  std::vector<double> block(613);
  for (std::size_t n = 0; (n = stream.next(block)) > 0;)
    got.insert(got.end(), block.begin(), block.begin() + n);
  ASSERT_EQ(got.size(), whole.accel_ms2.size());
  EXPECT_EQ(std::memcmp(got.data(), whole.accel_ms2.data(), got.size() * sizeof(double)), 0);
  // And the tilt changed the signal (it is not silently off).
  Scenario white = s;
  white.vibration.noise_tilt_db_per_decade = 0.0;
  Scenario white_motion;
  timing_scenarios(white, white_motion, for_can);
  const Vibration w = synthesize_vibration(white_motion, build_motion(white_motion, s.seed), s.seed);
  ASSERT_EQ(w.accel_ms2.size(), whole.accel_ms2.size());
  EXPECT_NE(std::memcmp(w.accel_ms2.data(), whole.accel_ms2.data(), w.accel_ms2.size() * sizeof(double)), 0);
}

TEST(CanStream, FramesInTheWholeLogsOrderWithSmallWindows) {
  Scenario s = load_scenario(source_path("config/scenarios/joint_rotation_faulty.toml"));
  s.motion.cycles = 4;
  s.can.other_frames_per_s = 400;  // many ties with the speed frames' microseconds
  const MotionProfile m = build_motion_plan(s, 7);
  const MotionProfile lazy = build_motion_lazy(s, 7);
  ASSERT_NE(lazy.lazy, nullptr);
  const std::vector<SimCanFrame> whole = generate_can(s, m, 7);
  for (const std::size_t window : {std::size_t{1}, std::size_t{13}, std::size_t{1000000}}) {
    SCOPED_TRACE(window);
    CanStream stream(s, window == 13 ? lazy : m, 7, window);
    SimCanFrame f;
    std::size_t k = 0;
    while (stream.next(f)) {
      ASSERT_LT(k, whole.size());
      EXPECT_EQ(f.frame.t_ns, whole[k].frame.t_ns) << k;
      EXPECT_EQ(f.frame.id, whole[k].frame.id) << k;
      EXPECT_EQ(std::memcmp(f.frame.data.data(), whole[k].frame.data.data(), f.frame.data.size()), 0) << k;
      EXPECT_EQ(f.is_speed, whole[k].is_speed) << k;
      ++k;
    }
    EXPECT_EQ(k, whole.size());
  }
}

TEST(TruthToml, StreamedLongArraysAndPlateausEqualTheWholeTable) {
  // 300 cycles: every per-cycle array is long enough to be streamed (plateaus, cycle starts, severities,
  // drift factors, cycle variation rows). Only the plan and the truth are needed, not the samples.
  Scenario s = load_case(kCases[1]);
  s.motion.cycles = 300;
  s.faults.push_back(s.faults.front());  // a second fault: its severities stay in the table
  s.faults.back().onset_cycle = 100;
  s.faults.back().ramp_cycles = 50;
  const MotionProfile m = build_motion_plan(s, 11);
  Vibration v;
  v.cycle_variation = draw_cycle_variation(s.vibration, m.cycles, 11);
  v.impulse_times_s.assign(5, 0.0);
  v.effect_impacts = 3;
  SimulationSummary sum;
  sum.seed = 11;
  sum.samples = motion_samples(m);
  sum.speed_frames = 1234;
  const std::string whole = truth_toml_whole(s, m, v, 56, sum);
  const std::string streamed = truth_toml_streamed(s, m, v, 56, sum);
  EXPECT_EQ(streamed, whole);
  // From the lazy plan (plateaus and cycle starts regenerated while printing).
  const MotionProfile lazy = build_motion_lazy(s, 11);
  ASSERT_NE(lazy.lazy, nullptr);
  EXPECT_EQ(truth_toml_streamed(s, lazy, v, 56, sum), whole);
  EXPECT_EQ(truth_toml_whole(s, lazy, v, 56, sum), whole);
  // The cycle variation drawn again while printing (what simulate_to_directory does).
  Vibration drawn = v;
  drawn.cycle_variation = CycleVariation{};
  EXPECT_EQ(truth_toml_streamed(s, lazy, drawn, 56, sum), whole);
  EXPECT_NE(whole.find("cycle_amplitude_factors = [\n    [ "), std::string::npos);  // multi-line rows
  EXPECT_GT(whole.size(), 100000U);
}

}  // namespace
}  // namespace ptda::sim
