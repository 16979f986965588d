// `ptda report --history DIR`: the HTML trend report of a daemon's event history (docs/fleet.md,
// "Event history"): the feature trends against their class bands on a time axis in hours, the alarm
// episodes, the state changes and the counts, without example windows (the history keeps features,
// not samples).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "ptda/cli/report.hpp"

namespace ptda::cli {

struct HistoryReadOptions {
  double last_hours = 0.0;  ///< > 0: only lines of the last this many hours before the newest line
};

/// Reads DIR/history.<k>.jsonl (oldest first) and DIR/history.jsonl into report data, keeping a few
/// fields per line. A partial last line of the newest file (a power cut while writing) and any line that
/// is not a JSON object of a known type are left out with a note (the count, and "<file>:<line>: what"
/// of the first). Throws ptda::Error when DIR has no history file or no line with a time.
/// Thread: any. Allocates, reads files.
[[nodiscard]] ReportData history_report_data(const std::filesystem::path& dir, const HistoryReadOptions& opt);

}  // namespace ptda::cli
