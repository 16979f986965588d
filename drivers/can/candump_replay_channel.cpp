#include "can/candump_replay_channel.hpp"

#include <exception>
#include <string>
#include <utility>

#include "ptda/common/error.hpp"
#include "ptda/formats/candump.hpp"

namespace ptda::drivers {

CandumpReplayChannel::CandumpReplayChannel(CandumpReplayConfig config, Clock& clock)
    : config_(std::move(config)), clock_(clock) {}

CandumpReplayChannel::~CandumpReplayChannel() = default;

void CandumpReplayChannel::configure() {
  reader_ = std::make_unique<formats::CandumpReader>(config_.path);  // throws ptda::Error naming the file
  record_ = std::make_unique<formats::CandumpRecord>();
  record_->iface.reserve(32);
  frame_count_ = 0;
  // One validating pass: a malformed line fails here, with its line number, not in the run state.
  while (reader_->next(*record_)) {
    if (!config_.interface.empty() && record_->iface != config_.interface) continue;
    if (config_.skip_transmitted && record_->direction == 'T') continue;
    if (frame_count_ == 0) first_t_ns_ = record_->frame.t_ns;
    ++frame_count_;
  }
  reader_->rewind();
  tx_.assign(config_.tx_capacity, CanFrame{});
  tx_count_ = 0;
  pos_ = 0;
  configured_ = true;
}

void CandumpReplayChannel::activate() {
  if (!configured_) throw Error(config_.path.string(), 0, 0, "candump replay: activate() before configure()");
  origin_unix_ns_ = config_.timeline.origin_unix_ns.value_or(frame_count_ == 0 ? 0 : first_t_ns_);
  origin_mono_ns_ = config_.timeline.origin_mono_ns.value_or(clock_.now_ns());
  reader_->rewind();
  pos_ = 0;
  have_next_ = false;
  at_end_ = false;
  active_ = true;
}

bool CandumpReplayChannel::pull() noexcept {
  try {
    while (reader_->next(*record_)) {
      if (!config_.interface.empty() && record_->iface != config_.interface) continue;
      if (config_.skip_transmitted && record_->direction == 'T') continue;
      next_ = record_->frame;
      return true;
    }
  } catch (const std::exception&) {  // the file changed since configure(): counted, never thrown
    stats_.rx_errors.add();
  }
  at_end_ = true;
  return false;
}

CanStatus CandumpReplayChannel::receive(std::span<CanFrame> out, std::size_t& received,
                                        std::int64_t timeout_ns) noexcept {
  received = 0;
  if (!active_) return CanStatus::kNotActive;
  if (!have_next_ && (at_end_ || !(have_next_ = pull()))) return CanStatus::kEndOfStream;
  if (out.empty()) return CanStatus::kOk;
  const bool paced = config_.pace == ReplayPace::kRealTime;
  std::int64_t now = clock_.now_ns();
  if (paced) {
    const std::int64_t due = map_time(next_.t_ns);
    if (due > now) {
      if (timeout_ns <= 0) return CanStatus::kTimeout;  // a poll (burst read): no wait
      const std::int64_t deadline = now + timeout_ns;
      clock_.sleep_until_ns(due < deadline ? due : deadline);
      now = clock_.now_ns();
      if (due > now) return CanStatus::kTimeout;
    }
  }
  while (received < out.size() && have_next_) {
    const std::int64_t t = map_time(next_.t_ns);
    if (paced && t > now) break;
    CanFrame& f = out[received];
    f = next_;
    f.t_ns = t;
    if (f.error()) apply_error_frame(f, stats_);
    stats_.rx_frames.add();
    ++received;
    ++pos_;
    have_next_ = pull();
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
