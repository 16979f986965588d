// mqtt_load_bench: the broker load of a plant (issue 15 item 6, docs/fleet.md "Broker load").
// Opens --joints MQTT connections to a broker, one per joint, each publishing what one ptdad publishes
// with [mqtt] defaults (docs/fleet.md "Topics"): a window summary and a health message every
// --summary-s (QoS 0), and a level change (alarm event + retained status, QoS 1) every --change-s, with
// the real payloads of daemon/mqtt/mqtt_publisher.cpp. One extra client subscribes to `ptda/#` as a
// plant-wide dashboard would. Runs --seconds, then prints the messages sent and received and the
// bytes. The broker's CPU time and RSS are read by scripts/bench_mqtt.sh from /proc around this run.
//
// Usage: mqtt_load_bench --port P [--joints 500] [--seconds 60] [--summary-s 10] [--change-s 60]
// Thread: main + libmosquitto's network thread per connection (mosquitto_loop_start). Allocates.
#include <mosquitto.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

#include "mqtt/mqtt_publisher.hpp"

namespace {

using Clock = std::chrono::steady_clock;

std::atomic<std::uint64_t> g_received{0};
std::atomic<std::uint64_t> g_received_bytes{0};
std::atomic<std::uint64_t> g_received_qos1{0};  ///< alarm and status messages (published at QoS 1)
std::atomic<std::uint64_t> g_received_health{0};

double arg_or(int argc, char** argv, const char* name, double def) {
  for (int i = 1; i + 1 < argc; ++i) {
    if (std::strcmp(argv[i], name) == 0) return std::atof(argv[i + 1]);
  }
  return def;
}

ptda::daemon::MqttEvent event(ptda::daemon::EventKind kind, const char* level, std::int64_t t_ns) {
  ptda::daemon::MqttEvent e;
  e.kind = kind;
  e.t_mono_ns = t_ns;
  e.t_unix_ns = 1'795'000'000'000'000'000LL + t_ns;
  e.level.assign(level);
  e.state.assign("running");
  e.phase.assign("monitoring");
  e.causes.assign("rms+entropy");
  e.status.assign("scored");
  e.have_features = true;
  e.class_id = 0;
  e.abnormal_in_last_n = 1;
  e.rms_res = 0.484238948;
  e.entropy_res = 0.662522068;
  e.rms_lo = 0.250158713;
  e.rms_hi = 0.276894542;
  e.entropy_lo = 0.902363466;
  e.entropy_hi = 0.917436074;
  e.speed_rad_s = 3.49046906;
  e.window_n = 12345;
  e.abnormal = true;
  return e;
}

}  // namespace

