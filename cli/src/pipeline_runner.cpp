#include "ptda/cli/pipeline_runner.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <optional>
#include <set>
#include <sstream>
#include <utility>

#include "ptda/cli/progress.hpp"
#include "ptda/common/can_frame.hpp"
#include "ptda/common/error.hpp"
#include "ptda/common/time.hpp"
#include "ptda/config/speed_codec.hpp"
#include "ptda/dsp/decision.hpp"
#include "ptda/dsp/frame_clock.hpp"
#include "ptda/dsp/window_slicer.hpp"
#include "ptda/formats/baseline_file.hpp"
#include "ptda/formats/candump.hpp"

namespace ptda::cli {

namespace fs = std::filesystem;

namespace {

std::string num(double v) {
  std::ostringstream s;
  s.precision(10);
  s << v;
  return s.str();
}

}  // namespace

RecordingInfo open_recording(const fs::path& dir) {
  std::error_code ec;
  if (!fs::exists(dir, ec)) throw Error(dir.string() + ": recording directory does not exist");
  if (!fs::is_directory(dir, ec))
    throw Error(dir.string() + ": not a directory (expected a recording directory)");
  RecordingInfo rec;
  rec.dir = dir;
  rec.meta = formats::read_recording_meta(dir);
  rec.wav_path = dir / rec.meta.vibration_file;
  rec.can_path = dir / rec.meta.can_file;
  {
    formats::WavReader wav(rec.wav_path);
    rec.wav = wav.info();
  }
  if (rec.meta.channel >= rec.wav.channels) {
    throw Error((dir / "recording.toml").string() + ": channel " + std::to_string(rec.meta.channel) +
                " but " + rec.wav_path.string() + " has " + std::to_string(rec.wav.channels) + " channel(s)");
  }
  if (rec.wav.sample_rate_hz == 0) throw Error(rec.wav_path.string() + ": sample rate is 0");
  rec.t0_ns = seconds_to_ns(rec.meta.start_time_s);
  rec.duration_s = static_cast<double>(rec.wav.frames) / static_cast<double>(rec.wav.sample_rate_hz);
  return rec;
}

std::string recording_id(const RecordingInfo& rec) {
  std::ifstream in(rec.wav_path, std::ios::binary);
  if (!in) throw Error(rec.wav_path.string() + ": cannot open to fingerprint it");
  // The CRC of the first MiB, read through a 64 KiB buffer: a zeroed 1 MiB vector cost more start-up
  // time (its page faults) than the CRC itself.
  constexpr std::size_t kHeadBytes = std::size_t{1} << 20;
  std::array<char, std::size_t{1} << 16> chunk{};
  std::uint32_t crc_value = 0;
  for (std::size_t done = 0; done < kHeadBytes && in;) {
    in.read(chunk.data(), static_cast<std::streamsize>(std::min(chunk.size(), kHeadBytes - done)));
    const auto got = static_cast<std::size_t>(in.gcount());
    crc_value = formats::crc32(chunk.data(), got, crc_value);
    done += got;
  }
  if (in.bad()) throw Error(rec.wav_path.string() + ": read error while fingerprinting it");
  std::error_code ec;
  const std::uintmax_t size = fs::file_size(rec.wav_path, ec);
  if (ec) throw Error(rec.wav_path.string() + ": cannot read its size: " + ec.message());
  char crc[16];
  std::snprintf(crc, sizeof crc, "%08x", crc_value);
  return "wav:" + std::to_string(size) + ":" + crc + ":ch" + std::to_string(rec.meta.channel);
}

double pipeline_fs_hz(const RecordingInfo& rec, const config::PipelineConfig& cfg,
                      const std::string& config_source) {
  const double fs = static_cast<double>(rec.wav.sample_rate_hz);
  if (cfg.fs_hz != 0.0 && std::abs(cfg.fs_hz - fs) > 1e-9 * fs) {
    throw Error(config_source + ": [acquisition] fs_hz = " + num(cfg.fs_hz) + " Hz but recording " +
                rec.wav_path.string() + " is sampled at " + num(fs) + " Hz");
  }
  return fs;
}

CanCounters run_recording(const RecordingInfo& rec, const config::PipelineConfig& cfg, PipelineSink& sink,
                          const RunOptions& options) {
  formats::WavReader wav(rec.wav_path);
  formats::CandumpReader can(rec.can_path);
  CanCounters counters;
  const double fs = static_cast<double>(wav.info().sample_rate_hz);
  const std::int64_t latency_ns = seconds_to_ns(cfg.speed_latency_s);
  const float scale = static_cast<float>(rec.meta.scale);
  const bool scaled = rec.meta.scale != 1.0;

  std::optional<dsp::SpeedSample> pending;
  bool can_done = false;
  formats::CandumpRecord record;
  // Reads CAN frames until the next decoded speed sample (counting everything else).
  auto fetch = [&]() {
    while (!pending && !can_done) {
      if (!can.next(record)) {
        can_done = true;
        return;
      }
      if (counters.frames == 0) counters.first_frame_t_ns = record.frame.t_ns;
      counters.last_frame_t_ns = record.frame.t_ns;
      ++counters.frames;
      if ((record.frame.flags & kCanError) == 0)
        ++counters.ids[record.frame.id | (record.frame.extended() ? CanCounters::kExtendedIdKey : 0U)];
      config::DecodedSpeed decoded;
      switch (config::decode_speed(record.frame, cfg.speed_frame, decoded)) {
        case config::DecodeResult::kOk:
          pending = dsp::SpeedSample{record.frame.t_ns - latency_ns, decoded.speed_rad_s, decoded.angle_rad,
                                     decoded.has_angle};
          if (counters.speed_frames == 0) counters.first_speed_t_ns = pending->t_ns;
          counters.last_speed_t_ns = pending->t_ns;
          ++counters.speed_frames;
          break;
        case config::DecodeResult::kOtherId:
          ++counters.other_id;
          break;
        case config::DecodeResult::kWrongDlc:
          ++counters.wrong_dlc;
          break;
        case config::DecodeResult::kRtr:
          ++counters.rtr;
          break;
        case config::DecodeResult::kErrorFrame:
          ++counters.error_frames;
          break;
      }
    }
  };

  Progress progress(options.progress_label.empty() ? rec.dir.filename().string() : options.progress_label,
                    rec.wav.frames, options.progress);
  // Windows are drained once per block, so the slicer's history (4 windows + 1 s by default) must hold
  // a block plus a window: blocks of more than a quarter second are read in quarter seconds. (16384-frame
  // blocks at 10 kHz with 1000-sample windows lost windows before this cap.)
  const std::size_t quarter_s = std::max<std::size_t>(1, static_cast<std::size_t>(fs / 4.0));
  std::vector<float> block(std::clamp<std::size_t>(options.block_frames, 1, quarter_s));
  std::uint64_t pos = 0;
  for (;;) {
    const std::size_t n = wav.read(rec.meta.channel, block);
    if (n == 0) break;
    if (scaled) {
      for (std::size_t i = 0; i < n; ++i) block[i] *= scale;
    }
    const std::int64_t t_end_ns =
        rec.t0_ns + static_cast<std::int64_t>(std::llround(static_cast<double>(pos + n) * 1e9 / fs));
    for (;;) {
      fetch();
      if (!pending || pending->t_ns >= t_end_ns) break;
      sink.on_speed(*pending);
      pending.reset();
    }
    sink.on_samples(std::span<const float>(block.data(), n));
    pos += n;
    sink.on_block_end();
    progress.update(pos);
  }
  for (;;) {
    fetch();
    if (!pending) break;
    sink.on_speed(*pending);
    pending.reset();
  }
  sink.on_finish();
  progress.done();
  counters.comment_lines = can.comment_lines();
  counters.first_comment_line = can.first_comment_line();
  check_can_input(rec, cfg, counters, options.config_source);
  return counters;
}

namespace {

std::string can_id_text(std::uint32_t key) {
  const bool ext = (key & CanCounters::kExtendedIdKey) != 0;
  char buf[32];
  std::snprintf(buf, sizeof buf, ext ? "0x%08X (extended)" : "0x%03X", key & ~CanCounters::kExtendedIdKey);
  return buf;
}

// Seconds from the recording's start (3 decimals), the time base of `ptda monitor`'s table.
std::string rel_s(std::int64_t t_ns, std::int64_t t0_ns) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.3f", static_cast<double>(t_ns - t0_ns) * 1e-9);
  return buf;
}

}  // namespace

