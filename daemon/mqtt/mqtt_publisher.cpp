#include "mqtt/mqtt_publisher.hpp"

#include <mosquitto.h>
#include <pthread.h>
#include <spdlog/spdlog.h>
#include <time.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <fstream>
#include <system_error>

#include "ptda/common/error.hpp"

namespace ptda::daemon {

namespace fs = std::filesystem;

namespace {

constexpr int kSchema = 1;
constexpr std::int64_t kFlushNs = 2'000'000'000;  // at a stop, how long the queue may take to drain

std::int64_t steady_ns() noexcept {
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

std::string read_password(const fs::path& p, const std::string& key) {
  std::ifstream in(p, std::ios::binary);
  if (!in) throw Error(key + " " + p.string() + ": cannot read: " + std::strerror(errno));
  std::string line;
  std::getline(in, line);
  if (!line.empty() && line.back() == '\r') line.pop_back();
  if (line.empty()) throw Error(key + " " + p.string() + ": the first line (the password) is empty");
  return line;
}

void check_readable(const fs::path& p, const char* key) {
  if (p.empty()) return;
  std::ifstream in(p);
  if (!in)
    throw Error(std::string("[mqtt] ") + key + " " + p.string() + ": cannot read: " + std::strerror(errno));
}

struct Json {
  std::string out;
  bool first = true;
  void key(std::string_view k) {
    if (!first) out += ',';
    first = false;
    str_lit(k);
    out += ':';
  }
  void str_lit(std::string_view v) {
    char buf[512];
    TextBuffer b(buf, sizeof buf);
    b.append_json_string(v);
    out.append(b.view());
  }
  void str(std::string_view k, std::string_view v) {
    key(k);
    str_lit(v);
  }
  void num(std::string_view k, double v) {
    key(k);
    char buf[40];
    TextBuffer b(buf, sizeof buf);
    b.append_double(v, "null");
    out.append(b.view());
  }
  void u64(std::string_view k, std::uint64_t v) {
    key(k);
    out += std::to_string(v);
  }
  void i64(std::string_view k, std::int64_t v) {
    key(k);
    out += std::to_string(v);
  }
  void boolean(std::string_view k, bool v) {
    key(k);
    out += v ? "true" : "false";
  }
  void secs(std::string_view k, std::int64_t ns) {
    key(k);
    char buf[40];
    TextBuffer b(buf, sizeof buf);
    append_seconds(b, static_cast<double>(ns) * 1e-9);
    out.append(b.view());
  }
  void utc(std::string_view k, std::int64_t unix_ns) {
    char buf[32];
    const std::size_t n = format_rfc3339_utc(unix_ns, buf, sizeof buf);
    if (n == 0) {
      key(k);
      out += "null";
    } else {
      str(k, std::string_view(buf, n));
    }
  }
  void band(std::string_view k, double lo, double hi) {
    key(k);
    char buf[80];
    TextBuffer b(buf, sizeof buf);
    b.append_char('[');
    b.append_double(lo, "null");
    b.append_char(',');
    b.append_double(hi, "null");
    b.append_char(']');
    out.append(b.view());
  }
};

}  // namespace

MqttSettings resolve_mqtt_settings(const MqttSection& cfg, const std::string& joint,
                                   const char* credentials_directory) {
  MqttSettings s;
  s.cfg = cfg;
  s.joint = joint;
  s.topic_prefix = cfg.topic_prefix;
  const std::string_view ph = "{joint}";
  for (std::size_t at = s.topic_prefix.find(ph); at != std::string::npos; at = s.topic_prefix.find(ph)) {
    if (joint.empty()) {
      throw Error("[mqtt] topic_prefix \"" + cfg.topic_prefix +
                  "\" uses {joint} but no joint is set ([daemon] joint or ptdad --joint)");
    }
    s.topic_prefix.replace(at, ph.size(), joint);
  }
  s.client_id = !cfg.client_id.empty() ? cfg.client_id : (joint.empty() ? "ptdad" : "ptdad-" + joint);
  if (credentials_directory != nullptr && credentials_directory[0] != '\0') {
    const fs::path cred = fs::path(credentials_directory) / "mqtt_password";
    std::error_code ec;
    if (fs::exists(cred, ec)) {
      if (cfg.username.empty())
        throw Error("[mqtt] the systemd credential mqtt_password needs mqtt.username");
      s.password = read_password(cred, "systemd credential");
      s.password_source = "systemd credential mqtt_password";
    }
  }
  if (s.password.empty() && !cfg.password_file.empty()) {
    s.password = read_password(cfg.password_file, "[mqtt] password_file");
    s.password_source = cfg.password_file.string();
  }
  check_readable(cfg.tls_ca_file, "tls_ca_file");
  check_readable(cfg.tls_cert_file, "tls_cert_file");
  check_readable(cfg.tls_key_file, "tls_key_file");
  return s;
}

std::string mqtt_event_json(const MqttEvent& e, std::uint64_t seq, std::string_view joint) {
  Json j;
  j.out.reserve(512);
  j.out += '{';
  j.i64("schema", kSchema);
  j.str("type", event_kind_name(e.kind));
  if (!joint.empty()) j.str("joint", joint);
  // Summaries are numbered by their own queue: the alarm/fault/state `seq` stays gapless.
  if (seq > 0) j.u64(e.kind == EventKind::kSummary ? "summary_seq" : "seq", seq);
  j.secs("t_mono_s", e.t_mono_ns);
  j.utc("t_utc", e.t_unix_ns);
  if (e.kind == EventKind::kSummary) {
    j.u64("n", e.window_n);
    j.str("status", e.status.view());
    j.num("speed_rad_s", e.speed_rad_s);
  } else {
    j.str("level", e.level.view());
    j.str("causes", e.causes.view());
  }
  if (e.kind == EventKind::kState) {
    j.str("state", e.state.view());
    j.str("phase", e.phase.view());
  }
  if (e.kind != EventKind::kState) {
    if (e.have_features) {
      j.i64("class", e.class_id);
      j.num("rms_res", e.rms_res);
      j.num("entropy_res", e.entropy_res);
      j.band("rms_band", e.rms_lo, e.rms_hi);
      j.band("entropy_band", e.entropy_lo, e.entropy_hi);
      if (e.kind == EventKind::kSummary) {
        j.boolean("abnormal", e.abnormal);
      } else {
        j.u64("abnormal_in_last_n", e.abnormal_in_last_n);
      }
    } else {
      j.key("class");
      j.out += "null";
    }
  }
  j.out += '}';
  return j.out;
}

std::string mqtt_status_json(const MqttEvent* last_state, bool online, std::uint64_t seq,
                             std::string_view joint, std::string_view client_id) {
  Json j;
  j.out += '{';
  j.i64("schema", kSchema);
  j.boolean("online", online);
  if (!joint.empty()) j.str("joint", joint);
  j.str("client_id", client_id);
  if (seq > 0) j.u64("seq", seq);
  if (last_state != nullptr) {
    j.secs("t_mono_s", last_state->t_mono_ns);
    j.utc("t_utc", last_state->t_unix_ns);
    j.str("state", last_state->state.view());
    j.str("phase", last_state->phase.view());
    j.str("level", last_state->level.view());
    j.str("causes", last_state->causes.view());
  }
  j.out += '}';
  return j.out;
}

// ---------------------------------------------------------------------------------------------------

MqttPublisher::MqttPublisher(MqttSettings s) : s_(std::move(s)) {
  static const int init = [] { return mosquitto_lib_init(); }();
  if (init != MOSQ_ERR_SUCCESS) throw Error("[mqtt] libmosquitto initialisation failed");
  DiskQueueConfig qc;
  qc.dir = s_.cfg.queue_dir;
  qc.max_bytes = s_.cfg.queue_max_bytes;
  qc.segment_bytes = std::min<std::uint64_t>(1ULL << 20U, std::max<std::uint64_t>(qc.max_bytes / 8, 4096));
  // The summaries have their own queue (DIR/summaries, a quarter of queue_max_bytes): when it is full
  // its oldest summaries go, and an alarm never competes with them for room.
  DiskQueueConfig sc = qc;
  sc.dir = s_.cfg.queue_dir / "summaries";
  sc.max_bytes = qc.max_bytes / kSummaryShareDiv;
  sc.segment_bytes = std::min<std::uint64_t>(1ULL << 20U, std::max<std::uint64_t>(sc.max_bytes / 8, 4096));
  qc.max_bytes -= sc.max_bytes;
  qc.segment_bytes = std::min<std::uint64_t>(1ULL << 20U, std::max<std::uint64_t>(qc.max_bytes / 8, 4096));
  queue_ = std::make_unique<DiskQueue>(qc);
  summaries_ = std::make_unique<DiskQueue>(sc);
  ring_ = std::make_unique<SpscRing<MqttEvent, kRingEvents>>();
  mosq_ = mosquitto_new(s_.client_id.c_str(), true, this);
  if (mosq_ == nullptr) throw Error("[mqtt] mosquitto_new failed: " + std::string(std::strerror(errno)));
  const auto fail = [&](const std::string& what, int rc) {
    mosquitto_destroy(mosq_);
    mosq_ = nullptr;
    throw Error("[mqtt] " + what + ": " + mosquitto_strerror(rc));
  };
  mosquitto_int_option(mosq_, MOSQ_OPT_PROTOCOL_VERSION, MQTT_PROTOCOL_V311);
  if (!s_.cfg.username.empty()) {
    const int rc = mosquitto_username_pw_set(mosq_, s_.cfg.username.c_str(),
                                             s_.password.empty() ? nullptr : s_.password.c_str());
    if (rc != MOSQ_ERR_SUCCESS) fail("username", rc);
  }
  if (!s_.cfg.tls_ca_file.empty()) {
    const int rc =
        mosquitto_tls_set(mosq_, s_.cfg.tls_ca_file.c_str(), nullptr,
                          s_.cfg.tls_cert_file.empty() ? nullptr : s_.cfg.tls_cert_file.c_str(),
                          s_.cfg.tls_key_file.empty() ? nullptr : s_.cfg.tls_key_file.c_str(), nullptr);
    if (rc != MOSQ_ERR_SUCCESS) fail("tls_ca_file/tls_cert_file/tls_key_file", rc);
  }
  const std::string will = mqtt_status_json(nullptr, false, 0, s_.joint, s_.client_id);
  const std::string will_topic = topic("status");
  int rc = mosquitto_will_set(mosq_, will_topic.c_str(), static_cast<int>(will.size()), will.data(), 1, true);
  if (rc != MOSQ_ERR_SUCCESS) fail("last will on " + will_topic, rc);
  mosquitto_connect_callback_set(mosq_, &MqttPublisher::cb_connect);
  mosquitto_disconnect_callback_set(mosq_, &MqttPublisher::cb_disconnect);
  mosquitto_publish_callback_set(mosq_, &MqttPublisher::cb_publish);
  mosquitto_log_callback_set(mosq_, &MqttPublisher::cb_log);
  update_queue_stats();
  spdlog::info(
      "mqtt: broker {}:{} as {}, topics {}/..., {}{}; queue {} ({} pending event(s), {} summaries)",
      s_.cfg.host, s_.cfg.port, s_.client_id, s_.topic_prefix, s_.cfg.tls_ca_file.empty() ? "no TLS" : "TLS",
      s_.cfg.username.empty() ? std::string()
                              : ", user " + s_.cfg.username +
                                    (s_.password.empty() ? "" : ", password from " + s_.password_source),
      s_.cfg.queue_dir.string(), queue_->pending(), summaries_->pending());
  thread_ = std::thread([this] { run(); });
}

MqttPublisher::~MqttPublisher() {
  stop_.store(true);
  if (thread_.joinable()) thread_.join();
  if (mosq_ != nullptr) mosquitto_destroy(mosq_);
}

bool MqttPublisher::post(const MqttEvent& e) noexcept {
  if (ring_->try_push(e)) return true;
  dropped_handoff_.fetch_add(1, std::memory_order_relaxed);
  return false;
}

MqttStats MqttPublisher::stats() const noexcept {
  MqttStats st;
  st.enabled = true;
  st.connected = connected_flag_.load(std::memory_order_relaxed);
  st.queue_bytes = queue_bytes_.load(std::memory_order_relaxed);
  st.queue_pending = queue_pending_.load(std::memory_order_relaxed);
  st.summary_queue_pending = summary_pending_.load(std::memory_order_relaxed);
  st.dropped_event = queue_dropped_events_.load(std::memory_order_relaxed);
  st.dropped_summary = queue_dropped_summaries_.load(std::memory_order_relaxed);
  st.dropped_handoff = dropped_handoff_.load(std::memory_order_relaxed);
  st.dropped_io = dropped_io_.load(std::memory_order_relaxed);
  st.published = published_.load(std::memory_order_relaxed);
  st.alarm_durable_us_last = durable_us_last_.load(std::memory_order_relaxed);
  st.alarm_durable_us_max = durable_us_max_.load(std::memory_order_relaxed);
  st.connect_failures = connect_failures_.load(std::memory_order_relaxed);
  std::lock_guard lock(error_mutex_);
  st.last_error = last_error_;
  return st;
}

void MqttPublisher::set_error(std::string_view text, bool log_it) {
  {
    std::lock_guard lock(error_mutex_);
    if (text == last_error_.view()) return;  // logged once per distinct error
    last_error_.assign(text);
  }
  if (log_it && !text.empty()) spdlog::error("mqtt: {}", text);
}

void MqttPublisher::run() noexcept {
  // Named first (before anything allocates): tests/support/alloc_counter.cpp leaves this thread out.
  pthread_setname_np(pthread_self(), "ptda-mqtt");
  std::int64_t now = steady_ns();
  next_connect_ns_ = now;
  while (!stop_.load(std::memory_order_acquire)) {
    now = steady_ns();
    try {
      step(now);
    } catch (const std::exception& e) {
      set_error(e.what(), true);
    }
    if (!connected_ && !connecting_) {
      timespec ts{0, 20'000'000};
      ::nanosleep(&ts, nullptr);
    }
  }
  // Stop: every event still in the ring goes into the queue (delivered after the restart if not now);
  // while connected, the queue gets up to kFlushNs to drain.
  MqttEvent e;
  while (ring_->try_pop(e)) {
    try {
      handle(e, now);
    } catch (const std::exception& ex) {
      set_error(ex.what(), true);
    }
  }
  const std::int64_t flush_end = steady_ns() + kFlushNs;
  while (connected_ && queue_->pending() + summaries_->pending() > 0 && steady_ns() < flush_end) {
    if (inflight_mid_ < 0) send_front();
    if (mosquitto_loop(mosq_, 20, 1) != MOSQ_ERR_SUCCESS) break;
  }
  if (queue_->pending() + summaries_->pending() > 0) {
    spdlog::info("mqtt: {} event(s) and {} summaries stay queued for the next start", queue_->pending(),
                 summaries_->pending());
  }
  // Graceful stop: the retained status says offline (a clean disconnect does not send the will).
  if (connected_) {
    const std::string off =
        mqtt_status_json(have_state_ ? &last_state_ : nullptr, false, 0, s_.joint, s_.client_id);
    int mid = 0;
    if (mosquitto_publish(mosq_, &mid, topic("status").c_str(), static_cast<int>(off.size()), off.data(), 1,
                          true) == MOSQ_ERR_SUCCESS) {
      for (int i = 0; i < 20 && connected_; ++i) mosquitto_loop(mosq_, 20, 1);
    }
    mosquitto_disconnect(mosq_);
    mosquitto_loop(mosq_, 20, 1);
  }
}

void MqttPublisher::step(std::int64_t now_ns) {
  MqttEvent e;
  int handled = 0;
  while (handled < 64 && ring_->try_pop(e)) {
    handle(e, now_ns);
    ++handled;
  }
  if (connecting_ && now_ns >= next_connect_ns_) on_disconnect(MOSQ_ERR_CONN_LOST);  // connect timed out
  if (!connected_ && !connecting_ && now_ns >= next_connect_ns_) try_connect(now_ns);
  if (connected_ && inflight_mid_ < 0) send_front();
  if (connected_ || connecting_) {
    const int rc = mosquitto_loop(mosq_, handled > 0 ? 0 : 20, 1);
    if (rc != MOSQ_ERR_SUCCESS && (connected_ || connecting_)) {
      // The connection broke (or the TLS handshake failed): the callback may not have run.
      on_disconnect(rc);
    }
  }
  if (connected_ && s_.cfg.window_summary_interval_s > 0.0 && now_ns >= next_health_ns_) {
    next_health_ns_ =
        now_ns + static_cast<std::int64_t>(std::max(10.0, s_.cfg.window_summary_interval_s) * 1e9);
    Json j;
    j.out += '{';
    j.i64("schema", kSchema);
    if (!s_.joint.empty()) j.str("joint", s_.joint);
    const MqttStats st = stats();
    j.u64("queue_bytes", st.queue_bytes);
    j.u64("queue_pending", st.queue_pending);
    j.u64("summary_queue_pending", st.summary_queue_pending);
    j.u64("published", st.published);
    j.u64("connect_failures", st.connect_failures);
    j.u64("dropped_event", st.dropped_event);
    j.u64("dropped_summary", st.dropped_summary);
    j.u64("dropped_handoff", st.dropped_handoff);
    j.out += '}';
    (void)mosquitto_publish(mosq_, nullptr, topic("health").c_str(), static_cast<int>(j.out.size()),
                            j.out.data(), 0, false);
  }
}

void MqttPublisher::handle(const MqttEvent& e, std::int64_t /*now_ns*/) {
  DiskQueue& q = e.kind == EventKind::kSummary ? *summaries_ : *queue_;
  const std::uint64_t seq = q.next_seq();
  const std::string payload = mqtt_event_json(e, seq, s_.joint);
  try {
    // A summary's append may first drop the oldest summaries (counted); it never fails for room.
    const std::uint64_t got = q.append(e.kind, payload);
    // 0: a summary larger than its whole queue (dropped and counted by the queue).
    if (got != seq && !(got == 0 && e.kind == EventKind::kSummary))
      set_error("internal: queue sequence mismatch", true);
  } catch (const Error& err) {
    dropped_io_.fetch_add(1, std::memory_order_relaxed);
    set_error(std::string("queue: ") + err.what(), true);
    return;
  }
  if (e.recorded_mono_ns > 0 && e.kind != EventKind::kSummary) {
    // From the processing thread's record of the level change to the fsync'ed queue record: what a
    // kill -9 or a power cut can lose of an alarm whose outputs were already set.
    const auto us =
        static_cast<std::uint64_t>(std::max<std::int64_t>(0, steady_ns() - e.recorded_mono_ns) / 1000);
    durable_us_last_.store(us, std::memory_order_relaxed);
    if (us > durable_us_max_.load(std::memory_order_relaxed))
      durable_us_max_.store(us, std::memory_order_relaxed);
  }
  if (e.kind == EventKind::kState) {
    last_state_ = e;
    have_state_ = true;
    newest_state_seq_ = seq;
  }
  update_queue_stats();
}

void MqttPublisher::update_queue_stats() noexcept {
  queue_bytes_.store(queue_->bytes() + summaries_->bytes(), std::memory_order_relaxed);
  queue_pending_.store(queue_->pending(), std::memory_order_relaxed);
  summary_pending_.store(summaries_->pending(), std::memory_order_relaxed);
  queue_dropped_events_.store(queue_->counters().dropped_events, std::memory_order_relaxed);
  queue_dropped_summaries_.store(summaries_->counters().dropped_summaries, std::memory_order_relaxed);
}

std::string MqttPublisher::tls_hint(int rc, int err, const std::string& why) const {
  if (s_.cfg.tls_ca_file.empty()) return {};
  // With TLS 1.3 the broker judges the client certificate after the client's side of the handshake is
  // done, so a missing or untrusted one shows only as the broker's alert ("tlsv13 alert certificate
  // required", "unknown ca") when OpenSSL logs it, or else as a bare "Protocol error" (EPROTO from the
  // socket, or libmosquitto's own code).
  const bool alert = why.find(" alert ") != std::string::npos;
  const bool closed = rc == MOSQ_ERR_PROTOCOL || (rc == MOSQ_ERR_ERRNO && err == EPROTO) ||
                      why.find("Protocol error") != std::string::npos;
  if (!alert && !closed) return {};
  return s_.cfg.tls_cert_file.empty()
             ? " (broker closed TLS: if it requires a client certificate, set mqtt.tls_cert_file and "
               "mqtt.tls_key_file)"
             : " (broker closed TLS: does it trust the CA that signed mqtt.tls_cert_file?)";
}

void MqttPublisher::try_connect(std::int64_t now_ns) {
  const int rc = mosquitto_connect_async(mosq_, s_.cfg.host.c_str(), static_cast<int>(s_.cfg.port),
                                         static_cast<int>(s_.cfg.keepalive_s));
  if (rc == MOSQ_ERR_SUCCESS) {
    connecting_ = true;
    next_connect_ns_ = now_ns + static_cast<std::int64_t>(s_.cfg.reconnect_max_s * 1e9);  // connect timeout
    return;
  }
  const int err = errno;
  connect_failures_.fetch_add(1, std::memory_order_relaxed);
  std::string why = last_log_error_.empty()
                        ? std::string(rc == MOSQ_ERR_ERRNO ? std::strerror(err) : mosquitto_strerror(rc))
                        : last_log_error_;
  last_log_error_.clear();
  why += tls_hint(rc, err, why);
  set_error(std::string("connect to ") + s_.cfg.host + ":" + std::to_string(s_.cfg.port) + ": " + why, true);
  backoff_s_ =
      backoff_s_ <= 0.0 ? s_.cfg.reconnect_min_s : std::min(backoff_s_ * 2.0, s_.cfg.reconnect_max_s);
  next_connect_ns_ = now_ns + static_cast<std::int64_t>(backoff_s_ * 1e9);
}

// Delivery order: the event queue's backlog first, then the summaries (oldest first). Alarms are what an
// operator acts on; a summary carries its own summary_seq and window times, so a receiver can still put
// it on the time line. One message in flight at a time.
void MqttPublisher::send_front() {
  QueuedEvent ev;
  const bool summary = queue_->pending() == 0;
  if (!(summary ? summaries_->front(ev) : queue_->front(ev))) return;
  if (summary) {
    int mid = 0;
    const std::string t = topic("window");
    const int rc = mosquitto_publish(mosq_, &mid, t.c_str(), static_cast<int>(ev.payload.size()),
                                     ev.payload.data(), 1, false);
    if (rc == MOSQ_ERR_SUCCESS) {
      inflight_mid_ = mid;
      inflight_seq_ = ev.seq;
      inflight_summary_ = true;
    } else if (rc != MOSQ_ERR_NO_CONN) {
      set_error(std::string("publish to ") + t + ": " + mosquitto_strerror(rc), true);
    }
    return;
  }
  const bool is_state = ev.kind == EventKind::kState;
  std::string payload = std::move(ev.payload);
  if (is_state) {
    // The status topic holds the joint's state with "online": true added.
    if (payload.size() > 1 && payload.front() == '{') payload.insert(1, "\"online\":true,");
  }
  const std::string t = topic(is_state ? "status" : "alarm");
  const bool retain = is_state && ev.seq >= newest_state_seq_;
  int mid = 0;
  const int rc =
      mosquitto_publish(mosq_, &mid, t.c_str(), static_cast<int>(payload.size()), payload.data(), 1, retain);
  if (rc == MOSQ_ERR_SUCCESS) {
    inflight_mid_ = mid;
    inflight_seq_ = ev.seq;
    inflight_summary_ = false;
  } else if (rc != MOSQ_ERR_NO_CONN) {
    set_error(std::string("publish to ") + t + ": " + mosquitto_strerror(rc), true);
  }
}

void MqttPublisher::on_connect(int rc) {
  connecting_ = false;
  if (rc == 0) {
    connected_ = true;
    connected_flag_.store(true, std::memory_order_relaxed);
    backoff_s_ = 0.0;
    inflight_mid_ = -1;
    spdlog::info("mqtt: connected to {}:{} ({} queued event(s) to deliver)", s_.cfg.host, s_.cfg.port,
                 queue_->pending());
    set_error("", false);
    // The retained status: online, with the last state known (a queued state event replaces it).
    const std::string on =
        mqtt_status_json(have_state_ ? &last_state_ : nullptr, true, 0, s_.joint, s_.client_id);
    if (!(have_state_ && queue_->pending() > 0)) {
      (void)mosquitto_publish(mosq_, nullptr, topic("status").c_str(), static_cast<int>(on.size()), on.data(),
                              1, true);
    }
    return;
  }
  connect_failures_.fetch_add(1, std::memory_order_relaxed);
  set_error(std::string("broker refused the connection: ") + mosquitto_connack_string(rc), true);
  backoff_s_ =
      backoff_s_ <= 0.0 ? s_.cfg.reconnect_min_s : std::min(backoff_s_ * 2.0, s_.cfg.reconnect_max_s);
  next_connect_ns_ = steady_ns() + static_cast<std::int64_t>(backoff_s_ * 1e9);
  (void)mosquitto_disconnect(mosq_);
}

void MqttPublisher::on_disconnect(int rc) {
  const bool was_connected = connected_;
  const bool was_connecting = connecting_;
  connected_ = false;
  connecting_ = false;
  connected_flag_.store(false, std::memory_order_relaxed);
  inflight_mid_ = -1;  // the front is sent again after the reconnect (at least once)
  if (stop_.load()) return;
  const std::int64_t now = steady_ns();
  if (was_connecting) {
    connect_failures_.fetch_add(1, std::memory_order_relaxed);
    const int err = errno;
    std::string why = last_log_error_.empty()
                          ? std::string(rc == MOSQ_ERR_ERRNO ? std::strerror(err) : mosquitto_strerror(rc))
                          : last_log_error_;
    why += tls_hint(rc, err, why);
    // Keep a refusal's CONNACK text (set by on_connect) rather than the socket close that follows it.
    bool keep = false;
    {
      std::lock_guard lock(error_mutex_);
      keep = last_error_.view().rfind("broker refused", 0) == 0;
      // libmosquitto logs the OpenSSL reason only on some attempts: keep it over the bare "A TLS error".
      if (last_log_error_.empty() && rc == MOSQ_ERR_TLS)
        keep = keep || last_error_.view().find("TLS: ") != std::string_view::npos;
    }
    if (!keep) set_error("connect to " + s_.cfg.host + ":" + std::to_string(s_.cfg.port) + ": " + why, true);
  } else if (was_connected) {
    spdlog::warn("mqtt: connection to {}:{} lost ({}); reconnecting", s_.cfg.host, s_.cfg.port,
                 mosquitto_strerror(rc));
    set_error(std::string("connection lost: ") + mosquitto_strerror(rc), false);
  }
  last_log_error_.clear();
  backoff_s_ =
      backoff_s_ <= 0.0 ? s_.cfg.reconnect_min_s : std::min(backoff_s_ * 2.0, s_.cfg.reconnect_max_s);
  next_connect_ns_ = now + static_cast<std::int64_t>(backoff_s_ * 1e9);
}

void MqttPublisher::on_publish(int mid) {
  if (mid != inflight_mid_) return;  // a status or health message
  DiskQueue& q = inflight_summary_ ? *summaries_ : *queue_;
  try {
    // A summary in flight may have been dropped meanwhile to make room (then nothing to acknowledge).
    if (q.front_seq() == inflight_seq_) q.ack(inflight_seq_);
  } catch (const Error& e) {
    set_error(std::string("queue: ") + e.what(), true);
  }
  inflight_mid_ = -1;
  published_.fetch_add(1, std::memory_order_relaxed);
  update_queue_stats();
}

void MqttPublisher::on_log(int level, const char* text) {
  if (level == MOSQ_LOG_ERR && text != nullptr) {
    last_log_error_ = text;
    // "OpenSSL Error[0]: error:0A000086:SSL routines::certificate verify failed" -> the readable tail.
    const std::size_t colon = last_log_error_.rfind("::");
    if (colon != std::string::npos) last_log_error_ = "TLS: " + last_log_error_.substr(colon + 2);
  }
}

void MqttPublisher::cb_connect(mosquitto*, void* self, int rc) {
  static_cast<MqttPublisher*>(self)->on_connect(rc);
}
void MqttPublisher::cb_disconnect(mosquitto*, void* self, int rc) {
  auto* p = static_cast<MqttPublisher*>(self);
  if (p->connected_ || p->connecting_) p->on_disconnect(rc);
}
void MqttPublisher::cb_publish(mosquitto*, void* self, int mid) {
  static_cast<MqttPublisher*>(self)->on_publish(mid);
}
void MqttPublisher::cb_log(mosquitto*, void* self, int level, const char* text) {
  static_cast<MqttPublisher*>(self)->on_log(level, text);
}

}  // namespace ptda::daemon
