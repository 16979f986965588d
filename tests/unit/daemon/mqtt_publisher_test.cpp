// [mqtt] configuration (located errors that name the key), the settings resolved for one joint (topic
// prefix, client id, password from a file or the systemd credential) and the JSON payloads (schema 1).
// The broker itself is tested in tests/golden/mqtt_broker_test.cpp (ctest -L mqtt).
#include "mqtt/mqtt_publisher.hpp"

#include <gtest/gtest.h>

#include <fstream>

#include "daemon_test_support.hpp"
#include "ptda/common/error.hpp"
#include "status_text.hpp"

namespace ptda::daemon::test {
namespace {

std::string error_of(const std::string& text) {
  try {
    (void)parse_daemon_config(text, "t.toml");
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

const std::string kMinimal = "[extraction]\nwindow_len = 4096\n[adc]\nscenario = \"s.toml\"\n";
const std::string kOn = kMinimal + "[mqtt]\nenabled = true\n";

TEST(MqttConfig, DefaultsAndKeys) {
  const DaemonConfig off = parse_daemon_config(kMinimal, "t.toml");
  EXPECT_FALSE(off.mqtt.enabled);
  EXPECT_EQ(off.mqtt.port, 1883U);
  EXPECT_EQ(off.mqtt.queue_max_bytes, 32ULL << 20U);
  EXPECT_EQ(off.mqtt.window_summary_interval_s, 10.0);
  const DaemonConfig c = parse_daemon_config(
      kOn +
          "host = \"broker.plant\"\nport = 8883\nclient_id = \"cab17-j4\"\ntopic_prefix = "
          "\"ptda/p1/c3/r17/{joint}\"\n"
          "keepalive_s = 20\ntls_ca_file = \"/etc/ptda/ca.pem\"\ntls_cert_file = \"/etc/ptda/c.pem\"\n"
          "tls_key_file = \"/etc/ptda/c.key\"\nusername = \"j4\"\npassword_file = \"/etc/ptda/pw\"\n"
          "queue_dir = \"/var/lib/ptda/mqtt\"\nqueue_max_bytes = 1048576\nwindow_summary_interval_s = 0\n"
          "reconnect_min_s = 0.5\nreconnect_max_s = 30\n",
      "t.toml");
  EXPECT_TRUE(c.mqtt.enabled);
  EXPECT_EQ(c.mqtt.host, "broker.plant");
  EXPECT_EQ(c.mqtt.port, 8883U);
  EXPECT_EQ(c.mqtt.client_id, "cab17-j4");
  EXPECT_EQ(c.mqtt.topic_prefix, "ptda/p1/c3/r17/{joint}");
  EXPECT_EQ(c.mqtt.keepalive_s, 20U);
  EXPECT_EQ(c.mqtt.tls_key_file, fs::path("/etc/ptda/c.key"));
  EXPECT_EQ(c.mqtt.password_file, fs::path("/etc/ptda/pw"));
  EXPECT_EQ(c.mqtt.queue_max_bytes, 1048576U);
  EXPECT_EQ(c.mqtt.window_summary_interval_s, 0.0);
  EXPECT_EQ(c.mqtt.reconnect_max_s, 30.0);
}

TEST(MqttConfig, ErrorsNameTheKeyAndThePlace) {
  // Enabled without the two keys it cannot work without.
  EXPECT_EQ(error_of(kOn + "queue_dir = \"/q\"\n"),
            "t.toml:6:11: mqtt.enabled = true needs mqtt.topic_prefix (e.g. "
            "\"ptda/plant1/cell3/robot17/{joint}\")");
  EXPECT_EQ(
      error_of(kOn + "topic_prefix = \"ptda/x\"\n"),
      "t.toml:6:11: mqtt.enabled = true needs mqtt.queue_dir (the store-and-forward queue's directory)");
  const std::string ok = kOn + "topic_prefix = \"ptda/x\"\nqueue_dir = \"/q\"\n";
  EXPECT_EQ(error_of(ok), "(no error)");
  EXPECT_EQ(error_of(ok + "port = 0\n").rfind("t.toml:9:8: mqtt.port", 0), 0U) << error_of(ok + "port = 0\n");
  EXPECT_EQ(error_of(ok + "queue_max_bytes = 1000\n").rfind("t.toml:9:19: mqtt.queue_max_bytes", 0), 0U)
      << error_of(ok + "queue_max_bytes = 1000\n");
  EXPECT_EQ(error_of(ok + "queue_max_bytes = 100000.5\n").rfind("t.toml:9:19: mqtt.queue_max_bytes", 0), 0U)
      << error_of(ok + "queue_max_bytes = 100000.5\n");
  EXPECT_NE(error_of(ok + "queue_max_bytes = 100000.5\n").find("whole number of bytes"), std::string::npos);
  EXPECT_EQ(error_of(kOn + "topic_prefix = \"ptda/#\"\nqueue_dir = \"/q\"\n")
                .rfind("t.toml:7:16: mqtt.topic_prefix must be a topic without wildcards", 0),
            0U)
      << error_of(kOn + "topic_prefix = \"ptda/#\"\nqueue_dir = \"/q\"\n");
  EXPECT_NE(error_of(kOn + "topic_prefix = \"ptda/x/\"\nqueue_dir = \"/q\"\n").find("trailing '/'"),
            std::string::npos);
  EXPECT_EQ(error_of(ok + "host = \"\"\n").rfind("t.toml:9:8: mqtt.host must not be empty", 0), 0U)
      << error_of(ok + "host = \"\"\n");
  EXPECT_EQ(error_of(ok + "tls_cert_file = \"/c.pem\"\n"),
            "t.toml:9:17: mqtt.tls_cert_file and mqtt.tls_key_file go together (the client certificate and "
            "its key)");
  EXPECT_EQ(error_of(ok + "tls_cert_file = \"/c.pem\"\ntls_key_file = \"/c.key\"\n"),
            "t.toml:9:17: a client certificate (mqtt.tls_cert_file) needs TLS: set mqtt.tls_ca_file");
  EXPECT_EQ(error_of(ok + "password_file = \"/pw\"\n"),
            "t.toml:9:17: mqtt.password_file needs mqtt.username");
  EXPECT_EQ(error_of(ok + "reconnect_min_s = 10\nreconnect_max_s = 5\n"),
            "t.toml:10:19: mqtt.reconnect_max_s must be at least mqtt.reconnect_min_s");
  EXPECT_EQ(
      error_of(ok + "pasword_file = \"/pw\"\n").rfind("t.toml:9:1: unknown key 'pasword_file' in [mqtt]", 0),
      0U)
      << error_of(ok + "pasword_file = \"/pw\"\n");
}

TEST(MqttSettings, TopicClientIdAndPasswordSources) {
  const fs::path dir = scratch("mqtt_settings");
  MqttSection c;
  c.enabled = true;
  c.topic_prefix = "ptda/p1/c3/r17/{joint}";
  c.queue_dir = dir / "q";
  MqttSettings s = resolve_mqtt_settings(c, "joint4", nullptr);
  EXPECT_EQ(s.topic_prefix, "ptda/p1/c3/r17/joint4");
  EXPECT_EQ(s.client_id, "ptdad-joint4");
  EXPECT_TRUE(s.password.empty());
  try {
    (void)resolve_mqtt_settings(c, "", nullptr);
    ADD_FAILURE() << "no error for {joint} without a joint";
  } catch (const Error& e) {
    EXPECT_EQ(
        std::string(e.what()),
        "[mqtt] topic_prefix \"ptda/p1/c3/r17/{joint}\" uses {joint} but no joint is set ([daemon] joint or "
        "ptdad --joint)");
  }
  c.username = "j4";
  c.password_file = dir / "pw";
  std::ofstream(c.password_file) << "from-file\nsecond line ignored\n";
  s = resolve_mqtt_settings(c, "joint4", nullptr);
  EXPECT_EQ(s.password, "from-file");
  EXPECT_EQ(s.password_source, c.password_file.string());
  // The systemd credential wins over the file ($CREDENTIALS_DIRECTORY/mqtt_password, LoadCredential=).
  fs::create_directories(dir / "creds");
  std::ofstream(dir / "creds" / "mqtt_password") << "from-credential\r\n";
  s = resolve_mqtt_settings(c, "joint4", (dir / "creds").c_str());
  EXPECT_EQ(s.password, "from-credential");
  EXPECT_EQ(s.password_source, "systemd credential mqtt_password");
  // A credentials directory without that file: the file again.
  EXPECT_EQ(resolve_mqtt_settings(c, "joint4", dir.c_str()).password, "from-file");
  std::ofstream(c.password_file) << "\n";
  try {
    (void)resolve_mqtt_settings(c, "joint4", nullptr);
    ADD_FAILURE() << "no error for an empty password";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "[mqtt] password_file " + c.password_file.string() +
                                         ": the first line (the password) is empty");
  }
  c.password_file.clear();
  c.tls_ca_file = dir / "missing-ca.pem";
  try {
    (void)resolve_mqtt_settings(c, "joint4", nullptr);
    ADD_FAILURE() << "no error for a missing CA file";
  } catch (const Error& e) {
    EXPECT_EQ(
        std::string(e.what()).rfind("[mqtt] tls_ca_file " + c.tls_ca_file.string() + ": cannot read", 0), 0U)
        << e.what();
  }
}

MqttEvent alarm_event() {
  MqttEvent e;
  e.kind = EventKind::kAlarm;
  e.t_mono_ns = 669'573'000'000;
  e.t_unix_ns = 1'795'785'446'847'000'000;  // 2026-11-27T13:17:26.847Z
  e.level.assign("alarm");
  e.causes.assign("rms+entropy");
  e.have_features = true;
  e.class_id = 0;
  e.abnormal_in_last_n = 3;
  e.rms_res = 0.484238948;
  e.entropy_res = 0.662522068;
  e.rms_lo = 0.25;
  e.rms_hi = 0.2769;
  e.entropy_lo = 0.9024;
  e.entropy_hi = 0.9174;
  return e;
}

TEST(MqttPayload, AlarmFaultStateSummaryAndStatus) {
  EXPECT_EQ(mqtt_event_json(alarm_event(), 42, "joint4"),
            R"({"schema":1,"type":"alarm","joint":"joint4","seq":42,"t_mono_s":669.573,)"
            R"("t_utc":"2026-11-27T13:17:26.847Z","level":"alarm","causes":"rms+entropy","class":0,)"
            R"("rms_res":0.484238948,"entropy_res":0.662522068,"rms_band":[0.25,0.2769],)"
            R"("entropy_band":[0.9024,0.9174],"abnormal_in_last_n":3})");
  MqttEvent f;
  f.kind = EventKind::kFault;
  f.t_mono_ns = 1'500'000'000;
  f.t_unix_ns = 0;
  f.level.assign("fault");
  f.causes.assign("speed");
  EXPECT_EQ(mqtt_event_json(f, 7, ""),
            R"({"schema":1,"type":"fault","seq":7,"t_mono_s":1.500,"t_utc":"1970-01-01T00:00:00.000Z",)"
            R"("level":"fault","causes":"speed","class":null})");
  MqttEvent st = f;
  st.kind = EventKind::kState;
  st.state.assign("paused");
  st.phase.assign("paused (speed)");
  EXPECT_EQ(
      mqtt_event_json(st, 8, "joint4"),
      R"({"schema":1,"type":"state","joint":"joint4","seq":8,"t_mono_s":1.500,"t_utc":"1970-01-01T00:00:00.000Z",)"
      R"x("level":"fault","causes":"speed","state":"paused","phase":"paused (speed)"})x");
  MqttEvent w = alarm_event();
  w.kind = EventKind::kSummary;
  w.window_n = 12;
  w.status.assign("scored");
  w.speed_rad_s = -3.5;
  w.abnormal = true;
  EXPECT_EQ(
      mqtt_event_json(w, 0, "joint4"),
      R"({"schema":1,"type":"summary","joint":"joint4","t_mono_s":669.573,"t_utc":"2026-11-27T13:17:26.847Z",)"
      R"("n":12,"status":"scored","speed_rad_s":-3.5,"class":0,"rms_res":0.484238948,"entropy_res":0.662522068,)"
      R"("rms_band":[0.25,0.2769],"entropy_band":[0.9024,0.9174],"abnormal":true})");
  EXPECT_EQ(mqtt_status_json(nullptr, false, 0, "joint4", "ptdad-joint4"),
            R"({"schema":1,"online":false,"joint":"joint4","client_id":"ptdad-joint4"})");
  EXPECT_EQ(
      mqtt_status_json(&st, true, 0, "joint4", "ptdad-joint4"),
      R"({"schema":1,"online":true,"joint":"joint4","client_id":"ptdad-joint4","t_mono_s":1.500,)"
      R"x("t_utc":"1970-01-01T00:00:00.000Z","state":"paused","phase":"paused (speed)","level":"fault","causes":"speed"})x");
  // Every payload parses as JSON; text is escaped.
  MqttEvent odd = st;
  odd.phase.assign("a \"quoted\"\nphase");
  const std::string text = mqtt_event_json(odd, 9, "j\"4");
  EXPECT_TRUE(ptda::test::JsonChecker(text).valid()) << text;
  EXPECT_NE(text.find(R"("phase":"a \"quoted\"\nphase")"), std::string::npos) << text;
  EXPECT_NE(text.find(R"("joint":"j\"4")"), std::string::npos) << text;
  for (const std::string& p : {mqtt_event_json(alarm_event(), 1, "joint4"), mqtt_event_json(w, 0, ""),
                               mqtt_status_json(&st, true, 0, "", "c")})
    EXPECT_TRUE(ptda::test::JsonChecker(p).valid()) << p;
}

}  // namespace
}  // namespace ptda::daemon::test
