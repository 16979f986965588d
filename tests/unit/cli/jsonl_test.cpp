// JSON Lines writer: escaping, round-trip numbers, null for non-finite values; and the reader the tests
// use to parse it back.
#include "ptda/cli/jsonl.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "ptda/cli/monitor_output.hpp"
#include "ptda/common/error.hpp"
#include "ptda/common/time.hpp"

namespace ptda::cli {
namespace {

TEST(JsonString, EscapesQuotesBackslashesAndControls) {
  EXPECT_EQ(json_string("plain"), "\"plain\"");
  EXPECT_EQ(json_string("a\"b\\c"), "\"a\\\"b\\\\c\"");
  EXPECT_EQ(json_string("l1\nl2\r\t\b\f"), "\"l1\\nl2\\r\\t\\b\\f\"");
  EXPECT_EQ(json_string(std::string_view("\x01\x1f\x7f", 3)), "\"\\u0001\\u001f\\u007f\"");
  EXPECT_EQ(json_string(std::string_view("nul\0x", 5)), "\"nul\\u0000x\"");
  EXPECT_EQ(json_string("m/s^2 \xc2\xb5"), "\"m/s^2 \xc2\xb5\"");  // UTF-8 passes through
}

TEST(JsonNumber, ShortestRoundTripAndNull) {
  EXPECT_EQ(json_number(0.1), "0.1");
  EXPECT_EQ(json_number(1.0), "1");
  EXPECT_EQ(json_number(-2.5e-7), "-2.5e-07");
  EXPECT_EQ(json_number(1700000012.345678), "1700000012.345678");
  EXPECT_EQ(json_number(std::nan("")), "null");
  EXPECT_EQ(json_number(std::numeric_limits<double>::infinity()), "null");
  for (const double v : {0.1 + 0.2, 1.0 / 3.0, 6.02214076e23, 4.9406564584124654e-324, 1700000000.0001234}) {
    const std::string s = json_number(v);
    EXPECT_EQ(std::strtod(s.c_str(), nullptr), v) << s;
  }
}

TEST(JsonObject, BuildsOneLine) {
  JsonObject o;
  o.add("n", 3)
      .add("t", 0.25)
      .add("ok", true)
      .add("name", "a\"b")
      .add_null("segment")
      .add_pair("band", 0.5, 1.5);
  o.add_optional("seg2", 7).add("big", static_cast<std::uint64_t>(18446744073709551615ULL));
  EXPECT_EQ(
      o.str(),
      "{\"n\":3,\"t\":0.25,\"ok\":true,\"name\":\"a\\\"b\",\"segment\":null,\"band\":[0.5,1.5],\"seg2\":7,"
      "\"big\":18446744073709551615}");
  EXPECT_EQ(JsonObject().str(), "{}");
}

TEST(JsonRoundTrip, WriterOutputParsesBack) {
  JsonObject o;
  const std::string tricky = std::string("q\"b\\s/\n\x02 end");
  o.add("s", tricky)
      .add("x", 0.1 + 0.2)
      .add("nan", std::nan(""))
      .add_pair("band", -1e-300, 1e300)
      .add("f", false);
  const JsonValue v = parse_json(o.str(), "test");
  EXPECT_EQ(v.at("s").as_string(), tricky);
  EXPECT_EQ(v.at("x").as_number(), 0.1 + 0.2);
  EXPECT_TRUE(v.at("nan").is_null());
  ASSERT_EQ(v.at("band").array.size(), 2U);
  EXPECT_EQ(v.at("band").array[0].as_number(), -1e-300);
  EXPECT_EQ(v.at("band").array[1].as_number(), 1e300);
  EXPECT_FALSE(v.at("f").as_bool());
}

TEST(JsonParse, ErrorsNameSourceAndColumn) {
  try {
    (void)parse_json("{\"a\":1,}", "out.jsonl:4");
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "out.jsonl:4: column 8: expected a string key");
  }
  EXPECT_THROW((void)parse_json("{\"a\":1} x", "s"), Error);
  EXPECT_THROW((void)parse_json("{\"a\":\"unterminated}", "s"), Error);
  EXPECT_THROW((void)parse_json("{\"a\":1,\"a\":2}", "s"), Error);
  EXPECT_THROW((void)parse_json("{\"a\":1}", "s").at("b"), Error);
}

TEST(WindowJson, ScoredAndUnclassifiedWindows) {
  dsp::WindowResult w;
  w.ref.seq = 12;
  w.ref.region_seq = 3;
  w.ref.t_start_ns = 1'700'000'001'250'000'000;
  w.ref.t_end_ns = 1'700'000'001'410'000'000;
  w.ref.speed_rad_s = -1.0471975511965976;
  w.status = dsp::WindowStatus::kScored;
  w.class_id = 1;
  w.features = {0.0625, 0.875};
  w.thresholds.rms = {0.03125, 0.0500};
  w.thresholds.entropy = {0.5, 0.95};
  w.verdict = {true, false};
  w.alarm = true;
  w.abnormal_in_last_n = 3;
  w.kofn_alarm = true;
  w.detector = dsp::AlarmDetector::kKOfN;
  w.z_rms = 2.5;
  w.z_entropy = -0.25;
  w.seq_statistic = 1.5;
  w.seq_feature = dsp::SeqFeature::kRmsHigh;
  w.seq_max_statistic = 4.5;
  w.seq_warn = true;
  // Times: UNIX seconds of the ns timestamps, written so they read back to the same double.
  const std::string t_start = json_number(ns_to_seconds(w.ref.t_start_ns));
  const std::string t_end = json_number(ns_to_seconds(w.ref.t_end_ns));
  EXPECT_EQ(t_start.substr(0, 13), "1700000001.25");
  EXPECT_EQ(t_end.substr(0, 13), "1700000001.41");
  EXPECT_EQ(
      window_json(w, dsp::Method::kPtda),
      "{\"n\":12,\"t_start\":" + t_start + ",\"t_end\":" + t_end +
          ",\"segment\":1,\"region\":3,"
          "\"speed_rad_s\":-1.0471975511965976,\"status\":\"scored\",\"method\":\"ptda\",\"rms_res\":0.0625,"
          "\"entropy_res\":0.875,\"rms_band\":[0.03125,0.05],\"entropy_band\":[0.5,0.95],\"rms_out\":true,"
          "\"entropy_out\":false,\"abnormal\":true,\"alarm\":true,\"abnormal_in_last_n\":3,\"rms_low\":false,"
          "\"detector\":\"k_of_n\",\"kofn_alarm\":true,\"seq_alarm\":false,\"seq_warn\":true,\"z_rms\":2.5,"
          "\"z_entropy\":-0.25,\"cusum\":1.5,\"cusum_feature\":\"rms_high\",\"cusum_max\":4.5}");
  // The band CUSUM's evidence (only with [decision] band_cusum on), the text the daemon's history
  // writes (tests/unit/daemon/history_log_test.cpp, BandCusumEvidenceEndsTheWindowLine).
  w.band_on = true;
  w.band_alarm = true;
  w.band_z_max = 3.5;
  w.band_statistic = 12.0;
  w.band_index = 7;
  w.band_max_statistic = 12.0;
  w.band_max_index = 7;
  w.band_lo_hz = 2802.5;
  w.band_hi_hz = 3200.0;
  const std::string banded = window_json(w, dsp::Method::kPtda);
  const std::string tail =
      R"("cusum_max":4.5,"band_alarm":true,"band_z_max":3.5,"band_cusum":12,"band_cusum_band":7,)"
      R"("band_cusum_max":12,"band":7,"band_hz":[2802.5,3200]})";
  EXPECT_EQ(banded.substr(banded.size() - tail.size()), tail) << banded;
  w.band_on = false;
  w.status = dsp::WindowStatus::kNoClass;
  w.class_id = -1;
  w.alarm = false;
  const JsonValue v = parse_json(window_json(w, dsp::Method::kTda), "w");
  EXPECT_TRUE(v.at("segment").is_null());
  EXPECT_TRUE(v.at("rms_res").is_null());
  EXPECT_EQ(v.at("status").as_string(), "no_class");
  EXPECT_EQ(v.at("method").as_string(), "tda");
  EXPECT_FALSE(v.at("abnormal").as_bool());
  EXPECT_TRUE(v.at("cusum").is_null());  // no class: no class statistic; the largest stays
  EXPECT_EQ(v.at("cusum_max").as_number(), 4.5);
}

}  // namespace
}  // namespace ptda::cli
