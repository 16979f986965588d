// The run-time half of ptdad: three real-time threads joined by two SPSC rings, built from a
// DaemonConfig. When both inputs are at real-time pace, one thread does all three stages' work (the
// processing thread reads both inputs on the CAN thread's schedule: serve_inputs(); docs/daemon.md,
// "One thread at real-time pace"), so each due time costs one wake-up instead of three.
//
//   acquisition ── SampleSource::read ──▶ SampleRing (kSampleRingBlocks blocks of ≤ 1024 samples) ──┐
//   can ── CanChannel::receive ─ decode_speed ─ latency ──▶ SpeedRing (kSpeedRingSamples) ───────────┤
//                                   └─ clear frame ─▶ AlarmManager::post_clear_request              │
//   processing ◀───────────────────────────────────────────────────────────────────────────────────┘
//      merges both streams by time ─▶ dsp::MonitorEngine (the code `ptda monitor` runs) ─▶ WindowResult
//      (order domain, docs/method.md §9: speed ─ dsp::FrameClock ─▶ dsp::AngleResampler ◀─ vibration,
//       ─▶ dsp::OrderWindowCutter ─▶ MonitorEngine::judge_window, as `ptda monitor` in order mode)
//      ─▶ AlarmManager ─▶ AlarmOutputs (GPIO line, CAN frame); publishes PipelineStatus (seqlock)
//
// Lifecycle (what is true in each state):
//   constructed  - holds a copy of the configuration; nothing opened or allocated.
//   configured   - configure() opened every device/file, read and checked the baseline (a baseline that
//                  is missing, corrupt or does not match puts the pipeline in "refused": it runs, judges
//                  nothing and shows kFault with cause "baseline"), built the engine, allocated the rings
//                  and every buffer. Throws ptda::Error for everything else (device, recording, scenario).
//   active       - activate() started the devices and the three threads (or the one). From here on nothing
//                  allocates, throws, logs or blocks except each thread's one wait.
//   deactivated  - deactivate() stopped and joined the threads (each checks the stop flag at least every
//                  kStageWaitNs, or is rung out of its real-time sleep), drove the outputs fail-safe and
//                  stopped the devices. Idempotent.
//
// Time: every timestamp is on the daemon clock (CLOCK_MONOTONIC ns). The first vibration block defines
// t0 = t_mono_ns(first block) - first_index / fs ("stream time" 0). The engine runs on stream time
// (t - t0) with sample i at ceil(i * 1e9 / fs): speed samples are shifted by -t0 before they are pushed,
// results by +t0 after they are polled. CAN frames carry receive times on the same clock; the pipeline's
// [can] speed_latency_s is subtracted from each. See docs/daemon.md, "Time alignment".
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "alarm/alarm_manager.hpp"
#include "core/daemon_config.hpp"
#include "core/seqlock.hpp"
#include "core/sim_backends.hpp"
#include "core/wake_plan.hpp"
#include "ptda/drivers/alarm_output.hpp"
#include "ptda/drivers/can_channel.hpp"
#include "ptda/drivers/clock.hpp"
#include "ptda/drivers/counter.hpp"
#include "ptda/drivers/sample_source.hpp"
#include "ptda/dsp/angle_resampler.hpp"
#include "ptda/dsp/baseline.hpp"
#include "ptda/dsp/coverage.hpp"
#include "ptda/dsp/frame_clock.hpp"
#include "ptda/dsp/monitor_engine.hpp"
#include "ptda/dsp/order_windows.hpp"
#include "rt/spsc_ring.hpp"
#include "rt/wake_signal.hpp"
#include "training/field_trainer.hpp"

namespace ptda::drivers {
class WavReplaySource;
class CandumpReplayChannel;
class SocketCanChannel;
class CanAlarmOutput;
}  // namespace ptda::drivers

