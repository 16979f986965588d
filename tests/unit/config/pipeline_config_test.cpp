// Pipeline configuration: every key, defaults, located errors (line:column counted by hand in the
// inline TOML), drop-in order, ignored tables and the shipped examples.
#include "ptda/config/pipeline_config.hpp"

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "ptda/common/error.hpp"
#include "ptda/config/pipeline_config_builder.hpp"
#include "ptda/config/toml_reader.hpp"

namespace ptda::config {
namespace {

namespace fs = std::filesystem;

constexpr const char* kMinimal = "[extraction]\nwindow_len = 4096\n";

std::string error_of(std::string_view text, const std::vector<std::string>& ignored = {}) {
  try {
    (void)parse_pipeline_config(text, "cfg.toml", ignored);
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

fs::path temp_dir() {
  const char* env = std::getenv("PTDA_TEST_TMP");
  fs::path dir = (env != nullptr && *env != '\0') ? fs::path(env) : fs::temp_directory_path();
  dir /= "config_pipeline_config_test_" + std::to_string(::getpid());
  fs::create_directories(dir);
  return dir;
}

fs::path write_file(const fs::path& path, const std::string& text) {
  std::ofstream(path) << text;
  return path;
}

void expect_signal_eq(const SignalSpec& a, const SignalSpec& b) {
  EXPECT_EQ(a.start_byte, b.start_byte);
  EXPECT_EQ(a.length, b.length);
  EXPECT_EQ(a.little_endian, b.little_endian);
  EXPECT_EQ(a.is_signed, b.is_signed);
  EXPECT_EQ(a.scale, b.scale);
  EXPECT_EQ(a.offset, b.offset);
}

// Exact equality of every field (used for defaults and for the format round trip).
void expect_config_eq(const PipelineConfig& a, const PipelineConfig& b) {
  EXPECT_EQ(a.fs_hz, b.fs_hz);
  EXPECT_EQ(a.speed_latency_s, b.speed_latency_s);
  EXPECT_EQ(a.speed_frame.id, b.speed_frame.id);
  EXPECT_EQ(a.speed_frame.extended, b.speed_frame.extended);
  EXPECT_EQ(a.speed_frame.dlc, b.speed_frame.dlc);
  EXPECT_EQ(a.speed_frame.period_s, b.speed_frame.period_s);
  EXPECT_EQ(a.speed_frame.has_angle, b.speed_frame.has_angle);
  expect_signal_eq(a.speed_frame.speed, b.speed_frame.speed);
  expect_signal_eq(a.speed_frame.angle, b.speed_frame.angle);
  EXPECT_EQ(a.extraction.window_len, b.extraction.window_len);
  EXPECT_EQ(a.extraction.hop, b.extraction.hop);
  EXPECT_EQ(a.extraction.speed_tol_rel, b.extraction.speed_tol_rel);
  EXPECT_EQ(a.extraction.speed_tol_abs_rad_s, b.extraction.speed_tol_abs_rad_s);
  EXPECT_EQ(a.extraction.min_speed_rad_s, b.extraction.min_speed_rad_s);
  EXPECT_EQ(a.extraction.max_speed_rad_s, b.extraction.max_speed_rad_s);
  EXPECT_EQ(a.extraction.min_duration_s, b.extraction.min_duration_s);
  EXPECT_EQ(a.extraction.guard_s, b.extraction.guard_s);
  EXPECT_EQ(a.extraction.max_speed_gap_s, b.extraction.max_speed_gap_s);
  EXPECT_EQ(a.extraction.max_windows_per_region, b.extraction.max_windows_per_region);
  EXPECT_EQ(a.extraction.clip_abs, b.extraction.clip_abs);
  EXPECT_EQ(a.classes.speed_tol_rel, b.classes.speed_tol_rel);
  EXPECT_EQ(a.classes.speed_tol_abs_rad_s, b.classes.speed_tol_abs_rad_s);
  EXPECT_EQ(a.classes.min_regions, b.classes.min_regions);
  EXPECT_EQ(a.thresholds.kind, b.thresholds.kind);
  EXPECT_EQ(a.thresholds.false_alarm_rate, b.thresholds.false_alarm_rate);
  EXPECT_EQ(a.thresholds.margin, b.thresholds.margin);
  EXPECT_EQ(a.thresholds.confidence, b.thresholds.confidence);
  EXPECT_EQ(a.thresholds.holdout_fraction, b.thresholds.holdout_fraction);
  EXPECT_EQ(a.decision.k, b.decision.k);
  EXPECT_EQ(a.decision.n, b.decision.n);
  EXPECT_EQ(a.decision.sequential.enabled, b.decision.sequential.enabled);
  EXPECT_EQ(a.decision.sequential.k, b.decision.sequential.k);
  EXPECT_EQ(a.decision.sequential.h_warn, b.decision.sequential.h_warn);
  EXPECT_EQ(a.decision.sequential.h_alarm, b.decision.sequential.h_alarm);
  EXPECT_EQ(a.decision.sequential.step_cap, b.decision.sequential.step_cap);
  EXPECT_EQ(a.decision.band.step_cap, b.decision.band.step_cap);
  EXPECT_EQ(a.decision.mesh.step_cap, b.decision.mesh.step_cap);
  EXPECT_EQ(a.method, b.method);
  EXPECT_EQ(a.gearbox.kind, b.gearbox.kind);
  EXPECT_EQ(a.gearbox.z_in, b.gearbox.z_in);
  EXPECT_EQ(a.gearbox.z_spur, b.gearbox.z_spur);
  EXPECT_EQ(a.gearbox.z_pin, b.gearbox.z_pin);
  EXPECT_EQ(a.gearbox.ratio, b.gearbox.ratio);
}

// Every key with a value different from its default.
constexpr const char* kEveryKey = R"([acquisition]
fs_hz = 51200
[can]
speed_latency_s = 0.012
[can.speed_frame]
id = 0x18FF0184
extended = true
dlc = 6
period_s = 0.01
has_angle = true
[can.speed_frame.speed]
start_byte = 1
length = 2
byte_order = "big"
signed = false
scale = 0.001
offset = -30.5
[can.speed_frame.angle]
start_byte = 3
length = 3
byte_order = "little"
signed = true
scale = 2e-4
offset = 1.25
[extraction]
window_len = 10240
hop = 5120
speed_tol_rel = 0.03
speed_tol_abs_rad_s = 0.01
min_speed_rad_s = 0.2
max_speed_rad_s = 8
min_duration_s = 0.45
guard_s = 0.025
max_speed_gap_s = 0.02
max_windows_per_region = 2
clip_abs = 150.0
[classes]
speed_tol_rel = 0.1
speed_tol_abs_rad_s = 0.05
min_regions = 4
[thresholds]
method = "tolerance"
false_alarm_rate = 0.01
margin = 0.15
confidence = 0.95
holdout_fraction = 0.25
[decision]
k = 2
n = 7
sequential = "off"
cusum_k = 0.5
cusum_warn = 3.5
cusum_alarm = 9
cusum_step_cap = 1.5
band_cusum_step_cap = 4
[monitor]
method = "tda"
[gearbox]
kind = "cycloidal"
z_in = 28
z_spur = 23
z_pin = 40
)";

TEST(PipelineConfig, DefaultsWhenKeysAbsent) {
  const PipelineConfig cfg = parse_pipeline_config(kMinimal, "cfg.toml");
  PipelineConfig expected;
  expected.extraction.window_len = 4096;
  expect_config_eq(cfg, expected);
  // The documented defaults, spelled out (README "Keys").
  EXPECT_EQ(cfg.fs_hz, 0.0);
  EXPECT_EQ(cfg.speed_frame.id, 0x184U);
  EXPECT_FALSE(cfg.speed_frame.extended);
  EXPECT_EQ(cfg.speed_frame.dlc, 8);
  EXPECT_EQ(cfg.speed_frame.speed.scale, 1e-4);
  EXPECT_EQ(cfg.speed_frame.angle.start_byte, 4);
  EXPECT_EQ(cfg.speed_frame.angle.scale, 1e-5);
  EXPECT_EQ(cfg.speed_frame.period_s, 0.004);
  EXPECT_EQ(cfg.extraction.hop, 0U);
  EXPECT_EQ(cfg.decision.k, 3U);
  EXPECT_EQ(cfg.decision.n, 5U);
  EXPECT_EQ(cfg.thresholds.kind, dsp::ThresholdPolicy::Kind::kTolerance);
  EXPECT_EQ(cfg.thresholds.false_alarm_rate, 1e-3);
  EXPECT_EQ(cfg.thresholds.confidence, 0.9);
  EXPECT_EQ(cfg.thresholds.holdout_fraction, 0.0);
  EXPECT_TRUE(cfg.decision.sequential.enabled);
  EXPECT_EQ(cfg.decision.sequential.k, 1.0);
  EXPECT_EQ(cfg.decision.sequential.h_warn, 4.0);
  EXPECT_EQ(cfg.decision.sequential.h_alarm, 7.0);
  EXPECT_EQ(cfg.decision.sequential.step_cap, 2.5);  // session 38; the band CUSUM has none by default
  EXPECT_EQ(cfg.decision.band.step_cap, dsp::kNoStepCap);
  EXPECT_EQ(cfg.method, dsp::Method::kPtda);
  EXPECT_EQ(cfg.gearbox.kind, dsp::GearboxInfo::Kind::kUnknown);
  EXPECT_EQ(cfg.gearbox.ratio, 0.0);
}

TEST(PipelineConfig, ParsesEveryKey) {
  const PipelineConfig cfg = parse_pipeline_config(kEveryKey, "every.toml");
  EXPECT_EQ(cfg.fs_hz, 51200.0);
  EXPECT_EQ(cfg.speed_latency_s, 0.012);
  EXPECT_EQ(cfg.speed_frame.id, 0x18FF0184U);
  EXPECT_TRUE(cfg.speed_frame.extended);
  EXPECT_EQ(cfg.speed_frame.dlc, 6);
  EXPECT_EQ(cfg.speed_frame.period_s, 0.01);
  EXPECT_TRUE(cfg.speed_frame.has_angle);
  expect_signal_eq(cfg.speed_frame.speed, SignalSpec{1, 2, false, false, 0.001, -30.5});
  expect_signal_eq(cfg.speed_frame.angle, SignalSpec{3, 3, true, true, 2e-4, 1.25});
  EXPECT_EQ(cfg.extraction.window_len, 10240U);
  EXPECT_EQ(cfg.extraction.hop, 5120U);
  EXPECT_EQ(cfg.extraction.speed_tol_rel, 0.03);
  EXPECT_EQ(cfg.extraction.speed_tol_abs_rad_s, 0.01);
  EXPECT_EQ(cfg.extraction.min_speed_rad_s, 0.2);
  EXPECT_EQ(cfg.extraction.max_speed_rad_s, 8.0);  // integer literal accepted for a float key
  EXPECT_EQ(cfg.extraction.min_duration_s, 0.45);
  EXPECT_EQ(cfg.extraction.guard_s, 0.025);
  EXPECT_EQ(cfg.extraction.max_speed_gap_s, 0.02);
  EXPECT_EQ(cfg.extraction.max_windows_per_region, 2U);
  EXPECT_EQ(cfg.extraction.clip_abs, 150.0);
  EXPECT_EQ(cfg.classes.speed_tol_rel, 0.1);
  EXPECT_EQ(cfg.classes.speed_tol_abs_rad_s, 0.05);
  EXPECT_EQ(cfg.classes.min_regions, 4U);
  EXPECT_EQ(cfg.thresholds.kind, dsp::ThresholdPolicy::Kind::kTolerance);
  EXPECT_EQ(cfg.thresholds.false_alarm_rate, 0.01);
  EXPECT_EQ(cfg.thresholds.margin, 0.15);
  EXPECT_EQ(cfg.thresholds.confidence, 0.95);
  EXPECT_EQ(cfg.thresholds.holdout_fraction, 0.25);
  EXPECT_EQ(cfg.decision.k, 2U);
  EXPECT_EQ(cfg.decision.n, 7U);
  EXPECT_FALSE(cfg.decision.sequential.enabled);
  EXPECT_EQ(cfg.decision.sequential.k, 0.5);
  EXPECT_EQ(cfg.decision.sequential.h_warn, 3.5);
  EXPECT_EQ(cfg.decision.sequential.h_alarm, 9.0);
  EXPECT_EQ(cfg.decision.sequential.step_cap, 1.5);
  EXPECT_EQ(cfg.decision.band.step_cap, 4.0);
  EXPECT_EQ(cfg.method, dsp::Method::kTda);
  EXPECT_EQ(cfg.gearbox.kind, dsp::GearboxInfo::Kind::kCycloidal);
  EXPECT_EQ(cfg.gearbox.z_in, 28U);
  EXPECT_EQ(cfg.gearbox.z_spur, 23U);
  EXPECT_EQ(cfg.gearbox.z_pin, 40U);
  // eq. 1: 1 + 23/28 * 40 = 1 + 920/28 = 33.857142857... (paper: R = 33.86).
  EXPECT_NEAR(cfg.gearbox.ratio, 33.857142857142857, 1e-12);
}

TEST(PipelineConfig, FormatRoundTrips) {
  const PipelineConfig cfg = parse_pipeline_config(kEveryKey, "every.toml");
  const std::string text = format_pipeline_config(cfg);
  expect_config_eq(parse_pipeline_config(text, "formatted.toml"), cfg);
  const PipelineConfig minimal = parse_pipeline_config(kMinimal, "cfg.toml");
  expect_config_eq(parse_pipeline_config(format_pipeline_config(minimal), "formatted.toml"), minimal);
  EXPECT_NE(text.find("id = 0x18FF0184\n"), std::string::npos) << text;
  EXPECT_NE(text.find("ratio = 33.857142857142854\n"), std::string::npos) << text;
}

TEST(PipelineConfig, IntegerBasesAndMethods) {
  // TOML hex, octal (0o604 = 388 = 0x184) and binary integers all work for ids.
  EXPECT_EQ(parse_pipeline_config("[can.speed_frame]\nid = 0o604\n[extraction]\nwindow_len = 4096\n", "c")
                .speed_frame.id,
            0x184U);
  EXPECT_EQ(parse_pipeline_config("[can.speed_frame]\nid = 0b111\n[extraction]\nwindow_len = 4096\n", "c")
                .speed_frame.id,
            7U);
  EXPECT_EQ(
      parse_pipeline_config("[monitor]\nmethod = \"raw\"\n[extraction]\nwindow_len = 4096\n", "c").method,
      dsp::Method::kRaw);
  // Dotted keys at the top level are the same tables.
  const PipelineConfig dotted =
      parse_pipeline_config("extraction.window_len = 3200\ndecision.k = 1\ndecision.n = 1\n", "c");
  EXPECT_EQ(dotted.extraction.window_len, 3200U);
  EXPECT_EQ(dotted.decision.k, 1U);
}

TEST(PipelineConfig, GearboxRatio) {
  const auto ratio = [](const std::string& gearbox) {
    return parse_pipeline_config(std::string(kMinimal) + "[gearbox]\n" + gearbox, "c").gearbox.ratio;
  };
  EXPECT_EQ(ratio("kind = \"parallel\"\nz_in = 20\nz_spur = 50\n"), 2.5);  // driven / driving
  EXPECT_EQ(ratio("kind = \"parallel\"\n"), 0.0);                          // teeth unknown
  EXPECT_EQ(ratio("kind = \"cycloidal\"\nratio = 81\n"), 81.0);            // explicit, no teeth
  EXPECT_EQ(ratio("ratio = 12.5\n"), 12.5);                                // kind unknown
  // The paper's rounded R = 33.86 agrees with eq. 1 within 0.1 % and is kept as written.
  EXPECT_EQ(ratio("kind = \"cycloidal\"\nz_in = 28\nz_spur = 23\nz_pin = 40\nratio = 33.86\n"), 33.86);
  EXPECT_EQ(cycloidal_ratio(28, 23, 40), 1.0 + 23.0 / 28.0 * 40.0);
  EXPECT_EQ(cycloidal_ratio(0, 23, 40), 0.0);
}

TEST(PipelineConfigErrors, UnknownKeysAndTables) {
  EXPECT_EQ(
      error_of("[extraction]\nwindow_len = 4096\nwindwo = 3\n"),
      "cfg.toml:3:1: unknown key 'windwo' in [extraction] (known: window_len, hop, speed_tol_rel, "
      "speed_tol_abs_rad_s, min_speed_rad_s, max_speed_rad_s, min_duration_s, guard_s, max_speed_gap_s, "
      "max_windows_per_region, clip_abs, domain, samples_per_rev, revolutions, speed_band_rel, "
      "anti_alias_half_taps, anti_alias_cutoff, min_shaft_hz, can_time_smoothing_frames, speed_law)");
  EXPECT_EQ(error_of("[extration]\nwindow_len = 4096\n"),
            "cfg.toml:1:2: unknown table 'extration' at the top level (known: acquisition, can, extraction, "
            "classes, thresholds, decision, monitor, gearbox)");
  EXPECT_EQ(
      error_of("fs_hz = 25600\n[extraction]\nwindow_len = 4096\n"),
      "cfg.toml:1:1: unknown key 'fs_hz' at the top level (known: acquisition, can, extraction, classes, "
      "thresholds, decision, monitor, gearbox)");
  // Nested: the key's own column.
  EXPECT_EQ(error_of("[extraction]\nwindow_len = 4096\n[can.speed_frame.speed]\n  lenght = 2\n"),
            "cfg.toml:4:3: unknown key 'lenght' in [can.speed_frame.speed] (known: start_byte, length, "
            "byte_order, little_endian, "
            "signed, scale, offset)");
}

TEST(PipelineConfigErrors, IgnoredTables) {
  const std::string text = std::string(kMinimal) + "[daemon]\nrt_priority = 80\n[alarm]\ngpio = 17\n";
  EXPECT_EQ(
      error_of(text),
      "cfg.toml:3:2: unknown table 'daemon' at the top level (known: acquisition, can, extraction, classes, "
      "thresholds, decision, monitor, gearbox)");
  EXPECT_EQ(error_of(text, {"daemon", "alarm"}), "(no error)");
  EXPECT_EQ(
      error_of(text, {"daemon"}),
      "cfg.toml:5:2: unknown table 'alarm' at the top level (known: daemon, acquisition, can, extraction, "
      "classes, thresholds, decision, monitor, gearbox)");
}

TEST(PipelineConfigErrors, IgnoredKeysInsidePipelineTables) {
  // The daemon may keep its own keys in a pipeline table, e.g. the CAN interface name in [can].
  const std::string text = std::string(kMinimal) + "[can]\ninterface = \"can0\"\nspeed_latency_s = 0.002\n";
  EXPECT_EQ(error_of(text),
            "cfg.toml:4:1: unknown key 'interface' in [can] (known: speed_latency_s, speed_frame)");
  EXPECT_EQ(error_of(text, {"can.interface"}), "(no error)");
  EXPECT_EQ(parse_pipeline_config(text, "cfg.toml", {"can.interface"}).speed_latency_s, 0.002);
  // A dotted name only covers its own table: "interface" at the top level is still unknown there.
  EXPECT_EQ(
      error_of("interface = 1\n" + std::string(kMinimal), {"can.interface"}),
      "cfg.toml:1:1: unknown key 'interface' at the top level (known: acquisition, can, extraction, classes, "
      "thresholds, decision, monitor, gearbox)");
  EXPECT_EQ(error_of(std::string(kMinimal) + "[can.speed_frame.speed]\nunit = \"rad/s\"\n",
                     {"can.speed_frame.speed.unit"}),
            "(no error)");
}

TEST(PipelineConfigErrors, WrongTypes) {
  // Value columns: `fs_hz = "25600"` -> the string starts at column 9.
  EXPECT_EQ(error_of("[acquisition]\nfs_hz = \"25600\"\n"),
            "cfg.toml:2:9: acquisition.fs_hz must be a number, not a string");
  EXPECT_EQ(error_of("[extraction]\nwindow_len = 4096.0\n"),
            "cfg.toml:2:14: extraction.window_len must be an integer, not a float");
  EXPECT_EQ(error_of("[extraction]\nwindow_len = 4096\n[can.speed_frame]\nextended = 1\n"),
            "cfg.toml:4:12: can.speed_frame.extended must be a boolean (true/false), not an integer");
  EXPECT_EQ(error_of("[extraction]\nwindow_len = 4096\n[monitor]\nmethod = 2\n"),
            "cfg.toml:4:10: monitor.method must be a string, not an integer");
  EXPECT_EQ(error_of("can = 3\n"), "cfg.toml:1:7: can must be a table, not an integer");
  EXPECT_EQ(error_of("[acquisition]\nfs_hz = nan\n"),
            "cfg.toml:2:9: acquisition.fs_hz must be a finite number");
  EXPECT_EQ(error_of("[[extraction]]\nwindow_len = 4096\n"),
            "cfg.toml:1:1: extraction must be a table, not an array");
  EXPECT_EQ(error_of("[extraction]\nwindow_len = [4096]\n"),
            "cfg.toml:2:14: extraction.window_len must be an integer, not an array");
  // Inline tables are ordinary tables.
  EXPECT_EQ(parse_pipeline_config("extraction = { window_len = 3200, hop = 1600 }\n", "c").extraction.hop,
            1600U);
}

TEST(PipelineConfigErrors, OutOfRangeValues) {
  EXPECT_EQ(error_of("[acquisition]\nfs_hz = 250000\n"),
            "cfg.toml:2:9: acquisition.fs_hz = 250000 is outside 0..200000");
  EXPECT_EQ(error_of("[acquisition]\nfs_hz = 0.5\n"),
            "cfg.toml:2:9: acquisition.fs_hz must be 0 (take the recording's rate) or 1..200000");
  EXPECT_EQ(error_of("[decision]\nk = 0\n"), "cfg.toml:2:5: decision.k = 0 is outside 1..64");
  EXPECT_EQ(error_of("[decision]\nn = 65\n"), "cfg.toml:2:5: decision.n = 65 is outside 1..64");
  EXPECT_EQ(error_of("[thresholds]\nfalse_alarm_rate = 0.5\n"),
            "cfg.toml:2:20: thresholds.false_alarm_rate must be > 0 and < 0.5");
  EXPECT_EQ(error_of("[thresholds]\nconfidence = 1.0\n"),
            "cfg.toml:2:14: thresholds.confidence must be > 0.5 and < 1");
  EXPECT_EQ(error_of("[thresholds]\nholdout_fraction = 0.95\n"),
            "cfg.toml:2:20: thresholds.holdout_fraction = 0.95 is outside 0..0.9");
  EXPECT_EQ(error_of("[decision]\ncusum_k = 0\n"), "cfg.toml:2:11: decision.cusum_k must be > 0");
  EXPECT_EQ(error_of("[decision]\nsequential = \"ewma\"\n"),
            "cfg.toml:2:14: decision.sequential must be one of \"cusum\", \"off\", not \"ewma\"");
  EXPECT_EQ(error_of("[extraction]\nwindow_len = 4096\n[decision]\ncusum_warn = 8\n"),
            "cfg.toml:4:14: [decision] cusum_warn = 8.0 must not exceed cusum_alarm = 7.0");
  EXPECT_EQ(error_of("[thresholds]\nfalse_alarm_rate = 0\n"),
            "cfg.toml:2:20: thresholds.false_alarm_rate must be > 0 and < 0.5");
  EXPECT_EQ(error_of("[extraction]\nwindow_len = 0\n"),
            "cfg.toml:2:14: extraction.window_len = 0 is outside 4..16777216");
  // 4094 = 2 * 23 * 89 is not a KissFFT fast length.
  EXPECT_EQ(
      error_of("[extraction]\nwindow_len = 4094\n"),
      "cfg.toml:2:14: extraction.window_len = 4094 is not an FFT length: it must be even with prime factors "
      "2, 3 and 5 only (e.g. 3200, 4096, 10240, 12800)");
  EXPECT_EQ(error_of("[extraction]\nwindow_len = 4096\nmax_speed_gap_s = 0\n"),
            "cfg.toml:3:19: extraction.max_speed_gap_s must be > 0");
  EXPECT_EQ(error_of("[extraction]\nwindow_len = 4096\n[can.speed_frame]\ndlc = 9\n"),
            "cfg.toml:4:7: can.speed_frame.dlc = 9 is outside 1..8");
  EXPECT_EQ(error_of("[extraction]\nwindow_len = 4096\n[can.speed_frame.angle]\nscale = 0.0\n"),
            "cfg.toml:4:9: can.speed_frame.angle.scale must not be 0");
  EXPECT_EQ(error_of("[thresholds]\nmethod = \"median\"\n"),
            "cfg.toml:2:10: thresholds.method must be one of \"gaussian\", \"quantile\", \"tolerance\", not "
            "\"median\"");
  EXPECT_EQ(
      error_of("[extraction]\nwindow_len = 4096\n[can.speed_frame.speed]\nbyte_order = \"motorola\"\n"),
      "cfg.toml:4:14: can.speed_frame.speed.byte_order must be one of \"little\", \"big\", not \"motorola\"");
  EXPECT_EQ(error_of("[extraction]\nwindow_len = -4096\n"),
            "cfg.toml:2:14: extraction.window_len = -4096 is outside 4..16777216");
}

TEST(PipelineConfigErrors, SyntaxErrorsAreLocated) {
  const std::string e = error_of("[extraction]\nwindow_len = 4096 x\n");
  EXPECT_EQ(e.rfind("cfg.toml:2:19: TOML syntax error: ", 0), 0U) << e;
  // A repeated key: toml++ reports it where it notices, after the '=' of the second k (3:5).
  EXPECT_EQ(
      error_of("[decision]\nk = 1\nk = 2\n"),
      "cfg.toml:3:5: TOML syntax error: Error while parsing key-value pair: cannot redefine existing integer "
      "'k'");
}

TEST(PipelineConfigErrors, CrossKeyChecksPointAtTheKey) {
  EXPECT_EQ(
      error_of("[acquisition]\nfs_hz = 25600\n"),
      "cfg.toml: [extraction] window_len is required: the window length in samples (only factors 2, 3, 5; it "
      "must fit inside the job's constant-speed plateau)");
  EXPECT_EQ(error_of("[extraction]\nwindow_len = 4096\n[decision]\nk = 6\n"),
            "cfg.toml:4:5: [decision] k = 6 must not exceed n = 5 (alarm when k of the last n windows are "
            "abnormal)");
  EXPECT_EQ(error_of("[extraction]\nwindow_len = 4096\nmin_speed_rad_s = 2\nmax_speed_rad_s = 1.5\n"),
            "cfg.toml:4:19: [extraction] min_speed_rad_s (2.0) must be below max_speed_rad_s (1.5)");
  EXPECT_EQ(error_of("[extraction]\nwindow_len = 4096\nspeed_tol_rel = 0\nspeed_tol_abs_rad_s = 0\n"),
            "cfg.toml:4:23: [extraction] speed_tol_rel and speed_tol_abs_rad_s are both 0: no speed would "
            "ever count "
            "as constant");
  EXPECT_EQ(
      error_of("[extraction]\nwindow_len = 4096\n[classes]\nspeed_tol_rel = 0\nspeed_tol_abs_rad_s = 0\n"),
      "cfg.toml:5:23: [classes] speed_tol_rel and speed_tol_abs_rad_s are both 0: no two regions would share "
      "a class");
}

TEST(PipelineConfigErrors, SpeedFrameConsistency) {
  EXPECT_EQ(error_of("[extraction]\nwindow_len = 4096\n[can.speed_frame]\nid = 0x800\n"),
            "cfg.toml:4:6: [can.speed_frame] id 2048 does not fit a 11-bit standard identifier (max 2047)");
  // The default angle (bytes 4..7) no longer fits a 4-byte frame: the dlc is what changed.
  EXPECT_EQ(error_of("[extraction]\nwindow_len = 4096\n[can.speed_frame]\ndlc = 4\n"),
            "cfg.toml:4:7: [can.speed_frame] angle signal (bytes 4..7, dlc 4): bytes extend beyond the "
            "frame's dlc");
  EXPECT_EQ(error_of("[extraction]\nwindow_len = 4096\n[can.speed_frame]\ndlc = 4\nhas_angle = false\n"),
            "(no error)");
  // A signal's own length is at fault when it was written.
  EXPECT_EQ(
      error_of("[extraction]\nwindow_len = 4096\n[can.speed_frame.speed]\nlength = 6\n"),
      "cfg.toml:4:10: [can.speed_frame] speed signal (bytes 0..5) and angle signal (bytes 4..7) overlap");
}

TEST(PipelineConfigErrors, Gearbox) {
  const std::string base = std::string(kMinimal) + "[gearbox]\n";  // [gearbox] is line 3
  EXPECT_EQ(error_of(base + "kind = \"cycloidal\"\nz_in = 28\nz_spur = 23\nz_pin = 40\nratio = 30\n"),
            "cfg.toml:8:9: [gearbox] ratio = 30.0 disagrees with the teeth: 1 + z_spur/z_in * z_pin = "
            "33.857142857142854 (remove one of them)");
  EXPECT_EQ(
      error_of(base + "kind = \"cycloidal\"\nz_in = 28\nz_spur = 23\n"),
      "cfg.toml:4:8: [gearbox] a cycloidal gearbox needs z_in, z_spur and z_pin > 0 (eq. 1) or an explicit "
      "ratio; z_pin is 0");
  EXPECT_EQ(error_of(base + "z_in = 28\n"),
            "cfg.toml:4:8: [gearbox] z_in is given but kind is \"unknown\": set kind = \"cycloidal\" or "
            "\"parallel\"");
  EXPECT_EQ(error_of(base + "kind = \"parallel\"\nz_in = 20\nz_spur = 50\nz_pin = 3\n"),
            "cfg.toml:7:9: [gearbox] z_pin must be 0 for a parallel gearbox (it has no pins)");
  EXPECT_EQ(error_of(base + "kind = \"parallel\"\nz_spur = 50\n"),
            "cfg.toml:5:10: [gearbox] a parallel gearbox needs both z_in (driving) and z_spur (driven), or "
            "neither");
  EXPECT_EQ(error_of(base + "kind = \"planetary\"\n"),
            "cfg.toml:4:8: gearbox.kind must be one of \"cycloidal\", \"parallel\", \"unknown\", not "
            "\"planetary\"");
}

class PipelineConfigFiles : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = temp_dir(); }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(PipelineConfigFiles, DropInsOverrideKeyByKeyInOrder) {
  const auto base = write_file(dir_ / "base.toml",
                               "[extraction]\nwindow_len = 4096\nhop = 2048\n[decision]\nk = 3\nn = 5\n");
  const auto a = write_file(dir_ / "10-a.toml", "[decision]\nk = 4\n[monitor]\nmethod = \"tda\"\n");
  const auto b = write_file(dir_ / "20-b.toml", "[decision]\nk = 2\nn = 8\n");

