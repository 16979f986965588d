// Baseline store: CRC-32 against known vectors and zlib, exact round trip, the byte layout, every
// corruption case with its message, and atomic writes that never damage the previous file.
#include "ptda/formats/baseline_file.hpp"

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "ptda/common/error.hpp"
#include "ptda/dsp/training.hpp"

namespace fs = std::filesystem;
using ptda::Error;
using ptda::dsp::Baseline;
using ptda::formats::crc32;
using ptda::formats::parse_baseline;
using ptda::formats::read_baseline;
using ptda::formats::serialize_baseline;
using ptda::formats::write_baseline;
using Bytes = std::vector<std::uint8_t>;

namespace {

fs::path temp_dir(const std::string& name) {
  const char* env = std::getenv("PTDA_TEST_TMP");
  fs::path d = (env != nullptr ? fs::path(env) : fs::temp_directory_path()) /
               ("formats_baseline_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

// A random baseline that passes validate_baseline: bands lo < hi, spreads > 0, counts within the
// class's windows, magnitudes >= 0.
Baseline make_baseline(std::uint32_t n, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-10.0, 10.0);
  std::uniform_real_distribution<double> pos(0.01, 10.0);
  Baseline b;
  b.fs_hz = 25600.0;
  b.window_len = n;
  b.gearbox = {ptda::dsp::GearboxInfo::Kind::kCycloidal, 10, 40, 41, 164.0};
  b.policy = {ptda::dsp::ThresholdPolicy::Kind::kQuantile, 1e-3, 0.1, 0.95, 0.25, false};  // no line gain
  b.policy.day_sd_floor = 0.25;
  const auto stats = [&](std::uint32_t windows) {
    const double mean = u(rng);
    return ptda::dsp::FeatureStats{mean, pos(rng), mean - pos(rng), mean + pos(rng),
                                   static_cast<std::uint32_t>(rng() % (windows - 1)) + 2};
  };
  for (std::uint32_t k = 0; k < 3; ++k) {
    ptda::dsp::ClassBaseline c;
    c.segment = {k + 7, static_cast<std::int8_t>(k % 2 == 0 ? 1 : -1), 0.5 + k, 0.05, 1.25, 12 + k};
    c.n_windows = 40 + k;
    c.mean_magnitude.resize(n / 2 + 1);
    c.tda_mean.resize(n);
    for (auto& v : c.mean_magnitude) v = static_cast<float>(pos(rng));
    for (auto& v : c.tda_mean) v = static_cast<float>(u(rng));
    for (std::size_t m = 0; m < ptda::dsp::kMethodCount; ++m) {
      const double rms_lo = pos(rng);
      const double ent_lo = u(rng);
      c.thresholds[m] = {{rms_lo, rms_lo + pos(rng)}, {ent_lo, ent_lo + pos(rng)}};
      c.rms_stats[m] = stats(c.n_windows);
      c.entropy_stats[m] = stats(c.n_windows);
      c.log_rms_stats[m] = stats(c.n_windows);
      const auto held = static_cast<std::uint32_t>(rng() % 1000);
      const auto part = [&] { return static_cast<std::uint32_t>(rng() % (held + 1)); };
      c.holdout[m] = {held, part(), part(), part(), part(), u(rng), pos(rng), u(rng), pos(rng)};
    }
    for (auto& d : c.day_spread)
      d = {static_cast<std::uint32_t>(rng() % 5) + 1,
           pos(rng),
           pos(rng),
           pos(rng),
           pos(rng),
           pos(rng),
           pos(rng)};
    c.windows_per_hour = 1440.0 + k;
    b.classes.push_back(c);
  }
  // Signed zero and extreme finite values must survive bit for bit.
  b.classes[0].thresholds[0].rms.hi = std::numeric_limits<double>::max();
  b.classes[1].rms_stats[2].mean = -0.0;
  b.source = "trained on rec/healthy-01 by ptda 0.1.0";
  b.training = {ptda::dsp::TrainingRecording{"wav:4867590:e1a78178:ch0", "rec/healthy-01", 1.7e9 + 0.375,
                                             1.7e9 + 30.5, 50},
                ptda::dsp::TrainingRecording{"wav:12:00000000:ch1", "", 0.0, -0.0, 0}};
  return b;
}

template <typename T>
bool same_bits(T a, T b) {
  return std::memcmp(&a, &b, sizeof(T)) == 0;
}

void expect_equal(const Baseline& a, const Baseline& b) {
  EXPECT_EQ(a.fs_hz, b.fs_hz);
  EXPECT_EQ(a.window_len, b.window_len);
  EXPECT_EQ(a.gearbox.kind, b.gearbox.kind);
  EXPECT_EQ(a.gearbox.z_in, b.gearbox.z_in);
  EXPECT_EQ(a.gearbox.z_spur, b.gearbox.z_spur);
  EXPECT_EQ(a.gearbox.z_pin, b.gearbox.z_pin);
  EXPECT_EQ(a.gearbox.ratio, b.gearbox.ratio);
  EXPECT_EQ(a.policy.kind, b.policy.kind);
  EXPECT_EQ(a.policy.false_alarm_rate, b.policy.false_alarm_rate);
  EXPECT_EQ(a.policy.margin, b.policy.margin);
  EXPECT_EQ(a.policy.confidence, b.policy.confidence);
  EXPECT_EQ(a.policy.holdout_fraction, b.policy.holdout_fraction);
  EXPECT_EQ(a.policy.ptda_line_gain, b.policy.ptda_line_gain);
  EXPECT_EQ(a.policy.ptda_floor_gain, b.policy.ptda_floor_gain);
  EXPECT_EQ(a.policy.day_sd_floor, b.policy.day_sd_floor);
  EXPECT_EQ(a.source, b.source);
  ASSERT_EQ(a.training.size(), b.training.size());
  for (std::size_t i = 0; i < a.training.size(); ++i) {
    EXPECT_EQ(a.training[i].id, b.training[i].id);
    EXPECT_EQ(a.training[i].path, b.training[i].path);
    EXPECT_TRUE(same_bits(a.training[i].from_unix_s, b.training[i].from_unix_s));
    EXPECT_TRUE(same_bits(a.training[i].to_unix_s, b.training[i].to_unix_s));
    EXPECT_EQ(a.training[i].windows, b.training[i].windows);
  }
  ASSERT_EQ(a.classes.size(), b.classes.size());
  for (std::size_t i = 0; i < a.classes.size(); ++i) {
    const auto& x = a.classes[i];
    const auto& y = b.classes[i];
    EXPECT_EQ(x.segment.id, y.segment.id);
    EXPECT_EQ(x.segment.direction, y.segment.direction);
    EXPECT_EQ(x.segment.speed_rad_s, y.segment.speed_rad_s);
    EXPECT_EQ(x.segment.speed_tol_rad_s, y.segment.speed_tol_rad_s);
    EXPECT_EQ(x.segment.duration_s, y.segment.duration_s);
    EXPECT_EQ(x.segment.regions, y.segment.regions);
    EXPECT_EQ(x.n_windows, y.n_windows);
    EXPECT_EQ(x.mean_magnitude, y.mean_magnitude);
    EXPECT_EQ(x.tda_mean, y.tda_mean);
    EXPECT_EQ(x.windows_per_hour, y.windows_per_hour);
    EXPECT_EQ(x.band_recordings, y.band_recordings);
    ASSERT_EQ(x.band_stats.size(), y.band_stats.size());
    for (std::size_t k = 0; k < x.band_stats.size(); ++k) {
      EXPECT_TRUE(same_bits(x.band_stats[k].mean, y.band_stats[k].mean));
      EXPECT_TRUE(same_bits(x.band_stats[k].within_sd, y.band_stats[k].within_sd));
      EXPECT_TRUE(same_bits(x.band_stats[k].between_est, y.band_stats[k].between_est));
      EXPECT_TRUE(same_bits(x.band_stats[k].between_sd, y.band_stats[k].between_sd));
      EXPECT_EQ(x.band_stats[k].clean_bins, y.band_stats[k].clean_bins);
    }
    EXPECT_EQ(x.mesh_recordings, y.mesh_recordings);
    ASSERT_EQ(x.mesh_stats.size(), y.mesh_stats.size());
    for (std::size_t k = 0; k < x.mesh_stats.size(); ++k) {
      EXPECT_TRUE(same_bits(x.mesh_stats[k].mean, y.mesh_stats[k].mean));
      EXPECT_TRUE(same_bits(x.mesh_stats[k].within_sd, y.mesh_stats[k].within_sd));
      EXPECT_TRUE(same_bits(x.mesh_stats[k].between_est, y.mesh_stats[k].between_est));
      EXPECT_TRUE(same_bits(x.mesh_stats[k].between_sd, y.mesh_stats[k].between_sd));
      EXPECT_EQ(x.mesh_stats[k].windows, y.mesh_stats[k].windows);
    }
    for (std::size_t m = 0; m < ptda::dsp::kMethodCount; ++m) {
      EXPECT_TRUE(same_bits(x.log_rms_stats[m].mean, y.log_rms_stats[m].mean));
      EXPECT_TRUE(same_bits(x.log_rms_stats[m].stddev, y.log_rms_stats[m].stddev));
      EXPECT_EQ(x.log_rms_stats[m].n, y.log_rms_stats[m].n);
      const auto& dx = x.day_spread[m];
      const auto& dy = y.day_spread[m];
      EXPECT_EQ(dx.recordings, dy.recordings);
      EXPECT_EQ(dx.log_rms_within_sd, dy.log_rms_within_sd);
      EXPECT_EQ(dx.log_rms_between_est, dy.log_rms_between_est);
      EXPECT_EQ(dx.log_rms_between_sd, dy.log_rms_between_sd);
      EXPECT_EQ(dx.entropy_within_sd, dy.entropy_within_sd);
      EXPECT_EQ(dx.entropy_between_est, dy.entropy_between_est);
      EXPECT_EQ(dx.entropy_between_sd, dy.entropy_between_sd);
      const auto& hx = x.holdout[m];
      const auto& hy = y.holdout[m];
      EXPECT_EQ(hx.windows, hy.windows);
      EXPECT_EQ(hx.abnormal, hy.abnormal);
      EXPECT_EQ(hx.rms_high, hy.rms_high);
      EXPECT_EQ(hx.rms_low, hy.rms_low);
      EXPECT_EQ(hx.entropy_out, hy.entropy_out);
      EXPECT_EQ(hx.z_rms_mean, hy.z_rms_mean);
      EXPECT_EQ(hx.z_rms_sd, hy.z_rms_sd);
      EXPECT_EQ(hx.z_entropy_mean, hy.z_entropy_mean);
      EXPECT_EQ(hx.z_entropy_sd, hy.z_entropy_sd);
      EXPECT_TRUE(same_bits(x.thresholds[m].rms.lo, y.thresholds[m].rms.lo));
      EXPECT_TRUE(same_bits(x.thresholds[m].rms.hi, y.thresholds[m].rms.hi));
      EXPECT_TRUE(same_bits(x.thresholds[m].entropy.lo, y.thresholds[m].entropy.lo));
      EXPECT_TRUE(same_bits(x.thresholds[m].entropy.hi, y.thresholds[m].entropy.hi));
      for (const auto* pair : {&x.rms_stats, &x.entropy_stats}) {
        const auto& other = pair == &x.rms_stats ? y.rms_stats : y.entropy_stats;
        EXPECT_TRUE(same_bits((*pair)[m].mean, other[m].mean));
        EXPECT_TRUE(same_bits((*pair)[m].stddev, other[m].stddev));
        EXPECT_TRUE(same_bits((*pair)[m].min, other[m].min));
        EXPECT_TRUE(same_bits((*pair)[m].max, other[m].max));
        EXPECT_EQ((*pair)[m].n, other[m].n);
      }
    }
  }
}

std::string message_of(const Bytes& bytes) {
  try {
    (void)parse_baseline(bytes, "b.bin");
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

void put_u32(Bytes& b, std::size_t at, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) b[at + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(v >> (8 * i));
}
// Recomputes the trailing CRC so a deliberately inconsistent body reaches the structural checks.
void fix_crc(Bytes& b) {
  put_u32(b, b.size() - 4, crc32(b.data(), b.size() - 4));
}

void write_file(const fs::path& p, const Bytes& b) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
}
Bytes read_file(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return Bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// Offsets from the layout table in docs/recording-format.md.
constexpr std::size_t kOffWindowLen = 28;
constexpr std::size_t kOffClassCount = 86;
constexpr std::size_t kOffClasses = 90;
// Version 4 tail before the CRC: day_sd_floor (f64), then per class 3 x (u32 + 6 f64) day spreads.
constexpr std::size_t v4_tail(std::size_t classes) {
  return 8 + classes * 3 * 52;
}
// Where the version-3 option flags sit in a version-4 file of `classes` classes.
std::size_t options_at(const Bytes& b, std::size_t classes) {
  return b.size() - 4 - v4_tail(classes) - 4;
}
// The same baseline as an older version: the fields added since cut off, the size and CRC fixed.
Bytes as_version(const Bytes& v4, std::size_t classes, std::uint32_t version) {
  Bytes b(v4.begin(), v4.end() - 4 - static_cast<std::ptrdiff_t>(v4_tail(classes)));
  if (version < 3) b.resize(b.size() - 4);  // no option flags
  b[8] = static_cast<std::uint8_t>(version);
  put_u32(b, 12, static_cast<std::uint32_t>(b.size() + 4));
  b.resize(b.size() + 4);
  fix_crc(b);
  return b;
}

}  // namespace

TEST(Crc32, KnownVectors) {
  const char* check = "123456789";
  EXPECT_EQ(crc32(check, 9), 0xCBF43926U);  // the standard CRC-32/ISO-HDLC check value
  EXPECT_EQ(crc32(nullptr, 0), 0U);
  EXPECT_EQ(crc32("a", 1), 0xE8B7BE43U);
  // Continuing over pieces equals one pass.
  EXPECT_EQ(crc32(check + 4, 5, crc32(check, 4)), 0xCBF43926U);
}

TEST(Crc32, MatchesZlib) {
  std::mt19937 rng(7);
  for (std::size_t len : {1U, 2U, 3U, 7U, 8U, 15U, 64U, 255U, 1000U, 65537U}) {
    Bytes b(len);
    for (auto& v : b) v = static_cast<std::uint8_t>(rng());
    const auto z = static_cast<std::uint32_t>(::crc32(0L, b.data(), static_cast<uInt>(b.size())));
    EXPECT_EQ(crc32(b.data(), b.size()), z) << len;
    const std::size_t half = len / 2;
    EXPECT_EQ(crc32(b.data() + half, len - half, crc32(b.data(), half)), z) << len;
  }
}

// crc32 takes eight bytes per step and the rest one by one: every start alignment, every length up to
// a few steps, and every split point of a continued CRC against zlib's crc32.
TEST(Crc32, EightBytesAtATimeMatchesZlibAtEveryAlignmentLengthAndSplit) {
  std::mt19937 rng(11);
  Bytes b(128);
  for (auto& v : b) v = static_cast<std::uint8_t>(rng());
  for (std::size_t off = 0; off < 9; ++off) {
    for (std::size_t len = 0; off + len <= 80; ++len) {
      const auto z = static_cast<std::uint32_t>(::crc32(0L, b.data() + off, static_cast<uInt>(len)));
      EXPECT_EQ(crc32(b.data() + off, len), z) << off << " " << len;
    }
  }
  const auto whole = static_cast<std::uint32_t>(::crc32(0L, b.data(), static_cast<uInt>(b.size())));
  for (std::size_t cut = 0; cut <= b.size(); ++cut)
    EXPECT_EQ(crc32(b.data() + cut, b.size() - cut, crc32(b.data(), cut)), whole) << cut;
  // A start value other than 0 (a continued CRC) over a whole number of 8-byte steps.
  const auto z = static_cast<std::uint32_t>(::crc32(0xDEADBEEFUL, b.data(), 64));
  EXPECT_EQ(crc32(b.data(), 64, 0xDEADBEEFU), z);
}

TEST(BaselineFile, RoundTripIsExact) {
  const fs::path dir = temp_dir("roundtrip");
  for (const std::uint32_t n : {4U, 6U, 250U, 256U, 4096U}) {
    const Baseline b = make_baseline(n, n);
    write_baseline(dir / "b.bin", b);
    expect_equal(read_baseline(dir / "b.bin"), b);
  }
  Baseline empty;
  empty.fs_hz = 1.0;
  empty.window_len = 16;
  write_baseline(dir / "e.bin", empty);
  expect_equal(read_baseline(dir / "e.bin"), empty);
  // No temporary file is left behind.
  std::size_t files = 0;
  for (const auto& e : fs::directory_iterator(dir)) {
    EXPECT_EQ(e.path().string().find(".tmp"), std::string::npos) << e.path();
    ++files;
  }
  EXPECT_EQ(files, 2U);
  fs::remove_all(dir);
}

TEST(BaselineFile, ByteLayoutMatchesTheDocumentedTable) {
  const Baseline b = make_baseline(16, 1);
  const Bytes bytes = serialize_baseline(b);
  // Header 90 + per class (41 + 4*9 + 4 + 4*16 + 96 + 216 + v2: 108 log stats + 8 windows/h + 156
  // hold-out) + source length 4 + text + training count 4 + per training recording (4 + id + 4 + path +
  // 8 + 8 + 4) + CRC 4.
  const std::size_t per_class = 41 + 4 * 9 + 4 + 4 * 16 + 96 + 216 + 108 + 8 + 156;
  std::size_t training = 4;
  for (const auto& t : b.training) training += 4 + t.id.size() + 4 + t.path.size() + 8 + 8 + 4;
  ASSERT_EQ(bytes.size(),
            90 + 3 * per_class + 4 + b.source.size() + training + 4 + v4_tail(3) + 4);  // v3 options, v4
  const std::size_t at_training = 90 + 3 * per_class + 4 + b.source.size();
  EXPECT_EQ(bytes[at_training], 2);                            // two training recordings
  EXPECT_EQ(bytes[at_training + 4], b.training[0].id.size());  // the first id's length
  EXPECT_EQ(
      std::string(bytes.begin() + static_cast<std::ptrdiff_t>(at_training + 8),
                  bytes.begin() + static_cast<std::ptrdiff_t>(at_training + 8 + b.training[0].id.size())),
      b.training[0].id);
  EXPECT_EQ(std::string(bytes.begin(), bytes.begin() + 8), "PTDABASE");
  EXPECT_EQ(bytes[8], 4);  // version 4, little-endian
  const std::size_t opt = options_at(bytes, 3);
  EXPECT_EQ(bytes[opt] | bytes[opt + 1] | bytes[opt + 2] | bytes[opt + 3],
            2);  // v3 option flags: bit 1, the floor gain (default); this baseline has no line gain
  std::uint64_t floor_bits = 0;
  for (int i = 0; i < 8; ++i)
    floor_bits |= static_cast<std::uint64_t>(bytes[opt + 4 + static_cast<std::size_t>(i)]) << (8 * i);
  EXPECT_EQ(std::bit_cast<double>(floor_bits), 0.25);                 // v4: day_sd_floor
  EXPECT_EQ(bytes[opt + 12], b.classes[0].day_spread[0].recordings);  // then class 0, method raw
  EXPECT_EQ(bytes[9] | bytes[10] | bytes[11], 0);
  std::uint64_t size = 0;
  for (int i = 0; i < 8; ++i)
    size |= static_cast<std::uint64_t>(bytes[12 + static_cast<std::size_t>(i)]) << (8 * i);
  EXPECT_EQ(size, bytes.size());
  std::uint64_t fs_bits = 0;
  for (int i = 0; i < 8; ++i)
    fs_bits |= static_cast<std::uint64_t>(bytes[20 + static_cast<std::size_t>(i)]) << (8 * i);
  EXPECT_EQ(std::bit_cast<double>(fs_bits), 25600.0);
  EXPECT_EQ(bytes[kOffWindowLen], 16);
  EXPECT_EQ(bytes[32], 0);   // gearbox kind cycloidal
  EXPECT_EQ(bytes[33], 10);  // z_in
  EXPECT_EQ(bytes[53], 1);   // policy kind quantile
  std::uint64_t conf_bits = 0;
  for (int i = 0; i < 8; ++i)
    conf_bits |= static_cast<std::uint64_t>(bytes[70 + static_cast<std::size_t>(i)]) << (8 * i);
  EXPECT_EQ(std::bit_cast<double>(conf_bits), 0.95);  // v2: policy confidence, then hold-out fraction
  EXPECT_EQ(bytes[kOffClassCount], 3);                // class count
  EXPECT_EQ(bytes[kOffClasses], 7);                   // first class id
  EXPECT_EQ(bytes[kOffClasses + 4], 1);               // direction +1
  EXPECT_EQ(bytes[kOffClasses + 37], 9);              // mean_magnitude count N/2+1
  // Second class has direction -1, stored as the byte 0xFF.
  EXPECT_EQ(bytes[kOffClasses + per_class + 4], 0xFF);
  std::uint32_t crc = 0;
  for (int i = 0; i < 4; ++i)
    crc |= static_cast<std::uint32_t>(bytes[bytes.size() - 4 + static_cast<std::size_t>(i)]) << (8 * i);
  EXPECT_EQ(crc, static_cast<std::uint32_t>(::crc32(0L, bytes.data(), static_cast<uInt>(bytes.size() - 4))));
}

// A version-1 file is a version-2 file without the training section: it is still read, with no
// training recordings. Built here from the version-2 bytes exactly as the version-1 writer laid them out.
TEST(BaselineFile, Version1FilesAreStillRead) {
  // The version-1 file written by the build before format 2 (see ReadsVersion1GoldenFile): it has no
  // training list, so it is read with an empty one. Cutting a version-2 stream cannot stand in for it:
  // version 2 also adds per-class and policy fields.
  const fs::path golden =
      fs::path(PTDA_SOURCE_DIR) / "tests" / "data" / "formats" / "baseline_v1_joint_rotation.bin";
  const Bytes v1 = read_file(golden);
  ASSERT_GT(v1.size(), 20U);
  ASSERT_EQ(v1[8], 1);
  const Baseline read = parse_baseline(v1, "v1.bin");
  EXPECT_TRUE(read.training.empty());
  // Written back it becomes version 4 with the same content and still no training list.
  const Baseline again = parse_baseline(serialize_baseline(read), "v2.bin");
  expect_equal(again, read);
  // The same bytes marked version 2 lack the version-2 fields: reported, not misread.
  Bytes v1_as_2 = v1;
  v1_as_2[8] = 2;
  fix_crc(v1_as_2);
  EXPECT_NE(message_of(v1_as_2).find("inconsistent baseline at byte"), std::string::npos)
      << message_of(v1_as_2);
}

// Version 3 appends option flags before the CRC; a version-2 file (the same bytes without them) is read
// with no options, and the line-gain option survives a round trip and prepares the line groups.
TEST(BaselineFile, Version3OptionsAndVersion2Files) {
  Baseline b = make_baseline(8, 2);
  b.policy.ptda_floor_gain = false;  // as a version-2 file reads: no options, no day spread
  b.policy.day_sd_floor = 0.0;
  for (auto& c : b.classes) c.day_spread = {};
  const Bytes v2 = as_version(serialize_baseline(b), 3, 2);
  const Baseline from_v2 = parse_baseline(v2, "v2.bin");
  EXPECT_FALSE(from_v2.policy.ptda_line_gain);
  expect_equal(from_v2, b);
  b.policy.ptda_line_gain = true;
  b.classes[0].mean_magnitude.assign(b.classes[0].mean_magnitude.size(), 1.0F);
  b.classes[0].mean_magnitude[2] = 40.0F;
  const Baseline lg = parse_baseline(serialize_baseline(b), "lg.bin");
  EXPECT_TRUE(lg.policy.ptda_line_gain);
  expect_equal(lg, b);
  ASSERT_EQ(lg.classes[0].line_groups.size(), 1U);  // prepared by the reader: bins [1, 4)
  EXPECT_EQ(lg.classes[0].line_groups[0].begin, 1U);
  EXPECT_EQ(lg.classes[0].line_groups[0].end, 4U);
  EXPECT_FALSE(lg.policy.ptda_floor_gain);
  EXPECT_FALSE(lg.classes[0].floor_gain);
  // Bit 1: the floor gain, also handed to every class by the reader.
  b.policy.ptda_floor_gain = true;
  const Bytes fg_bytes = serialize_baseline(b);
  EXPECT_EQ(fg_bytes[options_at(fg_bytes, 3)], 3U);  // options word (little-endian): bits 0 and 1
  const Baseline fg = parse_baseline(fg_bytes, "fg.bin");
  EXPECT_TRUE(fg.policy.ptda_floor_gain);
  EXPECT_TRUE(fg.classes[0].floor_gain);
  // An unknown bit is refused, naming the known ones.
  Bytes bit2 = fg_bytes;
  bit2[options_at(bit2, 3)] = 7;
  fix_crc(bit2);
  EXPECT_NE(message_of(bit2).find("unknown option bits 0x00000004 (this build knows"), std::string::npos)
      << message_of(bit2);
}

TEST(BaselineFile, EveryCorruptionIsReported) {
  const Bytes good = serialize_baseline(make_baseline(8, 2));
  const std::string n = std::to_string(good.size());

  EXPECT_EQ(message_of({}), "b.bin: not a ptda baseline (bad magic, expected \"PTDABASE\")");
  Bytes magic = good;
  magic[3] = 'X';
  EXPECT_EQ(message_of(magic), "b.bin: not a ptda baseline (bad magic, expected \"PTDABASE\")");
  EXPECT_EQ(message_of(Bytes(good.begin(), good.begin() + 12)),
            "b.bin: truncated: 12 bytes, shorter than the header");
  EXPECT_EQ(message_of(Bytes(good.begin(), good.end() - 10)),
            "b.bin: truncated: header says " + n + " bytes, file has " + std::to_string(good.size() - 10));
  Bytes longer = good;
  longer.push_back(0);
  EXPECT_EQ(message_of(longer), "b.bin: corrupt: header says " + n + " bytes, file has " +
                                    std::to_string(good.size() + 1) + " (trailing bytes)");
  Bytes version = good;
  // Version 8 (session 19, the mesh detector's statistics) is the newest readable one.
  version[8] = 9;
  EXPECT_EQ(message_of(version), "b.bin: unsupported baseline format version 9 (this build reads 1 to 8)");
  version[8] = 0;
  EXPECT_EQ(message_of(version), "b.bin: unsupported baseline format version 0 (this build reads 1 to 8)");
  Bytes flipped = good;
  flipped[good.size() / 2] ^= 0x01;
  const std::string crc_msg = message_of(flipped);
  EXPECT_EQ(crc_msg.rfind("b.bin: corrupt: CRC-32 mismatch (stored 0x", 0), 0U) << crc_msg;

  // Structural errors behind a valid CRC (a buggy writer or a hand-made file).
  Bytes wrong_n = good;
  put_u32(wrong_n, kOffWindowLen, 10);  // N = 10 needs 6 magnitudes; the file has 5
  fix_crc(wrong_n);
  EXPECT_EQ(message_of(wrong_n), "b.bin: inconsistent baseline at byte " + std::to_string(kOffClasses + 41) +
                                     ": class 0: mean_magnitude has 5 values, window_len 10 needs N/2+1 = 6");
  Bytes dir = good;
  dir[kOffClasses + 4] = 0;
  fix_crc(dir);
  EXPECT_EQ(message_of(dir), "b.bin: inconsistent baseline at byte " + std::to_string(kOffClasses + 5) +
                                 ": class 0: direction must be +1 or -1, got 0");
  Bytes classes = good;
  put_u32(classes, kOffClassCount, 1000000);
  fix_crc(classes);
  EXPECT_EQ(
      message_of(classes).rfind("b.bin: inconsistent baseline at byte 90: 1000000 classes cannot fit", 0),
      0U);
  Bytes policy = good;
  policy[53] = 9;
  fix_crc(policy);
  EXPECT_EQ(message_of(policy),
            "b.bin: inconsistent baseline at byte 54: unknown threshold policy kind 9 for format version 4");
  const Baseline gb = make_baseline(8, 2);
  std::size_t training = 4;
  for (const auto& t : gb.training) training += 4 + t.id.size() + 4 + t.path.size() + 8 + 8 + 4;
  const std::size_t at_training =
      good.size() - 4 - v4_tail(3) - 4 - training;  // CRC, v4 day spread, v3 options, training list
  Bytes src = good;
  put_u32(src, at_training - gb.source.size() - 4, 5);  // source shorter than stored: misaligned
  fix_crc(src);
  EXPECT_EQ(message_of(src).rfind("b.bin: inconsistent baseline at byte", 0), 0U) << message_of(src);
  Bytes fewer = good;
  put_u32(fewer, at_training, 1);  // one training recording of the two stored: the rest is misread
  fix_crc(fewer);
  // The second recording's bytes are then read as the v3 option flags: a located error either way.
  EXPECT_EQ(message_of(fewer).rfind("b.bin: inconsistent baseline at byte", 0), 0U) << message_of(fewer);
  Bytes options = good;
  put_u32(options, options_at(good, 3), 0xCU);  // bits 2 and 3 mean nothing to this build
  fix_crc(options);
  EXPECT_EQ(
      message_of(options),
      "b.bin: inconsistent baseline at byte " + std::to_string(options_at(good, 3) + 4) +
          ": unknown option bits 0x0000000C (this build knows bit 0, line_gain, and bit 1, floor_gain)");

  // The same checks through the file API name the path.
  const fs::path d = temp_dir("corrupt");
  write_file(d / "c.bin", flipped);
  try {
    (void)read_baseline(d / "c.bin");
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind((d / "c.bin").string() + ": corrupt: CRC-32 mismatch", 0), 0U)
        << e.what();
  }
  try {
    (void)read_baseline(d / "missing.bin");
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), (d / "missing.bin").string() + ": baseline file not found");
  }
  try {
    (void)read_baseline(d);
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), d.string() + ": is a directory, not a baseline file");
  }
  fs::remove_all(d);
}

