// RIFF/WAVE: PCM 16/24/32-bit or IEEE float32, 1..8 channels, up to 200 kHz; WAVE_FORMAT_EXTENSIBLE too.
// Unknown chunks are skipped (odd sizes padded); a data size of 0 or 0xFFFFFFFF (streamed writers) means
// "up to the end of the file". All functions here are offline: any thread, they block on file I/O and
// allocate, and they throw ptda::Error naming the file.
#pragma once

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

namespace ptda::formats {

enum class WavSampleFormat : std::uint8_t { kPcm16, kPcm24, kPcm32, kFloat32 };

struct WavInfo {
  std::uint32_t sample_rate_hz = 0;  ///< nominal rate from the header
  std::uint16_t channels = 0;
  WavSampleFormat format = WavSampleFormat::kFloat32;
  std::uint64_t frames = 0;  ///< samples per channel
};

/// Streaming reader of one channel as float "stored sample values": PCM is returned as the integer
/// code (e.g. -32768..32767 for 16-bit, no normalisation), float32 as is; recording.toml's `scale`
/// turns these into physical units. Throws ptda::Error naming the file and what is wrong.
class WavReader {
 public:
  explicit WavReader(const std::filesystem::path& path);
  ~WavReader();
  WavReader(const WavReader&) = delete;
  WavReader& operator=(const WavReader&) = delete;

  [[nodiscard]] const WavInfo& info() const noexcept { return info_; }
  /// Reads up to out.size() frames of `channel`; returns frames read (0 at the end).
  /// Throws ptda::Error on a short/corrupt file (with the frame index) or a bad channel.
  /// Thread: the owner's. Blocks on file I/O; allocates only the first time a larger block is needed.
  std::size_t read(std::uint16_t channel, std::span<float> out);
  /// Moves the read position to `frame` (clamped to the end). Throws ptda::Error on an I/O error.
  void seek(std::uint64_t frame);
  /// Current read position in frames.
  [[nodiscard]] std::uint64_t position() const noexcept { return pos_frames_; }

 private:
  std::filesystem::path path_;
  std::FILE* f_ = nullptr;
  WavInfo info_;
  std::uint64_t data_offset_ = 0;
  std::uint64_t pos_frames_ = 0;
  std::vector<std::uint8_t> buf_;
  std::uint16_t block_align_ = 0;       // bytes per frame
  std::uint16_t bytes_per_sample_ = 0;  // container bytes of one sample
};

/// Bytes of one sample in `format` (2, 3, 4, 4).
[[nodiscard]] std::uint16_t wav_bytes_per_sample(WavSampleFormat format) noexcept;

/// Reads one whole channel. Throws ptda::Error.
[[nodiscard]] std::vector<float> read_wav_channel(const std::filesystem::path& path, std::uint16_t channel,
                                                  WavInfo* info = nullptr);

/// Writes interleaved frames (channels.size() channels of equal length) in `format`. PCM values are
/// rounded and saturated to the format's integer range (they are codes, not normalised values).
/// Throws ptda::Error.
void write_wav(const std::filesystem::path& path, std::uint32_t sample_rate_hz, WavSampleFormat format,
               const std::vector<std::vector<float>>& channels);

/// Streaming writer with the frame count known up front: the header is written at construction, the
/// samples block by block (the same bytes as write_wav for the same samples), close() checks the count.
/// Values are encoded as write_wav does. Thread: the owner's; blocks on file I/O; allocates at
/// construction only. Throws ptda::Error naming the file.
class WavWriter {
 public:
  WavWriter(const std::filesystem::path& path, std::uint32_t sample_rate_hz, WavSampleFormat format,
            std::uint16_t channels, std::uint64_t frames);
  ~WavWriter();
  WavWriter(const WavWriter&) = delete;
  WavWriter& operator=(const WavWriter&) = delete;

  /// Appends interleaved frames (size a multiple of the channel count). A NaN in a PCM file or more
  /// frames than announced throws (naming the frame).
  void write(std::span<const float> interleaved);
  /// Pads, flushes and closes; throws when fewer frames than announced were written.
  void close();
  [[nodiscard]] std::uint64_t frames_written() const noexcept { return written_; }

 private:
  std::string name_;
  std::FILE* f_ = nullptr;
  WavSampleFormat format_;
  std::uint16_t channels_ = 0;
  std::uint16_t bps_ = 0;
  std::uint64_t frames_ = 0;
  std::uint64_t written_ = 0;
  std::vector<std::uint8_t> block_;
};

}  // namespace ptda::formats