  const PipelineConfig only_base = load_pipeline_config(base);
  EXPECT_EQ(only_base.decision.k, 3U);
  EXPECT_EQ(only_base.method, dsp::Method::kPtda);

  const PipelineConfig ab = load_pipeline_config(base, {a, b});
  EXPECT_EQ(ab.decision.k, 2U);  // b wins over a
  EXPECT_EQ(ab.decision.n, 8U);
  EXPECT_EQ(ab.method, dsp::Method::kTda);  // from a, untouched by b
  EXPECT_EQ(ab.extraction.window_len, 4096U);
  EXPECT_EQ(ab.extraction.hop, 2048U);  // from base, untouched by drop-ins

  const PipelineConfig ba = load_pipeline_config(base, {b, a});
  EXPECT_EQ(ba.decision.k, 4U);  // a applied last
  EXPECT_EQ(ba.decision.n, 8U);
}

TEST_F(PipelineConfigFiles, CrossChecksRunOnTheMergedResult) {
  // The base alone is inconsistent (k > n); the drop-in fixes it.
  const auto base = write_file(dir_ / "base.toml", "[extraction]\nwindow_len = 4096\n[decision]\nk = 6\n");
  const auto fix = write_file(dir_ / "fix.toml", "[decision]\nn = 8\n");
  EXPECT_EQ(load_pipeline_config(base, {fix}).decision.k, 6U);
  // A drop-in that breaks it is named with its own line and column.
  const auto ok = write_file(dir_ / "ok.toml", "[extraction]\nwindow_len = 4096\n");
  const auto bad = write_file(dir_ / "bad.toml", "# raise k\n[decision]\nk = 9\n");
  try {
    (void)load_pipeline_config(ok, {bad});
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()),
              bad.string() +
                  ":3:5: [decision] k = 9 must not exceed n = 5 (alarm when k of the last n "
                  "windows are abnormal)");
  }
}