namespace ptda::daemon {

inline constexpr std::size_t kSampleRingBlocks = 64;      ///< 64 x 1024 samples: 2.56 s at 25.6 kHz
inline constexpr std::size_t kSpeedRingSamples = 4096;    ///< 16 s of 4 ms speed frames
inline constexpr std::size_t kCanBatch = 64;              ///< frames per receive() call
inline constexpr std::int64_t kStageWaitNs = 50'000'000;  ///< longest wait of a stage before it re-checks
/// Real-time sources are read when a window can close (docs/daemon.md, "Sleeping until a window can
/// close"): the processing thread publishes the earliest time the next window can close
/// (WindowSlicer::next_close_ns()); the acquisition thread wakes once the block holding that window's
/// last sample is complete, the CAN thread once the speed frame after that block has arrived, each takes
/// everything ready without waiting, and the CAN thread rings the processing thread (one thread: it reads
/// both inputs itself at the CAN thread's time, serve_inputs()). When no window can
/// close (speed changing, standstill) they sleep for at most kMaxSleepNs, or less when the rings, an IIO
/// buffer, the staleness checks or the watchdog need it (Pipeline::wake_schedule()).
inline constexpr std::int64_t kMaxSleepNs = 250'000'000;
/// The order domain (no slicer to ask) keeps a fixed grid of bursts of this period, as before the
/// wake-ups followed the windows; an IIO buffer of unknown length caps the max sleep at it.
inline constexpr std::int64_t kBurstPeriodNs = 20'000'000;
/// Fast replays: the processing thread sleeps on its doorbell (rt/wake_signal.hpp) at most this long
/// when it has no work (every block and frame batch rings it). At real-time pace it sleeps until the
/// CAN thread rings, the CAN verdict frame's period, a held block's hold time, or wake_schedule()'s
/// max sleep + CAN offset; one thread: until its own input time (the CAN thread's), the verdict frame's
/// period or unpublished work's publication (no hold-time wake-up: docs/daemon.md).
inline constexpr std::int64_t kProcessingIdleWaitNs = 50'000'000;
/// One thread (both inputs at real-time pace): a pass that has worked this long since it last read the
/// inputs reads them again between two steps, so a slow pass does not leave the device's buffer and the
/// socket's receive queue unread for longer than this plus one step.
inline constexpr std::int64_t kInputServeBudgetNs = 10'000'000;
/// The processing thread publishes its status (seqlock) at most this often, and at most this long
/// after it did some work.
inline constexpr std::int64_t kPublishPeriodNs = 10'000'000;
/// A block stamp that moves more than this against the sample index since the previous block is a clock
/// jump: the block's samples are declared invalid (the index stays the time base).
inline constexpr std::int64_t kTimeJumpNs = 100'000'000;

using SampleRing = SpscRing<drivers::SampleBlock, kSampleRingBlocks>;
// The rings hold at least twice the longest sleep at the production rates (25.6 kHz in 256-sample
// blocks; speed frames every 1 ms or slower). configure() shortens the sleep for smaller blocks or
// faster rates (ring time / 2), so no configuration overflows a ring by sleeping; an overflow that still
// happens (a stall) is counted (acq_ring_full_*, can_ring_full).
static_assert(kSampleRingBlocks * 256 * 1'000'000'000LL / 25'600 >= 2 * kMaxSleepNs,
              "the sample ring must hold two max sleeps of 256-sample blocks at 25.6 kHz");
static_assert(static_cast<std::int64_t>(kSpeedRingSamples) * 1'000'000 >= 2 * kMaxSleepNs,
              "the speed ring must hold two max sleeps of 1 ms speed frames");
using SpeedRing = SpscRing<dsp::SpeedSample, kSpeedRingSamples>;
/// Windows handed from processing to the supervisor for the event history ([history]); the supervisor
/// drains it every status period, so 256 windows cover periods of seconds at any window rate a
/// 25.6 kHz channel gives (at most 8 windows/s of 3200 samples without overlap).
inline constexpr std::size_t kWindowLogWindows = 256;
using WindowLogRing = SpscRing<dsp::WindowResult, kWindowLogWindows>;

/// What the processing stage is doing (the reason behind the daemon state).
enum class Phase : std::uint8_t {
  kStarting = 0,      ///< activated, no vibration block yet
  kMonitoring = 1,    ///< windows are being judged
  kPausedSpeed = 2,   ///< no speed sample for [daemon] speed_stale_periods frame periods, or bus-off
  kPausedSensor = 3,  ///< no vibration block for [daemon] sensor_stale_s (real-time sources)
  kRefused = 4,       ///< no usable baseline: nothing is judged
  kTraining = 5,      ///< field training: windows go to the FieldTrainer
  kEnded = 6,         ///< a replay ended and every window was processed: kFault with no cause (no
                      ///< verdict; not a sensor fault), daemon state "ended"
  kNotJudging = 7,    ///< running, but no window judged for [daemon] coverage_timeout_s of motion (or a
                      ///< finished replay judged nothing): kFault with cause coverage, never kNormal
};
[[nodiscard]] const char* phase_name(Phase p) noexcept;

enum class PipelineMode : std::uint8_t { kMonitor = 0, kTrain = 1 };

/// Receives every processed window (test and tool hook). Called on the processing thread: must not
/// block, allocate or throw.
class WindowSink {
 public:
  virtual ~WindowSink() = default;
  virtual void on_window(const dsp::WindowResult& w) noexcept = 0;
};

/// Marks the points of the latency path (benchmark hook: daemon/bench/daemon_bench.cpp). Each call is
/// made on the named thread and must not block, allocate or throw; the implementation takes its own
/// timestamps. Unset (nullptr, the default) it costs one predictable branch per block and per output
/// update.
class PipelineProbe {
 public:
  virtual ~PipelineProbe() = default;
  /// Acquisition thread (processing, with one thread): `b` was just pushed into the sample ring.
  virtual void on_block_pushed(const drivers::SampleBlock& b) noexcept = 0;
  /// Processing thread: `b` was just popped from the sample ring (it may still wait for speed).
  virtual void on_block_popped(const drivers::SampleBlock& b) noexcept = 0;
  /// Processing thread: every alarm output was just set to `report`.
  virtual void on_outputs_set(const drivers::AlarmReport& report) noexcept = 0;
};

/// Test-only hook (tests/unit/daemon/daemon_faults_test.cpp and friends; docs/daemon.md, "Faults"):
/// supplies the vibration source and the CAN channel instead of the configured [adc]/[can] backends,
/// and may add alarm outputs after the configured ones. The configured pace still decides between
/// back-pressure (fast) and dropping (real time). Called by Pipeline::configure() on the main thread,
/// once per pipeline (a reload or the end of field training asks again). May allocate and throw.
class DeviceFactory {
 public:
  virtual ~DeviceFactory() = default;
  [[nodiscard]] virtual std::unique_ptr<drivers::SampleSource> make_source(drivers::Clock& clock) = 0;
  [[nodiscard]] virtual std::unique_ptr<drivers::CanChannel> make_channel(drivers::Clock& clock) = 0;
  /// Appends extra outputs (e.g. drivers::RecordingAlarmOutput); `channel` is the pipeline's channel.
  virtual void add_outputs(std::vector<std::unique_ptr<drivers::AlarmOutput>>& outputs,
                           drivers::CanChannel& channel) {
    (void)outputs;
    (void)channel;
  }
};

/// Published by the processing thread (seqlock), read by the supervisor.
struct PipelineStatus {
  Phase phase = Phase::kStarting;
  std::uint8_t fault_causes = 0;  ///< AlarmCause bits passed to the alarm manager
  bool have_t0 = false;
  bool ended = false;
  std::int64_t t0_mono_ns = 0;     ///< daemon time of sample 0
  std::int64_t data_time_ns = 0;   ///< end time of the newest vibration block pushed
  std::int64_t last_speed_ns = 0;  ///< newest speed sample (latency applied)
  std::int64_t clock_ns = 0;       ///< the alarm manager's time base at publication (data time in fast
                                   ///< replays, the daemon clock otherwise; never goes back)
  std::uint64_t windows = 0, scored = 0, no_class = 0, abnormal = 0, alarm_windows = 0;
  std::uint64_t blocks = 0, samples = 0, speeds = 0;
  std::uint64_t gap_samples = 0;     ///< samples declared missing to the engine (index jumps)
  std::uint64_t index_back = 0;      ///< blocks dropped because their index went backwards
  std::uint64_t blocks_invalid = 0;  ///< blocks whose samples were declared invalid (short read,
                                     ///< device timestamp back or jumping): their windows are discarded
  std::uint64_t time_jumps = 0;      ///< block stamps that jumped against the sample index (> kTimeJumpNs)
  std::uint64_t speeds_before_t0 = 0;
  std::uint64_t pauses = 0;              ///< transitions into a paused phase
  std::uint64_t window_log_dropped = 0;  ///< windows the history ring could not hold (supervisor late)
  std::int64_t max_block_dev_ns = 0;     ///< max |block stamp - (t0 + index / fs)|
  dsp::SlicerCounters slicer;            ///< time domain (all zero in the order domain)
  bool order_domain = false;  ///< [extraction] domain = "order": the counters below, not the slicer's
  dsp::AngleResamplerCounters resampler;  ///< order domain: the angle resampler's counters
  std::uint64_t order_windows_cut = 0;    ///< order domain: windows the OrderWindowCutter completed
  bool have_window = false;
  dsp::WindowResult last_window;  ///< last scored window (times on the daemon clock)
  AlarmState alarm;
  drivers::AlarmReport report;
  AlarmCounters alarm_counters;
  dsp::CoverageState coverage;  ///< judged/unmatched windows, motion since the last judgement
};

/// How the acquisition and CAN threads (or the one thread) schedule their wake-ups at real-time pace
/// (plan_wake()). Fixed at configure() (max_sleep_ns also by set_liveness_period_ns()); next_due_ns is the
/// processing thread's latest publication.
struct WakeSchedule {
  bool follows_windows = false;  ///< time domain, monitoring: wake-ups follow next_close_ns()
  std::int64_t max_sleep_ns = 0;
  std::int64_t spacing_ns = 0;      ///< no window closes sooner than this after the previous one
  std::int64_t acq_offset_ns = 0;   ///< after the due time: the block holding the window's end is complete
  std::int64_t can_offset_ns = 0;   ///< after the due time: the speed frame after that block has arrived
  std::int64_t retry_ns = 0;        ///< a late window: the stages retry this often (one frame period + 1 ms)
  std::int64_t late_window_ns = 0;  ///< ... for at most this long after due + can_offset_ns
  std::int64_t next_due_ns = kNoDue;
  bool late = false;  ///< the due window is still open after the stages served it
  /// Both inputs at real-time pace: the processing thread reads them itself when a window can close
  /// (due + can_offset_ns), and the acquisition and CAN threads are not started (docs/daemon.md).
  bool single_thread = false;
  /// The outputs are handed the verdict at least this often (set at activate()): the CAN frame's period
  /// when the daemon sends each frame, half the kernel timer's lease when the kernel re-sends it.
  std::int64_t output_refresh_ns = 0;
  bool output_kernel_timed = false;  ///< the kernel re-sends the CAN verdict frame ([alarm.can] timer)
};

struct StageHeartbeats {
  std::uint64_t acquisition = 0, can = 0, processing = 0;
};

/// Counters of the acquisition and CAN stages (single writer each: their threads, or the processing
/// thread when it reads both inputs; read by any thread).
struct PipelineCounters {
  std::uint64_t acq_ring_full_blocks = 0, acq_ring_full_samples = 0, acq_read_errors = 0;
  bool acq_end = false;
  std::uint64_t can_frames = 0, can_speed = 0, can_other_id = 0, can_wrong_dlc = 0, can_rtr = 0;
  std::uint64_t can_error_frames = 0, can_ring_full = 0, can_clear_frames = 0, can_receive_errors = 0;
  bool can_end = false;
  std::uint64_t output_errors = 0;
  /// Real-time pace, one thread: sleeps planned one retry step ahead because the due window was still
  /// open after its inputs were read (WakeSchedule::late: a late speed frame or block, a loaded machine).
  std::uint64_t late_waits = 0;
  /// Real-time pace: sleeps cut short to publish work done within kPublishPeriodNs (a pass with work
  /// that came too soon after the previous publication: passes close together, a slow or loaded machine).
  std::uint64_t publish_waits = 0;
};

class Pipeline {
 public:
  /// Copies the configuration. `clock` must outlive the pipeline. Thread: main. Allocates.
  Pipeline(const DaemonConfig& cfg, PipelineMode mode, drivers::Clock& clock);
  ~Pipeline();
  Pipeline(const Pipeline&) = delete;
  Pipeline& operator=(const Pipeline&) = delete;

