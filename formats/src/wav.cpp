// RIFF/WAVE reading and writing. Every multi-byte field is decoded explicitly as little-endian so the
// code does not depend on the host's byte order or struct layout.
#include "ptda/formats/wav.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <string>

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#endif

#include "ptda/common/error.hpp"
#include "ptda/common/file_check.hpp"

namespace ptda::formats {
namespace {

constexpr std::uint16_t kTagPcm = 1;
constexpr std::uint16_t kTagFloat = 3;
constexpr std::uint16_t kTagExtensible = 0xFFFE;
constexpr std::uint32_t kMaxRateHz = 200000;
constexpr std::uint16_t kMaxChannels = 8;
// KSDATAFORMAT_SUBTYPE_PCM / _IEEE_FLOAT share everything but the first two bytes (the format tag).
constexpr std::array<std::uint8_t, 14> kGuidTail = {0x00, 0x00, 0x00, 0x00, 0x10, 0x00, 0x80,
                                                    0x00, 0x00, 0xAA, 0x00, 0x38, 0x9B, 0x71};
// Frames per block when streaming; keeps the I/O buffer at most 8 ch * 4 B * 4096 = 128 KiB.
constexpr std::size_t kBlockFrames = 4096;

std::uint16_t le16(const std::uint8_t* p) noexcept {
  return static_cast<std::uint16_t>(p[0] | (p[1] << 8));
}
std::uint32_t le32(const std::uint8_t* p) noexcept {
  return static_cast<std::uint32_t>(p[0]) | (static_cast<std::uint32_t>(p[1]) << 8) |
         (static_cast<std::uint32_t>(p[2]) << 16) | (static_cast<std::uint32_t>(p[3]) << 24);
}
void put16(std::uint8_t* p, std::uint16_t v) noexcept {
  p[0] = static_cast<std::uint8_t>(v);
  p[1] = static_cast<std::uint8_t>(v >> 8);
}
void put32(std::uint8_t* p, std::uint32_t v) noexcept {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}

std::string errno_text() {
  return std::strerror(errno);
}

#if defined(__x86_64__) && defined(__GNUC__)
#define PTDA_WAV_AVX2 1
// Mono 24-bit PCM, eight samples per step with AVX2: two 16-byte loads (bytes 0..15 and 12..27 of the
// step's 24) make one register whose 128-bit halves each hold four samples in their first 12 bytes; one
// byte shuffle per half puts sample k's three bytes into the top of 32-bit lane k (zero below), an
// arithmetic shift by 8 sign-extends, and the conversion to float is exact (|code| < 2^24). The same
// values as the scalar loop. Reads 4 bytes past the step's 24, so it stops while at least 10 samples
// (30 bytes) are left and returns the samples decoded; the caller decodes the rest.
__attribute__((target("avx2"))) std::size_t decode_pcm24_mono_avx2(const std::uint8_t* p, std::size_t n,
                                                                   float* out) noexcept {
  const __m256i shuffle = _mm256_setr_epi8(-1, 0, 1, 2, -1, 3, 4, 5, -1, 6, 7, 8, -1, 9, 10, 11,  //
                                           -1, 0, 1, 2, -1, 3, 4, 5, -1, 6, 7, 8, -1, 9, 10, 11);
  std::size_t i = 0;
  for (; i + 10 <= n; i += 8) {
    const std::uint8_t* const q = p + 3 * i;
    const __m128i lo = _mm_loadu_si128(reinterpret_cast<const __m128i*>(q));
    const __m128i hi = _mm_loadu_si128(reinterpret_cast<const __m128i*>(q + 12));
    const __m256i v = _mm256_shuffle_epi8(_mm256_set_m128i(hi, lo), shuffle);
    _mm256_storeu_ps(out + i, _mm256_cvtepi32_ps(_mm256_srai_epi32(v, 8)));
  }
  return i;
}

bool cpu_has_avx2() noexcept {
  static const bool has = __builtin_cpu_supports("avx2") != 0;
  return has;
}
#endif

// Decodes n samples spaced `stride` bytes apart into out[0..n): one loop per format, so the compiler
// keeps the format switch out of the per-sample path (issue 13). PCM gives the integer code, float32
// the stored value bit for bit. One channel (stride = the sample's size) has its own loops with a
// constant stride, which the compiler vectorises (wav.cpp is built with the dynamic cost model,
// formats/CMakeLists.txt), and 24-bit mono its AVX2 loop where the CPU has it.
void decode_block(const std::uint8_t* p, std::size_t stride, std::size_t n, WavSampleFormat format,
                  float* out) noexcept {
  constexpr bool kLittle = std::endian::native == std::endian::little;
  switch (format) {
    case WavSampleFormat::kPcm16:
      if (kLittle && stride == 2) {
        for (std::size_t i = 0; i < n; ++i) {
          std::int16_t v = 0;
          std::memcpy(&v, p + 2 * i, sizeof v);
          out[i] = static_cast<float>(v);
        }
        return;
      }
      for (std::size_t i = 0; i < n; ++i, p += stride)
        out[i] = static_cast<float>(static_cast<std::int16_t>(le16(p)));
      return;
    case WavSampleFormat::kPcm24:
      if constexpr (kLittle) {
#if defined(PTDA_WAV_AVX2)
        if (stride == 3 && cpu_has_avx2()) {
          const std::size_t done = decode_pcm24_mono_avx2(p, n, out);
          p += 3 * done;
          out += done;
          n -= done;
        }
#endif
        // One 4-byte load per sample (the top byte, from the next sample or channel, is shifted out);
        // every sample but the last is followed by at least one more byte of the block.
        for (; n > 1; --n, ++out, p += stride) {
          std::uint32_t u = 0;
          std::memcpy(&u, p, sizeof u);
          *out = static_cast<float>(static_cast<std::int32_t>(u << 8) >> 8);
        }
      }
      for (std::size_t i = 0; i < n; ++i, p += stride) {
        const std::uint32_t u = (static_cast<std::uint32_t>(p[0]) << 8) |
                                (static_cast<std::uint32_t>(p[1]) << 16) |
                                (static_cast<std::uint32_t>(p[2]) << 24);
        out[i] = static_cast<float>(static_cast<std::int32_t>(u) >> 8);
      }
      return;
    case WavSampleFormat::kPcm32:
      if (kLittle && stride == 4) {
        for (std::size_t i = 0; i < n; ++i) {
          std::int32_t v = 0;
          std::memcpy(&v, p + 4 * i, sizeof v);
          out[i] = static_cast<float>(v);
        }
        return;
      }
      for (std::size_t i = 0; i < n; ++i, p += stride)
        out[i] = static_cast<float>(static_cast<std::int32_t>(le32(p)));
      return;
    case WavSampleFormat::kFloat32:
      if (kLittle && stride == sizeof(float)) {  // one channel: the bytes already are the floats
        std::memcpy(out, p, n * sizeof(float));
        return;
      }
      for (std::size_t i = 0; i < n; ++i, p += stride) {
        const std::uint32_t u = le32(p);
        std::memcpy(out + i, &u, sizeof(float));
      }
      return;
  }
}

struct FileCloser {
  void operator()(std::FILE* f) const noexcept {
    if (f != nullptr) std::fclose(f);
  }
};

}  // namespace

std::uint16_t wav_bytes_per_sample(WavSampleFormat format) noexcept {
  switch (format) {
    case WavSampleFormat::kPcm16:
      return 2;
    case WavSampleFormat::kPcm24:
      return 3;
    case WavSampleFormat::kPcm32:
      return 4;
    case WavSampleFormat::kFloat32:
      return 4;
  }
  return 4;
}

WavReader::WavReader(const std::filesystem::path& path) : path_(path) {
  const std::string name = path.string();
  require_regular_file(path, kNoSizeLimit, "WAV file");  // a FIFO would block fopen
  f_ = std::fopen(name.c_str(), "rb");
  if (f_ == nullptr) throw Error(name + ": cannot open WAV file: " + errno_text());
  // No stdio buffer: read() asks for whole blocks (kBlockFrames frames), and a buffered FILE split each
  // into a copy from its 4 KiB buffer plus a second read(2) because the data chunk does not start on a
  // 4 KiB boundary. Unbuffered, each block is one read(2) straight into buf_ (if this fails, the FILE
  // just stays buffered).
  (void)std::setvbuf(f_, nullptr, _IONBF, 0);
  try {
    if (fseeko(f_, 0, SEEK_END) != 0) throw Error(name + ": cannot seek: " + errno_text());
    const off_t end = ftello(f_);
    if (end < 0) throw Error(name + ": cannot tell file size: " + errno_text());
    const auto file_size = static_cast<std::uint64_t>(end);
    std::rewind(f_);

    std::array<std::uint8_t, 12> riff{};
    if (file_size < riff.size() || std::fread(riff.data(), 1, riff.size(), f_) != riff.size())
      throw Error(name + ": not a WAV file: shorter than the 12-byte RIFF header");
    if (std::memcmp(riff.data(), "RIFF", 4) != 0 || std::memcmp(riff.data() + 8, "WAVE", 4) != 0)
      throw Error(name + ": not a WAV file: missing RIFF/WAVE signature");
    // The RIFF size field is ignored: streamed writers leave it 0 or 0xFFFFFFFF.

    bool have_fmt = false;
    bool have_data = false;
    std::uint64_t data_bytes = 0;
    std::uint64_t pos = riff.size();
    while (pos + 8 <= file_size) {
      std::array<std::uint8_t, 8> hdr{};
      if (fseeko(f_, static_cast<off_t>(pos), SEEK_SET) != 0 || std::fread(hdr.data(), 1, 8, f_) != 8)
        throw Error(name + ": cannot read chunk header at offset " + std::to_string(pos));
      const std::string id(reinterpret_cast<const char*>(hdr.data()), 4);
      const std::uint32_t size = le32(hdr.data() + 4);
      const std::uint64_t body = pos + 8;
      const std::uint64_t avail = file_size - body;
      if (id == "data") {
        if (!have_fmt) throw Error(name + ": data chunk before fmt chunk");
        have_data = true;
        data_offset_ = body;
        if (size == 0 || size == 0xFFFFFFFFU) {
          // Streamed writer never patched the size: the data runs to the end of the file.
          data_bytes = avail - avail % block_align_;
          break;
        }
        if (size > avail)
          throw Error(name + ": truncated: header says " + std::to_string(size) + " bytes, file has " +
                      std::to_string(avail));
        if (size % block_align_ != 0)
          throw Error(name + ": data chunk size " + std::to_string(size) + " is not a multiple of the " +
                      std::to_string(block_align_) + "-byte frame");
        data_bytes = size;
        break;  // everything needed is known; chunks after the data are not read
      }
      if (size > avail)
        throw Error(name + ": truncated: '" + id + "' chunk at offset " + std::to_string(pos) + " says " +
                    std::to_string(size) + " bytes, file has " + std::to_string(avail));
      if (id == "fmt ") {
        if (have_fmt) throw Error(name + ": more than one fmt chunk");
        if (size < 16) throw Error(name + ": fmt chunk too short (" + std::to_string(size) + " bytes)");
        std::array<std::uint8_t, 40> fmt{};
        const std::size_t n = std::min<std::size_t>(size, fmt.size());
        if (std::fread(fmt.data(), 1, n, f_) != n) throw Error(name + ": cannot read fmt chunk");
        std::uint16_t tag = le16(fmt.data());
        const std::uint16_t channels = le16(fmt.data() + 2);
        const std::uint32_t rate = le32(fmt.data() + 4);
        const std::uint16_t block_align = le16(fmt.data() + 12);
        const std::uint16_t bits = le16(fmt.data() + 14);
        if (tag == kTagExtensible) {
          if (size < 40) throw Error(name + ": WAVE_FORMAT_EXTENSIBLE fmt chunk shorter than 40 bytes");
          const std::uint16_t valid_bits = le16(fmt.data() + 18);
          if (valid_bits > bits)
            throw Error(name + ": valid bits per sample " + std::to_string(valid_bits) +
                        " exceed container " + std::to_string(bits));
          if (std::memcmp(fmt.data() + 26, kGuidTail.data(), kGuidTail.size()) != 0)
            throw Error(name + ": unsupported WAVE_FORMAT_EXTENSIBLE sub-format GUID");
          tag = le16(fmt.data() + 24);
        }
        if (tag == kTagPcm) {
          if (bits == 16) {
            info_.format = WavSampleFormat::kPcm16;
          } else if (bits == 24) {
            info_.format = WavSampleFormat::kPcm24;
          } else if (bits == 32) {
            info_.format = WavSampleFormat::kPcm32;
          } else {
            throw Error(name + ": unsupported PCM bits per sample " + std::to_string(bits) + " (16, 24, 32)");
          }
        } else if (tag == kTagFloat) {
          if (bits != 32)
            throw Error(name + ": unsupported IEEE float bits per sample " + std::to_string(bits) + " (32)");
          info_.format = WavSampleFormat::kFloat32;
        } else {
          throw Error(name + ": unsupported WAV format tag " + std::to_string(tag) +
                      " (1 = PCM, 3 = IEEE float, 0xFFFE = extensible)");
        }
        if (channels < 1 || channels > kMaxChannels)
          throw Error(name + ": unsupported channel count " + std::to_string(channels) + " (1..8)");
        if (rate < 1 || rate > kMaxRateHz)
          throw Error(name + ": unsupported sample rate " + std::to_string(rate) + " Hz (1..200000)");
        bytes_per_sample_ = wav_bytes_per_sample(info_.format);
        if (block_align != channels * bytes_per_sample_)
          throw Error(name + ": block align " + std::to_string(block_align) + " does not match " +
                      std::to_string(channels) + " channels x " + std::to_string(bytes_per_sample_) +
                      " bytes");
        block_align_ = block_align;
        info_.channels = channels;
        info_.sample_rate_hz = rate;
        have_fmt = true;
      }
      // RIFF chunks are padded to an even size.
      pos = body + size + (size & 1U);
    }
    if (!have_fmt) throw Error(name + ": no fmt chunk");
    if (!have_data) throw Error(name + ": no data chunk");
    info_.frames = data_bytes / block_align_;
    if (fseeko(f_, static_cast<off_t>(data_offset_), SEEK_SET) != 0)
      throw Error(name + ": cannot seek to the data: " + errno_text());
  } catch (...) {
    std::fclose(f_);
    f_ = nullptr;
    throw;
  }
}

WavReader::~WavReader() {
  if (f_ != nullptr) std::fclose(f_);
}

void WavReader::seek(std::uint64_t frame) {
  pos_frames_ = std::min(frame, info_.frames);
  const std::uint64_t off = data_offset_ + pos_frames_ * block_align_;
  if (fseeko(f_, static_cast<off_t>(off), SEEK_SET) != 0)
    throw Error(path_.string() + ": cannot seek to frame " + std::to_string(pos_frames_) + ": " +
                errno_text());
}

std::size_t WavReader::read(std::uint16_t channel, std::span<float> out) {
  if (channel >= info_.channels)
    throw Error(path_.string() + ": channel " + std::to_string(channel) + " out of range (file has " +
                std::to_string(info_.channels) + " channels)");
  const std::uint64_t left = info_.frames - pos_frames_;
  const std::size_t want = static_cast<std::size_t>(std::min<std::uint64_t>(left, out.size()));
  std::size_t done = 0;
  const std::size_t ch_off = static_cast<std::size_t>(channel) * bytes_per_sample_;
  while (done < want) {
    const std::size_t n = std::min(kBlockFrames, want - done);
    const std::size_t bytes = n * block_align_;
    if (buf_.size() < bytes) buf_.resize(bytes);
    const std::size_t got = std::fread(buf_.data(), 1, bytes, f_);
    if (got != bytes)
      throw Error(path_.string() + ": unexpected end of file or read error at frame " +
                  std::to_string(pos_frames_ + got / block_align_) + " of " + std::to_string(info_.frames));
    decode_block(buf_.data() + ch_off, block_align_, n, info_.format, out.data() + done);
    done += n;
    pos_frames_ += n;
  }
  return done;
}

std::vector<float> read_wav_channel(const std::filesystem::path& path, std::uint16_t channel, WavInfo* info) {
  WavReader r(path);
  if (channel >= r.info().channels)
    throw Error(path.string() + ": channel " + std::to_string(channel) + " out of range (file has " +
                std::to_string(r.info().channels) + " channels)");
  std::vector<float> out(static_cast<std::size_t>(r.info().frames));
  std::size_t done = 0;
  while (done < out.size()) {
    const std::size_t n = r.read(channel, std::span<float>(out).subspan(done));
    if (n == 0) break;
    done += n;
  }
  if (info != nullptr) *info = r.info();
  return out;
}

namespace {

// Rounds half away from zero and saturates to [lo, hi]; PCM values are integer codes.
std::int64_t to_code(float v, std::int64_t lo, std::int64_t hi) noexcept {
  const double r = std::round(static_cast<double>(v));
  if (r <= static_cast<double>(lo)) return lo;
  if (r >= static_cast<double>(hi)) return hi;
  return static_cast<std::int64_t>(r);
}

void encode_sample(std::uint8_t* p, float v, WavSampleFormat format) noexcept {
  switch (format) {
    case WavSampleFormat::kPcm16:
      put16(p, static_cast<std::uint16_t>(static_cast<std::int16_t>(to_code(v, -32768, 32767))));
      return;
    case WavSampleFormat::kPcm24: {
      const auto u = static_cast<std::uint32_t>(static_cast<std::int32_t>(to_code(v, -8388608, 8388607)));
      p[0] = static_cast<std::uint8_t>(u);
      p[1] = static_cast<std::uint8_t>(u >> 8);
      p[2] = static_cast<std::uint8_t>(u >> 16);
      return;
    }
    case WavSampleFormat::kPcm32:
      put32(p, static_cast<std::uint32_t>(static_cast<std::int32_t>(to_code(
                   v, std::numeric_limits<std::int32_t>::min(), std::numeric_limits<std::int32_t>::max()))));
      return;
    case WavSampleFormat::kFloat32: {
      std::uint32_t u = 0;
      std::memcpy(&u, &v, sizeof u);
      put32(p, u);
      return;
    }
  }
}

}  // namespace

void write_wav(const std::filesystem::path& path, std::uint32_t sample_rate_hz, WavSampleFormat format,
               const std::vector<std::vector<float>>& channels) {
  const std::string name = path.string();
  if (channels.empty() || channels.size() > kMaxChannels)
    throw Error(name + ": cannot write " + std::to_string(channels.size()) + " channels (1..8)");
  if (sample_rate_hz < 1 || sample_rate_hz > kMaxRateHz)
    throw Error(name + ": cannot write sample rate " + std::to_string(sample_rate_hz) + " Hz (1..200000)");
  const std::size_t frames = channels[0].size();
  for (std::size_t c = 1; c < channels.size(); ++c) {
    if (channels[c].size() != frames)
      throw Error(name + ": channel " + std::to_string(c) + " has " + std::to_string(channels[c].size()) +
                  " samples, channel 0 has " + std::to_string(frames));
  }
  if (format != WavSampleFormat::kFloat32) {  // before creating the file
    for (std::size_t c = 0; c < channels.size(); ++c) {
      for (std::size_t i = 0; i < frames; ++i) {
        if (std::isnan(channels[c][i]))
          throw Error(name + ": NaN sample at channel " + std::to_string(c) + " frame " + std::to_string(i) +
                      " cannot be stored as PCM");
      }
    }
  }
  const auto n_ch = static_cast<std::uint16_t>(channels.size());
  WavWriter w(path, sample_rate_hz, format, n_ch, frames);
  std::vector<float> inter(kBlockFrames * n_ch);
  for (std::size_t start = 0; start < frames; start += kBlockFrames) {
    const std::size_t n = std::min(kBlockFrames, frames - start);
    for (std::size_t i = 0; i < n; ++i) {
      for (std::size_t c = 0; c < n_ch; ++c) inter[i * n_ch + c] = channels[c][start + i];
    }
    w.write(std::span<const float>(inter.data(), n * n_ch));
  }
  w.close();
}

WavWriter::WavWriter(const std::filesystem::path& path, std::uint32_t sample_rate_hz, WavSampleFormat format,
                     std::uint16_t channels, std::uint64_t frames)
    : name_(path.string()), format_(format), channels_(channels), frames_(frames) {
  if (channels < 1 || channels > kMaxChannels)
    throw Error(name_ + ": cannot write " + std::to_string(channels) + " channels (1..8)");
  if (sample_rate_hz < 1 || sample_rate_hz > kMaxRateHz)
    throw Error(name_ + ": cannot write sample rate " + std::to_string(sample_rate_hz) + " Hz (1..200000)");
  const bool is_float = format == WavSampleFormat::kFloat32;
  bps_ = wav_bytes_per_sample(format);
  const auto block_align = static_cast<std::uint16_t>(channels * bps_);
  const std::uint64_t data_bytes = frames * block_align;
  // Float files carry the 18-byte fmt (cbSize = 0) and a fact chunk, as the WAVE spec asks for non-PCM.
  const std::uint32_t fmt_size = is_float ? 18 : 16;
  const std::uint32_t fact_bytes = is_float ? 12 : 0;
  const std::uint64_t riff_size = 4 + (8 + fmt_size) + fact_bytes + 8 + data_bytes + (data_bytes & 1U);
  if (riff_size > 0xFFFFFFFFULL) throw Error(name_ + ": too much data for a RIFF file (4 GiB limit)");

  std::vector<std::uint8_t> hdr;
  hdr.reserve(64);
  auto add4 = [&hdr](const char* s) { hdr.insert(hdr.end(), s, s + 4); };
  auto add16 = [&hdr](std::uint16_t v) {
    std::uint8_t b[2];
    put16(b, v);
    hdr.insert(hdr.end(), b, b + 2);
  };
  auto add32 = [&hdr](std::uint32_t v) {
    std::uint8_t b[4];
    put32(b, v);
    hdr.insert(hdr.end(), b, b + 4);
  };
  add4("RIFF");
  add32(static_cast<std::uint32_t>(riff_size));
  add4("WAVE");
  add4("fmt ");
  add32(fmt_size);
  add16(is_float ? kTagFloat : kTagPcm);
  add16(channels);
  add32(sample_rate_hz);
  add32(sample_rate_hz * block_align);
  add16(block_align);
  add16(static_cast<std::uint16_t>(bps_ * 8));
  if (is_float) {
    add16(0);
    add4("fact");
    add32(4);
    add32(static_cast<std::uint32_t>(frames));
  }
  add4("data");
  add32(static_cast<std::uint32_t>(data_bytes));

  f_ = std::fopen(name_.c_str(), "wb");
  if (f_ == nullptr) throw Error(name_ + ": cannot create WAV file: " + errno_text());
  if (std::fwrite(hdr.data(), 1, hdr.size(), f_) != hdr.size()) {
    const std::string why = errno_text();
    std::fclose(f_);
    f_ = nullptr;
    throw Error(name_ + ": write failed: " + why);
  }
  block_.resize(kBlockFrames * block_align);
}

WavWriter::~WavWriter() {
  if (f_ != nullptr) std::fclose(f_);
}

void WavWriter::write(std::span<const float> interleaved) {
  if (f_ == nullptr) throw Error(name_ + ": write after close");
  if (interleaved.size() % channels_ != 0)
    throw Error(name_ + ": " + std::to_string(interleaved.size()) + " values are not whole frames of " +
                std::to_string(channels_) + " channels");
  const std::size_t frames = interleaved.size() / channels_;
  if (frames > frames_ - written_)
    throw Error(name_ + ": more than the announced " + std::to_string(frames_) + " frames");
  const std::size_t block_align = static_cast<std::size_t>(channels_) * bps_;
  const bool is_float = format_ == WavSampleFormat::kFloat32;
  for (std::size_t start = 0; start < frames; start += kBlockFrames) {
    const std::size_t n = std::min(kBlockFrames, frames - start);
    for (std::size_t i = 0; i < n; ++i) {
      for (std::size_t c = 0; c < channels_; ++c) {
        const float v = interleaved[(start + i) * channels_ + c];
        if (!is_float && std::isnan(v))
          throw Error(name_ + ": NaN sample at channel " + std::to_string(c) + " frame " +
                      std::to_string(written_ + start + i) + " cannot be stored as PCM");
        encode_sample(block_.data() + i * block_align + c * bps_, v, format_);
      }
    }
    if (std::fwrite(block_.data(), 1, n * block_align, f_) != n * block_align)
      throw Error(name_ + ": write failed: " + errno_text());
  }
  written_ += frames;
}

void WavWriter::close() {
  if (f_ == nullptr) return;
  if (written_ != frames_)
    throw Error(name_ + ": " + std::to_string(written_) + " frames written, " + std::to_string(frames_) +
                " announced");
  const std::uint64_t data_bytes = frames_ * channels_ * bps_;
  if ((data_bytes & 1U) != 0 && std::fputc(0, f_) == EOF)
    throw Error(name_ + ": write failed: " + errno_text());
  std::FILE* f = f_;
  f_ = nullptr;
  if (std::fclose(f) != 0) throw Error(name_ + ": close failed: " + errno_text());
}

}  // namespace ptda::formats