TEST_F(PipelineConfigFiles, MissingWindowLenNamesTheMainFile) {
  const auto base = write_file(dir_ / "main.toml", "[decision]\nk = 2\n");
  const auto d = write_file(dir_ / "10-d.toml", "[decision]\nn = 4\n");
  try {
    (void)load_pipeline_config(base, {d});
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind(base.string() + ": [extraction] window_len is required", 0), 0U)
        << e.what();
  }
}

TEST_F(PipelineConfigFiles, ErrorsNameTheFileTheyAreIn) {
  const auto base = write_file(dir_ / "base.toml", "[extraction]\nwindow_len = 4096\n");
  const auto typo = write_file(dir_ / "typo.toml", "\n\n[decison]\nk = 1\n");
  const auto syntax = write_file(dir_ / "syntax.toml", "[decision]\nk = = 1\n");
  try {
    (void)load_pipeline_config(base, {typo});
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind(typo.string() + ":3:2: unknown table 'decison'", 0), 0U)
        << e.what();
  }
  try {
    (void)load_pipeline_config(base, {syntax});
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind(syntax.string() + ":2:5: TOML syntax error", 0), 0U) << e.what();
  }
  const fs::path missing = dir_ / "missing.toml";
  try {
    (void)load_pipeline_config(base, {missing});
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()),
              missing.string() + ": cannot open configuration file: No such file or directory");
  }
}

