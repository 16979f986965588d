// Clearing a latched alarm through the daemon's real threads: the CAN clear frame ([can.clear_frame])
// and the local command (SIGUSR1). A clear is accepted only once min_hold_s passed and the k-of-n
// condition is gone; the alarm outputs (a RecordingAlarmOutput standing in for the GPIO line, and the
// CAN alarm frames captured from the fake channel) show the exact sequence of levels.
//
// The input is the simulated healthy arc-welding job with the vibration amplified 4x for 8 s (a gross
// fault); a gate holds the data at chosen stream times so each clear meets a known state, judged on
// data time (fast pace).
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include "alarm/can_alarm_output.hpp"
#include "daemon_fakes.hpp"
#include "daemon_test_support.hpp"

namespace ptda::daemon::test {
namespace {

using drivers::AlarmLevel;
constexpr std::int64_t kS = 1'000'000'000;

class Clear : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    block_daemon_signals();
    sigset_t set;
    sigemptyset(&set);
    sigaddset(&set, SIGUSR1);
    pthread_sigmask(SIG_BLOCK, &set, nullptr);
  }
};

std::string clear_config(const fs::path& dir) {
  // k = n = 5: only a run of abnormal windows alarms, so the healthy parts never do (checked below).
  // The test times the clears on the k-of-n condition (gone after 5 healthy windows); the CUSUM's
  // CUSUM is switched off so that the clear times are k-of-n's alone.
  std::string pipe = with_decision(arc_pipeline(), 5, 5);
  const std::size_t at = pipe.find("\nn = 5\n");
  if (at == std::string::npos) throw std::runtime_error("clear_config: no 'n = 5' line");
  pipe.insert(at + 7, "sequential = \"off\"\n");
  return "[daemon]\nbaseline = \"" + (dir / "baseline.bin").string() + "\"\nstatus_dir = \"" +
         (dir / "status").string() +
         "\"\nstatus_period_s = 0.05\n\n[adc]\nbackend = \"wav\"\nrecording = \"" +
         (dir / "not-opened").string() +
         "\"\npace = \"fast\"\n\n[can]\nbackend = \"candump\"\npace = \"fast\"\n\n[can.clear_frame]\nenabled "
         "= true\n"
         "id = 0x3A1\ndata = \"C1\"\n\n[alarm]\nmin_hold_s = 20.0\nlatch = true\nwarning = "
         "false\n\n[alarm.can]\n"
         "enabled = true\nid = 0x3A0\n\n" +
         pipe;
}

CanFrame clear_frame(std::int64_t t_ns) {
  CanFrame f;
  f.t_ns = t_ns;
  f.id = 0x3A1;
  f.len = 1;
  f.data[0] = 0xC1;
  return f;
}

/// Consecutive duplicates removed.
std::vector<AlarmLevel> squeeze(const std::vector<AlarmLevel>& in) {
  std::vector<AlarmLevel> out;
  for (const AlarmLevel l : in) {
    if (out.empty() || out.back() != l) out.push_back(l);
  }
  return out;
}

std::string names(const std::vector<AlarmLevel>& v) {
  std::string s;
  for (const AlarmLevel l : v) s += std::string(drivers::alarm_level_name(l)) + " ";
  return s;
}

