#include "can/candump_replay_channel.hpp"

#include <string>
#include <utility>

#include "ptda/common/error.hpp"
#include "ptda/formats/candump.hpp"

namespace ptda::drivers {

CandumpReplayChannel::CandumpReplayChannel(CandumpReplayConfig config, Clock& clock)
    : config_(std::move(config)), clock_(clock) {}

void CandumpReplayChannel::configure() {
  frames_.clear();
  formats::CandumpReader reader(config_.path);  // throws ptda::Error naming the file
  formats::CandumpRecord rec;
  while (reader.next(rec)) {
    if (!config_.interface.empty() && rec.iface != config_.interface) continue;
    if (config_.skip_transmitted && rec.direction == 'T') continue;
    if (frames_.size() >= config_.max_frames) {
      throw Error(config_.path.string(), reader.line_no(), 0,
                  "more than max_frames = " + std::to_string(config_.max_frames) + " frames");
    }
    frames_.push_back(rec.frame);
  }
  frames_.shrink_to_fit();
  tx_.assign(config_.tx_capacity, CanFrame{});
  tx_count_ = 0;
  pos_ = 0;
  configured_ = true;
}

void CandumpReplayChannel::activate() {
  if (!configured_) throw Error(config_.path.string(), 0, 0, "candump replay: activate() before configure()");
  origin_unix_ns_ = config_.timeline.origin_unix_ns.value_or(frames_.empty() ? 0 : frames_.front().t_ns);
  origin_mono_ns_ = config_.timeline.origin_mono_ns.value_or(clock_.now_ns());
  pos_ = 0;
  active_ = true;
}

CanStatus CandumpReplayChannel::receive(std::span<CanFrame> out, std::size_t& received,
                                        std::int64_t timeout_ns) noexcept {
  received = 0;
  if (!active_) return CanStatus::kNotActive;
  if (pos_ >= frames_.size()) return CanStatus::kEndOfStream;
  if (out.empty()) return CanStatus::kOk;
  const bool paced = config_.pace == ReplayPace::kRealTime;
  std::int64_t now = clock_.now_ns();
  if (paced) {
    const std::int64_t due = map_time(frames_[pos_].t_ns);
    if (due > now) {
      const std::int64_t deadline = now + (timeout_ns > 0 ? timeout_ns : 0);
      clock_.sleep_until_ns(due < deadline ? due : deadline);
      now = clock_.now_ns();
      if (due > now) return CanStatus::kTimeout;
    }
  }
  while (received < out.size() && pos_ < frames_.size()) {
    const CanFrame& src = frames_[pos_];
    const std::int64_t t = map_time(src.t_ns);
    if (paced && t > now) break;
    CanFrame& f = out[received];
    f = src;
    f.t_ns = t;
    if (f.error()) apply_error_frame(f, stats_);
    stats_.rx_frames.add();
    ++received;
    ++pos_;
  }
  return CanStatus::kOk;
}

CanStatus CandumpReplayChannel::send(const CanFrame& frame) noexcept {
  if (!active_) return CanStatus::kNotActive;
  if (tx_count_ >= tx_.size()) {
    stats_.tx_full.add();
    return CanStatus::kTxFull;
  }
  CanFrame& f = tx_[tx_count_++];
  f = frame;
  f.t_ns = clock_.now_ns();
  stats_.tx_frames.add();
  return CanStatus::kOk;
}

}  // namespace ptda::drivers
