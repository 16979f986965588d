// ptda fleet --broker mqtt://HOST[:PORT] [--topic FILTER] [--seconds S] [--refresh S] [--username U
//            --password-file F] [--ca-file F]
// A live table of every joint that publishes under the topic filter (the `ptdad` MQTT topic tree,
// docs/fleet.md "MQTT"): state, alarm level, the last alarm event, the age of the last window and the
// share of windows judged, for a plant without Grafana. Thread: the main thread of the tool (libmosquitto's
// network loop runs in it: mosquitto_loop, no second thread).
#include <mosquitto.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <fstream>
#include <map>
#include <optional>
#include <ostream>
#include <string>
#include <thread>

#include "ptda/cli/args.hpp"
#include "ptda/cli/commands.hpp"
#include "ptda/cli/jsonl.hpp"
#include "ptda/cli/text.hpp"
#include "ptda/common/error.hpp"

namespace ptda::cli {

namespace {

struct JointView {
  std::optional<bool> online;
  std::string state, phase, level, causes;
  std::optional<double> status_unix_s;  ///< t_utc of the newest state event
  std::uint64_t alarm_seq = 0;          ///< newest alarm/fault event (0 = none seen)
  std::string alarm_level;
  std::optional<double> alarm_unix_s;
  std::optional<double> window_unix_s;  ///< t_utc of the newest window summary
  std::uint64_t windows = 0, windows_scored = 0;
};

struct FleetState {
  std::map<std::string, JointView, std::less<>> joints;  ///< by topic prefix (the topic minus its last level)
  std::uint64_t messages = 0;
  std::uint64_t bad_payloads = 0;
  std::string last_bad;  ///< topic and reason of the last payload that could not be read
  int connack = -1;      ///< -1 = no CONNACK yet, 0 = accepted, > 0 = refused (mosquitto_connack_string)
  bool subscribed = false;
  std::string filter;
};

/// "2026-11-27T13:17:52.298Z" -> seconds since the epoch; nullopt when it is not that form.
std::optional<double> parse_utc(const std::string& s) {
  int y = 0, mo = 0, d = 0, h = 0, mi = 0;
  double sec = 0.0;
  char z = 0;
  if (std::sscanf(s.c_str(), "%4d-%2d-%2dT%2d:%2d:%lf%c", &y, &mo, &d, &h, &mi, &sec, &z) != 7 || z != 'Z') {
    return std::nullopt;
  }
  std::tm tm{};
  tm.tm_year = y - 1900;
  tm.tm_mon = mo - 1;
  tm.tm_mday = d;
  tm.tm_hour = h;
  tm.tm_min = mi;
  tm.tm_sec = 0;
  const std::time_t t = ::timegm(&tm);
  if (t == static_cast<std::time_t>(-1)) return std::nullopt;
  return static_cast<double>(t) + sec;
}

std::optional<double> utc_of(const JsonValue& j) {
  const auto it = j.object.find("t_utc");
  if (it == j.object.end() || it->second.kind != JsonValue::Kind::kString) return std::nullopt;
  return parse_utc(it->second.string);
}

std::string str_or(const JsonValue& j, std::string_view key, std::string fallback) {
  const auto it = j.object.find(key);
  if (it == j.object.end() || it->second.kind != JsonValue::Kind::kString) return fallback;
  return it->second.string;
}

/// One message into the state. A payload that is not a schema-1 JSON object is counted, never fatal.
void take(FleetState& st, const std::string& topic, std::string_view payload) {
  ++st.messages;
  const std::size_t slash = topic.rfind('/');
  if (slash == std::string::npos || slash == 0) return;
  const std::string prefix = topic.substr(0, slash);
  const std::string leaf = topic.substr(slash + 1);
  if (leaf != "status" && leaf != "alarm" && leaf != "window" && leaf != "health") return;
  if (payload.empty()) return;  // a cleared retained message
  JsonValue j;
  try {
    j = parse_json(payload, topic);
    if (j.kind != JsonValue::Kind::kObject) throw Error(topic + ": not a JSON object");
    const auto schema = j.object.find("schema");
    if (schema == j.object.end() || schema->second.kind != JsonValue::Kind::kNumber ||
        schema->second.number != 1.0) {
      throw Error(topic + ": no \"schema\":1 (this ptda reads schema 1)");
    }
  } catch (const Error& e) {
    ++st.bad_payloads;
    st.last_bad = e.what();
    return;
  }
  JointView& v = st.joints[prefix];
  if (leaf == "status") {
    const auto on = j.object.find("online");
    if (on != j.object.end() && on->second.kind == JsonValue::Kind::kBool) v.online = on->second.boolean;
    v.state = str_or(j, "state", v.state);
    v.phase = str_or(j, "phase", v.phase);
    v.level = str_or(j, "level", v.level);
    v.causes = str_or(j, "causes", v.causes);
    if (auto t = utc_of(j)) v.status_unix_s = t;
  } else if (leaf == "alarm") {
    const auto seq = j.object.find("seq");
    const std::uint64_t s =
        (seq != j.object.end() && seq->second.kind == JsonValue::Kind::kNumber && seq->second.number >= 0.0)
            ? static_cast<std::uint64_t>(seq->second.number)
            : 0;
    if (s >= v.alarm_seq) {
      v.alarm_seq = s;
      v.alarm_level = str_or(j, "level", "?");
      v.alarm_unix_s = utc_of(j);
      // An alarm event is newer news of the level than a retained status from before it.
      if (!v.status_unix_s || (v.alarm_unix_s && *v.alarm_unix_s >= *v.status_unix_s)) {
        v.level = v.alarm_level;
        v.causes = str_or(j, "causes", v.causes);
      }
    }
  } else if (leaf == "window") {
    ++v.windows;
    if (str_or(j, "status", "") == "scored") ++v.windows_scored;
    if (auto t = utc_of(j)) v.window_unix_s = t;
  }
}

std::string age(const std::optional<double>& t_unix_s, double now_unix_s) {
  if (!t_unix_s) return "-";
  const double a = now_unix_s - *t_unix_s;
  if (a < 0.0) return "0 s";
  if (a < 120.0) return fixed(a, 1) + " s";
  if (a < 7200.0) return fixed(a / 60.0, 1) + " min";
  return fixed(a / 3600.0, 1) + " h";
}

std::string pad(std::string s, std::size_t w) {
  if (s.size() < w) s.append(w - s.size(), ' ');
  return s;
}

void print_table(std::ostream& out, const FleetState& st, const std::string& where) {
  const double now =
      std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  out << "\nptda fleet: " << st.joints.size() << " joint" << (st.joints.size() == 1 ? "" : "s") << " on "
      << where << " (" << st.filter << "), " << st.messages << " message" << (st.messages == 1 ? "" : "s")
      << "\n";
  std::size_t wj = 5;
  for (const auto& [k, v] : st.joints) wj = std::max(wj, k.size());
  out << pad("joint", wj) << "  " << pad("online", 7) << pad("state", 10) << pad("phase", 14)
      << pad("level", 9) << pad("causes", 14) << pad("last alarm event", 26) << pad("window age", 12)
      << "windows judged\n";
  for (const auto& [k, v] : st.joints) {
    std::string last = "-";
    if (v.alarm_seq > 0)
      last =
          "#" + std::to_string(v.alarm_seq) + " " + v.alarm_level + ", " + age(v.alarm_unix_s, now) + " ago";
    std::string judged = "-";
    if (v.windows > 0) {
      judged = std::to_string(v.windows_scored) + "/" + std::to_string(v.windows) + " (" +
               fixed(100.0 * static_cast<double>(v.windows_scored) / static_cast<double>(v.windows), 0) +
               " %)";
    }
    out << pad(k, wj) << "  " << pad(v.online ? (*v.online ? "yes" : "NO") : "?", 7)
        << pad(v.state.empty() ? "-" : v.state, 10) << pad(v.phase.empty() ? "-" : v.phase, 14)
        << pad(v.level.empty() ? "-" : v.level, 9) << pad(v.causes.empty() ? "-" : v.causes, 14)
        << pad(last, 26) << pad(age(v.window_unix_s, now), 12) << judged << "\n";
  }
  if (st.bad_payloads > 0) {
    out << "unreadable payloads: " << st.bad_payloads << " (last: " << st.last_bad << ")\n";
  }
  out.flush();
}

struct Broker {
  std::string host;
  int port = 1883;
};

Broker parse_broker(const std::string& url) {
  std::string rest = url;
  int default_port = 1883;
  if (rest.rfind("mqtt://", 0) == 0) {
    rest = rest.substr(7);
  } else if (rest.rfind("mqtts://", 0) == 0) {
    rest = rest.substr(8);
    default_port = 8883;
  } else if (rest.find("://") != std::string::npos) {
    throw UsageError("--broker: '" + url + "' is not mqtt://HOST[:PORT] or mqtts://HOST[:PORT]");
  }
  if (!rest.empty() && rest.back() == '/') rest.pop_back();
  Broker b;
  b.port = default_port;
  const std::size_t colon = rest.rfind(':');
  if (colon != std::string::npos && rest.find(']') == std::string::npos) {
    b.host = rest.substr(0, colon);
    b.port = static_cast<int>(parse_u64_arg(rest.substr(colon + 1), "broker port"));
  } else {
    b.host = rest;
  }
  if (b.host.empty()) throw UsageError("--broker: no host in '" + url + "'");
  if (b.port < 1 || b.port > 65535)
    throw UsageError("--broker: port " + std::to_string(b.port) + " is not 1..65535");
  return b;
}

std::string read_password(const std::string& file) {
  std::ifstream in(file);
  if (!in) throw Error(file + ": cannot read the password file: " + std::strerror(errno));
  std::string line;
  std::getline(in, line);
  if (!line.empty() && line.back() == '\r') line.pop_back();
  return line;
}

struct MosqLib {
  MosqLib() { mosquitto_lib_init(); }
  ~MosqLib() { mosquitto_lib_cleanup(); }
  MosqLib(const MosqLib&) = delete;
  MosqLib& operator=(const MosqLib&) = delete;
};

struct MosqHandle {
  mosquitto* m = nullptr;
  ~MosqHandle() {
    if (m != nullptr) {
      mosquitto_disconnect(m);
      mosquitto_destroy(m);
    }
  }
};

std::string mosq_error(int rc) {
  if (rc == MOSQ_ERR_ERRNO) return std::strerror(errno);
  return mosquitto_strerror(rc);
}

}  // namespace

int cmd_fleet(std::span<const std::string> args, std::ostream& out) {
  ArgParser parser(
      "fleet", "--broker mqtt://HOST[:PORT] [--topic FILTER] [--seconds S] [--refresh S] [options]",
      "Subscribes to the ptdad topic tree on an MQTT broker and prints a table of every joint: online,\n"
      "state and phase, alarm level and causes, the last alarm event (seq, level, age), the age of the last\n"
      "window summary and the share of summarised windows that were judged (docs/fleet.md). Retained status\n"
      "messages fill the table at once; alarm and window columns fill as events arrive. Prints the table\n"
      "every --refresh seconds, and once more at the end.");
  parser
      .option("broker", "URL", "mqtt://HOST[:PORT] (1883) or mqtts://HOST[:PORT] (8883, needs --ca-file)",
              true)
      .option("topic", "FILTER", "subscription filter (default ptda/#: every joint under the default prefix)")
      .option("seconds", "S", "stop after S seconds (default 0: run until interrupted)")
      .option("refresh", "S", "seconds between tables (default 2; 0 = only the final table)")
      .option("username", "NAME", "broker user name")
      .option("password-file", "FILE", "the password, first line of FILE (never printed)")
      .option("ca-file", "FILE", "TLS: CA certificate to check the broker against")
      .option("client-id", "ID", "MQTT client id (default: ptda-fleet-<pid>)");
  const ParsedArgs a = parser.parse(args);
  if (a.help()) {
    out << parser.help_text();
    return kExitOk;
  }
  const Broker broker = parse_broker(a.value("broker"));
  const double seconds = a.has("seconds") ? parse_double_arg(a.value("seconds"), "seconds") : 0.0;
  const double refresh = a.has("refresh") ? parse_double_arg(a.value("refresh"), "refresh") : 2.0;
  if (!(seconds >= 0.0) || !std::isfinite(seconds)) throw UsageError("--seconds: must be >= 0");
  if (!(refresh >= 0.0) || !std::isfinite(refresh)) throw UsageError("--refresh: must be >= 0");
  if (a.has("password-file") && !a.has("username")) throw UsageError("--password-file needs --username");
  FleetState st;
  st.filter = a.value_or("topic", "ptda/#");
  const std::string where = broker.host + ":" + std::to_string(broker.port);

  const MosqLib lib;
  MosqHandle h;
  const std::string client_id = a.value_or("client-id", "ptda-fleet-" + std::to_string(::getpid()));
  h.m = mosquitto_new(client_id.c_str(), true, &st);
  if (h.m == nullptr) throw Error("mosquitto_new failed: " + std::string(std::strerror(errno)));
  if (a.has("username")) {
    const std::string pw = a.has("password-file") ? read_password(a.value("password-file")) : std::string();
    const int rc = mosquitto_username_pw_set(h.m, a.value("username").c_str(),
                                             a.has("password-file") ? pw.c_str() : nullptr);
    if (rc != MOSQ_ERR_SUCCESS) throw Error("user name/password: " + mosq_error(rc));
  }
  if (a.has("ca-file")) {
    const int rc = mosquitto_tls_set(h.m, a.value("ca-file").c_str(), nullptr, nullptr, nullptr, nullptr);
    if (rc != MOSQ_ERR_SUCCESS) throw Error(a.value("ca-file") + ": TLS CA file: " + mosq_error(rc));
  }
  mosquitto_connect_callback_set(h.m, [](mosquitto* m, void* ud, int rc) {
    auto* s = static_cast<FleetState*>(ud);
    s->connack = rc;
    if (rc == 0) s->subscribed = mosquitto_subscribe(m, nullptr, s->filter.c_str(), 1) == MOSQ_ERR_SUCCESS;
  });
  mosquitto_message_callback_set(h.m, [](mosquitto*, void* ud, const mosquitto_message* msg) {
    auto* s = static_cast<FleetState*>(ud);
    take(*s, msg->topic != nullptr ? msg->topic : "",
         std::string_view(static_cast<const char*>(msg->payload),
                          static_cast<std::size_t>(std::max(0, msg->payloadlen))));
  });
  int rc = mosquitto_connect(h.m, broker.host.c_str(), broker.port, 30);
  if (rc != MOSQ_ERR_SUCCESS) throw Error("cannot connect to " + where + ": " + mosq_error(rc));

  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  const auto end =
      start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
  auto next_table =
      start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(refresh));
  std::uint64_t lost = 0;
  while (seconds == 0.0 || Clock::now() < end) {
    rc = mosquitto_loop(h.m, 100, 1);
    if (st.connack > 0) {
      throw Error("" + where +
                  " refused the connection: " + std::string(mosquitto_connack_string(st.connack)));
    }
    if (rc != MOSQ_ERR_SUCCESS) {
      if (++lost == 1 || lost % 10 == 0)
        out << "ptda fleet: connection to " << where << " lost (" << mosq_error(rc) << "), reconnecting\n";
      std::this_thread::sleep_for(std::chrono::seconds(1));
      (void)mosquitto_reconnect(h.m);
    }
    if (refresh > 0.0 && Clock::now() >= next_table) {
      print_table(out, st, where);
      next_table += std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(refresh));
    }
  }
  if (st.connack < 0)
    throw Error("no answer (CONNACK) from " + where + " within " + fixed(seconds, 1) + " s");
  print_table(out, st, where);
  return kExitOk;
}

}  // namespace ptda::cli
