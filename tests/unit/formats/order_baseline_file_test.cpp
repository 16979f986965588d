// Baseline format version 5 (issue 16): an order-domain baseline stores its domain, S and R; a
// time-domain baseline is still written as version 4 byte for byte; version 1 and 4 files read as time
// domain; inconsistent order fields are refused with a message naming them.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include "ptda/common/error.hpp"
#include "ptda/dsp/baseline.hpp"
#include "ptda/formats/baseline_file.hpp"

namespace {

namespace fs = std::filesystem;
using ptda::Error;
using ptda::dsp::Baseline;
using ptda::dsp::Domain;
using ptda::formats::crc32;
using ptda::formats::parse_baseline;
using ptda::formats::serialize_baseline;
using Bytes = std::vector<std::uint8_t>;

// A plausible baseline (validate_baseline passes) of window length n, two classes.
Baseline make_baseline(std::uint32_t n, double fs_hz) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> pos(0.1, 2.0);
  Baseline b;
  b.fs_hz = fs_hz;
  b.window_len = n;
  b.gearbox = {ptda::dsp::GearboxInfo::Kind::kCycloidal, 28, 23, 40, 1.0 + 23.0 / 28.0 * 40.0};
  for (std::uint32_t k = 0; k < 2; ++k) {
    ptda::dsp::ClassBaseline c;
    c.segment = {k, static_cast<std::int8_t>(k == 0 ? 1 : -1), 3.46, 0.17, 0.0, 20};
    c.n_windows = 40;
    c.mean_magnitude.assign(n / 2 + 1, 0.0F);
    c.tda_mean.assign(n, 0.0F);
    for (auto& v : c.mean_magnitude) v = static_cast<float>(pos(rng));
    for (std::size_t m = 0; m < ptda::dsp::kMethodCount; ++m) {
      c.thresholds[m] = {{0.3, 1.0}, {0.4, 0.9}};
      c.rms_stats[m] = {0.6, 0.1, 0.4, 0.9, 40};
      c.entropy_stats[m] = {0.65, 0.05, 0.5, 0.8, 40};
      c.log_rms_stats[m] = {-0.5, 0.15, -0.9, -0.1, 40};
    }
    b.classes.push_back(c);
  }
  b.source = "test";
  return b;
}

Baseline make_order_baseline() {
  Baseline b = make_baseline(4096, 1024.0);
  b.domain = Domain::kOrder;
  b.samples_per_rev = 1024;
  b.revolutions = 4;
  return b;
}

