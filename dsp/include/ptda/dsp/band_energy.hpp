// Band energies of the referred PTDA residual and their standardisation for the band CUSUM
// (`[decision] band_cusum`, docs/method.md §6 "Band detector"; measured in §8, sessions 11 and 12).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "ptda/dsp/baseline.hpp"

namespace ptda::dsp {

/// Lower bin edge of band b of `count` equal bands of bins 1..half (half = N/2): band b holds the bins
/// [band_edge(half, count, b), band_edge(half, count, b + 1)), band_edge(half, count, count) = half + 1.
/// Thread: any. Never allocates.
[[nodiscard]] constexpr std::size_t band_edge(std::size_t half, std::size_t count, std::size_t b) noexcept {
  return 1 + b * half / count;
}

/// The clean floor bins of a class's healthy mean magnitude a[k], k = 0..N/2 (1 = clean): k >= 1,
/// outside every line group of find_line_groups(a) (whatever the line-gain policy), and a[k] <= 2 x
/// (6 dB above) its local floor, the median of a over the 65 bins centred on k as find_line_groups()
/// takes it. So neither a line nor its leakage skirt, whose level moves with the line from day to
/// day. Deterministic. Thread: any. Allocates.
[[nodiscard]] std::vector<unsigned char> clean_floor_bins(std::span<const float> mean_magnitude);

/// Clean bins per band (out.size() >= count). Thread: any. Never allocates.
void clean_bins_per_band(std::span<const unsigned char> clean, std::size_t count,
                         std::span<std::uint32_t> out) noexcept;

/// out[b] = ln(max(1e-30, sum of energy[k] over the clean bins k of band b)), b < count, from the
/// one-sided residual energies |R[k]|^2, k = 0..N/2 (WindowAnalyzer::residual_energy()). Sums in
/// double. energy.size() must equal clean.size() and out.size() >= count (else out is NaN).
/// Thread: any. Never allocates.
void band_log_energies(std::span<const float> energy, std::span<const unsigned char> clean, std::size_t count,
                       std::span<double> out) noexcept;

/// Parameters of the band CUSUM ([decision] band_* keys, config/README.md).
struct BandCusumConfig {
  /// `band_cusum`: on by default since session 13 (opt-in in session 12). On by default it runs only
  /// where it can (method PTDA, a baseline with band statistics) and is off elsewhere with a notice.
  bool enabled = true;
  /// The configuration said `band_cusum = true` itself: then a baseline without band statistics or a
  /// method other than PTDA is an error, not a silent fallback.
  bool required = false;
  double k = 1.0;                 ///< `band_cusum_k`: reference value in total sds per window
  double h = 10.0;                ///< `band_cusum_h`: alarm when some band's statistic exceeds h
  double day_allowance = 1.0;     ///< `band_cusum_day_allowance`: extra k in between-day sds
  double step_cap = 1000.0;       ///< `band_cusum_step_cap`: largest step one window adds (1000: none)
  std::uint32_t band_count = 32;  ///< `band_count`: bands of bins 1..N/2 (training stores them)
  /// Run-time geometry for the alarm record's frequency range (set by with_band_geometry()): N/2
  /// and the bin spacing fs/N in Hz (order domain: cycles per revolution). 0 = unknown.
  std::uint32_t half_bins = 0;
  double bin_hz = 0.0;
};

/// Throws ptda::Error naming the [decision] key unless 0 < k <= 10, 0 < h <= 1000,
/// 0 <= day_allowance <= 10, 0 < step_cap <= 1000 and 1 <= band_count <= kMaxBands. Thread: any. Allocates
/// only the message.
void check_band_cusum(const BandCusumConfig& cfg);

/// How one class standardises its band energies: z_b = (ln E_b - mean_b) / sd_b with
/// sd_b = sqrt(within_sd^2 + between_sd^2), and the CUSUM of band b runs on z_b - allowance_b with
/// allowance_b = day_allowance x between_sd x sqrt(1 + 1/R) / sd_b (R training recordings).
/// active_b = 0 for a band without clean bins or with sd_b not > 0 (its z is 0: never accumulates).
struct BandScale {
  std::uint32_t count = 0;
  std::array<double, kMaxBands> mean{};
  std::array<double, kMaxBands> sd{};
  std::array<double, kMaxBands> allowance{};
  std::array<unsigned char, kMaxBands> active{};
};

/// The BandScale of class c (c.band_stats must hold at most kMaxBands entries; more are ignored).
/// Thread: any. Never allocates or throws.
[[nodiscard]] BandScale band_scale(const ClassBaseline& c, double day_allowance) noexcept;

}  // namespace ptda::dsp
