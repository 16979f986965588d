// RIFF/WAVE: PCM 16/24/32-bit or IEEE float32, 1..8 channels, up to 200 kHz; WAVE_FORMAT_EXTENSIBLE too.
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
  std::uint64_t frames = 0;          ///< samples per channel
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
  std::size_t read(std::uint16_t channel, std::span<float> out);

 private:
  std::filesystem::path path_;
  std::FILE* f_ = nullptr;
  WavInfo info_;
  std::uint64_t data_offset_ = 0;
  std::uint64_t pos_frames_ = 0;
  std::vector<std::uint8_t> buf_;
};

/// Reads one whole channel. Throws ptda::Error.
[[nodiscard]] std::vector<float> read_wav_channel(const std::filesystem::path& path, std::uint16_t channel,
                                                  WavInfo* info = nullptr);

/// Writes interleaved frames (channels.size() channels of equal length) in `format`. PCM values are
/// rounded and saturated to the format's integer range (they are codes, not normalised values).
/// Throws ptda::Error.
void write_wav(const std::filesystem::path& path, std::uint32_t sample_rate_hz, WavSampleFormat format,
               const std::vector<std::vector<float>>& channels);

}  // namespace ptda::formats
