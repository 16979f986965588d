// WAV reader/writer: round trips of every sample format and channel count, hand-built headers
// (extensible, odd chunks, streamed sizes), malformed files with their messages, and a fuzz run.
#include "ptda/formats/wav.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "ptda/common/error.hpp"

namespace fs = std::filesystem;
using ptda::Error;
using ptda::formats::read_wav_channel;
using ptda::formats::WavInfo;
using ptda::formats::WavReader;
using ptda::formats::WavSampleFormat;
using ptda::formats::write_wav;

namespace {

fs::path temp_dir(const std::string& name) {
  const char* env = std::getenv("PTDA_TEST_TMP");
  fs::path d = (env != nullptr ? fs::path(env) : fs::temp_directory_path()) /
               ("formats_wav_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

using Bytes = std::vector<std::uint8_t>;

// push_back, not insert: GCC 12 -O2 reports a false -Wstringop-overflow for insert into an empty vector.
void put(Bytes& b, const char* four) {
  for (int i = 0; i < 4; ++i) b.push_back(static_cast<std::uint8_t>(four[i]));
}
void put16(Bytes& b, std::uint16_t v) {
  b.push_back(static_cast<std::uint8_t>(v));
  b.push_back(static_cast<std::uint8_t>(v >> 8));
}
void put32(Bytes& b, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) b.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}

// fmt chunk body (16 bytes) for tag/channels/rate/bits.
Bytes fmt_body(std::uint16_t tag, std::uint16_t ch, std::uint32_t rate, std::uint16_t bits) {
  Bytes b;
  put16(b, tag);
  put16(b, ch);
  put32(b, rate);
  put32(b, rate * ch * bits / 8);
  put16(b, static_cast<std::uint16_t>(ch * bits / 8));
  put16(b, bits);
  return b;
}

// WAVE_FORMAT_EXTENSIBLE fmt body (40 bytes) with sub-format tag `sub` (1 PCM, 3 float).
Bytes extensible_body(std::uint16_t ch, std::uint32_t rate, std::uint16_t bits, std::uint16_t valid_bits,
                      std::uint16_t sub) {
  Bytes b = fmt_body(0xFFFE, ch, rate, bits);
  put16(b, 22);  // cbSize
  put16(b, valid_bits);
  put32(b, 0x3);  // channel mask FL|FR
  put16(b, sub);
  const std::uint8_t tail[14] = {0x00, 0x00, 0x00, 0x00, 0x10, 0x00, 0x80,
                                 0x00, 0x00, 0xAA, 0x00, 0x38, 0x9B, 0x71};
  b.insert(b.end(), tail, tail + 14);
  return b;
}

void add_chunk(Bytes& b, const char* id, const Bytes& body, std::uint32_t size_field) {
  put(b, id);
  put32(b, size_field);
  b.insert(b.end(), body.begin(), body.end());
  if (body.size() % 2 == 1) b.push_back(0);  // RIFF pad byte
}
void add_chunk(Bytes& b, const char* id, const Bytes& body) {
  add_chunk(b, id, body, static_cast<std::uint32_t>(body.size()));
}

Bytes riff(const Bytes& chunks) {
  Bytes b;
  put(b, "RIFF");
  put32(b, static_cast<std::uint32_t>(4 + chunks.size()));
  put(b, "WAVE");
  b.insert(b.end(), chunks.begin(), chunks.end());
  return b;
}

void write_bytes(const fs::path& p, const Bytes& b) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
}
Bytes read_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return Bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

std::string error_of(const fs::path& p) {
  try {
    WavReader r(p);
    std::vector<float> buf(64);
    while (r.read(0, buf) > 0) {
    }
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

// Values a format stores exactly, including its extremes and negative values.
std::vector<float> test_values(WavSampleFormat f, std::size_t n, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::vector<float> v(n);
  for (std::size_t i = 0; i < n; ++i) {
    switch (f) {
      case WavSampleFormat::kPcm16:
        v[i] = static_cast<float>(static_cast<int>(rng() % 65536) - 32768);
        break;
      case WavSampleFormat::kPcm24:
        v[i] = static_cast<float>(static_cast<int>(rng() % 16777216) - 8388608);
        break;
      // float holds integers exactly up to 2^24; scale so the codes are exact and span the range.
      case WavSampleFormat::kPcm32:
        v[i] = static_cast<float>((static_cast<int>(rng() % 65536) - 32768) * 65536);
        break;
      case WavSampleFormat::kFloat32:
        v[i] = std::uniform_real_distribution<float>(-1e3F, 1e3F)(rng);
        break;
    }
  }
  if (n >= 4 && f == WavSampleFormat::kPcm16) {
    v[0] = -32768;
    v[1] = 32767;
    v[2] = -1;
  }
  if (n >= 4 && f == WavSampleFormat::kPcm24) {
    v[0] = -8388608;
    v[1] = 8388607;
    v[2] = -1;
    v[3] = -123456;
  }
  if (n >= 4 && f == WavSampleFormat::kPcm32) {
    v[0] = -2147483648.0F;
    v[1] = 2147483520.0F;  // largest float below 2^31
    v[2] = -1;
  }
  if (n >= 4 && f == WavSampleFormat::kFloat32) {
    v[0] = -0.0F;
    v[1] = std::numeric_limits<float>::denorm_min();
    v[2] = std::numeric_limits<float>::infinity();
  }
  return v;
}

}  // namespace

TEST(Wav, RoundTripEveryFormatAndChannelCount) {
  const fs::path dir = temp_dir("roundtrip");
  for (const auto f : {WavSampleFormat::kPcm16, WavSampleFormat::kPcm24, WavSampleFormat::kPcm32,
                       WavSampleFormat::kFloat32}) {
    for (std::uint16_t ch = 1; ch <= 8; ++ch) {
      SCOPED_TRACE("format " + std::to_string(static_cast<int>(f)) + " channels " + std::to_string(ch));
      std::vector<std::vector<float>> chans;
      for (std::uint16_t c = 0; c < ch; ++c) chans.push_back(test_values(f, 101, 17U * ch + c));
      const fs::path p = dir / "x.wav";
      write_wav(p, 25600, f, chans);
      // Header (44 bytes PCM, 58 with the float fmt extension and fact chunk) + data + pad byte.
      const std::size_t data = 101U * ch * ptda::formats::wav_bytes_per_sample(f);
      EXPECT_EQ(fs::file_size(p), (f == WavSampleFormat::kFloat32 ? 58U : 44U) + data + data % 2);
      for (std::uint16_t c = 0; c < ch; ++c) {
        WavInfo info;
        const auto back = read_wav_channel(p, c, &info);
        EXPECT_EQ(info.sample_rate_hz, 25600U);
        EXPECT_EQ(info.channels, ch);
        EXPECT_EQ(info.format, f);
        EXPECT_EQ(info.frames, 101U);
        ASSERT_EQ(back.size(), chans[c].size());
        for (std::size_t i = 0; i < back.size(); ++i) {
          // Bitwise: -0.0 and denormals must survive too.
          EXPECT_EQ(std::memcmp(&back[i], &chans[c][i], sizeof(float)), 0)
              << "frame " << i << ": " << back[i] << " vs " << chans[c][i];
        }
      }
    }
  }
  fs::remove_all(dir);
}

TEST(Wav, Pcm16HeaderBytesAreCanonical) {
  const fs::path dir = temp_dir("bytes");
  write_wav(dir / "a.wav", 8000, WavSampleFormat::kPcm16, {{-2.0F, 1.0F}});
  // Canonical 44-byte header written out by hand from the RIFF/WAVE spec.
  Bytes expect;
  put(expect, "RIFF");
  put32(expect, 36 + 4);
  put(expect, "WAVE");
  add_chunk(expect, "fmt ", fmt_body(1, 1, 8000, 16));
  add_chunk(expect, "data", Bytes{0xFE, 0xFF, 0x01, 0x00});
  EXPECT_EQ(read_bytes(dir / "a.wav"), expect);
  fs::remove_all(dir);
}

TEST(Wav, PcmWritesRoundAndSaturate) {
  const fs::path dir = temp_dir("saturate");
  const std::vector<float> in = {40000.0F, -40000.0F, 1.5F, -1.5F, 2.4F, -2.6F, 32767.4F, -32768.5F};
  write_wav(dir / "a.wav", 100, WavSampleFormat::kPcm16, {in});
  EXPECT_EQ(read_wav_channel(dir / "a.wav", 0),
            (std::vector<float>{32767, -32768, 2, -2, 2, -3, 32767, -32768}));
  write_wav(dir / "b.wav", 100, WavSampleFormat::kPcm24, {{1e9F, -1e9F, -0.5F}});
  EXPECT_EQ(read_wav_channel(dir / "b.wav", 0), (std::vector<float>{8388607, -8388608, -1}));
  write_wav(dir / "c.wav", 100, WavSampleFormat::kPcm32, {{1e12F, -1e12F}});
  EXPECT_EQ(read_wav_channel(dir / "c.wav", 0), (std::vector<float>{2147483647.0F, -2147483648.0F}));
  fs::remove_all(dir);
}

TEST(Wav, ExtensibleHeaderWith24BitNegativeValuesAndOddChunks) {
  const fs::path dir = temp_dir("ext");
  Bytes chunks;
  add_chunk(chunks, "LIST", Bytes{'I', 'N', 'F', 'O', 'x'});  // odd size: one pad byte follows
  add_chunk(chunks, "fmt ", extensible_body(2, 48000, 24, 24, 1));
  add_chunk(chunks, "fact", Bytes{2, 0, 0, 0});
  // Two frames of 24-bit stereo: (-1, 0x123456), (-8388608, -2).
  add_chunk(chunks, "data", Bytes{0xFF, 0xFF, 0xFF, 0x56, 0x34, 0x12, 0x00, 0x00, 0x80, 0xFE, 0xFF, 0xFF});
  add_chunk(chunks, "junk", Bytes{1, 2, 3});  // after the data: never read
  write_bytes(dir / "e.wav", riff(chunks));
  WavInfo info;
  EXPECT_EQ(read_wav_channel(dir / "e.wav", 0, &info), (std::vector<float>{-1.0F, -8388608.0F}));
  EXPECT_EQ(read_wav_channel(dir / "e.wav", 1), (std::vector<float>{1193046.0F, -2.0F}));
  EXPECT_EQ(info.format, WavSampleFormat::kPcm24);
  EXPECT_EQ(info.sample_rate_hz, 48000U);
  EXPECT_EQ(info.frames, 2U);

  Bytes fl;
  add_chunk(fl, "fmt ", extensible_body(1, 1000, 32, 32, 3));
  Bytes data;
  const float vals[2] = {-0.25F, 3.5F};
  for (const float v : vals) {
    std::uint32_t u = 0;
    std::memcpy(&u, &v, 4);
    put32(data, u);
  }
  add_chunk(fl, "data", data);
  write_bytes(dir / "f.wav", riff(fl));
  EXPECT_EQ(read_wav_channel(dir / "f.wav", 0, &info), (std::vector<float>{-0.25F, 3.5F}));
  EXPECT_EQ(info.format, WavSampleFormat::kFloat32);
  fs::remove_all(dir);
}

TEST(Wav, StreamedDataSizeUsesFileSize) {
  const fs::path dir = temp_dir("stream");
  for (const std::uint32_t size_field : {0U, 0xFFFFFFFFU}) {
    Bytes chunks;
    add_chunk(chunks, "fmt ", fmt_body(1, 2, 1000, 16));
    // 3 whole stereo frames and a partial one (a writer killed mid-frame): the partial frame is dropped.
    add_chunk(chunks, "data", Bytes{1, 0, 2, 0, 3, 0, 4, 0, 0xFF, 0xFF, 6, 0, 7, 0}, size_field);
    Bytes file = riff(chunks);
    file.resize(file.size());
    write_bytes(dir / "s.wav", file);
    WavInfo info;
    EXPECT_EQ(read_wav_channel(dir / "s.wav", 1, &info), (std::vector<float>{2, 4, 6}));
    EXPECT_EQ(info.frames, 3U);
  }
  fs::remove_all(dir);
}

TEST(Wav, BlockReadsAndSeekMatchWholeRead) {
  const fs::path dir = temp_dir("blocks");
  std::vector<std::vector<float>> chans(3);
  for (int c = 0; c < 3; ++c)
    chans[static_cast<std::size_t>(c)] =
        test_values(WavSampleFormat::kPcm24, 10007, 5U + static_cast<unsigned>(c));
  write_wav(dir / "b.wav", 51200, WavSampleFormat::kPcm24, chans);
  WavReader r(dir / "b.wav");
  std::vector<float> got;
  std::vector<float> buf(777);
  std::size_t n = 0;
  while ((n = r.read(2, buf)) > 0)
    got.insert(got.end(), buf.begin(), buf.begin() + static_cast<std::ptrdiff_t>(n));
  EXPECT_EQ(got, chans[2]);
  EXPECT_EQ(r.position(), 10007U);
  r.seek(5000);
  ASSERT_EQ(r.read(1, std::span<float>(buf).first(3)), 3U);
  EXPECT_EQ(buf[0], chans[1][5000]);
  EXPECT_EQ(buf[2], chans[1][5002]);
  r.seek(1u << 30);  // clamped to the end
  EXPECT_EQ(r.read(0, buf), 0U);
  try {
    (void)r.read(3, buf);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("channel 3 out of range (file has 3 channels)"), std::string::npos)
        << e.what();
  }
  fs::remove_all(dir);
}

// One channel has its own decoding loops (a constant stride, vectorised; 24-bit mono eight samples at a
// time with AVX2 where the CPU has it, the last few samples of every read one by one). Every read size
// from 1 to 40 frames and every start frame from 0 to 11 gives the stored codes bit for bit, with the
// format's extremes at every position of an eight-sample step, and the same values as the channel read
// out of a two-channel file (the interleaved loops).
TEST(Wav, OneChannelDecodingGivesTheStoredValuesAtEveryReadSizeAndStart) {
  const fs::path dir = temp_dir("mono");
  for (const auto f : {WavSampleFormat::kPcm16, WavSampleFormat::kPcm24, WavSampleFormat::kPcm32,
                       WavSampleFormat::kFloat32}) {
    SCOPED_TRACE("format " + std::to_string(static_cast<int>(f)));
    std::vector<float> v = test_values(f, 301, 41U);
    const std::vector<float> edge(v.begin(), v.begin() + 3);  // the format's extremes and -1 (or -0, inf)
    for (std::size_t i = 0; i < 48; ++i) v[i + 4] = i % 4 == 3 ? 0.0F : edge[(i + i / 8) % 3];
    write_wav(dir / "m.wav", 25600, f, {v});
    std::vector<float> other = test_values(f, 301, 42U);
    write_wav(dir / "s.wav", 25600, f, {other, v});
    EXPECT_EQ(std::memcmp(read_wav_channel(dir / "s.wav", 1).data(), v.data(), v.size() * sizeof(float)), 0);
    WavReader r(dir / "m.wav");
    std::vector<float> buf(40);
    for (std::size_t start = 0; start < 12; ++start) {
      for (std::size_t len = 1; len <= buf.size(); ++len) {
        r.seek(start);
        std::size_t at = start;
        std::size_t n = 0;
        while ((n = r.read(0, std::span<float>(buf).first(len))) > 0) {
          ASSERT_LE(at + n, v.size());
          ASSERT_EQ(std::memcmp(buf.data(), v.data() + at, n * sizeof(float)), 0)
              << "start " << start << " read size " << len << " at frame " << at;
          at += n;
        }
        EXPECT_EQ(at, v.size());
      }
    }
  }
  fs::remove_all(dir);
}

TEST(Wav, MalformedFilesGiveClearErrors) {
  const fs::path dir = temp_dir("bad");
  const fs::path p = dir / "bad.wav";
  const std::string name = p.string();
  auto check = [&](const Bytes& file, const std::string& what) {
    write_bytes(p, file);
    EXPECT_EQ(error_of(p), name + ": " + what);
  };
  auto with_fmt = [](const Bytes& fmt, const Bytes& data) {
    Bytes c;
    add_chunk(c, "fmt ", fmt);
    add_chunk(c, "data", data);
    return riff(c);
  };
  check(Bytes{'R', 'I', 'F'}, "not a WAV file: shorter than the 12-byte RIFF header");
  Bytes not_wave = with_fmt(fmt_body(1, 1, 8000, 16), Bytes{0, 0});
  std::memcpy(not_wave.data() + 8, "AVI ", 4);
  check(not_wave, "not a WAV file: missing RIFF/WAVE signature");
  check(with_fmt(fmt_body(2, 1, 8000, 16), Bytes{0, 0}),
        "unsupported WAV format tag 2 (1 = PCM, 3 = IEEE float, 0xFFFE = extensible)");
  check(with_fmt(fmt_body(1, 1, 8000, 8), Bytes{0, 0}), "unsupported PCM bits per sample 8 (16, 24, 32)");
  check(with_fmt(fmt_body(3, 1, 8000, 64), Bytes{0, 0}), "unsupported IEEE float bits per sample 64 (32)");
  check(with_fmt(fmt_body(1, 9, 8000, 16), Bytes{0, 0}), "unsupported channel count 9 (1..8)");
  check(with_fmt(fmt_body(1, 0, 8000, 16), Bytes{0, 0}), "unsupported channel count 0 (1..8)");
  check(with_fmt(fmt_body(1, 1, 0, 16), Bytes{0, 0}), "unsupported sample rate 0 Hz (1..200000)");
  check(with_fmt(fmt_body(1, 1, 200001, 16), Bytes{0, 0}), "unsupported sample rate 200001 Hz (1..200000)");
  Bytes bad_align = fmt_body(1, 2, 8000, 16);
  bad_align[12] = 3;
  check(with_fmt(bad_align, Bytes{0, 0}), "block align 3 does not match 2 channels x 2 bytes");
  check(with_fmt(Bytes{1, 0, 1, 0}, Bytes{0, 0}), "fmt chunk too short (4 bytes)");
  Bytes guid = extensible_body(1, 8000, 16, 16, 1);
  guid[39] = 0;
  check(with_fmt(guid, Bytes{0, 0}), "unsupported WAVE_FORMAT_EXTENSIBLE sub-format GUID");
  check(with_fmt(extensible_body(1, 8000, 16, 16, 2), Bytes{0, 0}),
        "unsupported WAV format tag 2 (1 = PCM, 3 = IEEE float, 0xFFFE = extensible)");
  check(with_fmt(extensible_body(1, 8000, 16, 20, 1), Bytes{0, 0}),
        "valid bits per sample 20 exceed container 16");
  check(with_fmt(fmt_body(1, 2, 8000, 16), Bytes{0, 0, 0, 0, 0, 0}),
        "data chunk size 6 is not a multiple of the 4-byte frame");
  {
    Bytes c;
    add_chunk(c, "LIST", Bytes{1, 2});
    check(riff(c), "no fmt chunk");
  }
  {
    Bytes c;
    add_chunk(c, "fmt ", fmt_body(1, 1, 8000, 16));
    check(riff(c), "no data chunk");
  }
  {
    Bytes c;
    add_chunk(c, "data", Bytes{0, 0});
    add_chunk(c, "fmt ", fmt_body(1, 1, 8000, 16));
    check(riff(c), "data chunk before fmt chunk");
  }
  {
    Bytes c;
    add_chunk(c, "fmt ", fmt_body(1, 1, 8000, 16));
    add_chunk(c, "data", Bytes{1, 0, 2, 0, 3, 0, 4, 0}, 100);
    check(riff(c), "truncated: header says 100 bytes, file has 8");
  }
  {
    Bytes c;
    add_chunk(c, "LIST", Bytes{1, 2}, 5000);
    check(riff(c), "truncated: 'LIST' chunk at offset 12 says 5000 bytes, file has 2");
  }
  EXPECT_NE(
      error_of(dir / "missing.wav").find("missing.wav: cannot open WAV file: No such file or directory"),
      std::string::npos);
  fs::remove_all(dir);
}

TEST(Wav, WriterRejectsBadInput) {
  const fs::path dir = temp_dir("wbad");
  const fs::path p = dir / "w.wav";
  auto err = [&](auto fn) -> std::string {
    try {
      fn();
    } catch (const Error& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_EQ(err([&] { write_wav(p, 100, WavSampleFormat::kPcm16, {}); }),
            p.string() + ": cannot write 0 channels (1..8)");
  EXPECT_EQ(
      err([&] { write_wav(p, 100, WavSampleFormat::kPcm16, std::vector<std::vector<float>>(9, {1.0F})); }),
      p.string() + ": cannot write 9 channels (1..8)");
  EXPECT_EQ(err([&] { write_wav(p, 0, WavSampleFormat::kPcm16, {{1.0F}}); }),
            p.string() + ": cannot write sample rate 0 Hz (1..200000)");
  EXPECT_EQ(err([&] {
              write_wav(p, 100, WavSampleFormat::kPcm16, {{1.0F, 2.0F}, {1.0F}});
            }),
            p.string() + ": channel 1 has 1 samples, channel 0 has 2");
  EXPECT_EQ(err([&] {
              write_wav(p, 100, WavSampleFormat::kPcm24, {{1.0F, std::nanf("")}});
            }),
            p.string() + ": NaN sample at channel 0 frame 1 cannot be stored as PCM");
  EXPECT_NE(err([&] {
              write_wav(dir / "no" / "w.wav", 100, WavSampleFormat::kPcm16, {{1.0F}});
            }).find("cannot create WAV file"),
            std::string::npos);
  fs::remove_all(dir);
}

// Random header bytes and truncations must only ever produce ptda::Error.
TEST(Wav, RandomHeadersOnlyThrowPtdaError) {
  // Thousands of small files: use tmpfs when there is one (a disk write costs ~5 ms on the CI VM).
  fs::path dir = temp_dir("fuzz");
  if (fs::is_directory("/dev/shm")) {
    fs::remove_all(dir);
    dir = fs::path("/dev/shm") / ("ptda_formats_wav_fuzz_" + std::to_string(::getpid()));
    fs::create_directories(dir);
  }
  write_wav(dir / "seed.wav", 1000, WavSampleFormat::kFloat32, {{1, 2, 3, 4, 5}, {6, 7, 8, 9, 10}});
  Bytes ext;
  add_chunk(ext, "LIST", Bytes{1, 2, 3});
  add_chunk(ext, "fmt ", extensible_body(2, 48000, 24, 24, 1));
  add_chunk(ext, "data", Bytes(60, 0x80));
  const std::vector<Bytes> seeds = {read_bytes(dir / "seed.wav"), riff(ext)};
  std::mt19937 rng(99);
  int ok = 0;
  int errors = 0;
  for (int iter = 0; iter < 3000; ++iter) {
    Bytes b = seeds[static_cast<std::size_t>(iter) % seeds.size()];
    const int edits = 1 + static_cast<int>(rng() % 6);
    for (int e = 0; e < edits; ++e)
      b[rng() % std::min<std::size_t>(b.size(), 80)] = static_cast<std::uint8_t>(rng());
    if (rng() % 4 == 0) b.resize(rng() % b.size());
    write_bytes(dir / "f.wav", b);
    try {
      WavReader r(dir / "f.wav");
      std::vector<float> buf(16);
      for (std::uint16_t c = 0; c < r.info().channels; ++c) {
        r.seek(0);
        while (r.read(c, buf) > 0) {
        }
      }
      ++ok;
    } catch (const Error&) {
      ++errors;
    } catch (...) {
      ADD_FAILURE() << "non-ptda exception at iteration " << iter;
    }
  }
  EXPECT_GT(ok, 10);
  EXPECT_GT(errors, 100);
  fs::remove_all(dir);
}