// A version 1 file written by ptda before format 2 (commit b930fd4: `ptda train` on `ptda simulate
// --scenario config/scenarios/joint_rotation_healthy.toml --seed 1001` with config/examples/
// joint_rotation.toml at window_len = hop = 256). The values below are what that build printed.
TEST(BaselineFile, ReadsVersion1GoldenFile) {
  const fs::path golden =
      fs::path(PTDA_SOURCE_DIR) / "tests" / "data" / "formats" / "baseline_v1_joint_rotation.bin";
  const Bytes bytes = read_file(golden);
  ASSERT_GT(bytes.size(), 20U);
  EXPECT_EQ(bytes[8], 1);
  const Baseline b = read_baseline(golden);
  EXPECT_EQ(b.fs_hz, 25600.0);
  EXPECT_EQ(b.window_len, 256U);
  EXPECT_EQ(b.policy.kind, ptda::dsp::ThresholdPolicy::Kind::kGaussian);
  EXPECT_EQ(b.policy.false_alarm_rate, 1e-3);
  EXPECT_EQ(b.policy.holdout_fraction, 0.0);  // not in version 1: defaults
  EXPECT_EQ(b.policy.confidence, 0.9);
  ASSERT_EQ(b.classes.size(), 2U);
  const auto ptda_m = static_cast<std::size_t>(ptda::dsp::Method::kPtda);
  const auto& c0 = b.classes[0];
  EXPECT_EQ(c0.segment.direction, 1);
  EXPECT_EQ(c0.segment.regions, 20U);
  EXPECT_EQ(c0.n_windows, 20U);
  EXPECT_NEAR(c0.thresholds[ptda_m].rms.lo, 0.22121, 5e-6);
  EXPECT_NEAR(c0.thresholds[ptda_m].rms.hi, 0.3668, 5e-5);
  EXPECT_NEAR(c0.rms_stats[ptda_m].mean, 0.29401, 5e-6);
  EXPECT_EQ(b.classes[1].segment.direction, -1);
  EXPECT_NEAR(b.classes[1].entropy_stats[ptda_m].mean, 0.84372, 5e-6);
  // Log statistics derived by the delta method: sd_log = sd / mean, mean_log = ln(mean) - sd_log^2/2.
  const auto& s = c0.rms_stats[ptda_m];
  EXPECT_DOUBLE_EQ(c0.log_rms_stats[ptda_m].stddev, s.stddev / s.mean);
  EXPECT_DOUBLE_EQ(c0.log_rms_stats[ptda_m].mean,
                   std::log(s.mean) - 0.5 * (s.stddev / s.mean) * (s.stddev / s.mean));
  EXPECT_EQ(c0.holdout[ptda_m].windows, 0U);
  EXPECT_EQ(c0.windows_per_hour, 0.0);
  // Written back, it becomes a version 4 file with the same content (floor 0, no day spread).
  const Bytes v4 = serialize_baseline(b);
  EXPECT_EQ(v4[8], 4);
  expect_equal(parse_baseline(v4, "v4"), b);
}

