// The service files the daemon relies on (systemd/): parsed as text and checked for the properties
// ptdad needs at run time (readiness/watchdog protocol, CAN, GPIO and IIO access, directories).
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

const fs::path kDir = fs::path(PTDA_SOURCE_DIR) / "systemd";

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  EXPECT_TRUE(in.good()) << p;
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::string trim(std::string s) {
  const auto b = s.find_first_not_of(" \t\r");
  if (b == std::string::npos) return {};
  const auto e = s.find_last_not_of(" \t\r");
  return s.substr(b, e - b + 1);
}

/// systemd INI: "[Section]" headers, "Key=value" lines, '#'/';' comment lines, repeated keys accumulate
/// (an empty assignment resets the list, as systemd does for list settings).
using Unit = std::map<std::string, std::map<std::string, std::vector<std::string>>>;
Unit parse_unit(const std::string& text) {
  Unit u;
  std::string section;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    line = trim(line);
    if (line.empty() || line[0] == '#' || line[0] == ';') continue;
    if (line.front() == '[' && line.back() == ']') {
      section = line.substr(1, line.size() - 2);
      continue;
    }
    const auto eq = line.find('=');
    if (eq == std::string::npos) continue;
    const std::string key = trim(line.substr(0, eq));
    const std::string value = trim(line.substr(eq + 1));
    auto& values = u[section][key];
    if (value.empty()) values.clear();
    values.push_back(value);
  }
  return u;
}

/// The last assignment of a key ("" when absent).
std::string last(const Unit& u, const std::string& section, const std::string& key) {
  const auto s = u.find(section);
  if (s == u.end()) return {};
  const auto k = s->second.find(key);
  if (k == s->second.end() || k->second.empty()) return {};
  return k->second.back();
}

/// Every space-separated word of every assignment of a key.
std::vector<std::string> words(const Unit& u, const std::string& section, const std::string& key) {
  std::vector<std::string> out;
  const auto s = u.find(section);
  if (s == u.end()) return out;
  const auto k = s->second.find(key);
  if (k == s->second.end()) return out;
  for (const std::string& v : k->second) {
    std::istringstream in(v);
    std::string w;
    while (in >> w) out.push_back(w);
  }
  return out;
}

bool contains(const std::vector<std::string>& v, const std::string& w) {
  return std::find(v.begin(), v.end(), w) != v.end();
}

bool is_true(const std::string& v) {
  return v == "yes" || v == "true" || v == "1" || v == "on";
}

/// What ptdad needs from its unit; returns the violated requirements.
std::vector<std::string> check_service(const Unit& u) {
  std::vector<std::string> bad;
  const auto need = [&bad](bool ok, const std::string& what) {
    if (!ok) bad.push_back(what);
  };
  need(last(u, "Service", "Type") == "notify", "Type=notify (READY=1 after configure)");
  const std::string wd = last(u, "Service", "WatchdogSec");
  need(!wd.empty() && wd != "0" && wd != "infinity" && std::isdigit(static_cast<unsigned char>(wd[0])) != 0,
       "WatchdogSec= set to a finite time");
  need(last(u, "Service", "NotifyAccess") == "main", "NotifyAccess=main");
  need(last(u, "Service", "Restart") == "on-failure", "Restart=on-failure");
  need(last(u, "Service", "ExecStart").rfind("/usr/bin/ptdad", 0) == 0, "ExecStart=/usr/bin/ptdad ...");
  need(last(u, "Service", "ExecReload") == "/bin/kill -HUP $MAINPID", "ExecReload=/bin/kill -HUP $MAINPID");
  need(last(u, "Service", "User") == "ptda", "User=ptda");
  need(contains(words(u, "Service", "SupplementaryGroups"), "ptda-hw"), "SupplementaryGroups=ptda-hw");
  need(last(u, "Service", "StateDirectory") == "ptda", "StateDirectory=ptda (baseline)");
  need(last(u, "Service", "RuntimeDirectory") == "ptda", "RuntimeDirectory=ptda (status files)");
  need(last(u, "Service", "ConfigurationDirectory") == "ptda", "ConfigurationDirectory=ptda");

  const std::vector<std::string> families = words(u, "Service", "RestrictAddressFamilies");
  need(contains(families, "AF_CAN") && contains(families, "AF_UNIX") &&
           (families.empty() || families.front()[0] != '~'),
       "RestrictAddressFamilies allows AF_CAN and AF_UNIX");
  need(!is_true(last(u, "Service", "PrivateNetwork")), "no PrivateNetwork (CAN lives in the host netns)");
  need(!is_true(last(u, "Service", "PrivateDevices")), "no PrivateDevices=yes (hides gpiochip/iio)");
  need(last(u, "Service", "DevicePolicy") == "closed", "DevicePolicy=closed");
  const auto allows = u.count("Service") != 0 && u.at("Service").count("DeviceAllow") != 0
                          ? u.at("Service").at("DeviceAllow")
                          : std::vector<std::string>{};
  need(contains(allows, "char-gpiochip rw"), "DeviceAllow=char-gpiochip rw");
  need(contains(allows, "char-iio rw"), "DeviceAllow=char-iio rw");
  need(!is_true(last(u, "Service", "ProtectKernelTunables")),
       "ProtectKernelTunables off (IIO configure writes sysfs)");
  need(is_true(last(u, "Service", "NoNewPrivileges")), "NoNewPrivileges=yes");
  need(last(u, "Service", "ProtectSystem") == "strict", "ProtectSystem=strict");
  need(is_true(last(u, "Service", "ProtectHome")), "ProtectHome=yes");
  need(u.count("Service") != 0 && u.at("Service").count("CapabilityBoundingSet") != 0 &&
           last(u, "Service", "CapabilityBoundingSet").empty(),
       "CapabilityBoundingSet= (empty)");
  need(contains(words(u, "Service", "SystemCallFilter"), "@system-service"),
       "SystemCallFilter=@system-service");
  return bad;
}

