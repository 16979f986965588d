#include "core/daemon_config.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <map>
#include <system_error>

#include "ptda/common/error.hpp"
#include "ptda/config/pipeline_config_builder.hpp"
#include "ptda/config/toml_reader.hpp"
#include "ptda/drivers/sample_source.hpp"
#include "ptda/formats/baseline_file.hpp"
#include "ptda/formats/recording.hpp"
#include "ptda/formats/wav.hpp"
#include "ptda/sim/simulator.hpp"

namespace ptda::daemon {

namespace fs = std::filesystem;
using config::SourceLocation;
using config::TableReader;

bool valid_joint_name(std::string_view name) noexcept {
  return !name.empty() && name.size() <= 32 && std::all_of(name.begin(), name.end(), [](char ch) {
    return std::isalnum(static_cast<unsigned char>(ch)) != 0 || ch == '_' || ch == '.' || ch == '-';
  });
}

const char* adc_backend_name(AdcBackend b) noexcept {
  switch (b) {
    case AdcBackend::kIio:
      return "iio";
    case AdcBackend::kWav:
      return "wav";
    case AdcBackend::kSim:
      return "sim";
  }
  return "?";
}

const char* can_backend_name(CanBackend b) noexcept {
  switch (b) {
    case CanBackend::kSocketCan:
      return "socketcan";
    case CanBackend::kCandump:
      return "candump";
    case CanBackend::kSim:
      return "sim";
  }
  return "?";
}

const char* pace_name(Pace p) noexcept {
  return p == Pace::kFast ? "fast" : "realtime";
}

std::vector<std::string> daemon_owned_tables() {
  return {"daemon",
          "adc",
          "alarm",
          "training",
          "history",
          "mqtt",
          "can.backend",
          "can.interface",
          "can.replay_file",
          "can.pace",
          "can.bus_error_frames",
          "can.rcvbuf_bytes",
          "can.clear_frame"};
}

std::vector<fs::path> list_dropins(const fs::path& conf_dir) {
  std::vector<fs::path> out;
  std::error_code ec;
  if (conf_dir.empty() || !fs::exists(conf_dir, ec)) return out;
  if (!fs::is_directory(conf_dir, ec)) throw Error(conf_dir.string() + ": drop-in path is not a directory");
  fs::directory_iterator it(conf_dir, ec);
  if (ec) throw Error(conf_dir.string() + ": cannot read drop-in directory: " + ec.message());
  for (const auto& entry : it) {
    const fs::path& p = entry.path();
    if (p.extension() != ".toml") continue;
    std::error_code ec2;
    if (!entry.is_regular_file(ec2)) continue;
    out.push_back(p);
  }
  // Lexical byte order of the file names, as systemd orders drop-ins.
  std::sort(out.begin(), out.end(), [](const fs::path& a, const fs::path& b) {
    return a.filename().string() < b.filename().string();
  });
  return out;
}

namespace {

/// Applies the daemon's tables of one file after another, remembering where each key was set so the
/// cross-key checks point at the line that made the combination invalid.
class DaemonTablesBuilder {
 public:
  void apply(const toml::table& root, const std::string& source, const fs::path& base_dir) {
    TableReader top(root, "", source);
    base_dir_ = base_dir;
    if (const toml::table* t = top.table("daemon")) apply_daemon(*t, source);
    if (const toml::table* t = top.table("adc")) apply_adc(*t, source);
    if (const toml::table* t = top.table("can")) apply_can(*t, source);
    if (const toml::table* t = top.table("alarm")) apply_alarm(*t, source);
    if (const toml::table* t = top.table("training")) apply_training(*t, source);
    if (const toml::table* t = top.table("history")) apply_history(*t, source);
    if (const toml::table* t = top.table("mqtt")) apply_mqtt(*t, source);
  }