TEST_F(PipelineConfigFiles, IgnoredTablesWithDropIns) {
  const auto base = write_file(dir_ / "ptdad.toml", "[daemon]\nrt = 1\n[extraction]\nwindow_len = 3200\n");
  const auto d = write_file(dir_ / "10.toml", "[adc]\ndevice = \"x\"\n[decision]\nk = 1\n");
  EXPECT_THROW((void)load_pipeline_config(base, {d}), Error);
  const PipelineConfig cfg = load_pipeline_config(base, {d}, {"daemon", "adc"});
  EXPECT_EQ(cfg.extraction.window_len, 3200U);
  EXPECT_EQ(cfg.decision.k, 1U);
}

TEST(PipelineConfigBuilderApi, DaemonCanReuseReaderForItsOwnTables) {
  // What the daemon does: one parse, its own tables through TableReader, the rest through the builder.
  const toml::table root = parse_toml(
      "[daemon]\nrt_priority = 80\nname = \"ptdad\"\n[extraction]\nwindow_len = 4096\n", "ptdad.toml");
  PipelineConfigBuilder builder({"daemon"});
  builder.apply(root, "ptdad.toml");
  EXPECT_EQ(builder.finish().extraction.window_len, 4096U);

  TableReader top(root, "", "ptdad.toml");
  const toml::table* daemon = top.table("daemon");
  ASSERT_NE(daemon, nullptr);
  TableReader r(*daemon, "daemon", "ptdad.toml");
  std::uint32_t prio = 0;
  EXPECT_TRUE(r.read("rt_priority", prio, 1, 99));
  EXPECT_EQ(prio, 80U);
  std::string absent = "keep";
  EXPECT_FALSE(r.read("missing", absent));
  EXPECT_EQ(absent, "keep");
  try {
    r.finish();
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()),
              "ptdad.toml:3:1: unknown key 'name' in [daemon] (known: rt_priority, missing)");
  }
  r.ignore("name");
  EXPECT_NO_THROW(r.finish());
}

