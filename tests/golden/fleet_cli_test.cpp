// `ptda fleet --broker URL` against a real Mosquitto broker (issue 15 item 5, docs/fleet.md "ptda fleet").
// ctest label `mqtt`. Messages are published with `mosquitto_pub` in the payload format of ptdad's
// publisher (docs/fleet.md "Payloads"; the format itself is pinned in
// tests/unit/daemon/mqtt_publisher_test.cpp): retained status messages before the fleet view starts, an alarm
// event, window summaries and a malformed payload while it runs.
#include <chrono>
#include <cstdlib>
#include <future>
#include <sstream>
#include <string>
#include <vector>

#include "golden_support.hpp"
#include "mqtt_support.hpp"
#include "ptda/cli/commands.hpp"

namespace ptda::golden {
namespace {

struct FleetRun {
  int code = -1;
  std::string out, err;
};

FleetRun run_fleet(const std::vector<std::string>& args) {
  std::ostringstream out, err;
  FleetRun r;
  r.code = cli::run_cli(args, out, err);
  r.out = out.str();
  r.err = err.str();
  return r;
}

void publish(int port, const std::string& topic, const std::string& payload, bool retain) {
  std::vector<std::string> argv = {
      "mosquitto_pub", "-h", "127.0.0.1", "-p", std::to_string(port), "-q", "1", "-t", topic, "-m", payload};
  if (retain) argv.push_back("-r");
  std::string cmd;
  for (const std::string& a : argv) cmd += shell_quote(a) + " ";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
}

/// The line of the table that starts with `joint`.
std::string row(const std::string& table, const std::string& joint) {
  std::istringstream in(table);
  std::string last;
  for (std::string line; std::getline(in, line);) {
    if (line.rfind(joint + " ", 0) == 0) last = line;
  }
  return last;
}

bool has(const std::string& s, const std::string& needle) {
  return s.find(needle) != std::string::npos;
}

TEST(FleetCli, TableOfEveryJointFromRetainedStatusAndLiveEvents) {
  const fs::path dir = scratch_dir("fleet_table");
  const int port = free_port();
  ASSERT_GT(port, 0);
  Broker broker(dir, port, "allow_anonymous true\n");
  broker.start();
  const std::string j4 = "ptda/plant1/cell3/robot17/joint4";
  const std::string j5 = "ptda/plant1/cell3/robot17/joint5";
  publish(
      port, j4 + "/status",
      R"({"online":true,"schema":1,"type":"state","joint":"joint4","seq":6,"t_mono_s":690.0,)"
      R"("t_utc":"2026-11-27T13:17:50.000Z","level":"normal","causes":"none","state":"running","phase":"monitoring"})",
      true);
  publish(port, j5 + "/status", R"({"schema":1,"online":false,"joint":"joint5","client_id":"ptdad-joint5"})",
          true);

  auto fleet = std::async(std::launch::async, [&] {
    return run_fleet({"fleet", "--broker", "mqtt://127.0.0.1:" + std::to_string(port), "--seconds", "4",
                      "--refresh", "0"});
  });
  std::this_thread::sleep_for(1500ms);  // the fleet view has subscribed (the retained messages came first)
  publish(
      port, j4 + "/alarm",
      R"({"schema":1,"type":"alarm","joint":"joint4","seq":7,"t_mono_s":695.023,"t_utc":"2026-11-27T13:17:52.298Z",)"
      R"("level":"alarm","causes":"rms+entropy","class":0,"rms_res":0.48,"entropy_res":0.66,)"
      R"("rms_band":[0.25,0.27],"entropy_band":[0.90,0.91],"abnormal_in_last_n":1})",
      false);
  publish(
      port, j4 + "/window",
      R"({"schema":1,"type":"summary","joint":"joint4","t_mono_s":669.5,"t_utc":"2026-11-27T13:17:26.847Z",)"
      R"("n":0,"status":"scored","speed_rad_s":3.49,"class":0,"rms_res":0.48,"entropy_res":0.66,"abnormal":true})",
      false);
  publish(
      port, j4 + "/window",
      R"({"schema":1,"type":"summary","joint":"joint4","t_mono_s":679.5,"t_utc":"2026-11-27T13:17:36.847Z",)"
      R"("n":1,"status":"no_class","speed_rad_s":2.5,"class":null,"abnormal":false})",
      false);
  publish(port, j5 + "/alarm", "not json at all", false);
  const FleetRun r = fleet.get();
  ASSERT_EQ(r.code, 0) << r.err << r.out;
  EXPECT_TRUE(has(r.out, "ptda fleet: 2 joints on 127.0.0.1:" + std::to_string(port) + " (ptda/#)")) << r.out;
  const std::string r4 = row(r.out, j4);
  const std::string r5 = row(r.out, j5);
  ASSERT_FALSE(r4.empty()) << r.out;
  ASSERT_FALSE(r5.empty()) << r.out;
  // joint4: online, running/monitoring, the alarm event is newer than the retained status -> level alarm.
  EXPECT_TRUE(has(r4, " yes ")) << r4;
  EXPECT_TRUE(has(r4, "running")) << r4;
  EXPECT_TRUE(has(r4, "monitoring")) << r4;
  EXPECT_TRUE(has(r4, "alarm    rms+entropy")) << r4;
  EXPECT_TRUE(has(r4, "#7 alarm, ")) << r4;
  EXPECT_TRUE(has(r4, "1/2 (50 %)")) << r4;  // one scored, one no_class summary
  // joint5: its last will (online false), nothing else known.
  EXPECT_TRUE(has(r5, " NO ")) << r5;
  // The malformed payload is counted and named, not fatal.
  EXPECT_TRUE(has(r.out, "unreadable payloads: 1 (last: " + j5 + "/alarm")) << r.out;
}

TEST(FleetCli, ErrorsSayWhatAndWhere) {
  const fs::path dir = scratch_dir("fleet_errors");
  const int port = free_port();
  ASSERT_GT(port, 0);
  // Nothing listens on the port yet.
  FleetRun r = run_fleet({"fleet", "--broker", "mqtt://127.0.0.1:" + std::to_string(port), "--seconds", "1"});
  EXPECT_EQ(r.code, cli::kExitFailure);
  EXPECT_TRUE(has(r.err, "cannot connect to 127.0.0.1:" + std::to_string(port) + ": Connection refused"))
      << r.err;
  // A broker that wants a password refuses an anonymous client: CONNACK "not authorised".
  ASSERT_EQ(std::system(
                ("mosquitto_passwd -b -c " + shell_quote((dir / "passwd").string()) + " joint4 pw").c_str()),
            0);
  Broker broker(dir, port, "allow_anonymous false\npassword_file " + (dir / "passwd").string() + "\n");
  broker.start();
  r = run_fleet({"fleet", "--broker", "mqtt://127.0.0.1:" + std::to_string(port), "--seconds", "3"});
  EXPECT_EQ(r.code, cli::kExitFailure);
  EXPECT_TRUE(has(r.err, "127.0.0.1:" + std::to_string(port) + " refused the connection: ")) << r.err;
  EXPECT_TRUE(has(r.err, "not authori")) << r.err;
  // Usage errors.
  r = run_fleet({"fleet", "--broker", "http://127.0.0.1"});
  EXPECT_EQ(r.code, cli::kExitUsage);
  EXPECT_TRUE(has(r.err, "--broker: 'http://127.0.0.1' is not mqtt://HOST[:PORT]")) << r.err;
  r = run_fleet({"fleet", "--broker", "mqtt://h:70000"});
  EXPECT_EQ(r.code, cli::kExitUsage);
  EXPECT_TRUE(has(r.err, "port 70000 is not 1..65535")) << r.err;
}

}  // namespace
}  // namespace ptda::golden
