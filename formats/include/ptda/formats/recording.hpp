// A recording directory: recording.toml + a WAV file + a candump log (+ truth.toml from the simulator,
// which no analysis command reads). Layout and keys: docs/recording-format.md. Offline code: any thread,
// blocks on file I/O, allocates, throws ptda::Error.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

namespace ptda::formats {

struct RecordingMeta {
  std::string vibration_file = "vibration.wav";  ///< relative to the directory
  std::uint16_t channel = 0;                     ///< 0-based
  double start_time_s = 0.0;                     ///< UNIX seconds of sample 0 (CAN log clock)
  double scale = 1.0;                            ///< stored sample value * scale = value in `unit`
  std::string unit = "m/s^2";
  std::string can_file = "can.log";  ///< relative to the directory
};

/// Reads and validates DIR/recording.toml (format = "ptda-recording", version = 1; every key checked,
/// referenced files must exist, `channel` must exist in the WAV, whose header is read to check). Throws
/// ptda::Error with file, line and column of the bad key or value.
[[nodiscard]] RecordingMeta read_recording_meta(const std::filesystem::path& dir);
/// Writes DIR/recording.toml (creates DIR); floats are written in shortest round-trip form, so they
/// read back bit-identical. Does not check that the referenced files exist. Throws ptda::Error.
void write_recording_meta(const std::filesystem::path& dir, const RecordingMeta& meta);

}  // namespace ptda::formats
