// The subcommands of `ptda`. Each takes its arguments (after the subcommand name) and writes its normal
// output to `out`; errors are thrown (UsageError -> exit 2, ptda::Error -> exit 1) and turned into
// "ptda <cmd>: <what and where>" on stderr by run_cli(). Thread: the main thread of the tool.
#pragma once

#include <iosfwd>
#include <span>
#include <string>

namespace ptda::cli {

inline constexpr int kExitOk = 0;
inline constexpr int kExitFailure = 1;  ///< data or runtime error (bad file, mismatch, I/O)
inline constexpr int kExitUsage = 2;    ///< the command line is wrong
/// `ptda monitor` judged nothing: no window was scored, or the run ended in "not judging" (coverage).
inline constexpr int kExitNotJudged = 3;
/// The inputs cannot work together (a commissioning mistake): `ptda doctor` found a problem, or `ptda
/// train` refused a recording whose vibration contradicts its CAN speed (docs/cli.md, exit statuses).
inline constexpr int kExitCommissioning = 4;

int cmd_simulate(std::span<const std::string> args, std::ostream& out);
int cmd_import(std::span<const std::string> args, std::ostream& out);
int cmd_train(std::span<const std::string> args, std::ostream& out);
int cmd_monitor(std::span<const std::string> args, std::ostream& out);
int cmd_report(std::span<const std::string> args, std::ostream& out);
int cmd_doctor(std::span<const std::string> args, std::ostream& out);
int cmd_evaluate(std::span<const std::string> args, std::ostream& out);
int cmd_gap(std::span<const std::string> args, std::ostream& out);
int cmd_gap_bench(std::span<const std::string> args, std::ostream& out);
int cmd_fleet(std::span<const std::string> args, std::ostream& out);

/// Dispatches args[0] as the subcommand ("--help"/"-h"/"help" or nothing: overview). Catches every
/// exception and returns the exit code; error text goes to err.
int run_cli(std::span<const std::string> args, std::ostream& out, std::ostream& err);

/// Text of `ptda --help`.
[[nodiscard]] std::string overview_help();

}  // namespace ptda::cli