  /// See the lifecycle above. Throws ptda::Error "what: where". Thread: main. Blocks and allocates.
  void configure();
  /// Activates devices and outputs, starts the threads. Throws ptda::Error (nothing left running).
  /// Thread: main. Spawns threads (allocates).
  void activate();
  /// Stops and joins the threads, outputs fail-safe, devices stopped. Thread: main. Blocks ≤ ~0.1 s.
  void deactivate() noexcept;

  /// Test/tool hook, set before activate(). Thread: main.
  void set_window_sink(WindowSink* sink) noexcept { sink_ = sink; }
  /// Hand every window to the supervisor through the window log ring (the event history). Thread: main,
  /// before activate(), or the supervisor after a reload. Never allocates (the ring is allocated in
  /// configure()).
  void enable_window_log(bool on) noexcept { window_log_on_.store(on, std::memory_order_relaxed); }
  /// The next window for the history, oldest first; false when none. Thread: the supervisor only (the
  /// ring's consumer). Never blocks or allocates.
  bool pop_window_log(dsp::WindowResult& out) noexcept { return window_log_ && window_log_->try_pop(out); }
  /// An eventfd the processing thread writes (non-blocking) after the outputs were set for a new level
  /// change, so the supervisor drains the change ring at once instead of at its next status period.
  /// Thread: main, before activate(). Never allocates.
  void set_wake_fd(int fd) noexcept { wake_fd_ = fd; }
  /// The next alarm level change, oldest first; false when none. Thread: the supervisor only (the
  /// ring's consumer). Never blocks or allocates.
  bool pop_level_change(LevelChange& out) noexcept { return level_ring_ && level_ring_->try_pop(out); }
  /// Test-only hook, set before configure() (see DeviceFactory). Thread: main.
  void set_device_factory(DeviceFactory* f) noexcept { factory_ = f; }
  /// Benchmark hook, set before activate(). Thread: main.
  void set_probe(PipelineProbe* probe) noexcept { probe_ = probe; }
  /// Training mode: the trainer of the pipeline this one replaces (a reload); configure() copies its
  /// pool when compatible (FieldTrainer::take_over; the result in training_carry()). Must stay alive
  /// until configure() returns. Set before configure(). Thread: main.
  void set_previous_trainer(const FieldTrainer* previous) noexcept { previous_trainer_ = previous; }
  /// What configure() kept of the previous trainer (nullopt: none was set). Thread: main.
  [[nodiscard]] const std::optional<TrainingCarryOver>& training_carry() const noexcept { return carry_; }
  /// Hands the field trainer (with its pool) to the caller, e.g. to carry it into the pipeline of a
  /// reload. Only after deactivate() (no thread adds to it then). Thread: main.
  [[nodiscard]] std::unique_ptr<FieldTrainer> release_trainer() noexcept { return std::move(trainer_); }
  /// Test-only fault injection: while true the processing thread stops working and stops beating
  /// (it still honours stop); with one thread the acquisition and CAN heartbeats stop with it. Thread:
  /// any. Never blocks.
  void set_processing_stall(bool stall) noexcept { stall_.store(stall, std::memory_order_relaxed); }
  /// The longest a stage may sleep so that a liveness check sees its heartbeat (e.g. half the
  /// watchdog ping period); 0 = none. Set before configure(). Thread: main.
  void set_liveness_period_ns(std::int64_t ns) noexcept { liveness_ns_ = ns; }
  /// After configure(). Thread: any. Never blocks or allocates.
  [[nodiscard]] WakeSchedule wake_schedule() const noexcept;
  /// Posts an operator clear of a latched alarm. Thread: any. Never blocks or allocates.
  void post_clear() noexcept;