TEST(PipelineConfigExamples, EveryExampleParses) {
  const fs::path dir = fs::path(PTDA_SOURCE_DIR) / "config" / "examples";
  const auto load = [&](const char* name) { return load_pipeline_config(dir / name); };

  const PipelineConfig joint = load("joint_rotation.toml");
  EXPECT_EQ(joint.fs_hz, 25600.0);
  EXPECT_EQ(joint.extraction.window_len, 12800U);
  EXPECT_NEAR(joint.gearbox.ratio, 33.857142857142857, 1e-12);
  // The explicit speed frame in the example is the built-in default.
  expect_signal_eq(joint.speed_frame.speed, SpeedFrameSpec{}.speed);
  expect_signal_eq(joint.speed_frame.angle, SpeedFrameSpec{}.angle);
  EXPECT_EQ(joint.speed_frame.id, 0x184U);

  const PipelineConfig arc = load("arc_welding.toml");
  EXPECT_EQ(arc.extraction.window_len, 3200U);
  EXPECT_EQ(arc.fs_hz, 25600.0);
  const PipelineConfig spot = load("spot_welding.toml");
  EXPECT_EQ(spot.extraction.window_len, 10240U);

  // Each robot example's window (plus guard) must fit its min_duration, which must fit the plateau
  // the paper reports (0.6 s, 0.14 s, 0.48 s).
  const auto check_fit = [](const PipelineConfig& c, double plateau_s) {
    const double window_s = c.extraction.window_len / c.fs_hz;
    EXPECT_LE(window_s + c.extraction.guard_s, c.extraction.min_duration_s);
    EXPECT_LT(c.extraction.min_duration_s, plateau_s);
  };
  check_fit(joint, 0.6);
  check_fit(arc, 0.14);
  check_fit(spot, 0.48);

  const PipelineConfig gfd = load("gfd.toml");
  EXPECT_EQ(gfd.fs_hz, 0.0);
  EXPECT_EQ(gfd.extraction.window_len, 4096U);
  EXPECT_EQ(gfd.extraction.hop, 4096U);
  EXPECT_EQ(gfd.gearbox.kind, dsp::GearboxInfo::Kind::kParallel);
  EXPECT_EQ(gfd.gearbox.ratio, 0.0);

  // The effective configuration of each example parses back to the same values.
  for (const PipelineConfig* c : {&joint, &arc, &spot, &gfd}) {
    expect_config_eq(parse_pipeline_config(format_pipeline_config(*c), "formatted.toml"), *c);
  }
}

