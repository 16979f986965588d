#include <exception>
#include <filesystem>
#include <ostream>
#include <string_view>

#include "ptda/cli/args.hpp"
#include "ptda/cli/commands.hpp"
#include "ptda/common/error.hpp"

namespace ptda::cli {

namespace {

struct Command {
  std::string_view name;
  std::string_view summary;
  int (*run)(std::span<const std::string>, std::ostream&);
};

constexpr Command kCommands[] = {
    {"simulate", "simulate a robot joint + gearbox into a recording directory", &cmd_simulate},
    {"import", "turn one column of a CSV(.gz) file into a constant-speed recording", &cmd_import},
    {"doctor", "commissioning check: CAN id, speed scale, plateaus vs. window, baseline vs. job",
     &cmd_doctor},
    {"train", "learn the healthy baseline (segment classes, averages, thresholds)", &cmd_train},
    {"monitor", "score every window of a recording against a baseline (table + JSONL)", &cmd_monitor},
    {"report", "compare raw, TDA and PTDA over recordings in one HTML report", &cmd_report},
    {"evaluate", "separation of healthy and faulty windows: ratios and ROC AUC per feature", &cmd_evaluate},
    {"gap", "diagnose where and why a simulator departs from a measured recording", &cmd_gap},
    {"gap-bench", "score the gap diagnosis on simulated cases with withheld effects", &cmd_gap_bench},
    {"fleet", "live table of every joint publishing to an MQTT broker (ptdad [mqtt])", &cmd_fleet},
};

}  // namespace

std::string overview_help() {
  std::string s =
      "usage: ptda <command> [options]\n\n"
      "Condition monitoring of robot gearboxes by phase-based time domain averaging (PTDA).\n\n"
      "commands:\n";
  for (const auto& c : kCommands) {
    s += "  " + std::string(c.name) + std::string(10 - c.name.size(), ' ') + std::string(c.summary) + "\n";
  }
  s += "\n'ptda <command> --help' describes each command's options.\n"
       "exit codes: 0 ok, 1 data or runtime error, 2 usage error, 3 nothing cut or judged, 4 a\n"
       "commissioning mistake (run 'ptda doctor'); docs/cli.md lists them per command.\n";
  return s;
}

int run_cli(std::span<const std::string> args, std::ostream& out, std::ostream& err) {
  if (args.empty() || args[0] == "--help" || args[0] == "-h" || args[0] == "help") {
    if (args.empty()) {
      err << overview_help();
      return kExitUsage;
    }
    out << overview_help();
    return kExitOk;
  }
  const std::string& name = args[0];
  const Command* cmd = nullptr;
  for (const auto& c : kCommands) {
    if (c.name == name) cmd = &c;
  }
  if (cmd == nullptr) {
    err << "ptda: unknown command '" << name << "' (try 'ptda --help')\n";
    return kExitUsage;
  }
  try {
    const int rc = cmd->run(args.subspan(1), out);
    out.flush();
    return rc;
  } catch (const UsageError& e) {
    out.flush();
    err << "ptda " << name << ": " << e.what() << "\n(try 'ptda " << name << " --help')\n";
    return kExitUsage;
  } catch (const std::filesystem::filesystem_error& e) {
    out.flush();
    err << "ptda " << name << ": " << e.what() << "\n";
    return kExitFailure;
  } catch (const std::exception& e) {
    out.flush();
    err << "ptda " << name << ": " << e.what() << "\n";
    return kExitFailure;
  }
}

}  // namespace ptda::cli