  /// Thread: any. Never blocks (retries a torn read) or allocates.
  [[nodiscard]] PipelineStatus status() const noexcept { return published_.load(); }
  [[nodiscard]] StageHeartbeats heartbeats() const noexcept;
  [[nodiscard]] PipelineCounters counters() const noexcept;
  [[nodiscard]] drivers::SampleSourceCounters source_counters() const noexcept;
  [[nodiscard]] drivers::CanCounters can_counters() const noexcept;
  [[nodiscard]] drivers::CanBusState can_bus_state() const noexcept;

  /// After configure(). Thread: any.
  [[nodiscard]] bool refused() const noexcept { return !refusal_.empty(); }
  /// Why the default-on band detector is off for this baseline and method (empty when it runs or the
  /// configuration switched it off; docs/method.md §6 "Band detector"). Thread: the owner's (configure).
  [[nodiscard]] std::string band_off_reason() const {
    return engine_ ? engine_->band_off_reason() : std::string();
  }
  /// As band_off_reason(), for the default-on mesh detector (docs/method.md §6 "Mesh detector").
  [[nodiscard]] std::string mesh_off_reason() const {
    return engine_ ? engine_->mesh_off_reason() : std::string();
  }
  [[nodiscard]] const std::string& refusal() const noexcept { return refusal_; }
  [[nodiscard]] const dsp::Baseline* baseline() const noexcept { return baseline_.get(); }
  [[nodiscard]] double fs_hz() const noexcept { return fs_hz_; }
  [[nodiscard]] bool fast() const noexcept { return fast_; }
  [[nodiscard]] PipelineMode mode() const noexcept { return mode_; }
  [[nodiscard]] const DaemonConfig& config() const noexcept { return cfg_; }
  /// The field trainer (training mode), else nullptr. Thread: see FieldTrainer.
  [[nodiscard]] const FieldTrainer* trainer() const noexcept { return trainer_.get(); }
  /// Fast replay in training mode: cut windows still wait in the slicer for room in the trainer's
  /// queue (the end of the replay is not reached for training until they are out). Thread: any.
  [[nodiscard]] bool training_backlog() const noexcept {
    return train_backlog_.load(std::memory_order_acquire);
  }
  /// A one-line description of the inputs, e.g. "adc sim (scenario ...), can sim". Thread: any.
  [[nodiscard]] const std::string& inputs_text() const noexcept { return inputs_text_; }
  /// Who re-sends the CAN verdict frame, for the log ("" without one). Thread: main, after activate().
  [[nodiscard]] const std::string& can_timer_text() const noexcept { return can_timer_text_; }
  /// Daemon-clock time that sample 0 of a WAV replay and the start of a candump replay map to; unset
  /// for devices and the simulator. Thread: main, after activate().
  [[nodiscard]] std::optional<std::int64_t> replay_origin_mono_ns() const noexcept {
    return replay_origin_mono_ns_;
  }