namespace {

void put_u64(Bytes& b, std::size_t at, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) b[at + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(v >> (8 * i));
}
// A copy of `good` with the double at `at` replaced and the CRC recomputed: a forged file the CRC
// cannot catch.
Bytes forged_f64(const Bytes& good, std::size_t at, double v) {
  Bytes b = good;
  put_u64(b, at, std::bit_cast<std::uint64_t>(v));
  fix_crc(b);
  return b;
}
Bytes forged_f32(const Bytes& good, std::size_t at, float v) {
  Bytes b = good;
  put_u32(b, at, std::bit_cast<std::uint32_t>(v));
  fix_crc(b);
  return b;
}
Bytes forged_u32(const Bytes& good, std::size_t at, std::uint32_t v) {
  Bytes b = good;
  put_u32(b, at, v);
  fix_crc(b);
  return b;
}

}  // namespace

// Issue 14 item 4: a CRC-valid baseline with NaN, infinite or inverted bands, a zero spread or counts
// that disagree is refused with the class, method and field, instead of blinding the monitor.
TEST(BaselineFile, ForgedValuesAreRefusedWithTheirLocation) {
  const Bytes good = serialize_baseline(make_baseline(8, 2));
  ASSERT_NO_THROW((void)parse_baseline(good, "b.bin"));
  // Offsets within a class record for window_len 8 (docs/recording-format.md): 5 mean magnitudes,
  // 8 TDA samples, then 3 x 32 bytes of bands, 3 x 36 of each statistics block, 8 windows/h, 3 x 52
  // hold-out.
  constexpr std::size_t kPerClass = 681;
  const auto cls = [](std::size_t i) { return kOffClasses + i * kPerClass; };
  const auto band = [&](std::size_t i, std::size_t m) { return cls(i) + 97 + 32 * m; };
  const auto rms_stats = [&](std::size_t i, std::size_t m) { return cls(i) + 193 + 36 * m; };
  const auto log_stats = [&](std::size_t i, std::size_t m) { return cls(i) + 409 + 36 * m; };
  const auto holdout = [&](std::size_t i, std::size_t m) { return cls(i) + 525 + 52 * m; };
  const double inf = std::numeric_limits<double>::infinity();
  const std::string p = "b.bin: implausible baseline: ";

  EXPECT_EQ(message_of(forged_f64(good, 20, inf)), p + "fs_hz is inf, must be > 0 and <= 10000000");
  EXPECT_EQ(message_of(forged_f64(good, 54, 2.0)), p + "policy false_alarm_rate is 2, must be in (0, 1)");
  EXPECT_EQ(message_of(forged_f64(good, cls(0) + 5, inf)),
            p + "class 0 (id 7): speed_rad_s is inf, not a finite number");
  EXPECT_EQ(message_of(forged_f64(good, cls(2) + 5, 0.0)),
            p + "class 2 (id 9): speed_rad_s is 0, must be > 0 (a constant-speed class)");
  EXPECT_EQ(message_of(forged_f32(good, cls(0) + 41 + 4 * 3, -1.0F)),
            p + "class 0 (id 7): mean_magnitude[3] is -1, must be >= 0");
  EXPECT_EQ(message_of(forged_f32(good, cls(1) + 65 + 4 * 6, std::numeric_limits<float>::quiet_NaN())),
            p + "class 1 (id 8): tda_mean[6] is nan, not a finite number");
  // Bands: NaN, infinite, inverted (lo >= hi), an rms_res band entirely below 0.
  EXPECT_EQ(message_of(forged_f64(good, band(1, 2) + 8, std::numeric_limits<double>::quiet_NaN())),
            p + "class 1 (id 8): method ptda, rms_res band hi is nan, not a finite number");
  EXPECT_EQ(message_of(forged_f64(good, band(0, 1) + 16, -inf)),
            p + "class 0 (id 7): method tda, entropy_res band lo is -inf, not a finite number");
  EXPECT_EQ(message_of(forged_f64(good, band(0, 1) + 16, 1e6))
                .rfind(p + "class 0 (id 7): method tda, entropy_res band is [1000000, ", 0),
            0U);
  EXPECT_NE(message_of(forged_f64(good, band(0, 1) + 16, 1e6)).find("], needs lo < hi"), std::string::npos);
  Bytes below = forged_f64(good, band(2, 0), -2.0);
  below = forged_f64(below, band(2, 0) + 8, -1.0);
  EXPECT_EQ(message_of(below),
            p + "class 2 (id 9): method raw, rms_res band hi is -1, must be > 0 (rms_res >= 0)");
  // Statistics: a zero or negative spread, NaN, more windows than the class has.
  EXPECT_EQ(message_of(forged_f64(good, rms_stats(2, 0) + 8, 0.0))
                .rfind(p + "class 2 (id 9): method raw, rms_res stats stddev is 0 over ", 0),
            0U);
  EXPECT_EQ(message_of(forged_f64(good, log_stats(1, 2) + 8, -0.5)),
            p + "class 1 (id 8): method ptda, ln(rms_res) stats stddev is -0.5, must be >= 0");
  EXPECT_EQ(message_of(forged_f64(good, rms_stats(0, 2), std::numeric_limits<double>::quiet_NaN())),
            p + "class 0 (id 7): method ptda, rms_res stats mean is nan, not a finite number");
  EXPECT_EQ(message_of(forged_u32(good, rms_stats(0, 1) + 32, 1000)),
            p + "class 0 (id 7): method tda, rms_res stats n is 1000, more than the class's 40 windows");
  // Hold-out: more abnormal windows than scored, a NaN z spread.
  Bytes held = forged_u32(good, holdout(1, 0), 3);
  held = forged_u32(held, holdout(1, 0) + 4, 4);
  EXPECT_EQ(message_of(held),
            p + "class 1 (id 8): method raw, hold-out abnormal is 4, more than its 3 windows");
  EXPECT_EQ(message_of(forged_f64(good, holdout(0, 2) + 28, std::numeric_limits<double>::quiet_NaN())),
            p + "class 0 (id 7): method ptda, hold-out z_rms_sd is nan, not a finite number");
  // Class speeds and window counts.
  EXPECT_EQ(message_of(forged_u32(good, cls(1) + 33, 0)),
            p + "class 1 (id 8): n_windows is 0 (a class is trained on at least one window)");

  // Through the file API the path leads the message, and the writer refuses the same values.
  const fs::path d = temp_dir("forged");
  write_file(d / "f.bin", forged_f64(good, band(1, 2) + 8, inf));
  try {
    (void)read_baseline(d / "f.bin");
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), (d / "f.bin").string() +
                                         ": implausible baseline: class 1 (id 8): method "
                                         "ptda, rms_res band hi is inf, not a finite number");
  }
  Baseline bad = make_baseline(8, 2);
  bad.classes[2].entropy_stats[1].stddev = 0.0;
  try {
    write_baseline(d / "w.bin", bad);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(
        std::string(e.what()).find(": not written: baseline: implausible baseline: class 2 (id 9): method "
                                   "tda, entropy_res stats stddev is 0 over "),
        std::string::npos)
        << e.what();
  }
  EXPECT_FALSE(fs::exists(d / "w.bin"));
  fs::remove_all(d);
}

