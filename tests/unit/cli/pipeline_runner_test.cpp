// The shared recording feeder of train/monitor/report: CAN decode counters, latency, scale, time
// interleaving; and the window selection / renumbering / re-debouncing helpers.
#include "ptda/cli/pipeline_runner.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "ptda/common/error.hpp"
#include "ptda/common/time.hpp"
#include "ptda/config/speed_codec.hpp"
#include "ptda/formats/candump.hpp"
#include "ptda/formats/recording.hpp"
#include "ptda/formats/wav.hpp"

namespace ptda::cli {
namespace {

namespace fs = std::filesystem;

fs::path scratch(const std::string& name) {
  const char* env = std::getenv("PTDA_TEST_TMP");
  const fs::path base = env != nullptr ? fs::path(env) : fs::temp_directory_path();
  const fs::path dir = base / "cli_pipeline_runner" / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

constexpr std::int64_t kT0Ns = 1'700'000'000'000'000'000LL;

// 10000 samples at 1000 Hz (10 s), value i; scale 2; CAN: a speed frame every 0.1 s (101 frames,
// 0..10 s) plus one frame of each kind that must be counted and not used.
fs::path make_recording(const std::string& name) {
  const fs::path dir = scratch(name);
  std::vector<std::vector<float>> ch(1);
  for (int i = 0; i < 10000; ++i) ch[0].push_back(static_cast<float>(i));
  formats::write_wav(dir / "vibration.wav", 1000, formats::WavSampleFormat::kFloat32, ch);
  const config::SpeedFrameSpec spec;
  std::vector<formats::CandumpRecord> recs;
  auto add = [&](const CanFrame& f) {
    formats::CandumpRecord r;
    r.frame = f;
    r.iface = "can0";
    recs.push_back(r);
  };
  for (int i = 0; i <= 100; ++i) {
    add(config::encode_speed(spec, kT0Ns + i * 100'000'000LL, 1.5, 0.0));
    if (i == 10) {
      CanFrame other;
      other.t_ns = kT0Ns + i * 100'000'000LL + 1'000'000;
      other.id = 0x201;
      other.len = 2;
      add(other);
      CanFrame short_frame = config::encode_speed(spec, other.t_ns + 1'000'000, 1.5, 0.0);
      short_frame.len = 4;  // the speed id with DLC 4
      add(short_frame);
      CanFrame rtr;
      rtr.t_ns = other.t_ns + 2'000'000;
      rtr.id = 0x184;
      rtr.flags = kCanRtr;
      add(rtr);
      CanFrame err;
      err.t_ns = other.t_ns + 3'000'000;
      err.id = 0x4;
      err.len = 8;
      err.flags = kCanError;
      add(err);
    }
  }
  formats::write_candump(dir / "can.log", recs);
  formats::RecordingMeta meta;
  meta.start_time_s = 1.7e9;
  meta.scale = 2.0;
  formats::write_recording_meta(dir, meta);
  return dir;
}

struct Event {
  bool speed = false;
  std::int64_t t_ns = 0;  // speed: sample time; block: end time of the block
  std::size_t n = 0;
  float first = 0.0F;
};

class RecordingSink final : public PipelineSink {
 public:
  void on_speed(const dsp::SpeedSample& s) override {
    events.push_back({true, s.t_ns, 0, 0.0F});
    speeds.push_back(s.speed_rad_s);
  }
  void on_samples(std::span<const float> block) override {
    samples += block.size();
    const std::int64_t end = kT0Ns + static_cast<std::int64_t>(samples) * 1'000'000LL;
    events.push_back({false, end, block.size(), block.front()});
  }
  void on_finish() override { finished = true; }
  std::vector<Event> events;
  std::vector<double> speeds;
  std::size_t samples = 0;
  bool finished = false;
};

TEST(RunRecording, CountsFramesAppliesLatencyAndScaleAndInterleavesByTime) {
  const fs::path dir = make_recording("run");
  const RecordingInfo rec = open_recording(dir);
  EXPECT_EQ(rec.t0_ns, kT0Ns);
  EXPECT_DOUBLE_EQ(rec.duration_s, 10.0);
  config::PipelineConfig cfg;
  cfg.speed_latency_s = 0.05;  // 50 ms subtracted from every CAN timestamp
  RecordingSink sink;
  RunOptions opts;
  // 1000 frames asked for; at 1 kHz a block is capped at a quarter second (250 frames), so that the
  // slicer's default history (4 windows + 1 s) always holds a block plus a window between drains.
  opts.block_frames = 1000;
  opts.progress = false;
  const CanCounters c = run_recording(rec, cfg, sink, opts);
  EXPECT_EQ(c.frames, 105U);
  EXPECT_EQ(c.speed_frames, 101U);
  EXPECT_EQ(c.other_id, 1U);
  EXPECT_EQ(c.wrong_dlc, 1U);
  EXPECT_EQ(c.rtr, 1U);
  EXPECT_EQ(c.error_frames, 1U);
  EXPECT_TRUE(sink.finished);
  EXPECT_EQ(sink.samples, 10000U);
  ASSERT_EQ(sink.speeds.size(), 101U);
  for (const double v : sink.speeds) EXPECT_NEAR(v, 1.5, 1e-12);

  // Blocks of 250 samples scaled by 2; the first speed sample comes at -50 ms, before any block.
  std::int64_t last_block_end = kT0Ns;
  std::size_t blocks = 0, speeds_seen = 0;
  for (const Event& e : sink.events) {
    if (e.speed) {
      EXPECT_EQ(e.t_ns, kT0Ns + static_cast<std::int64_t>(speeds_seen) * 100'000'000LL - 50'000'000LL);
      // A speed sample is delivered only once the previous block ended at or before its time...
      if (blocks > 0) {
        EXPECT_GE(e.t_ns, last_block_end);
      }
      ++speeds_seen;
    } else {
      EXPECT_EQ(e.n, 250U);
      EXPECT_EQ(e.first, 2.0F * static_cast<float>(blocks * 250));
      // ...and every speed sample earlier than the block's end came before the block: sample k is at
      // k * 100 - 50 ms, so those with k * 100 < end + 50 ms.
      const std::size_t end_ms = (blocks + 1) * 250;
      const auto expected_before = std::min<std::size_t>(101, (end_ms + 49) / 100 + 1);
      EXPECT_EQ(speeds_seen, expected_before) << "block " << blocks;
      last_block_end = e.t_ns;
      ++blocks;
    }
  }
  EXPECT_EQ(blocks, 40U);
}

TEST(RunRecording, ABlockLargerThanTheSlicerHistoryLosesNoWindow) {
  // Windows of 100 samples at 1 kHz: the slicer keeps 4 windows + 1 s = 1400 samples. Blocks of 4000
  // frames (read whole, drained after) would overwrite windows before they are popped; the runner reads
  // at most a quarter second per block, so the windows equal those of 100-frame blocks, none lost.
  const fs::path dir = make_recording("big_block");
  const RecordingInfo rec = open_recording(dir);
  config::PipelineConfig cfg;
  cfg.extraction.window_len = 100;
  cfg.extraction.max_speed_gap_s = 0.2;  // speed frames every 100 ms
  RunOptions small;
  small.block_frames = 100;
  small.progress = false;
  RunOptions big = small;
  big.block_frames = 4000;
  const CollectResult a = collect_windows(rec, cfg, 1000.0, small);
  const CollectResult b = collect_windows(rec, cfg, 1000.0, big);
  EXPECT_EQ(a.slicer.windows_lost, 0U);
  EXPECT_EQ(b.slicer.windows_lost, 0U);
  ASSERT_GT(a.data.refs.size(), 80U);  // 0.1 .. 10 s in 100-sample windows
  ASSERT_EQ(b.data.refs.size(), a.data.refs.size());
  for (std::size_t i = 0; i < a.data.refs.size(); ++i) {
    EXPECT_EQ(b.data.refs[i].first_sample, a.data.refs[i].first_sample) << "window " << i;
    EXPECT_EQ(b.data.windows[i], a.data.windows[i]) << "window " << i;
  }
}

TEST(RunRecording, ConfiguredRateMustMatchTheRecording) {
  const fs::path dir = make_recording("rate");
  const RecordingInfo rec = open_recording(dir);
  config::PipelineConfig cfg;
  EXPECT_EQ(pipeline_fs_hz(rec, cfg, "cfg.toml"), 1000.0);
  cfg.fs_hz = 2000.0;
  try {
    (void)pipeline_fs_hz(rec, cfg, "cfg.toml");
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "cfg.toml: [acquisition] fs_hz = 2000 Hz but recording " +
                                         (dir / "vibration.wav").string() + " is sampled at 1000 Hz");
  }
  EXPECT_THROW((void)open_recording(dir / "missing"), Error);
}

dsp::CollectedWindows fake(std::size_t regions, std::size_t per_region) {
  dsp::CollectedWindows c;
  std::uint64_t seq = 0;
  for (std::size_t r = 0; r < regions; ++r) {
    dsp::RegionInfo info;
    info.seq = r;
    c.regions.push_back(info);
    for (std::size_t k = 0; k < per_region; ++k) {
      dsp::WindowRef ref;
      ref.seq = seq;
      ref.region_seq = r;
      c.refs.push_back(ref);
      c.windows.push_back(std::vector<float>{static_cast<float>(seq)});
      ++seq;
    }
  }
  return c;
}

TEST(CollectedWindows, AppendRenumbersAndSelectKeepsRegionsOfKeptWindows) {
  dsp::CollectedWindows all = fake(3, 2);  // windows 0..5 in regions 0..2
  append_collected(all, fake(2, 2));       // windows 6..9 in regions 3..4
  ASSERT_EQ(all.refs.size(), 10U);
  ASSERT_EQ(all.regions.size(), 5U);
  EXPECT_EQ(all.refs[6].seq, 6U);
  EXPECT_EQ(all.refs[6].region_seq, 3U);
  EXPECT_EQ(all.refs[9].region_seq, 4U);
  EXPECT_EQ(all.regions[4].seq, 4U);
  EXPECT_EQ(all.windows[9][0], 3.0F);  // the appended recording's own window 3

  const dsp::CollectedWindows first_half = select_windows(all, FractionRange{0.0, 0.5});
  ASSERT_EQ(first_half.refs.size(), 5U);  // windows 0..4
  EXPECT_EQ(first_half.refs.back().seq, 4U);
  ASSERT_EQ(first_half.regions.size(), 3U);  // regions 0, 1, 2 (window 4 is in region 2)
  EXPECT_EQ(first_half.regions.back().seq, 2U);
  const dsp::CollectedWindows second_half = select_windows(all, FractionRange{0.5, 1.0});
  ASSERT_EQ(second_half.refs.size(), 5U);
  EXPECT_EQ(second_half.refs.front().seq, 5U);
  ASSERT_EQ(second_half.regions.size(), 3U);  // regions 2, 3, 4
  EXPECT_EQ(second_half.regions.front().seq, 2U);
}

TEST(Redebounce, RecomputesKOfNOverTheSubsetAndSkipsUnclassified) {
  // k = 2 of n = 3; the alarm before the subset must not leak in.
  const std::vector<int> pattern = {1, 0, 2, 1, 1, 0, 0, 0};  // 1 abnormal, 0 ok, 2 no class
  std::vector<dsp::WindowResult> w(pattern.size());
  for (std::size_t i = 0; i < w.size(); ++i) {
    w[i].status = pattern[i] == 2 ? dsp::WindowStatus::kNoClass : dsp::WindowStatus::kScored;
    w[i].verdict.rms_out = pattern[i] == 1;
    w[i].alarm = true;  // stale state from the full run
  }
  redebounce(w, dsp::DecisionConfig{2, 3, {}, {}, {}});
  // scored history: a, ok, (skip), a -> 2 of last 3 -> alarm; a -> ok,a,a alarm; ok -> a,a,ok alarm;
  // ok -> a,ok,ok no; ok -> no
  const std::vector<bool> expected = {false, false, false, true, true, true, false, false};
  const std::vector<std::uint32_t> counts = {1, 1, 1, 2, 2, 2, 1, 0};
  for (std::size_t i = 0; i < w.size(); ++i) {
    EXPECT_EQ(w[i].alarm, expected[i]) << i;
    EXPECT_EQ(w[i].abnormal_in_last_n, counts[i]) << i;
  }
}

// check_can_input's cases beyond the golden test: the speed id present but never decodable, extended
// ids, many ids, a log of error frames only, and timelines that overlap partly (accepted).
TEST(CheckCanInput, NamesTheIdsAndTheReason) {
  RecordingInfo rec;
  rec.dir = "rec";
  rec.can_path = "rec/can.log";
  rec.wav_path = "rec/vibration.wav";
  rec.t0_ns = kT0Ns;
  rec.duration_s = 10.0;
  rec.meta.start_time_s = 1.7e9;
  config::PipelineConfig cfg;  // speed id 0x184, standard, dlc 8
  const auto message = [&](const CanCounters& c) {
    try {
      check_can_input(rec, cfg, c, "cfg.toml");
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("(no error)");
  };
  CanCounters dlc;
  dlc.frames = 7;
  dlc.ids[0x184] = 5;
  dlc.ids[0x100] = 2;
  dlc.wrong_dlc = 4;
  dlc.rtr = 1;
  EXPECT_EQ(
      message(dlc),
      "rec/can.log: none of the 5 frames with id 0x184 decoded as a speed sample (4 with a length other "
      "than dlc = 8, 1 remote frames); check [can.speed_frame] dlc in cfg.toml");
  CanCounters many;
  for (std::uint32_t id = 0x200; id < 0x20A; ++id) many.ids[id] = 10 + (id - 0x200);
  many.ids[0x184 | CanCounters::kExtendedIdKey] = 100;  // the right number, but extended
  many.frames = 100 + 145;
  EXPECT_EQ(
      message(many),
      "rec/can.log: no frame with id 0x184 in the CAN log (245 frames); ids seen: 0x00000184 (extended) "
      "(100 frames), 0x209 (19 frames), 0x208 (18 frames), 0x207 (17 frames), 0x206 (16 frames), 0x205 "
      "(15 frames), 0x204 (14 frames), 0x203 (13 frames), and 3 more ids. Set id (and extended) in "
      "[can.speed_frame] of cfg.toml to the joint's speed frame");
  CanCounters errors;
  errors.frames = 3;
  errors.error_frames = 3;
  EXPECT_NE(message(errors).find("(3 frames); ids seen: none but error frames."), std::string::npos)
      << message(errors);
  // Speed samples from 9 s before to 1 s after the start: they overlap, accepted.
  CanCounters partly;
  partly.frames = partly.speed_frames = 2;
  partly.ids[0x184] = 2;
  partly.first_speed_t_ns = kT0Ns - 9 * kNsPerS;
  partly.last_speed_t_ns = kT0Ns + kNsPerS;
  EXPECT_EQ(message(partly), "(no error)");
  partly.last_speed_t_ns = kT0Ns - 1;  // ends 1 ns before the first sample
  EXPECT_EQ(message(partly),
            "rec/can.log: the CAN speed frames (-9.000 to -0.000 s) do not overlap the vibration recording "
            "rec/vibration.wav (0.000 to 10.000 s); times in seconds from start_time 1700000000 of "
            "rec/recording.toml: check start_time and the log's clock");
}

TEST(Redebounce, RestartsTheCusumOverTheSubset) {
  // Class 0 windows with z_rms = 3 (k 1: +2 per window), stale statistics from the full run.
  std::vector<dsp::WindowResult> w(5);
  for (auto& r : w) {
    r.status = dsp::WindowStatus::kScored;
    r.class_id = 0;
    r.z_rms = 3.0;
    r.seq_statistic = 13.0;
    r.seq_alarm = true;
  }
  redebounce(w, dsp::DecisionConfig{3, 5, {}, {}, {}});  // cusum_warn 4, cusum_alarm 7
  // The cap is cusum_alarm + (n - k) cusum_k = 7 + 2 = 9 (docs/method.md §6), so the fifth is 9, not 10.
  const std::vector<double> s = {2.0, 4.0, 6.0, 8.0, 9.0};
  for (std::size_t i = 0; i < w.size(); ++i) {
    EXPECT_DOUBLE_EQ(w[i].seq_statistic, s[i]) << i;
    EXPECT_EQ(w[i].seq_warn, s[i] >= 4.0) << i;
    EXPECT_EQ(w[i].seq_alarm, s[i] >= 7.0) << i;
    EXPECT_EQ(w[i].seq_feature, dsp::SeqFeature::kRmsHigh) << i;
  }
  EXPECT_EQ(w[3].detector, dsp::AlarmDetector::kSequential);  // verdicts all ok: k-of-n silent
  EXPECT_TRUE(w[3].alarm);
}

}  // namespace
}  // namespace ptda::cli
