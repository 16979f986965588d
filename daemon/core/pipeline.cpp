#include "core/pipeline.hpp"

#include <pthread.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <span>

#include "adc/iio_sample_source.hpp"
#include "adc/wav_replay_source.hpp"
#include "alarm/can_alarm_output.hpp"
#include "alarm/gpiod_output.hpp"
#include "can/candump_replay_channel.hpp"
#include "can/socketcan_channel.hpp"
#include "ptda/common/error.hpp"
#include "ptda/common/time.hpp"
#include "ptda/config/pipeline_config.hpp"
#include "ptda/config/speed_codec.hpp"
#include "ptda/formats/baseline_file.hpp"
#include "ptda/formats/recording.hpp"

namespace ptda::daemon {

namespace fs = std::filesystem;
using drivers::AlarmLevel;
using drivers::CanStatus;
using drivers::SourceStatus;

const char* phase_name(Phase p) noexcept {
  switch (p) {
    case Phase::kStarting:
      return "starting";
    case Phase::kMonitoring:
      return "monitoring";
    case Phase::kPausedSpeed:
      return "paused: no joint speed";
    case Phase::kPausedSensor:
      return "paused: no vibration data";
    case Phase::kRefused:
      return "refused";
    case Phase::kTraining:
      return "training";
    case Phase::kEnded:
      return "replay ended";
    case Phase::kNotJudging:
      return "not judging";
  }
  return "?";
}

namespace {

/// The one idle wait of a stage. Thread: any. Never allocates.
void sleep_ns(std::int64_t ns) noexcept {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(ns / kNsPerS);
  ts.tv_nsec = static_cast<long>(ns % kNsPerS);
  ::clock_nanosleep(CLOCK_MONOTONIC, 0, &ts, nullptr);
}

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

bool same_rate(double a, double b) {
  return std::abs(a - b) <= 1e-9 * std::max(std::abs(a), std::abs(b));
}

bool matches_clear(const CanFrame& f, const ClearFrameSpec& spec) noexcept {
  if (!spec.enabled || f.error() || f.rtr() || f.id != spec.id || f.extended() != spec.extended) return false;
  if (f.len != spec.len) return false;
  for (std::uint8_t i = 0; i < spec.len; ++i) {
    if (f.data[i] != spec.data[i]) return false;
  }
  return true;
}

}  // namespace

Pipeline::Pipeline(const DaemonConfig& cfg, PipelineMode mode, drivers::Clock& clock)
    : cfg_(cfg), mode_(mode), clock_(clock) {}

Pipeline::~Pipeline() {
  deactivate();
}

void Pipeline::configure() {
  // Test-only hook: the test's devices replace the configured backends.
  if (factory_ != nullptr) make_test_devices();
  const RecordingLink link = configure_vibration_source();
  configure_can(link);
  configure_outputs();
  if (mode_ == PipelineMode::kMonitor) {
    configure_monitoring();
  } else {
    configure_training();
  }
  configure_alarm_manager();
  configure_rings_and_timing();
  configured_ = true;
}

void Pipeline::make_test_devices() {
  source_ = factory_->make_source(clock_);
  channel_ = factory_->make_channel(clock_);
  source_fast_ = cfg_.adc.pace == Pace::kFast;
  can_fast_ = cfg_.can.pace == Pace::kFast;
  inputs_text_ = "test devices (" + std::string(pace_name(cfg_.adc.pace)) + ")";
}

Pipeline::RecordingLink Pipeline::configure_vibration_source() {
  const config::PipelineConfig& pc = cfg_.pipeline;
  RecordingLink link;
  if (!source_) switch (cfg_.adc.backend) {
      case AdcBackend::kSim: {
        sim_ = make_sim_recording(cfg_.adc.scenario, cfg_.adc.seed);
        SimSourceConfig sc;
        sc.block_len = cfg_.adc.block_len;
        sc.fast = cfg_.adc.pace == Pace::kFast;
        sc.loop = cfg_.adc.loop;
        source_ = std::make_unique<SimSampleSource>(sim_, sim_anchor_, clock_, sc);
        source_fast_ = sc.fast;
        inputs_text_ = "adc sim (" + cfg_.adc.scenario.string() + ", seed " + std::to_string(sim_->seed) +
                       ", " + pace_name(cfg_.adc.pace) + (sc.loop ? ", looping" : "") + ")";
        break;
      }
      case AdcBackend::kWav: {
        const formats::RecordingMeta meta = formats::read_recording_meta(cfg_.adc.recording);
        drivers::WavReplayConfig wc;
        wc.path = cfg_.adc.recording / meta.vibration_file;
        wc.channel = meta.channel;
        wc.block_len = cfg_.adc.block_len;
        wc.scale = static_cast<float>(meta.scale);
        wc.pace = cfg_.adc.pace == Pace::kFast ? drivers::ReplayPace::kAsFastAsPossible
                                               : drivers::ReplayPace::kRealTime;
        wc.start_unix_ns = seconds_to_ns(meta.start_time_s);
        wc.timeline.origin_unix_ns = wc.start_unix_ns;  // origin_mono_ns: set by activate()
        link.start_unix_ns = wc.start_unix_ns;
        link.can_log = cfg_.adc.recording / meta.can_file;
        auto wav = std::make_unique<drivers::WavReplaySource>(wc, clock_);
        wav_replay_ = wav.get();
        source_ = std::move(wav);
        source_fast_ = cfg_.adc.pace == Pace::kFast;
        inputs_text_ = "adc wav (" + cfg_.adc.recording.string() + ", " + pace_name(cfg_.adc.pace) + ")";
        break;
      }
      case AdcBackend::kIio: {
        drivers::IioSourceConfig ic;
        ic.sysfs_dir = cfg_.adc.sysfs_dir;
        ic.dev_path = cfg_.adc.device;
        ic.channel = cfg_.adc.channel;
        ic.timestamp = cfg_.adc.timestamp;
        ic.fs_hz = pc.fs_hz;
        ic.trigger = cfg_.adc.trigger;
        ic.buffer_length = cfg_.adc.buffer_length;
        ic.watermark = cfg_.adc.watermark;
        ic.block_len = cfg_.adc.block_len;
        ic.scale = cfg_.adc.scale;
        source_ = std::make_unique<drivers::IioSampleSource>(ic, clock_);
        source_fast_ = false;
        inputs_text_ = "adc iio (" + cfg_.adc.device.string() + " " + cfg_.adc.channel + ")";
        break;
      }
    }
  source_->configure();
  fs_hz_ = source_->fs_hz();
  if (!(fs_hz_ >= 1.0 && fs_hz_ <= 1e6))
    throw Error("adc: sample rate " + num(fs_hz_) + " Hz is outside 1..1e6");
  if (pc.fs_hz != 0.0 && !same_rate(pc.fs_hz, fs_hz_)) {
    throw Error(cfg_.files.empty() ? std::string("config") : cfg_.files.front().string(), 0, 0,
                "[acquisition] fs_hz = " + num(pc.fs_hz) + " Hz but the " +
                    adc_backend_name(cfg_.adc.backend) + " source delivers " + num(fs_hz_) + " Hz");
  }
  fs_mhz_ = std::llround(fs_hz_ * 1000.0);
  return link;
}

void Pipeline::configure_can(const RecordingLink& link) {
  const config::PipelineConfig& pc = cfg_.pipeline;
  if (!channel_) switch (cfg_.can.backend) {
      case CanBackend::kSim: {
        SimCanConfig cc;
        cc.fast = cfg_.can.pace == Pace::kFast;
        cc.loop = cfg_.adc.loop;
        channel_ = std::make_unique<SimCanChannel>(sim_, sim_anchor_, clock_, cc);
        can_fast_ = cc.fast;
        inputs_text_ += ", can sim (" + std::string(pace_name(cfg_.can.pace)) + ")";
        break;
      }
      case CanBackend::kCandump: {
        drivers::CandumpReplayConfig cc;
        cc.path = cfg_.can.replay_file.empty() ? link.can_log : cfg_.can.replay_file;
        cc.pace = cfg_.can.pace == Pace::kFast ? drivers::ReplayPace::kAsFastAsPossible
                                               : drivers::ReplayPace::kRealTime;
        if (link.start_unix_ns) cc.timeline.origin_unix_ns = *link.start_unix_ns;
        cc.cyclic = cfg_.alarm.can_enabled && cfg_.alarm.can_kernel_timer;  // emulated at real-time pace
        auto candump = std::make_unique<drivers::CandumpReplayChannel>(cc, clock_);
        candump_replay_ = candump.get();
        channel_ = std::move(candump);
        can_fast_ = cfg_.can.pace == Pace::kFast;
        inputs_text_ += ", can candump (" + cc.path.string() + ", " + pace_name(cfg_.can.pace) + ")";
        break;
      }
      case CanBackend::kSocketCan: {
        drivers::SocketCanConfig sc;
        sc.interface = cfg_.can.interface;
        sc.filters.push_back({pc.speed_frame.id, pc.speed_frame.extended, 0});
        if (cfg_.can.clear_frame.enabled) {
          sc.filters.push_back({cfg_.can.clear_frame.id, cfg_.can.clear_frame.extended, 0});
        }
        sc.bus_error_frames = cfg_.can.bus_error_frames;
        sc.rcvbuf_bytes = static_cast<int>(cfg_.can.rcvbuf_bytes);
        sc.cyclic = cfg_.alarm.can_enabled && cfg_.alarm.can_kernel_timer;
        auto socketcan = std::make_unique<drivers::SocketCanChannel>(sc, clock_);
        socketcan_ = socketcan.get();
        channel_ = std::move(socketcan);
        can_fast_ = false;
        inputs_text_ += ", can socketcan (" + cfg_.can.interface + ")";
        break;
      }
    }
  channel_->configure();
  fast_ = source_fast_ && can_fast_;
}

void Pipeline::configure_outputs() {
  if (cfg_.alarm.gpio_enabled) {
    drivers::GpiodOutputConfig gc;
    gc.chip = cfg_.alarm.gpio_chip;
    gc.line = cfg_.alarm.gpio_line;
    gc.active_low = cfg_.alarm.gpio_active_low;
    outputs_.push_back(std::make_unique<drivers::GpiodOutput>(gc));
  }
  if (cfg_.alarm.can_enabled) {
    drivers::CanAlarmConfig ac;
    ac.id = cfg_.alarm.can_id;
    ac.extended = cfg_.alarm.can_extended;
    ac.period_ns = seconds_to_ns(cfg_.alarm.can_period_s);
    ac.kernel_timer = cfg_.alarm.can_kernel_timer;
    ac.lease_ns = seconds_to_ns(cfg_.alarm.can_lease_s);
    auto out = std::make_unique<drivers::CanAlarmOutput>(ac, *channel_, &clock_);
    can_output_ = out.get();
    outputs_.push_back(std::move(out));
  }
  if (factory_ != nullptr) factory_->add_outputs(outputs_, *channel_);
  for (auto& o : outputs_) o->configure();
}

void Pipeline::configure_monitoring() {
  const config::PipelineConfig& pc = cfg_.pipeline;
  const std::uint32_t window_len = pc.extraction.window_len;
  const fs::path& path = cfg_.daemon.baseline;
  const bool order = pc.domain == dsp::Domain::kOrder;
  try {
    auto baseline = std::make_unique<dsp::Baseline>(formats::read_baseline(path));
    // As `ptda monitor` (cli::check_baseline_matches): the same domain, and in the order domain the
    // same S, R and gearbox ratio; the vibration's own rate then only enters the resampler.
    config::check_baseline_domain(*baseline, path.string(), pc, "the configuration");
    if (!order && !same_rate(baseline->fs_hz, fs_hz_)) {
      throw Error(path.string() + ": baseline was trained at " + num(baseline->fs_hz) + " Hz but the " +
                  adc_backend_name(cfg_.adc.backend) + " source delivers " + num(fs_hz_) + " Hz");
    }
    if (baseline->window_len != window_len) {
      throw Error(
          path.string() + ": baseline window length is " + std::to_string(baseline->window_len) +
          " samples but the configuration sets [extraction] window_len = " + std::to_string(window_len));
    }
    // Order domain: the engine judges windows on the angle axis, its "sample rate" is S (the baseline's
    // fs_hz) and its slicer stays unused, as in `ptda monitor` (cli::monitor_recording).
    engine_ = std::make_unique<dsp::MonitorEngine>(*baseline, pc.extraction, pc.decision, pc.method,
                                                   order ? baseline->fs_hz : fs_hz_, 0);
    dsp::CoverageConfig cc;
    cc.timeout_s = cfg_.daemon.coverage_timeout_s;
    cc.moving_speed_rad_s = pc.extraction.min_speed_rad_s;
    cc.max_speed_gap_s = pc.extraction.max_speed_gap_s;
    coverage_ = std::make_unique<dsp::CoverageTracker>(*baseline, cc);
    baseline_ = std::move(baseline);
  } catch (const Error& e) {
    refusal_ = e.what();
    engine_.reset();
    coverage_.reset();
    baseline_.reset();
  }
  // Outside the try: a resampler the configuration cannot build is a configuration error (thrown), not
  // a baseline refusal.
  if (order && engine_) configure_order_front();
}

void Pipeline::configure_order_front() {
  const config::PipelineConfig& pc = cfg_.pipeline;
  // t0 = 0: the processing thread feeds stream time (speed samples shifted by -t0, latency already
  // subtracted by the CAN thread), so the resampler's sample n lies at n / fs as in `ptda monitor`.
  order_res_ = std::make_unique<dsp::AngleResampler>(config::angle_resampler_config(pc), fs_hz_, 0);
  order_cut_ =
      std::make_unique<dsp::OrderWindowCutter>(config::order_window_config(pc, order_res_->pass_order()));
  if (order_cut_->window_len() != pc.extraction.window_len) {
    throw Error("[extraction] order windows of " + std::to_string(order_cut_->window_len()) +
                " samples but window_len = " + std::to_string(pc.extraction.window_len));
  }
  order_window_.assign(order_cut_->window_len(), 0.0F);
  order_nan_.assign(drivers::kMaxBlock, std::numeric_limits<float>::quiet_NaN());
  if (pc.order.can_time_smoothing_frames > 0) {
    order_clock_ =
        std::make_unique<dsp::FrameClock>(pc.speed_frame.period_s, pc.order.can_time_smoothing_frames);
  }
}

void Pipeline::configure_training() {
  const config::PipelineConfig& pc = cfg_.pipeline;
  if (pc.domain == dsp::Domain::kOrder) {
    throw Error((cfg_.files.empty() ? std::string("config") : cfg_.files.front().string()) +
                ": [extraction] domain = \"order\": field training (ptdad --train) collects time-domain "
                "windows only; train an order baseline with `ptda train` (docs/method.md §9)");
  }
  const std::uint32_t window_len = pc.extraction.window_len;
  train_slicer_ = std::make_unique<dsp::WindowSlicer>(pc.extraction, fs_hz_, 0);
  FieldTrainerConfig tc;
  tc.fs_hz = fs_hz_;
  tc.window_len = window_len;
  tc.max_windows = cfg_.training.max_windows;
  tc.max_regions = cfg_.training.max_regions;
  tc.target_cycles = cfg_.training.target_cycles;
  tc.classes = pc.classes;
  tc.thresholds = pc.thresholds;
  tc.gearbox = pc.gearbox;
  tc.spill_dir = training_spill_dir(cfg_);
  trainer_ = std::make_unique<FieldTrainer>(tc);
  if (previous_trainer_ != nullptr) carry_ = trainer_->take_over(*previous_trainer_);
  previous_trainer_ = nullptr;
  train_window_.assign(window_len, 0.0F);
  // A fast replay waits for the trainer's writer instead of dropping windows: a block is released only
  // when the queue has room for every window it can complete (one per hop of its samples, plus one).
  const auto hop = static_cast<std::uint64_t>(std::max<std::int64_t>(train_slicer_->hop_samples(), 1));
  const std::uint64_t per_block = drivers::kMaxBlock / hop + 2;
  train_block_windows_ =
      static_cast<std::size_t>(std::min<std::uint64_t>(per_block, FieldTrainer::kSpillSlots));
}

void Pipeline::configure_alarm_manager() {
  AlarmManagerConfig amc;
  amc.warning_enabled = cfg_.alarm.warning;
  amc.warning_k = cfg_.alarm.warning_k;
  amc.warning_hold_s = cfg_.alarm.warning_hold_s;
  amc.min_hold_s = cfg_.alarm.min_hold_s;
  amc.latch = cfg_.alarm.latch;
  alarm_time_ns_ = clock_.now_ns();
  alarm_ = std::make_unique<AlarmManager>(amc, alarm_time_ns_);
  level_ring_ = std::make_unique<LevelChangeRing>();
  alarm_->set_change_ring(level_ring_.get());
}

void Pipeline::configure_rings_and_timing() {
  const config::PipelineConfig& pc = cfg_.pipeline;
  sample_ring_ = std::make_unique<SampleRing>();
  speed_ring_ = std::make_unique<SpeedRing>();
  window_log_ = std::make_unique<WindowLogRing>();
  acq_block_ = std::make_unique<drivers::SampleBlock>();
  held_block_ = std::make_unique<drivers::SampleBlock>();
  latency_ns_ = seconds_to_ns(pc.speed_latency_s);
  speed_stale_ns_ = seconds_to_ns(cfg_.daemon.speed_stale_periods * pc.speed_frame.period_s);
  sensor_stale_ns_ = seconds_to_ns(cfg_.daemon.sensor_stale_s);
  // A block waits for the speed sample that follows it at most this long (real-time sources).
  hold_ns_ =
      std::min<std::int64_t>(std::max<std::int64_t>(seconds_to_ns(4 * pc.speed_frame.period_s), 50'000'000),
                             std::max<std::int64_t>(speed_stale_ns_ / 2, 1'000'000));
  // Wake-ups (docs/daemon.md, "Sleeping until a window can close"). The acquisition thread wakes one
  // block after the due time (the block holding the window's last sample is then complete; +1 ms for a
  // device's delivery); the CAN thread one speed frame period (+ the speed latency, +1 ms) after that,
  // so the speed sample that follows the newest block is in its ring too.
  const std::int64_t frame_ns = std::max<std::int64_t>(seconds_to_ns(pc.speed_frame.period_s), 1);
  const std::int64_t block_ns =
      static_cast<std::int64_t>(std::ceil(static_cast<double>(cfg_.adc.block_len) * 1e9 / fs_hz_));
  wake_ = WakeSchedule{};
  wake_.acq_offset_ns = block_ns + 1'000'000;
  wake_.can_offset_ns = wake_.acq_offset_ns + std::max<std::int64_t>(latency_ns_, 0) + frame_ns + 1'000'000;
  // The longest sleep: half of what the sample ring, the speed ring and an IIO buffer hold (an IIO
  // buffer of unknown length ("keep"): the burst period), half the sensor staleness (blocks arrive at
  // least twice in it), a quarter of the stall time and the liveness period (watchdog).
  std::int64_t max_sleep = kMaxSleepNs;
  max_sleep = std::min(max_sleep, static_cast<std::int64_t>(kSampleRingBlocks) * block_ns / 2);
  max_sleep = std::min(max_sleep, static_cast<std::int64_t>(kSpeedRingSamples) * frame_ns / 2);
  if (cfg_.adc.backend == AdcBackend::kIio && factory_ == nullptr) {
    max_sleep = std::min(
        max_sleep,
        cfg_.adc.buffer_length == 0
            ? kBurstPeriodNs
            : static_cast<std::int64_t>(static_cast<double>(cfg_.adc.buffer_length) * 1e9 / fs_hz_ / 2));
  }
  max_sleep = std::min(max_sleep, sensor_stale_ns_ / 2);
  max_sleep = std::min(max_sleep, seconds_to_ns(cfg_.daemon.stage_stall_s) / 4);
  if (liveness_ns_ > 0) max_sleep = std::min(max_sleep, liveness_ns_);
  wake_.max_sleep_ns = std::max<std::int64_t>(max_sleep, 1'000'000);
  wake_.follows_windows = engine_ != nullptr && order_res_ == nullptr;
  if (wake_.follows_windows) {
    // No window closes sooner than one hop after the previous one in its region, nor sooner than
    // new_run_close_ns() after a speed sample that starts a new region.
    const dsp::WindowSlicer& sl = engine_->slicer();
    const auto hop_ns = static_cast<std::int64_t>(static_cast<double>(sl.hop_samples()) * 1e9 / fs_hz_);
    wake_.spacing_ns = std::max<std::int64_t>(std::min(hop_ns, sl.new_run_close_ns()), 1'000'000);
  } else {
    wake_.spacing_ns = kBurstPeriodNs;  // the order domain: a fixed grid of bursts
    if (order_res_) wake_.acq_offset_ns = 0;
  }
  // A window still open when the CAN thread has served its due time (a late frame or block): retry every
  // frame period for as long as a speed gap may last before it breaks the run (then the due time moves).
  wake_.retry_ns = frame_ns + 1'000'000;
  wake_.late_window_ns = seconds_to_ns(pc.extraction.max_speed_gap_s) + hold_ns_;
  // Both inputs at real-time pace: the processing thread reads them when a window can close. Three
  // threads would cost three wake-ups per due time (docs/daemon.md, "One thread at real-time pace").
  wake_.single_thread = !source_fast_ && !can_fast_;
  next_due_ns_.store(kNoDue, std::memory_order_relaxed);
  due_late_.store(false, std::memory_order_relaxed);
  st_ = PipelineStatus{};
  st_.order_domain = cfg_.pipeline.domain == dsp::Domain::kOrder;
  st_.phase = mode_ == PipelineMode::kMonitor && refused() ? Phase::kRefused : Phase::kStarting;
  published_.store(st_);
}

void Pipeline::activate() {
  if (!configured_) throw Error("pipeline: activate() before configure()");
  if (active_) return;
  std::size_t outputs_started = 0;
  // Replays start at activation, as a device starts delivering then: sample 0 of the WAV and the log's
  // start map to this instant (one origin for both, so they stay aligned exactly). Taken at configure()
  // instead, the configure time would be released as a burst of overdue blocks, and the start of a WAV
  // replay could not be lined up with a live bus: the CAN verdict output's first frame, sent below,
  // follows it by the time the activations take (docs/daemon.md, "Time alignment").
  const std::int64_t origin_mono = clock_.now_ns();
  if (wav_replay_ != nullptr) wav_replay_->set_origin_mono_ns(origin_mono);
  if (candump_replay_ != nullptr) candump_replay_->set_origin_mono_ns(origin_mono);
  if (wav_replay_ != nullptr || candump_replay_ != nullptr) replay_origin_mono_ns_ = origin_mono;
  try {
    source_->activate();
    channel_->activate();
    for (auto& o : outputs_) {
      o->activate();
      ++outputs_started;
    }
  } catch (...) {
    for (std::size_t i = 0; i < outputs_started; ++i) outputs_[i]->deactivate();
    channel_->deactivate();
    source_->deactivate();
    throw;
  }
  // An unchanged verdict is handed to the outputs at least this often: each CAN frame when the daemon
  // times them, a renewal of the kernel timer's lease otherwise (GPIO needs no re-sends).
  output_period_ns_ =
      can_output_ != nullptr ? can_output_->refresh_period_ns() : seconds_to_ns(cfg_.alarm.can_period_s);
  wake_.output_refresh_ns = output_period_ns_;
  wake_.output_kernel_timed = can_output_ != nullptr && can_output_->kernel_timed();
  if (can_output_ != nullptr) {
    char text[256];
    if (wake_.output_kernel_timed) {
      std::snprintf(text, sizeof text, "re-sent every %g s by the kernel (%s), lease %g s",
                    cfg_.alarm.can_period_s, socketcan_ != nullptr ? "CAN_BCM" : "emulated by the replay",
                    cfg_.alarm.can_lease_s);
    } else {
      std::snprintf(text, sizeof text, "re-sent every %g s by the daemon%s%s", cfg_.alarm.can_period_s,
                    socketcan_ != nullptr && !socketcan_->cyclic_error().empty() ? ": " : "",
                    socketcan_ != nullptr ? socketcan_->cyclic_error().c_str() : "");
    }
    can_timer_text_ = text;  // activate() may allocate
  }
  stop_.store(false, std::memory_order_relaxed);
  last_block_arrival_ns_ = clock_.now_ns();
  burst_origin_ns_ = last_block_arrival_ns_;
  active_ = true;
  if (!wake_.single_thread) {
    acq_thread_ = std::thread([this] { acquisition_loop(); });
    can_thread_ = std::thread([this] { can_loop(); });
    pthread_setname_np(acq_thread_.native_handle(), "ptdad-acq");
    pthread_setname_np(can_thread_.native_handle(), "ptdad-can");
  }
  if (trainer_) trainer_->start(source_fast_ ? &work_signal_ : nullptr);  // only a fast replay waits for it
  proc_thread_ = std::thread([this] { processing_loop(); });
  pthread_setname_np(proc_thread_.native_handle(), "ptdad-proc");
}

void Pipeline::deactivate() noexcept {
  if (!active_) return;
  stop_.store(true, std::memory_order_relaxed);
  work_signal_.ring();
  acq_signal_.ring();
  can_signal_.ring();
  if (acq_thread_.joinable()) acq_thread_.join();
  if (can_thread_.joinable()) can_thread_.join();
  if (proc_thread_.joinable()) proc_thread_.join();
  if (trainer_) trainer_->stop();  // after the processing thread: every queued window is written
  for (auto& o : outputs_) o->deactivate();
  channel_->deactivate();
  source_->deactivate();
  active_ = false;
}

void Pipeline::post_clear() noexcept {
  if (alarm_) alarm_->post_clear_request(ClearSource::kLocal);
  work_signal_.ring();
}

WakeSchedule Pipeline::wake_schedule() const noexcept {
  WakeSchedule w = wake_;
  w.next_due_ns = next_due_ns_.load(std::memory_order_relaxed);
  w.late = due_late_.load(std::memory_order_relaxed);
  return w;
}

StageHeartbeats Pipeline::heartbeats() const noexcept {
  return {acq_beat_.load(std::memory_order_relaxed), can_beat_.load(std::memory_order_relaxed),
          proc_beat_.load(std::memory_order_relaxed)};
}

PipelineCounters Pipeline::counters() const noexcept {
  PipelineCounters c;
  c.acq_ring_full_blocks = acq_ring_full_blocks_.get();
  c.acq_ring_full_samples = acq_ring_full_samples_.get();
  c.acq_read_errors = acq_read_errors_.get();
  c.acq_end = acq_end_.load(std::memory_order_acquire);
  c.can_frames = can_frames_n_.get();
  c.can_speed = can_speed_.get();
  c.can_other_id = can_other_id_.get();
  c.can_wrong_dlc = can_wrong_dlc_.get();
  c.can_rtr = can_rtr_.get();
  c.can_error_frames = can_error_frames_.get();
  c.can_ring_full = can_ring_full_.get();
  c.can_clear_frames = can_clear_frames_.get();
  c.can_receive_errors = can_receive_errors_.get();
  c.can_end = can_end_.load(std::memory_order_acquire);
  c.output_errors = output_errors_.get();
  c.late_waits = late_waits_.get();
  c.publish_waits = publish_waits_.get();
  return c;
}

drivers::SampleSourceCounters Pipeline::source_counters() const noexcept {
  return source_ ? source_->counters() : drivers::SampleSourceCounters{};
}
drivers::CanCounters Pipeline::can_counters() const noexcept {
  return channel_ ? channel_->counters() : drivers::CanCounters{};
}
drivers::CanBusState Pipeline::can_bus_state() const noexcept {
  return channel_ ? channel_->bus_state() : drivers::CanBusState::kErrorActive;
}

// ---- acquisition thread -------------------------------------------------------------------------

void Pipeline::wait_stage(WakeSignal& signal, std::int64_t offset_ns) noexcept {
  // The ticket first: a deactivate() from here on ends the wait at once.
  const std::uint32_t ticket = signal.ticket();
  if (stop_.load(std::memory_order_relaxed)) return;
  const std::int64_t now = clock_.now_ns();
  const std::int64_t wake = plan_wake(now, next_due_ns_.load(std::memory_order_relaxed), offset_ns,
                                      wake_.spacing_ns, wake_.max_sleep_ns, burst_origin_ns_,
                                      due_late_.load(std::memory_order_relaxed), wake_.retry_ns);
  if (wake > now) signal.wait(ticket, wake - now);
}

SourceStatus Pipeline::acquire(std::int64_t timeout_ns) noexcept {
  // The source fills the ring's next free slot in place (a block is 4 KiB of which a 256-sample block
  // uses 1 KiB: no copy of it); with the ring full, the spare block.
  drivers::SampleBlock* const slot = sample_ring_->claim();
  drivers::SampleBlock& block = slot != nullptr ? *slot : *acq_block_;
  const SourceStatus st = source_->read(block, timeout_ns);
  switch (st) {
    case SourceStatus::kOk:
      if (slot != nullptr) {
        sample_ring_->commit();
        if (probe_ != nullptr) probe_->on_block_pushed(block);
        break;
      }
      // A full ring is an overrun for a real-time source (the block is dropped and counted; the
      // index jump becomes a gap downstream) and back-pressure for a fast replay.
      while (!sample_ring_->try_push(block)) {
        if (!source_fast_) {
          acq_ring_full_blocks_.add();
          acq_ring_full_samples_.add(block.count);
          break;
        }
        if (stop_.load(std::memory_order_relaxed)) return st;
        acq_beat_.fetch_add(1, std::memory_order_relaxed);
        work_signal_.ring();  // the consumer must drain what this burst pushed so far
        sleep_ns(200'000);
      }
      if (probe_ != nullptr) probe_->on_block_pushed(block);  // a dropped block is reported too
      break;
    case SourceStatus::kTimeout:
      break;
    case SourceStatus::kEndOfStream:
      acq_end_.store(true, std::memory_order_release);
      break;
    case SourceStatus::kError:
    case SourceStatus::kNotActive:
      acq_read_errors_.add();
      break;
  }
  return st;
}

void Pipeline::acquisition_loop() noexcept {
  while (!stop_.load(std::memory_order_relaxed)) {
    acq_beat_.fetch_add(1, std::memory_order_relaxed);
    if (acq_end_.load(std::memory_order_relaxed)) {
      sleep_ns(kStageWaitNs);
      continue;
    }
    if (source_fast_) {
      // As fast as the pipeline takes it: the read waits (if at all) and every block rings.
      const SourceStatus st = acquire(kStageWaitNs);
      if (st == SourceStatus::kOk || st == SourceStatus::kEndOfStream) work_signal_.ring();
      if (st == SourceStatus::kError || st == SourceStatus::kNotActive) sleep_ns(10'000'000);
      continue;
    }
    // Real-time pace: this thread's one wait lasts until a window can close (wait_stage); then every
    // block the device (or the replay's clock) has ready is taken without waiting. The processing thread
    // is not rung for blocks: it waits for the speed sample after a block anyway, and the CAN thread
    // that brings it wakes after this one (WakeSchedule::can_offset_ns). It is rung when the ring fills
    // up or the stream ends.
    wait_stage(acq_signal_, wake_.acq_offset_ns);
    SourceStatus st = SourceStatus::kOk;
    bool rang = false;
    for (std::size_t i = 0; i < kSampleRingBlocks && !stop_.load(std::memory_order_relaxed); ++i) {
      st = acquire(0);
      if (st != SourceStatus::kOk) break;
      if (!rang && sample_ring_->size_approx() > kSampleRingBlocks / 2) {  // a long burst (after a stall)
        work_signal_.ring();
        rang = true;
      }
    }
    if (st == SourceStatus::kEndOfStream) work_signal_.ring();
  }
}

// ---- CAN thread ---------------------------------------------------------------------------------

CanStatus Pipeline::receive_batch(std::int64_t timeout_ns, std::size_t& received) noexcept {
  const config::SpeedFrameSpec& spec = cfg_.pipeline.speed_frame;
  const ClearFrameSpec& clear = cfg_.can.clear_frame;
  std::size_t n = 0;
  received = 0;
  const CanStatus st = channel_->receive(std::span<CanFrame>(can_frames_), n, timeout_ns);
  if (st == CanStatus::kEndOfStream) {
    can_end_.store(true, std::memory_order_release);
    return st;
  }
  if (st == CanStatus::kError || st == CanStatus::kNotActive) {
    can_receive_errors_.add();
    return st;
  }
  for (std::size_t i = 0; i < n; ++i) {
    const CanFrame& f = can_frames_[i];
    can_frames_n_.add();
    config::DecodedSpeed d;
    switch (config::decode_speed(f, spec, d)) {
      case config::DecodeResult::kOk: {
        can_speed_.add();
        const dsp::SpeedSample s{f.t_ns - latency_ns_, d.speed_rad_s, d.angle_rad, d.has_angle};
        while (!speed_ring_->try_push(s)) {
          if (!can_fast_) {
            can_ring_full_.add();
            break;
          }
          if (stop_.load(std::memory_order_relaxed)) return st;
          can_beat_.fetch_add(1, std::memory_order_relaxed);
          work_signal_.ring();
          sleep_ns(200'000);
        }
        break;
      }
      case config::DecodeResult::kOtherId:
        if (matches_clear(f, clear)) {
          can_clear_frames_.add();
          alarm_->post_clear_request(ClearSource::kCan);
        } else {
          can_other_id_.add();
        }
        break;
      case config::DecodeResult::kWrongDlc:
        can_wrong_dlc_.add();
        break;
      case config::DecodeResult::kRtr:
        can_rtr_.add();
        break;
      case config::DecodeResult::kErrorFrame:
        can_error_frames_.add();
        break;
    }
  }
  received = n;
  return st;
}

void Pipeline::can_loop() noexcept {
  while (!stop_.load(std::memory_order_relaxed)) {
    can_beat_.fetch_add(1, std::memory_order_relaxed);
    if (can_end_.load(std::memory_order_relaxed)) {
      sleep_ns(kStageWaitNs);
      continue;
    }
    std::size_t n = 0;
    if (can_fast_) {
      const CanStatus st = receive_batch(kStageWaitNs, n);
      if (st == CanStatus::kEndOfStream || n > 0) work_signal_.ring();
      if (st == CanStatus::kError || st == CanStatus::kNotActive) sleep_ns(10'000'000);
      continue;
    }
    // Real-time pace: this thread's one wait lasts until the speed frame after the block that can close
    // a window has arrived (wait_stage). Then the socket (recvmmsg, kernel receive stamps) or the replay
    // is drained without waiting, batch after batch, and the processing thread is rung once: the pass
    // was scheduled for it (a window may close; else the staleness checks see the stages alive).
    wait_stage(can_signal_, wake_.can_offset_ns);
    CanStatus st = CanStatus::kOk;
    for (std::size_t i = 0; i < kSpeedRingSamples / kCanBatch && !stop_.load(std::memory_order_relaxed);
         ++i) {
      st = receive_batch(0, n);
      if (st != CanStatus::kOk || n < kCanBatch) break;
      if (speed_ring_->size_approx() > kSpeedRingSamples / 2) work_signal_.ring();  // a long burst
    }
    work_signal_.ring();
  }
}

// ---- processing thread --------------------------------------------------------------------------

void Pipeline::prune_speeds_before_t0() noexcept {
  dsp::SpeedSample dropped;
  while (speed_ring_->size_approx() > kSpeedRingSamples / 2 && speed_ring_->try_pop(dropped))
    ++st_.speeds_before_t0;
}

bool Pipeline::serve_inputs() noexcept {
  acq_beat_.fetch_add(1, std::memory_order_relaxed);
  can_beat_.fetch_add(1, std::memory_order_relaxed);
  last_serve_ns_ = clock_.now_ns();
  bool more = false;
  // CAN first: its speed samples let process_step() release the blocks read next. The socket's receive
  // queue (kernel receive stamps) and the device's buffer hold what arrived since the last pass.
  if (!can_end_.load(std::memory_order_relaxed)) {
    std::size_t n = 0;
    for (std::size_t i = 0; i < kSpeedRingSamples / kCanBatch; ++i) {
      if (speed_ring_->size_approx() > kSpeedRingSamples / 2) {
        if (st_.have_t0) {  // this thread must empty it first
          more = true;
          break;
        }
        prune_speeds_before_t0();  // no block yet: read on
      }
      if (receive_batch(0, n) != CanStatus::kOk || n < kCanBatch) break;
    }
  }
  if (acq_end_.load(std::memory_order_relaxed)) return more;
  for (std::size_t i = 0; i < kSampleRingBlocks; ++i) {
    // Past 3/4 process_step() releases blocks without their speed sample; stop there and let it.
    if (sample_ring_->size_approx() > kSampleRingBlocks * 3 / 4) return true;
    if (acquire(0) != SourceStatus::kOk) return more;
  }
  return true;
}

std::int64_t Pipeline::sample_time(std::uint64_t index) const noexcept {
  // ceil(index * 1e12 / fs_mhz), exact (the slicer's convention for sample times), in 64 bits (no
  // unsigned __int128 on 32-bit targets), as WindowSlicer::offset_ns: index = q * F + m, whole multiples
  // of F samples are 1000 s, and m * 1e9 = c * F + e.
  const auto f = static_cast<std::uint64_t>(fs_mhz_);
  const std::uint64_t q = index / f;
  const std::uint64_t m = index % f;
  const std::uint64_t c = m * 1'000'000'000ULL / f;
  const std::uint64_t e = m * 1'000'000'000ULL - c * f;
  return static_cast<std::int64_t>(q * 1'000'000'000'000ULL + c * 1000 + (e * 1000 + f - 1) / f);
}

void Pipeline::push_block(const drivers::SampleBlock& b) noexcept {
  if (b.first_index < base_index_ + expected_index_) {
    ++st_.index_back;
    return;
  }
  const std::uint64_t index = b.first_index - base_index_;
  // The sample index is the time base (t0 + index / fs). A block stamp that steps by more than
  // kTimeJumpNs against it since the previous block is a clock jump the index does not show (a clock
  // step, or samples lost without an index jump): the block is not trusted, so no window spans the jump.
  const std::int64_t dev = b.t_mono_ns - (st_.t0_mono_ns + sample_time(index));
  bool invalid = (b.flags & (drivers::kBlockShortRead | drivers::kBlockTimeBack)) != 0;
  if (have_dev_ && (dev - last_dev_ > kTimeJumpNs || last_dev_ - dev > kTimeJumpNs)) {
    ++st_.time_jumps;
    invalid = true;
  }
  have_dev_ = true;
  last_dev_ = dev;
  if (index > expected_index_) {
    const std::uint64_t gap = index - expected_index_;
    if (order_res_) {
      order_mark_gap(gap);
    } else if (engine_) {
      engine_->mark_gap(gap);
    }
    if (train_slicer_) train_slicer_->mark_gap(gap);
    st_.gap_samples += gap;
  }
  if (invalid) {
    // Short read (bytes lost upstream) or a doubtful stamp: the samples keep their place but are
    // invalid, so every window containing them is discarded (slicer windows_invalid).
    ++st_.blocks_invalid;
    if (order_res_) {
      order_mark_gap(b.count);
    } else if (engine_) {
      engine_->mark_gap(b.count);
    }
    if (train_slicer_) train_slicer_->mark_gap(b.count);
  } else {
    const std::span<const float> samples(b.samples, b.count);
    if (order_res_) {
      order_res_->push_samples(samples);
    } else if (engine_) {
      engine_->push_samples(samples);
    }
    if (train_slicer_) train_slicer_->push_samples(samples);
  }
  expected_index_ = index + b.count;
  ++st_.blocks;
  st_.samples += b.count;
  st_.data_time_ns = st_.t0_mono_ns + sample_time(expected_index_);
  st_.max_block_dev_ns = std::max(st_.max_block_dev_ns, dev < 0 ? -dev : dev);
}

void Pipeline::push_speed(const dsp::SpeedSample& s) noexcept {
  dsp::SpeedSample shifted = s;
  shifted.t_ns -= st_.t0_mono_ns;
  if (!streams_finished_) {
    if (order_res_) {
      // As `ptda monitor` in the order domain: the log time smoothed on the frame grid (dsp::FrameClock,
      // shift-invariant, so stream time gives the offline tool's times), then the resampler.
      if (order_clock_) shifted.t_ns = order_clock_->smooth(shifted.t_ns);
      order_res_->push_speed(shifted);
    } else if (engine_) {
      engine_->push_speed(shifted);
    }
    if (coverage_) coverage_->on_speed(s);  // daemon time, as the windows it sees
    if (train_slicer_) train_slicer_->push_speed(shifted);
  }
  ++st_.speeds;
  st_.last_speed_ns = std::max(st_.last_speed_ns, s.t_ns);
  have_any_speed_ = true;
}

void Pipeline::order_mark_gap(std::uint64_t count) noexcept {
  // O(count) (a NaN costs the resampler a compare): a gap of an hour at 25.6 kHz is ~0.1 s of work.
  while (count > 0) {
    const std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(count, order_nan_.size()));
    order_res_->push_samples(std::span<const float>(order_nan_.data(), n));
    count -= n;
  }
}

void Pipeline::on_judged(dsp::WindowResult& r, std::int64_t now) noexcept {
  const std::int64_t t0 = st_.t0_mono_ns;
  r.ref.t_start_ns += t0;
  r.ref.t_end_ns += t0;
  ++st_.windows;
  if (r.status == dsp::WindowStatus::kScored) {
    ++st_.scored;
    if (r.verdict.abnormal()) ++st_.abnormal;
    st_.have_window = true;
    st_.last_window = r;
  } else {
    ++st_.no_class;
  }
  if (r.alarm) ++st_.alarm_windows;
  if (coverage_) coverage_->on_window(r);
  alarm_->on_window(r, alarm_time(fast_ ? r.ref.t_end_ns : now));
  if (sink_ != nullptr) sink_->on_window(r);
  if (window_log_on_.load(std::memory_order_relaxed) && !window_log_->try_push(r)) ++st_.window_log_dropped;
}

void Pipeline::drain_windows(std::int64_t now) noexcept {
  if (order_res_) {
    // The order domain, as `ptda monitor` (cli OrderMonitorSink): every order sample into the cutter,
    // every completed window judged by the engine. No slicer, so no discarded count for the coverage.
    dsp::OrderSample o;
    dsp::OrderWindowRef ref;
    const std::span<float> buf(order_window_);
    while (order_res_->pop(o)) {
      if (!order_cut_->push(o, ref, buf)) continue;
      dsp::WindowResult r;
      engine_->judge_window(dsp::window_ref_of(ref, buf.size()), buf, r);
      on_judged(r, now);
    }
  } else if (engine_) {
    dsp::WindowResult r;
    while (engine_->poll(r)) on_judged(r, now);
    if (coverage_) {
      const dsp::SlicerCounters& sc = engine_->slicer().counters();
      coverage_->on_discarded_total(sc.windows_invalid + sc.windows_lost + sc.windows_overflow);
    }
  }
  if (train_slicer_) drain_training();
}

void Pipeline::drain_training() noexcept {
  // A fast replay takes a window out of the slicer only when the trainer's queue has a slot: the rest
  // wait in the slicer's history (no block is released meanwhile, so no sample overwrites them).
  // A real-time source cannot wait: a window that finds the queue full is dropped and counted.
  dsp::WindowRef ref;
  bool backlog = false;
  for (;;) {
    if (source_fast_ && trainer_->free_slots() == 0) {
      backlog = train_slicer_->has_window();
      break;
    }
    if (!train_slicer_->pop(ref, std::span<float>(train_window_))) break;
    ++st_.windows;
    trainer_->add_window(ref, train_window_);
  }
  train_backlog_.store(backlog, std::memory_order_release);
  dsp::RegionInfo region;
  while (train_slicer_->pop_region(region)) trainer_->add_region(region);
}

bool Pipeline::process_step(std::int64_t now) noexcept {
  bool work = false;
  if (train_slicer_ && source_fast_ && train_backlog_.load(std::memory_order_relaxed)) {
    drain_training();  // windows that waited for the trainer's writer
    work = !train_backlog_.load(std::memory_order_relaxed);
  }
  // Only the valid samples of a block are copied out of the ring (a 256-sample block: 1 of 4 KiB).
  if (!have_block_ && sample_ring_->pop_with([this](const drivers::SampleBlock& b) noexcept {
        drivers::SampleBlock& h = *held_block_;
        h.t_mono_ns = b.t_mono_ns;
        h.first_index = b.first_index;
        h.count = b.count;
        h.flags = b.flags;
        h.gap_samples = b.gap_samples;
        std::memcpy(h.samples, b.samples, std::min<std::size_t>(b.count, drivers::kMaxBlock) * sizeof(float));
      })) {
    if (probe_ != nullptr) probe_->on_block_popped(*held_block_);
    have_block_ = true;
    last_block_arrival_ns_ = now;
    if (!st_.have_t0) {
      st_.have_t0 = true;
      st_.t0_mono_ns = held_block_->t_mono_ns;
      base_index_ = held_block_->first_index;
      expected_index_ = 0;
    }
    work = true;
  }
  if (!st_.have_t0) {
    // Speed samples wait in their ring for t0. A real-time source that never delivers must not stall
    // the CAN stage: keep the newest half of the ring.
    if (!fast_) prune_speeds_before_t0();
    return work;
  }
  if (!have_speed_ && speed_ring_->try_pop(next_speed_)) {
    have_speed_ = true;
    work = true;
  }
  const bool can_end = can_end_.load(std::memory_order_acquire);
  if (have_block_) {
    const drivers::SampleBlock& b = *held_block_;
    const std::uint64_t end_index = b.first_index >= base_index_ ? b.first_index - base_index_ + b.count : 0;
    const std::int64_t block_end = st_.t0_mono_ns + sample_time(end_index);
    // Speed samples before the block's end go first (as `ptda monitor` interleaves them).
    while (have_speed_ && next_speed_.t_ns < block_end) {
      push_speed(next_speed_);
      have_speed_ = speed_ring_->try_pop(next_speed_);
      work = true;
    }
    const bool release =
        have_speed_ || can_end ||
        (!fast_ && (now - block_end > hold_ns_ || sample_ring_->size_approx() > kSampleRingBlocks * 3 / 4));
    // Field training from a fast replay: wait (the writer rings work_signal_) rather than drop windows:
    // nothing left in the slicer, and room for what one block can complete.
    const bool trainer_room =
        !source_fast_ || !trainer_ ||
        (!train_backlog_.load(std::memory_order_relaxed) && trainer_->free_slots() >= train_block_windows_);
    if (release && trainer_room) {
      push_block(b);
      have_block_ = false;
      work = true;
      // Poll after every block, as `ptda monitor` does: the slicer's history holds a few windows, so
      // windows must be taken out before many more blocks overwrite their samples.
      drain_windows(now);
    }
  } else if (have_speed_) {
    const bool acq_end = acq_end_.load(std::memory_order_acquire) && sample_ring_->size_approx() == 0;
    if (acq_end || (!fast_ && speed_ring_->size_approx() > kSpeedRingSamples / 2)) {
      push_speed(next_speed_);
      have_speed_ = false;
      work = true;
    }
  }
  if (!streams_finished_ && !have_block_ && acq_end_.load(std::memory_order_acquire) &&
      sample_ring_->size_approx() == 0) {
    const bool can_live = cfg_.can.backend == CanBackend::kSocketCan;
    if (can_live || (can_end && !have_speed_ && speed_ring_->size_approx() == 0)) {
      finish_streams();
      drain_windows(now);
      if (coverage_) coverage_->finish();
      work = true;
    }
  }
  return work;
}

std::int64_t Pipeline::alarm_time(std::int64_t candidate) noexcept {
  // Fast replays judge on data time, real-time sources on the clock; either way never backwards.
  alarm_time_ns_ = std::max(alarm_time_ns_, candidate);
  return alarm_time_ns_;
}

void Pipeline::finish_streams() noexcept {
  // Order domain: `ptda monitor` drains the resampler at the end and finishes nothing (a partial
  // window is dropped); drain_windows() after this does the same.
  if (engine_ && !order_res_) engine_->finish();
  if (train_slicer_) train_slicer_->finish();
  streams_finished_ = true;
  st_.ended = true;
}

void Pipeline::update_phase(std::int64_t now) noexcept {
  Phase phase = Phase::kMonitoring;
  std::uint8_t causes = 0;
  const bool acq_end = acq_end_.load(std::memory_order_acquire);
  if (mode_ == PipelineMode::kMonitor && !engine_) {
    phase = Phase::kRefused;
    causes = drivers::kCauseBaseline;
  } else if (st_.ended) {
    // The end of a replay is no input fault: no cause bit; the alarm manager shows kFault (no verdict).
    phase = Phase::kEnded;
    if (coverage_ && coverage_->state().level == dsp::CoverageLevel::kNotJudging) {
      phase = Phase::kNotJudging;  // the replay's verdict: it ended blind
      causes = drivers::kCauseCoverage;
    }
  } else {
    const bool sensor_stale = !fast_ && (acq_end || now - last_block_arrival_ns_ > sensor_stale_ns_);
    bool speed_stale = channel_->bus_state() == drivers::CanBusState::kBusOff;
    if (st_.have_t0) {
      const std::int64_t last = have_any_speed_ ? st_.last_speed_ns : st_.t0_mono_ns;
      if (st_.data_time_ns - last > speed_stale_ns_) speed_stale = true;
    }
    if (sensor_stale) {
      phase = Phase::kPausedSensor;
      causes = drivers::kCauseSensor;
    } else if (speed_stale) {
      phase = Phase::kPausedSpeed;
      causes = drivers::kCauseSpeed;
    } else if (!st_.have_t0) {
      phase = Phase::kStarting;
    } else if (mode_ == PipelineMode::kTrain) {
      phase = Phase::kTraining;
    } else if (coverage_ && coverage_->state().level == dsp::CoverageLevel::kNotJudging) {
      phase = Phase::kNotJudging;
      causes = drivers::kCauseCoverage;
    }
    if (mode_ == PipelineMode::kTrain) causes |= drivers::kCauseBaseline;  // nothing is judged while training
  }
  if ((phase == Phase::kPausedSpeed || phase == Phase::kPausedSensor) && phase != st_.phase) ++st_.pauses;
  st_.phase = phase;
  if (causes != st_.fault_causes || !faults_applied_) {
    alarm_->set_faults(causes, alarm_time(fast_ ? st_.data_time_ns : now));
    st_.fault_causes = causes;
    faults_applied_ = true;
  }
  if (st_.ended && !ended_applied_) {
    alarm_->set_input_ended(alarm_time(fast_ ? st_.data_time_ns : now));
    ended_applied_ = true;
  }
}

void Pipeline::drive_outputs(std::int64_t now, bool force) noexcept {
  if (outputs_.empty()) return;
  const drivers::AlarmReport report = alarm_->report();
  // With the kernel timer a new window's values go into the frames it sends at once (one system call,
  // no frame of its own), not at the next renewal.
  const bool changed = report.level != last_output_level_ || report.causes != last_output_causes_ ||
                       (wake_.output_kernel_timed && !drivers::same_report(report, last_output_report_));
  // At real-time pace an unchanged frame rides on this pass once half its period has passed
  // (resend_due); processing_wait_ns() still wakes this thread for it at the full period. A fast
  // replay passes all the time: there the period alone counts, as before.
  const bool due = fast_ ? now - last_output_ns_ >= output_period_ns_
                         : resend_due(now, last_output_ns_, output_period_ns_);
  if (!force && !changed && !due) return;
  for (auto& o : outputs_) {
    if (o->set(report) != drivers::OutputStatus::kOk) output_errors_.add();
  }
  if (probe_ != nullptr) probe_->on_outputs_set(report);
  last_output_level_ = report.level;
  last_output_causes_ = report.causes;
  last_output_report_ = report;
  last_output_ns_ = now;
}

bool Pipeline::publish(std::int64_t now, bool force) noexcept {
  if (!force && now - last_publish_ns_ < kPublishPeriodNs) return false;
  if (engine_) st_.slicer = engine_->slicer().counters();
  if (order_res_) {
    st_.resampler = order_res_->counters();
    st_.order_windows_cut = order_cut_->windows();
  }
  if (train_slicer_) st_.slicer = train_slicer_->counters();
  st_.clock_ns = alarm_time_ns_;
  st_.alarm = alarm_->state();
  st_.report = alarm_->report();
  st_.alarm_counters = alarm_->counters();
  if (coverage_) st_.coverage = coverage_->state();
  published_.store(st_);
  last_publish_ns_ = now;
  return true;
}

void Pipeline::publish_due(std::int64_t now) noexcept {
  std::int64_t due = kNoDue;
  if (!streams_finished_) {
    if (wake_.follows_windows) {
      if (st_.have_t0) due = st_.t0_mono_ns + engine_->slicer().next_close_ns();
    } else if (order_res_) {
      due = burst_origin_ns_;  // the fixed grid (WakeSchedule::spacing_ns = kBurstPeriodNs)
    }
  }
  const std::int64_t old_due = next_due_ns_.load(std::memory_order_relaxed);
  next_due_ns_.store(due, std::memory_order_relaxed);
  if (due != old_due) {
    // A stage that has just served a due time that was only a bound (no run yet) planned one spacing
    // ahead; a run that began since may close sooner. Ring a stage whose plan the new due time brings
    // forward: it plans again (one wake-up, about once per region).
    const bool late_now = due_late_.load(std::memory_order_relaxed);
    const auto sooner = [&](std::int64_t offset_ns) {
      return plan_wake(now, due, offset_ns, wake_.spacing_ns, wake_.max_sleep_ns, burst_origin_ns_, late_now,
                       wake_.retry_ns) < plan_wake(now, old_due, offset_ns, wake_.spacing_ns,
                                                   wake_.max_sleep_ns, burst_origin_ns_, late_now,
                                                   wake_.retry_ns);
    };
    if (!wake_.single_thread && sooner(wake_.acq_offset_ns)) acq_signal_.ring();
    if (!wake_.single_thread && sooner(wake_.can_offset_ns)) can_signal_.ring();
  }
  // Late: both stages have served the due time (this pass follows the CAN thread's, or is the one
  // thread's own input pass) and the window is still open. The stages planned one spacing ahead; ring them to
  // retry every frame period instead.
  const bool late = wake_.follows_windows && due != kNoDue && now >= due + wake_.can_offset_ns &&
                    now < due + wake_.can_offset_ns + wake_.late_window_ns;
  if (late != due_late_.load(std::memory_order_relaxed)) {
    due_late_.store(late, std::memory_order_relaxed);
    if (late && !wake_.single_thread) {
      acq_signal_.ring();
      can_signal_.ring();
    }
  }
}

std::int64_t Pipeline::processing_wait_ns(std::int64_t now, bool unpublished) const noexcept {
  // The CAN thread rings after every pass it makes (at most max_sleep_ns apart); the timeout covers what
  // depends on time alone: the CAN verdict frame's period, the publication of work done, a held block's
  // hold time (it waits for the speed sample after it). One thread: its own input schedule instead of
  // the CAN thread's rings, and no hold-time wake-up (below).
  std::int64_t wait_ns = wake_.max_sleep_ns + wake_.can_offset_ns;
  if (!outputs_.empty() && output_period_ns_ > 0)
    wait_ns = std::min(wait_ns, last_output_ns_ + output_period_ns_ - now);
  if (unpublished) wait_ns = std::min(wait_ns, last_publish_ns_ + kPublishPeriodNs - now);
  if (wake_.single_thread) {
    // This thread reads the inputs: when the speed frame after the block that can close a window has
    // arrived (the CAN thread's schedule), or on the grid of max sleeps.
    wait_ns =
        std::min(wait_ns, plan_wake(now, next_due_ns_.load(std::memory_order_relaxed), wake_.can_offset_ns,
                                    wake_.spacing_ns, wake_.max_sleep_ns, burst_origin_ns_,
                                    due_late_.load(std::memory_order_relaxed), wake_.retry_ns) -
                              now);
  }
  if (have_block_ && !wake_.single_thread) {
    // (One thread: the block waits for the next input pass instead, which brings its speed sample or
    // releases it once the hold time has passed; a window's last block is never held then, as the pass
    // comes after the speed frame that follows it. Waking for it would double the wake-ups.)
    const drivers::SampleBlock& b = *held_block_;
    const std::uint64_t end_index = b.first_index >= base_index_ ? b.first_index - base_index_ + b.count : 0;
    wait_ns = std::min(wait_ns, st_.t0_mono_ns + sample_time(end_index) + hold_ns_ + 1 - now);
  }
  return std::max<std::int64_t>(wait_ns, 100'000);
}

void Pipeline::processing_loop() noexcept {
  std::int64_t now = clock_.now_ns();
  update_phase(now);
  drive_outputs(now, true);
  publish(now, true);
  bool unpublished = false;  // work done since the last publication
  while (!stop_.load(std::memory_order_relaxed)) {
    if (stall_.load(std::memory_order_relaxed)) {  // test-only fault injection: no work, no heartbeat
      sleep_ns(5'000'000);
      continue;
    }
    proc_beat_.fetch_add(1, std::memory_order_relaxed);
    // The ticket is taken before looking at the rings, so work published from here on ends the wait.
    const std::uint32_t ticket = work_signal_.ticket();
    now = clock_.now_ns();
    bool more_input = wake_.single_thread && serve_inputs();
    bool work = false;
    for (std::size_t round = 0;; ++round) {
      for (int i = 0; i < 64; ++i) {
        if (!process_step(now)) break;
        work = true;
        // One thread: a long pass (several windows judged, a slow machine) reads the inputs again
        // between steps, so the device's and the socket's buffers are read at least this often.
        if (wake_.single_thread && clock_.now_ns() - last_serve_ns_ >= kInputServeBudgetNs)
          more_input = serve_inputs() || more_input;
      }
      // A long burst (after a stall) is read in ring-sized parts, each processed before the next.
      if (!more_input || round + 1 >= kSampleRingBlocks || stop_.load(std::memory_order_relaxed)) break;
      proc_beat_.fetch_add(1, std::memory_order_relaxed);
      more_input = serve_inputs();
    }
    update_phase(now);
    alarm_->tick(alarm_time(fast_ ? st_.data_time_ns : now));
    drive_outputs(now, false);
    if (wake_fd_ >= 0 && alarm_->level_change_count() != woken_changes_) {
      // A level change is on the outputs: wake the supervisor to take it from the ring now (eventfd,
      // non-blocking: a failed write only means the counter is already non-zero).
      woken_changes_ = alarm_->level_change_count();
      const std::uint64_t one = 1;
      [[maybe_unused]] const auto n = ::write(wake_fd_, &one, sizeof one);
    }
    if (work) unpublished = true;
    if (publish(now, false)) unpublished = false;
    if (!fast_) publish_due(now);
    if (!work) {
      // Idle: sleep until rung, but publish what was done within kPublishPeriodNs (the supervisor and
      // status.json must not see a stale phase for a whole idle period).
      std::int64_t wait_ns = kProcessingIdleWaitNs;
      if (!fast_) {
        wait_ns = processing_wait_ns(now, unpublished);
        if (wake_.single_thread && due_late_.load(std::memory_order_relaxed)) late_waits_.add();
        if (unpublished) publish_waits_.add();
      } else if (unpublished) {
        wait_ns = std::clamp<std::int64_t>(last_publish_ns_ + kPublishPeriodNs - now, 100'000, wait_ns);
      }
      work_signal_.wait(ticket, wait_ns);
    }
  }
  publish(clock_.now_ns(), true);
}

}  // namespace ptda::daemon
