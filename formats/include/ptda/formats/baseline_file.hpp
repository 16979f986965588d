// Baseline store: a versioned little-endian binary file with a header (magic "PTDABASE", version,
// sample rate, window length, segment classes, gearbox, thresholds) and a CRC-32 over everything
// before it. Written atomically: temporary file in the same directory, fsync, rename, fsync(dir).
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "ptda/dsp/baseline.hpp"

namespace ptda::formats {

/// Layout version written by this build (docs/recording-format.md describes it). Version 2 added the
/// threshold confidence and hold-out fraction, per class the ln(rms_res) statistics, windows per hour
/// and hold-out results, and after the source text the training recordings. Version 1 files are still
/// read (log statistics derived from the linear ones, no hold-out, no training list). Version 3 appends
/// option flags before the CRC (bit 0: PTDA line gain); versions 1 and 2 read with no options. Version 4
/// appends the between-day floor and per class and method the day spread (dsp::DaySpread); versions
/// 1 to 3 read with floor 0 and no day spread (the session-6 standardisation, same verdicts).
/// Version 5 appends the domain (u8: 0 time, 1 order) and the order windows' samples per revolution S
/// and revolutions R (u32 each); it is written for order-domain baselines only. A time-domain baseline
/// is still written as version 4 (unchanged bytes), and versions 1 to 4 read as time domain.
/// Version 6 appends the order domain's speed law (f64 applied exponent, f64 fit, f64 its standard
/// error; dsp::Baseline::speed_law_*); version 5 reads with no speed law.
/// Version 7 (session 12) is written only for a baseline with band-energy statistics (policy.band_count
/// > 0, `[decision] band_cusum`): after the domain block (always present in version 7; the speed law only
/// for the order domain) u32 band_count, then per class u32 recordings and per band f64 mean, within sd,
/// between-day estimate, between-day sd used, u32 clean bins (dsp::BandEnergyStats). Versions 1 to 6
/// read with no band statistics; other baselines are written as before (4 or 6), byte for byte.
/// Version 8 (session 19) is written only for a baseline with mesh-modulation statistics
/// (policy.mesh_stats, `[decision] mesh_cusum`): the version-7 block (band_count may then be 0, with no
/// per-class band records), then per class u32 recordings and, for am then pm, f64 mean, within sd,
/// between-day estimate, between-day sd used, u32 windows (dsp::MeshFeatureStats). Versions 1 to 7
/// read with no mesh statistics; other baselines are written as before, byte for byte.
inline constexpr std::uint32_t kBaselineFormatVersion = 8;
inline constexpr std::uint32_t kBaselineBandVersion = 7;
inline constexpr std::uint32_t kBaselineOrderDomainVersion = 6;
inline constexpr std::uint32_t kBaselineTimeDomainVersion = 4;
inline constexpr std::uint32_t kBaselineOldestReadableVersion = 1;

/// Throws ptda::Error for an inconsistent baseline, ptda::WriteError (naming the path, the failed step
/// and the errno) when writing fails; never leaves a partial file at `path`. The temporary file is
/// "<path>.tmp-<random>", created O_EXCL|O_NOFOLLOW (common/atomic_file.hpp), mode 0644 minus the umask.
/// Thread: any (offline / configure time). Blocks (fsync) and allocates.
void write_baseline(const std::filesystem::path& path, const dsp::Baseline& baseline);

/// Throws ptda::Error when missing, truncated, corrupt (CRC), of another version or inconsistent,
/// saying which. Thread: any (configure time). Blocks and allocates.
[[nodiscard]] dsp::Baseline read_baseline(const std::filesystem::path& path);

/// The exact bytes write_baseline stores (CRC included). Throws ptda::Error for an inconsistent
/// baseline (vector lengths vs window_len, bad enums). Thread: any; allocates.
[[nodiscard]] std::vector<std::uint8_t> serialize_baseline(const dsp::Baseline& baseline);
/// Parses bytes produced by serialize_baseline; `source` names them in error messages. Throws like
/// read_baseline. Thread: any; allocates.
[[nodiscard]] dsp::Baseline parse_baseline(std::span<const std::uint8_t> bytes, const std::string& source);

/// Largest sample rate and window length a baseline may declare (10 MHz, 2^24 samples).
inline constexpr double kMaxBaselineFsHz = 1e7;
inline constexpr std::uint32_t kMaxBaselineWindowLen = 1U << 24;

/// The semantic checks parse_baseline and serialize_baseline run after the structure is known good:
/// every number finite, fs_hz and window_len plausible (a supported FFT length), every band lo < hi
/// (rms_res hi > 0), standard deviations > 0 over >= 2 windows, mean magnitudes >= 0, class speeds > 0,
/// counts within the class's windows, policy values in range, training times ordered. Throws
/// ptda::Error "<where>: implausible baseline: class I (id K): method M, <field> ..." naming the first
/// failing class, method and field. Thread: any; allocates only for the message.
void validate_baseline(const dsp::Baseline& baseline, const std::string& where);

/// CRC-32 (IEEE 802.3, reflected, poly 0xEDB88320), as zlib's crc32. Exposed for tests. Pass the
/// previous result as `crc` to continue over several buffers. Thread: any; never allocates.
[[nodiscard]] std::uint32_t crc32(const void* data, std::size_t len, std::uint32_t crc = 0) noexcept;

}  // namespace ptda::formats
