// ptdad: the condition-monitoring daemon (docs/daemon.md).
#include <spdlog/spdlog.h>

#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>
#include <string_view>

#include "core/daemon.hpp"
#include "core/daemon_config.hpp"
#include "core/logging.hpp"
#include "ptda/common/error.hpp"
#include "ptda/drivers/clock.hpp"

namespace {

constexpr int kExitOk = 0;
constexpr int kExitError = 1;
constexpr int kExitUsage = 2;

constexpr const char* kUsage =
    "usage: ptdad [--config FILE] [--config-dir DIR] [--check-config] [--train] [--status-dir DIR]\n"
    "             [--joint NAME] [--foreground] [--exit-at-end] [--help] [--version]\n"
    "\n"
    "Monitors a robot gearbox by phase-based time domain averaging: vibration from the ADC, joint speed\n"
    "from CAN, constant-speed windows, residual features against a trained baseline, k-of-n alarm on a\n"
    "GPIO line and/or a CAN frame. Runs as a systemd Type=notify service (docs/daemon.md).\n"
    "\n"
    "options:\n"
    "  --config FILE      main configuration (default /etc/ptda/ptda.toml)\n"
    "  --config-dir DIR   drop-ins DIR/*.toml applied in lexical order (default: conf.d next to FILE)\n"
    "  --check-config     validate the configuration and open every path it names (baseline, recording,\n"
    "                     scenario, devices; with --train the baseline's directory instead of the\n"
    "                     baseline) and exit: 0 = valid, 1 = \"file:line:column: what\" or a path problem\n"
    "  --train            field training: collect healthy windows, write the baseline, then monitor\n"
    "  --status-dir DIR   write status.json to DIR instead of [daemon] status_dir\n"
    "  --joint NAME       the joint's name instead of [daemon] joint (label joint=NAME on every metric;\n"
    "                     ptdad@NAME.service passes its instance)\n"
    "  --foreground       log to the terminal even under systemd (default: journal when\n"
    "                     $JOURNAL_STREAM is set, terminal otherwise)\n"
    "  --exit-at-end      exit 0 once a replay (adc wav / candump, sim without loop) is processed\n"
    "  -h, --help         show this help\n"
    "  --version          show the version\n"
    "\n"
    "test-only options (fault injection for the test suite; never use them in production):\n"
    "  --test-exit-after-windows N       stop after N processed windows\n"
    "  --test-stall-processing-after S   stop the processing thread's progress after S seconds\n"
    "\n"
    "signals: SIGTERM/SIGINT stop; SIGHUP reloads the configuration (an invalid one is rejected and\n"
    "the running configuration kept); SIGUSR1 clears a latched alarm (accepted only once the hold time\n"
    "passed and the condition is gone).\n"
    "exit codes: 0 stopped on request, 1 configuration or start-up error, 2 usage error.\n";

struct Cli {
  ptda::daemon::DaemonOptions options;
  bool check_only = false;
  bool foreground = false;
};

[[noreturn]] void usage_error(const std::string& what) {
  std::fprintf(stderr, "ptdad: %s\n(see ptdad --help)\n", what.c_str());
  std::exit(kExitUsage);
}

double parse_number(std::string_view opt, const std::string& text) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || end == nullptr || *end != '\0' || !(v >= 0.0)) {
    usage_error(std::string(opt) + ": expected a non-negative number, got '" + text + "'");
  }
  return v;
}

Cli parse_cli(int argc, char** argv) {
  Cli cli;
  for (int i = 1; i < argc; ++i) {
    const std::string_view a = argv[i];
    const auto value = [&]() -> std::string {
      if (i + 1 >= argc) usage_error(std::string(a) + " needs a value");
      return argv[++i];
    };
    if (a == "-h" || a == "--help") {
      std::fputs(kUsage, stdout);
      std::exit(kExitOk);
    } else if (a == "--version") {
      std::printf("ptdad %s\n", PTDA_VERSION);
      std::exit(kExitOk);
    } else if (a == "--config") {
      cli.options.config_file = value();
    } else if (a == "--config-dir") {
      cli.options.config_dir = std::filesystem::path(value());
    } else if (a == "--check-config") {
      cli.check_only = true;
    } else if (a == "--train") {
      cli.options.train = true;
    } else if (a == "--status-dir") {
      cli.options.status_dir = value();
      if (cli.options.status_dir.empty()) usage_error("--status-dir: empty path");
    } else if (a == "--joint") {
      cli.options.joint = value();
      if (!ptda::daemon::valid_joint_name(cli.options.joint)) {
        usage_error("--joint: '" + cli.options.joint +
                    "' is not a joint name (1 to 32 characters of A-Z, a-z, 0-9, '_', '.' and '-')");
      }
    } else if (a == "--foreground") {
      cli.foreground = true;
    } else if (a == "--exit-at-end") {
      cli.options.exit_at_end = true;
    } else if (a == "--test-exit-after-windows") {
      cli.options.exit_after_windows = static_cast<std::uint64_t>(parse_number(a, value()));
    } else if (a == "--test-stall-processing-after") {
      cli.options.stall_processing_after_s = parse_number(a, value());
    } else {
      usage_error("unknown option '" + std::string(a) + "'");
    }
  }
  return cli;
}

}  // namespace

int main(int argc, char** argv) {
  // A file size limit (LimitFSIZE=) must fail a write with EFBIG, which the writers count and report
  // (status files, the baseline, field training's spill file), not kill the daemon with SIGXFSZ.
  std::signal(SIGXFSZ, SIG_IGN);
  Cli cli = parse_cli(argc, argv);
  using namespace ptda::daemon;

  if (cli.check_only) {
    try {
      const std::filesystem::path dir =
          cli.options.config_dir ? *cli.options.config_dir : cli.options.config_file.parent_path() / "conf.d";
      const DaemonConfig cfg = load_daemon_config(cli.options.config_file, list_dropins(dir));
      for (const std::string& w : cfg.pipeline.warnings) std::fprintf(stderr, "warning: %s\n", w.c_str());
      // Syntax alone is not "valid": every path must open (a missing baseline or recording is an error).
      const std::vector<std::string> problems = check_config_paths(cfg, cli.options.train);
      for (const std::string& p : problems) {
        std::fprintf(stderr, "%s: %s\n", cli.options.config_file.c_str(), p.c_str());
      }
      if (!problems.empty()) return kExitError;
      std::printf("%s: configuration is valid (%zu file(s); adc %s, can %s, window %u samples, method %s)\n",
                  cli.options.config_file.c_str(), cfg.files.size(), adc_backend_name(cfg.adc.backend),
                  can_backend_name(cfg.can.backend), cfg.pipeline.extraction.window_len,
                  ptda::dsp::method_name(cfg.pipeline.method).data());
      return kExitOk;
    } catch (const std::exception& e) {
      std::fprintf(stderr, "%s\n", e.what());
      return kExitError;
    }
  }

  try {
    setup_logging(cli.foreground ? LogTarget::kTerminal : LogTarget::kAuto, "info");
    const char* notify = std::getenv("NOTIFY_SOCKET");
    cli.options.notify_socket = notify != nullptr ? notify : "";
    cli.options.watchdog = watchdog_settings_from_environment();
    ptda::drivers::MonotonicClock clock;
    Daemon daemon(cli.options, clock);
    daemon.configure();
    daemon.activate();
    return daemon.run();
  } catch (const std::exception& e) {
    spdlog::critical("{}", e.what());
    return kExitError;
  }
}
