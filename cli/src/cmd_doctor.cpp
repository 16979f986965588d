// ptda doctor --recording DIR --config FILE [--baseline FILE]
#include <optional>
#include <ostream>

#include "ptda/cli/args.hpp"
#include "ptda/cli/commands.hpp"
#include "ptda/cli/doctor.hpp"
#include "ptda/cli/pipeline_runner.hpp"
#include "ptda/cli/text.hpp"
#include "ptda/common/error.hpp"
#include "ptda/config/pipeline_config.hpp"
#include "ptda/formats/baseline_file.hpp"

namespace ptda::cli {

int cmd_doctor(std::span<const std::string> args, std::ostream& out) {
  ArgParser parser(
      "doctor", "--recording DIR --config FILE [--baseline FILE]",
      "Commissioning check: does this recording, configuration (and baseline) fit together? Reports the\n"
      "CAN frames per id and the ones decoded as speed (and the likely speed id when it is another one),\n"
      "the speed range against [gearbox] and against the vibration's own GMF comb (a wrong speed scale\n"
      "shows as a factor), the plateau lengths per speed against the window, and the baseline's classes\n"
      "against the recording's speeds. In the order domain ([extraction] domain = \"order\"): the CAN angle\n"
      "against the integrated speed (a unit or scale mistake shows as a factor), the shaft speeds against "
      "the\n"
      "resampler's band, the windows of R revolutions cut and the share of the motion they cover.\n"
      "Each problem is one sentence with its fix. Exit 0 when nothing is\n"
      "wrong, 4 when a problem was found.");
  parser.option("recording", "DIR", "a recording of the joint doing its job", true)
      .option("config", "FILE", "pipeline configuration TOML", true)
      .option("baseline", "FILE", "baseline to check against the recording's speeds");
  const ParsedArgs a = parser.parse(args);
  if (a.help()) {
    out << parser.help_text();
    return kExitOk;
  }
  const std::string config_path = a.value("config");
  const config::PipelineConfig cfg = config::load_pipeline_config(config_path);
  const RecordingInfo rec = open_recording(a.value("recording"));
  std::optional<dsp::Baseline> baseline;
  if (a.has("baseline")) baseline = formats::read_baseline(a.value("baseline"));
  out << "doctor " << rec.dir.string() << " with " << config_path
      << (baseline ? " and " + a.value("baseline") : std::string()) << ": " << fixed(rec.duration_s, 2)
      << " s at " << general(static_cast<double>(rec.wav.sample_rate_hz), 10) << " Hz\n";
  for (const std::string& w : cfg.warnings) out << "note (config): " << w << "\n";
  const DoctorReport rep = diagnose_commissioning(rec, cfg, config_path, baseline ? &*baseline : nullptr,
                                                  a.value_or("baseline", ""));
  print_diagnosis(out, rep);
  if (rep.problems()) {
    out << "doctor: problems found (see PROBLEM lines)\n";
    return kExitCommissioning;
  }
  out << "doctor: no problem found: the recording, the configuration" << (baseline ? " and the baseline" : "")
      << " fit together\n";
  return kExitOk;
}

}  // namespace ptda::cli