 private:
  /// What a WAV recording tells the candump replay of the same recording: its start (the shared
  /// timeline origin) and its CAN log.
  struct RecordingLink {
    std::optional<std::int64_t> start_unix_ns;
    std::filesystem::path can_log;
  };
  // The steps of configure(), in order. Thread: main. Allocate; throw ptda::Error (device, file).
  void make_test_devices();                       ///< DeviceFactory's source and channel
  RecordingLink configure_vibration_source();     ///< [adc] backend; fs_hz_ checked against [acquisition]
  void configure_can(const RecordingLink& link);  ///< [can] backend
  void configure_outputs();                       ///< GPIO / CAN alarm outputs (+ the factory's)
  void configure_monitoring();                    ///< baseline, engine, coverage (or refusal_)
  void configure_order_front();                   ///< order domain: resampler, cutter, frame clock
  void configure_training();                      ///< slicer and FieldTrainer (takes over a previous pool)
  void drain_training() noexcept;                 ///< train slicer -> FieldTrainer (processing thread)
  void configure_alarm_manager();                 ///< AlarmManager (warning, hold, latch)
  void configure_rings_and_timing();              ///< rings, blocks, staleness and hold times, status

  void acquisition_loop() noexcept;
  void can_loop() noexcept;
  /// Reads one block with the given timeout and pushes it (back-pressure for fast sources). Thread:
  /// acquisition (processing, with timeout 0, with WakeSchedule::single_thread).
  drivers::SourceStatus acquire(std::int64_t timeout_ns) noexcept;
  /// Receives one batch of frames with the given timeout and handles them; `received` = frames taken.
  /// Thread: CAN (processing, with timeout 0, with WakeSchedule::single_thread).
  drivers::CanStatus receive_batch(std::int64_t timeout_ns, std::size_t& received) noexcept;
  /// Both inputs at real-time pace (WakeSchedule::single_thread): drains the CAN channel, then reads every
  /// block the source has ready, without waiting, into the rings this same thread consumes. Returns true when
  /// it stopped because a ring is full enough that the caller should process before it reads on. Beats the
  /// acquisition and CAN heartbeats. Thread: processing. Never blocks or allocates.
  bool serve_inputs() noexcept;
  /// Sleeps until plan_wake() with the stage's offset (the stage's one wait; deactivate() rings
  /// `signal` to end it at once). Thread: acquisition or CAN, real-time pace.
  void wait_stage(WakeSignal& signal, std::int64_t offset_ns) noexcept;
  /// Publishes the daemon time the next window can close (next_due_ns_), and whether it is late (the
  /// stages served it and it is still open: due_late_; the stages are rung to retry sooner). Thread:
  /// processing.
  void publish_due(std::int64_t now) noexcept;
  /// How long the processing thread may sleep at real-time pace. Thread: processing.
  [[nodiscard]] std::int64_t processing_wait_ns(std::int64_t now, bool unpublished) const noexcept;
  void processing_loop() noexcept;