  void finish(DaemonConfig& out) const {
    out.daemon = daemon_;
    out.adc = adc_;
    out.can = can_;
    out.alarm = alarm_;
    out.training = training_;
    out.history = history_;
    out.mqtt = mqtt_;
    if (alarm_.can_enabled && alarm_.can_kernel_timer && alarm_.can_lease_s < 2.0 * alarm_.can_period_s) {
      const bool lease_set = set_at_.count("alarm.can.lease_s") != 0;
      char text[200];
      std::snprintf(text, sizeof text,
                    "alarm.can.lease_s (%g s) must be at least twice alarm.can.period_s (%g s): the kernel "
                    "would stop sending between two renewals (or set alarm.can.timer = \"daemon\")",
                    alarm_.can_lease_s, alarm_.can_period_s);
      fail_key(lease_set ? "alarm.can.lease_s" : "alarm.can.period_s", text);
    }
    if (mqtt_.enabled) {
      if (mqtt_.topic_prefix.empty())
        fail_key("mqtt.enabled",
                 "mqtt.enabled = true needs mqtt.topic_prefix (e.g. \"ptda/plant1/cell3/robot17/{joint}\")");
      if (mqtt_.queue_dir.empty())
        fail_key("mqtt.enabled",
                 "mqtt.enabled = true needs mqtt.queue_dir (the store-and-forward queue's directory)");
      if (mqtt_.tls_cert_file.empty() != mqtt_.tls_key_file.empty())
        fail_key(mqtt_.tls_cert_file.empty() ? "mqtt.tls_key_file" : "mqtt.tls_cert_file",
                 "mqtt.tls_cert_file and mqtt.tls_key_file go together (the client certificate and its key)");
      if (!mqtt_.tls_cert_file.empty() && mqtt_.tls_ca_file.empty())
        fail_key("mqtt.tls_cert_file",
                 "a client certificate (mqtt.tls_cert_file) needs TLS: set mqtt.tls_ca_file");
      if (!mqtt_.password_file.empty() && mqtt_.username.empty())
        fail_key("mqtt.password_file", "mqtt.password_file needs mqtt.username");
      if (mqtt_.reconnect_max_s < mqtt_.reconnect_min_s)
        fail_key("mqtt.reconnect_max_s", "mqtt.reconnect_max_s must be at least mqtt.reconnect_min_s");
    }
    const double fs = out.pipeline.fs_hz;
    if (adc_.backend == AdcBackend::kIio && fs == 0.0) {
      fail_key("adc.backend", "adc.backend = \"iio\" needs [acquisition] fs_hz (the ADC's sample rate)");
    }
    if (adc_.backend == AdcBackend::kWav && adc_.recording.empty()) {
      fail_key("adc.backend", "adc.backend = \"wav\" needs adc.recording (a recording directory)");
    }
    if (adc_.backend == AdcBackend::kSim && adc_.scenario.empty()) {
      fail_key("adc.backend", "adc.backend = \"sim\" needs adc.scenario (a simulator scenario file)");
    }
    if (can_.backend == CanBackend::kSim && adc_.backend != AdcBackend::kSim) {
      fail_key("can.backend",
               "can.backend = \"sim\" serves the simulator's speed frames and needs "
               "adc.backend = \"sim\" (now \"" +
                   std::string(adc_backend_name(adc_.backend)) + "\")");
    }
    if (adc_.backend == AdcBackend::kSim && can_.backend != CanBackend::kSim) {
      fail_key("adc.backend",
               "adc.backend = \"sim\" needs can.backend = \"sim\" (the simulated joint "
               "speed belongs to the simulated vibration; now \"" +
                   std::string(can_backend_name(can_.backend)) + "\")");
    }
    if (can_.backend == CanBackend::kCandump && can_.replay_file.empty() &&
        adc_.backend != AdcBackend::kWav) {
      fail_key("can.backend",
               "can.backend = \"candump\" needs can.replay_file (or adc.backend = \"wav\", "
               "whose recording's can.log is then replayed)");
    }
    if (alarm_.can_enabled && can_.backend == CanBackend::kSim) {
      // The simulator channel records sent frames like the candump replay does: allowed.
    }
    if (training_.target_cycles < 3) {
      fail_key("training.target_cycles",
               "training.target_cycles must be at least 3 (leave-one-out thresholds)");
    }
  }

