// Replay backend of SampleSource: one channel of a recording's WAV file (formats::WavReader, opened at
// configure()), in blocks with synthetic timestamps t0 + index / fs on the daemon clock, paced at real
// time (a block is released once the clock has passed its last sample, like a real ADC FIFO) or as
// fast as the caller reads. The file is read up to kReadAheadBlocks blocks at a time into a buffer
// allocated at configure(); the blocks are still handed out one by one, each when its time has come.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <vector>

#include "ptda/drivers/clock.hpp"
#include "ptda/drivers/sample_source.hpp"

namespace ptda::formats {
class WavReader;
}

namespace ptda::drivers {

struct WavReplayConfig {
  std::filesystem::path path;
  std::uint16_t channel = 0;      ///< 0-based
  std::uint32_t block_len = 256;  ///< samples per block, 1..kMaxBlock
  float scale = 1.0F;             ///< sample = stored value * scale
  ReplayPace pace = ReplayPace::kRealTime;
  std::int64_t start_unix_ns = 0;  ///< log time of sample 0 (recording.toml start_time_s)
  ReplayTimeline timeline;         ///< log time -> daemon clock (shared with the CAN replay)
};

class WavReplaySource final : public SampleSource {
 public:
  /// Blocks read from the file per read (the last read of a file may hold fewer).
  static constexpr std::uint32_t kReadAheadBlocks = 16;

  /// `clock` must outlive the source.
  WavReplaySource(WavReplayConfig config, Clock& clock);
  ~WavReplaySource() override;

  /// Opens the WAV, checks the channel and block length, primes the reader's buffers.
  /// Throws ptda::Error naming the file. Thread: main, start-up. Blocks and allocates.
  void configure() override;
  /// Rewinds to sample 0 and anchors the timeline. Throws ptda::Error.
  void activate() override;
  /// Sets the timeline's daemon-clock origin (ReplayTimeline::origin_mono_ns) for the next activate().
  /// Thread: main, while not active.
  void set_origin_mono_ns(std::int64_t origin_mono_ns) noexcept {
    config_.timeline.origin_mono_ns = origin_mono_ns;
  }
  /// Real-time pace: sleeps on the clock (at most timeout_ns) until the block's last sample is due.
  /// kEndOfStream after the last sample. File errors return kError (counted).
  SourceStatus read(SampleBlock& out, std::int64_t timeout_ns) noexcept override;
  void deactivate() noexcept override { active_ = false; }
  [[nodiscard]] double fs_hz() const noexcept override { return fs_hz_; }

  /// Total samples in the file. Thread: any after configure().
  [[nodiscard]] std::uint64_t total_samples() const noexcept { return total_; }
  /// Daemon-clock time of sample `index`. Thread: any after activate().
  [[nodiscard]] std::int64_t sample_time_ns(std::uint64_t index) const noexcept;
  /// Reads from the file since activate() (a plain counter; tests check the read-ahead).
  /// Thread: the reader's.
  [[nodiscard]] std::uint64_t file_reads() const noexcept { return file_reads_; }

 private:
  WavReplayConfig config_;
  Clock& clock_;
  std::unique_ptr<formats::WavReader> reader_;
  double fs_hz_ = 0.0;
  std::uint64_t total_ = 0;
  std::int64_t t0_mono_ns_ = 0;  ///< daemon time of sample 0
  std::uint64_t next_index_ = 0;
  /// Up to kReadAheadBlocks blocks read ahead of their release times: samples [staged_pos_,
  /// staged_end_) are not handed out yet, the first of them is sample next_index_.
  std::vector<float> staged_;
  std::uint32_t staged_pos_ = 0;
  std::uint32_t staged_end_ = 0;
  /// A multi-block read failed (a truncated or unreadable file): one block per read from then on,
  /// so every complete block before the cut is still delivered. Cleared by activate().
  bool single_block_ = false;
  std::uint64_t file_reads_ = 0;
  bool active_ = false;

  /// Refills staged_ at next_index_; kOk (at least one sample staged), kEndOfStream or kError.
  SourceStatus refill() noexcept;
};

}  // namespace ptda::drivers