void check_can_input(const RecordingInfo& rec, const config::PipelineConfig& cfg, const CanCounters& can,
                     const std::string& config_source) {
  const std::string log = rec.can_path.string();
  if (can.frames == 0) {
    if (can.comment_lines > 0) {
      throw Error(log + ":" + std::to_string(can.first_comment_line) + ": not a candump log: none of its " +
                  std::to_string(can.comment_lines) +
                  " non-blank lines is a frame \"(seconds.fraction) iface ID#DATA\" (lines not starting "
                  "with '(' are comments); point can_file in " +
                  (rec.dir / "recording.toml").string() + " at the `candump -l` log");
    }
    throw Error(log +
                ": the CAN log has no frames (empty or blank): no joint speed, so no window can be cut");
  }
  const config::SpeedFrameSpec& spec = cfg.speed_frame;
  if (can.speed_frames == 0) {
    const std::uint32_t key = spec.id | (spec.extended ? CanCounters::kExtendedIdKey : 0U);
    const auto it = can.ids.find(key);
    if (it == can.ids.end()) {
      // Most frequent first; ties by id.
      std::vector<std::pair<std::uint32_t, std::uint64_t>> seen(can.ids.begin(), can.ids.end());
      std::stable_sort(seen.begin(), seen.end(),
                       [](const auto& a, const auto& b) { return a.second > b.second; });
      std::string ids;
      const std::size_t shown = std::min<std::size_t>(seen.size(), 8);
      for (std::size_t i = 0; i < shown; ++i) {
        ids += (i == 0 ? "" : ", ") + can_id_text(seen[i].first) + " (" + std::to_string(seen[i].second) +
               " frames)";
      }
      if (seen.size() > shown) ids += ", and " + std::to_string(seen.size() - shown) + " more ids";
      if (seen.empty()) ids = "none but error frames";
      throw Error(log + ": no frame with id " + can_id_text(key) + " in the CAN log (" +
                  std::to_string(can.frames) + " frames); ids seen: " + ids +
                  ". Set id (and extended) in [can.speed_frame] of " + config_source +
                  " to the joint's speed frame");
    }
    throw Error(log + ": none of the " + std::to_string(it->second) + " frames with id " + can_id_text(key) +
                " decoded as a speed sample (" + std::to_string(can.wrong_dlc) +
                " with a length other than " + "dlc = " + std::to_string(spec.dlc) + ", " +
                std::to_string(can.rtr) + " remote frames); check [can.speed_frame] dlc in " + config_source);
  }
  // The vibration covers [t0, t0 + duration); the speed samples [first, last]. Disjoint: nothing can
  // be cut, whatever the configuration says.
  const std::int64_t vib_end_ns = rec.t0_ns + seconds_to_ns(rec.duration_s);
  if (can.last_speed_t_ns < rec.t0_ns || can.first_speed_t_ns >= vib_end_ns) {
    throw Error(log + ": the CAN speed frames (" + rel_s(can.first_speed_t_ns, rec.t0_ns) + " to " +
                rel_s(can.last_speed_t_ns, rec.t0_ns) + " s) do not overlap the vibration recording " +
                rec.wav_path.string() + " (0.000 to " + rel_s(vib_end_ns, rec.t0_ns) +
                " s); times in seconds from start_time " + num(rec.meta.start_time_s) + " of " +
                (rec.dir / "recording.toml").string() + ": check start_time and the log's clock");
  }
}