  // Processing helpers (processing thread only).
  bool process_step(std::int64_t now) noexcept;
  /// Before the first block (no t0): drops the oldest speed samples down to half the ring, counted in
  /// speeds_before_t0, so a source that never delivers does not stall the CAN stage.
  void prune_speeds_before_t0() noexcept;
  void push_block(const drivers::SampleBlock& b) noexcept;
  void push_speed(const dsp::SpeedSample& s) noexcept;
  void drain_windows(std::int64_t now) noexcept;
  /// One judged window (engine_ stream time): counts, coverage, alarm manager, sink, history.
  void on_judged(dsp::WindowResult& r, std::int64_t now) noexcept;
  /// Order domain: `count` missing or invalid samples go to the resampler as NaN (it breaks the
  /// segment there and keeps the index as its time base), in chunks of order_nan_.
  void order_mark_gap(std::uint64_t count) noexcept;
  void update_phase(std::int64_t now) noexcept;
  void drive_outputs(std::int64_t now, bool force) noexcept;
  bool publish(std::int64_t now, bool force) noexcept;  ///< true when it published
  void finish_streams() noexcept;
  [[nodiscard]] std::int64_t alarm_time(std::int64_t candidate) noexcept;
  [[nodiscard]] std::int64_t sample_time(std::uint64_t index) const noexcept;  ///< stream time of index

