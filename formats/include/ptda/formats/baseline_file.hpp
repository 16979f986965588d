// Baseline store: a versioned little-endian binary file with a header (magic "PTDABASE", version,
// sample rate, window length, segment classes, gearbox, thresholds) and a CRC-32 over everything
// before it. Written atomically: temporary file in the same directory, fsync, rename, fsync(dir).
#pragma once

#include <filesystem>

#include "ptda/dsp/baseline.hpp"

namespace ptda::formats {

/// Throws ptda::Error (naming the path and the failed step); never leaves a partial file at `path`.
void write_baseline(const std::filesystem::path& path, const dsp::Baseline& baseline);

/// Throws ptda::Error when missing, truncated, corrupt (CRC), of another version or inconsistent,
/// saying which.
[[nodiscard]] dsp::Baseline read_baseline(const std::filesystem::path& path);

/// CRC-32 (IEEE 802.3, reflected, poly 0xEDB88320), as zlib's crc32. Exposed for tests.
[[nodiscard]] std::uint32_t crc32(const void* data, std::size_t len, std::uint32_t crc = 0) noexcept;

}  // namespace ptda::formats