// Issue 14 item 8: as root, a baseline others can write is refused with the fix.
TEST(BaselineFile, WorldWritableBaselineIsRefusedAsRoot) {
  if (::geteuid() != 0) GTEST_SKIP() << "needs euid 0 (FileCheckTest covers the check with an injected euid)";
  const fs::path d = temp_dir("writable");
  write_baseline(d / "b.bin", make_baseline(8, 4));
  ASSERT_EQ(::chmod((d / "b.bin").c_str(), 0666), 0);
  try {
    (void)read_baseline(d / "b.bin");
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()),
              (d / "b.bin").string() +
                  ": baseline file is world-writable (mode 0666) and ptda runs as root: another user could "
                  "change what it does. Fix: chmod go-w " +
                  (d / "b.bin").string());
  }
  ASSERT_EQ(::chmod((d / "b.bin").c_str(), 0644), 0);
  EXPECT_NO_THROW((void)read_baseline(d / "b.bin"));
  fs::remove_all(d);
}

TEST(BaselineFile, InconsistentBaselineIsNotWritten) {
  const fs::path dir = temp_dir("inconsistent");
  Baseline b = make_baseline(8, 3);
  b.classes[1].tda_mean.pop_back();
  try {
    write_baseline(dir / "b.bin", b);
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()),
              (dir / "b.bin").string() +
                  ": not written: baseline: class 1 (id 8): tda_mean has 7 values, window_len is 8");
  }
  EXPECT_FALSE(fs::exists(dir / "b.bin"));
  b = make_baseline(8, 3);
  b.window_len = 0;
  EXPECT_THROW(write_baseline(dir / "b.bin", b), Error);
  b = make_baseline(8, 3);
  b.classes[2].segment.direction = 0;
  EXPECT_THROW(write_baseline(dir / "b.bin", b), Error);
  EXPECT_TRUE(fs::is_empty(dir));
  fs::remove_all(dir);
}

