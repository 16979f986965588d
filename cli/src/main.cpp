// `ptda`: the offline tool (simulate, import, train, monitor, report). All logic lives in ptda_cli so
// tests can run the subcommands in-process; this file only adapts argv and the standard streams.
#include <iostream>
#include <string>
#include <vector>

#include "ptda/cli/commands.hpp"

int main(int argc, char** argv) {
  std::ios::sync_with_stdio(true);
  std::vector<std::string> args;
  args.reserve(static_cast<std::size_t>(argc > 1 ? argc - 1 : 0));
  for (int i = 1; i < argc; ++i) args.emplace_back(argv[i]);
  return ptda::cli::run_cli(args, std::cout, std::cerr);
}
