#include "ptda/cli/csv_import.hpp"

#include <zlib.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <string_view>
#include <system_error>

#include "ptda/common/error.hpp"
#include "ptda/common/time.hpp"
#include "ptda/formats/candump.hpp"
#include "ptda/formats/recording.hpp"
#include "ptda/formats/wav.hpp"

namespace ptda::cli {

namespace fs = std::filesystem;

namespace {

/// Streams lines out of a plain or gzip file through zlib.
class GzLineReader {
 public:
  explicit GzLineReader(const fs::path& path) : path_(path.string()) {
    std::error_code ec;
    if (!fs::exists(path, ec)) throw Error(path_ + ": file does not exist");
    if (fs::is_directory(path, ec)) throw Error(path_ + ": is a directory, expected a CSV file");
    f_ = gzopen(path_.c_str(), "rb");
    if (f_ == nullptr) throw Error(path_ + ": cannot open");
    buf_.resize(1 << 16);
  }
  ~GzLineReader() {
    if (f_ != nullptr) gzclose(f_);
  }
  GzLineReader(const GzLineReader&) = delete;
  GzLineReader& operator=(const GzLineReader&) = delete;

  /// Next line without the end-of-line characters; false at the end of the file. A last line without
  /// '\n' is returned too.
  bool next(std::string& line) {
    line.clear();
    bool any = false;
    for (;;) {
      if (pos_ == len_) {
        if (eof_) {
          if (!any) return false;
          break;
        }
        const int n = gzread(f_, buf_.data(), static_cast<unsigned>(buf_.size()));
        if (n < 0) {
          int errnum = 0;
          const char* msg = gzerror(f_, &errnum);
          throw Error(path_ + ":" + std::to_string(line_no_ + 1) + ": read error: " +
                      (msg != nullptr ? msg : "unknown zlib error") + " (truncated or corrupt gzip?)");
        }
        if (n == 0) {
          // zlib reports a truncated gzip stream (Z_BUF_ERROR) only through gzerror at the end.
          int errnum = Z_OK;
          const char* msg = gzerror(f_, &errnum);
          if (errnum != Z_OK) {
            throw Error(path_ + ":" + std::to_string(line_no_ + 1) + ": read error: " +
                        (msg != nullptr ? msg : "unknown zlib error") + " (truncated or corrupt gzip?)");
          }
          eof_ = true;
          continue;
        }
        pos_ = 0;
        len_ = static_cast<std::size_t>(n);
      }
      any = true;
      const char* begin = buf_.data() + pos_;
      const void* nl = std::memchr(begin, '\n', len_ - pos_);
      if (nl == nullptr) {
        line.append(begin, len_ - pos_);
        pos_ = len_;
        continue;
      }
      const auto n = static_cast<std::size_t>(static_cast<const char*>(nl) - begin);
      line.append(begin, n);
      pos_ += n + 1;
      break;
    }
    ++line_no_;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    return true;
  }
  /// Number of the line returned last (1-based).
  [[nodiscard]] long line_no() const noexcept { return line_no_; }