namespace {

class CollectSink final : public PipelineSink {
 public:
  CollectSink(const dsp::ExtractionConfig& cfg, double fs_hz, std::int64_t t0_ns,
              const CollectVisitor& visitor)
      : slicer_(cfg, fs_hz, t0_ns), buf_(cfg.window_len), visitor_(visitor) {}

  void on_speed(const dsp::SpeedSample& s) override { slicer_.push_speed(s); }
  void on_samples(std::span<const float> block) override { slicer_.push_samples(block); }
  void on_block_end() override { drain(); }
  void on_finish() override {
    slicer_.finish();
    drain();
  }

  dsp::CollectedWindows data;
  [[nodiscard]] const dsp::WindowSlicer& slicer() const noexcept { return slicer_; }

 private:
  void drain() {
    dsp::WindowRef ref;
    while (slicer_.pop(ref, buf_)) {
      if (visitor_) {
        visitor_(ref, buf_);  // the visitor keeps what it needs: nothing grows here
      } else {
        data.refs.push_back(ref);
        data.windows.push_back(buf_);
      }
    }
    dsp::RegionInfo region;
    while (slicer_.pop_region(region)) {
      if (!visitor_) data.regions.push_back(region);
    }
  }

  dsp::WindowSlicer slicer_;
  std::vector<float> buf_;
  const CollectVisitor& visitor_;
};

// Pass 0 of `ptda train`: the windows' places and the regions into a spilled index, renumbered.
class IndexSink final : public PipelineSink {
 public:
  IndexSink(const dsp::ExtractionConfig& cfg, double fs_hz, std::int64_t t0_ns, dsp::TrainingIndex& index,
            IndexRenumber& renumber)
      : slicer_(cfg, fs_hz, t0_ns),
        buf_(cfg.window_len),
        index_(index),
        renumber_(renumber),
        region_offset_(renumber.region_offset),
        window_offset_(renumber.window_offset) {}