// Issue 14 item 8: as root, a configuration file (or drop-in) others can write is refused, saying how
// to fix it (common/file_check.hpp tests both sides with an injected euid).
TEST(PipelineConfigPermissions, GroupWritableConfigIsRefusedAsRoot) {
  if (::geteuid() != 0) GTEST_SKIP() << "needs euid 0 (FileCheckTest covers the check with an injected euid)";
  const fs::path dir = temp_dir();
  const fs::path base = write_file(dir / "writable.toml", "[extraction]\nwindow_len = 4096\n");
  ASSERT_EQ(::chmod(base.c_str(), 0664), 0);
  try {
    (void)load_pipeline_config(base);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()),
              base.string() +
                  ": configuration file is group-writable (mode 0664) and ptda runs as root: another user "
                  "could change what it does. Fix: chmod go-w " +
                  base.string());
  }
  ASSERT_EQ(::chmod(base.c_str(), 0644), 0);
  EXPECT_NO_THROW((void)load_pipeline_config(base));
  fs::remove_all(dir);
}

// One CAN frame schema (issue 17): `byte_order` is the spelling; the scenarios' old `little_endian`
// is accepted for one release with a warning naming file:line:column, and a pair that disagrees is an
// error at the deprecated key.
TEST(SpeedFrameSchema, DeprecatedLittleEndianIsAcceptedWithAWarningNamingFileLine) {
  const PipelineConfig cfg = parse_pipeline_config(std::string(kMinimal) +
                                                       "[can.speed_frame.speed]\n"
                                                       "little_endian = false\n"
                                                       "[can.speed_frame.angle]\n"
                                                       "byte_order = \"big\"\n",
                                                   "cfg.toml");
  EXPECT_FALSE(cfg.speed_frame.speed.little_endian);
  EXPECT_FALSE(cfg.speed_frame.angle.little_endian);
  ASSERT_EQ(cfg.warnings.size(), 1U);
  EXPECT_EQ(cfg.warnings[0],
            "cfg.toml:4:1: can.speed_frame.speed.little_endian = false is deprecated (accepted until the "
            "next release): write byte_order = \"big\" instead, the spelling shared by pipeline "
            "configurations and simulator scenarios");
  EXPECT_TRUE(parse_pipeline_config(std::string(kMinimal) + "[can.speed_frame.speed]\nbyte_order = "
                                                            "\"little\"\n",
                                    "cfg.toml")
                  .warnings.empty());
}

