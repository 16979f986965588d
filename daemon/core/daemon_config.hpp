// ptdad's configuration: the monitoring pipeline (config::PipelineConfig, the same tables and rules as
// `ptda`) plus the daemon's own tables [daemon], [adc], the daemon keys of [can], [alarm] and
// [training], read from one main file and conf.d/*.toml drop-ins in lexical order. Every key is
// documented in config/README.md ("Daemon tables"); commented examples: config/examples/ptdad.toml
// and config/examples/ptdad.d/.
//
// Configure-time only: every function here may be called from any thread (on its own objects),
// allocates, reads files and throws ptda::Error "<file>:<line>:<column>: <what>".
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "ptda/config/pipeline_config.hpp"

namespace ptda::daemon {

enum class AdcBackend : std::uint8_t { kIio = 0, kWav = 1, kSim = 2 };
enum class CanBackend : std::uint8_t { kSocketCan = 0, kCandump = 1, kSim = 2 };
/// How replay and simulator backends release data: at the pace of their timestamps, or as fast as the
/// pipeline takes it (rings then apply back-pressure instead of dropping).
enum class Pace : std::uint8_t { kRealTime = 0, kFast = 1 };

[[nodiscard]] const char* adc_backend_name(AdcBackend b) noexcept;
[[nodiscard]] const char* can_backend_name(CanBackend b) noexcept;
[[nodiscard]] const char* pace_name(Pace p) noexcept;

/// [daemon]
struct DaemonSection {
  std::filesystem::path baseline = "/var/lib/ptda/baseline.bin";
  std::filesystem::path status_dir = "/run/ptda";  ///< status.json goes here ("" = none)
  std::filesystem::path metrics_path;              ///< node_exporter textfile (*.prom); "" = off
  std::string log_level = "info";                  ///< trace, debug, info, warn, error
  /// Name of the monitored joint ("joint4"): "joint" in status.json, the label joint="..." on every
  /// metric. 1-32 of A-Z a-z 0-9 _ . - (it also names MQTT topics and instances). "" = none.
  std::string joint;
  double status_period_s = 1.0;       ///< status file, STATUS= and counter log period
  double speed_stale_periods = 25.0;  ///< no speed for this many frame periods: paused
  double sensor_stale_s = 1.0;        ///< no vibration block for this long: paused
  double stage_stall_s = 2.0;         ///< a stage whose heartbeat stood still this long is stalled
  /// No window judged for this long while the joint moves: phase "not judging", kFault cause coverage.
  double coverage_timeout_s = 60.0;
};

/// A joint name fit for a metric label, an MQTT topic level and a unit instance: 1-32 characters of
/// A-Z a-z 0-9 _ . - ([daemon] joint, ptdad --joint). Thread: any. Never allocates.
[[nodiscard]] bool valid_joint_name(std::string_view name) noexcept;

/// [adc]
struct AdcSection {
  AdcBackend backend = AdcBackend::kSim;
  std::uint32_t block_len = 256;  ///< samples per block (1..1024)
  float scale = 1.0F;             ///< iio: sample = raw code * scale
  // iio
  std::filesystem::path sysfs_dir = "/sys/bus/iio/devices/iio:device0";
  std::filesystem::path device = "/dev/iio:device0";
  std::string channel = "accel_x";
  std::string trigger;
  std::uint32_t buffer_length = 4096;
  std::uint32_t watermark = 0;
  bool timestamp = true;
  // wav (a recording directory) and sim (a scenario)
  std::filesystem::path recording;
  std::filesystem::path scenario;
  std::uint32_t seed = 0;  ///< sim: 0 = the scenario's own seed
  Pace pace = Pace::kRealTime;
  bool loop = true;  ///< sim: start over at the end of the simulated recording
};

/// The frame that clears a latched alarm ([can.clear_frame]).
struct ClearFrameSpec {
  bool enabled = false;
  std::uint32_t id = 0x3A1;
  bool extended = false;
  std::uint8_t len = 1;
  std::array<std::uint8_t, 8> data{0xC1};  ///< payload that must match exactly (first len bytes)
};

/// The daemon's keys of [can] (the pipeline owns speed_latency_s and [can.speed_frame]).
struct CanSection {
  CanBackend backend = CanBackend::kSim;
  std::string interface = "can0";
  std::filesystem::path replay_file;  ///< candump: the log ("" with [adc] wav = the recording's can.log)
  Pace pace = Pace::kRealTime;
  bool bus_error_frames = false;
  std::uint32_t rcvbuf_bytes = 0;
  ClearFrameSpec clear_frame;
};

/// [alarm], [alarm.gpio], [alarm.can]
struct AlarmSection {
  double min_hold_s = 10.0;
  bool latch = true;
  bool warning = true;
  std::uint32_t warning_k = 1;
  double warning_hold_s = 0.0;
  bool gpio_enabled = false;
  std::string gpio_chip = "/dev/gpiochip0";
  std::uint32_t gpio_line = 0;
  bool gpio_active_low = false;
  bool can_enabled = false;
  std::uint32_t can_id = 0x3A0;
  bool can_extended = false;
  double can_period_s = 0.1;  ///< the verdict frame is re-sent at least this often
  /// Who re-sends an unchanged verdict frame: the kernel's broadcast manager where the CAN channel has
  /// one ("auto": SocketCAN with CAN_BCM, a real-time candump replay), else the daemon ("daemon").
  bool can_kernel_timer = true;
  double can_lease_s = 0.5;  ///< kernel timer: the frames stop this long after the daemon's last renewal
};

/// [training] (field training mode, `ptdad --train`)
struct TrainingSection {
  std::uint32_t target_cycles = 20;  ///< windows per segment class before the baseline is written
  double max_duration_s = 3600.0;    ///< training gives up after this long
  std::filesystem::path output;      ///< baseline written here ("" = [daemon] baseline)
  std::uint32_t max_windows = 4096;  ///< windows kept at most (on disk: max_windows x window_len floats)
  std::uint32_t max_regions = 4096;
  std::filesystem::path spill_dir;  ///< the windows' spill file ("" = the baseline's directory)
};

/// [history]: the event history on the cabinet (docs/fleet.md, "Event history").
struct HistorySection {
  std::filesystem::path dir;   ///< history.jsonl and its rotations ("" = no history)
  double max_file_mib = 16.0;  ///< a file is rotated before it passes this size
  std::uint32_t files = 8;     ///< history.jsonl + files - 1 rotations: the bound is files x size
};

/// [mqtt]: publishing to a broker with store-and-forward (docs/fleet.md, "MQTT").
struct MqttSection {
  bool enabled = false;
  std::string host = "localhost";
  std::uint32_t port = 1883;
  std::string client_id;     ///< "" = "ptdad-<joint>" or "ptdad"
  std::string topic_prefix;  ///< required when enabled; "{joint}" is replaced by the joint name
  std::uint32_t keepalive_s = 30;
  std::filesystem::path tls_ca_file;    ///< set: TLS, the broker's certificate checked against this CA
  std::filesystem::path tls_cert_file;  ///< client certificate (with tls_key_file)
  std::filesystem::path tls_key_file;
  std::string username;
  std::filesystem::path password_file;           ///< first line; $CREDENTIALS_DIRECTORY/mqtt_password wins
  std::filesystem::path queue_dir;               ///< store-and-forward queue (required when enabled)
  std::uint64_t queue_max_bytes = 32ULL << 20U;  ///< 32 MiB: 3/4 for events (24 h of a level and a state
                                                 ///< change every 2 s), 1/4 for summaries (docs/fleet.md)
  double window_summary_interval_s = 10.0;       ///< at most one window summary per this (0 = none)
  double reconnect_min_s = 1.0;
  double reconnect_max_s = 60.0;
  bool operator==(const MqttSection&) const = default;
};

struct DaemonConfig {
  config::PipelineConfig pipeline;
  DaemonSection daemon;
  AdcSection adc;
  CanSection can;
  AlarmSection alarm;
  TrainingSection training;
  HistorySection history;
  MqttSection mqtt;
  std::vector<std::filesystem::path> files;  ///< the files read, in order (main first)
};

/// Tables and keys of the shared files that belong to the daemon (passed to the pipeline parser as
/// ignored_tables). Thread: any. Allocates.
[[nodiscard]] std::vector<std::string> daemon_owned_tables();

/// The drop-ins of conf_dir: its regular files ending in ".toml", in lexical (byte) order. A missing
/// directory yields none; an unreadable one throws. Thread: any. Allocates, reads the directory.
[[nodiscard]] std::vector<std::filesystem::path> list_dropins(const std::filesystem::path& conf_dir);

/// Reads main_file and then each drop-in in order (later keys override earlier ones key by key) and
/// validates the result: unknown keys, wrong types, out-of-range values and inconsistent combinations
/// are errors "<file>:<line>:<column>: <what>". Relative paths in a file are relative to that file's
/// directory. Does not open devices, recordings or the baseline. Thread: any. Allocates, reads files.
[[nodiscard]] DaemonConfig load_daemon_config(const std::filesystem::path& main_file,
                                              const std::vector<std::filesystem::path>& dropins = {});

/// Where field training spills its windows: [training] spill_dir, else the directory of the baseline
/// it will write ([training] output, else [daemon] baseline). Thread: any. Allocates.
[[nodiscard]] std::filesystem::path training_spill_dir(const DaemonConfig& cfg);

/// What `ptdad --check-config` adds to the syntax check: opens every path the configuration names and
/// returns one sentence per problem (empty = ready to run). Monitoring (train = false): the baseline
/// must read (formats::read_baseline) and fit [extraction] window_len and [acquisition] fs_hz; field
/// training (train = true): the directory the baseline will be written to must exist. [adc] wav: the
/// recording directory and its WAV; [can] candump: the log; [adc] sim: the scenario parses; [adc] iio:
/// the sysfs directory and the device node exist. Thread: any. Allocates, reads files (blocks).
[[nodiscard]] std::vector<std::string> check_config_paths(const DaemonConfig& cfg, bool train);

/// As load_daemon_config() for TOML text (tests); `source` names it and relative paths are relative
/// to the current directory. Thread: any. Allocates.
[[nodiscard]] DaemonConfig parse_daemon_config(std::string_view toml_text, const std::string& source);

}  // namespace ptda::daemon
