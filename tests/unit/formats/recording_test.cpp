// recording.toml: round trip and one hand-written malformed file per rule, each with file:line:column.
#include "ptda/formats/recording.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "ptda/common/error.hpp"
#include "ptda/formats/candump.hpp"
#include "ptda/formats/wav.hpp"

namespace fs = std::filesystem;
using ptda::Error;
using ptda::formats::read_recording_meta;
using ptda::formats::RecordingMeta;
using ptda::formats::write_recording_meta;

namespace {

class RecordingTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const char* env = std::getenv("PTDA_TEST_TMP");
    dir_ =
        (env != nullptr ? fs::path(env) : fs::temp_directory_path()) /
        ("formats_recording_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) +
         "_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    // A 2-channel WAV and an empty CAN log: the files a valid recording.toml refers to.
    ptda::formats::write_wav(dir_ / "vibration.wav", 1000, ptda::formats::WavSampleFormat::kPcm16,
                             {{1, 2}, {3, 4}});
    ptda::formats::write_candump(dir_ / "can.log", {});
  }
  void TearDown() override { fs::remove_all(dir_); }

  void write_toml(const std::string& text) const {
    std::ofstream out(dir_ / "recording.toml", std::ios::trunc);
    out << text;
  }
  // The error message read_recording_meta throws for `text`, or "" when it does not throw.
  std::string error_for(const std::string& text) const {
    write_toml(text);
    try {
      (void)read_recording_meta(dir_);
    } catch (const Error& e) {
      return e.what();
    }
    return "";
  }
  [[nodiscard]] std::string file() const { return (dir_ / "recording.toml").string(); }

  fs::path dir_;
};

// A valid file; tests replace one line at a time. Line numbers below refer to this layout.
const std::string kValid =
    "format = \"ptda-recording\"\n"  // 1
    "version = 1\n"                  // 2
    "\n"                             // 3
    "[vibration]\n"                  // 4
    "file = \"vibration.wav\"\n"     // 5
    "channel = 1\n"                  // 6
    "start_time = 1700000000.5\n"    // 7
    "scale = 0.001\n"                // 8
    "unit = \"m/s^2\"\n"             // 9
    "\n"                             // 10
    "[can]\n"                        // 11
    "file = \"can.log\"\n";          // 12

std::string replace(std::string s, const std::string& from, const std::string& to) {
  const auto pos = s.find(from);
  EXPECT_NE(pos, std::string::npos) << from;
  if (pos != std::string::npos) s.replace(pos, from.size(), to);
  return s;
}

}  // namespace

TEST_F(RecordingTest, RoundTrip) {
  RecordingMeta m;
  m.vibration_file = "vibration.wav";
  m.channel = 1;
  m.start_time_s = 1700000000.123456;  // not exactly representable: must come back bit-identical
  m.scale = 9.80665 / 16384.0;
  m.unit = "m/s^2 \"quoted\" \\ back";
  m.can_file = "can.log";
  write_recording_meta(dir_, m);
  const RecordingMeta back = read_recording_meta(dir_);
  EXPECT_EQ(back.vibration_file, m.vibration_file);
  EXPECT_EQ(back.channel, m.channel);
  EXPECT_EQ(back.start_time_s, m.start_time_s);
  EXPECT_EQ(back.scale, m.scale);
  EXPECT_EQ(back.unit, m.unit);
  EXPECT_EQ(back.can_file, m.can_file);

  m.scale = 1.0;  // written as "1.0", a TOML float
  m.start_time_s = 0.0;
  m.channel = 0;
  write_recording_meta(dir_, m);
  EXPECT_EQ(read_recording_meta(dir_).scale, 1.0);
}

TEST_F(RecordingTest, WriteCreatesTheDirectory) {
  RecordingMeta m;
  write_recording_meta(dir_ / "sub" / "rec", m);
  EXPECT_TRUE(fs::is_regular_file(dir_ / "sub" / "rec" / "recording.toml"));
}

TEST_F(RecordingTest, ValidHandWrittenFileIsRead) {
  write_toml(kValid);
  const RecordingMeta m = read_recording_meta(dir_);
  EXPECT_EQ(m.channel, 1);
  EXPECT_EQ(m.start_time_s, 1700000000.5);
  EXPECT_EQ(m.scale, 0.001);
  EXPECT_EQ(m.unit, "m/s^2");
  // Integers are accepted for the numeric keys.
  write_toml(replace(kValid, "scale = 0.001", "scale = 2"));
  EXPECT_EQ(read_recording_meta(dir_).scale, 2.0);
}