// Issue 14 item 2: the old writer opened "<path>.tmp.<pid>" O_CREAT|O_TRUNC without O_NOFOLLOW, so a
// symlink planted there (a baseline directory writable by another user) made ptdad (root) overwrite
// the file it pointed to. Now the temporary name is random and created O_EXCL|O_NOFOLLOW.
TEST(BaselineFile, SymlinkAtThePredictableTemporaryNameIsNotFollowed) {
  const fs::path dir = temp_dir("symlink");
  const fs::path victim_dir = temp_dir("symlink_victim");
  const fs::path victim = victim_dir / "victim";
  {
    std::ofstream out(victim, std::ios::binary);
    out << "not a baseline";
  }
  const fs::path p = dir / "baseline.bin";
  fs::create_symlink(victim, dir / ("baseline.bin.tmp." + std::to_string(::getpid())));
  fs::create_symlink(victim, dir / "baseline.bin.tmp");
  const Baseline b = make_baseline(16, 3);
  write_baseline(p, b);
  expect_equal(read_baseline(p), b);
  std::ifstream in(victim, std::ios::binary);
  const std::string victim_text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(victim_text, "not a baseline");
  EXPECT_FALSE(fs::is_symlink(p));
  fs::remove_all(dir);
  fs::remove_all(victim_dir);
}

