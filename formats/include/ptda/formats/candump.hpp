// The `candump -l` log format: "(seconds.microseconds) iface FRAME [R|T]".
// FRAME: 3-hex standard or 8-hex extended id; "#" classic data (0..8 bytes, '.' separators allowed),
// "#R" / "#R<dlc>" remote frames, "##<flags-nibble><data>" CAN FD (0..64 bytes), error frames as
// 8-hex ids with CAN_ERR_FLAG (0x20000000). Newer can-utils suffixes ("_<dlc>") and CAN XL lines are
// accepted and their extra fields ignored (CAN XL lines are skipped like comments, since CanFrame cannot
// hold them). Lines not starting with '(' are comments (as canplayer). Offline code: throws ptda::Error.
#pragma once

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <iosfwd>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "ptda/common/can_frame.hpp"

namespace ptda::formats {

struct CandumpRecord {
  CanFrame frame;  ///< frame.t_ns = UNIX ns from the log timestamp
  std::string iface;
  char direction = 0;  ///< 'R', 'T' or 0 when absent
};

/// Parses one line. Returns std::nullopt for comment/blank lines (and CAN XL lines). Throws ptda::Error
/// "<source>:<line_no>: <what>" for a malformed line. Thread: any. Does not block; allocates only when
/// the iface name outgrows the capacity of `out.iface` (see the overload below).
[[nodiscard]] std::optional<CandumpRecord> parse_candump_line(std::string_view line,
                                                              const std::string& source, long line_no);

/// Parses into `out` (reusing its iface capacity). Returns false for comment/blank/CAN XL lines, leaving
/// `out` unspecified. Throws like parse_candump_line.
bool parse_candump_line_into(std::string_view line, const std::string& source, long line_no,
                             CandumpRecord& out);

namespace detail {
/// The fast path of parse_candump_line_into (exposed for tests): a classic data frame in candump's own
/// spelling, "(<1-18 digits>.<1-9 digits>) <iface> <3 or 8 hex digits>#<0-8 hex byte pairs>[ R|T]"
/// with single spaces and a standard id up to 7FF or an extended one up to 1FFFFFFF. Fills `out` as
/// parse_candump_line_full does and returns true for such a line; returns false, leaving `out`
/// untouched, for any other line (which the full parser then accepts, skips or rejects). Expects the
/// line ending already stripped. Thread: any. Allocates (and can throw std::bad_alloc) only when the
/// iface name outgrows the capacity of `out.iface`, as parse_candump_line_into.
bool parse_common_candump_line(std::string_view line, CandumpRecord& out);
/// parse_candump_line_into without its fast path (exposed for tests). Throws like it.
bool parse_candump_line_full(std::string_view line, const std::string& source, long line_no,
                             CandumpRecord& out);
}  // namespace detail

/// Streaming reader: next() returns false at the end. Throws ptda::Error on a malformed line or a read
/// error. Thread: the owner's. Blocks on file I/O; after warm-up next() does not allocate.
class CandumpReader {
 public:
  explicit CandumpReader(const std::filesystem::path& path);
  ~CandumpReader();
  CandumpReader(const CandumpReader&) = delete;
  CandumpReader& operator=(const CandumpReader&) = delete;
  bool next(CandumpRecord& out);
  /// Back to the first line (line numbers and comment counts start again). Thread: the owner's. Never
  /// allocates or throws.
  void rewind() noexcept;
  [[nodiscard]] long line_no() const noexcept { return line_no_; }
  /// Non-blank lines skipped as comments (not starting with '(') so far, and the number of the first
  /// (0 when none): a file of only such lines is not a candump log (cli/pipeline_runner says so).
  [[nodiscard]] std::uint64_t comment_lines() const noexcept { return comment_lines_; }
  [[nodiscard]] long first_comment_line() const noexcept { return first_comment_line_; }

 private:
  std::filesystem::path path_;
  std::string source_;  // path_ as text, for error messages without a per-line conversion
  std::FILE* f_ = nullptr;
  long line_no_ = 0;
  std::uint64_t comment_lines_ = 0;
  long first_comment_line_ = 0;
  std::vector<char> buf_;  // file bytes: [begin_, end_) not yet consumed; sized once at construction
  std::size_t begin_ = 0;
  std::size_t end_ = 0;
  bool eof_ = false;
  // The next line without its '\n' (a view into buf_, valid until the next call); false at the end.
  // Throws ptda::Error (at line_no_ + 1) on a read error or a line longer than the limit.
  bool next_line(std::string_view& line);
};

/// Reads a whole log. Throws ptda::Error. Thread: any; blocks, allocates.
[[nodiscard]] std::vector<CandumpRecord> read_candump(const std::filesystem::path& path);

/// Formats one record exactly as `candump -l` does (timestamp with 6 decimals, truncated to whole
/// microseconds), without the newline. Throws ptda::Error for a record candump could not have written
/// (negative time, standard id above 0x7FF, too long payload, empty iface). Thread: any; allocates.
[[nodiscard]] std::string format_candump_line(const CandumpRecord& rec);
/// Writes one line per record. Throws ptda::Error naming the file. Thread: any; blocks, allocates.
void write_candump(const std::filesystem::path& path, const std::vector<CandumpRecord>& records);

/// Streaming candump writer: one line per write() (the same bytes as write_candump), close() flushes.
/// Throws ptda::Error naming the file (and the record's index for a record candump could not have
/// written). Thread: the owner's; blocks on file I/O; allocates.
class CandumpWriter {
 public:
  explicit CandumpWriter(const std::filesystem::path& path);
  ~CandumpWriter();
  CandumpWriter(const CandumpWriter&) = delete;
  CandumpWriter& operator=(const CandumpWriter&) = delete;

  void write(const CandumpRecord& rec);
  void close();
  [[nodiscard]] std::uint64_t records_written() const noexcept { return written_; }

 private:
  std::string name_;
  std::FILE* f_ = nullptr;
  std::uint64_t written_ = 0;
};

}  // namespace ptda::formats