 private:
  void note(const TableReader& r, std::string_view key) { set_at_[r.qualified(key)] = r.location(key); }

  template <typename T, typename... Range>
  void get(TableReader& r, std::string_view key, T& out, Range... range) {
    if (r.read(key, out, range...)) note(r, key);
  }

  void get_path(TableReader& r, std::string_view key, fs::path& out) {
    std::string text;
    if (!r.read(key, text)) return;
    note(r, key);
    if (text.empty()) {
      out.clear();
      return;
    }
    fs::path p(text);
    out = p.is_relative() && !base_dir_.empty() ? (base_dir_ / p).lexically_normal() : p;
  }

  void get_pace(TableReader& r, std::string_view key, Pace& out) {
    if (r.read_choice(key, out, {{"realtime", Pace::kRealTime}, {"fast", Pace::kFast}})) note(r, key);
  }

  [[noreturn]] void fail_key(const std::string& key, const std::string& what) const {
    const auto it = set_at_.find(key);
    config::fail_at(it != set_at_.end() ? it->second : SourceLocation{first_source_, 0, 0}, what);
  }

  void apply_daemon(const toml::table& t, const std::string& source) {
    remember_source(source);
    TableReader r(t, "daemon", source);
    get_path(r, "baseline", daemon_.baseline);
    get_path(r, "status_dir", daemon_.status_dir);
    get_path(r, "metrics_path", daemon_.metrics_path);
    if (r.read_choice("log_level", daemon_.log_level,
                      {std::pair<std::string_view, std::string>{"trace", "trace"},
                       {"debug", "debug"},
                       {"info", "info"},
                       {"warn", "warn"},
                       {"error", "error"}})) {
      note(r, "log_level");
    }
    if (r.read("joint", daemon_.joint)) {
      if (!valid_joint_name(daemon_.joint)) {
        r.fail_value("joint", "must be 1 to 32 characters of A-Z, a-z, 0-9, '_', '.' and '-', not \"" +
                                  daemon_.joint + "\"");
      }
      note(r, "joint");
    }
    get(r, "status_period_s", daemon_.status_period_s, 0.05, 60.0);
    get(r, "speed_stale_periods", daemon_.speed_stale_periods, 2.0, 100000.0);
    get(r, "sensor_stale_s", daemon_.sensor_stale_s, 0.01, 3600.0);
    get(r, "stage_stall_s", daemon_.stage_stall_s, 0.1, 3600.0);
    get(r, "coverage_timeout_s", daemon_.coverage_timeout_s, 0.1, 86400.0);
    if (!daemon_.metrics_path.empty() && daemon_.metrics_path.extension() != ".prom") {
      r.fail_value("metrics_path",
                   "must end in \".prom\" (the node_exporter textfile collector reads only *.prom)");
    }
    r.finish();
  }

  void apply_adc(const toml::table& t, const std::string& source) {
    remember_source(source);
    TableReader r(t, "adc", source);
    if (r.read_choice("backend", adc_.backend,
                      {{"iio", AdcBackend::kIio}, {"wav", AdcBackend::kWav}, {"sim", AdcBackend::kSim}})) {
      note(r, "backend");
    }
    get(r, "block_len", adc_.block_len, std::uint32_t{1}, static_cast<std::uint32_t>(drivers::kMaxBlock));
    double scale = adc_.scale;
    if (r.read("scale", scale, -1e12, 1e12)) {
      if (scale == 0.0) r.fail_value("scale", "must not be 0");
      adc_.scale = static_cast<float>(scale);
      note(r, "scale");
    }
    get_path(r, "sysfs_dir", adc_.sysfs_dir);
    get_path(r, "device", adc_.device);
    get(r, "channel", adc_.channel);
    get(r, "trigger", adc_.trigger);
    get(r, "buffer_length", adc_.buffer_length, std::uint32_t{0}, std::uint32_t{1} << 24);
    get(r, "watermark", adc_.watermark, std::uint32_t{0}, std::uint32_t{1} << 24);
    get(r, "timestamp", adc_.timestamp);
    get_path(r, "recording", adc_.recording);
    get_path(r, "scenario", adc_.scenario);
    get(r, "seed", adc_.seed, std::uint32_t{0}, std::uint32_t{0xFFFFFFFF});
    get_pace(r, "pace", adc_.pace);
    get(r, "loop", adc_.loop);
    if (adc_.channel.empty()) r.fail_value("channel", "must not be empty");
    r.finish();
  }

