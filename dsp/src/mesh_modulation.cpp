// Mesh amplitude/phase demodulation at the input-shaft rate (see the header). The plan lives in memory
// this object owns (KissFFT's dry-run `lenmem` protocol) and the transform is out of place, so compute()
// never allocates.
#include "ptda/dsp/mesh_modulation.hpp"

#include <kiss_fft.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include "ptda/common/error.hpp"
#include "ptda/dsp/analyzer.hpp"
#include "ptda/dsp/decision.hpp"

namespace ptda::dsp {

namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Smallest n >= want whose only prime factors are 2, 3 and 5 (KissFFT's fast radices: any other factor
// makes it allocate scratch per call).
std::size_t smooth_length(std::size_t want) {
  for (std::size_t n = std::max<std::size_t>(want, 8);; ++n) {
    std::size_t m = n;
    for (std::size_t p : {2U, 3U, 5U}) {
      while (m % p == 0) m /= p;
    }
    if (m == 1) return n;
  }
}

std::int64_t round_bin(double x) noexcept {
  return static_cast<std::int64_t>(std::llround(x));
}

}  // namespace

double input_shaft_hz(double ratio, double speed_rad_s) noexcept {
  return ratio * std::fabs(speed_rad_s) / kTwoPi;
}

MeshGeometry mesh_geometry(double fs_hz, std::size_t window_len, const GearboxInfo& g,
                           const SegmentClass& seg) noexcept {
  return MeshGeometry{window_len, fs_hz,           g.z_in,
                      g.ratio,    seg.speed_rad_s, seg.speed_rad_s + seg.speed_tol_rad_s};
}

void check_mesh_cusum(const MeshCusumConfig& cfg) {
  if (!(cfg.k > 0.0 && cfg.k <= 10.0))
    throw Error("decision.mesh_cusum_k: must be > 0 and <= 10 standard deviations, got " +
                std::to_string(cfg.k));
  if (!(cfg.h > 0.0 && cfg.h <= 1000.0))
    throw Error("decision.mesh_cusum_h: must be > 0 and <= 1000, got " + std::to_string(cfg.h));
  if (!(cfg.one_day_allowance >= 0.0 && cfg.one_day_allowance <= 10.0))
    throw Error(
        "decision.mesh_cusum_one_day_allowance: must be >= 0 and <= 10 between-day standard deviations, "
        "got " +
        std::to_string(cfg.one_day_allowance));
  check_step_cap("mesh_cusum_step_cap", cfg.step_cap);
}

MeshScale mesh_scale(const ClassBaseline& c, double one_day_allowance) noexcept {
  MeshScale s;
  const double q = c.mesh_recordings <= 1 ? one_day_allowance : 0.0;
  const double days =
      c.mesh_recordings > 0 ? std::sqrt(1.0 + 1.0 / static_cast<double>(c.mesh_recordings)) : 1.0;
  for (std::size_t i = 0; i < kMeshFeatureCount && i < c.mesh_stats.size(); ++i) {
    const MeshFeatureStats& st = c.mesh_stats[i];
    const double sd = std::sqrt(st.within_sd * st.within_sd + st.between_sd * st.between_sd);
    s.mean[i] = st.mean;
    s.sd[i] = sd;
    s.active[i] = st.windows > 0 && sd > 0.0 && std::isfinite(sd) && std::isfinite(st.mean);
    s.allowance[i] = s.active[i] ? q * st.between_sd * days / sd : 0.0;
  }
  return s;
}

double revolution_autocorrelation(std::span<const double> x, double samples_per_rev) noexcept {
  const std::size_t n = x.size();
  if (n < 2 || !(samples_per_rev > 0.0) || !std::isfinite(samples_per_rev)) return kNaN;
  double mean = 0.0;
  for (double v : x) mean += v;
  mean /= static_cast<double>(n);
  double c0 = 0.0;
  for (double v : x) c0 += (v - mean) * (v - mean);
  c0 /= static_cast<double>(n);
  if (!(c0 > 0.0)) return kNaN;
  double sum = 0.0;
  std::uint32_t lags = 0;
  for (std::uint32_t m = 1; m <= kMeshMaxLags; ++m) {
    if (static_cast<double>(m) * samples_per_rev > static_cast<double>(n) - samples_per_rev) break;
    const auto lag = static_cast<std::size_t>(std::llround(static_cast<double>(m) * samples_per_rev));
    if (lag == 0 || lag >= n) break;
    double c = 0.0;
    for (std::size_t i = 0; i + lag < n; ++i) c += (x[i] - mean) * (x[i + lag] - mean);
    sum += c / static_cast<double>(n - lag) / c0;
    ++lags;
  }
  return lags == 0 ? kNaN : sum / static_cast<double>(lags);
}

struct MeshDemodulator::Impl {
  MeshGeometry g;
  std::size_t half = 0;                // N/2
  std::size_t m = 0;                   // decimated length
  std::vector<unsigned char> in_line;  // per bin k = 0..N/2: inside a line group of the class mean
  std::unique_ptr<unsigned char[]> plan_mem;
  kiss_fft_cfg plan = nullptr;
  std::vector<kiss_fft_cpx> band;  // the harmonic's bins, carrier at index 0
  std::vector<kiss_fft_cpx> z;     // its analytic signal at the decimated rate
  std::vector<double> mag;
  std::vector<double> phase;
  std::vector<double> am_sum;
  std::vector<double> pm_sum;
  std::uint32_t line_harmonics = 0;

