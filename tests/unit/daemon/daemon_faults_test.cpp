// ptdad's bad-input handling through the real threads, with in-memory devices (daemon_fakes.hpp) that
// serve exactly the blocks and frames each test built from the simulated healthy arc-welding job.
// Every fault run is compared with the same input without the fault, so no assertion depends on the
// simulator preset's numbers: only on which windows exist and what the counters say.
#include <gtest/gtest.h>

#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <set>

#include "daemon_fakes.hpp"
#include "daemon_test_support.hpp"
#include "ptda/common/time.hpp"
#include "status_text.hpp"

namespace ptda::daemon::test {
namespace {

std::shared_ptr<const SimRecording> healthy() {
  static const auto rec = make_sim_recording(arc_scenario(), 7);
  return rec;
}

struct Win {
  std::uint64_t seq = 0;
  std::int64_t first_sample = 0;
  std::int64_t t_start = 0, t_end = 0;  ///< stream time
  std::int32_t class_id = -1;
  int status = 0;
  std::uint64_t rms_bits = 0, entropy_bits = 0;
  bool operator==(const Win&) const = default;
};

struct Sink final : WindowSink {
  explicit Sink(const FakeDevices& dev) : dev_(dev) { w.resize(8192); }
  void on_window(const dsp::WindowResult& r) noexcept override {
    if (n >= w.size()) return;
    Win& x = w[n++];
    x.seq = r.ref.seq;
    x.first_sample = r.ref.first_sample;
    x.t_start = r.ref.t_start_ns - dev_.origin();
    x.t_end = r.ref.t_end_ns - dev_.origin();
    x.class_id = r.class_id;
    x.status = static_cast<int>(r.status);
    x.rms_bits = std::bit_cast<std::uint64_t>(r.features.rms_res);
    x.entropy_bits = std::bit_cast<std::uint64_t>(r.features.entropy_res);
  }
  [[nodiscard]] std::vector<Win> windows() const {
    return {w.begin(), w.begin() + static_cast<std::ptrdiff_t>(n)};
  }
  const FakeDevices& dev_;
  std::vector<Win> w;
  std::size_t n = 0;
};

using ptda::test::read_text;

struct RunResult {
  std::vector<Win> windows;
  DaemonView view;
  std::string status_json;
  drivers::CanCounters can;
  int code = -1;
};

RunResult run_to_end(const fs::path& dir, const std::string& config_text, FakeDevices& dev) {
  write_text(dir / "ptdad.toml", config_text);
  DaemonOptions opt;
  opt.config_file = dir / "ptdad.toml";
  opt.config_dir = fs::path();
  opt.exit_at_end = true;
  drivers::MonotonicClock clock;
  Sink sink(dev);
  Daemon d(opt, clock);
  d.set_window_sink(&sink);
  d.set_device_factory(&dev);
  d.configure();
  d.activate();
  RunResult r;
  r.code = d.run();
  r.view = d.view();
  r.windows = sink.windows();
  r.status_json = read_text(dir / "status" / "status.json");
  r.can = dev.last_channel->counters();
  return r;
}

std::shared_ptr<ChannelPlan> clean_frames() {
  auto p = std::make_shared<ChannelPlan>();
  p->frames = healthy()->frames;
  return p;
}

/// How the daemon's decoder classifies each frame of a plan (the expected counters).
std::array<std::size_t, 5> classify(const ChannelPlan& plan, const config::SpeedFrameSpec& spec) {
  std::array<std::size_t, 5> n{};
  for (const CanFrame& f : plan.frames) {
    config::DecodedSpeed d;
    ++n[static_cast<std::size_t>(config::decode_speed(f, spec, d))];
  }
  return n;
}
constexpr std::size_t kOk = 0, kOther = 1, kWrongDlc = 2, kRtr = 3, kError = 4;

bool contains(const std::string& json, const std::string& needle) {
  return json.find(needle) != std::string::npos;
}

class Faults : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { block_daemon_signals(); }
};

constexpr std::size_t kBlock = 512;

TEST_F(Faults, AdcFaultsDiscardExactlyTheAffectedWindows) {
  const fs::path dir = scratch("faults_adc");
  write_sim_baseline(dir / "baseline.bin");
  const auto rec = healthy();
  float peak = 0.0F;
  for (const float x : rec->samples) peak = std::max(peak, std::abs(x));
  const double clip = 2.0 * static_cast<double>(peak);  // never reached by the clean signal
  const std::string cfg = fake_config(dir, "", "clip_abs = " + std::to_string(clip));

  const auto clean_plan = std::make_shared<SourcePlan>(plan_blocks(*rec, kBlock));
  FakeDevices clean_dev(clean_plan, clean_frames());
  const RunResult clean = run_to_end(dir, cfg, clean_dev);
  ASSERT_EQ(clean.code, 0);
  ASSERT_GE(clean.windows.size(), 40U);
  EXPECT_EQ(clean.view.pipeline.slicer.windows_invalid, 0U);
  EXPECT_EQ(clean.view.pipeline.blocks_invalid, 0U);

  // Eight faults, each in the middle of a different clean window.
  const std::uint32_t n_win = clean.view.window_len;
  std::vector<std::int64_t> at;
  for (int k = 1; k <= 8; ++k) {
    const Win& w = clean.windows[clean.windows.size() * static_cast<std::size_t>(k) / 10];
    at.push_back(w.first_sample + n_win / 2);
  }
  auto plan = std::make_shared<SourcePlan>(*clean_plan);
  auto& blocks = plan->blocks;
  const auto block_of = [&](std::int64_t s) { return static_cast<std::size_t>(s) / kBlock; };
  std::set<std::int64_t> bad;  // stream sample indices whose windows must go
  const auto bad_block = [&](std::size_t b) {
    for (std::size_t i = 0; i < blocks[b].count; ++i)
      bad.insert(static_cast<std::int64_t>(blocks[b].first_index + i));
  };
  const std::size_t b_overrun = block_of(at[0]), b_short = block_of(at[1]), b_back = block_of(at[5]);
  const std::size_t b_jump_fwd = block_of(at[6]), b_jump_back = block_of(at[7]);
  bad_block(b_overrun);
  bad_block(b_short);
  bad_block(b_back);
  bad_block(b_jump_fwd);
  bad_block(b_jump_back);
  // 1. ADC overrun: one block lost; the next keeps its index (a jump) and says so.
  blocks[b_overrun + 1].flags |= drivers::kBlockGap;
  blocks[b_overrun + 1].gap_samples = kBlock;
  // 2. A short read inside a block.
  blocks[b_short].flags |= drivers::kBlockShortRead;
  // 3-5. NaN, +Inf and a clipped sample.
  blocks[block_of(at[2])].samples[at[2] % kBlock] = std::nanf("");
  blocks[block_of(at[3])].samples[at[3] % kBlock] = INFINITY;
  // (above clip_abs: the configured value is a rounded decimal of `clip`)
  blocks[block_of(at[4])].samples[at[4] % kBlock] = static_cast<float>(1.5 * clip);
  bad.insert(at[2]);
  bad.insert(at[3]);
  bad.insert(at[4]);
  // 6. The device stamp did not advance.
  blocks[b_back].t_mono_ns = blocks[b_back - 1].t_mono_ns;
  blocks[b_back].flags |= drivers::kBlockTimeBack;
  // 7-8. The stamps jump forward by 0.3 s (and stay there), later back by 0.3 s, with no index jump.
  for (std::size_t b = b_jump_fwd; b < b_jump_back; ++b) blocks[b].t_mono_ns += 300'000'000;
  blocks.erase(blocks.begin() + static_cast<std::ptrdiff_t>(b_overrun));

  FakeDevices faulty_dev(plan, clean_frames());
  const RunResult faulty = run_to_end(dir, cfg, faulty_dev);
  ASSERT_EQ(faulty.code, 0);

  // Exactly the clean windows that contain a bad sample are missing; the others are bit-identical.
  std::vector<Win> expected;
  std::size_t missing = 0;
  for (const Win& w : clean.windows) {
    const auto it = bad.lower_bound(w.first_sample);
    if (it != bad.end() && *it < w.first_sample + n_win) {
      ++missing;
    } else {
      expected.push_back(w);
    }
  }
  EXPECT_EQ(missing, 8U);  // each fault sits in the middle of its own window
  for (const Win& w : faulty.windows) {
    const auto it = bad.lower_bound(w.first_sample);
    EXPECT_FALSE(it != bad.end() && *it < w.first_sample + n_win)
        << "window seq " << w.seq << " at sample " << w.first_sample << " contains bad sample " << *it;
  }
  ASSERT_EQ(faulty.windows.size(), expected.size());
  for (std::size_t i = 0; i < expected.size(); ++i) {
    ASSERT_EQ(faulty.windows[i], expected[i]) << "window " << i << " seq " << expected[i].seq;
  }
  const PipelineStatus& ps = faulty.view.pipeline;
  EXPECT_EQ(ps.slicer.windows_invalid, missing);
  EXPECT_EQ(ps.gap_samples, kBlock);
  EXPECT_EQ(ps.blocks_invalid, 4U);  // short read, stamp back, two stamp jumps
  EXPECT_EQ(ps.time_jumps, 2U);
  EXPECT_EQ(ps.slicer.samples_nonfinite, 2U);
  EXPECT_EQ(ps.slicer.samples_clipped, 1U);
  EXPECT_EQ(ps.alarm_counters.alarms_raised, clean.view.pipeline.alarm_counters.alarms_raised);
  EXPECT_EQ(ps.scored + ps.no_class + missing, clean.view.pipeline.scored + clean.view.pipeline.no_class);
  // status.json shows the source's counters and the discarded windows.
  EXPECT_TRUE(contains(faulty.status_json, "\"gaps\":1,")) << faulty.status_json;
  EXPECT_TRUE(contains(faulty.status_json, "\"lost_samples\":512,"));
  EXPECT_TRUE(contains(faulty.status_json, "\"short_reads\":1,"));
  EXPECT_TRUE(contains(faulty.status_json, "\"time_back\":1,"));
  EXPECT_TRUE(contains(faulty.status_json, "\"windows_invalid\":" + std::to_string(missing) + ","));
  std::printf(
      "adc faults: clean %zu windows, faulty %zu (missing %zu); gap_samples %llu, blocks_invalid %llu, "
      "time_jumps %llu, nonfinite %llu, clipped %llu, windows_invalid %llu, alarms %llu (clean %llu)\n",
      clean.windows.size(), faulty.windows.size(), missing, static_cast<unsigned long long>(ps.gap_samples),
      static_cast<unsigned long long>(ps.blocks_invalid), static_cast<unsigned long long>(ps.time_jumps),
      static_cast<unsigned long long>(ps.slicer.samples_nonfinite),
      static_cast<unsigned long long>(ps.slicer.samples_clipped),
      static_cast<unsigned long long>(ps.slicer.windows_invalid),
      static_cast<unsigned long long>(ps.alarm_counters.alarms_raised),
      static_cast<unsigned long long>(clean.view.pipeline.alarm_counters.alarms_raised));
}

// The order domain (issue 16): a lost block (index jump) and a short read go to the angle resampler as
// NaN samples, which break its segment there. No order window spans a bad sample, the clean windows
// that did are gone, each fault adds exactly one resampler break, and the NaN samples are counted.
TEST_F(Faults, OrderDomainAdcFaultsBreakTheResamplerSegment) {
  const fs::path dir = scratch("faults_order_adc");
  const std::string cfg = "[daemon]\nbaseline = \"" + (dir / "baseline.bin").string() +
                          "\"\nstatus_dir = \"" + (dir / "status").string() +
                          "\"\nstatus_period_s = 0.05\n\n[adc]\nbackend = \"wav\"\nrecording = \"" +
                          (dir / "not-opened").string() +
                          "\"\npace = \"fast\"\n\n[can]\nbackend = \"candump\"\npace = \"fast\"\n"
                          "speed_latency_s = 0.0005\n\n" +
                          order_pipeline();
  write_sim_order_baseline(dir / "baseline.bin", cfg);
  const auto rec = make_sim_recording(joint_scenario(), 101);
  auto frames = std::make_shared<ChannelPlan>();
  frames->frames = rec->frames;
  const auto clean_plan = std::make_shared<SourcePlan>(plan_blocks(*rec, kBlock));
  FakeDevices clean_dev(clean_plan, frames);
  const RunResult clean = run_to_end(dir, cfg, clean_dev);
  ASSERT_EQ(clean.code, 0);
  ASSERT_GE(clean.windows.size(), 60U);
  const PipelineStatus& cs = clean.view.pipeline;
  EXPECT_TRUE(cs.order_domain);
  EXPECT_EQ(cs.blocks_invalid, 0U);

  // Two faults, each in the middle of a different clean window: a lost block and a short read.
  const auto mid = [&](std::size_t k) {
    const Win& w = clean.windows[clean.windows.size() * k / 3];
    return (w.t_start + w.t_end) / 2;
  };
  const auto block_at = [&](std::int64_t t_ns) {
    return static_cast<std::size_t>(static_cast<double>(t_ns) * 1e-9 * rec->fs_hz) / kBlock;
  };
  const std::size_t b_lost = block_at(mid(1)), b_short = block_at(mid(2));
  ASSERT_LT(b_lost + 1, b_short);
  auto plan = std::make_shared<SourcePlan>(*clean_plan);
  auto& blocks = plan->blocks;
  const auto span_of = [&](std::size_t b) {
    return std::pair<std::int64_t, std::int64_t>{
        blocks[b].t_mono_ns, rec->sample_offset_ns(blocks[b].first_index + blocks[b].count)};
  };
  const std::array<std::pair<std::int64_t, std::int64_t>, 2> bad{span_of(b_lost), span_of(b_short)};
  blocks[b_short].flags |= drivers::kBlockShortRead;
  blocks[b_lost + 1].flags |= drivers::kBlockGap;
  blocks[b_lost + 1].gap_samples = kBlock;
  blocks.erase(blocks.begin() + static_cast<std::ptrdiff_t>(b_lost));

  FakeDevices faulty_dev(plan, frames);
  const RunResult faulty = run_to_end(dir, cfg, faulty_dev);
  ASSERT_EQ(faulty.code, 0);
  const PipelineStatus& fs_ = faulty.view.pipeline;
  const auto overlaps = [&](const Win& w) {
    for (const auto& [t0, t1] : bad)
      if (w.t_start < t1 && t0 <= w.t_end) return true;
    return false;
  };
  std::size_t clean_hit = 0;
  for (const Win& w : clean.windows) clean_hit += overlaps(w) ? 1 : 0;
  EXPECT_EQ(clean_hit, 2U);  // each fault sits inside one clean window
  for (const Win& w : faulty.windows) EXPECT_FALSE(overlaps(w)) << "window seq " << w.seq;
  EXPECT_LT(faulty.windows.size(), clean.windows.size());
  EXPECT_EQ(fs_.gap_samples, kBlock);
  EXPECT_EQ(fs_.blocks_invalid, 1U);
  EXPECT_EQ(fs_.resampler.breaks, cs.resampler.breaks + 2);
  EXPECT_EQ(fs_.resampler.samples_unused, cs.resampler.samples_unused + 2 * kBlock);
  EXPECT_EQ(fs_.resampler.samples, cs.resampler.samples);  // the lost block's place was filled (NaN)
  EXPECT_TRUE(contains(faulty.status_json, "\"breaks\":" + std::to_string(fs_.resampler.breaks) + ","))
      << faulty.status_json;
  std::printf("order adc faults: clean %zu windows, faulty %zu; breaks %llu (clean %llu)\n",
              clean.windows.size(), faulty.windows.size(),
              static_cast<unsigned long long>(fs_.resampler.breaks),
              static_cast<unsigned long long>(cs.resampler.breaks));
}

CanFrame error_frame(std::int64_t t_ns, std::uint32_t cls, std::uint8_t d1) {
  CanFrame f;
  f.t_ns = t_ns;
  f.id = cls;
  f.flags = kCanError;
  f.len = 8;
  f.data[1] = d1;
  return f;
}

// Both inputs at real-time pace: one thread reads them (docs/daemon.md, "One thread at real-time
// pace"). A bus that delivers a backlog of frames before the first vibration block must be drained
// whole: the oldest half of the speed ring is dropped (speeds_before_t0), never the newest frames
// (can_ring_full). Read in ring-halves with one sample dropped per round, the backlog overflowed.
TEST_F(Faults, OneThreadDrainsASpeedBacklogBeforeTheFirstBlock) {
  const fs::path dir = scratch("faults_one_thread_backlog");
  write_sim_baseline(dir / "baseline.bin");
  std::string cfg = fake_config(dir);
  for (std::size_t at = cfg.find("pace = \"fast\""); at != std::string::npos;
       at = cfg.find("pace = \"fast\""))
    cfg.replace(at, 13, "pace = \"realtime\"");
  write_text(dir / "ptdad.toml", cfg);
  const auto source = std::make_shared<SourcePlan>(plan_blocks(*healthy(), kBlock));
  const auto frames = clean_frames();
  const std::size_t n = frames->frames.size();
  ASSERT_GT(n, 2 * daemon::kSpeedRingSamples);  // a backlog larger than the ring
  FakeDevices dev(source, frames);
  dev.gate.t_ns = -1;                       // no block is ever released
  dev.gate.can_lead_ns = INT64_C(1) << 60;  // every frame is there at once
  DaemonOptions opt;
  opt.config_file = dir / "ptdad.toml";
  opt.config_dir = fs::path();
  drivers::MonotonicClock clock;
  Daemon d(opt, clock);
  d.set_device_factory(&dev);
  d.configure();
  d.activate();
  DaemonRunThread runner(d);
  const bool drained = wait_for([&] { return d.view().counters.can_frames >= n; }, std::chrono::seconds(10));
  const DaemonView v = d.view();
  ASSERT_TRUE(v.wake.single_thread);
  EXPECT_TRUE(drained) << v.counters.can_frames << " of " << n << " frames received";
  EXPECT_EQ(v.counters.can_ring_full, 0U);
  ASSERT_GT(v.counters.can_speed, 2 * daemon::kSpeedRingSamples);  // (the plan has other frames too)
  EXPECT_FALSE(v.pipeline.have_t0);
  // All but at most a ring's worth (the newest) were dropped as too early for any block.
  EXPECT_GE(v.pipeline.speeds_before_t0, v.counters.can_speed - daemon::kSpeedRingSamples);
  EXPECT_LE(v.pipeline.speeds_before_t0, v.counters.can_speed);
}

TEST_F(Faults, MalformedAndUnexpectedFramesAreCountedAndIgnored) {
  const fs::path dir = scratch("faults_can_frames");
  write_sim_baseline(dir / "baseline.bin");
  const std::string cfg = fake_config(dir);
  const auto rec = healthy();
  const auto source = std::make_shared<SourcePlan>(plan_blocks(*rec, kBlock));
  FakeDevices clean_dev(source, clean_frames());
  const RunResult clean = run_to_end(dir, cfg, clean_dev);
  ASSERT_EQ(clean.code, 0);
  ASSERT_GE(clean.windows.size(), 40U);

  // Between the speed frames: 50 each of a wrong-DLC speed frame (a huge speed if it were decoded),
  // an RTR with the speed id, an unknown id, an extended frame with the speed id's number; error
  // frames: error-passive at 1/3, back to active at 1/2, bus-off as the very last frame; a receive
  // overflow of 17 frames reported after frame 1000.
  auto plan = std::make_shared<ChannelPlan>();
  const auto& src = rec->frames;
  std::size_t wrong = 0, rtr = 0, other = 0, last_inject = 0;
  const config::SpeedFrameSpec spec = parse_daemon_config(cfg, "faults.toml").pipeline.speed_frame;
  for (std::size_t i = 0; i < src.size(); ++i) {
    plan->frames.push_back(src[i]);
    config::DecodedSpeed ds;
    const bool speed = config::decode_speed(src[i], spec, ds) == config::DecodeResult::kOk;
    if (speed && i % (src.size() / 50) < 2 && i + 1 < src.size() && i - last_inject > 10) {
      last_inject = i;
      CanFrame f = src[i];
      f.t_ns += 1000;
      f.len = 4;
      std::memset(f.data.data(), 0x7F, 4);
      plan->frames.push_back(f);
      ++wrong;
      CanFrame r = src[i];
      r.t_ns += 2000;
      r.flags |= kCanRtr;
      r.len = 0;
      plan->frames.push_back(r);
      ++rtr;
      CanFrame o = src[i];
      o.t_ns += 3000;
      o.id = 0x123;
      std::memset(o.data.data(), 0xFF, 8);
      plan->frames.push_back(o);
      CanFrame e = src[i];
      e.t_ns += 4000;
      e.flags |= kCanExtended;
      std::memset(e.data.data(), 0x7F, 8);
      plan->frames.push_back(e);
      other += 2;
    }
    if (i == src.size() / 3)
      plan->frames.push_back(error_frame(src[i].t_ns + 500, 0x004U /*CRTL*/, 0x10 /*RX_PASSIVE*/));
    if (i == src.size() / 2) plan->frames.push_back(error_frame(src[i].t_ns + 500, 0x004U, 0x40 /*ACTIVE*/));
  }
  plan->frames.push_back(error_frame(src.back().t_ns + 1000, 0x040U /*BUSOFF*/, 0));
  plan->overflow_at = 1000;
  plan->overflow_drops = 17;
  FakeDevices dev(source, plan);
  const RunResult faulty = run_to_end(dir, cfg, dev);
  ASSERT_EQ(faulty.code, 0);

  // Windows unaffected.
  ASSERT_EQ(faulty.windows.size(), clean.windows.size());
  for (std::size_t i = 0; i < clean.windows.size(); ++i) ASSERT_EQ(faulty.windows[i], clean.windows[i]) << i;
  const PipelineCounters& c = faulty.view.counters;
  const auto expect = classify(*plan, spec);
  EXPECT_GE(wrong, 40U);
  EXPECT_EQ(expect[kWrongDlc], wrong);
  EXPECT_EQ(expect[kRtr], rtr);
  EXPECT_EQ(expect[kOther], clean.view.counters.can_other_id + other);
  EXPECT_EQ(c.can_speed, expect[kOk]);
  EXPECT_EQ(c.can_speed, clean.view.counters.can_speed);
  EXPECT_EQ(c.can_wrong_dlc, wrong);
  EXPECT_EQ(c.can_rtr, rtr);
  EXPECT_EQ(c.can_other_id, expect[kOther]);
  EXPECT_EQ(c.can_error_frames, 3U);
  EXPECT_EQ(expect[kError], 3U);
  EXPECT_EQ(c.can_frames, plan->frames.size());
  EXPECT_EQ(faulty.can.error_passive, 1U);
  EXPECT_EQ(faulty.can.bus_off, 1U);
  EXPECT_EQ(faulty.view.pipeline.alarm_counters.alarms_raised,
            clean.view.pipeline.alarm_counters.alarms_raised);
  EXPECT_TRUE(contains(faulty.status_json, "\"wrong_dlc\":" + std::to_string(wrong) + ","))
      << faulty.status_json;
  EXPECT_TRUE(contains(faulty.status_json, "\"other_ids\":" + std::to_string(expect[kOther]) + ","));
  EXPECT_TRUE(contains(faulty.status_json, "\"error_frames\":3,"));
  EXPECT_TRUE(contains(faulty.status_json, "\"remote_frames\":" + std::to_string(rtr) + ","))
      << faulty.status_json;
  EXPECT_TRUE(contains(faulty.status_json, "\"rx_overflow_drops\":17,"));
  EXPECT_TRUE(contains(faulty.status_json, "\"bus_off\":1,"));
  EXPECT_TRUE(contains(faulty.status_json, "\"bus_state\":\"bus_off\""));
  std::printf(
      "can faults: frames %llu, speed %llu, wrong_dlc %llu, rtr %llu, other %llu, error frames %llu, "
      "error_passive %llu, bus_off %llu, rx_overflow_drops %llu; windows %zu = clean %zu\n",
      static_cast<unsigned long long>(c.can_frames), static_cast<unsigned long long>(c.can_speed),
      static_cast<unsigned long long>(c.can_wrong_dlc), static_cast<unsigned long long>(c.can_rtr),
      static_cast<unsigned long long>(c.can_other_id), static_cast<unsigned long long>(c.can_error_frames),
      static_cast<unsigned long long>(faulty.can.error_passive),
      static_cast<unsigned long long>(faulty.can.bus_off),
      static_cast<unsigned long long>(faulty.can.rx_overflow_drops), faulty.windows.size(),
      clean.windows.size());
}

TEST_F(Faults, ErrorPassiveAndBusOffReachTheStatusWhileTheyLast) {
  const fs::path dir = scratch("faults_bus_state");
  write_sim_baseline(dir / "baseline.bin");
  const auto rec = healthy();
  const auto source = std::make_shared<SourcePlan>(plan_blocks(*rec, kBlock));
  auto plan = std::make_shared<ChannelPlan>();
  const auto& src = rec->frames;
  const std::int64_t t_passive = src[src.size() / 4].t_ns, t_off = src[src.size() / 2].t_ns;
  for (std::size_t i = 0; i < src.size(); ++i) {
    plan->frames.push_back(src[i]);
    if (i == src.size() / 4) plan->frames.push_back(error_frame(t_passive + 500, 0x004U, 0x10));
    if (i == src.size() / 2) plan->frames.push_back(error_frame(t_off + 500, 0x040U, 0));
    if (i == src.size() / 2 + 500)
      plan->frames.push_back(error_frame(src[i].t_ns + 500, 0x100U /*RESTARTED*/, 0));
  }
  FakeDevices clean_dev(source, clean_frames());
  const RunResult clean = run_to_end(dir, fake_config(dir), clean_dev);
  ASSERT_EQ(clean.code, 0);
  FakeDevices dev(source, plan);
  write_text(dir / "ptdad.toml", fake_config(dir));
  DaemonOptions opt;
  opt.config_file = dir / "ptdad.toml";
  opt.config_dir = fs::path();
  drivers::MonotonicClock clock;
  Daemon d(opt, clock);
  d.set_device_factory(&dev);
  dev.gate.t_ns = t_passive + 100'000'000;
  d.configure();
  d.activate();
  DaemonRunThread runner(d);
  const fs::path status = dir / "status" / "status.json";
  ASSERT_TRUE(wait_for([&] { return contains(read_text(status), "\"bus_state\":\"error_passive\""); }));
  // Error-passive still receives: monitoring goes on (or starts: the first window may still be on its way).
  EXPECT_TRUE(wait_for([&] { return d.view().phase == Phase::kMonitoring; })) << phase_name(d.view().phase);
  // Bus-off: no speed can come, monitoring pauses with the reason and a fault, never an alarm.
  dev.gate.t_ns = t_off + 100'000'000;
  ASSERT_TRUE(wait_for([&] { return contains(read_text(status), "\"bus_state\":\"bus_off\""); }));
  ASSERT_TRUE(wait_for([&] { return d.view().reason.view().find("(bus-off)") != std::string_view::npos; }));
  DaemonView v = d.view();
  EXPECT_EQ(v.phase, Phase::kPausedSpeed);
  EXPECT_EQ(v.state, DaemonState::kPaused);
  // kFault, or a latched alarm raised before (it keeps the confirmed verdict), never kNormal.
  EXPECT_NE(v.pipeline.report.level, drivers::AlarmLevel::kNormal);
  EXPECT_EQ(v.pipeline.report.level == drivers::AlarmLevel::kAlarm, v.pipeline.alarm.latched);
  EXPECT_NE(v.pipeline.report.causes & drivers::kCauseSpeed, 0U);
  std::printf("bus-off reason: %.*s\n", static_cast<int>(v.reason.view().size()), v.reason.view().data());
  // The controller restarts: monitoring resumes by itself.
  dev.gate.t_ns = std::numeric_limits<std::int64_t>::max();
  ASSERT_TRUE(wait_for([&] { return d.view().pipeline.ended; }));
  v = d.view();
  EXPECT_EQ(dev.last_channel->counters().restarts, 1U);
  EXPECT_EQ(dev.last_channel->bus_state(), drivers::CanBusState::kErrorActive);
  EXPECT_EQ(v.pipeline.pauses, 1U);
  EXPECT_EQ(v.pipeline.alarm_counters.alarms_raised, clean.view.pipeline.alarm_counters.alarms_raised);
  d.request_stop();
  runner.join();
}

TEST_F(Faults, SpeedRangeDirectionFlipsAndCanClockJumpsBreakWindows) {
  const fs::path dir = scratch("faults_speed");
  write_sim_baseline(dir / "baseline.bin");
  const std::string cfg = fake_config(dir);
  const auto rec = healthy();
  const auto source = std::make_shared<SourcePlan>(plan_blocks(*rec, kBlock));
  FakeDevices clean_dev(source, clean_frames());
  const RunResult clean = run_to_end(dir, cfg, clean_dev);
  ASSERT_EQ(clean.code, 0);
  ASSERT_GE(clean.windows.size(), 40U);
  const DaemonConfig dc = parse_daemon_config(cfg, "faults.toml");
  const config::SpeedFrameSpec& spec = dc.pipeline.speed_frame;

  // Four faults, each in the middle of a different clean window: 20 ms above max_speed_rad_s, 20 ms
  // of the opposite direction, one frame stamped 0.5 s in the past, one stamped 1 s in the future.
  auto plan = std::make_shared<ChannelPlan>(*clean_frames());
  auto& fr = plan->frames;
  std::vector<std::pair<std::int64_t, std::int64_t>> spans;  // stream time no window may overlap
  const auto frame_at = [&](std::int64_t t) {
    return static_cast<std::size_t>(
        std::lower_bound(fr.begin(), fr.end(), t,
                         [](const CanFrame& f, std::int64_t v) { return f.t_ns < v; }) -
        fr.begin());
  };
  const auto mid = [&](int k) {
    const Win& w = clean.windows[clean.windows.size() * static_cast<std::size_t>(k) / 5];
    return (w.t_start + w.t_end) / 2;
  };
  const auto rewrite = [&](std::size_t i, double speed) {
    config::DecodedSpeed d;
    ASSERT_EQ(config::decode_speed(fr[i], spec, d), config::DecodeResult::kOk);
    fr[i] = config::encode_speed(spec, fr[i].t_ns, speed, d.angle_rad);
  };
  std::size_t i = frame_at(mid(1));
  spans.emplace_back(fr[i - 1].t_ns, fr[i + 5].t_ns);
  for (std::size_t j = i; j < i + 5; ++j) rewrite(j, 50.0);  // > max_speed_rad_s = 10
  i = frame_at(mid(2));
  spans.emplace_back(fr[i - 1].t_ns, fr[i + 5].t_ns);
  for (std::size_t j = i; j < i + 5; ++j) {
    config::DecodedSpeed d;
    ASSERT_EQ(config::decode_speed(fr[j], spec, d), config::DecodeResult::kOk);
    rewrite(j, -d.speed_rad_s);
  }
  i = frame_at(mid(3));
  spans.emplace_back(fr[i - 1].t_ns, fr[i + 1].t_ns);
  fr[i].t_ns -= 500'000'000;
  i = frame_at(mid(4));
  spans.emplace_back(fr[i - 1].t_ns, fr[i].t_ns + 1'000'000'000);
  fr[i].t_ns += 1'000'000'000;
  FakeDevices dev(source, plan);
  const RunResult faulty = run_to_end(dir, cfg, dev);
  ASSERT_EQ(faulty.code, 0);

  for (const Win& w : faulty.windows) {
    for (const auto& [a, b] : spans) {
      EXPECT_FALSE(w.t_start < b && a < w.t_end)
          << "window seq " << w.seq << " [" << w.t_start << ", " << w.t_end << ") overlaps the fault [" << a
          << ", " << b << "]";
    }
  }
  // The clean windows of the faulty spans are gone; every other window is unchanged in content.
  std::size_t gone = 0;
  for (const Win& c : clean.windows) {
    bool hit = false;
    for (const auto& [a, b] : spans) hit = hit || (c.t_start < b && a < c.t_end);
    const auto it = std::find_if(faulty.windows.begin(), faulty.windows.end(),
                                 [&](const Win& w) { return w.first_sample == c.first_sample; });
    if (hit) {
      ++gone;
      EXPECT_TRUE(it == faulty.windows.end()) << "seq " << c.seq;
    } else if (it != faulty.windows.end()) {
      EXPECT_EQ(it->rms_bits, c.rms_bits);
      EXPECT_EQ(it->entropy_bits, c.entropy_bits);
      EXPECT_EQ(it->class_id, c.class_id);
    }
  }
  EXPECT_GE(gone, 4U);
  const dsp::SlicerCounters& s = faulty.view.pipeline.slicer;
  EXPECT_EQ(s.speed_out_of_range, clean.view.pipeline.slicer.speed_out_of_range + 5);
  EXPECT_GT(s.speed_out_of_order, clean.view.pipeline.slicer.speed_out_of_order);
  EXPECT_GT(s.speed_gaps, clean.view.pipeline.slicer.speed_gaps);
  EXPECT_EQ(faulty.view.pipeline.alarm_counters.alarms_raised,
            clean.view.pipeline.alarm_counters.alarms_raised);
  EXPECT_GE(faulty.windows.size() + 8, clean.windows.size());  // only the faults' neighbourhoods are lost
  std::printf(
      "speed faults: clean %zu windows, faulty %zu, gone %zu; out_of_range %llu (+5), out_of_order %llu "
      "(clean %llu), speed_gaps %llu (clean %llu), alarms %llu (clean %llu)\n",
      clean.windows.size(), faulty.windows.size(), gone,
      static_cast<unsigned long long>(s.speed_out_of_range),
      static_cast<unsigned long long>(s.speed_out_of_order),
      static_cast<unsigned long long>(clean.view.pipeline.slicer.speed_out_of_order),
      static_cast<unsigned long long>(s.speed_gaps),
      static_cast<unsigned long long>(clean.view.pipeline.slicer.speed_gaps),
      static_cast<unsigned long long>(faulty.view.pipeline.alarm_counters.alarms_raised),
      static_cast<unsigned long long>(clean.view.pipeline.alarm_counters.alarms_raised));
}

TEST_F(Faults, SpeedFramesStopWhileOtherIdsContinue) {
  // The speed id falls silent for 3 s while an unrelated id keeps the bus busy: paused, not fooled.
  const fs::path dir = scratch("faults_speed_stop");
  write_sim_baseline(dir / "baseline.bin");
  const auto rec = healthy();
  const auto source = std::make_shared<SourcePlan>(plan_blocks(*rec, kBlock));
  auto plan = std::make_shared<ChannelPlan>();
  const std::int64_t a = 20'000'000'000, b = 23'000'000'000;
  std::size_t others = 0;
  for (const CanFrame& f : rec->frames) {
    if (f.t_ns >= a && f.t_ns < b) {
      CanFrame o = f;
      o.id = 0x185;
      plan->frames.push_back(o);
      ++others;
    } else {
      plan->frames.push_back(f);
    }
  }
  FakeDevices dev(source, plan);
  const RunResult r = run_to_end(dir, fake_config(dir), dev);
  ASSERT_EQ(r.code, 0);
  EXPECT_EQ(r.view.pipeline.pauses, 1U);
  EXPECT_EQ(r.view.counters.can_other_id,
            classify(*plan, parse_daemon_config(fake_config(dir), "f.toml").pipeline.speed_frame)[kOther]);
  EXPECT_GE(r.view.counters.can_other_id, others);
  // The silence; the end of the replay is no fault cause any more (phase "replay ended", no cause bit).
  EXPECT_EQ(r.view.pipeline.alarm_counters.faults_entered, 1U);
  std::size_t before = 0, inside = 0, after = 0;
  for (const Win& w : r.windows) (w.t_end <= a ? before : w.t_start < b ? inside : after)++;
  EXPECT_GT(before, 10U);
  EXPECT_EQ(inside, 0U);
  EXPECT_GT(after, 10U);
  std::printf(
      "speed id silent 3 s, %zu other-id frames: pauses %llu, faults_entered %llu, windows %zu/%zu/%zu\n",
      others, static_cast<unsigned long long>(r.view.pipeline.pauses),
      static_cast<unsigned long long>(r.view.pipeline.alarm_counters.faults_entered), before, inside, after);
}

}  // namespace
}  // namespace ptda::daemon::test