  void on_speed(const dsp::SpeedSample& s) override { slicer_.push_speed(s); }
  void on_samples(std::span<const float> block) override { slicer_.push_samples(block); }
  void on_block_end() override { drain(); }
  void on_finish() override {
    slicer_.finish();
    drain();
  }

  [[nodiscard]] const dsp::WindowSlicer& slicer() const noexcept { return slicer_; }
  std::uint64_t windows = 0;
  std::uint64_t regions = 0;

 private:
  void drain() {
    dsp::WindowRef ref;
    while (slicer_.pop(ref, buf_)) {
      ref.seq += window_offset_;
      ref.region_seq += region_offset_;
      index_.refs.push_back(ref);
      index_.recording.push_back(renumber_.recordings);
      renumber_.window_offset = std::max(renumber_.window_offset, ref.seq + 1);
      renumber_.region_offset = std::max(renumber_.region_offset, ref.region_seq + 1);
      ++windows;
    }
    dsp::RegionInfo region;
    while (slicer_.pop_region(region)) {
      region.seq += region_offset_;
      index_.regions.push_back(region);
      renumber_.region_offset = std::max(renumber_.region_offset, region.seq + 1);
      ++regions;
    }
  }

  dsp::WindowSlicer slicer_;
  std::vector<float> buf_;
  dsp::TrainingIndex& index_;
  IndexRenumber& renumber_;
  const std::uint64_t region_offset_;
  const std::uint64_t window_offset_;
};

class MonitorSink final : public PipelineSink {
 public:
  MonitorSink(dsp::MonitorEngine& engine, dsp::CoverageTracker& coverage, std::vector<dsp::WindowResult>* out,
              const WindowObserver& observer)
      : engine_(engine), coverage_(coverage), out_(out), observer_(observer) {}

