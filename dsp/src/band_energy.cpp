// Band energies of the referred residual and their per-class standardisation (band CUSUM).
#include "ptda/dsp/band_energy.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "number_text.hpp"
#include "ptda/common/error.hpp"
#include "ptda/dsp/analyzer.hpp"
#include "ptda/dsp/decision.hpp"

namespace ptda::dsp {

std::vector<unsigned char> clean_floor_bins(std::span<const float> mean_magnitude) {
  const std::size_t bins = mean_magnitude.size();
  std::vector<unsigned char> clean(bins, 0);
  if (bins < 3) return clean;
  const std::vector<float> floor = local_floor_medians(mean_magnitude);
  std::vector<unsigned char> in_line(bins, 0);
  for (const LineGroup& g : find_line_groups(mean_magnitude, floor)) {
    for (std::size_t k = g.begin; k < std::min<std::size_t>(g.end, bins); ++k) in_line[k] = 1;
  }
  constexpr double kCleanOverFloor = 2.0;  // 6 dB over find_line_groups()' local floor
  for (std::size_t k = 1; k < bins; ++k) {
    if (in_line[k] != 0) continue;
    clean[k] =
        static_cast<double>(mean_magnitude[k]) <= kCleanOverFloor * static_cast<double>(floor[k]) ? 1 : 0;
  }
  return clean;
}

void clean_bins_per_band(std::span<const unsigned char> clean, std::size_t count,
                         std::span<std::uint32_t> out) noexcept {
  if (clean.size() < 2 || count == 0 || out.size() < count) return;
  const std::size_t half = clean.size() - 1;
  for (std::size_t b = 0; b < count; ++b) {
    std::uint32_t n = 0;
    for (std::size_t k = band_edge(half, count, b); k < band_edge(half, count, b + 1); ++k) n += clean[k];
    out[b] = n;
  }
}

void band_log_energies(std::span<const float> energy, std::span<const unsigned char> clean, std::size_t count,
                       std::span<double> out) noexcept {
  const std::size_t m = std::min(count, out.size());
  if (energy.size() != clean.size() || energy.size() < 2 || out.size() < count) {
    for (std::size_t b = 0; b < m; ++b) out[b] = std::numeric_limits<double>::quiet_NaN();
    return;
  }
  const std::size_t half = energy.size() - 1;
  for (std::size_t b = 0; b < count; ++b) {
    // Four independent accumulators (one double chain would wait on every add) and a select, not a
    // branch or a multiply: an unclean bin adds 0 even when it holds a NaN, a clean NaN propagates.
    double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0;
    const std::size_t hi = band_edge(half, count, b + 1);
    std::size_t k = band_edge(half, count, b);
    for (; k + 4 <= hi; k += 4) {
      s0 += clean[k] != 0 ? static_cast<double>(energy[k]) : 0.0;
      s1 += clean[k + 1] != 0 ? static_cast<double>(energy[k + 1]) : 0.0;
      s2 += clean[k + 2] != 0 ? static_cast<double>(energy[k + 2]) : 0.0;
      s3 += clean[k + 3] != 0 ? static_cast<double>(energy[k + 3]) : 0.0;
    }
    for (; k < hi; ++k) s0 += clean[k] != 0 ? static_cast<double>(energy[k]) : 0.0;
    const double sum = (s0 + s1) + (s2 + s3);
    out[b] = std::isnan(sum) ? sum : std::log(std::max(1e-30, sum));
  }
}

void check_band_cusum(const BandCusumConfig& cfg) {
  using detail::num;
  if (!(cfg.k > 0.0 && cfg.k <= 10.0))
    throw Error("decision.band_cusum_k: must be > 0 and <= 10 standard deviations, got " + num(cfg.k));
  if (!(cfg.h > 0.0 && cfg.h <= 1000.0))
    throw Error("decision.band_cusum_h: must be > 0 and <= 1000, got " + num(cfg.h));
  if (!(cfg.day_allowance >= 0.0 && cfg.day_allowance <= 10.0))
    throw Error(
        "decision.band_cusum_day_allowance: must be >= 0 and <= 10 between-day standard deviations, got " +
        num(cfg.day_allowance));
  check_step_cap("band_cusum_step_cap", cfg.step_cap);
  if (cfg.band_count < 1 || cfg.band_count > kMaxBands)
    throw Error("decision.band_count: must be 1.." + std::to_string(kMaxBands) + ", got " +
                std::to_string(cfg.band_count));
}

BandScale band_scale(const ClassBaseline& c, double day_allowance) noexcept {
  BandScale s;
  s.count = static_cast<std::uint32_t>(std::min<std::size_t>(c.band_stats.size(), kMaxBands));
  const double days =
      c.band_recordings > 0 ? std::sqrt(1.0 + 1.0 / static_cast<double>(c.band_recordings)) : 1.0;
  for (std::size_t b = 0; b < s.count; ++b) {
    const BandEnergyStats& st = c.band_stats[b];
    const double sd = std::sqrt(st.within_sd * st.within_sd + st.between_sd * st.between_sd);
    s.mean[b] = st.mean;
    s.sd[b] = sd;
    s.active[b] = st.clean_bins > 0 && sd > 0.0 && std::isfinite(sd) && std::isfinite(st.mean) ? 1 : 0;
    s.allowance[b] = s.active[b] != 0 ? day_allowance * st.between_sd * days / sd : 0.0;
  }
  return s;
}

}  // namespace ptda::dsp
