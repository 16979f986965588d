// In-memory devices for the daemon's fault tests (daemon_faults_test, daemon_clear_test,
// daemon_training_test): a SampleSource that serves exactly the blocks (samples, indices, flags,
// stamps) a test built, and a CanChannel that serves exactly the frames it built and records the frames
// sent to it (CAN alarm frames). They are plugged into the daemon's real threads through the test-only
// DeviceFactory hook (daemon/core/pipeline.hpp). Times in a plan are stream times (sample 0 at 0 ns);
// the factory maps them onto the daemon clock with one origin per pipeline (the clock at configure,
// like the replay backends' ReplayTimeline), so the stream and the alarm manager's clock agree.
//
// A gate (stream time) lets a test hold the data at a point: blocks ending after the gate and frames
// after gate + can_lead_ns are not released until the test moves the gate.
#pragma once

#include <time.h>

#include <atomic>
#include <cstdint>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "alarm/recording_alarm_output.hpp"
#include "core/pipeline.hpp"
#include "core/sim_backends.hpp"
#include "ptda/drivers/can_channel.hpp"
#include "ptda/drivers/sample_source.hpp"

namespace ptda::daemon::test {

/// What the fake source serves, block by block (t_mono_ns relative to the stream origin).
struct SourcePlan {
  double fs_hz = 0.0;
  std::vector<drivers::SampleBlock> blocks;
};

/// What the fake channel serves (t_ns relative to the stream origin), plus counter injections.
struct ChannelPlan {
  std::vector<CanFrame> frames;
  /// After frame index `overflow_at` was released, rx_overflow_drops reads `overflow_drops` (as the
  /// SocketCAN driver reports SO_RXQ_OVFL). SIZE_MAX = never.
  std::size_t overflow_at = std::numeric_limits<std::size_t>::max();
  std::uint64_t overflow_drops = 0;
};

/// Splits samples into blocks of block_len with exact stamps (sample i at ceil(i * 1e9 / fs)).
inline SourcePlan plan_blocks(const SimRecording& rec, std::size_t block_len) {
  SourcePlan p;
  p.fs_hz = rec.fs_hz;
  for (std::size_t pos = 0; pos < rec.samples.size(); pos += block_len) {
    drivers::SampleBlock b;
    b.first_index = pos;
    b.count = static_cast<std::uint32_t>(std::min(block_len, rec.samples.size() - pos));
    b.t_mono_ns = rec.sample_offset_ns(pos);
    std::copy_n(rec.samples.data() + pos, b.count, b.samples);
    p.blocks.push_back(b);
  }
  return p;
}

/// Sets [decision] k and n in a pipeline text (whatever the example file sets them to).
/// (Plain string search: GCC 12's <regex> trips -Wmaybe-uninitialized under ASan + -Werror.)
inline std::string with_decision(std::string pipeline, int k, int n) {
  const auto set_line = [&pipeline](const std::string& key, int value) {
    const std::string prefix = "\n" + key + " = ";
    const std::size_t pos = pipeline.find(prefix);
    if (pos == std::string::npos) throw std::runtime_error("with_decision: no '" + key + " = ' line");
    const std::size_t end = pipeline.find('\n', pos + 1);
    pipeline.replace(pos + 1, end - (pos + 1), key + " = " + std::to_string(value));
  };
  set_line("k", k);
  set_line("n", n);
  return pipeline;
}

inline void nap_ms(int ms) {
  timespec ts{0, static_cast<long>(ms) * 1'000'000L};
  ::nanosleep(&ts, nullptr);
}

/// Shared between a factory and the devices it made.
struct Gate {
  std::atomic<std::int64_t> t_ns{std::numeric_limits<std::int64_t>::max()};
  std::int64_t can_lead_ns = 200'000'000;  ///< frames up to gate + this are released
};

class FakeSource final : public drivers::SampleSource {
 public:
  FakeSource(std::shared_ptr<const SourcePlan> plan, std::int64_t origin_ns, Gate& gate)
      : plan_(std::move(plan)), origin_(origin_ns), gate_(gate) {}
  void configure() override {}
  void activate() override {
    pos_ = 0;
    active_ = true;
  }
  drivers::SourceStatus read(drivers::SampleBlock& out, std::int64_t timeout_ns) noexcept override {
    (void)timeout_ns;
    if (!active_) return drivers::SourceStatus::kNotActive;
    if (pos_ >= plan_->blocks.size()) {
      if (!ended_) stats_.end_of_stream.add();
      ended_ = true;
      return drivers::SourceStatus::kEndOfStream;
    }
    const drivers::SampleBlock& b = plan_->blocks[pos_];
    const std::int64_t block_end = b.t_mono_ns + static_cast<std::int64_t>(1e9 * b.count / plan_->fs_hz);
    if (block_end > gate_.t_ns.load(std::memory_order_acquire)) {
      nap_ms(1);
      stats_.timeouts.add();
      return drivers::SourceStatus::kTimeout;
    }
    out = b;
    out.t_mono_ns += origin_;
    ++pos_;
    stats_.blocks.add();
    stats_.samples.add(b.count);
    if ((b.flags & drivers::kBlockGap) != 0) {
      stats_.gaps.add();
      stats_.lost_samples.add(b.gap_samples);
    }
    if ((b.flags & drivers::kBlockShortRead) != 0) stats_.short_reads.add();
    if ((b.flags & drivers::kBlockTimeBack) != 0) stats_.time_back.add();
    return drivers::SourceStatus::kOk;
  }
  void deactivate() noexcept override { active_ = false; }
  [[nodiscard]] double fs_hz() const noexcept override { return plan_->fs_hz; }

