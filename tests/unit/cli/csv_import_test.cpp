// `ptda import`: CSV / CSV.gz column reading (names, indices, every malformed-input error with file,
// line and column) and the recording it writes (WAV samples, constant-speed CAN log, recording.toml).
#include "ptda/cli/csv_import.hpp"

#include <gtest/gtest.h>
#include <zlib.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>

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
  const fs::path dir = base / "cli_csv_import" / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

fs::path write_text(const fs::path& p, const std::string& text) {
  std::ofstream f(p, std::ios::binary);
  f << text;
  return p;
}

fs::path write_gz(const fs::path& p, const std::string& text) {
  gzFile g = gzopen(p.string().c_str(), "wb");
  EXPECT_NE(g, nullptr);
  EXPECT_EQ(gzwrite(g, text.data(), static_cast<unsigned>(text.size())), static_cast<int>(text.size()));
  gzclose(g);
  return p;
}

std::string error_of(const fs::path& p, const std::string& column) {
  try {
    (void)read_csv_column(p, column);
  } catch (const Error& e) {
    return e.what();
  }
  return "<no error>";
}

const std::string kCsv = "a1,a2,a3,a4\n1.5,-2,3e-3,4\n0.25,+5,-6.5,7\n-8,9,10,11\n";

TEST(ReadCsvColumn, ByNameAndByIndex) {
  const auto dir = scratch("by_name");
  const auto p = write_text(dir / "x.csv", kCsv);
  const CsvColumn by_name = read_csv_column(p, "a2");
  EXPECT_EQ(by_name.index, 1U);
  EXPECT_EQ(by_name.name, "a2");
  EXPECT_EQ(by_name.columns, 4U);
  EXPECT_EQ(by_name.data_rows, 3);
  EXPECT_EQ(by_name.values, (std::vector<float>{-2.0F, 5.0F, 9.0F}));
  const CsvColumn by_index = read_csv_column(p, "2");
  EXPECT_EQ(by_index.name, "a3");
  EXPECT_EQ(by_index.values, (std::vector<float>{3e-3F, -6.5F, 10.0F}));
}

TEST(ReadCsvColumn, NameWinsOverIndexAndQuotesAreStripped) {
  const auto dir = scratch("name_wins");
  const auto p = write_text(dir / "x.csv", "\"1\", \"b\"\n10,20\n");
  EXPECT_EQ(read_csv_column(p, "1").values, (std::vector<float>{10.0F}));  // the column named "1"
  EXPECT_EQ(read_csv_column(p, "b").values, (std::vector<float>{20.0F}));
}

TEST(ReadCsvColumn, GzipAndPlainGiveTheSameValues) {
  const auto dir = scratch("gz");
  std::string big = "a,b\n";
  for (int i = 0; i < 50000; ++i) big += std::to_string(i) + "," + std::to_string(0.001 * i) + "\n";
  const auto plain = write_text(dir / "big.csv", big);
  const auto gz = write_gz(dir / "big.csv.gz", big);
  const CsvColumn a = read_csv_column(plain, "b");
  const CsvColumn b = read_csv_column(gz, "b");
  ASSERT_EQ(a.values.size(), 50000U);
  EXPECT_EQ(a.values, b.values);
  EXPECT_EQ(b.values[49999], static_cast<float>(49.999));
  EXPECT_LT(fs::file_size(gz), fs::file_size(plain));  // it really was compressed
}

TEST(ReadCsvColumn, CrLfAndMissingFinalNewlineAndTrailingBlankLines) {
  const auto dir = scratch("crlf");
  EXPECT_EQ(read_csv_column(write_text(dir / "a.csv", "x\r\n1\r\n2"), "x").values,
            (std::vector<float>{1.0F, 2.0F}));
  EXPECT_EQ(read_csv_column(write_text(dir / "b.csv", "x\n1\n2\n\n\n"), "x").values,
            (std::vector<float>{1.0F, 2.0F}));
}

TEST(ReadCsvColumn, MalformedCellNamesFileLineAndColumn) {
  const auto dir = scratch("malformed");
  const auto p = write_text(dir / "bad.csv", "a1,a2,a3\n1,2,3\n4,x5,6\n");
  // Line 3, cell 2, even though only a1 is imported: no cell is skipped silently.
  EXPECT_EQ(error_of(p, "a1"), p.string() + ":3:2: not a number 'x5' in column 'a2'");
  const auto q = write_text(dir / "empty_cell.csv", "a1,a2\n1,2\n3,\n");
  EXPECT_EQ(error_of(q, "a1"), q.string() + ":3:2: empty cell in column 'a2'");
  const auto r = write_text(dir / "nan.csv", "a1\n1\nnan\n");
  EXPECT_EQ(error_of(r, "a1"), r.string() + ":3:1: not a finite number 'nan' in column 'a1'");
  const auto s = write_text(dir / "trailing.csv", "a1\n1.5.2\n");
  EXPECT_EQ(error_of(s, "a1"), s.string() + ":2:1: not a number '1.5.2' in column 'a1'");
}

