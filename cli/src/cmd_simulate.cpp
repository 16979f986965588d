// ptda simulate --scenario FILE --out DIR [--seed N]
#include <cmath>
#include <iostream>
#include <numbers>
#include <ostream>

#include "ptda/cli/args.hpp"
#include "ptda/cli/commands.hpp"
#include "ptda/cli/text.hpp"
#include "ptda/sim/simulator.hpp"

namespace ptda::cli {

int cmd_simulate(std::span<const std::string> args, std::ostream& out) {
  ArgParser parser("simulate", "--scenario FILE --out DIR [--seed N]",
                   "Simulates the scenario (joint motion, gearbox vibration, sensor, CAN speed frames) and\n"
                   "writes a recording directory: recording.toml, vibration.wav, can.log and truth.toml.");
  parser.option("scenario", "FILE", "scenario TOML (see config/scenarios/ and docs/simulator.md)", true)
      .option("out", "DIR", "recording directory to write (created)", true)
      .option("seed", "N", "random seed, overrides the scenario's seed");
  const ParsedArgs a = parser.parse(args);
  if (a.help()) {
    out << parser.help_text();
    return kExitOk;
  }
  std::optional<std::uint64_t> seed;
  if (a.has("seed")) seed = parse_u64_arg(a.value("seed"), "seed");
  const sim::Scenario scenario = sim::load_scenario(a.value("scenario"));
  for (const std::string& w : scenario.warnings) std::cerr << "warning: " << w << "\n";
  const sim::SimulationSummary s = sim::simulate_to_directory(scenario, a.value("out"), seed);

  out << "simulated '" << scenario.name << "' (seed " << s.seed << ") into " << a.value("out") << "\n";
  out << "  cycles        " << s.cycles << "\n";
  out << "  duration      " << fixed(s.duration_s, 3) << " s (" << s.samples << " samples at "
      << general(s.fs_hz, 8) << " Hz)\n";
  out << "  CAN frames    " << s.can_frames << " (" << s.speed_frames << " speed frames)\n";
  out << "  ratio         " << fixed(s.ratio, 4) << "\n";
  out << "  plateaus      ";
  if (s.plateau_speeds_rad_s.empty()) out << "none";
  for (std::size_t i = 0; i < s.plateau_speeds_rad_s.size(); ++i) {
    if (i > 0) out << ", ";
    out << fixed(s.plateau_speeds_rad_s[i], 4) << " rad/s";
    if (i < s.plateau_durations_s.size()) out << " for " << fixed(s.plateau_durations_s[i], 3) << " s";
  }
  out << "\n";
  out << "  GMF           " << fixed(s.gmf_hz_at_first_plateau, 2) << " Hz at the first plateau\n";
  if (s.harmonics_above_nyquist > 0) {
    out << "  note          " << s.harmonics_above_nyquist
        << " GMF harmonic(s) above Nyquist were left out\n";
  }
  if (s.clipped_samples > 0)
    out << "  clipped       " << s.clipped_samples << " samples at the sensor range\n";
  double max_sev = 0.0;
  for (const double v : s.severity_per_cycle) max_sev = std::max(max_sev, v);
  if (max_sev > 0.0) {
    std::size_t first = 0;
    while (first < s.severity_per_cycle.size() && s.severity_per_cycle[first] <= 0.0) ++first;
    out << "  fault         from cycle " << first << ", max severity " << fixed(max_sev, 3) << "\n";
  } else {
    out << "  fault         none (healthy)\n";
  }
  return kExitOk;
}

}  // namespace ptda::cli
