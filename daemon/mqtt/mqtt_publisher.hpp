// MQTT publishing with store-and-forward (issue 15 items 1 and 2; docs/fleet.md, "MQTT").
//
//   supervisor (main thread) ──post(MqttEvent)──▶ SpscRing<MqttEvent, 256> ──▶ publisher thread
//                                                  (fixed, lock-free; full = counted drop)
//   publisher thread: alarm/fault/state ─JSON─▶ DiskQueue::append (fsync) ─▶ publish QoS 1, one in flight
//                     ─▶ PUBACK (on_publish, mid) ─▶ DiskQueue::ack; window summaries (rate-limited) ─▶
//                     their own DiskQueue (DIR/summaries, 1/kSummaryShareDiv of queue_max_bytes, oldest
//                     dropped when full, no fsync of its own) ─▶ QoS 1 once the event queue is empty.
//
// The publisher thread is not a real-time thread: it formats JSON (allocates), writes and fsyncs the queue
// and runs libmosquitto's network loop (mosquitto_loop, no extra thread). The real-time threads never see
// it: the supervisor copies what it already reads from the pipeline into fixed-size events.
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>

#include "core/daemon_config.hpp"
#include "mqtt/disk_queue.hpp"
#include "rt/spsc_ring.hpp"
#include "status/status_writer.hpp"

struct mosquitto;
struct mosquitto_message;

namespace ptda::daemon {

/// One event for the broker, trivially copyable (it crosses the SpscRing by memcpy).
struct MqttEvent {
  EventKind kind = EventKind::kState;
  std::int64_t t_mono_ns =
      0;  ///< the window's end (alarm, fault, summary) or the change (state), daemon clock
  std::int64_t t_unix_ns = 0;  ///< the same instant on the wall clock
  FixedString<12> level;       ///< normal, warning, alarm, fault
  FixedString<16> state;       ///< daemon state (running, paused, ...)
  FixedString<24> phase;
  FixedString<64> causes;      ///< "rms+entropy", "none"
  FixedString<16> status;      ///< summary: scored, no_class, ...
  bool have_features = false;  ///< class_id .. bands are valid
  std::int32_t class_id = -1;
  std::uint32_t abnormal_in_last_n = 0;
  double rms_res = 0.0, entropy_res = 0.0;
  double rms_lo = 0.0, rms_hi = 0.0, entropy_lo = 0.0, entropy_hi = 0.0;
  double speed_rad_s = 0.0;           ///< summary
  std::uint64_t window_n = 0;         ///< summary: the window's number
  bool abnormal = false;              ///< summary
  std::int64_t recorded_mono_ns = 0;  ///< alarm/fault: CLOCK_MONOTONIC when the processing thread
                                      ///< recorded the change (0: unknown); the publisher measures
                                      ///< from it to the queue's fsync
};

/// The [mqtt] table resolved for one daemon: the joint and the password filled in.
struct MqttSettings {
  MqttSection cfg;
  std::string joint;            ///< "" = none
  std::string topic_prefix;     ///< cfg.topic_prefix with "{joint}" replaced
  std::string client_id;        ///< cfg.client_id or "ptdad-<joint>" / "ptdad"
  std::string password;         ///< from the credential or password_file ("" = none); never logged
  std::string password_source;  ///< where it came from (for the log): a path or "systemd credential"
};

/// Resolves `cfg` (with the joint from [daemon] joint / --joint): the topic prefix, the client id and the
/// password ($CREDENTIALS_DIRECTORY/mqtt_password when that file exists, else password_file). Throws
/// ptda::Error naming the key and the file. Thread: main. Allocates and reads files.
[[nodiscard]] MqttSettings resolve_mqtt_settings(const MqttSection& cfg, const std::string& joint,
                                                 const char* credentials_directory);

/// The JSON payloads (schema 1). Thread: any. Allocate.
[[nodiscard]] std::string mqtt_event_json(const MqttEvent& e, std::uint64_t seq, std::string_view joint);
[[nodiscard]] std::string mqtt_status_json(const MqttEvent* last_state, bool online, std::uint64_t seq,
                                           std::string_view joint, std::string_view client_id);

class MqttPublisher {
 public:
  static constexpr std::size_t kRingEvents = 256;
  /// The summary queue gets queue_max_bytes / kSummaryShareDiv, the event queue the rest.
  static constexpr std::uint64_t kSummaryShareDiv = 4;

