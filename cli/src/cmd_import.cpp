// ptda import --csv FILE --column NAME_OR_INDEX --rate HZ --shaft-speed SPEED --out DIR [...]
#include <unistd.h>

#include <filesystem>
#include <ostream>
#include <string>
#include <system_error>

#include "ptda/cli/args.hpp"
#include "ptda/cli/commands.hpp"
#include "ptda/cli/csv_import.hpp"
#include "ptda/cli/text.hpp"
#include "ptda/common/error.hpp"

namespace ptda::cli {
namespace {

namespace fs = std::filesystem;

/// Removes a partly written import directory when the import fails (issue 14 item 9: a failed
/// import left an empty directory behind).
class TempDirGuard {
 public:
  explicit TempDirGuard(fs::path dir) : dir_(std::move(dir)) {}
  ~TempDirGuard() {
    if (!dir_.empty()) {
      std::error_code ec;
      fs::remove_all(dir_, ec);
    }
  }
  TempDirGuard(const TempDirGuard&) = delete;
  TempDirGuard& operator=(const TempDirGuard&) = delete;
  void release() { dir_.clear(); }

 private:
  fs::path dir_;
};

}  // namespace

int cmd_import(std::span<const std::string> args, std::ostream& out) {
  ArgParser parser(
      "import", "--csv FILE --column NAME_OR_INDEX --rate HZ --shaft-speed SPEED --out DIR [options]",
      "Turns one column of a CSV or gzip-compressed CSV file (header line, then one sample per line) into a\n"
      "recording directory: a float32 WAV and a generated CAN log with a constant-speed frame every 4 ms.\n"
      "For imported data the CAN \"joint\" speed is the speed of the measured shaft. Every malformed cell "
      "is\n"
      "an error naming file, line and column.");
  parser.option("csv", "FILE", "CSV or CSV.gz input", true)
      .option("column", "NAME_OR_INDEX", "header name, or 0-based index when no header name matches", true)
      .option("rate", "HZ", "sample rate in Hz (a whole number)", true)
      .option("shaft-speed", "SPEED", "constant shaft speed with unit: 30Hz, 30rev/s, 1800rpm, 188.5rad/s",
              true)
      .option("out", "DIR", "recording directory to write (created; must not exist unless --force)", true)
      .flag("force", "replace an existing --out directory (only once the import has succeeded)")
      .option("unit", "UNIT", "physical unit of the values (default m/s^2)")
      .option("scale", "X", "stored value * X = value in UNIT (default 1)")
      .option("start-time", "UNIX_S", "UNIX time of the first sample in seconds (default 0)");
  const ParsedArgs a = parser.parse(args);
  if (a.help()) {
    out << parser.help_text();
    return kExitOk;
  }
  ImportOptions o;
  o.csv = a.value("csv");
  o.column = a.value("column");
  o.rate_hz = parse_double_arg(a.value("rate"), "rate");
  if (!(o.rate_hz > 0.0) || o.rate_hz != static_cast<double>(static_cast<std::uint64_t>(o.rate_hz)) ||
      o.rate_hz > 4.0e9) {
    throw UsageError("--rate: need a positive whole number of Hz (WAV stores integer rates), got '" +
                     a.value("rate") + "'");
  }
  o.shaft_speed_rad_s = parse_speed_rad_s(a.value("shaft-speed"), "shaft-speed");
  const fs::path out_dir = a.value("out");
  const bool force = a.has("force");
  std::error_code ec;
  if (fs::exists(fs::symlink_status(out_dir, ec)) && !force)
    throw Error(out_dir.string() + ": already exists; pass --force to replace it");
  // Written into a sibling directory first and renamed at the end: a failure removes it and leaves
  // an existing --out untouched.
  fs::path parent = out_dir.parent_path();
  if (parent.empty()) parent = ".";
  const fs::path tmp_dir = parent / ("." + out_dir.filename().string() + ".import-tmp." +
                                     std::to_string(static_cast<long>(::getpid())));
  fs::remove_all(tmp_dir, ec);
  o.out_dir = tmp_dir;
  o.unit = a.value_or("unit", "m/s^2");
  if (a.has("scale")) {
    o.scale = parse_double_arg(a.value("scale"), "scale");
    if (o.scale == 0.0) throw UsageError("--scale: must be non-zero");
  }
  if (a.has("start-time")) o.start_time_s = parse_double_arg(a.value("start-time"), "start-time");

  TempDirGuard guard(tmp_dir);
  const ImportSummary s = import_csv(o);
  if (fs::exists(fs::symlink_status(out_dir, ec))) {
    fs::remove_all(out_dir, ec);  // --force (checked above)
    if (ec) throw Error(out_dir.string() + ": cannot replace: " + ec.message());
  }
  fs::rename(tmp_dir, out_dir, ec);
  if (ec) throw Error(out_dir.string() + ": cannot move the import into place: " + ec.message());
  guard.release();
  out << "imported " << a.value("csv") << " column '" << s.column_name << "' (index " << s.column_index
      << ") into " << a.value("out") << "\n";
  out << "  samples      " << s.samples << " at " << general(o.rate_hz, 10)
      << " Hz = " << fixed(s.duration_s, 3) << " s\n";
  out << "  values       min " << general(s.min_value) << ", max " << general(s.max_value) << ", rms "
      << general(s.rms) << " (stored; scale " << general(o.scale) << " -> " << o.unit << ")\n";
  out << "  shaft speed  " << fixed(o.shaft_speed_rad_s, 4)
      << " rad/s = " << fixed(o.shaft_speed_rad_s / (2.0 * 3.14159265358979323846), 4)
      << " rev/s, written as the joint speed in " << s.speed_frames << " CAN frames (id 0x" << std::hex
      << o.speed_frame.id << std::dec << " every " << fixed(o.speed_frame.period_s * 1000.0, 1) << " ms)\n";
  return kExitOk;
}

}  // namespace ptda::cli