  DaemonConfig cfg_;
  PipelineMode mode_;
  drivers::Clock& clock_;
  std::string inputs_text_;

  // Devices and outputs.
  std::shared_ptr<const SimRecording> sim_;
  SimAnchor sim_anchor_;
  std::unique_ptr<drivers::SampleSource> source_;
  std::unique_ptr<drivers::CanChannel> channel_;
  drivers::WavReplaySource* wav_replay_ = nullptr;           ///< source_, when it is a WAV replay
  drivers::CandumpReplayChannel* candump_replay_ = nullptr;  ///< channel_, when it is a candump replay
  drivers::SocketCanChannel* socketcan_ = nullptr;           ///< channel_, when it is SocketCAN
  drivers::CanAlarmOutput* can_output_ = nullptr;            ///< in outputs_, when [alarm.can] is on
  std::string can_timer_text_;
  std::optional<std::int64_t> replay_origin_mono_ns_;
  std::int64_t burst_origin_ns_ = 0;               ///< origin of the wake-up grids (activate())
  std::int64_t liveness_ns_ = 0;                   ///< set_liveness_period_ns()
  WakeSchedule wake_;                              ///< fixed at configure() (next_due_ns: see next_due_ns_)
  std::atomic<std::int64_t> next_due_ns_{kNoDue};  ///< processing -> acquisition, CAN
  std::atomic<bool> due_late_{false};              ///< processing -> acquisition, CAN
  WakeSignal acq_signal_, can_signal_;             ///< rung by deactivate() to end a stage's sleep
  std::vector<std::unique_ptr<drivers::AlarmOutput>> outputs_;
  bool source_fast_ = false, can_fast_ = false, fast_ = false;
  std::int64_t last_serve_ns_ = 0;  ///< when serve_inputs() last ran (processing thread)
  double fs_hz_ = 0.0;
  std::int64_t fs_mhz_ = 0;