  /// Opens the disk queue (ptda::Error naming the directory), sets up libmosquitto (TLS files are
  /// checked here: ptda::Error naming the key) and starts the publisher thread. Thread: main. Allocates.
  explicit MqttPublisher(MqttSettings s);
  /// Publishes an offline status, disconnects and joins the thread (at most about a second).
  ~MqttPublisher();
  MqttPublisher(const MqttPublisher&) = delete;
  MqttPublisher& operator=(const MqttPublisher&) = delete;

  /// Hands an event to the publisher thread. Thread: one producer (the supervisor). Never blocks or
  /// allocates; false (and counted) when the ring is full.
  bool post(const MqttEvent& e) noexcept;
  /// Thread: any. Never allocates; takes a short mutex for the error text.
  [[nodiscard]] MqttStats stats() const noexcept;
  [[nodiscard]] const MqttSettings& settings() const noexcept { return s_; }

 private:
  void run() noexcept;
  void step(std::int64_t now_ns);
  void handle(const MqttEvent& e, std::int64_t now_ns);
  void try_connect(std::int64_t now_ns);
  /// A hint for a TLS connection the broker closed (client certificate missing or untrusted), or "".
  std::string tls_hint(int rc, int err, const std::string& why) const;
  void send_front();
  void update_queue_stats() noexcept;
  void set_error(std::string_view text, bool log_it);
  void on_connect(int rc);
  void on_disconnect(int rc);
  void on_publish(int mid);
  void on_log(int level, const char* text);
  static void cb_connect(mosquitto*, void*, int);
  static void cb_disconnect(mosquitto*, void*, int);
  static void cb_publish(mosquitto*, void*, int);
  static void cb_log(mosquitto*, void*, int, const char*);
  [[nodiscard]] std::string topic(std::string_view leaf) const {
    return s_.topic_prefix + "/" + std::string(leaf);
  }

  MqttSettings s_;
  std::unique_ptr<DiskQueue> queue_;      ///< alarms, faults, states: one gapless seq
  std::unique_ptr<DiskQueue> summaries_;  ///< window summaries: their own summary_seq
  std::unique_ptr<SpscRing<MqttEvent, kRingEvents>> ring_;
  mosquitto* mosq_ = nullptr;
  std::thread thread_;
  std::atomic<bool> stop_{false};

  // Publisher-thread state.
  bool connected_ = false;
  bool connecting_ = false;
  int inflight_mid_ = -1;
  std::uint64_t inflight_seq_ = 0;
  bool inflight_summary_ = false;  ///< the message in flight came from summaries_
  double backoff_s_ = 0.0;
  std::int64_t next_connect_ns_ = 0;
  std::int64_t next_health_ns_ = 0;
  bool have_state_ = false;
  MqttEvent last_state_;
  std::uint64_t newest_state_seq_ = 0;  ///< only the newest state is published retained
  std::string last_log_error_;          ///< the last libmosquitto error log line (TLS details)

  // Shared with stats().
  std::atomic<bool> connected_flag_{false};
  std::atomic<std::uint64_t> dropped_handoff_{0}, dropped_io_{0}, published_{0}, connect_failures_{0},
      queue_bytes_{0}, queue_pending_{0}, summary_pending_{0}, queue_dropped_summaries_{0},
      queue_dropped_events_{0}, durable_us_last_{0}, durable_us_max_{0};
  mutable std::mutex error_mutex_;
  FixedString<256> last_error_;
};

}  // namespace ptda::daemon