  void on_speed(const dsp::SpeedSample& s) override {
    engine_.push_speed(s);
    coverage_.on_speed(s);
  }
  void on_samples(std::span<const float> block) override { engine_.push_samples(block); }
  void on_block_end() override { drain(); }
  void on_finish() override {
    engine_.finish();
    drain();
    coverage_.finish();
  }

 private:
  // As the daemon's processing thread: every window, then the slicer's discarded count.
  void drain() {
    dsp::WindowResult r;
    while (engine_.poll(r)) {
      if (observer_) observer_(r, engine_);
      coverage_.on_window(r);
      if (out_ != nullptr) out_->push_back(r);
    }
    const dsp::SlicerCounters& sc = engine_.slicer().counters();
    coverage_.on_discarded_total(sc.windows_invalid + sc.windows_lost + sc.windows_overflow);
  }

  dsp::MonitorEngine& engine_;
  dsp::CoverageTracker& coverage_;
  std::vector<dsp::WindowResult>* out_;  // nullptr: not kept
  const WindowObserver& observer_;
};

// The order domain's front end: resampler and window cutter, fed like the slicer.
class OrderFront {
 public:
  OrderFront(const config::PipelineConfig& cfg, double fs_hz, std::int64_t t0_ns)
      : res_(config::angle_resampler_config(cfg), fs_hz, t0_ns),
        cut_(config::order_window_config(cfg, res_.pass_order())),
        buf_(cut_.window_len()),
        clock_(cfg.speed_frame.period_s, cfg.order.can_time_smoothing_frames),
        smooth_(cfg.order.can_time_smoothing_frames > 0) {}
  void push_speed(dsp::SpeedSample s) {
    if (smooth_) s.t_ns = clock_.smooth(s.t_ns);
    res_.push_speed(s);
  }
  void push_samples(std::span<const float> block) { res_.push_samples(block); }
  template <typename F>
  void drain(F&& f) {
    dsp::OrderSample o;
    dsp::OrderWindowRef ref;
    while (res_.pop(o)) {
      if (cut_.push(o, ref, buf_)) f(ref, std::span<const float>(buf_));
    }
  }
  [[nodiscard]] const dsp::AngleResamplerCounters& counters() const noexcept { return res_.counters(); }
  [[nodiscard]] std::uint64_t windows() const noexcept { return cut_.windows(); }

 private:
  dsp::AngleResampler res_;
  dsp::OrderWindowCutter cut_;
  std::vector<float> buf_;
  dsp::FrameClock clock_;
  bool smooth_;
};

class OrderCollectSink final : public PipelineSink {
 public:
  OrderCollectSink(const config::PipelineConfig& cfg, double fs_hz, std::int64_t t0_ns,
                   const OrderVisitor& visitor)
      : front_(cfg, fs_hz, t0_ns), visitor_(visitor) {}
  void on_speed(const dsp::SpeedSample& s) override { front_.push_speed(s); }
  void on_samples(std::span<const float> block) override { front_.push_samples(block); }
  void on_block_end() override { drain(); }
  void on_finish() override { drain(); }
  dsp::OrderWindows data;
  [[nodiscard]] const OrderFront& front() const noexcept { return front_; }

 private:
  void drain() {
    front_.drain([this](const dsp::OrderWindowRef& ref, std::span<const float> x) {
      if (visitor_) {
        visitor_(ref, x);  // the visitor keeps what it needs: nothing grows here
      } else {
        data.refs.push_back(ref);
        data.windows.emplace_back(x.begin(), x.end());
      }
    });
  }
  OrderFront front_;
  const OrderVisitor& visitor_;
};

class OrderMonitorSink final : public PipelineSink {
 public:
  OrderMonitorSink(const config::PipelineConfig& cfg, double fs_hz, std::int64_t t0_ns,
                   dsp::MonitorEngine& engine, dsp::CoverageTracker& coverage,
                   std::vector<dsp::WindowResult>* out, const WindowObserver& observer)
      : front_(cfg, fs_hz, t0_ns), engine_(engine), coverage_(coverage), out_(out), observer_(observer) {}
  void on_speed(const dsp::SpeedSample& s) override {
    front_.push_speed(s);
    coverage_.on_speed(s);
  }
  void on_samples(std::span<const float> block) override { front_.push_samples(block); }
  void on_block_end() override { drain(); }
  void on_finish() override {
    drain();
    coverage_.finish();
  }
  [[nodiscard]] const OrderFront& front() const noexcept { return front_; }