int main(int argc, char** argv) {
  const int port = static_cast<int>(arg_or(argc, argv, "--port", 0));
  const int joints = static_cast<int>(arg_or(argc, argv, "--joints", 500));
  const double seconds = arg_or(argc, argv, "--seconds", 60);
  const double summary_s = arg_or(argc, argv, "--summary-s", 10);
  const double change_s = arg_or(argc, argv, "--change-s", 60);
  // libmosquitto's loop uses select(): a descriptor >= FD_SETSIZE (1024) is never served, and each
  // connection takes 3 (socket + wake-up pair), so one process holds at most ~330 joints. The script runs
  // several processes (--first: the first joint's index) and one dashboard (--dashboard 1).
  const int first = static_cast<int>(arg_or(argc, argv, "--first", 0));
  const bool dashboard = arg_or(argc, argv, "--dashboard", 1) != 0.0;
  if (port <= 0 || joints <= 0 || joints > 300 || first < 0 || !(seconds > 0) || !(summary_s > 0) ||
      !(change_s > 0)) {
    std::fprintf(
        stderr,
        "usage: mqtt_load_bench --port P [--joints N<=300] [--first J] [--dashboard 0|1] [--seconds S] "
        "[--summary-s S] [--change-s S]\n");
    return 2;
  }
  mosquitto_lib_init();
  // The dashboard: every message of every joint.
  mosquitto* sub = mosquitto_new("bench-dashboard", true, nullptr);
  mosquitto_message_callback_set(sub, [](mosquitto*, void*, const mosquitto_message* m) {
    g_received.fetch_add(1, std::memory_order_relaxed);
    g_received_bytes.fetch_add(static_cast<std::uint64_t>(m->payloadlen), std::memory_order_relaxed);
    if (m->qos == 1) g_received_qos1.fetch_add(1, std::memory_order_relaxed);
    const std::size_t len = std::strlen(m->topic);
    if (len > 7 && std::strcmp(m->topic + len - 7, "/health") == 0) g_received_health.fetch_add(1);
  });
  if (dashboard && (mosquitto_connect(sub, "127.0.0.1", port, 60) != MOSQ_ERR_SUCCESS ||
                    mosquitto_subscribe(sub, nullptr, "ptda/#", 1) != MOSQ_ERR_SUCCESS ||
                    mosquitto_loop_start(sub) != MOSQ_ERR_SUCCESS)) {
    std::fprintf(stderr, "mqtt_load_bench: cannot connect the subscriber to 127.0.0.1:%d\n", port);
    return 1;
  }
  std::vector<mosquitto*> clients;
  std::vector<std::string> prefix;
  for (int j = 0; j < joints; ++j) {
    const int g = first + j;  // the joint's index in the plant
    const std::string id = "bench-joint" + std::to_string(g);
    mosquitto* m = mosquitto_new(id.c_str(), true, nullptr);
    prefix.push_back("ptda/plant1/cell" + std::to_string(g / 6) + "/robot" + std::to_string(g / 6) +
                     "/joint" + std::to_string(g % 6 + 1));
    const std::string will = ptda::daemon::mqtt_status_json(nullptr, false, 0, "joint", id);
    mosquitto_will_set(m, (prefix.back() + "/status").c_str(), static_cast<int>(will.size()), will.data(), 1,
                       true);
    if (mosquitto_connect(m, "127.0.0.1", port, 60) != MOSQ_ERR_SUCCESS ||
        mosquitto_loop_start(m) != MOSQ_ERR_SUCCESS) {
      std::fprintf(stderr, "mqtt_load_bench: connection %d failed (file descriptors? ulimit -n)\n", j);
      return 1;
    }
    clients.push_back(m);
  }
  std::this_thread::sleep_for(std::chrono::seconds(1));
  std::uint64_t sent = 0, sent_bytes = 0, sent_qos1 = 0;
  auto pub = [&](int j, const char* leaf, const std::string& payload, int qos, bool retain) {
    if (mosquitto_publish(clients[static_cast<std::size_t>(j)], nullptr,
                          (prefix[static_cast<std::size_t>(j)] + leaf).c_str(),
                          static_cast<int>(payload.size()), payload.data(), qos,
                          retain) == MOSQ_ERR_SUCCESS) {
      ++sent;
      sent_bytes += payload.size();
      if (qos == 1) ++sent_qos1;
    }
  };
  // Joint j's schedule is offset by j / joints of a period, so the load is spread as in a plant.
  const auto start = Clock::now();
  std::vector<double> next_summary(static_cast<std::size_t>(joints)),
      next_change(static_cast<std::size_t>(joints));
  for (int j = 0; j < joints; ++j) {
    next_summary[static_cast<std::size_t>(j)] = summary_s * j / joints;
    next_change[static_cast<std::size_t>(j)] = change_s * j / joints;
  }
  std::uint64_t seq = 0;
  bool alarm = false;
  for (;;) {
    const double t = std::chrono::duration<double>(Clock::now() - start).count();
    if (t >= seconds) break;
    const auto t_ns = static_cast<std::int64_t>(t * 1e9);
    for (int j = 0; j < joints; ++j) {
      const auto ju = static_cast<std::size_t>(j);
      if (t >= next_summary[ju]) {
        next_summary[ju] += summary_s;
        pub(j, "/window",
            ptda::daemon::mqtt_event_json(event(ptda::daemon::EventKind::kSummary, "alarm", t_ns), 0,
                                          "joint"),
            0, false);
        pub(j, "/health", std::string(158, ' ').replace(0, 12, "{\"schema\":1}"), 0, false);
      }
      if (t >= next_change[ju]) {
        next_change[ju] += change_s;
        alarm = !alarm;
        const auto e = event(ptda::daemon::EventKind::kAlarm, alarm ? "alarm" : "normal", t_ns);
        pub(j, "/alarm", ptda::daemon::mqtt_event_json(e, ++seq, "joint"), 1, false);
        auto s = event(ptda::daemon::EventKind::kState, alarm ? "alarm" : "normal", t_ns);
        pub(j, "/status", ptda::daemon::mqtt_status_json(&s, true, ++seq, "joint", "bench"), 1, true);
      }
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  // Let the last messages arrive: until all are in, or nothing arrived for 3 s.
  const auto drain_start = Clock::now();
  std::uint64_t seen = g_received.load();
  auto last_progress = Clock::now();
  // (The dashboard also counts the other processes' messages: it waits for quiet, not for a count.)
  while (dashboard && Clock::now() - last_progress < std::chrono::seconds(3)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    if (g_received.load() != seen) {
      seen = g_received.load();
      last_progress = Clock::now();
    }
  }
  const double drain_s = std::chrono::duration<double>(Clock::now() - drain_start).count();
  const std::uint64_t received = g_received.load();  // a fresh broker per run: nothing retained before
  std::printf(
      "joints=%d seconds=%.0f sent=%llu sent_qos1=%llu sent_bytes=%llu received=%llu received_qos1=%llu "
      "received_health=%llu received_bytes=%llu "
      "msg_per_s=%.1f bytes_per_s=%.0f drain_s=%.1f\n",
      joints, seconds, static_cast<unsigned long long>(sent), static_cast<unsigned long long>(sent_qos1),
      static_cast<unsigned long long>(sent_bytes), static_cast<unsigned long long>(received),
      static_cast<unsigned long long>(g_received_qos1.load()),
      static_cast<unsigned long long>(g_received_health.load()),
      static_cast<unsigned long long>(g_received_bytes.load()), static_cast<double>(sent) / seconds,
      static_cast<double>(sent_bytes) / seconds, drain_s);
  for (mosquitto* m : clients) {
    mosquitto_disconnect(m);
    mosquitto_loop_stop(m, false);
    mosquitto_destroy(m);
  }
  if (dashboard) {
    mosquitto_disconnect(sub);
    mosquitto_loop_stop(sub, false);
  }
  mosquitto_destroy(sub);
  mosquitto_lib_cleanup();
  return 0;
}