  void apply_can(const toml::table& t, const std::string& source) {
    remember_source(source);
    TableReader r(t, "can", source);
    r.ignore("speed_latency_s");  // the pipeline's
    r.ignore("speed_frame");
    if (r.read_choice("backend", can_.backend,
                      {{"socketcan", CanBackend::kSocketCan},
                       {"candump", CanBackend::kCandump},
                       {"sim", CanBackend::kSim}})) {
      note(r, "backend");
    }
    get(r, "interface", can_.interface);
    get_path(r, "replay_file", can_.replay_file);
    get_pace(r, "pace", can_.pace);
    get(r, "bus_error_frames", can_.bus_error_frames);
    get(r, "rcvbuf_bytes", can_.rcvbuf_bytes, std::uint32_t{0}, std::uint32_t{1} << 30);
    if (can_.interface.empty() || can_.interface.size() >= 16) {
      r.fail_value("interface", "must be a network interface name of 1..15 characters");
    }
    if (const toml::table* c = r.table("clear_frame")) {
      TableReader cr(*c, "can.clear_frame", source);
      ClearFrameSpec& spec = can_.clear_frame;
      get(cr, "enabled", spec.enabled);
      get(cr, "id", spec.id, std::uint32_t{0}, std::uint32_t{0x1FFFFFFF});
      get(cr, "extended", spec.extended);
      std::string hex;
      if (cr.read("data", hex)) {
        note(cr, "data");
        if (hex.empty() || hex.size() % 2 != 0 || hex.size() > 16) {
          cr.fail_value("data", "must be 1..8 bytes as an even number of hex digits (e.g. \"C1\"), not \"" +
                                    hex + "\"");
        }
        for (std::size_t i = 0; i < hex.size(); i += 2) {
          const auto nibble = [&](char ch) -> int {
            if (std::isxdigit(static_cast<unsigned char>(ch)) == 0) {
              cr.fail_value("data", "must be hex digits, not \"" + hex + "\"");
            }
            return std::isdigit(static_cast<unsigned char>(ch)) != 0
                       ? ch - '0'
                       : (std::tolower(static_cast<unsigned char>(ch)) - 'a' + 10);
          };
          spec.data[i / 2] = static_cast<std::uint8_t>(nibble(hex[i]) * 16 + nibble(hex[i + 1]));
        }
        spec.len = static_cast<std::uint8_t>(hex.size() / 2);
      }
      if (!spec.extended && spec.id > 0x7FF)
        cr.fail_value("id", "is above 0x7FF: set extended = true for a 29-bit id");
      cr.finish();
    }
    r.finish();
  }