 private:
  void drain() {
    front_.drain([this](const dsp::OrderWindowRef& ref, std::span<const float> x) {
      dsp::WindowResult r;
      engine_.judge_window(window_ref_of(ref, x.size()), x, r);
      if (observer_) observer_(r, engine_);
      coverage_.on_window(r);
      if (out_ != nullptr) out_->push_back(r);
    });
  }
  OrderFront front_;
  dsp::MonitorEngine& engine_;
  dsp::CoverageTracker& coverage_;
  std::vector<dsp::WindowResult>* out_;
  const WindowObserver& observer_;
};

}  // namespace

OrderCollectResult collect_order_windows(const RecordingInfo& rec, const config::PipelineConfig& cfg,
                                         double fs_hz, const RunOptions& options,
                                         const OrderVisitor& visitor) {
  OrderCollectSink sink(cfg, fs_hz, rec.t0_ns, visitor);
  OrderCollectResult result;
  result.can = run_recording(rec, cfg, sink, options);
  result.resampler = sink.front().counters();
  result.data = std::move(sink.data);
  return result;
}

void append_order_windows(dsp::OrderWindows& all, dsp::OrderWindows more) {
  std::uint32_t recording = 0;
  std::uint64_t seq_offset = 0, segment_offset = 0;
  if (!all.refs.empty()) {
    if (all.recording.size() != all.refs.size()) all.recording.assign(all.refs.size(), 0U);
    for (const std::uint32_t r : all.recording) recording = std::max(recording, r + 1U);
    for (const auto& r : all.refs) {
      seq_offset = std::max(seq_offset, r.seq + 1);
      segment_offset = std::max(segment_offset, r.segment + 1);
    }
  }
  for (std::size_t i = 0; i < more.refs.size(); ++i) {
    dsp::OrderWindowRef ref = more.refs[i];
    ref.seq += seq_offset;
    ref.segment += segment_offset;
    all.refs.push_back(ref);
    all.windows.push_back(std::move(more.windows[i]));
    all.recording.push_back(recording);
  }
}

CollectResult collect_windows(const RecordingInfo& rec, const config::PipelineConfig& cfg, double fs_hz,
                              const RunOptions& options, const CollectVisitor& visitor) {
  CollectSink sink(cfg.extraction, fs_hz, rec.t0_ns, visitor);
  CollectResult result;
  result.can = run_recording(rec, cfg, sink, options);
  result.slicer = sink.slicer().counters();
  result.data = std::move(sink.data);
  result.fs_hz = fs_hz;
  return result;
}

void append_collected(dsp::CollectedWindows& all, dsp::CollectedWindows more) {
  if (all.refs.empty() && all.regions.empty() && all.windows.empty()) {
    // The first recording: taken as it is (recording 0, nothing to renumber), without a second copy.
    all = std::move(more);
    all.recording.assign(all.refs.size(), 0U);
    return;
  }
  // Recording (day) index of the appended windows: one past the last one's (docs/method.md §5).
  std::uint32_t recording = 0;
  if (!all.refs.empty()) {
    if (all.recording.size() != all.refs.size()) all.recording.assign(all.refs.size(), 0U);
    for (const std::uint32_t r : all.recording) recording = std::max(recording, r + 1U);
  }
  std::uint64_t region_offset = 0;
  std::uint64_t window_offset = 0;
  for (const auto& r : all.regions) region_offset = std::max(region_offset, r.seq + 1);
  for (const auto& w : all.refs) {
    region_offset = std::max(region_offset, w.region_seq + 1);
    window_offset = std::max(window_offset, w.seq + 1);
  }
  // Exact sizes: no doubling slack on top of a long recording's refs.
  all.regions.reserve(all.regions.size() + more.regions.size());
  all.refs.reserve(all.refs.size() + more.refs.size());
  all.recording.reserve(all.recording.size() + more.refs.size());
  if (more.windows.size() == more.refs.size()) all.windows.reserve(all.windows.size() + more.windows.size());
  for (auto& r : more.regions) {
    r.seq += region_offset;
    all.regions.push_back(r);
  }
  for (std::size_t i = 0; i < more.refs.size(); ++i) {
    auto ref = more.refs[i];
    ref.seq += window_offset;
    ref.region_seq += region_offset;
    all.refs.push_back(ref);
    if (more.windows.size() == more.refs.size()) all.windows.push_back(std::move(more.windows[i]));
    all.recording.push_back(recording);
  }
}