 private:
  std::string path_;
  gzFile f_ = nullptr;
  std::vector<char> buf_;
  std::size_t pos_ = 0, len_ = 0;
  bool eof_ = false;
  long line_no_ = 0;
};

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

std::vector<std::string_view> split(std::string_view line) {
  std::vector<std::string_view> cells;
  std::size_t start = 0;
  for (;;) {
    const auto comma = line.find(',', start);
    if (comma == std::string_view::npos) {
      cells.push_back(line.substr(start));
      return cells;
    }
    cells.push_back(line.substr(start, comma - start));
    start = comma + 1;
  }
}

bool is_blank(std::string_view s) {
  return trim(s).empty();
}

}  // namespace

CsvColumn read_csv_column(const fs::path& path, const std::string& column) {
  const std::string file = path.string();
  GzLineReader reader(path);
  std::string line;
  auto next_line = [&]() -> bool { return reader.next(line); };
  if (!next_line() || is_blank(line)) {
    throw Error(file, 1, 0, "empty file or blank first line: expected a header line of column names");
  }
  std::string_view header = line;
  if (header.substr(0, 3) == "\xEF\xBB\xBF") header.remove_prefix(3);  // UTF-8 byte order mark
  std::vector<std::string> names;
  for (auto cell : split(header)) {
    cell = trim(cell);
    if (cell.size() >= 2 && cell.front() == '"' && cell.back() == '"') cell = cell.substr(1, cell.size() - 2);
    names.emplace_back(cell);
  }

  CsvColumn out;
  out.columns = names.size();
  const auto named = std::count(names.begin(), names.end(), column);
  if (named > 1) {
    throw Error(file, 1, 0,
                "column name '" + column + "' appears " + std::to_string(named) + " times in the header");
  }
  if (named == 1) {
    out.index = static_cast<std::size_t>(std::find(names.begin(), names.end(), column) - names.begin());
  } else {
    std::size_t idx = 0;
    const auto r = std::from_chars(column.data(), column.data() + column.size(), idx);
    if (column.empty() || r.ec != std::errc{} || r.ptr != column.data() + column.size()) {
      std::string list;
      for (const auto& n : names) list += (list.empty() ? "" : ", ") + n;
      throw Error(file, 1, 0, "no column named '" + column + "' (header: " + list + ")");
    }
    if (idx >= names.size()) {
      throw Error(file, 1, 0,
                  "column index " + column + " out of range: the header has " + std::to_string(names.size()) +
                      " column(s) (0-based)");
    }
    out.index = idx;
  }
  out.name = names[out.index];

  long blank_line = 0;
  while (next_line()) {
    const long line_no = reader.line_no();
    if (is_blank(line)) {
      if (blank_line == 0) blank_line = line_no;
      continue;
    }
    if (blank_line != 0) {
      throw Error(file, blank_line, 0, "blank line inside the data (only allowed at the end of the file)");
    }
    const auto cells = split(line);
    if (cells.size() != names.size()) {
      throw Error(
          file, line_no, static_cast<long>(std::min(cells.size(), names.size()) + 1),
          std::to_string(cells.size()) + " cell(s) but the header has " + std::to_string(names.size()));
    }
    for (std::size_t c = 0; c < cells.size(); ++c) {
      const std::string_view cell = trim(cells[c]);
      const auto col = static_cast<long>(c + 1);
      if (cell.empty()) throw Error(file, line_no, col, "empty cell in column '" + names[c] + "'");
      const char* begin = cell.data();
      if (*begin == '+') ++begin;
      double v = 0.0;
      const auto r = std::from_chars(begin, cell.data() + cell.size(), v);
      if (r.ec == std::errc::result_out_of_range) {
        throw Error(file, line_no, col, "number out of range '" + std::string(cell) + "'");
      }
      if (r.ec != std::errc{} || r.ptr != cell.data() + cell.size()) {
        throw Error(file, line_no, col,
                    "not a number '" + std::string(cell) + "' in column '" + names[c] + "'");
      }
      if (!std::isfinite(v)) {
        throw Error(file, line_no, col,
                    "not a finite number '" + std::string(cell) + "' in column '" + names[c] + "'");
      }
      if (c == out.index) {
        if (std::abs(v) > static_cast<double>(std::numeric_limits<float>::max())) {
          throw Error(file, line_no, col,
                      "value " + std::string(cell) + " does not fit a float32 WAV sample");
        }
        out.values.push_back(static_cast<float>(v));
      }
    }
    ++out.data_rows;
  }
  if (out.data_rows == 0) throw Error(file, 0, 0, "no data rows after the header line");
  return out;
}

ImportSummary import_csv(const ImportOptions& o) {
  if (!(o.rate_hz > 0.0) || o.rate_hz != std::floor(o.rate_hz) || o.rate_hz > 4.0e9) {
    throw Error(
        "--rate: the sample rate must be a positive whole number of Hz (WAV stores integer rates), got " +
        std::to_string(o.rate_hz));
  }
  if (!std::isfinite(o.shaft_speed_rad_s) || o.shaft_speed_rad_s == 0.0) {
    throw Error("--shaft-speed: must be finite and non-zero");
  }
  const double max_speed =
      static_cast<double>(std::numeric_limits<std::int32_t>::max()) * o.speed_frame.speed.scale;
  if (o.speed_frame.speed.length == 4 && std::abs(o.shaft_speed_rad_s) > max_speed) {
    throw Error("--shaft-speed: " + std::to_string(o.shaft_speed_rad_s) +
                " rad/s does not fit the speed frame (max " + std::to_string(max_speed) + " rad/s)");
  }
  if (!std::isfinite(o.scale) || o.scale == 0.0) throw Error("--scale: must be finite and non-zero");
  config::validate(o.speed_frame);

  CsvColumn col = read_csv_column(o.csv, o.column);
  ImportSummary summary;
  summary.column_name = col.name;
  summary.column_index = col.index;
  summary.samples = col.values.size();
  summary.duration_s = static_cast<double>(col.values.size()) / o.rate_hz;
  const auto [mn, mx] = std::minmax_element(col.values.begin(), col.values.end());
  summary.min_value = *mn;
  summary.max_value = *mx;
  double sq = 0.0;
  for (const float v : col.values) sq += static_cast<double>(v) * static_cast<double>(v);
  summary.rms = std::sqrt(sq / static_cast<double>(col.values.size()));

  std::error_code ec;
  fs::create_directories(o.out_dir, ec);
  if (ec) throw Error(o.out_dir.string() + ": cannot create directory: " + ec.message());

  formats::RecordingMeta meta;
  meta.start_time_s = o.start_time_s;
  meta.scale = o.scale;
  meta.unit = o.unit;
  const auto rate = static_cast<std::uint32_t>(o.rate_hz);
  std::vector<std::vector<float>> channels;
  channels.push_back(std::move(col.values));
  formats::write_wav(o.out_dir / meta.vibration_file, rate, formats::WavSampleFormat::kFloat32, channels);

  // Constant-speed CAN log: one frame per period from sample 0 until one period past the last sample.
  const double period = o.speed_frame.period_s;
  const auto frames = static_cast<std::uint64_t>(std::ceil(summary.duration_s / period)) + 1;
  std::vector<formats::CandumpRecord> records;
  records.reserve(frames);
  const std::int64_t t0_ns = seconds_to_ns(o.start_time_s);
  constexpr double kTwoPi = 2.0 * std::numbers::pi;
  for (std::uint64_t i = 0; i < frames; ++i) {
    const double t = static_cast<double>(i) * period;
    double angle = std::fmod(o.shaft_speed_rad_s * t, kTwoPi);
    if (angle < 0.0) angle += kTwoPi;
    formats::CandumpRecord rec;
    rec.frame = config::encode_speed(o.speed_frame, t0_ns + seconds_to_ns(t), o.shaft_speed_rad_s, angle);
    rec.iface = "can0";
    records.push_back(rec);
  }
  formats::write_candump(o.out_dir / meta.can_file, records);
  summary.speed_frames = records.size();
  formats::write_recording_meta(o.out_dir, meta);
  return summary;
}

}  // namespace ptda::cli