TEST_F(RecordingTest, MalformedFilesPointAtLineAndColumn) {
  const std::string f = file();
  EXPECT_EQ(error_for(replace(kValid, "format = \"ptda-recording\"", "format = \"wav\"")),
            f + ":1:10: format is 'wav', expected 'ptda-recording'");
  EXPECT_EQ(error_for(replace(kValid, "format = \"ptda-recording\"", "")),
            f + ":1:1: missing key 'format' in the top level");
  EXPECT_EQ(error_for(replace(kValid, "version = 1", "version = 2")),
            f + ":2:11: unsupported version 2 (this build reads version 1)");
  EXPECT_EQ(error_for(replace(kValid, "version = 1", "version = \"1\"")),
            f + ":2:11: 'version' in the top level must be an integer");
  EXPECT_EQ(error_for(replace(kValid, "version = 1", "version = 1\nextra = 3")),
            f + ":3:1: unknown key 'extra' in the top level");
  EXPECT_EQ(error_for(replace(kValid, "unit = \"m/s^2\"", "unit = \"m/s^2\"\nchanel = 0")),
            f + ":10:1: unknown key 'chanel' in [vibration]");
  EXPECT_EQ(error_for(replace(kValid, "[can]\nfile = \"can.log\"\n", "")),
            f + ":1:1: missing key 'can' in the top level");
  EXPECT_EQ(error_for(replace(kValid, "channel = 1\n", "")),
            f + ":4:1: missing key 'channel' in [vibration]");
  EXPECT_EQ(error_for(replace(kValid, "channel = 1", "channel = 2")),
            f + ":6:11: channel 2 out of range: vibration.wav has 2 channel(s)");
  EXPECT_EQ(error_for(replace(kValid, "channel = 1", "channel = -1")),
            f + ":6:11: channel -1 must not be negative");
  EXPECT_EQ(error_for(replace(kValid, "channel = 1", "channel = 1.0")),
            f + ":6:11: 'channel' in [vibration] must be an integer");
  EXPECT_EQ(error_for(replace(kValid, "start_time = 1700000000.5", "start_time = \"now\"")),
            f + ":7:14: 'start_time' in [vibration] must be a number");
  EXPECT_EQ(error_for(replace(kValid, "start_time = 1700000000.5", "start_time = -1.0")),
            f + ":7:14: start_time must not be negative");
  // Issue 14 item 1: 9.3e9 s overflowed the ns conversion (UB) and gave 0 windows silently.
  EXPECT_EQ(error_for(replace(kValid, "start_time = 1700000000.5", "start_time = 9.3e9")),
            f + ":7:14: start_time 9.3e+09 s is out of range (at most 4e+09 s UNIX time, year 2096)");
  EXPECT_EQ(error_for(replace(kValid, "start_time = 1700000000.5", "start_time = 4000000001")),
            f + ":7:14: start_time 4000000001.0 s is out of range (at most 4e+09 s UNIX time, year 2096)");
  EXPECT_EQ(error_for(replace(kValid, "start_time = 1700000000.5", "start_time = nan")),
            f + ":7:14: 'start_time' in [vibration] must be finite");
  EXPECT_EQ(error_for(replace(kValid, "scale = 0.001", "scale = 0.0")), f + ":8:9: scale must not be zero");
  EXPECT_EQ(error_for(replace(kValid, "unit = \"m/s^2\"", "unit = \"\"")),
            f + ":9:8: 'unit' in [vibration] must not be empty");
  EXPECT_EQ(
      error_for(replace(kValid,
                        "[vibration]\nfile = \"vibration.wav\"\nchannel = 1\nstart_time = 1700000000.5\n"
                        "scale = 0.001\nunit = \"m/s^2\"\n",
                        "vibration = 3\n")),
      f + ":4:13: 'vibration' must be a table ([vibration])");
  EXPECT_EQ(
      error_for(replace(kValid, "file = \"vibration.wav\"", "file = \"missing.wav\"")),
      f + ":5:8: file '" + (dir_ / "missing.wav").string() + "' does not exist or is not a regular file");
  EXPECT_EQ(error_for(replace(kValid, "file = \"can.log\"", "file = \"nope.log\"")),
            f + ":12:8: file '" + (dir_ / "nope.log").string() + "' does not exist or is not a regular file");
  // A TOML syntax error keeps toml++'s own position and description.
  const std::string syntax = error_for(replace(kValid, "channel = 1", "channel = = 1"));
  EXPECT_EQ(syntax.rfind(f + ":6:11: ", 0), 0U) << syntax;
}

TEST_F(RecordingTest, MissingTomlAndBadWavAreErrors) {
  EXPECT_EQ(
      [&] {
        try {
          (void)read_recording_meta(dir_);
        } catch (const Error& e) {
          return std::string(e.what());
        }
        return std::string();
      }(),
      file() + ": recording.toml not found");
  // A referenced WAV that is not a WAV: the WAV reader's message names that file.
  {
    std::ofstream out(dir_ / "vibration.wav", std::ios::trunc);
    out << "not audio";
  }
  EXPECT_EQ(error_for(kValid),
            (dir_ / "vibration.wav").string() + ": not a WAV file: shorter than the 12-byte RIFF header");
}