IndexResult index_windows(const RecordingInfo& rec, const config::PipelineConfig& cfg, double fs_hz,
                          const RunOptions& options, dsp::TrainingIndex& index, IndexRenumber& renumber) {
  IndexSink sink(cfg.extraction, fs_hz, rec.t0_ns, index, renumber);
  IndexResult result;
  result.can = run_recording(rec, cfg, sink, options);
  result.slicer = sink.slicer().counters();
  result.windows = sink.windows;
  result.regions = sink.regions;
  ++renumber.recordings;
  return result;
}

dsp::TrainingIndex select_windows(const dsp::TrainingIndex& all, const FractionRange& range) {
  const std::uint64_t count = all.refs.size();
  const std::uint64_t first = range.first(count);
  const std::uint64_t last = range.last(count);
  dsp::TrainingIndex out(all.spill);
  dsp::SpillVector<std::uint64_t> used(all.spill);
  {
    dsp::SpillVector<dsp::WindowRef>::Reader refs(all.refs);
    dsp::SpillVector<std::uint32_t>::Reader recs(all.recording);
    for (std::uint64_t i = 0; i < last; ++i) {
      const dsp::WindowRef r = refs.next();
      const std::uint32_t rec = recs.next();
      if (i < first) continue;
      out.refs.push_back(r);
      out.recording.push_back(rec);
      used.push_back(r.region_seq);
    }
  }
  // The regions whose seq is used: both lists in seq order, merged.
  const dsp::SpillVector<std::uint64_t> used_sorted = dsp::sorted(used, std::less<>());
  const dsp::SpillVector<dsp::RegionInfo> regions = dsp::sorted(
      all.regions, [](const dsp::RegionInfo& a, const dsp::RegionInfo& b) { return a.seq < b.seq; });
  dsp::SpillVector<std::uint64_t>::Reader u(used_sorted);
  regions.for_each([&](const dsp::RegionInfo& r) {
    while (!u.done() && u.peek() < r.seq) (void)u.next();
    if (!u.done() && u.peek() == r.seq) out.regions.push_back(r);
  });
  return out;
}

dsp::CollectedWindows select_windows(const dsp::CollectedWindows& all, const FractionRange& range) {
  const std::uint64_t count = all.refs.size();
  const std::uint64_t first = range.first(count);
  const std::uint64_t last = range.last(count);
  dsp::CollectedWindows out;
  std::set<std::uint64_t> regions_used;
  for (std::uint64_t i = first; i < last; ++i) {
    out.refs.push_back(all.refs[i]);
    if (all.windows.size() == all.refs.size()) out.windows.push_back(all.windows[i]);
    if (all.recording.size() == all.refs.size()) out.recording.push_back(all.recording[i]);
    regions_used.insert(all.refs[i].region_seq);
  }
  for (const auto& r : all.regions) {
    if (regions_used.count(r.seq) != 0) out.regions.push_back(r);
  }
  return out;
}

