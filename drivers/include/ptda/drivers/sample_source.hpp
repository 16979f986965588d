// The ADC seam: blocks of one vibration channel with a monotonic timestamp. Backends: IIO buffered
// capture (iio_sample_source), WAV replay (wav_replay_source). Chosen by configuration at start-up.
//
// Lifecycle (what is true in each state):
//   constructed  - holds its configuration only; nothing opened.
//   configured   - configure() opened and validated everything, allocated every buffer; fs_hz() valid.
//   active       - activate() started the stream; read() delivers blocks.
//   deactivated  - deactivate() stopped the stream; activate() may start it again.
#pragma once

#include <cstddef>
#include <cstdint>

#include "ptda/drivers/counter.hpp"

namespace ptda::drivers {

/// Samples per block at most (one read() call).
inline constexpr std::size_t kMaxBlock = 1024;

enum SampleBlockFlag : std::uint32_t {
  kBlockGap = 1U << 0,        ///< samples were lost just before samples[0]; see gap_samples
  kBlockShortRead = 1U << 1,  ///< a read returned part of a scan; the bytes were kept and completed
  kBlockClockTime = 1U << 2,  ///< t_mono_ns estimated from the clock at read time, not a device stamp
  kBlockTimeBack = 1U << 3,   ///< the device timestamp went backwards (or did not advance)
};

/// Contiguous, uniformly spaced samples (1 / fs_hz apart). A gap always starts a new block.
struct SampleBlock {
  std::int64_t t_mono_ns = 0;     ///< time of samples[0] on the daemon's monotonic clock
  std::uint64_t first_index = 0;  ///< index of samples[0] since activate(), counting lost samples too
  std::uint32_t count = 0;        ///< valid samples in samples[0..count)
  std::uint32_t flags = 0;        ///< SampleBlockFlag bits
  std::uint32_t gap_samples = 0;  ///< estimated samples lost before samples[0] (0 unless kBlockGap)
  float samples[kMaxBlock] = {};  ///< stored values (raw ADC codes * configured scale)
};

enum class SourceStatus : std::uint8_t {
  kOk = 0,       ///< a block with count > 0
  kTimeout,      ///< nothing arrived within the timeout (block untouched)
  kEndOfStream,  ///< the source has no more data (replay ended, device went away)
  kError,        ///< a read failed (counted); the caller decides whether to deactivate
  kNotActive,    ///< read() outside the active state
};

/// Plain snapshot of a source's counters.
struct SampleSourceCounters {
  std::uint64_t blocks = 0;
  std::uint64_t samples = 0;
  std::uint64_t timeouts = 0;      ///< reads with a timeout > 0 that found no block in time
  std::uint64_t short_reads = 0;   ///< reads that ended inside a scan
  std::uint64_t gaps = 0;          ///< discontinuities detected from timestamps
  std::uint64_t lost_samples = 0;  ///< sum of the gaps' estimated sizes
  std::uint64_t time_back = 0;     ///< device timestamps that went backwards
  std::uint64_t read_errors = 0;
  std::uint64_t end_of_stream = 0;
};

/// The live counters behind SampleSourceCounters: written by the reading thread, read by any.
struct SampleSourceStats {
  Counter blocks, samples, timeouts, short_reads, gaps, lost_samples, time_back, read_errors, end_of_stream;
  [[nodiscard]] SampleSourceCounters snapshot() const noexcept {
    return {blocks.get(),       samples.get(),   timeouts.get(),    short_reads.get(),  gaps.get(),
            lost_samples.get(), time_back.get(), read_errors.get(), end_of_stream.get()};
  }
};

class SampleSource {
 public:
  virtual ~SampleSource() = default;
  SampleSource(const SampleSource&) = delete;
  SampleSource& operator=(const SampleSource&) = delete;

  /// Opens and validates the device or file and allocates all buffers. Throws ptda::Error saying what
  /// and where. Thread: the main thread at start-up. Blocks and allocates.
  virtual void configure() = 0;
  /// Starts the stream (enables the device buffer; anchors replay time). Throws ptda::Error.
  /// Thread: the main thread. May block briefly; never allocates.
  virtual void activate() = 0;
  /// Fills `out` with the next block. Waits at most timeout_ns for data (this is the reading thread's
  /// one wait); timeout_ns <= 0 polls: no wait, and its kTimeout is not counted in `timeouts` (ptdad
  /// reads real-time sources in bursts this way after its burst timer). Thread: the one reading thread.
  /// Never allocates, throws or logs.
  virtual SourceStatus read(SampleBlock& out, std::int64_t timeout_ns) noexcept = 0;
  /// Stops the stream. Safe to call in any state and twice. Thread: the main thread, after the reading
  /// thread stopped calling read(). Never throws.
  virtual void deactivate() noexcept = 0;

  /// Sample rate after configure() (the device's actual rate, which may differ from the requested one).
  /// Thread: any. Never blocks.
  [[nodiscard]] virtual double fs_hz() const noexcept = 0;
  /// Thread: any. Never blocks or allocates.
  [[nodiscard]] SampleSourceCounters counters() const noexcept { return stats_.snapshot(); }

 protected:
  SampleSource() = default;
  SampleSourceStats stats_;
};

}  // namespace ptda::drivers