TEST(SystemdUnits, ServiceHasWhatTheDaemonNeeds) {
  const Unit u = parse_unit(slurp(kDir / "ptdad.service"));
  EXPECT_EQ(check_service(u), std::vector<std::string>{});
  EXPECT_EQ(last(u, "Service", "WatchdogSec"), "5s");
  EXPECT_EQ(last(u, "Install", "WantedBy"), "multi-user.target");
}

TEST(SystemdUnits, CheckerCatchesBrokenUnits) {
  const std::string good = slurp(kDir / "ptdad.service");
  const auto broken = [&](const std::string& from, const std::string& to) {
    std::string t = good;
    const auto at = t.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    if (at != std::string::npos) t.replace(at, from.size(), to);
    return check_service(parse_unit(t));
  };
  EXPECT_EQ(broken("PrivateDevices=no", "PrivateDevices=yes"),
            std::vector<std::string>{"no PrivateDevices=yes (hides gpiochip/iio)"});
  EXPECT_EQ(broken("Type=notify", "Type=simple"),
            std::vector<std::string>{"Type=notify (READY=1 after configure)"});
  EXPECT_EQ(broken("WatchdogSec=5s", "WatchdogSec=0"),
            std::vector<std::string>{"WatchdogSec= set to a finite time"});
  EXPECT_EQ(broken("AF_UNIX AF_CAN", "AF_UNIX AF_INET"),
            std::vector<std::string>{"RestrictAddressFamilies allows AF_CAN and AF_UNIX"});
  EXPECT_EQ(broken("DeviceAllow=char-iio rw", "DeviceAllow=char-iio r"),
            std::vector<std::string>{"DeviceAllow=char-iio rw"});
  // A later empty assignment resets a list setting.
  EXPECT_EQ(broken("DeviceAllow=char-iio rw\n", "DeviceAllow=char-iio rw\nDeviceAllow=\n"),
            (std::vector<std::string>{"DeviceAllow=char-gpiochip rw", "DeviceAllow=char-iio rw"}));
}

TEST(SystemdUnits, CanDropInBindsToTheInterface) {
  const Unit u = parse_unit(slurp(kDir / "ptdad.service.d" / "10-can0.conf"));
  EXPECT_EQ(last(u, "Unit", "BindsTo"), "sys-subsystem-net-devices-can0.device");
  EXPECT_EQ(last(u, "Unit", "After"), "sys-subsystem-net-devices-can0.device");
}

TEST(SystemdUnits, SysusersUdevAndNetworkFiles) {
  const std::string sysusers = slurp(kDir / "ptda.sysusers");
  EXPECT_NE(sysusers.find("\nu ptda "), std::string::npos);
  EXPECT_NE(sysusers.find("\ng ptda-hw "), std::string::npos);
  EXPECT_NE(sysusers.find("\nm ptda ptda-hw"), std::string::npos);

  const std::string rules = slurp(kDir / "60-ptda.rules");
  EXPECT_NE(rules.find(R"(SUBSYSTEM=="gpio", KERNEL=="gpiochip[0-9]*", GROUP="ptda-hw", MODE="0660")"),
            std::string::npos);
  EXPECT_NE(rules.find(R"(SUBSYSTEM=="iio", KERNEL=="iio:device[0-9]*", GROUP="ptda-hw", MODE="0660")"),
            std::string::npos);
  // The sysfs attributes the IIO source writes (docs/drivers.md, IIO setup sequence).
  for (const char* attr : {"sampling_frequency", "current_timestamp_clock", "buffer/enable", "buffer/length",
                           "buffer/watermark", "trigger/current_trigger", "scan_elements/*_en"}) {
    EXPECT_NE(rules.find(attr), std::string::npos) << attr;
  }
  // udev substitutes "$x": a shell variable must be written "$$x".
  const std::string::size_type run = rules.find("RUN+=");
  ASSERT_NE(run, std::string::npos);
  for (std::string::size_type i = rules.find('$', run); i != std::string::npos; i = rules.find('$', i + 2)) {
    EXPECT_EQ(rules[i + 1], '$') << "unescaped $ at " << i;
  }

  const Unit net = parse_unit(slurp(kDir / "80-can0.network"));
  EXPECT_EQ(last(net, "Match", "Name"), "can0");
  EXPECT_EQ(last(net, "CAN", "BitRate"), "500K");
  EXPECT_EQ(last(net, "CAN", "RestartSec"), "100ms");
}

}  // namespace
