// `[extraction] domain = "order"` and the order keys (issue 16): defaults, every key, window_len derived
// from R S, the round trip through format_pipeline_config, and each error with the key it names.
#include <gtest/gtest.h>

#include <string>

#include "ptda/common/error.hpp"
#include "ptda/config/pipeline_config.hpp"
#include "ptda/dsp/angle_resampler.hpp"

namespace ptda::config {
namespace {

// A cycloidal gearbox (ratio 33.857) and the default speed frame, which carries the angle.
constexpr const char* kGearbox = "[gearbox]\nkind = \"cycloidal\"\nz_in = 28\nz_spur = 23\nz_pin = 40\n";

std::string order_text(const std::string& extraction_keys) {
  return "[extraction]\ndomain = \"order\"\n" + extraction_keys + kGearbox;
}

std::string error_of(const std::string& text) {
  try {
    (void)parse_pipeline_config(text, "cfg.toml");
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

bool has(const std::string& text, const std::string& needle) {
  return text.find(needle) != std::string::npos;
}

TEST(OrderConfig, TimeIsTheDefault) {
  const PipelineConfig c = parse_pipeline_config("[extraction]\nwindow_len = 4096\n", "cfg.toml");
  EXPECT_EQ(c.domain, dsp::Domain::kTime);
  EXPECT_EQ(c.extraction.window_len, 4096U);
  // The order defaults (docs/cli.md): the bench's S = 1024, R = 8 (docs/results-order.md).
  EXPECT_EQ(c.order.samples_per_rev, 1024U);
  EXPECT_EQ(c.order.revolutions, 8U);
  EXPECT_EQ(c.order.speed_band_rel, 0.1);
  EXPECT_EQ(c.order.anti_alias_half_taps, 32U);
  EXPECT_EQ(c.order.anti_alias_cutoff, 0.8);
  EXPECT_EQ(c.order.min_shaft_hz, 0.5);
  EXPECT_EQ(c.order.can_time_smoothing_frames, 32U);
  // The time domain keeps the window_len requirement.
  EXPECT_TRUE(has(error_of("[extraction]\ndomain = \"time\"\n"), "window_len is required"));
}

TEST(OrderConfig, ParsesEveryOrderKeyAndDerivesWindowLen) {
  const PipelineConfig c = parse_pipeline_config(
      order_text("samples_per_rev = 512\nrevolutions = 6\nspeed_band_rel = 0.08\nanti_alias_half_taps = 48\n"
                 "anti_alias_cutoff = 0.7\nmin_shaft_hz = 1.5\nmax_speed_gap_s = "
                 "0.03\ncan_time_smoothing_frames = 0\n"),
      "cfg.toml");
  EXPECT_EQ(c.domain, dsp::Domain::kOrder);
  EXPECT_EQ(c.order.samples_per_rev, 512U);
  EXPECT_EQ(c.order.revolutions, 6U);
  EXPECT_EQ(c.order.speed_band_rel, 0.08);
  EXPECT_EQ(c.order.anti_alias_half_taps, 48U);
  EXPECT_EQ(c.order.anti_alias_cutoff, 0.7);
  EXPECT_EQ(c.order.min_shaft_hz, 1.5);
  EXPECT_EQ(c.order.can_time_smoothing_frames, 0U);
  EXPECT_EQ(c.extraction.window_len, 3072U);  // R S, no window_len given

  const dsp::AngleResamplerConfig rc = angle_resampler_config(c);
  EXPECT_EQ(rc.samples_per_rev, 512U);
  EXPECT_EQ(rc.half_taps, 48U);
  EXPECT_EQ(rc.cutoff, 0.7);
  EXPECT_EQ(rc.min_shaft_hz, 1.5);
  EXPECT_EQ(rc.max_speed_gap_s, 0.03);
  EXPECT_EQ(rc.speed_latency_s, 0.0);  // applied when the frames are decoded
  EXPECT_NEAR(rc.ratio, 1.0 + 23.0 / 28.0 * 40.0, 1e-12);
  const dsp::OrderWindowConfig oc = order_window_config(c, 123.5);
  EXPECT_EQ(oc.samples_per_rev, 512U);
  EXPECT_EQ(oc.revolutions, 6U);
  EXPECT_EQ(oc.max_order, 123.5);
  EXPECT_EQ(oc.ratio, rc.ratio);

  // A window_len equal to R S is accepted.
  EXPECT_EQ(parse_pipeline_config(order_text("window_len = 8192\n"), "cfg.toml").extraction.window_len,
            8192U);
}

TEST(OrderConfig, FormatRoundTrips) {
  const PipelineConfig c = parse_pipeline_config(
      order_text("samples_per_rev = 2048\nrevolutions = 4\nspeed_band_rel = 0.12\nmin_shaft_hz = 0.75\n"),
      "cfg.toml");
  const std::string text = format_pipeline_config(c);
  EXPECT_TRUE(
      has(text, "domain = \"order\"\nsamples_per_rev = 2048\nrevolutions = 4\nspeed_band_rel = 0.12\n"))
      << text;
  const PipelineConfig back = parse_pipeline_config(text, "formatted.toml");
  EXPECT_EQ(back.domain, dsp::Domain::kOrder);
  EXPECT_EQ(back.order.samples_per_rev, c.order.samples_per_rev);
  EXPECT_EQ(back.order.revolutions, c.order.revolutions);
  EXPECT_EQ(back.order.speed_band_rel, c.order.speed_band_rel);
  EXPECT_EQ(back.order.anti_alias_half_taps, c.order.anti_alias_half_taps);
  EXPECT_EQ(back.order.anti_alias_cutoff, c.order.anti_alias_cutoff);
  EXPECT_EQ(back.order.min_shaft_hz, c.order.min_shaft_hz);
  EXPECT_EQ(back.order.can_time_smoothing_frames, c.order.can_time_smoothing_frames);
  EXPECT_EQ(back.extraction.window_len, 8192U);
  // A time configuration formats domain = "time" and parses back to the time domain.
  const PipelineConfig t = parse_pipeline_config("[extraction]\nwindow_len = 4096\n", "cfg.toml");
  EXPECT_EQ(parse_pipeline_config(format_pipeline_config(t), "f.toml").domain, dsp::Domain::kTime);
}

TEST(OrderConfigErrors, PerKeyErrorsNameTheKey) {
  const std::string bad_domain = error_of("[extraction]\ndomain = \"angle\"\nwindow_len = 4096\n");
  EXPECT_TRUE(has(bad_domain, "cfg.toml:2:10")) << bad_domain;
  EXPECT_TRUE(has(bad_domain, "extraction.domain")) << bad_domain;
  EXPECT_TRUE(has(bad_domain, "order")) << bad_domain;

  const std::string odd = error_of(order_text("samples_per_rev = 1023\n"));
  EXPECT_TRUE(has(odd, "cfg.toml:3:19")) << odd;
  EXPECT_TRUE(has(odd, "samples_per_rev")) << odd;
  EXPECT_TRUE(has(odd, "must be even")) << odd;
  const std::string small = error_of(order_text("samples_per_rev = 8\n"));
  EXPECT_TRUE(has(small, "extraction.samples_per_rev")) << small;

  const std::string revs = error_of(order_text("revolutions = 0\n"));
  EXPECT_TRUE(has(revs, "cfg.toml:3:15")) << revs;
  EXPECT_TRUE(has(revs, "extraction.revolutions")) << revs;

  const std::string band = error_of(order_text("speed_band_rel = 0.0\n"));
  EXPECT_TRUE(has(band, "cfg.toml:3:18")) << band;
  EXPECT_TRUE(has(band, "speed_band_rel")) << band;
  EXPECT_TRUE(has(band, "must be > 0")) << band;

  const std::string cutoff = error_of(order_text("anti_alias_cutoff = 1.0\n"));
  EXPECT_TRUE(has(cutoff, "cfg.toml:3:21")) << cutoff;
  EXPECT_TRUE(has(cutoff, "anti_alias_cutoff")) << cutoff;

  const std::string taps = error_of(order_text("anti_alias_half_taps = 3\n"));
  EXPECT_TRUE(has(taps, "extraction.anti_alias_half_taps")) << taps;

  const std::string shaft = error_of(order_text("min_shaft_hz = 0.0\n"));
  EXPECT_TRUE(has(shaft, "extraction.min_shaft_hz")) << shaft;

  const std::string smoothing = error_of(order_text("can_time_smoothing_frames = 5000\n"));
  EXPECT_TRUE(has(smoothing, "extraction.can_time_smoothing_frames")) << smoothing;
}

TEST(OrderConfigErrors, CrossKeyErrors) {
  // window_len given and not R S.
  const std::string len = error_of(order_text("window_len = 4096\n"));
  EXPECT_TRUE(has(len,
                  "cfg.toml:3:14: [extraction] window_len = 4096 disagrees with domain = \"order\": "
                  "revolutions (8) x samples_per_rev (1024) = 8192"))
      << len;
  // R S not an FFT length: 1022 = 2 x 7 x 73.
  const std::string fft = error_of(order_text("samples_per_rev = 1022\n"));
  EXPECT_TRUE(has(fft,
                  "cfg.toml:3:19: [extraction] revolutions (8) x samples_per_rev (1022) = 8176 is not an "
                  "FFT length"))
      << fft;
  // The speed frame without the angle: named at has_angle.
  const std::string angle = error_of(order_text("") + "[can.speed_frame]\nhas_angle = false\n");
  EXPECT_TRUE(has(angle,
                  "cfg.toml:9:13: [extraction] domain = \"order\" resamples the vibration to the joint "
                  "angle, but [can.speed_frame] has_angle = false"))
      << angle;
  // No gearbox ratio.
  const std::string ratio = error_of("[extraction]\ndomain = \"order\"\n");
  EXPECT_TRUE(has(ratio, "cfg.toml:2:10: [extraction] domain = \"order\" needs the gearbox ratio")) << ratio;
  // An explicit ratio is enough.
  EXPECT_EQ(error_of("[extraction]\ndomain = \"order\"\n[gearbox]\nratio = 50.0\n"), "(no error)");
  // S too small for the mesh order z_in = 28: S = 64 passes orders up to 0.3608 x 64 = 20.1.
  const std::string mesh = error_of(order_text("samples_per_rev = 64\n"));
  EXPECT_TRUE(has(mesh, "cfg.toml:3:19: [extraction] samples_per_rev = 64 passes orders up to")) << mesh;
  EXPECT_TRUE(has(mesh, "below the gear mesh order z_in = 28")) << mesh;
  // Half-taps too small for the cutoff: no pass band (c/2 - 2.51/Q/2 <= 0 at Q = 4, c = 0.6).
  const std::string pass = error_of(order_text("anti_alias_half_taps = 4\nanti_alias_cutoff = 0.6\n"));
  EXPECT_TRUE(has(pass, "anti_alias_half_taps = 4 is too small for anti_alias_cutoff = 0.6")) << pass;
}

}  // namespace
}  // namespace ptda::config
