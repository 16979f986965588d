// The cabinet's event history (issue 15 item 3): every judged or cut window and every change of the
// daemon's state or alarm level, appended as JSON Lines to <dir>/history.jsonl, rotated by size into
// history.1.jsonl ... history.<files-1>.jsonl (the oldest dropped), so the whole history is bounded by
// max_file_bytes x files. Format and fsync policy: docs/fleet.md, "Event history".
//
// Written by the supervisor only (never by the real-time threads): the processing thread hands the
// windows over through Pipeline's window log ring. The line buffer is allocated at construction;
// writing a line does not allocate. Failures are counted and the line is dropped (counted), never
// retried out of order.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "ptda/dsp/monitor_engine.hpp"
#include "status/status_writer.hpp"

namespace ptda::daemon {

struct HistoryConfig {
  std::filesystem::path dir;                    ///< history.jsonl and its rotations go here
  std::uint64_t max_file_bytes = 16ULL << 20U;  ///< rotate before a line would pass this size
  std::uint32_t files = 8;                      ///< history.jsonl + files - 1 rotations (>= 2)
  std::string joint;                            ///< "joint" on every line ("" = none)
  std::string method;                           ///< the monitoring method, on window lines
};

struct HistoryCounters {
  std::uint64_t lines = 0;              ///< lines written
  std::uint64_t bytes = 0;              ///< bytes written (all files)
  std::uint64_t rotations = 0;          ///< files rotated
  std::uint64_t rotation_failures = 0;  ///< the current file could not be moved aside: history stopped
  std::uint64_t write_failures = 0;     ///< lines lost to a failed open/write/rename (dropped, counted)
  int last_errno = 0;                   ///< of the latest failure (0: none)
  std::uint64_t ring_dropped = 0;       ///< windows the ring could not hold (filled in by the daemon)
  std::uint64_t cut_bytes = 0;          ///< a partial last line (power loss) cut off when the file was opened
};

/// One window as a history line: the fields of `ptda monitor --jsonl` (cli window_json) plus
/// "type":"window", the joint, and the wall time of the window's end.
class HistoryLog {
 public:
  /// Creates `dir` (0750) when missing and opens history.jsonl for appending. Throws ptda::Error naming
  /// the directory when it cannot. Thread: the supervisor. Allocates, blocks on I/O.
  explicit HistoryLog(HistoryConfig cfg);
  ~HistoryLog();
  HistoryLog(const HistoryLog&) = delete;
  HistoryLog& operator=(const HistoryLog&) = delete;

  /// A window (scored or not) whose end is at wall time `end_unix_ns`. Thread: the supervisor. Never
  /// allocates; blocks on the write.
  void window(const dsp::WindowResult& w, std::int64_t end_unix_ns) noexcept;
  /// A state or alarm change: "type":"state" with the daemon state, phase, alarm level, causes (text)
  /// and reason. Thread: the supervisor. Never allocates; blocks on the write.
  void state(std::int64_t unix_ns, std::string_view state, std::string_view phase, std::string_view level,
             std::string_view causes, std::string_view reason) noexcept;

  [[nodiscard]] const HistoryCounters& counters() const noexcept { return counters_; }
  [[nodiscard]] HistoryCounters& counters() noexcept { return counters_; }
  [[nodiscard]] const std::filesystem::path& current_path() const noexcept { return path_; }
  /// history.jsonl (k = 0) or history.<k>.jsonl.
  [[nodiscard]] std::filesystem::path file(std::uint32_t k) const;

 private:
  void write_line(std::size_t len) noexcept;  ///< line_[0..len) ends in '\n'
  /// '{' and the members every line starts with: type, joint (when set), t_utc.
  void begin_line(JsonWriter& o, std::string_view type, std::int64_t unix_ns) const noexcept;
  /// '}' and '\n', then the write (an overflowing line is dropped and counted).
  void finish_line(TextBuffer& b, JsonWriter& o) noexcept;
  bool open_current() noexcept;
  void rotate() noexcept;

  HistoryConfig cfg_;
  std::filesystem::path path_;
  std::vector<std::string> rotated_;  ///< the rotation names, built once (rename() needs C strings)
  std::vector<char> line_;
  int fd_ = -1;
  std::uint64_t size_ = 0;        ///< of the current file
  bool rotation_failed_ = false;  ///< no more lines past the size bound (see rotate())
  HistoryCounters counters_;
};

}  // namespace ptda::daemon
