// `ptda import`: one column of a CSV or gzip-compressed CSV file becomes a recording directory
// (float32 WAV + a generated constant-speed CAN log). Thread: any (offline). Allocates; throws
// ptda::Error naming the file, line and column of bad input (no cell is ever skipped silently).
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "ptda/config/speed_codec.hpp"

namespace ptda::cli {

/// One numeric column of a CSV file.
struct CsvColumn {
  std::string name;           ///< header name of the column
  std::size_t index = 0;      ///< 0-based
  std::vector<float> values;  ///< one per data row, in file order
  std::size_t columns = 0;    ///< columns in the header
  long data_rows = 0;
};

/// Reads `column` of a CSV file, plain or gzip (detected by content; zlib streams either).
/// The first line is the header of column names (surrounding spaces and double quotes removed).
/// `column` is a header name, or a 0-based index when no header name equals it.
/// Every following line is one sample: all cells must be present and parse as finite numbers
/// (whole cell, surrounding spaces allowed). Blank lines are allowed only at the end of the file.
/// Errors: "<file>:<line>:<column>: <what>" (column 1-based as in editors, counted in cells).
[[nodiscard]] CsvColumn read_csv_column(const std::filesystem::path& path, const std::string& column);

struct ImportOptions {
  std::filesystem::path csv;
  std::string column;
  double rate_hz = 0.0;            ///< must be a positive integer (WAV stores integer rates)
  double shaft_speed_rad_s = 0.0;  ///< the measured shaft's speed, written as the CAN "joint" speed
  std::filesystem::path out_dir;
  std::string unit = "m/s^2";
  double scale = 1.0;                  ///< stored value * scale = value in unit
  double start_time_s = 0.0;           ///< UNIX seconds of sample 0
  config::SpeedFrameSpec speed_frame;  ///< default: 0x184 every 4 ms
};

struct ImportSummary {
  std::string column_name;
  std::size_t column_index = 0;
  std::uint64_t samples = 0;
  double duration_s = 0.0;
  std::uint64_t speed_frames = 0;
  float min_value = 0.0F;
  float max_value = 0.0F;
  double rms = 0.0;  ///< of the stored values
};

/// Reads the column and writes out_dir/{recording.toml, vibration.wav, can.log}. The CAN log holds a
/// speed frame every speed_frame.period_s from the start time until at least one period past the last
/// sample, with the constant shaft speed and the integrated angle (wrapped to [0, 2 pi)).
ImportSummary import_csv(const ImportOptions& options);

}  // namespace ptda::cli