TEST(BaselineFile, FailedWriteLeavesPreviousFileIntact) {
  const fs::path dir = temp_dir("atomic");
  const Baseline a = make_baseline(32, 10);
  const Baseline b = make_baseline(64, 11);
  const fs::path p = dir / "baseline.bin";
  write_baseline(p, a);
  const Bytes before = read_file(p);

  // 1. The target path is a directory: rename fails, the temporary file is removed.
  const fs::path as_dir = dir / "sub";
  fs::create_directories(as_dir / "keep");
  try {
    write_baseline(as_dir, b);
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind(as_dir.string() + ": writing baseline failed at rename: ", 0), 0U)
        << e.what();
  }
  EXPECT_TRUE(fs::is_directory(as_dir / "keep"));

  // 2. The parent "directory" is a regular file: the temporary file cannot be created.
  try {
    write_baseline(p / "x.bin", b);
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(
        std::string(e.what()),
        (p / "x.bin").string() + ": writing baseline failed at open of the temporary file: Not a directory");
  }

  // 3. A read-only directory (only meaningful when not root: root ignores the permission bits).
  if (::geteuid() != 0) {
    fs::permissions(dir, fs::perms::owner_read | fs::perms::owner_exec);
    EXPECT_THROW(write_baseline(p, b), Error);
    fs::permissions(dir, fs::perms::owner_all);
  }

  EXPECT_EQ(read_file(p), before);
  expect_equal(read_baseline(p), a);
  for (const auto& e : fs::directory_iterator(dir))
    EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos) << e.path();

  // A successful write replaces the file as a whole.
  write_baseline(p, b);
  expect_equal(read_baseline(p), b);
  fs::remove_all(dir);
}