TEST(SpeedFrameSchema, ConflictingByteOrderAndLittleEndianIsAnError) {
  EXPECT_EQ(error_of(std::string(kMinimal) +
                     "[can.speed_frame.angle]\nbyte_order = \"big\"\nlittle_endian = true\n"),
            "cfg.toml:5:1: can.speed_frame.angle.little_endian = true contradicts byte_order = \"big\" in "
            "the same table: delete little_endian (deprecated) and keep the right byte_order");
  // Agreeing: accepted, still a deprecation warning.
  const PipelineConfig cfg = parse_pipeline_config(
      std::string(kMinimal) + "[can.speed_frame.angle]\nbyte_order = \"big\"\nlittle_endian = false\n",
      "cfg.toml");
  EXPECT_FALSE(cfg.speed_frame.angle.little_endian);
  EXPECT_EQ(cfg.warnings.size(), 1U);
}

// The band CUSUM's keys: on by default since session 13 (time domain, PTDA) but not required, required
// when said, parsed and carried to training's policy when on, every bad value located at its key.
TEST(PipelineConfigBandCusum, KeysParseAndReachTraining) {
  const PipelineConfig def = parse_pipeline_config("[extraction]\nwindow_len = 4096\n", "cfg.toml");
  EXPECT_TRUE(def.decision.band.enabled);
  EXPECT_FALSE(def.decision.band.required);
  EXPECT_EQ(def.thresholds.band_count, 32U);  // training stores the band statistics by default
  EXPECT_EQ(def.decision.band.k, 1.0);
  EXPECT_EQ(def.decision.band.h, 10.0);
  EXPECT_EQ(def.decision.band.band_count, 32U);
  const PipelineConfig off =
      parse_pipeline_config("[extraction]\nwindow_len = 4096\n[decision]\nband_cusum = false\n", "cfg.toml");
  EXPECT_FALSE(off.decision.band.enabled);
  EXPECT_FALSE(off.decision.band.required);
  EXPECT_EQ(off.thresholds.band_count, 0U);
  // By default it is off where it cannot run: TDA/raw, and windows too short for 32 bands.
  const PipelineConfig tda =
      parse_pipeline_config("[extraction]\nwindow_len = 4096\n[monitor]\nmethod = \"tda\"\n", "cfg.toml");
  EXPECT_FALSE(tda.decision.band.enabled);
  EXPECT_EQ(tda.thresholds.band_count, 0U);
  const PipelineConfig shortw = parse_pipeline_config("[extraction]\nwindow_len = 32\n", "cfg.toml");
  EXPECT_FALSE(shortw.decision.band.enabled);
  // Said explicitly, another method is an error at its key.
  EXPECT_EQ(
      error_of(
          "[extraction]\nwindow_len = 4096\n[decision]\nband_cusum = true\n[monitor]\nmethod = \"raw\"\n"),
      "cfg.toml:6:10: [decision] band_cusum = true needs [monitor] method = \"ptda\" (the band statistics "
      "are those of the PTDA residual), got \"raw\": set band_cusum = false or method = \"ptda\"");
  const PipelineConfig on = parse_pipeline_config(
      "[extraction]\nwindow_len = 4096\n[decision]\nband_cusum = true\nband_cusum_k = 1.5\nband_cusum_h = "
      "12\n"
      "band_cusum_day_allowance = 1\nband_count = 16\n",
      "cfg.toml");
  EXPECT_TRUE(on.decision.band.enabled);
  EXPECT_TRUE(on.decision.band.required);
  EXPECT_EQ(on.decision.band.k, 1.5);
  EXPECT_EQ(on.decision.band.h, 12.0);
  EXPECT_EQ(on.decision.band.day_allowance, 1.0);
  EXPECT_EQ(on.decision.band.band_count, 16U);
  EXPECT_EQ(on.thresholds.band_count, 16U);  // training computes 16 bands' statistics
  // The formatted configuration reads back the same.
  const PipelineConfig back = parse_pipeline_config(format_pipeline_config(on), "formatted.toml");
  EXPECT_TRUE(back.decision.band.enabled);
  EXPECT_EQ(back.decision.band.k, 1.5);
  EXPECT_EQ(back.decision.band.h, 12.0);
  EXPECT_EQ(back.decision.band.day_allowance, 1.0);
  EXPECT_EQ(back.thresholds.band_count, 16U);
}

TEST(PipelineConfigBandCusum, BadValuesAreLocated) {
  EXPECT_EQ(error_of("[decision]\nband_cusum_k = 0\n"), "cfg.toml:2:16: decision.band_cusum_k must be > 0");
  EXPECT_EQ(error_of("[decision]\nband_cusum_h = 2000\n"),
            "cfg.toml:2:16: decision.band_cusum_h = 2000 is outside 0..1000");
  EXPECT_EQ(error_of("[decision]\nband_count = 65\n"),
            "cfg.toml:2:14: decision.band_count = 65 is outside 1..64");
  EXPECT_EQ(error_of("[decision]\nband_cusum_day_allowance = 11\n"),
            "cfg.toml:2:28: decision.band_cusum_day_allowance = 11 is outside 0..10");
  // The step caps (session 38): > 0 and at most 1000 (no cap).
  EXPECT_EQ(error_of("[decision]\nband_cusum_step_cap = 1001\n"),
            "cfg.toml:2:23: decision.band_cusum_step_cap = 1001 is outside 0..1000");
  EXPECT_EQ(error_of("[decision]\ncusum_step_cap = 0\n").rfind("cfg.toml:2:18: decision.cusum_step_cap", 0),
            0U)
      << error_of("[decision]\ncusum_step_cap = 0\n");
  EXPECT_EQ(error_of("[decision]\nmesh_cusum_step_cap = -2\n"),
            "cfg.toml:2:23: decision.mesh_cusum_step_cap = -2 is outside 0..1000");
  EXPECT_EQ(error_of("[decision]\nband_cusum = 1\n").rfind("cfg.toml:2:14: decision.band_cusum", 0), 0U)
      << error_of("[decision]\nband_cusum = 1\n");
  EXPECT_EQ(error_of("[extraction]\nwindow_len = 32\n[decision]\nband_cusum = true\nband_count = 32\n"),
            "cfg.toml:5:14: [decision] band_count = 32 needs at least one bin per band: must not exceed "
            "window_len / 2 = 16");
}