  // Monitoring.
  std::string refusal_;
  std::unique_ptr<dsp::Baseline> baseline_;
  std::unique_ptr<dsp::MonitorEngine> engine_;
  std::unique_ptr<dsp::CoverageTracker> coverage_;  ///< with engine_
  // Order domain (set with engine_ when [extraction] domain = "order"; engine_ then judges the cutter's
  // windows on the angle axis and its own slicer stays unused).
  std::unique_ptr<dsp::AngleResampler> order_res_;
  std::unique_ptr<dsp::OrderWindowCutter> order_cut_;
  std::unique_ptr<dsp::FrameClock> order_clock_;  ///< null when can_time_smoothing_frames = 0
  std::vector<float> order_window_;               ///< N = R S samples of the window being judged
  std::vector<float> order_nan_;                  ///< NaN chunk for gaps and invalid blocks
  std::unique_ptr<dsp::WindowSlicer> train_slicer_;
  std::unique_ptr<FieldTrainer> trainer_;
  std::size_t train_block_windows_ = 1;     ///< queue slots a fast replay keeps free before releasing a block
  std::atomic<bool> train_backlog_{false};  ///< fast replay: cut windows wait in the train slicer
  const FieldTrainer* previous_trainer_ = nullptr;
  std::optional<TrainingCarryOver> carry_;
  std::vector<float> train_window_;
  std::unique_ptr<AlarmManager> alarm_;
  WindowSink* sink_ = nullptr;
  std::atomic<bool> window_log_on_{false};  ///< a reload may turn the history on while processing runs
  std::unique_ptr<WindowLogRing> window_log_;
  std::unique_ptr<LevelChangeRing> level_ring_;  ///< every level change, for the supervisor
  int wake_fd_ = -1;                             ///< set_wake_fd()
  std::uint64_t woken_changes_ = 0;              ///< level_change_count() at the last wake
  PipelineProbe* probe_ = nullptr;
  DeviceFactory* factory_ = nullptr;

  // Rings (allocated at configure).
  std::unique_ptr<SampleRing> sample_ring_;
  std::unique_ptr<SpeedRing> speed_ring_;

  // Acquisition stage state (its thread, or processing with one thread).
  std::unique_ptr<drivers::SampleBlock> acq_block_;
  std::atomic<bool> acq_end_{false};
  drivers::Counter acq_ring_full_blocks_, acq_ring_full_samples_, acq_read_errors_;
  std::atomic<std::uint64_t> acq_beat_{0};

  // CAN stage state (its thread, or processing with one thread).
  std::array<CanFrame, kCanBatch> can_frames_{};
  std::atomic<bool> can_end_{false};
  drivers::Counter can_frames_n_, can_speed_, can_other_id_, can_wrong_dlc_, can_rtr_, can_error_frames_,
      can_ring_full_, can_clear_frames_, can_receive_errors_;
  std::atomic<std::uint64_t> can_beat_{0};
  std::int64_t latency_ns_ = 0;

  // Processing thread state.
  std::unique_ptr<drivers::SampleBlock> held_block_;
  bool have_block_ = false;
  dsp::SpeedSample next_speed_{};
  bool have_speed_ = false;
  bool streams_finished_ = false;
  std::uint64_t base_index_ = 0;      ///< first_index of the first block (stream sample 0)
  std::uint64_t expected_index_ = 0;  ///< stream index of the next sample
  bool have_dev_ = false;
  std::int64_t last_dev_ = 0;  ///< previous block's stamp - nominal time
  bool have_any_speed_ = false;
  bool faults_applied_ = false;
  bool ended_applied_ = false;      ///< the alarm manager was told the input ended
  std::int64_t alarm_time_ns_ = 0;  ///< monotone time base of the alarm manager
  std::int64_t last_block_arrival_ns_ = 0;
  std::int64_t hold_ns_ = 0;
  std::int64_t speed_stale_ns_ = 0;
  std::int64_t sensor_stale_ns_ = 0;
  std::int64_t last_publish_ns_ = 0;
  std::int64_t last_output_ns_ = 0;
  std::int64_t output_period_ns_ = 0;  ///< set at activate(): WakeSchedule::output_refresh_ns
  drivers::AlarmLevel last_output_level_ = drivers::AlarmLevel::kFault;
  std::uint8_t last_output_causes_ = 0xFF;
  drivers::AlarmReport last_output_report_{};
  PipelineStatus st_;  ///< the processing thread's working copy of what it publishes
  drivers::Counter output_errors_;
  drivers::Counter late_waits_, publish_waits_;
  std::atomic<std::uint64_t> proc_beat_{0};
  std::atomic<bool> stall_{false};

  Seqlock<PipelineStatus> published_;
  std::atomic<bool> stop_{false};
  WakeSignal
      work_signal_;  ///< rung by the acquisition and CAN threads (and deactivate()), waited on by processing
  std::thread acq_thread_, can_thread_, proc_thread_;
  bool configured_ = false;
  bool active_ = false;
};

}  // namespace ptda::daemon