  void apply_alarm(const toml::table& t, const std::string& source) {
    remember_source(source);
    TableReader r(t, "alarm", source);
    get(r, "min_hold_s", alarm_.min_hold_s, 0.0, 86400.0);
    get(r, "latch", alarm_.latch);
    get(r, "warning", alarm_.warning);
    get(r, "warning_k", alarm_.warning_k, std::uint32_t{1}, std::uint32_t{64});
    get(r, "warning_hold_s", alarm_.warning_hold_s, 0.0, 86400.0);
    if (const toml::table* g = r.table("gpio")) {
      TableReader gr(*g, "alarm.gpio", source);
      get(gr, "enabled", alarm_.gpio_enabled);
      get(gr, "chip", alarm_.gpio_chip);
      get(gr, "line", alarm_.gpio_line, std::uint32_t{0}, std::uint32_t{4095});
      get(gr, "active_low", alarm_.gpio_active_low);
      gr.finish();
    }
    if (const toml::table* c = r.table("can")) {
      TableReader cr(*c, "alarm.can", source);
      get(cr, "enabled", alarm_.can_enabled);
      get(cr, "id", alarm_.can_id, std::uint32_t{0}, std::uint32_t{0x1FFFFFFF});
      get(cr, "extended", alarm_.can_extended);
      get(cr, "period_s", alarm_.can_period_s, 0.01, 60.0);
      if (cr.read_choice("timer", alarm_.can_kernel_timer, {{"auto", true}, {"daemon", false}}))
        note(cr, "timer");
      get(cr, "lease_s", alarm_.can_lease_s, 0.02, 60.0);
      if (!alarm_.can_extended && alarm_.can_id > 0x7FF) {
        cr.fail_value("id", "is above 0x7FF: set extended = true for a 29-bit id");
      }
      cr.finish();
    }
    r.finish();
  }

  void apply_training(const toml::table& t, const std::string& source) {
    remember_source(source);
    TableReader r(t, "training", source);
    get(r, "target_cycles", training_.target_cycles, std::uint32_t{1}, std::uint32_t{100000});
    get(r, "max_duration_s", training_.max_duration_s, 1.0, 1e7);
    get_path(r, "output", training_.output);
    get(r, "max_windows", training_.max_windows, std::uint32_t{16}, std::uint32_t{1000000});
    get(r, "max_regions", training_.max_regions, std::uint32_t{16}, std::uint32_t{1000000});
    get_path(r, "spill_dir", training_.spill_dir);
    r.finish();
  }

  void apply_history(const toml::table& t, const std::string& source) {
    remember_source(source);
    TableReader r(t, "history", source);
    get_path(r, "dir", history_.dir);
    get(r, "max_file_mib", history_.max_file_mib, 0.01, 4096.0);
    get(r, "files", history_.files, std::uint32_t{2}, std::uint32_t{1000});
    r.finish();
  }

  void apply_mqtt(const toml::table& t, const std::string& source) {
    remember_source(source);
    TableReader r(t, "mqtt", source);
    get(r, "enabled", mqtt_.enabled);
    if (r.read("host", mqtt_.host)) {
      note(r, "host");
      if (mqtt_.host.empty()) r.fail_value("host", "must not be empty (the broker's host name or address)");
    }
    get(r, "port", mqtt_.port, std::uint32_t{1}, std::uint32_t{65535});
    if (r.read("client_id", mqtt_.client_id)) {
      note(r, "client_id");
      if (mqtt_.client_id.size() > 23 * 4) r.fail_value("client_id", "is longer than 92 bytes");
    }
    if (r.read("topic_prefix", mqtt_.topic_prefix)) {
      note(r, "topic_prefix");
      const std::string& tp = mqtt_.topic_prefix;
      if (tp.empty() || tp.front() == '/' || tp.back() == '/' ||
          tp.find_first_of("#+") != std::string::npos || tp.find('\0') != std::string::npos) {
        r.fail_value("topic_prefix",
                     "must be a topic without wildcards (# +) and without a leading or trailing '/', not \"" +
                         tp + "\"");
      }
    }
    get(r, "keepalive_s", mqtt_.keepalive_s, std::uint32_t{5}, std::uint32_t{3600});
    get_path(r, "tls_ca_file", mqtt_.tls_ca_file);
    get_path(r, "tls_cert_file", mqtt_.tls_cert_file);
    get_path(r, "tls_key_file", mqtt_.tls_key_file);
    get(r, "username", mqtt_.username);
    get_path(r, "password_file", mqtt_.password_file);
    get_path(r, "queue_dir", mqtt_.queue_dir);
    double max_bytes = static_cast<double>(mqtt_.queue_max_bytes);
    if (r.read("queue_max_bytes", max_bytes, 65536.0, 1099511627776.0)) {
      note(r, "queue_max_bytes");
      if (max_bytes != std::floor(max_bytes))
        r.fail_value("queue_max_bytes", "must be a whole number of bytes");
      mqtt_.queue_max_bytes = static_cast<std::uint64_t>(max_bytes);
    }
    get(r, "window_summary_interval_s", mqtt_.window_summary_interval_s, 0.0, 86400.0);
    get(r, "reconnect_min_s", mqtt_.reconnect_min_s, 0.1, 3600.0);
    get(r, "reconnect_max_s", mqtt_.reconnect_max_s, 0.1, 86400.0);
    r.finish();
  }

