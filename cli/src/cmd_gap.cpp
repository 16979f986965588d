// ptda gap --scenario NOMINAL.toml --real DIR [--json OUT] [--html OUT] [--seed N] [--effects a,b]
//          [--motion measured|scenario]
#include <fstream>
#include <iostream>
#include <ostream>
#include <sstream>

#include "ptda/cli/args.hpp"
#include "ptda/cli/commands.hpp"
#include "ptda/common/error.hpp"
#include "ptda/gap/diagnose.hpp"
#include "ptda/sim/simulator.hpp"

namespace ptda::cli {
namespace {

void write_file(const std::string& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  if (!f) throw Error(path + ": cannot open for writing");
  f << text;
  f.flush();
  if (!f) throw Error(path + ": write failed");
}

std::vector<sim::EffectKind> parse_effect_list(const std::string& text) {
  std::vector<sim::EffectKind> out;
  std::stringstream ss(text);
  std::string name;
  while (std::getline(ss, name, ',')) {
    const auto k = sim::effect_kind_from_name(name);
    if (!k) throw UsageError("--effects: unknown effect '" + name + "'");
    out.push_back(*k);
  }
  return out;
}

}  // namespace

int cmd_gap(std::span<const std::string> args, std::ostream& out) {
  ArgParser parser(
      "gap",
      "--scenario NOMINAL.toml --real DIR [--json OUT] [--html OUT] [--seed N] [--effects LIST] [--threads "
      "N] [--motion measured|scenario]",
      "Diagnoses the sim-to-real gap: drives the nominal model along the recording's own CAN speed,\n"
      "calibrates its free parameters on the fit part of the measured recording DIR (split by the\n"
      "program period), fits each candidate effect there, and keeps effects that shrink the gap on the\n"
      "held-out part significantly (docs/gap.md).");
  parser.option("scenario", "FILE", "nominal scenario (what the model knows, [[effects]] included)", true)
      .option("real", "DIR", "measured recording directory (truth.toml, if any, is not read)", true)
      .option("json", "OUT", "write the diagnosis as JSON (schema ptda-gap v1)")
      .option("html", "OUT", "write an HTML report with plots")
      .option("seed", "N", "seed of the model simulations (default 9001)")
      .option("effects", "LIST", "comma-separated candidate effects (default: all)")
      .option("threads", "N", "fitting threads (default: one per CPU; the result does not depend on it)")
      .option("motion", "measured|scenario",
              "what the model's motion follows (default: the measured CAN speed when usable)")
      .flag("quiet", "no progress lines on stderr");
  const ParsedArgs a = parser.parse(args);
  if (a.help()) {
    out << parser.help_text();
    return kExitOk;
  }
  gap::DiagnoseOptions opt;  // options first: a usage error must not wait for the data
  if (a.has("seed")) opt.sim_seed = parse_u64_arg(a.value("seed"), "seed");
  if (a.has("effects")) opt.candidates = parse_effect_list(a.value("effects"));
  if (a.has("motion")) {
    const std::string& m = a.value("motion");
    if (m == "measured")
      opt.motion = gap::MotionSource::kMeasured;
    else if (m == "scenario")
      opt.motion = gap::MotionSource::kScenario;
    else
      throw UsageError("--motion: '" + m + "' is not measured or scenario");
  }
  if (a.has("threads")) opt.threads = static_cast<unsigned>(parse_u64_arg(a.value("threads"), "threads"));
  const sim::Scenario nominal = sim::load_scenario(a.value("scenario"));
  for (const std::string& w : nominal.warnings) std::cerr << "warning: " << w << "\n";
  const gap::GapRecording real =
      gap::load_recording(a.value("real"), nominal.can.speed_frame, nominal.can.delay_s);
  if (!a.has("quiet")) opt.log = [](const std::string& s) { std::cerr << "ptda gap: " << s << "\n"; };
  const gap::Diagnosis d = gap::diagnose(nominal, real, opt);
  if (a.has("json")) write_file(a.value("json"), gap::diagnosis_json(d));
  if (a.has("html")) write_file(a.value("html"), gap::diagnosis_html(d));
  out << d.verdict << "\n";
  out << "  motion        " << d.motion_note << "\n";
  out << "  held-out gap  " << d.nominal_heldout.total << " -> " << d.final_heldout.total
      << " (expected from sampling " << d.noise_gap << " +- " << d.noise_gap_sd << ")\n";
  out << "  where         ";
  bool first = true;
  for (const auto& [p, v] : d.nominal_heldout.by_probe) {
    if (v < 0.05 * d.nominal_heldout.total) continue;
    out << (first ? "" : ", ") << p << " " << static_cast<int>(100.0 * v / d.nominal_heldout.total + 0.5)
        << " %";
    first = false;
  }
  out << "\n  runtime       " << d.runtime_s << " s, " << d.simulations << " simulations\n";
  return kExitOk;
}

}  // namespace ptda::cli