TEST_F(Clear, LatchedAlarmClearsOnlyWhenAllowed) {
  const fs::path dir = scratch("clear");
  write_sim_baseline(dir / "baseline.bin");
  const auto rec = make_sim_recording(arc_scenario(), 7);
  const std::int64_t duration = rec->loop_ns;
  const std::int64_t ta = duration * 3 / 10, tb = ta + 8 * kS;  // the fault: [ta, tb)
  ASSERT_GT(duration, ta + 30 * kS) << "the recording is too short for this test";

  const auto healthy_src = std::make_shared<SourcePlan>(plan_blocks(*rec, 512));
  auto faulty_src = std::make_shared<SourcePlan>(*healthy_src);
  for (drivers::SampleBlock& b : faulty_src->blocks) {
    if (b.t_mono_ns < ta || b.t_mono_ns >= tb) continue;
    for (std::uint32_t i = 0; i < b.count; ++i) b.samples[i] *= 4.0F;
  }
  // Clear frames: one in the second hold-only phase, one after the hold.
  const std::int64_t g1 = ta + 5 * kS;   // alarm raised, condition on, hold running
  const std::int64_t g2 = tb + 6 * kS;   // condition gone (>= 5 healthy windows), hold still running
  const std::int64_t g3 = ta + 25 * kS;  // hold over (raised by ta + 3 s at the latest), condition gone
  auto frames = std::make_shared<ChannelPlan>();
  for (const CanFrame& f : rec->frames) {
    if (!frames->frames.empty() && frames->frames.back().t_ns < g2 + kS / 2 && f.t_ns >= g2 + kS / 2) {
      frames->frames.push_back(clear_frame(g2 + kS / 2));
    }
    if (!frames->frames.empty() && frames->frames.back().t_ns < g3 + kS && f.t_ns >= g3 + kS) {
      frames->frames.push_back(clear_frame(g3 + kS));
    }
    frames->frames.push_back(f);
  }
  write_text(dir / "ptdad.toml", clear_config(dir));
  ASSERT_EQ(parse_daemon_config(clear_config(dir), "clear.toml").pipeline.decision.k, 5U);
  DaemonOptions opt;
  opt.config_file = dir / "ptdad.toml";
  opt.config_dir = fs::path();
  drivers::MonotonicClock clock;

  {  // Precondition: the same input without the fault never alarms with this configuration.
    FakeDevices dev(healthy_src, std::make_shared<ChannelPlan>(*frames), true);
    DaemonOptions o = opt;
    o.exit_at_end = true;
    Daemon d(o, clock);
    d.set_device_factory(&dev);
    d.configure();
    d.activate();
    ASSERT_EQ(d.run(), 0);
    ASSERT_EQ(d.view().pipeline.alarm_counters.alarms_raised, 0U);
    EXPECT_EQ(d.view().counters.can_clear_frames, 2U);
    // Nothing to clear (two requests posted before one tick count once).
    EXPECT_GE(d.view().pipeline.alarm_counters.clears_nothing, 1U);
    EXPECT_EQ(
        d.view().pipeline.alarm_counters.clears_accepted + d.view().pipeline.alarm_counters.clears_refused,
        0U);
  }

  FakeDevices dev(faulty_src, frames, true);
  dev.gate.can_lead_ns = kS / 5;
  Daemon d(opt, clock);
  d.set_device_factory(&dev);
  d.configure();
  d.activate();
  DaemonRunThread runner(d);
  const auto reach = [&](std::int64_t t) {
    dev.gate.t_ns = t;
    // Every block up to the gate processed (the last may wait for a later speed sample: 30 ms slack).
    return wait_for([&] { return d.view().pipeline.data_time_ns - dev.origin() >= t - 30'000'000; });
  };
  const auto counters = [&] { return d.view().pipeline.alarm_counters; };

  // 1. Local clear while the alarm is on and the hold runs: refused, the alarm stays.
  ASSERT_TRUE(reach(g1));
  ASSERT_TRUE(wait_for([&] { return d.view().pipeline.alarm.alarm_active; }));
  EXPECT_EQ(d.view().pipeline.report.level, AlarmLevel::kAlarm);
  EXPECT_TRUE(d.view().pipeline.alarm.condition);
  ASSERT_EQ(::kill(::getpid(), SIGUSR1), 0);
  ASSERT_TRUE(wait_for([&] { return counters().clears_refused == 1; }));
  EXPECT_EQ(d.view().local_clears, 1U);
  EXPECT_EQ(d.view().pipeline.report.level, AlarmLevel::kAlarm);

  // 2. CAN clear once the condition is gone but within the hold: refused, still latched.
  ASSERT_TRUE(reach(g2));
  EXPECT_FALSE(d.view().pipeline.alarm.condition);
  EXPECT_TRUE(d.view().pipeline.alarm.latched);
  dev.gate.t_ns = g2 + kS / 2;  // releases the clear frame at g2 + 0.5 s (+ lead)
  ASSERT_TRUE(wait_for([&] { return counters().clears_refused == 2; }));
  EXPECT_EQ(d.view().counters.can_clear_frames, 1U);
  EXPECT_EQ(d.view().pipeline.report.level, AlarmLevel::kAlarm);

  // 3. CAN clear after the hold with the condition gone: accepted, back to normal.
  ASSERT_TRUE(reach(g3));
  EXPECT_TRUE(d.view().pipeline.alarm.latched);
  EXPECT_EQ(d.view().pipeline.report.level, AlarmLevel::kAlarm);  // latched: no clear, no end
  dev.gate.t_ns = g3 + kS;
  ASSERT_TRUE(wait_for([&] { return counters().clears_accepted == 1; }));
  ASSERT_TRUE(wait_for([&] { return d.view().pipeline.report.level == AlarmLevel::kNormal; }));
  EXPECT_FALSE(d.view().pipeline.alarm.latched);

  // 4. A local clear with nothing latched is a no-op.
  ASSERT_EQ(::kill(::getpid(), SIGUSR1), 0);
  ASSERT_TRUE(wait_for([&] { return counters().clears_nothing == 1; }));

  dev.gate.t_ns = std::numeric_limits<std::int64_t>::max();
  ASSERT_TRUE(wait_for([&] { return d.view().pipeline.ended; }));
  const AlarmCounters c = counters();
  EXPECT_EQ(c.alarms_raised, 1U);
  EXPECT_EQ(c.clears_refused, 2U);
  EXPECT_EQ(c.clears_accepted, 1U);
  d.request_stop();
  runner.join();

  // The outputs: GPIO stand-in and CAN alarm frames show fault (start) -> normal -> alarm -> normal
  // (accepted clear) -> fault (end of the replay; deactivation).
  std::vector<AlarmLevel> shown;
  for (const drivers::AlarmReport& r : dev.last_output->reports()) shown.push_back(r.level);
  EXPECT_EQ(dev.last_output->dropped(), 0U);
  // The first fault is "not judged yet": no verdict is published before the first scored window.
  const std::vector<AlarmLevel> want = {AlarmLevel::kFault, AlarmLevel::kNormal, AlarmLevel::kAlarm,
                                        AlarmLevel::kNormal, AlarmLevel::kFault};
  EXPECT_EQ(squeeze(shown), want) << names(squeeze(shown));
  std::vector<AlarmLevel> sent;
  drivers::CanAlarmConfig ac;
  ac.id = 0x3A0;
  for (const CanFrame& f : dev.last_channel->sent()) {
    drivers::AlarmReport r;
    std::uint8_t alive = 0;
    ASSERT_TRUE(drivers::decode_alarm_frame(f, ac, r, alive));
    sent.push_back(r.level);
  }
  const std::vector<AlarmLevel> want_can = want;  // activate()'s fault frame merges with the first set()
  EXPECT_EQ(squeeze(sent), want_can) << names(squeeze(sent));
  // The GPIO line is energised only below kAlarm: off, on, off (alarm), on, off.
  std::printf(
      "clear: alarms %llu, clears refused %llu accepted %llu nothing %llu; outputs: %s; CAN frames %zu: %s\n",
      static_cast<unsigned long long>(c.alarms_raised), static_cast<unsigned long long>(c.clears_refused),
      static_cast<unsigned long long>(c.clears_accepted), static_cast<unsigned long long>(c.clears_nothing),
      names(squeeze(shown)).c_str(), sent.size(), names(squeeze(sent)).c_str());
}

}  // namespace
}  // namespace ptda::daemon::test