 private:
  std::shared_ptr<const SourcePlan> plan_;
  std::int64_t origin_;
  Gate& gate_;
  std::size_t pos_ = 0;
  bool active_ = false;
  bool ended_ = false;
};

class FakeChannel final : public drivers::CanChannel {
 public:
  FakeChannel(std::shared_ptr<const ChannelPlan> plan, std::int64_t origin_ns, Gate& gate)
      : plan_(std::move(plan)), origin_(origin_ns), gate_(gate) {
    sent_.resize(1 << 16);
  }
  void configure() override {}
  void activate() override {
    pos_ = 0;
    active_ = true;
  }
  drivers::CanStatus receive(std::span<CanFrame> out, std::size_t& received,
                             std::int64_t timeout_ns) noexcept override {
    (void)timeout_ns;
    received = 0;
    if (!active_) return drivers::CanStatus::kNotActive;
    if (pos_ >= plan_->frames.size()) return drivers::CanStatus::kEndOfStream;
    const std::int64_t limit = gate_.t_ns.load(std::memory_order_acquire);
    while (received < out.size() && pos_ < plan_->frames.size()) {
      const CanFrame& f = plan_->frames[pos_];
      if (limit != std::numeric_limits<std::int64_t>::max() && f.t_ns > limit + gate_.can_lead_ns) break;
      CanFrame g = f;
      g.t_ns += origin_;
      if (g.error()) drivers::apply_error_frame(g, stats_);
      stats_.rx_frames.add();
      if (g.error()) stats_.rx_error_frames.add();
      if (pos_ == plan_->overflow_at) stats_.rx_overflow_drops.set(plan_->overflow_drops);
      out[received++] = g;
      ++pos_;
    }
    if (received == 0) {
      nap_ms(1);
      return drivers::CanStatus::kTimeout;
    }
    return drivers::CanStatus::kOk;
  }
  drivers::CanStatus send(const CanFrame& frame) noexcept override {
    const std::size_t n = sent_count_.load(std::memory_order_relaxed);
    if (n >= sent_.size()) return drivers::CanStatus::kTxFull;
    sent_[n] = frame;
    sent_count_.store(n + 1, std::memory_order_release);
    stats_.tx_frames.add();
    return drivers::CanStatus::kOk;
  }
  void deactivate() noexcept override { active_ = false; }

  /// Frames sent so far. Thread: any once the sending thread stopped (or the count read acquires).
  [[nodiscard]] std::span<const CanFrame> sent() const noexcept {
    return {sent_.data(), sent_count_.load(std::memory_order_acquire)};
  }

 private:
  std::shared_ptr<const ChannelPlan> plan_;
  std::int64_t origin_;
  Gate& gate_;
  std::size_t pos_ = 0;
  bool active_ = false;
  std::vector<CanFrame> sent_;
  std::atomic<std::size_t> sent_count_{0};
};

/// Makes fresh fakes over the same plans for every pipeline (a reload or the end of field training
/// starts the stream again from its beginning). The latest devices stay inspectable.
class FakeDevices final : public DeviceFactory {
 public:
  FakeDevices(std::shared_ptr<const SourcePlan> source, std::shared_ptr<const ChannelPlan> channel,
              bool recording_output = false)
      : source_(std::move(source)), channel_(std::move(channel)), recording_output_(recording_output) {}

  std::unique_ptr<drivers::SampleSource> make_source(drivers::Clock& clock) override {
    origin_.store(clock.now_ns(), std::memory_order_release);
    auto s = std::make_unique<FakeSource>(source_, origin(), gate);
    last_source = s.get();
    ++pipelines;
    return s;
  }
  std::unique_ptr<drivers::CanChannel> make_channel(drivers::Clock& clock) override {
    (void)clock;
    auto c = std::make_unique<FakeChannel>(channel_, origin(), gate);
    last_channel = c.get();
    return c;
  }
  void add_outputs(std::vector<std::unique_ptr<drivers::AlarmOutput>>& outputs,
                   drivers::CanChannel& channel) override {
    (void)channel;
    if (!recording_output_) return;
    auto o = std::make_unique<drivers::RecordingAlarmOutput>(1 << 20);
    last_output = o.get();
    outputs.push_back(std::move(o));
  }
  /// Daemon time of stream time 0 of the latest pipeline.
  [[nodiscard]] std::int64_t origin() const noexcept { return origin_.load(std::memory_order_acquire); }

  Gate gate;
  FakeSource* last_source = nullptr;
  FakeChannel* last_channel = nullptr;
  drivers::RecordingAlarmOutput* last_output = nullptr;
  std::atomic<int> pipelines{0};  // counted by the daemon thread, read by the test thread

 private:
  std::shared_ptr<const SourcePlan> source_;
  std::shared_ptr<const ChannelPlan> channel_;
  bool recording_output_;
  // Written by the daemon thread at each (re)configure, read by the test thread (TSan found the race).
  std::atomic<std::int64_t> origin_{0};
};

}  // namespace ptda::daemon::test
