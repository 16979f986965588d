// ptdad's configuration: the daemon tables next to the pipeline tables, drop-ins in lexical order,
// located errors, cross-key checks, relative paths.
#include <gtest/gtest.h>

#include "daemon_test_support.hpp"
#include "ptda/common/error.hpp"

namespace ptda::daemon::test {
namespace {

std::string error_of(const std::string& text) {
  try {
    (void)parse_daemon_config(text, "t.toml");
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

const std::string kMinimal = "[extraction]\nwindow_len = 4096\n[adc]\nscenario = \"s.toml\"\n";

TEST(DaemonConfig, DefaultsAndOwnTablesBesideThePipeline) {
  const DaemonConfig c = parse_daemon_config(kMinimal, "t.toml");
  EXPECT_EQ(c.daemon.baseline, fs::path("/var/lib/ptda/baseline.bin"));
  EXPECT_EQ(c.daemon.status_dir, fs::path("/run/ptda"));
  EXPECT_TRUE(c.daemon.metrics_path.empty());
  EXPECT_TRUE(c.daemon.joint.empty());
  EXPECT_TRUE(c.history.dir.empty());  // no history unless configured (the shipped ptda.toml sets one)
  EXPECT_EQ(c.history.files, 8U);
  EXPECT_EQ(c.adc.backend, AdcBackend::kSim);
  EXPECT_EQ(c.can.backend, CanBackend::kSim);
  EXPECT_EQ(c.adc.block_len, 256U);
  EXPECT_EQ(c.daemon.speed_stale_periods, 25.0);
  EXPECT_EQ(c.daemon.coverage_timeout_s, 60.0);
  EXPECT_EQ(parse_daemon_config(kMinimal + "[daemon]\ncoverage_timeout_s = 12.5\n", "t.toml")
                .daemon.coverage_timeout_s,
            12.5);
  EXPECT_EQ(c.pipeline.extraction.window_len, 4096U);
  EXPECT_EQ(c.pipeline.speed_frame.id, 0x184U);
  EXPECT_EQ(c.alarm.min_hold_s, 10.0);
  EXPECT_TRUE(c.alarm.latch);

  const DaemonConfig d = parse_daemon_config(
      "[extraction]\nwindow_len = 4096\n"
      "[can]\nspeed_latency_s = 0.002\nbackend = \"socketcan\"\ninterface = \"can1\"\n"
      "[can.clear_frame]\nenabled = true\nid = 0x1A1\ndata = \"c1EA\"\n[can.speed_frame]\nid = 0x185\n"
      "[adc]\nbackend = \"iio\"\nchannel = \"accel_z\"\nblock_len = 512\n[acquisition]\nfs_hz = 25600\n"
      "[alarm]\nmin_hold_s = 3\n[alarm.gpio]\nenabled = true\nline = 17\nactive_low = true\n",
      "t.toml");
  EXPECT_EQ(d.pipeline.speed_latency_s, 0.002);
  EXPECT_EQ(d.pipeline.speed_frame.id, 0x185U);
  EXPECT_EQ(d.can.backend, CanBackend::kSocketCan);
  EXPECT_EQ(d.can.interface, "can1");
  EXPECT_TRUE(d.can.clear_frame.enabled);
  EXPECT_EQ(d.can.clear_frame.id, 0x1A1U);
  EXPECT_EQ(d.can.clear_frame.len, 2U);
  EXPECT_EQ(d.can.clear_frame.data[0], 0xC1);
  EXPECT_EQ(d.can.clear_frame.data[1], 0xEA);
  EXPECT_EQ(d.adc.backend, AdcBackend::kIio);
  EXPECT_EQ(d.adc.channel, "accel_z");
  EXPECT_EQ(d.adc.block_len, 512U);
  EXPECT_EQ(d.alarm.min_hold_s, 3.0);
  EXPECT_TRUE(d.alarm.gpio_enabled);
  EXPECT_EQ(d.alarm.gpio_line, 17U);
  EXPECT_TRUE(d.alarm.gpio_active_low);
}

TEST(DaemonConfig, ErrorsAreLocated) {
  EXPECT_EQ(error_of(kMinimal + "[daemon]\nbaselin = \"x\"\n")
                .rfind("t.toml:6:1: unknown key 'baselin' in [daemon]", 0),
            0U)
      << error_of(kMinimal + "[daemon]\nbaselin = \"x\"\n");
  EXPECT_EQ(error_of("[extraction]\nwindow_len = 4096\n[adc]\nbackend = \"spi\"\n"),
            "t.toml:4:11: adc.backend must be one of \"iio\", \"wav\", \"sim\", not \"spi\"");
  const std::string big_block =
      "[extraction]\nwindow_len = 4096\n[adc]\nscenario = \"s\"\nblock_len = 2048\n";
  EXPECT_EQ(error_of(big_block).rfind("t.toml:5:13: adc.block_len", 0), 0U) << error_of(big_block);
  // A daemon key misspelt in the shared [can] table is still an unknown key.
  EXPECT_NE(
      error_of(kMinimal + "[can]\nbakend = \"sim\"\n").find("t.toml:6:1: unknown key 'bakend' in [can]"),
      std::string::npos)
      << error_of(kMinimal + "[can]\nbakend = \"sim\"\n");
  EXPECT_NE(error_of(kMinimal + "[can.clear_frame]\ndata = \"C\"\n").find("t.toml:6:8: can.clear_frame.data"),
            std::string::npos);
  EXPECT_NE(error_of(kMinimal + "[daemon]\nmetrics_path = \"/tmp/x.txt\"\n").find("must end in \".prom\""),
            std::string::npos);
  // The joint's name labels metrics and (later) MQTT topics: no '/', '+', '#', spaces or quotes.
  const std::string bad_joint = kMinimal + "[daemon]\njoint = \"robot 17/j4\"\n";
  EXPECT_EQ(error_of(bad_joint),
            "t.toml:6:9: daemon.joint must be 1 to 32 characters of A-Z, a-z, 0-9, '_', '.' and '-', not "
            "\"robot 17/j4\"");
  EXPECT_EQ(error_of(kMinimal + "[daemon]\njoint = \"\"\n").rfind("t.toml:6:9: daemon.joint must be", 0), 0U);
  EXPECT_EQ(parse_daemon_config(kMinimal + "[daemon]\njoint = \"r17.j4-a_b\"\n", "t.toml").daemon.joint,
            "r17.j4-a_b");
  // [history]: the event history's bound is part of the configuration.
  const DaemonConfig hist = parse_daemon_config(
      kMinimal + "[history]\ndir = \"/var/lib/ptda/history\"\nmax_file_mib = 2.5\nfiles = 4\n", "t.toml");
  EXPECT_EQ(hist.history.dir, fs::path("/var/lib/ptda/history"));
  EXPECT_EQ(hist.history.max_file_mib, 2.5);
  EXPECT_EQ(hist.history.files, 4U);
  EXPECT_EQ(error_of(kMinimal + "[history]\nfiles = 1\n").rfind("t.toml:6:9: history.files", 0), 0U)
      << error_of(kMinimal + "[history]\nfiles = 1\n");
  EXPECT_EQ(error_of(kMinimal + "[history]\nmax_files = 3\n")
                .rfind("t.toml:6:1: unknown key 'max_files' in [history]", 0),
            0U)
      << error_of(kMinimal + "[history]\nmax_files = 3\n");
  const std::string zero_timeout = kMinimal + "[daemon]\ncoverage_timeout_s = 0\n";
  EXPECT_EQ(error_of(zero_timeout).rfind("t.toml:6:22: daemon.coverage_timeout_s", 0), 0U)
      << error_of(zero_timeout);
  // Pipeline errors come out the same way.
  EXPECT_EQ(error_of("[extraction]\nwindow_len = 4097\n").rfind("t.toml:2:", 0), 0U)
      << error_of("[extraction]\nwindow_len = 4097\n");
}

// Issue 14 item 8: a NUL inside a path (TOML "\u0000") and absurdly long strings are located errors.
// ptdad judges the time domain only; an order configuration is refused instead of running as time
// domain (ptda train/monitor take it: tests/unit/config/order_config_test.cpp).
// ptdad judges the order domain (issue 16): the order keys are the pipeline parser's, so a bad one is
// a located error naming the key, as in `ptda train` / `ptda monitor`.
TEST(DaemonConfig, OrderDomainIsAcceptedAndItsKeysChecked) {
  const std::string gearbox = "[gearbox]\nkind = \"cycloidal\"\nz_in = 28\nz_spur = 23\nz_pin = 40\n";
  const std::string head = "[adc]\nscenario = \"s.toml\"\n" + gearbox + "[extraction]\ndomain = \"order\"\n";
  const DaemonConfig c =
      parse_daemon_config(head + "revolutions = 4\ncan_time_smoothing_frames = 16\n", "t.toml");
  EXPECT_EQ(c.pipeline.domain, dsp::Domain::kOrder);
  EXPECT_EQ(c.pipeline.order.samples_per_rev, 1024U);  // the default S
  EXPECT_EQ(c.pipeline.order.revolutions, 4U);
  EXPECT_EQ(c.pipeline.order.can_time_smoothing_frames, 16U);
  EXPECT_EQ(c.pipeline.extraction.window_len, 4096U);  // R S, derived
  EXPECT_EQ(parse_daemon_config(kMinimal + "", "t.toml").pipeline.domain, dsp::Domain::kTime);
  // Field training collects time-domain windows only: --check-config --train says so.
  bool training_refused = false;
  for (const std::string& problem : check_config_paths(c, true))
    training_refused =
        training_refused || problem.rfind("[extraction] domain = \"order\": field training", 0) == 0;
  EXPECT_TRUE(training_refused);
  // Bad order keys: located, naming the key.
  EXPECT_EQ(error_of(head + "samples_per_rev = 1023\n"),
            "t.toml:10:19: extraction.samples_per_rev = 1023 must be even");
  EXPECT_EQ(
      error_of(head + "samples_per_rev = 1022\n"),
      "t.toml:10:19: [extraction] revolutions (8) x samples_per_rev (1022) = 8176 is not an FFT length up to "
      "2^24: it must have prime factors 2, 3 and 5 only (e.g. S = 1024, R = 8)");
  EXPECT_EQ(error_of(head + "revolutions = 0\n"),
            "t.toml:10:15: extraction.revolutions = 0 is outside 1..4096");
  EXPECT_EQ(error_of(head + "anti_alias_cutoff = 1.0\n"),
            "t.toml:10:21: extraction.anti_alias_cutoff must be > 0 and < 1 (a fraction of the output "
            "Nyquist order S/2)");
  EXPECT_EQ(error_of(head + "window_len = 4096\n"),
            "t.toml:10:14: [extraction] window_len = 4096 disagrees with domain = \"order\": revolutions (8) "
            "x samples_per_rev (1024) = 8192 (remove window_len; the order domain derives it)");
  EXPECT_EQ(error_of(head + "samples_per_rev = 32\n"),
            "t.toml:10:19: [extraction] samples_per_rev = 32 passes orders up to 11.545000000000002 only, "
            "below the gear mesh order z_in = 28: raise samples_per_rev");
  EXPECT_EQ(error_of(head + "can_time_smoothing_frames = 5000\n"),
            "t.toml:10:29: extraction.can_time_smoothing_frames = 5000 is outside 0..4096");
  // No gearbox ratio: the angle cannot be mapped to the input shaft.
  EXPECT_EQ(error_of("[adc]\nscenario = \"s.toml\"\n[extraction]\ndomain = \"order\"\n"),
            "t.toml:4:10: [extraction] domain = \"order\" needs the gearbox ratio (input-shaft angle = ratio "
            "x joint angle): set [gearbox] kind and teeth, or ratio");
}

TEST(DaemonConfig, NulInPathsAndOverlongNamesAreLocatedErrors) {
  const std::string nul = kMinimal + "[daemon]\nbaseline = \"/var/lib/ptda/a\\u0000.bin\"\n";
  EXPECT_EQ(error_of(nul),
            "t.toml:6:12: daemon.baseline contains a NUL byte (\\u0000) at byte 15; paths and names cannot");
  const std::string long_path = kMinimal + "[daemon]\nstatus_dir = \"/" + std::string(5000, 'x') + "\"\n";
  EXPECT_EQ(error_of(long_path), "t.toml:6:14: daemon.status_dir is 5001 bytes long, at most 4096 allowed");
  EXPECT_EQ(error_of(kMinimal + "[can]\ninterface = \"" + std::string(16, 'c') + "\"\n"),
            "t.toml:6:13: can.interface must be a network interface name of 1..15 characters");
}

TEST(DaemonConfig, CrossChecksPointAtTheKeyThatWasSet) {
  EXPECT_EQ(error_of("[extraction]\nwindow_len = 4096\n[adc]\nbackend = \"wav\"\n"),
            "t.toml:4:11: adc.backend = \"wav\" needs adc.recording (a recording directory)");
  EXPECT_EQ(
      error_of("[extraction]\nwindow_len = 4096\n[adc]\nbackend = \"iio\"\n[can]\nbackend = \"socketcan\"\n"),
      "t.toml:4:11: adc.backend = \"iio\" needs [acquisition] fs_hz (the ADC's sample rate)");
  // can.backend left at its default "sim": the error names the main file.
  EXPECT_EQ(
      error_of("[extraction]\nwindow_len = 4096\n[adc]\nbackend = \"wav\"\nrecording = \"r\"\n"),
      "t.toml: can.backend = \"sim\" serves the simulator's speed frames and needs adc.backend = \"sim\" "
      "(now \"wav\")");
  EXPECT_EQ(error_of("[extraction]\nwindow_len = 4096\n[adc]\nbackend = \"wav\"\nrecording = "
                     "\"r\"\n[can]\nbackend = \"sim\"\n"),
            "t.toml:7:11: can.backend = \"sim\" serves the simulator's speed frames and needs adc.backend = "
            "\"sim\" "
            "(now \"wav\")");
}

// [alarm.can] timer: the kernel re-sends the verdict frame where it can (default), with a lease that
// must cover two periods; "daemon" keeps the daemon's own sends.
TEST(DaemonConfig, AlarmCanTimerAndItsLease) {
  const DaemonConfig c = parse_daemon_config(kMinimal, "t.toml");
  EXPECT_TRUE(c.alarm.can_kernel_timer);
  EXPECT_EQ(c.alarm.can_lease_s, 0.5);
  const DaemonConfig d = parse_daemon_config(
      kMinimal + "[alarm.can]\nenabled = true\ntimer = \"daemon\"\nperiod_s = 0.5\n", "t.toml");
  EXPECT_FALSE(d.alarm.can_kernel_timer);  // the lease does not matter then
  const DaemonConfig k = parse_daemon_config(
      kMinimal + "[alarm.can]\nenabled = true\nperiod_s = 0.2\nlease_s = 0.4\n", "t.toml");
  EXPECT_TRUE(k.alarm.can_kernel_timer);
  EXPECT_EQ(k.alarm.can_lease_s, 0.4);
  EXPECT_EQ(error_of(kMinimal + "[alarm.can]\ntimer = \"bcm\"\n"),
            "t.toml:6:9: alarm.can.timer must be one of \"auto\", \"daemon\", not \"bcm\"");
  EXPECT_EQ(error_of(kMinimal + "[alarm.can]\nenabled = true\nperiod_s = 0.2\nlease_s = 0.3\n"),
            "t.toml:8:11: alarm.can.lease_s (0.3 s) must be at least twice alarm.can.period_s (0.2 s): the "
            "kernel would stop sending between two renewals (or set alarm.can.timer = \"daemon\")");
  // A longer period alone makes the default lease too short: the error points at the period.
  EXPECT_EQ(error_of(kMinimal + "[alarm.can]\nenabled = true\nperiod_s = 0.3\n")
                .rfind("t.toml:7:12: alarm.can.lease_s (0.5 s) must be at least twice", 0),
            0U)
      << error_of(kMinimal + "[alarm.can]\nenabled = true\nperiod_s = 0.3\n");
}

TEST(DaemonConfig, DropInsApplyInLexicalOrderKeyByKeyWithRelativePaths) {
  const fs::path dir = scratch("config_dropins");
  fs::create_directories(dir / "conf.d");
  write_text(dir / "ptdad.toml",
             kMinimal + "[decision]\nk = 3\nn = 5\n[daemon]\nbaseline = \"b/base.bin\"\n");
  write_text(dir / "conf.d" / "20-later.toml", "[decision]\nk = 4\n");
  write_text(dir / "conf.d" / "10-first.toml",
             "[decision]\nk = 2\nn = 6\n[adc]\nscenario = \"../sc/x.toml\"\n");
  write_text(dir / "conf.d" / "30-ignored.conf", "this is not toml");
  fs::create_directories(dir / "conf.d" / "40-dir.toml");
  const auto dropins = list_dropins(dir / "conf.d");
  ASSERT_EQ(dropins.size(), 2U);
  EXPECT_EQ(dropins[0].filename(), "10-first.toml");
  EXPECT_EQ(dropins[1].filename(), "20-later.toml");
  const DaemonConfig c = load_daemon_config(dir / "ptdad.toml", dropins);
  EXPECT_EQ(c.pipeline.decision.k, 4U);  // 20-later wins
  EXPECT_EQ(c.pipeline.decision.n, 6U);  // from 10-first, untouched by 20-later
  EXPECT_EQ(c.daemon.baseline, dir / "b" / "base.bin");
  EXPECT_EQ(c.adc.scenario, (dir / "sc" / "x.toml").lexically_normal());
  ASSERT_EQ(c.files.size(), 3U);
  EXPECT_TRUE(list_dropins(dir / "missing").empty());

  // An error in a drop-in names the drop-in; a cross-key error the file that set the key last.
  write_text(dir / "conf.d" / "20-later.toml", "[decision]\nk = 7\n");
  try {
    (void)load_daemon_config(dir / "ptdad.toml", list_dropins(dir / "conf.d"));
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind((dir / "conf.d" / "20-later.toml").string() + ":2:", 0), 0U)
        << e.what();
  }
}

TEST(DaemonConfig, ShippedExamplesAreValid) {
  const fs::path ex = source_dir() / "config" / "examples";
  const DaemonConfig main = load_daemon_config(ex / "ptdad.toml");
  EXPECT_EQ(main.adc.backend, AdcBackend::kSim);
  EXPECT_EQ(main.adc.scenario, source_dir() / "config" / "scenarios" / "joint_rotation_healthy.toml");
  EXPECT_TRUE(fs::exists(main.adc.scenario));
  struct Job {
    const char* file;
    std::uint32_t window_len;
  };
  for (const Job job : {Job{"10-joint_rotation.toml", 12800}, Job{"10-arc_welding.toml", 3200},
                        Job{"10-spot_welding.toml", 10240}}) {
    const DaemonConfig c = load_daemon_config(ex / "ptdad.toml", {ex / "ptdad.d" / job.file});
    EXPECT_EQ(c.pipeline.extraction.window_len, job.window_len) << job.file;
    EXPECT_TRUE(fs::exists(c.adc.scenario)) << c.adc.scenario;
  }
}

// `ptdad --check-config` (issue 17): syntax is not enough, every path must open.
TEST(DaemonConfigPaths, MissingBaselineAndRecordingAreProblemsNamingThePath) {
  const fs::path dir = scratch("config_paths");
  const fs::path baseline = dir / "missing.bin";
  DaemonConfig cfg = parse_daemon_config(sim_config(baseline, dir, "fast"), "t.toml");
  std::vector<std::string> p = check_config_paths(cfg, false);
  ASSERT_EQ(p.size(), 1U);
  EXPECT_NE(p[0].find("[daemon] baseline: " + baseline.string()), std::string::npos) << p[0];
  EXPECT_NE(p[0].find("refuses monitoring. Train one"), std::string::npos) << p[0];
  // Field training writes the baseline: its directory is what must exist.
  EXPECT_TRUE(check_config_paths(cfg, true).empty());
  cfg.daemon.baseline = dir / "no_such_dir" / "b.bin";
  p = check_config_paths(cfg, true);
  ASSERT_EQ(p.size(), 1U);
  EXPECT_NE(p[0].find("the directory " + (dir / "no_such_dir").string() + " does not exist"),
            std::string::npos)
      << p[0];
  // The windows' spill directory: the baseline's by default, else [training] spill_dir, which must exist.
  EXPECT_EQ(training_spill_dir(cfg), dir / "no_such_dir");
  cfg.daemon.baseline = dir / "b.bin";
  EXPECT_EQ(training_spill_dir(cfg), dir);
  cfg.training.output = dir / "out" / "trained.bin";
  EXPECT_EQ(training_spill_dir(cfg), dir / "out");
  cfg = parse_daemon_config(sim_config(baseline, dir, "fast") + "\n[training]\nspill_dir = \"" +
                                (dir / "no_spill").string() + "\"\n",
                            "t.toml");
  EXPECT_EQ(training_spill_dir(cfg), dir / "no_spill");
  p = check_config_paths(cfg, true);
  ASSERT_EQ(p.size(), 1U);
  EXPECT_EQ(p[0], "[training] spill_dir " + (dir / "no_spill").string() +
                      ": not a directory, so field training has nowhere to keep its windows");

  // A real baseline: no problem; then a replay of a recording that is not there.
  write_sim_baseline(baseline);
  cfg = parse_daemon_config(sim_config(baseline, dir, "fast"), "t.toml");
  EXPECT_TRUE(check_config_paths(cfg, false).empty());
  cfg.adc.backend = AdcBackend::kWav;
  cfg.adc.recording = dir / "no_recording";
  cfg.can.backend = CanBackend::kCandump;
  p = check_config_paths(cfg, false);
  ASSERT_EQ(p.size(), 1U);
  EXPECT_NE(p[0].find("[adc] recording: " + (dir / "no_recording").string()), std::string::npos) << p[0];
  cfg.adc.backend = AdcBackend::kSim;
  cfg.adc.scenario = dir / "no_scenario.toml";
  cfg.can.replay_file = dir / "no.log";
  p = check_config_paths(cfg, false);
  ASSERT_EQ(p.size(), 2U);
  EXPECT_NE(p[0].find("[adc] scenario: " + (dir / "no_scenario.toml").string()), std::string::npos) << p[0];
  EXPECT_NE(p[1].find("[can] replay_file " + (dir / "no.log").string() + " does not exist"),
            std::string::npos)
      << p[1];
}

}  // namespace
}  // namespace ptda::daemon::test