  void remember_source(const std::string& source) {
    if (first_source_.empty()) first_source_ = source;
  }

  DaemonSection daemon_;
  AdcSection adc_;
  CanSection can_;
  AlarmSection alarm_;
  TrainingSection training_;
  HistorySection history_;
  MqttSection mqtt_;
  fs::path base_dir_;
  std::string first_source_;
  std::map<std::string, SourceLocation, std::less<>> set_at_;
};

}  // namespace

DaemonConfig load_daemon_config(const fs::path& main_file, const std::vector<fs::path>& dropins) {
  DaemonConfig out;
  config::PipelineConfigBuilder pipeline(daemon_owned_tables());
  DaemonTablesBuilder tables;
  std::vector<fs::path> files{main_file};
  files.insert(files.end(), dropins.begin(), dropins.end());
  for (const auto& file : files) {
    const toml::table root = config::read_toml_file(file);
    pipeline.apply(root, file.string());
    tables.apply(root, file.string(), file.parent_path());
    out.files.push_back(file);
  }
  out.pipeline = pipeline.finish();
  tables.finish(out);
  return out;
}

DaemonConfig parse_daemon_config(std::string_view toml_text, const std::string& source) {
  DaemonConfig out;
  config::PipelineConfigBuilder pipeline(daemon_owned_tables());
  DaemonTablesBuilder tables;
  const toml::table root = config::parse_toml(toml_text, source);
  pipeline.apply(root, source);
  tables.apply(root, source, fs::path());
  out.pipeline = pipeline.finish();
  tables.finish(out);
  return out;
}

fs::path training_spill_dir(const DaemonConfig& cfg) {
  if (!cfg.training.spill_dir.empty()) return cfg.training.spill_dir;
  const fs::path out = cfg.training.output.empty() ? cfg.daemon.baseline : cfg.training.output;
  return out.has_parent_path() ? out.parent_path() : fs::path(".");
}

std::vector<std::string> check_config_paths(const DaemonConfig& cfg, bool train) {
  std::vector<std::string> problems;
  std::error_code ec;
  if (train) {
    if (cfg.pipeline.domain == dsp::Domain::kOrder) {
      problems.push_back(
          "[extraction] domain = \"order\": field training (ptdad --train) collects "
          "time-domain windows only; train an order baseline with `ptda train`");
    }
    const fs::path out = cfg.training.output.empty() ? cfg.daemon.baseline : cfg.training.output;
    const fs::path dir = out.has_parent_path() ? out.parent_path() : fs::path(".");
    if (!fs::is_directory(dir, ec)) {
      problems.push_back("[training] output / [daemon] baseline " + out.string() + ": the directory " +
                         dir.string() + " does not exist, so field training could not write the baseline");
    }
    if (!cfg.training.spill_dir.empty() && !fs::is_directory(cfg.training.spill_dir, ec)) {
      problems.push_back("[training] spill_dir " + cfg.training.spill_dir.string() +
                         ": not a directory, so field training has nowhere to keep its windows");
    }
  } else {
    try {
      const dsp::Baseline b = formats::read_baseline(cfg.daemon.baseline);
      const bool order = cfg.pipeline.domain == dsp::Domain::kOrder;
      if (b.domain != cfg.pipeline.domain) {
        problems.push_back("[daemon] baseline " + cfg.daemon.baseline.string() + " was trained in the " +
                           dsp::domain_name(b.domain) + " domain but [extraction] domain is \"" +
                           dsp::domain_name(cfg.pipeline.domain) +
                           "\": use the job's configuration or retrain");
      } else if (order && (b.samples_per_rev != cfg.pipeline.order.samples_per_rev ||
                           b.revolutions != cfg.pipeline.order.revolutions)) {
        problems.push_back(
            "[daemon] baseline " + cfg.daemon.baseline.string() + " has samples_per_rev = " +
            std::to_string(b.samples_per_rev) + ", revolutions = " + std::to_string(b.revolutions) +
            " but [extraction] sets samples_per_rev = " + std::to_string(cfg.pipeline.order.samples_per_rev) +
            ", revolutions = " + std::to_string(cfg.pipeline.order.revolutions));
      } else if (b.window_len != cfg.pipeline.extraction.window_len) {
        problems.push_back(
            "[daemon] baseline " + cfg.daemon.baseline.string() + " was trained with window_len " +
            std::to_string(b.window_len) + " but [extraction] window_len is " +
            std::to_string(cfg.pipeline.extraction.window_len) + ": use the job's configuration or retrain");
      }
      // Order domain: the baseline's fs_hz is S (samples per revolution), not the ADC rate.
      if (!order && b.domain == cfg.pipeline.domain && cfg.pipeline.fs_hz != 0.0 &&
          std::fabs(b.fs_hz - cfg.pipeline.fs_hz) > 1e-9 * b.fs_hz) {
        problems.push_back("[daemon] baseline " + cfg.daemon.baseline.string() + " was trained at " +
                           std::to_string(b.fs_hz) + " Hz but [acquisition] fs_hz is " +
                           std::to_string(cfg.pipeline.fs_hz));
      }
    } catch (const Error& e) {
      problems.push_back(
          "[daemon] baseline: " + std::string(e.what()) +
          ": without a baseline the daemon refuses monitoring. Train one (ptda train, or ptdad "
          "--train; check that with --check-config --train) or fix the path");
    }
  }
  if (cfg.adc.backend == AdcBackend::kWav) {
    try {
      const formats::RecordingMeta meta = formats::read_recording_meta(cfg.adc.recording);
      formats::WavReader wav(cfg.adc.recording / meta.vibration_file);
      if (cfg.can.backend == CanBackend::kCandump && cfg.can.replay_file.empty() &&
          !fs::is_regular_file(cfg.adc.recording / meta.can_file, ec)) {
        problems.push_back("[adc] recording " + cfg.adc.recording.string() + ": its CAN log " +
                           (cfg.adc.recording / meta.can_file).string() + " does not exist");
      }
    } catch (const Error& e) {
      problems.push_back("[adc] recording: " + std::string(e.what()));
    }
  } else if (cfg.adc.backend == AdcBackend::kSim) {
    try {
      (void)sim::load_scenario(cfg.adc.scenario);
    } catch (const Error& e) {
      problems.push_back("[adc] scenario: " + std::string(e.what()));
    }
  } else {
    for (const fs::path& p : {cfg.adc.sysfs_dir, cfg.adc.device}) {
      if (!fs::exists(p, ec))
        problems.push_back("[adc] " + p.string() +
                           " does not exist (is the IIO driver loaded? see docs/drivers.md)");
    }
  }
  if (cfg.can.backend == CanBackend::kCandump && !cfg.can.replay_file.empty() &&
      !fs::is_regular_file(cfg.can.replay_file, ec)) {
    problems.push_back("[can] replay_file " + cfg.can.replay_file.string() +
                       " does not exist or is not a file");
  }
  return problems;
}

}  // namespace ptda::daemon