void check_baseline_matches(const dsp::Baseline& baseline, const std::string& baseline_source,
                            const config::PipelineConfig& cfg, const std::string& config_source, double fs_hz,
                            const std::string& recording_source) {
  config::check_baseline_domain(baseline, baseline_source, cfg, config_source);
  // Order domain: the vibration's own rate only enters the resampler, not the windows.
  if (cfg.domain == dsp::Domain::kOrder) return;
  if (std::abs(baseline.fs_hz - fs_hz) > 1e-9 * fs_hz) {
    throw Error(baseline_source + ": baseline was trained at " + num(baseline.fs_hz) + " Hz but recording " +
                recording_source + " is sampled at " + num(fs_hz) + " Hz");
  }
  if (baseline.window_len != cfg.extraction.window_len) {
    throw Error(baseline_source + ": baseline window length is " + std::to_string(baseline.window_len) +
                " samples but " + config_source +
                " sets [extraction] window_len = " + std::to_string(cfg.extraction.window_len));
  }
}

MonitorResult monitor_recording(const RecordingInfo& rec, const config::PipelineConfig& cfg,
                                const dsp::Baseline& baseline, dsp::Method method, double fs_hz,
                                const WindowObserver& observer, const RunOptions& options,
                                bool keep_windows) {
  if (cfg.domain == dsp::Domain::kOrder) {
    // The engine judges windows on the angle axis: its "sample rate" is S (the baseline's fs_hz) and its
    // slicer is not used; decision, thresholds and outputs are the time domain's.
    dsp::MonitorEngine engine(baseline, cfg.extraction, cfg.decision, method, baseline.fs_hz, rec.t0_ns);
    dsp::CoverageConfig cc;
    cc.timeout_s = options.coverage_timeout_s;
    cc.moving_speed_rad_s = cfg.extraction.min_speed_rad_s;
    cc.max_speed_gap_s = cfg.extraction.max_speed_gap_s;
    dsp::CoverageTracker coverage(baseline, cc);
    MonitorResult result;
    result.domain = dsp::Domain::kOrder;
    OrderMonitorSink sink(cfg, fs_hz, rec.t0_ns, engine, coverage, keep_windows ? &result.windows : nullptr,
                          observer);
    result.can = run_recording(rec, cfg, sink, options);
    result.coverage = coverage.state();
    result.resampler = sink.front().counters();
    result.order_windows_cut = sink.front().windows();
    result.fs_hz = fs_hz;
    return result;
  }
  dsp::MonitorEngine engine(baseline, cfg.extraction, cfg.decision, method, fs_hz, rec.t0_ns);
  dsp::CoverageConfig cc;
  cc.timeout_s = options.coverage_timeout_s;
  cc.moving_speed_rad_s = cfg.extraction.min_speed_rad_s;
  cc.max_speed_gap_s = cfg.extraction.max_speed_gap_s;
  dsp::CoverageTracker coverage(baseline, cc);
  MonitorResult result;
  MonitorSink sink(engine, coverage, keep_windows ? &result.windows : nullptr, observer);
  result.can = run_recording(rec, cfg, sink, options);
  result.coverage = coverage.state();
  result.slicer = engine.slicer().counters();
  result.fs_hz = fs_hz;
  return result;
}

void redebounce(std::vector<dsp::WindowResult>& windows, const dsp::DecisionConfig& decision) {
  // Fresh k-of-n and CUSUM state over just these windows (class ids index the CUSUMs).
  std::size_t classes = 0;
  for (const auto& w : windows)
    if (w.class_id >= 0) classes = std::max(classes, static_cast<std::size_t>(w.class_id) + 1);
  dsp::DecisionState state(decision, classes);
  for (auto& w : windows) {
    w.seq_statistic = 0.0;
    w.seq_feature = dsp::SeqFeature::kNone;
    w.band_statistic = 0.0;
    w.band_index = -1;
    w.mesh_statistic = 0.0;
    w.mesh_feature = -1;
    if (w.status == dsp::WindowStatus::kScored) {
      state.scored(w, static_cast<std::size_t>(w.class_id));
    } else {
      state.unscored(w);
    }
  }
}

}  // namespace ptda::cli