TEST(PipelineConfigMeshCusum, OnByDefaultWhereItCanRunAndAskedForNeedsTheGearboxAndTheTimeDomain) {
  // Without tooth counts the default-on detector has no mesh frequency: off, with the reason.
  const PipelineConfig def = parse_pipeline_config("[extraction]\nwindow_len = 4096\n", "cfg.toml");
  EXPECT_FALSE(def.decision.mesh.enabled);
  EXPECT_FALSE(def.decision.mesh.required);
  EXPECT_FALSE(def.thresholds.mesh_stats);
  EXPECT_EQ(def.mesh_off_reason.rfind("no gearbox teeth", 0), 0U) << def.mesh_off_reason;
  EXPECT_EQ(def.decision.mesh.k, 0.75);  // 1 up to session 37
  EXPECT_EQ(def.decision.mesh.h, 10.0);
  EXPECT_EQ(def.decision.mesh.one_day_allowance, 1.0);
  EXPECT_EQ(def.decision.mesh.step_cap, 2.5);
  const std::string gearbox = "[gearbox]\nkind = \"cycloidal\"\nz_in = 28\nz_spur = 23\nz_pin = 40\n";
  // With them it is on (not required), and training stores the mesh statistics.
  const PipelineConfig teeth =
      parse_pipeline_config("[extraction]\nwindow_len = 4096\n" + gearbox, "cfg.toml");
  EXPECT_TRUE(teeth.decision.mesh.enabled);
  EXPECT_FALSE(teeth.decision.mesh.required);
  EXPECT_TRUE(teeth.thresholds.mesh_stats);
  EXPECT_TRUE(teeth.mesh_off_reason.empty()) << teeth.mesh_off_reason;
  // A parallel gearbox's teeth give the mesh too.
  const PipelineConfig parallel = parse_pipeline_config(
      "[extraction]\nwindow_len = 4096\n[gearbox]\nkind = \"parallel\"\nz_in = 20\nz_spur = 100\n",
      "cfg.toml");
  EXPECT_TRUE(parallel.decision.mesh.enabled);
  // A ratio alone does not (no z_in: no mesh frequency).
  const PipelineConfig ratio_only =
      parse_pipeline_config("[extraction]\nwindow_len = 4096\n[gearbox]\nratio = 33.86\n", "cfg.toml");
  EXPECT_FALSE(ratio_only.decision.mesh.enabled);
  // The order domain goes without it by default (not measured there).
  const PipelineConfig order_def =
      parse_pipeline_config("[extraction]\ndomain = \"order\"\n" + gearbox, "cfg.toml");
  EXPECT_FALSE(order_def.decision.mesh.enabled);
  EXPECT_FALSE(order_def.thresholds.mesh_stats);
  EXPECT_EQ(order_def.mesh_off_reason.rfind("the order domain", 0), 0U) << order_def.mesh_off_reason;
  // Switched off by the configuration: off, and nothing to explain.
  const PipelineConfig off = parse_pipeline_config(
      "[extraction]\nwindow_len = 4096\n[decision]\nmesh_cusum = false\n" + gearbox, "cfg.toml");
  EXPECT_FALSE(off.decision.mesh.enabled);
  EXPECT_FALSE(off.thresholds.mesh_stats);
  EXPECT_TRUE(off.mesh_off_reason.empty());
  const PipelineConfig on = parse_pipeline_config(
      "[extraction]\nwindow_len = 4096\n[decision]\nmesh_cusum = true\nmesh_cusum_k = 1.5\nmesh_cusum_h = "
      "12\n"
      "mesh_cusum_one_day_allowance = 0.5\nmesh_cusum_step_cap = 3\n" +
          gearbox,
      "cfg.toml");
  EXPECT_TRUE(on.decision.mesh.enabled);
  EXPECT_TRUE(on.decision.mesh.required);  // said explicitly
  EXPECT_TRUE(on.thresholds.mesh_stats);   // training stores the mesh statistics
  EXPECT_EQ(on.decision.mesh.k, 1.5);
  EXPECT_EQ(on.decision.mesh.h, 12.0);
  EXPECT_EQ(on.decision.mesh.one_day_allowance, 0.5);
  EXPECT_EQ(on.decision.mesh.step_cap, 3.0);
  const PipelineConfig back = parse_pipeline_config(format_pipeline_config(on), "formatted.toml");
  EXPECT_TRUE(back.decision.mesh.enabled);
  EXPECT_EQ(back.decision.mesh.k, 1.5);
  EXPECT_EQ(back.decision.mesh.h, 12.0);
  EXPECT_EQ(back.decision.mesh.one_day_allowance, 0.5);
  EXPECT_EQ(back.decision.mesh.step_cap, 3.0);
  // Without tooth counts there is no mesh frequency: an error at the key that asked for it.
  const std::string no_teeth = error_of("[extraction]\nwindow_len = 4096\n[decision]\nmesh_cusum = true\n");
  EXPECT_EQ(no_teeth.rfind("cfg.toml:4:14: [decision] mesh_cusum = true needs the input pinion's teeth", 0),
            0U)
      << no_teeth;
  // The order domain has not been measured with it.
  const std::string order =
      error_of("[extraction]\ndomain = \"order\"\n[decision]\nmesh_cusum = true\n" + gearbox);
  EXPECT_NE(order.find("[decision] mesh_cusum = true runs in the time domain only"), std::string::npos)
      << order;
  EXPECT_EQ(error_of("[decision]\nmesh_cusum_h = 2000\n"),
            "cfg.toml:2:16: decision.mesh_cusum_h = 2000 is outside 0..1000");
  EXPECT_EQ(error_of("[decision]\nmesh_cusum_one_day_allowance = 11\n"),
            "cfg.toml:2:32: decision.mesh_cusum_one_day_allowance = 11 is outside 0..10");
}

}  // namespace
}  // namespace ptda::config
