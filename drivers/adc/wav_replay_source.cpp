#include "adc/wav_replay_source.hpp"

#include <algorithm>
#include <cmath>
#include <exception>
#include <span>
#include <string>
#include <utility>

#include "ptda/common/error.hpp"
#include "ptda/formats/wav.hpp"

namespace ptda::drivers {

WavReplaySource::WavReplaySource(WavReplayConfig config, Clock& clock)
    : config_(std::move(config)), clock_(clock) {}

WavReplaySource::~WavReplaySource() = default;

void WavReplaySource::configure() {
  const std::string where = config_.path.string();
  if (config_.block_len == 0 || config_.block_len > kMaxBlock)
    throw Error(where, 0, 0, "block_len must be 1.." + std::to_string(kMaxBlock));
  reader_ = std::make_unique<formats::WavReader>(config_.path);
  const formats::WavInfo& info = reader_->info();
  if (config_.channel >= info.channels)
    throw Error(where, 0, 0,
                "channel " + std::to_string(config_.channel) + " out of range (file has " +
                    std::to_string(info.channels) + ")");
  if (info.sample_rate_hz == 0) throw Error(where, 0, 0, "sample rate 0");
  fs_hz_ = static_cast<double>(info.sample_rate_hz);
  total_ = info.frames;
  staged_.assign(static_cast<std::size_t>(config_.block_len) * kReadAheadBlocks, 0.0F);
  // Prime the reader once so its internal buffer is allocated now, not in the first read(). The
  // reader sizes its buffer before it reads, so a file cut within the read-ahead still primes it; a
  // file cut within its first block is refused here, as before the read-ahead.
  try {
    (void)reader_->read(config_.channel, std::span<float>(staged_.data(), staged_.size()));
  } catch (const Error&) {
    reader_->seek(0);
    (void)reader_->read(config_.channel, std::span<float>(staged_.data(), config_.block_len));
  }
  reader_->seek(0);
}

void WavReplaySource::activate() {
  if (!reader_) throw Error(config_.path.string(), 0, 0, "activate() before configure()");
  reader_->seek(0);
  const std::int64_t origin_unix = config_.timeline.origin_unix_ns.value_or(config_.start_unix_ns);
  const std::int64_t origin_mono = config_.timeline.origin_mono_ns.value_or(clock_.now_ns());
  t0_mono_ns_ = origin_mono + (config_.start_unix_ns - origin_unix);
  next_index_ = 0;
  staged_pos_ = 0;
  staged_end_ = 0;
  single_block_ = false;
  file_reads_ = 0;
  active_ = true;
}

std::int64_t WavReplaySource::sample_time_ns(std::uint64_t index) const noexcept {
  // Exact for any length: whole seconds in integers, the remainder in double.
  const auto fs = static_cast<std::uint64_t>(fs_hz_);
  const std::uint64_t whole_s = index / fs;
  const std::uint64_t rest = index % fs;
  return t0_mono_ns_ + static_cast<std::int64_t>(whole_s) * 1'000'000'000 +
         static_cast<std::int64_t>(std::llround(static_cast<double>(rest) * 1e9 / fs_hz_));
}

SourceStatus WavReplaySource::refill() noexcept {
  staged_pos_ = 0;
  staged_end_ = 0;
  if (next_index_ >= total_) return SourceStatus::kEndOfStream;
  for (;;) {
    const std::uint32_t want = config_.block_len * (single_block_ ? 1U : kReadAheadBlocks);
    try {
      ++file_reads_;
      staged_end_ =
          static_cast<std::uint32_t>(reader_->read(config_.channel, std::span<float>(staged_.data(), want)));
      return staged_end_ == 0 ? SourceStatus::kEndOfStream : SourceStatus::kOk;
    } catch (const std::exception&) {  // a truncated or unreadable file: counted, never thrown
      staged_end_ = 0;
      if (single_block_) {
        stats_.read_errors.add();
        return SourceStatus::kError;
      }
    }
    // The multi-block read failed somewhere in its blocks: read them again one by one from where it
    // started, so the complete blocks before the cut still come out, then the error as before.
    single_block_ = true;
    try {
      reader_->seek(next_index_);
    } catch (const std::exception&) {
      stats_.read_errors.add();
      return SourceStatus::kError;
    }
  }
}

SourceStatus WavReplaySource::read(SampleBlock& out, std::int64_t timeout_ns) noexcept {
  if (!active_) return SourceStatus::kNotActive;
  if (staged_pos_ == staged_end_) {
    const SourceStatus s = refill();
    if (s == SourceStatus::kEndOfStream) stats_.end_of_stream.add();
    if (s != SourceStatus::kOk) return s;
  }
  const std::uint32_t count = std::min(config_.block_len, staged_end_ - staged_pos_);
  if (config_.pace == ReplayPace::kRealTime) {
    // Released once the last sample of the block "has been acquired" (read ahead or not).
    const std::int64_t due = sample_time_ns(next_index_ + count - 1);
    std::int64_t now = clock_.now_ns();
    if (due > now) {
      if (timeout_ns <= 0) return SourceStatus::kTimeout;  // a poll (burst read): no wait, not counted
      clock_.sleep_until_ns(std::min(due, now + timeout_ns));
      now = clock_.now_ns();
      if (due > now) {
        stats_.timeouts.add();
        return SourceStatus::kTimeout;
      }
    }
  }
  out.t_mono_ns = sample_time_ns(next_index_);
  out.first_index = next_index_;
  out.count = count;
  out.flags = 0;
  out.gap_samples = 0;
  const float* in = staged_.data() + staged_pos_;
  for (std::uint32_t i = 0; i < count; ++i) out.samples[i] = in[i] * config_.scale;
  next_index_ += count;
  staged_pos_ += count;
  stats_.blocks.add();
  stats_.samples.add(out.count);
  return SourceStatus::kOk;
}

}  // namespace ptda::drivers