void fix_crc(Bytes& b) {
  const std::uint32_t crc = crc32(b.data(), b.size() - 4);
  for (int i = 0; i < 4; ++i)
    b[b.size() - 4 + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(crc >> (8 * i));
}

std::string error_of(const Bytes& b) {
  try {
    (void)parse_baseline(b, "o.bin");
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

/// Offset of the order section (domain u8, S u32, R u32, 3 x f64 speed law) from the end of the file.
constexpr std::size_t kOrderTail = 4 + 9 + 24;

TEST(OrderBaselineFile, OrderBaselineIsVersion6AndRoundTrips) {
  Baseline b = make_order_baseline();
  b.speed_law_exponent = 1.5;
  b.speed_law_fit = 1.5;
  b.speed_law_se = 0.25;
  const Bytes bytes = serialize_baseline(b);
  EXPECT_EQ(bytes[8], 6);  // version 6, little-endian
  // The last 33 bytes before the CRC: domain 1, S 1024, R 4 (little-endian), then the speed law.
  const std::size_t at = bytes.size() - kOrderTail;
  EXPECT_EQ(bytes[at], 1);
  EXPECT_EQ(bytes[at + 1] | (bytes[at + 2] << 8), 1024);
  EXPECT_EQ(bytes[at + 5], 4);
  double p = 0.0;
  std::memcpy(&p, bytes.data() + at + 9, sizeof p);  // IEEE-754 little-endian on every target we build
  EXPECT_EQ(p, 1.5);
  const Baseline back = parse_baseline(bytes, "o.bin");
  EXPECT_EQ(back.domain, Domain::kOrder);
  EXPECT_EQ(back.samples_per_rev, 1024U);
  EXPECT_EQ(back.revolutions, 4U);
  EXPECT_EQ(back.fs_hz, 1024.0);
  EXPECT_EQ(back.window_len, 4096U);
  EXPECT_EQ(back.classes.size(), 2U);
  EXPECT_EQ(back.speed_law_exponent, 1.5);
  EXPECT_EQ(back.speed_law_fit, 1.5);
  EXPECT_EQ(back.speed_law_se, 0.25);
  EXPECT_EQ(serialize_baseline(back), bytes);  // written back: the same bytes

  // A version 5 file (no speed law: the bytes before it, version 5, its CRC) reads with p = 0.
  Bytes v5(bytes.begin(), bytes.end() - 4 - 24);
  v5.insert(v5.end(), 4, 0);
  v5[8] = 5;
  const std::uint64_t size = v5.size();
  for (int i = 0; i < 8; ++i)
    v5[12 + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(size >> (8 * i));
  fix_crc(v5);
  const Baseline old = parse_baseline(v5, "v5.bin");
  EXPECT_EQ(old.domain, Domain::kOrder);
  EXPECT_EQ(old.speed_law_exponent, 0.0);
  EXPECT_EQ(old.revolutions, 4U);

  // An implausible exponent is refused on write and on read.
  b.speed_law_exponent = 9.0;
  EXPECT_THROW((void)serialize_baseline(b), Error);
}

TEST(OrderBaselineFile, TimeBaselineStaysVersion4AndReadsAsTime) {
  const Baseline t = make_baseline(4096, 25600.0);
  const Bytes bytes = serialize_baseline(t);
  EXPECT_EQ(bytes[8], 4);  // unchanged format for the time domain
  // The same baseline as an order baseline is exactly 33 bytes longer (domain, S, R, speed law).
  Baseline o = make_order_baseline();
  EXPECT_EQ(serialize_baseline(o).size(), bytes.size() + 33);
  const Baseline back = parse_baseline(bytes, "t.bin");
  EXPECT_EQ(back.domain, Domain::kTime);
  EXPECT_EQ(back.samples_per_rev, 0U);
  EXPECT_EQ(back.revolutions, 0U);
  // The version 1 golden file (session 1) reads as time domain.
  const fs::path golden =
      fs::path(PTDA_SOURCE_DIR) / "tests" / "data" / "formats" / "baseline_v1_joint_rotation.bin";
  EXPECT_EQ(ptda::formats::read_baseline(golden).domain, Domain::kTime);
}

TEST(OrderBaselineFile, InconsistentOrderFieldsAreRefused) {
  Baseline b = make_order_baseline();
  b.revolutions = 8;  // R S = 8192, window_len 4096
  try {
    (void)serialize_baseline(b);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(
        std::string(e.what()).find("order domain with samples_per_rev 1024, revolutions 8, window_len 4096 "
                                   "and fs_hz 1024: needs S even >= 16, R >= 1, window_len = R S and "
                                   "fs_hz = S"),
        std::string::npos)
        << e.what();
  }
  Baseline t = make_baseline(4096, 25600.0);
  t.samples_per_rev = 1024;  // time domain with order fields
  EXPECT_THROW((void)serialize_baseline(t), Error);
  Baseline r = make_order_baseline();
  r.gearbox.ratio = 0.0;
  EXPECT_THROW((void)serialize_baseline(r), Error);

  // An unknown domain byte.
  Bytes bytes = serialize_baseline(make_order_baseline());
  bytes[bytes.size() - kOrderTail] = 7;
  fix_crc(bytes);
  const std::string unknown = error_of(bytes);
  EXPECT_NE(unknown.find("unknown domain 7 (this build knows 0, time, and 1, order)"), std::string::npos)
      << unknown;
  // S changed in the file: caught by the semantic check.
  bytes = serialize_baseline(make_order_baseline());
  bytes[bytes.size() - kOrderTail + 1] = 0;  // S low byte (already 0 for 1024)
  bytes[bytes.size() - kOrderTail + 2] = 2;  // S high byte: S = 512
  fix_crc(bytes);
  const std::string s512 = error_of(bytes);
  EXPECT_NE(s512.find("order domain with samples_per_rev 512"), std::string::npos) << s512;
}

}  // namespace