namespace {

// Version 4 appends the between-day floor and the day spreads; a version-3 file (the same bytes without
// them) reads with floor 0 and no day spread, which the sequential detector takes as the session-6
// standardisation: no between-day allowance, the stats' own sd.
TEST(BaselineFile, Version4DaySpreadAndVersion3Files) {
  Baseline b = make_baseline(8, 2);
  const Bytes v4 = serialize_baseline(b);
  expect_equal(parse_baseline(v4, "v4.bin"), b);
  const Baseline from_v3 = parse_baseline(as_version(v4, 3, 3), "v3.bin");
  EXPECT_EQ(from_v3.policy.day_sd_floor, 0.0);
  for (const auto& c : from_v3.classes) {
    for (std::size_t m = 0; m < ptda::dsp::kMethodCount; ++m) {
      EXPECT_EQ(c.day_spread[m].recordings, 0U);
      const ptda::dsp::SeqScale z =
          ptda::dsp::sequential_scale(c, static_cast<ptda::dsp::Method>(m), from_v3.policy, 3.0);
      EXPECT_EQ(z.rms_allowance, 0.0);
      EXPECT_EQ(z.log_rms.stddev, c.log_rms_stats[m].stddev);
    }
  }
  // A negative spread is refused with its location.
  b.classes[1].day_spread[2].entropy_between_sd = -1.0;
  try {
    (void)serialize_baseline(b);
    FAIL() << "negative day spread written";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("class 1 (id 8): method ptda, day spread entropy between sd is -1"),
              std::string::npos)
        << e.what();
  }
  // Truncated inside the day spreads: a located structural error.
  Bytes cut(v4.begin(), v4.end() - 4 - 52);
  put_u32(cut, 12, static_cast<std::uint32_t>(cut.size() + 4));
  cut.resize(cut.size() + 4);
  fix_crc(cut);
  EXPECT_NE(message_of(cut).find("inconsistent baseline at byte"), std::string::npos) << message_of(cut);
}