TEST(ReadCsvColumn, WrongCellCountAndBlankLinesInside) {
  const auto dir = scratch("count");
  const auto p = write_text(dir / "short.csv", "a,b,c\n1,2,3\n4,5\n");
  EXPECT_EQ(error_of(p, "a"), p.string() + ":3:3: 2 cell(s) but the header has 3");
  const auto q = write_text(dir / "long.csv", "a,b\n1,2,3\n");
  EXPECT_EQ(error_of(q, "a"), q.string() + ":2:3: 3 cell(s) but the header has 2");
  const auto r = write_text(dir / "blank.csv", "a\n1\n\n2\n");
  EXPECT_EQ(error_of(r, "a"),
            r.string() + ":3: blank line inside the data (only allowed at the end of the file)");
}

TEST(ReadCsvColumn, EmptyFileHeaderOnlyAndMissingColumn) {
  const auto dir = scratch("empty");
  const auto p = write_text(dir / "empty.csv", "");
  EXPECT_EQ(error_of(p, "a"),
            p.string() + ":1: empty file or blank first line: expected a header line of column names");
  const auto gz = write_gz(dir / "empty.csv.gz", "");
  EXPECT_EQ(error_of(gz, "a"),
            gz.string() + ":1: empty file or blank first line: expected a header line of column names");
  const auto h = write_text(dir / "header.csv", "a,b\n");
  EXPECT_EQ(error_of(h, "a"), h.string() + ": no data rows after the header line");
  const auto c = write_text(dir / "cols.csv", "a1,a2\n1,2\n");
  EXPECT_EQ(error_of(c, "a9"), c.string() + ":1: no column named 'a9' (header: a1, a2)");
  EXPECT_EQ(error_of(c, "2"),
            c.string() + ":1: column index 2 out of range: the header has 2 column(s) (0-based)");
  EXPECT_EQ(error_of(dir / "nope.csv", "a"), (dir / "nope.csv").string() + ": file does not exist");
}

TEST(ReadCsvColumn, TruncatedGzipIsAnError) {
  const auto dir = scratch("truncated");
  std::string big = "a\n";
  for (int i = 0; i < 20000; ++i) big += std::to_string(i * 7919 % 10007) + "\n";
  const auto gz = write_gz(dir / "t.csv.gz", big);
  const auto size = fs::file_size(gz);
  fs::resize_file(gz, size / 2);
  const std::string msg = error_of(gz, "a");
  EXPECT_NE(msg.find(gz.string() + ":"), std::string::npos) << msg;
  EXPECT_NE(msg.find("read error"), std::string::npos) << msg;
}

TEST(ImportCsv, WritesRecordingWithConstantSpeedCanLog) {
  const auto dir = scratch("import");
  std::string text = "a1,a2\n";
  for (int i = 0; i < 1000; ++i) text += std::to_string(i) + "," + std::to_string(-0.5 * i) + "\n";
  ImportOptions o;
  o.csv = write_gz(dir / "in.csv.gz", text);
  o.column = "a2";
  o.rate_hz = 10000.0;  // 1000 samples = 0.1 s
  o.shaft_speed_rad_s = 30.0 * 2.0 * std::numbers::pi;
  o.out_dir = dir / "rec";
  o.scale = 0.5;
  o.start_time_s = 1700000000.0;
  const ImportSummary s = import_csv(o);
  EXPECT_EQ(s.samples, 1000U);
  EXPECT_DOUBLE_EQ(s.duration_s, 0.1);
  EXPECT_EQ(s.column_index, 1U);
  EXPECT_EQ(s.min_value, -499.5F);
  EXPECT_EQ(s.max_value, 0.0F);
  // 0.1 s / 4 ms = 25 periods plus the frame at t = 0: 26 frames, the last at 0.1 s (after the last sample).
  EXPECT_EQ(s.speed_frames, 26U);

  const formats::RecordingMeta meta = formats::read_recording_meta(o.out_dir);
  EXPECT_EQ(meta.start_time_s, 1700000000.0);
  EXPECT_EQ(meta.scale, 0.5);
  EXPECT_EQ(meta.unit, "m/s^2");
  formats::WavInfo info;
  const auto samples = formats::read_wav_channel(o.out_dir / meta.vibration_file, 0, &info);
  EXPECT_EQ(info.sample_rate_hz, 10000U);
  EXPECT_EQ(info.format, formats::WavSampleFormat::kFloat32);
  ASSERT_EQ(samples.size(), 1000U);
  EXPECT_EQ(samples[0], 0.0F);
  EXPECT_EQ(samples[999], -499.5F);  // stored as is; scale is in recording.toml

  const auto frames = formats::read_candump(o.out_dir / meta.can_file);
  ASSERT_EQ(frames.size(), 26U);
  const config::SpeedFrameSpec spec;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    config::DecodedSpeed d;
    ASSERT_EQ(config::decode_speed(frames[i].frame, spec, d), config::DecodeResult::kOk);
    EXPECT_NEAR(d.speed_rad_s, 188.4955592153876, 0.5e-4);  // 1e-4 rad/s resolution
    EXPECT_EQ(frames[i].frame.t_ns, 1'700'000'000'000'000'000LL + static_cast<std::int64_t>(i) * 4'000'000LL);
    // angle = speed * t wrapped to [0, 2 pi), 1e-5 rad resolution
    const double expected =
        std::fmod(188.4955592153876 * 0.004 * static_cast<double>(i), 2.0 * std::numbers::pi);
    EXPECT_NEAR(d.angle_rad, expected, 1e-5) << i;
  }
  EXPECT_GE(ns_to_seconds(frames.back().frame.t_ns - frames.front().frame.t_ns), 0.1);
}

}  // namespace
}  // namespace ptda::cli