  bool harmonic_is_line(std::int64_t kc) const noexcept {
    for (std::int64_t k = std::max<std::int64_t>(1, kc - 1); k <= kc + 1; ++k) {
      if (k >= 0 && static_cast<std::size_t>(k) <= half && in_line[static_cast<std::size_t>(k)] != 0)
        return true;
    }
    return false;
  }
};

MeshDemodulator::MeshDemodulator(const MeshGeometry& geometry, std::span<const float> mean_magnitude)
    : impl_(std::make_unique<Impl>()) {
  Impl& s = *impl_;
  s.g = geometry;
  const MeshGeometry& g = geometry;
  if (g.window_len < 8 || g.window_len % 2 != 0)
    throw Error("mesh detector: window length " + std::to_string(g.window_len) + " must be even and >= 8");
  if (!(g.fs_hz > 0.0) || !std::isfinite(g.fs_hz))
    throw Error("mesh detector: sample rate " + std::to_string(g.fs_hz) + " Hz must be > 0");
  if (g.z_in == 0) throw Error("mesh detector: the gearbox's z_in (input pinion teeth) is 0 or unknown");
  if (!(g.ratio > 0.0) || !std::isfinite(g.ratio))
    throw Error("mesh detector: the gearbox ratio " + std::to_string(g.ratio) + " must be > 0");
  if (!(g.speed_rad_s > 0.0) || !std::isfinite(g.speed_max_rad_s) || g.speed_max_rad_s < g.speed_rad_s)
    throw Error("mesh detector: the class's speed " + std::to_string(g.speed_rad_s) +
                " rad/s must be > 0 and " + "its largest speed " + std::to_string(g.speed_max_rad_s) +
                " rad/s not below it");
  s.half = g.window_len / 2;
  if (mean_magnitude.size() != s.half + 1)
    throw Error("mesh detector: the class mean has " + std::to_string(mean_magnitude.size()) +
                " bins, expected N/2 + 1 = " + std::to_string(s.half + 1));
  s.in_line.assign(s.half + 1, 0);
  for (const LineGroup& lg : find_line_groups(mean_magnitude)) {
    for (std::uint32_t k = lg.begin; k < lg.end && k <= s.half; ++k) s.in_line[k] = 1;
  }
  // The widest band: one GMF at the largest speed, plus a bin of rounding on each side. Twice that, so
  // the carrier's own drift and the modulation sit well inside the decimated rate.
  const double df = g.fs_hz / static_cast<double>(g.window_len);
  const double gmf_max = static_cast<double>(g.z_in) * input_shaft_hz(g.ratio, g.speed_max_rad_s);
  // Clamped in double first: a forged speed tolerance must not overflow the conversion.
  const double width = std::min(std::ceil(gmf_max / df) + 2.0, static_cast<double>(g.window_len));
  s.m = smooth_length(std::min(2 * static_cast<std::size_t>(width), g.window_len));
  std::size_t len_bytes = 0;
  kiss_fft_alloc(static_cast<int>(s.m), 1, nullptr, &len_bytes);
  if (len_bytes == 0) throw Error("mesh detector: KissFFT reported no plan size for " + std::to_string(s.m));
  s.plan_mem = std::make_unique<unsigned char[]>(len_bytes);
  std::size_t have = len_bytes;
  s.plan = kiss_fft_alloc(static_cast<int>(s.m), 1, s.plan_mem.get(), &have);
  if (s.plan == nullptr) throw Error("mesh detector: KissFFT could not plan length " + std::to_string(s.m));
  s.band.assign(s.m, kiss_fft_cpx{0.0F, 0.0F});
  s.z.assign(s.m, kiss_fft_cpx{0.0F, 0.0F});
  s.mag.assign(s.m, 0.0);
  s.phase.assign(s.m, 0.0);
  s.am_sum.assign(s.m, 0.0);
  s.pm_sum.assign(s.m, 0.0);
  const double gmf = static_cast<double>(g.z_in) * input_shaft_hz(g.ratio, g.speed_rad_s);
  for (std::uint32_t h = 1; h <= kMeshMaxHarmonics; ++h) {
    if ((h + 0.5) * gmf >= 0.5 * g.fs_hz) break;
    if (s.harmonic_is_line(round_bin(h * gmf / df))) ++s.line_harmonics;
  }
}

MeshDemodulator::~MeshDemodulator() = default;
MeshDemodulator::MeshDemodulator(MeshDemodulator&&) noexcept = default;
MeshDemodulator& MeshDemodulator::operator=(MeshDemodulator&&) noexcept = default;

std::size_t MeshDemodulator::decimated_len() const noexcept {
  return impl_ ? impl_->m : 0;
}

std::uint32_t MeshDemodulator::line_harmonics() const noexcept {
  return impl_ ? impl_->line_harmonics : 0;
}

MeshValues MeshDemodulator::compute(std::span<const std::complex<float>> spectrum,
                                    double speed_rad_s) noexcept {
  MeshValues out;
  if (!impl_) return out;
  Impl& s = *impl_;
  const MeshGeometry& g = s.g;
  if (spectrum.size() != s.half + 1 || !std::isfinite(speed_rad_s)) return out;
  const double n = static_cast<double>(g.window_len);
  const double f_in = input_shaft_hz(g.ratio, speed_rad_s);
  const double n_rev = f_in * n / g.fs_hz;
  if (n_rev < kMeshMinRevolutions) return out;
  const double df = g.fs_hz / n;
  const double gmf = static_cast<double>(g.z_in) * f_in;
  const auto m = static_cast<std::int64_t>(s.m);
  std::fill(s.am_sum.begin(), s.am_sum.end(), 0.0);
  std::fill(s.pm_sum.begin(), s.pm_sum.end(), 0.0);
  std::uint32_t used = 0;
  // Least-squares line through (i, phase[i]), i = 0..m-1: the abscissa's mean and sum of squares.
  const double i_mean = 0.5 * static_cast<double>(m - 1);
  const double i_ss = static_cast<double>(m) * (static_cast<double>(m) * static_cast<double>(m) - 1.0) / 12.0;
  for (std::uint32_t h = 1; h <= kMeshMaxHarmonics; ++h) {
    if ((h + 0.5) * gmf >= 0.5 * g.fs_hz) break;
    const std::int64_t kc = round_bin(h * gmf / df);
    if (!s.harmonic_is_line(kc)) continue;
    const std::int64_t lo = std::max<std::int64_t>(1, round_bin((h - 0.5) * gmf / df));
    const std::int64_t hi =
        std::min<std::int64_t>(static_cast<std::int64_t>(s.half) + 1, round_bin((h + 0.5) * gmf / df));
    if (hi - lo > m) return MeshValues{};  // faster than the class was sized for
    std::fill(s.band.begin(), s.band.end(), kiss_fft_cpx{0.0F, 0.0F});
    for (std::int64_t k = lo; k < hi; ++k) {
      const std::int64_t at = ((k - kc) % m + m) % m;
      const std::complex<float> x = spectrum[static_cast<std::size_t>(k)];
      s.band[static_cast<std::size_t>(at)] = kiss_fft_cpx{x.real(), x.imag()};
    }
    kiss_fft(s.plan, s.band.data(), s.z.data());
    double mag_mean = 0.0;
    for (std::size_t i = 0; i < s.m; ++i) {
      const double re = s.z[i].r;
      const double im = s.z[i].i;
      s.mag[i] = std::sqrt(re * re + im * im);
      mag_mean += s.mag[i];
      s.phase[i] = std::atan2(im, re);
    }
    mag_mean /= static_cast<double>(s.m);
    if (!(mag_mean > 0.0) || !std::isfinite(mag_mean)) continue;
    // Unwrap: each step taken to [-pi, pi).
    double offset = 0.0;
    double prev = s.phase[0];
    for (std::size_t i = 1; i < s.m; ++i) {
      const double raw = s.phase[i];
      double d = raw - prev;
      d -= kTwoPi * std::floor((d + std::numbers::pi) / kTwoPi);
      prev = raw;
      offset += d;
      s.phase[i] = s.phase[0] + offset;
    }
    double p_mean = 0.0;
    for (std::size_t i = 0; i < s.m; ++i) p_mean += s.phase[i];
    p_mean /= static_cast<double>(s.m);
    double cov = 0.0;
    for (std::size_t i = 0; i < s.m; ++i) cov += (static_cast<double>(i) - i_mean) * (s.phase[i] - p_mean);
    const double slope = cov / i_ss;
    const double inv_h = 1.0 / static_cast<double>(h);
    for (std::size_t i = 0; i < s.m; ++i) {
      s.am_sum[i] += s.mag[i] / mag_mean - 1.0;
      s.pm_sum[i] += (s.phase[i] - p_mean - slope * (static_cast<double>(i) - i_mean)) * inv_h;
    }
    ++used;
  }
  if (used == 0) return out;
  // Averages over the harmonics: the autocorrelation is scale-free, so the sums do.
  const double samples_per_rev = static_cast<double>(s.m) / n_rev;
  out.v[0] = revolution_autocorrelation(s.am_sum, samples_per_rev);
  out.v[1] = revolution_autocorrelation(s.pm_sum, samples_per_rev);
  out.harmonics = used;
  return out;
}

}  // namespace ptda::dsp