// Version 7 (session 12): the band CUSUM's statistics, written only when the policy has a band count;
// the same baseline without them is still written as version 4, byte for byte as before.
TEST(BaselineFile, Version7BandStatisticsRoundTripAndOnlyWhenPresent) {
  Baseline b = make_baseline(16, 5);
  const Bytes v4 = serialize_baseline(b);
  EXPECT_EQ(v4[8], 4U);
  b.policy.band_count = 4;
  std::uint32_t seed = 1;
  for (auto& c : b.classes) {
    c.band_recordings = 3;
    for (std::uint32_t k = 0; k < 4; ++k) {
      c.band_stats.push_back({-3.0 + 0.25 * seed, 0.5 + 0.01 * k, 0.1 * k, 0.15 + 0.1 * k, k + 1});
      ++seed;
    }
  }
  const Bytes v7 = serialize_baseline(b);
  EXPECT_EQ(v7[8], 7U);
  // After the version-4 body: domain u8 + S u32 + R u32, band_count u32, per class u32 + 4 x 36 bytes.
  EXPECT_EQ(v7.size(), v4.size() + 9 + 4 + b.classes.size() * (4 + 4 * 36));
  const Baseline back = parse_baseline(v7, "v7.bin");
  EXPECT_EQ(back.policy.band_count, 4U);
  expect_equal(back, b);
  // Without band statistics nothing changed: the bytes of the version-4 file.
  Baseline plain = back;
  plain.policy.band_count = 0;
  for (auto& c : plain.classes) {
    c.band_stats.clear();
    c.band_recordings = 0;
  }
  EXPECT_EQ(serialize_baseline(plain), v4);
  EXPECT_EQ(parse_baseline(v4, "v4.bin").policy.band_count, 0U);
  // A negative sd and a count that disagrees with the policy are refused with their location.
  Baseline bad = b;
  bad.classes[1].band_stats[2].within_sd = -1.0;
  try {
    (void)serialize_baseline(bad);
    FAIL() << "negative band sd written";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("class 1 (id 8): band 2 statistics"), std::string::npos) << e.what();
  }
  bad = b;
  bad.classes[0].band_stats.pop_back();
  try {
    (void)serialize_baseline(bad);
    FAIL() << "short band statistics written";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("3 band statistics, the policy's band_count is 4"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace

namespace ptda::formats {
namespace {

TEST(BaselineFile, Version8MeshStatisticsRoundTripWithAndWithoutBands) {
  Baseline b = make_baseline(16, 5);
  const Bytes v4 = serialize_baseline(b);
  b.policy.mesh_stats = true;
  std::uint32_t seed = 1;
  for (auto& c : b.classes) {
    c.mesh_recordings = 2;
    c.mesh_stats = {{0.1 * seed, 0.2, 0.05, 0.06, 40 + seed}, {-0.05 * seed, 0.3, 0.0, 0.09, 41 + seed}};
    ++seed;
  }
  b.classes[0].mesh_stats[1] = {};  // a class without pm (too slow, or no mesh line): windows 0
  const Bytes v8 = serialize_baseline(b);
  EXPECT_EQ(v8[8], 8U);
  // After the version-4 body: domain u8 + S u32 + R u32, band_count u32 (0, no band records), then per
  // class u32 + 2 x 36 bytes.
  EXPECT_EQ(v8.size(), v4.size() + 9 + 4 + b.classes.size() * (4 + 2 * 36));
  const Baseline back = parse_baseline(v8, "v8.bin");
  EXPECT_TRUE(back.policy.mesh_stats);
  EXPECT_EQ(back.policy.band_count, 0U);
  expect_equal(back, b);
  // With band statistics as well: both blocks come back.
  b.policy.band_count = 2;
  for (auto& c : b.classes) {
    c.band_recordings = 2;
    c.band_stats = {{-3.0, 0.5, 0.1, 0.15, 3}, {-2.0, 0.4, 0.0, 0.12, 4}};
  }
  const Bytes v8b = serialize_baseline(b);
  EXPECT_EQ(v8b.size(), v8.size() + b.classes.size() * (4 + 2 * 36));
  expect_equal(parse_baseline(v8b, "v8b.bin"), b);
  // A mesh count that disagrees with the policy, and a zero within sd with windows, are refused.
  Baseline bad = b;
  bad.classes[1].mesh_stats.pop_back();
  try {
    (void)serialize_baseline(bad);
    FAIL() << "short mesh statistics written";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("1 mesh statistics, the policy has mesh detector"),
              std::string::npos)
        << e.what();
  }
  bad = b;
  bad.classes[1].mesh_stats[0].within_sd = 0.0;
  try {
    (void)serialize_baseline(bad);
    FAIL() << "zero mesh sd written";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("class 1 (id 8): mesh feature am has"), std::string::npos)
        << e.what();
  }
  // A mesh block cut short (size and CRC re-sealed, so only the block's own bound can catch it) is
  // reported, not read past.
  Bytes cut(v8.begin(), v8.end() - 4 - 36);
  put_u32(cut, 12, static_cast<std::uint32_t>(cut.size() + 4));
  cut.resize(cut.size() + 4);
  fix_crc(cut);
  try {
    (void)parse_baseline(cut, "cut.bin");
    FAIL() << "truncated mesh block read";
  } catch (const Error& e) {
    EXPECT_NE(
        std::string(e.what()).find("the mesh statistics of 3 classes cannot fit in the remaining 192 bytes"),
        std::string::npos)
        << e.what();
  }
  // Forged statistics an autocorrelation cannot have are refused.
  bad = b;
  bad.classes[2].mesh_stats[1].mean = 40.0;
  try {
    (void)serialize_baseline(bad);
    FAIL() << "forged mesh mean written";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("mesh feature pm statistics"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace ptda::formats
