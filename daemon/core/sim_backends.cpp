#include "core/sim_backends.hpp"

#include <spdlog/spdlog.h>
#include <stdlib.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <system_error>

#include "ptda/common/error.hpp"
#include "ptda/common/time.hpp"
#include "ptda/formats/candump.hpp"
#include "ptda/formats/recording.hpp"
#include "ptda/formats/wav.hpp"
#include "ptda/sim/simulator.hpp"

namespace ptda::daemon {

namespace fs = std::filesystem;
using drivers::CanStatus;
using drivers::SourceStatus;

std::int64_t SimRecording::sample_offset_ns(std::uint64_t index) const noexcept {
  // ceil(index * 1e12 / fs_mhz) without overflow, in 64 bits (no unsigned __int128 on 32-bit targets),
  // as WindowSlicer::offset_ns: index = q * F + m, whole multiples of F samples are 1000 s, and
  // m * 1e9 = c * F + e.
  const auto f = static_cast<std::uint64_t>(fs_mhz);
  const std::uint64_t q = index / f;
  const std::uint64_t m = index % f;
  const std::uint64_t c = m * 1'000'000'000ULL / f;
  const std::uint64_t e = m * 1'000'000'000ULL - c * f;
  return static_cast<std::int64_t>(q * 1'000'000'000'000ULL + c * 1000 + (e * 1000 + f - 1) / f);
}

namespace {

/// A scratch directory removed when it goes out of scope.
class TempDir {
 public:
  TempDir() {
    const char* base = std::getenv("TMPDIR");
    std::string templ = std::string(base != nullptr && *base != '\0' ? base : "/tmp") + "/ptdad-sim-XXXXXX";
    std::vector<char> buf(templ.begin(), templ.end());
    buf.push_back('\0');
    if (::mkdtemp(buf.data()) == nullptr) {
      throw Error(templ + ": cannot create a scratch directory for the simulator: " + std::strerror(errno));
    }
    path_ = buf.data();
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  [[nodiscard]] const fs::path& path() const noexcept { return path_; }

 private:
  fs::path path_;
};

}  // namespace

std::shared_ptr<const SimRecording> make_sim_recording(const fs::path& scenario_path, std::uint32_t seed) {
  const sim::Scenario scenario = sim::load_scenario(scenario_path);
  for (const std::string& w : scenario.warnings) spdlog::warn("{}", w);
  // Simulate through the recording writer and read it back: the simulator backend then serves exactly
  // the bytes `ptda simulate` would write (quantised codes, candump microsecond timestamps).
  TempDir dir;
  const fs::path rec_dir = dir.path() / "rec";
  const sim::SimulationSummary summary = sim::simulate_to_directory(
      scenario, rec_dir, seed == 0 ? std::nullopt : std::optional<std::uint64_t>(seed));
  const formats::RecordingMeta meta = formats::read_recording_meta(rec_dir);

  auto rec = std::make_shared<SimRecording>();
  formats::WavInfo info;
  rec->samples = formats::read_wav_channel(rec_dir / meta.vibration_file, meta.channel, &info);
  if (rec->samples.empty()) throw Error(scenario_path.string() + ": the scenario simulates no samples");
  const auto scale = static_cast<float>(meta.scale);
  if (meta.scale != 1.0) {
    for (float& x : rec->samples) x *= scale;
  }
  rec->fs_hz = static_cast<double>(info.sample_rate_hz);
  rec->fs_mhz = static_cast<std::int64_t>(info.sample_rate_hz) * 1000;
  rec->start_unix_ns = seconds_to_ns(meta.start_time_s);
  rec->seed = summary.seed;
  rec->scenario_name = scenario.name;
  formats::CandumpReader reader(rec_dir / meta.can_file);
  formats::CandumpRecord record;
  while (reader.next(record)) {
    CanFrame f = record.frame;
    f.t_ns -= rec->start_unix_ns;
    rec->frames.push_back(f);
  }
  rec->loop_ns = rec->sample_offset_ns(rec->samples.size());
  // Frames stamped after the end of the vibration would appear twice per loop period: drop them.
  while (!rec->frames.empty() && rec->frames.back().t_ns >= rec->loop_ns) rec->frames.pop_back();
  return rec;
}

// ---- SimSampleSource --------------------------------------------------------------------------

SimSampleSource::SimSampleSource(std::shared_ptr<const SimRecording> rec, SimAnchor& anchor,
                                 drivers::Clock& clock, SimSourceConfig config)
    : rec_(std::move(rec)), anchor_(anchor), clock_(clock), config_(config) {}

void SimSampleSource::configure() {
  if (!rec_ || rec_->samples.empty()) throw Error("adc sim: no simulated recording");
  if (config_.block_len == 0 || config_.block_len > drivers::kMaxBlock) {
    throw Error("adc sim: block_len " + std::to_string(config_.block_len) + " is outside 1.." +
                std::to_string(drivers::kMaxBlock));
  }
  configured_ = true;
}

void SimSampleSource::activate() {
  if (!configured_) throw Error("adc sim: activate() before configure()");
  t0_mono_ns_ = anchor_.resolve(clock_);
  next_index_ = 0;
  active_ = true;
}

SourceStatus SimSampleSource::read(drivers::SampleBlock& out, std::int64_t timeout_ns) noexcept {
  if (!active_) return SourceStatus::kNotActive;
  const std::uint64_t total = rec_->samples.size();
  if (!config_.loop && next_index_ >= total) {
    stats_.end_of_stream.add();
    return SourceStatus::kEndOfStream;
  }
  const std::uint64_t loop = next_index_ / total;
  const std::uint64_t i = next_index_ % total;
  const auto count = static_cast<std::uint32_t>(std::min<std::uint64_t>(config_.block_len, total - i));
  const std::int64_t loop_base = static_cast<std::int64_t>(loop) * rec_->loop_ns;
  const std::int64_t t_first = t0_mono_ns_ + loop_base + rec_->sample_offset_ns(i);
  if (!config_.fast) {
    const std::int64_t due = t0_mono_ns_ + loop_base + rec_->sample_offset_ns(i + count - 1);
    std::int64_t now = clock_.now_ns();
    if (now < due) {
      if (timeout_ns <= 0) return SourceStatus::kTimeout;  // a poll (burst read): no wait, not counted
      clock_.sleep_until_ns(std::min(due, now + timeout_ns));
      now = clock_.now_ns();
      if (now < due) {
        stats_.timeouts.add();
        return SourceStatus::kTimeout;
      }
    }
  }
  out.t_mono_ns = t_first;
  out.first_index = next_index_;
  out.count = count;
  out.flags = 0;
  out.gap_samples = 0;
  std::memcpy(out.samples, rec_->samples.data() + i, count * sizeof(float));
  next_index_ += count;
  stats_.blocks.add();
  stats_.samples.add(count);
  return SourceStatus::kOk;
}

// ---- SimCanChannel ----------------------------------------------------------------------------

SimCanChannel::SimCanChannel(std::shared_ptr<const SimRecording> rec, SimAnchor& anchor,
                             drivers::Clock& clock, SimCanConfig config)
    : rec_(std::move(rec)), anchor_(anchor), clock_(clock), config_(config) {}

void SimCanChannel::configure() {
  if (!rec_) throw Error("can sim: no simulated recording");
  if (config_.loop && rec_->frames.empty()) throw Error("can sim: the scenario produced no CAN frames");
  tx_.assign(std::max<std::size_t>(1, config_.tx_capacity), CanFrame{});
  configured_ = true;
}

void SimCanChannel::activate() {
  if (!configured_) throw Error("can sim: activate() before configure()");
  t0_mono_ns_ = anchor_.resolve(clock_);
  next_frame_ = 0;
  active_ = true;
}

std::int64_t SimCanChannel::frame_time(std::uint64_t k) const noexcept {
  const std::uint64_t n = rec_->frames.size();
  return t0_mono_ns_ + static_cast<std::int64_t>(k / n) * rec_->loop_ns + rec_->frames[k % n].t_ns;
}

CanStatus SimCanChannel::receive(std::span<CanFrame> out, std::size_t& received,
                                 std::int64_t timeout_ns) noexcept {
  received = 0;
  if (!active_) return CanStatus::kNotActive;
  const std::uint64_t n = rec_->frames.size();
  if (n == 0 || (!config_.loop && next_frame_ >= n)) return CanStatus::kEndOfStream;
  if (!config_.fast) {
    const std::int64_t due = frame_time(next_frame_);
    std::int64_t now = clock_.now_ns();
    if (now < due) {
      if (timeout_ns <= 0) return CanStatus::kTimeout;  // a poll (burst read): no wait
      clock_.sleep_until_ns(std::min(due, now + timeout_ns));
      now = clock_.now_ns();
      if (now < due) return CanStatus::kTimeout;
    }
  }
  const std::int64_t now = config_.fast ? 0 : clock_.now_ns();
  while (received < out.size()) {
    if (!config_.loop && next_frame_ >= n) break;
    const std::int64_t t = frame_time(next_frame_);
    if (!config_.fast && t > now) break;
    CanFrame& f = out[received];
    f = rec_->frames[next_frame_ % n];
    f.t_ns = t;
    if (f.error()) drivers::apply_error_frame(f, stats_);
    ++received;
    ++next_frame_;
  }
  stats_.rx_frames.add(received);
  return received > 0 ? CanStatus::kOk : CanStatus::kTimeout;
}

CanStatus SimCanChannel::send(const CanFrame& frame) noexcept {
  if (!active_) return CanStatus::kNotActive;
  const std::uint64_t k = stats_.tx_frames.get();
  CanFrame& slot = tx_[k % tx_.size()];
  slot = frame;
  slot.t_ns = clock_.now_ns();
  stats_.tx_frames.add();
  return CanStatus::kOk;
}

CanFrame SimCanChannel::last_sent() const noexcept {
  const std::uint64_t k = stats_.tx_frames.get();
  return k == 0 ? CanFrame{} : tx_[(k - 1) % tx_.size()];
}

}  // namespace ptda::daemon
