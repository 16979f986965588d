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

CanStatus CandumpReplayChannel::record(const CanFrame& frame, std::int64_t t_ns) noexcept {
  if (tx_count_ >= tx_.size()) {
    stats_.tx_full.add();
    return CanStatus::kTxFull;
  }
  CanFrame& f = tx_[tx_count_++];
  f = frame;
  f.t_ns = t_ns;
  stats_.tx_frames.add();
  return CanStatus::kOk;
}

CanStatus CandumpReplayChannel::send(const CanFrame& frame) noexcept {
  if (!active_) return CanStatus::kNotActive;
  const std::int64_t now = clock_.now_ns();
  if (cyc_.set) run_cyclic(now);  // the kernel's frames before this one, in time order
  return record(frame, now);
}

// Linux's bcm_tx_timeout_handler: at each expiry one frame while count > 0; the expiry that finds count
// at 0, or the frame that brings it to 0, stops the timer (ival2 is 0: no second interval).
void CandumpReplayChannel::run_cyclic(std::int64_t now) noexcept {
  while (cyc_.running && cyc_.due_ns <= now) {
    if (cyc_.count == 0) {
      cyc_.running = false;
      break;
    }
    (void)record(cyc_.frames[cyc_.next], cyc_.due_ns);
    cyc_.next = (cyc_.next + 1) % cyc_.n;
    if (--cyc_.count == 0) {
      cyc_.running = false;
      break;
    }
    cyc_.due_ns += cyc_.period_ns;
  }
}

void CandumpReplayChannel::cyclic_send_one(std::int64_t now) noexcept {
  (void)record(cyc_.frames[cyc_.next], now);
  cyc_.next = (cyc_.next + 1) % cyc_.n;
  if (cyc_.count > 0) --cyc_.count;
}

CanStatus CandumpReplayChannel::set_cyclic(const CanCyclicTx& tx) noexcept {
  if (!active_) return CanStatus::kNotActive;
  const std::size_t n = tx.frames.size();
  bool valid =
      cyclic_supported() && n > 0 && n <= CanCyclicTx::kMaxFrames && tx.period_ns > 0 && tx.count > 0;
  for (std::size_t i = 0; valid && i < n; ++i) {
    const CanFrame& f = tx.frames[i];
    valid = !f.fd() && !f.error() && f.len <= 8 && f.id == tx.frames[0].id &&
            f.extended() == tx.frames[0].extended();
  }
  if (!valid) {
    stats_.tx_errors.add();
    return CanStatus::kError;
  }
  const std::int64_t now = clock_.now_ns();
  run_cyclic(now);
  if (cyc_.set &&
      (cyc_.frames[0].id != tx.frames[0].id || cyc_.frames[0].extended() != tx.frames[0].extended()))
    cyc_ = CyclicState{};                       // another id is another operation
  if (!cyc_.set || n != cyc_.n) cyc_.next = 0;  // the kernel restarts the turn when nframes changes
  for (std::size_t i = 0; i < n; ++i) cyc_.frames[i] = tx.frames[i];
  cyc_.n = n;
  cyc_.count = tx.count;
  cyc_.period_ns = tx.period_ns;
  const bool restart = tx.start == CanCyclicTx::Start::kRestart || !cyc_.set;
  cyc_.set = true;
  if (restart) {
    cyclic_send_one(now);
    cyc_.running = true;
    cyc_.due_ns = now + tx.period_ns;
  } else if (tx.start == CanCyclicTx::Start::kAnnounce) {
    cyclic_send_one(now);
  }
  return CanStatus::kOk;
}

void CandumpReplayChannel::deactivate() noexcept {
  if (active_ && cyc_.set) run_cyclic(clock_.now_ns());
  cyc_ = CyclicState{};
  active_ = false;
}

}  // namespace ptda::drivers
