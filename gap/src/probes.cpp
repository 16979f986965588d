// The probes (docs/gap.md "Probes") and the normalised gap between two probe sets.
#include "ptda/gap/probes.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>
#include <memory>
#include <numbers>
#include <numeric>

#include "ptda/dsp/analyzer.hpp"
#include "ptda/dsp/features.hpp"
#include "ptda/dsp/real_fft.hpp"
#include "ptda/sim/noise_tilt.hpp"

namespace ptda::gap {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kTiny = 1e-20;
// Fixed normalisation scales (one "unit" of gap); docs/gap.md explains the choice.
constexpr double kScaleHarmonicDb = 1.0;
constexpr double kScaleSidebandDb = 2.0;
constexpr double kScaleCoherenceDb = 1.0;
constexpr double kScalePhaseCoherence = 0.05;
constexpr int kLocalProbeNorm = 4;
constexpr int kHarmonicProbeNorm = 12;
constexpr double kScaleFloorDb = 1.0;
constexpr double kScaleLineDb = 3.0;
constexpr double kScaleLogKurtosis = 0.05;
constexpr double kScaleCrestDb = 1.0;
constexpr double kScaleExtremeLog10 = 0.3;
constexpr double kScaleResidualRmsDb = 0.5;
constexpr double kScaleEntropy = 0.005;
constexpr double kScaleGmfPpm = 100.0;
constexpr double kScaleLagMs = 2.0;

double db(double p) {
  return 10.0 * std::log10(std::max(p, kTiny));
}

double median_of(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const std::size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid), v.end());
  return v[mid];
}

struct Band {
  double lo = 0.0;
  double hi = 0.0;
};

/// 1/3-octave bands from max(20 Hz, 8 bins) to 0.45 fs, each at least 8 bins of the coarsest window.
std::vector<Band> make_bands(double fs_hz, std::size_t min_len) {
  std::vector<Band> out;
  const double df = fs_hz / static_cast<double>(min_len);
  double lo = std::max(20.0, 8.0 * df);
  const double top = 0.45 * fs_hz;
  while (lo < top) {
    double hi = std::max(lo * std::pow(2.0, 1.0 / 3.0), lo + 8.0 * df);
    if (hi > top) hi = top;
    if (hi - lo >= 4.0 * df) out.push_back({lo, hi});
    lo = hi;
  }
  return out;
}

std::size_t bin_of(double f_hz, double df) {
  return static_cast<std::size_t>(std::lround(f_hz / df));
}

/// Moments of a window (mean removed).
void window_stats(const float* x, std::size_t n, double& kurtosis, double& crest_db) {
  double mean = 0.0;
  for (std::size_t i = 0; i < n; ++i) mean += x[i];
  mean /= static_cast<double>(n);
  double m2 = 0.0, m4 = 0.0, peak = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double d = x[i] - mean;
    m2 += d * d;
    m4 += d * d * d * d;
    peak = std::max(peak, std::fabs(d));
  }
  m2 /= static_cast<double>(n);
  m4 /= static_cast<double>(n);
  kurtosis = m2 > 0.0 ? m4 / (m2 * m2) : 3.0;
  crest_db = m2 > 0.0 ? 20.0 * std::log10(peak / std::sqrt(m2)) : 0.0;
}

struct Accum {
  std::vector<double> power;  // mean amplitude^2 per bin
  std::size_t count = 0;
  std::size_t len = 0;
  double log_kurt = 0.0;
  double crest_db = 0.0;
};

class SpectrumCache {
 public:
  dsp::RealFft& fft(std::size_t n) {
    auto it = ffts_.find(n);
    if (it == ffts_.end()) it = ffts_.emplace(n, std::make_unique<dsp::RealFft>(n)).first;
    return *it->second;
  }
  const std::vector<float>& hann(std::size_t n) {
    auto it = hann_.find(n);
    if (it == hann_.end()) {
      std::vector<float> w(n);
      for (std::size_t i = 0; i < n; ++i)
        w[i] = static_cast<float>(
            0.5 - 0.5 * std::cos(2.0 * kPi * static_cast<double>(i) / static_cast<double>(n)));
      it = hann_.emplace(n, std::move(w)).first;
    }
    return it->second;
  }

 private:
  std::map<std::size_t, std::unique_ptr<dsp::RealFft>> ffts_;
  std::map<std::size_t, std::vector<float>> hann_;
};

/// Parabolic peak interpolation on dB values around bin k: fractional bin.
double interp_peak(const std::vector<double>& p, std::size_t k) {
  if (k == 0 || k + 1 >= p.size()) return static_cast<double>(k);
  const double a = db(p[k - 1]), b = db(p[k]), c = db(p[k + 1]);
  const double den = a - 2.0 * b + c;
  if (den >= 0.0) return static_cast<double>(k);
  return static_cast<double>(k) + 0.5 * (a - c) / den;
}

double envelope_lag(const GapRecording& rec, const std::vector<Segment>& segs,
                    const std::vector<char>& use_cycle) {
  const double fs = rec.fs_hz;
  // Frames of about 5 ms, whole samples; their time step is the frame's true length (at 20480 Hz a
  // frame is 102 samples, 4.98 ms: timing them as 5 ms made the lag drift by 3.9 ms per second).
  const auto frame = std::max<std::size_t>(1, static_cast<std::size_t>(0.005 * fs));
  const double frame_s = static_cast<double>(frame) / fs;
  const std::size_t frames = rec.accel_ms2.size() / frame;
  if (frames < 10 || rec.speed.size() < 3) return std::numeric_limits<double>::quiet_NaN();
  std::vector<double> env(frames), spd(frames);
  std::vector<char> use(frames, 0);
  std::size_t si = 0;
  std::size_t seg = 0;
  for (std::size_t f = 0; f < frames; ++f) {
    double ss = 0.0;
    for (std::size_t i = f * frame; i < (f + 1) * frame; ++i)
      ss += static_cast<double>(rec.accel_ms2[i]) * rec.accel_ms2[i];
    env[f] = std::sqrt(ss / static_cast<double>(frame));
    const double t = (static_cast<double>(f) + 0.5) * frame_s;
    while (si + 1 < rec.speed.size() && rec.speed[si + 1].t_s < t) ++si;
    double w = rec.speed[si].speed_rad_s;
    if (si + 1 < rec.speed.size() && t > rec.speed[si].t_s) {
      const double u = (t - rec.speed[si].t_s) / (rec.speed[si + 1].t_s - rec.speed[si].t_s);
      w += std::clamp(u, 0.0, 1.0) * (rec.speed[si + 1].speed_rad_s - rec.speed[si].speed_rad_s);
    }
    spd[f] = std::fabs(w);
    while (seg + 1 < segs.size() && segs[seg].t1_s < t) ++seg;
    const std::uint32_t c = segs.empty() ? 0 : segs[seg].cycle;
    use[f] = use_cycle.empty() || (c < use_cycle.size() && use_cycle[c] != 0) ? 1 : 0;
  }
  double smax = 0.0;
  for (double v : spd) smax = std::max(smax, v);
  double mean = 0.0, var = 0.0;
  for (double v : spd) mean += v;
  mean /= static_cast<double>(frames);
  for (double v : spd) var += (v - mean) * (v - mean);
  if (smax <= 0.0 || std::sqrt(var / static_cast<double>(frames)) < 0.05 * smax)
    return std::numeric_limits<double>::quiet_NaN();
  const int max_lag = static_cast<int>(0.2 / frame_s);
  std::vector<double> corr;
  for (int lag = -max_lag; lag <= max_lag; ++lag) {
    // env[f] compared with spd[f - lag]: positive lag = the vibration follows the CAN speed later.
    double sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0, n = 0;
    for (std::size_t f = 0; f < frames; ++f) {
      const auto g = static_cast<std::ptrdiff_t>(f) - lag;
      if (!use[f] || g < 0 || g >= static_cast<std::ptrdiff_t>(frames)) continue;
      const double x = env[f], y = spd[static_cast<std::size_t>(g)];
      sx += x;
      sy += y;
      sxx += x * x;
      syy += y * y;
      sxy += x * y;
      n += 1;
    }
    const double cov = sxy - sx * sy / std::max(n, 1.0);
    const double vx = sxx - sx * sx / std::max(n, 1.0);
    const double vy = syy - sy * sy / std::max(n, 1.0);
    corr.push_back(vx > 0 && vy > 0 ? cov / std::sqrt(vx * vy) : 0.0);
  }
  const auto best = static_cast<std::size_t>(std::max_element(corr.begin(), corr.end()) - corr.begin());
  double frac = static_cast<double>(best);
  if (best > 0 && best + 1 < corr.size()) {
    const double a = corr[best - 1], b = corr[best], c = corr[best + 1];
    const double den = a - 2 * b + c;
    if (den < 0) frac += 0.5 * (a - c) / den;
  }
  return (frac - max_lag) * frame_s;
}

void add(ProbeSet& ps, const std::string& probe, const std::string& key, double value, double scale,
         double f_lo, double f_hi, SegmentType seg, Stage stage, int order = 0) {
  if (!std::isfinite(value)) return;
  ps.elements.push_back(ProbeElement{probe, key, value, scale, f_lo, f_hi, seg, stage, order});
}

}  // namespace

const char* stage_name(Stage s) noexcept {
  switch (s) {
    case Stage::kRaw:
      return "raw_spectrum";
    case Stage::kResidual:
      return "residual_features";
    case Stage::kAlarm:
      return "alarm_decisions";
    case Stage::kAveraging:
      return "cycle_averaging";
  }
  return "?";
}

ProbeSet compute_probes(const GapRecording& rec, const std::vector<Segment>& segs,
                        const std::vector<Window>& windows, const std::vector<char>& use_cycle,
                        const ProbeContext& ctx, const ProbeSet* reference) {
  ProbeSet ps;
  const double fs = rec.fs_hz;
  ps.fs_hz = fs;
  const AnalysisPlan& plan = ctx.plan;
  SpectrumCache cache;
  auto selected = [&](const Window& w) {
    return use_cycle.empty() || (w.cycle < use_cycle.size() && use_cycle[w.cycle] != 0);
  };

  std::map<int, Accum> const_acc;                                           // per class
  std::map<int, std::vector<std::vector<std::complex<float>>>> const_spec;  // per class: window spectra
  Accum accel_acc, still_acc;
  std::size_t min_len = std::numeric_limits<std::size_t>::max();
  std::vector<float> buf;
  std::vector<std::complex<float>> spec;
  double max_abs = 0.0;
  std::vector<const Window*> used;
  for (const Window& w : windows) {
    if (!selected(w)) continue;
    used.push_back(&w);
    min_len = std::min(min_len, w.len);
    Accum& acc = w.type == SegmentType::kConstant ? const_acc[w.speed_class]
                 : w.type == SegmentType::kAccel  ? accel_acc
                                                  : still_acc;
    const float* x = rec.accel_ms2.data() + w.start;
    for (std::size_t i = 0; i < w.len; ++i) max_abs = std::max(max_abs, static_cast<double>(std::fabs(x[i])));
    const std::vector<float>& h = cache.hann(w.len);
    buf.resize(w.len);
    double mean = 0.0;
    for (std::size_t i = 0; i < w.len; ++i) mean += x[i];
    mean /= static_cast<double>(w.len);
    for (std::size_t i = 0; i < w.len; ++i) buf[i] = static_cast<float>((x[i] - mean) * h[i]);
    spec.resize(w.len / 2 + 1);
    cache.fft(w.len).forward(buf, spec);
    if (acc.power.empty()) {
      acc.power.assign(spec.size(), 0.0);
      acc.len = w.len;
    }
    const double norm = 2.0 / (0.5 * static_cast<double>(w.len));  // amplitude of a sine
    for (std::size_t k = 0; k < spec.size(); ++k) acc.power[k] += std::norm(spec[k]) * norm * norm;
    if (w.type == SegmentType::kConstant) const_spec[w.speed_class].push_back(spec);
    double kurt = 3.0, crest = 0.0;
    window_stats(x, w.len, kurt, crest);
    acc.log_kurt += std::log(kurt);
    acc.crest_db += crest;
    ++acc.count;
  }
  ps.windows = used.size();
  ps.max_abs_ms2 = max_abs;
  if (used.empty()) return ps;
  for (auto* acc : {&accel_acc, &still_acc}) {
    for (double& p : acc->power) p /= static_cast<double>(std::max<std::size_t>(acc->count, 1));
  }
  for (auto& [c, acc] : const_acc) {
    for (double& p : acc.power) p /= static_cast<double>(acc.count);
  }
  const std::vector<Band> bands = make_bands(fs, min_len);

  // ---- mesh probes per constant-speed class -------------------------------------------------------
  int max_nominal = 1;
  for (int k : ctx.nominal_orders) max_nominal = std::max(max_nominal, k);
  const int k_limit = std::min(40, 2 * max_nominal);
  std::vector<std::pair<double, double>> harmonic_exclusions;  // [lo, hi] Hz per class, for the line probe
  std::map<int, std::vector<std::pair<double, double>>> class_exclusions;
  for (auto& [c, acc] : const_acc) {
    const double df = fs / static_cast<double>(acc.len);
    const double w = plan.speeds[static_cast<std::size_t>(c)];
    const double gmf = std::fabs(sim::gmf_hz(ctx.gearbox, w));
    const double f_in = gmf / static_cast<double>(ctx.gearbox.z_in);
    const std::vector<double>& p = acc.power;
    ps.class_power[c] = p;
    if (gmf <= 0.0) continue;
    const std::string cls = "c" + std::to_string(c);
    struct Strong {
      int k;
      std::size_t bin;
      double floor_db;
      double peak_db;
    };
    std::vector<Strong> strong;
    std::map<int, std::size_t> nominal_bins;  // peak bin per nominal order
    for (int k = 1; k <= k_limit && k * gmf < 0.45 * fs; ++k) {
      const double f = k * gmf;
      class_exclusions[c].push_back({f - 3.6 * f_in - 3 * df, f + 3.6 * f_in + 3 * df});
      const std::size_t b = bin_of(f, df);
      std::size_t kb = b;
      double peak = 0.0;
      for (std::size_t j = b > 2 ? b - 2 : 0; j <= b + 2 && j < p.size(); ++j) {
        if (p[j] > peak) {
          peak = p[j];
          kb = j;
        }
      }
      std::vector<double> around;
      for (std::size_t j = b > 30 ? b - 30 : 1; j <= b + 30 && j < p.size(); ++j) {
        if (j + 3 < b || j > b + 3) around.push_back(p[j]);
      }
      const double floor_db = db(median_of(around));
      const double peak_db = db(peak);
      add(ps, "harmonics", cls + ".k" + std::to_string(k), std::max(peak_db, floor_db + 6.0),
          kScaleHarmonicDb, f, f, SegmentType::kConstant, Stage::kRaw, k);
      const bool nominal =
          std::find(ctx.nominal_orders.begin(), ctx.nominal_orders.end(), k) != ctx.nominal_orders.end();
      if (nominal) nominal_bins[k] = kb;
      if (nominal && peak_db > floor_db + 15.0) strong.push_back({k, kb, floor_db, peak_db});
    }
    // Nominal shaft-order lines (sim::VibrationSpec::shaft_orders): their level per class, calibrated
    // like the harmonics; their bins are left out of the `lines` probe, which looks for lines the model
    // does not have.
    for (int j : ctx.nominal_shaft_orders) {
      const double f = j * f_in;
      if (f >= 0.45 * fs) continue;
      class_exclusions[c].push_back({f - 3 * df, f + 3 * df});
      const std::size_t b = bin_of(f, df);
      double peak = 0.0;
      for (std::size_t q = b > 2 ? b - 2 : 0; q <= b + 2 && q < p.size(); ++q) peak = std::max(peak, p[q]);
      std::vector<double> around;
      for (std::size_t q = b > 30 ? b - 30 : 1; q <= b + 30 && q < p.size(); ++q) {
        if (q + 3 < b || q > b + 3) around.push_back(p[q]);
      }
      add(ps, "shaft_orders", cls + ".s" + std::to_string(j), std::max(db(peak), db(median_of(around)) + 6.0),
          kScaleHarmonicDb, f, f, SegmentType::kConstant, Stage::kRaw, j);
    }
    // Cross-cycle phase coherence per nominal order: in each window the phase of order k relative to
    // k / k0 times that of the lowest nominal order k0 (k a multiple of k0), psi = arg X_k -
    // (k / k0) arg X_k0, does not depend on where the window starts (the windows of a plateau are not
    // aligned to the shaft angle), only on whether the mesh waveform repeats. Unbiased mean resultant
    // length^2 over the n windows, (|sum e^{i psi}|^2 - n) / (n (n - 1)): 1 when the relative phases
    // repeat from cycle to cycle (time-domain averaging keeps the harmonics), 0 in expectation when they
    // are random (TDA loses them, PTDA's magnitude average does not). Scale: 0.05 widened by the spread
    // of the estimator for random phases, 1 / (n (n - 1)), counted for the measured and simulated side.
    if (!nominal_bins.empty() && const_spec[c].size() >= 2) {
      const int k0 = nominal_bins.begin()->first;
      const std::size_t b0 = nominal_bins.begin()->second;
      const auto& specs = const_spec[c];
      const double n = static_cast<double>(specs.size());
      for (const auto& [k, bk] : nominal_bins) {
        if (k == k0 || k % k0 != 0) continue;
        const double mult = static_cast<double>(k / k0);
        std::complex<double> sum = 0.0;
        for (const auto& sv : specs) {
          if (bk >= sv.size() || b0 >= sv.size()) continue;
          const double psi =
              std::arg(std::complex<double>(sv[bk])) - mult * std::arg(std::complex<double>(sv[b0]));
          sum += std::polar(1.0, psi);
        }
        const double coh = (std::norm(sum) - n) / (n * (n - 1.0));
        const double scale = std::sqrt(kScalePhaseCoherence * kScalePhaseCoherence + 2.0 / (n * (n - 1.0)));
        add(ps, "phase_coherence", cls + ".k" + std::to_string(k), coh, scale, k * gmf, k * gmf,
            SegmentType::kConstant, Stage::kAveraging, k);
      }
    }
    if (strong.empty()) continue;
    double f_lo = 1e300, f_hi = 0.0;
    for (const Strong& s : strong) {
      f_lo = std::min(f_lo, s.k * gmf);
      f_hi = std::max(f_hi, s.k * gmf);
    }
    // Sideband excess at offsets 0.5 .. 3.5 input-shaft orders, averaged over the strong harmonics.
    for (int j = 2; j <= 14; ++j) {
      const double delta = 0.25 * j * f_in;
      if (delta < 3.0 * df) continue;
      double sum = 0.0;
      for (const Strong& s : strong) {
        double best = 0.0;
        for (double sign : {-1.0, 1.0}) {
          const double f = s.k * gmf + sign * delta;
          if (f <= 0.0) continue;
          const std::size_t b = bin_of(f, df);
          for (std::size_t q = b > 1 ? b - 1 : 0; q <= b + 1 && q < p.size(); ++q)
            best = std::max(best, p[q]);
        }
        sum += std::max(0.0, db(best) - s.floor_db - 3.0);
      }
      char key[48];
      std::snprintf(key, sizeof key, "%s.d%.2f", cls.c_str(), 0.25 * j);
      add(ps, "sidebands", key, sum / static_cast<double>(strong.size()), kScaleSidebandDb, f_lo, f_hi,
          SegmentType::kConstant, Stage::kRaw);
    }
    // Line sharpness (within-window phase coherence) and the measured mesh frequency.
    const Strong* top = &strong.front();
    for (const Strong& s : strong) {
      double core = 0.0, wide = 0.0;
      for (std::size_t q = s.bin > 8 ? s.bin - 8 : 0; q <= s.bin + 8 && q < p.size(); ++q) {
        wide += p[q];
        if (q + 1 >= s.bin && q <= s.bin + 1) core += p[q];
      }
      add(ps, "coherence", cls + ".k" + std::to_string(s.k), db(core / std::max(wide, kTiny)),
          kScaleCoherenceDb, s.k * gmf, s.k * gmf, SegmentType::kConstant, Stage::kRaw, s.k);
      if (s.peak_db - s.floor_db > top->peak_db - top->floor_db) top = &s;
    }
    const double f_meas = interp_peak(p, top->bin) * df;
    add(ps, "tracking", cls + ".gmf_ppm", (f_meas / (top->k * gmf) - 1.0) * 1e6, kScaleGmfPpm, top->k * gmf,
        top->k * gmf, SegmentType::kConstant, Stage::kRaw);
  }

  // ---- noise floor and lines per band and segment type ----------------------------------------------
  auto band_probes = [&](SegmentType type,
                         const std::vector<std::pair<const std::vector<double>*, std::size_t>>& spectra,
                         const std::map<int, std::vector<std::pair<double, double>>>* excl) {
    if (spectra.empty()) return;
    const std::string tn = segment_type_name(type);
    for (std::size_t bi = 0; bi < bands.size(); ++bi) {
      const Band& band = bands[bi];
      double floor_sum = 0.0, line_sum = 0.0;
      int n = 0;
      for (std::size_t si = 0; si < spectra.size(); ++si) {
        const std::vector<double>& p = *spectra[si].first;
        const double df = fs / static_cast<double>(spectra[si].second);
        std::vector<double> in;
        double mx = 0.0;
        for (std::size_t q = bin_of(band.lo, df); q < bin_of(band.hi, df) && q < p.size(); ++q) {
          in.push_back(p[q]);
          const double f = static_cast<double>(q) * df;
          bool excluded = false;
          if (excl != nullptr) {
            auto it = excl->begin();
            std::advance(it, static_cast<std::ptrdiff_t>(si));
            for (const auto& [lo, hi] : it->second) excluded = excluded || (f >= lo && f <= hi);
          }
          if (!excluded) mx = std::max(mx, p[q]);
        }
        if (in.size() < 3) continue;
        const double fl = db(median_of(in));
        floor_sum += fl;
        line_sum += mx > 0.0 ? std::max(0.0, db(mx) - fl - 10.0) : 0.0;
        ++n;
      }
      if (n == 0) continue;
      const std::string key = tn + ".b" + std::to_string(bi);
      add(ps, "noise_floor", key, floor_sum / n, kScaleFloorDb, band.lo, band.hi, type, Stage::kRaw);
      add(ps, "lines", key, line_sum / n, kScaleLineDb, band.lo, band.hi, type, Stage::kRaw);
    }
  };
  {
    std::vector<std::pair<const std::vector<double>*, std::size_t>> cs;
    std::map<int, std::vector<std::pair<double, double>>> ex;
    for (auto& [c, acc] : const_acc) {
      cs.push_back({&acc.power, acc.len});
      ex[c] = class_exclusions[c];
    }
    band_probes(SegmentType::kConstant, cs, &ex);
    if (accel_acc.count > 0) band_probes(SegmentType::kAccel, {{&accel_acc.power, accel_acc.len}}, nullptr);
    if (still_acc.count > 0)
      band_probes(SegmentType::kStandstill, {{&still_acc.power, still_acc.len}}, nullptr);
    ps.accel_power = accel_acc.power;
    ps.still_power = still_acc.power;
  }

  // ---- transitions: +-50 ms around every segment boundary (outside the analysis windows' margins, where
  // knocks at torque reversals sit): mean crest factor and log kurtosis, and octave levels of the
  // kTransientLen samples around each interval's largest sample (where the knock rings).
  {
    const auto half = static_cast<std::size_t>(0.05 * fs);
    std::vector<double> tpow;
    std::vector<float> tbuf(kTransientLen);
    std::vector<std::complex<float>> tspec(kTransientLen / 2 + 1);
    double dcrest_sum = 0.0, dlk_sum = 0.0;
    std::size_t count = 0;
    std::vector<float> dbuf;
    for (std::size_t i = 1; i < segs.size(); ++i) {
      const std::uint32_t c = segs[i].cycle;
      if (!use_cycle.empty() && (c >= use_cycle.size() || use_cycle[c] == 0)) continue;
      const auto mid = static_cast<std::size_t>(std::max(0.0, segs[i].t0_s * fs));
      if (mid < half || mid + half > rec.accel_ms2.size() || 2 * half < kTransientLen) continue;
      const float* x = rec.accel_ms2.data() + (mid - half);
      const std::size_t n = 2 * half;
      // Crest factor and kurtosis of the first difference: it weights the spectrum by frequency, so a short
      // knock ringing at kHz stands out of a mesh vibration that is strong but lower in frequency (a knock
      // that the raw signal's largest sample and kurtosis miss on a job with a strong mesh). The raw
      // signal's are not compared: the mesh dominates there, so they depend on its unknown harmonic phases
      // (an independent control case read +0.26 in raw log kurtosis, z = 5, and got knocks named).
      dbuf.resize(n - 1);
      for (std::size_t j = 0; j + 1 < n; ++j) dbuf[j] = x[j + 1] - x[j];
      double dkurt = 3.0, dcrest = 0.0;
      window_stats(dbuf.data(), n - 1, dkurt, dcrest);
      dcrest_sum += dcrest;
      dlk_sum += std::log(dkurt);
      double mean = 0.0;
      for (std::size_t j = 0; j < n; ++j) mean += x[j];
      mean /= static_cast<double>(n);
      // The spectrum is taken where the differenced signal peaks (the knock, if there is one).
      std::size_t imax = 0;
      for (std::size_t j = 1; j + 1 < n; ++j) {
        if (std::fabs(dbuf[j]) > std::fabs(dbuf[imax])) imax = j;
      }
      const std::size_t t0 =
          std::min(imax > kTransientLen / 4 ? imax - kTransientLen / 4 : 0, n - kTransientLen);
      const std::vector<float>& th = cache.hann(kTransientLen);
      for (std::size_t j = 0; j < kTransientLen; ++j)
        tbuf[j] = static_cast<float>((x[t0 + j] - mean) * th[j]);
      cache.fft(kTransientLen).forward(tbuf, tspec);
      if (tpow.empty()) tpow.assign(tspec.size(), 0.0);
      for (std::size_t k = 0; k < tspec.size(); ++k) tpow[k] += std::norm(tspec[k]);
      ++count;
    }
    if (count > 0) {
      ps.transient_power = tpow;
      for (double& v : ps.transient_power) v /= static_cast<double>(count);
      add(ps, "transients", "diff_crest_db", dcrest_sum / static_cast<double>(count), kScaleCrestDb, 0, 0,
          SegmentType::kAccel, Stage::kRaw);
      add(ps, "transients", "diff_log_kurtosis", dlk_sum / static_cast<double>(count), kScaleLogKurtosis, 0,
          0, SegmentType::kAccel, Stage::kRaw);
      const double df = fs / static_cast<double>(kTransientLen);
      int bi = 0;
      for (double lo = 500.0; 2.0 * lo <= 0.45 * fs; lo *= 2.0, ++bi) {
        double sum = 0.0;
        int nb = 0;
        for (std::size_t q = bin_of(lo, df); q < bin_of(2.0 * lo, df) && q < tpow.size(); ++q) {
          sum += tpow[q];
          ++nb;
        }
        if (nb < 3) continue;
        add(ps, "transients", "oct" + std::to_string(bi), db(sum / (nb * static_cast<double>(count))),
            kScaleFloorDb, lo, 2.0 * lo, SegmentType::kAccel, Stage::kRaw);
      }
    }
  }

  // ---- amplitude statistics ----------------------------------------------------------------------------
  auto amp_probes = [&](SegmentType type, double log_kurt, double crest, std::size_t count) {
    if (count == 0) return;
    const std::string tn = segment_type_name(type);
    add(ps, "amplitude", tn + ".log_kurtosis", log_kurt / static_cast<double>(count), kScaleLogKurtosis, 0, 0,
        type, Stage::kRaw);
    add(ps, "amplitude", tn + ".crest_db", crest / static_cast<double>(count), kScaleCrestDb, 0, 0, type,
        Stage::kRaw);
  };
  {
    // Kurtosis and crest factor only where the mesh is silent: where it runs they depend on the relative
    // phases of its harmonics, which no nominal knows (a machine with other phases than the nominal's
    // read as an `amplitude` gap on every independent control case, issue 11). Clipping keeps its
    // phase-invariant signature below (flat tops), knocks theirs in the transients probe.
    amp_probes(SegmentType::kStandstill, still_acc.log_kurt, still_acc.crest_db, still_acc.count);
    // Flat tops: share of the windows' samples within 0.2 % of the largest magnitude.
    std::size_t near = 0, total = 0;
    for (const Window* w : used) {
      const float* x = rec.accel_ms2.data() + w->start;
      for (std::size_t i = 0; i < w->len; ++i) near += std::fabs(x[i]) >= 0.998 * max_abs ? 1U : 0U;
      total += w->len;
    }
    ps.rail_samples = near;
    ps.window_samples = total;
    add(ps, "amplitude", "extreme_share_log10",
        std::log10(std::max(static_cast<double>(near) / static_cast<double>(total), 1e-6)),
        kScaleExtremeLog10, 0, 0, SegmentType::kConstant, Stage::kRaw);
  }

  // ---- residual features (PTDA, leave-one-out) and alarms ---------------------------------------------
  ps.classes.resize(plan.speeds.size());
  for (auto& [c, acc] : const_acc) {
    std::vector<const Window*> ws;
    for (const Window* w : used) {
      if (w->type == SegmentType::kConstant && w->speed_class == c) ws.push_back(w);
    }
    if (ws.size() < 3) continue;
    const std::size_t n = acc.len;
    dsp::WindowAnalyzer an(n);
    std::vector<std::vector<float>> mags(ws.size(), std::vector<float>(n / 2 + 1));
    std::vector<double> sum(n / 2 + 1, 0.0);
    for (std::size_t i = 0; i < ws.size(); ++i) {
      an.magnitude(std::span<const float>(rec.accel_ms2.data() + ws[i]->start, n), mags[i]);
      for (std::size_t k = 0; k < sum.size(); ++k) sum[k] += mags[i][k];
    }
    ClassReference& ref = ps.classes[static_cast<std::size_t>(c)];
    ref.mean_magnitude.resize(sum.size());
    for (std::size_t k = 0; k < sum.size(); ++k)
      ref.mean_magnitude[k] = static_cast<float>(sum[k] / static_cast<double>(ws.size()));
    std::vector<float> loo(sum.size());
    std::vector<double> rms_v, ent_v;
    const double m = static_cast<double>(ws.size());
    for (std::size_t i = 0; i < ws.size(); ++i) {
      for (std::size_t k = 0; k < sum.size(); ++k)
        loo[k] = static_cast<float>((sum[k] - mags[i][k]) / (m - 1.0));
      const dsp::Features f = an.analyze_with(std::span<const float>(rec.accel_ms2.data() + ws[i]->start, n),
                                              loo, {}, dsp::Method::kPtda);
      rms_v.push_back(f.rms_res);
      ent_v.push_back(f.entropy_res);
    }
    double mr = 0, me = 0;
    for (std::size_t i = 0; i < rms_v.size(); ++i) {
      mr += rms_v[i];
      me += ent_v[i];
    }
    mr /= m;
    me /= m;
    double vr = 0;
    for (double r : rms_v) vr += (r - mr) * (r - mr);
    ref.rms_mean = mr;
    ref.rms_std = std::sqrt(vr / std::max(1.0, m - 1.0));
    const std::string cls = "c" + std::to_string(c);
    add(ps, "residual", cls + ".rms_db", 20.0 * std::log10(std::max(mr, 1e-12)), kScaleResidualRmsDb, 0, 0,
        SegmentType::kConstant, Stage::kResidual);
    add(ps, "residual", cls + ".entropy", me, kScaleEntropy, 0, 0, SegmentType::kConstant, Stage::kResidual);
    // Alarm: share of windows whose residual rms falls outside mean +- 3 sigma of the reference.
    const ClassReference* rr =
        reference != nullptr && static_cast<std::size_t>(c) < reference->classes.size() &&
                reference->classes[static_cast<std::size_t>(c)].mean_magnitude.size() == sum.size()
            ? &reference->classes[static_cast<std::size_t>(c)]
            : nullptr;
    std::size_t alarms = 0;
    for (std::size_t i = 0; i < ws.size(); ++i) {
      double r = rms_v[i];
      double lo = mr - 3.0 * ref.rms_std, hi = mr + 3.0 * ref.rms_std;
      if (rr != nullptr) {
        r = an.analyze_with(std::span<const float>(rec.accel_ms2.data() + ws[i]->start, n),
                            rr->mean_magnitude, {}, dsp::Method::kPtda)
                .rms_res;
        lo = rr->rms_mean - 3.0 * rr->rms_std;
        hi = rr->rms_mean + 3.0 * rr->rms_std;
      }
      alarms += (r < lo || r > hi) ? 1U : 0U;
    }
    // Reported, not part of the gap: with a handful of windows the rate is too coarse and too sensitive
    // to the reference's spread to be fitted (docs/gap.md).
    ps.alarm_rate[c] = static_cast<double>(alarms) / m;
  }

  // ---- CAN speed vs vibration timing ----------------------------------------------------------------
  ps.lag_s = envelope_lag(rec, segs, use_cycle);
  add(ps, "tracking", "envelope_lag_ms", ps.lag_s * 1e3, kScaleLagMs, 0, 0, SegmentType::kAccel, Stage::kRaw);
  return ps;
}

SpeedScaleEstimate estimate_speed_scale(const ProbeSet& ps, const ProbeContext& ctx, double tolerance) {
  SpeedScaleEstimate out;
  if (tolerance <= 0.0 || ps.fs_hz <= 0.0) return out;
  // A line whose search range (twice the tolerance, so that a scale beyond it is seen and then clamped by
  // the caller) stays within 0.4 x the distance to its nearest listed neighbour cannot be taken for that
  // neighbour: those lines give a first estimate. Every line is then searched around where that estimate
  // puts it, within 3 bins plus 3 sd of the first estimate (at shaft order 640 a 0.25 % slip is 1.6
  // orders, so a wide search there would find a neighbour of the rig's clusters).
  auto measure = [&](double centre, double sd_rel, bool second) {
    std::vector<std::pair<double, double>> rw;  // (ratio - 1, weight)
    for (const auto& [c, p] : ps.class_power) {
      if (c < 0 || static_cast<std::size_t>(c) >= ctx.plan.speeds.size() || p.size() < 64) continue;
      const double df = ps.fs_hz / (2.0 * static_cast<double>(p.size() - 1));
      const double gmf = std::fabs(sim::gmf_hz(ctx.gearbox, ctx.plan.speeds[static_cast<std::size_t>(c)]));
      if (gmf <= 0.0) continue;
      const double f_in = gmf / static_cast<double>(ctx.gearbox.z_in);
      std::vector<double> lines;
      for (int k : ctx.nominal_orders) lines.push_back(k * gmf);
      for (int j : ctx.nominal_shaft_orders) lines.push_back(j * f_in);
      std::sort(lines.begin(), lines.end());
      for (std::size_t i = 0; i < lines.size(); ++i) {
        const double f0 = lines[i];
        if (f0 >= 0.45 * ps.fs_hz || f0 < 8.0 * df) continue;
        double d_min = f0;  // the spectrum's origin is a neighbour too
        if (i > 0) d_min = std::min(d_min, f0 - lines[i - 1]);
        if (i + 1 < lines.size()) d_min = std::min(d_min, lines[i + 1] - f0);
        if (d_min < 4.0 * df) continue;  // two listed lines in one peak
        double half = 2.0 * tolerance * f0;
        if (second) {
          half = std::min(0.4 * d_min, 3.0 * df + 3.0 * sd_rel * f0);
        } else if (half > 0.4 * d_min) {
          continue;
        }
        half = std::max(half, 1.5 * df);
        const double fc = f0 * (1.0 + centre);
        const std::size_t lo = static_cast<std::size_t>(std::max(1.0, std::floor((fc - half) / df)));
        const std::size_t hi = std::min(p.size() - 2, static_cast<std::size_t>(std::ceil((fc + half) / df)));
        if (hi <= lo) continue;
        std::size_t b = lo;
        for (std::size_t q = lo; q <= hi; ++q)
          if (p[q] > p[b]) b = q;
        // A maximum on the search range's edge is a slope, not a line.
        if ((b == lo && p[b - 1] > p[b]) || (b == hi && p[b + 1] > p[b])) continue;
        std::vector<double> around;
        for (std::size_t q = b > 40 ? b - 40 : 1; q <= b + 40 && q + 1 < p.size(); ++q)
          if (q + 3 < b || q > b + 3) around.push_back(p[q]);
        if (around.size() < 20) continue;
        if (db(p[b]) - db(median_of(std::move(around))) < 12.0) continue;
        const double f = interp_peak(p, b) * df;
        rw.push_back({f / f0 - 1.0, (f0 / df) * (f0 / df)});
      }
    }
    return rw;
  };
  auto weighted_median = [](std::vector<std::pair<double, double>> v) {
    std::sort(v.begin(), v.end());
    double total = 0.0;
    for (const auto& [x, w] : v) total += w;
    double acc = 0.0;
    for (const auto& [x, w] : v) {
      acc += w;
      if (acc >= 0.5 * total) return x;
    }
    return v.back().first;
  };
  auto median_and_sd = [&](const std::vector<std::pair<double, double>>& rw) {
    const double med = weighted_median(rw);
    std::vector<std::pair<double, double>> dev;
    for (const auto& [x, w] : rw) dev.push_back({std::fabs(x - med), w});
    return std::pair<double, double>{
        med, 1.4826 * weighted_median(dev) / std::sqrt(static_cast<double>(rw.size()))};
  };
  std::vector<std::pair<double, double>> rw = measure(0.0, 0.0, false);
  if (rw.size() < 2) return out;
  const auto [first, first_sd] = median_and_sd(rw);
  rw = measure(std::clamp(first, -2.0 * tolerance, 2.0 * tolerance), first_sd, true);
  out.lines = static_cast<int>(rw.size());
  if (rw.empty()) return out;
  const auto [med, sd] = median_and_sd(rw);
  out.ppm = med * 1e6;
  out.sd_ppm = sd * 1e6;
  return out;
}

ProbeSet average_probes(const ProbeSet& a, const ProbeSet& b) {
  ProbeSet out;
  std::map<std::string, const ProbeElement*> bk;
  for (const ProbeElement& e : b.elements) bk[e.probe + "/" + e.key] = &e;
  for (const ProbeElement& e : a.elements) {
    auto it = bk.find(e.probe + "/" + e.key);
    if (it == bk.end()) continue;
    ProbeElement m = e;
    m.value = 0.5 * (e.value + it->second->value);
    out.elements.push_back(std::move(m));
  }
  out.classes = a.classes;
  out.windows = a.windows + b.windows;
  out.fs_hz = a.fs_hz;
  auto mean_vec = [](const std::vector<double>& x, const std::vector<double>& y) {
    if (x.size() != y.size()) return x.empty() ? y : x;
    std::vector<double> v(x.size());
    for (std::size_t i = 0; i < x.size(); ++i) v[i] = 0.5 * (x[i] + y[i]);
    return v;
  };
  out.class_power = a.class_power;
  for (auto& [c, p] : out.class_power) {
    auto it = b.class_power.find(c);
    if (it != b.class_power.end()) p = mean_vec(p, it->second);
  }
  for (const auto& [c, p] : b.class_power) out.class_power.emplace(c, p);
  out.accel_power = mean_vec(a.accel_power, b.accel_power);
  out.still_power = mean_vec(a.still_power, b.still_power);
  out.transient_power = mean_vec(a.transient_power, b.transient_power);
  out.max_abs_ms2 = std::max(a.max_abs_ms2, b.max_abs_ms2);
  out.rail_samples = a.rail_samples + b.rail_samples;
  out.window_samples = a.window_samples + b.window_samples;
  out.lag_s = std::isfinite(a.lag_s) && std::isfinite(b.lag_s) ? 0.5 * (a.lag_s + b.lag_s)
              : std::isfinite(a.lag_s)                         ? a.lag_s
                                                               : b.lag_s;
  return out;
}

namespace {

struct Pair {
  const ProbeElement* r;
  const ProbeElement* s;
  double diff;
};

/// Robust slope of y against x (Theil-Sen: the median of the pairwise slopes over pairs at least 0.05
/// apart in x), so that a few bands raised by lines or a resonance do not tilt the floor. 0 with fewer
/// than 4 points.
double floor_slope(const std::vector<std::pair<double, double>>& xy) {
  if (xy.size() < 4) return 0.0;
  std::vector<double> slopes;
  for (std::size_t i = 0; i < xy.size(); ++i)
    for (std::size_t j = i + 1; j < xy.size(); ++j) {
      const double dx = xy[j].first - xy[i].first;
      if (std::fabs(dx) >= 0.05) slopes.push_back((xy[j].second - xy[i].second) / dx);
    }
  return slopes.empty() ? 0.0 : median_of(slopes);
}

/// Matched elements with the free parameters profiled out; fills the offsets of `g`.
std::vector<Pair> profiled_pairs(const ProbeSet& real, const ProbeSet& sim, GapBreakdown& g) {
  std::map<std::string, const ProbeElement*> sim_by_key;
  for (const ProbeElement& e : sim.elements) sim_by_key[e.probe + "/" + e.key] = &e;
  std::vector<Pair> pairs;
  for (const ProbeElement& e : real.elements) {
    auto it = sim_by_key.find(e.probe + "/" + e.key);
    if (it == sim_by_key.end()) continue;
    pairs.push_back({&e, it->second, e.value - it->second->value});
  }
  // Profile out the free parameters of the nominal model.
  std::map<int, std::pair<double, int>> per_order;
  std::map<int, std::pair<double, int>> per_shaft_order;
  const double pivot_hz = ::ptda::sim::noise_tilt_pivot_hz(real.fs_hz > 0.0 ? real.fs_hz : sim.fs_hz);
  auto decades = [&](const ProbeElement& e) {  // band centre in decades from the tilt pivot
    return std::log10(std::sqrt(std::max(e.f_lo_hz, 1.0) * e.f_hi_hz) / pivot_hz);
  };
  std::vector<std::pair<double, double>> floor_xy;
  for (const Pair& p : pairs) {
    if (p.r->probe == "harmonics" || p.r->probe == "shaft_orders") {
      auto& a = (p.r->probe == "harmonics" ? per_order : per_shaft_order)[p.r->order];
      a.first += p.diff;
      a.second += 1;
    } else if (p.r->probe == "noise_floor" && p.r->segment == SegmentType::kConstant && p.r->f_hi_hz > 0.0) {
      floor_xy.push_back({decades(*p.r), p.diff});
    }
  }
  g.noise_tilt_db_per_decade = floor_slope(floor_xy);
  std::vector<double> level;
  for (const auto& [x, d] : floor_xy) level.push_back(d - g.noise_tilt_db_per_decade * x);
  g.noise_offset_db = median_of(level);
  for (auto& [k, a] : per_order) {
    if (k >= static_cast<int>(g.harmonic_offset_db.size()))
      g.harmonic_offset_db.resize(static_cast<std::size_t>(k) + 1, 0.0);
    g.harmonic_offset_db[static_cast<std::size_t>(k)] = a.first / a.second;
  }
  for (const auto& [j, a] : per_shaft_order) g.shaft_order_offset_db[j] = a.first / a.second;
  for (Pair& p : pairs) {
    if (p.r->probe == "harmonics") p.diff -= g.harmonic_offset_db[static_cast<std::size_t>(p.r->order)];
    if (p.r->probe == "shaft_orders") p.diff -= g.shaft_order_offset_db[p.r->order];
    if (p.r->probe == "noise_floor" || (p.r->probe == "transients" && p.r->key.rfind("oct", 0) == 0)) {
      p.diff -= g.noise_offset_db;
      if (p.r->f_hi_hz > 0.0) p.diff -= g.noise_tilt_db_per_decade * decades(*p.r);
    }
  }
  return pairs;
}

}  // namespace

std::map<std::string, double> profiled_differences(const ProbeSet& real, const ProbeSet& sim) {
  GapBreakdown g;
  std::map<std::string, double> out;
  for (const Pair& p : profiled_pairs(real, sim, g)) out[p.r->probe + "/" + p.r->key] = p.diff;
  // The profiled-out free parameters themselves (the calibration's offsets), so that their sampling
  // variance can be estimated like any element's (not gap elements).
  for (std::size_t k = 1; k < g.harmonic_offset_db.size(); ++k)
    out["calib/order.k" + std::to_string(k)] = g.harmonic_offset_db[k];
  for (const auto& [j, o] : g.shaft_order_offset_db) out["calib/shaft.s" + std::to_string(j)] = o;
  out["calib/noise_offset"] = g.noise_offset_db;
  out["calib/noise_tilt"] = g.noise_tilt_db_per_decade;
  return out;
}

ElementVariance jackknife_variance(const GapRecording& rec, const std::vector<Segment>& segs,
                                   const std::vector<Window>& windows, std::uint32_t cycles,
                                   const ProbeContext& ctx) {
  ElementVariance var;
  if (cycles < 3) return var;
  const ProbeSet all = compute_probes(rec, segs, windows, {}, ctx);
  std::map<std::string, std::vector<double>> reps;
  for (std::uint32_t j = 0; j < cycles; ++j) {
    std::vector<char> use(cycles, 1);
    use[j] = 0;
    const ProbeSet part = compute_probes(rec, segs, windows, use, ctx, &all);
    for (const auto& [k, d] : profiled_differences(part, all)) reps[k].push_back(d);
  }
  const double n = static_cast<double>(cycles);
  for (const auto& [k, v] : reps) {
    if (v.size() != cycles) continue;  // not defined in every replicate: no estimate
    double m = 0.0;
    for (double x : v) m += x;
    m /= n;
    double ss = 0.0;
    for (double x : v) ss += (x - m) * (x - m);
    var[k] = (n - 1.0) / n * ss;
  }
  return var;
}

GapBreakdown compare_probes(const ProbeSet& real, const ProbeSet& sim, const ElementVariance* noise) {
  GapBreakdown g;
  std::vector<Pair> pairs = profiled_pairs(real, sim, g);
  std::map<std::string, int> count;
  for (const Pair& p : pairs) ++count[p.r->probe];
  // Local probes: a single strong line is what they look for, so their sum is divided by at most
  // kLocalProbeNorm elements instead of averaging it away over every band.
  for (auto& [probe, n] : count) {
    if (probe == "lines") n = std::min(n, kLocalProbeNorm);
    // Most harmonic elements are orders the nominal model does not have (at the floor clamp on both
    // sides); the sum is divided by at most a dozen so that a level pattern across classes counts.
    if (probe == "harmonics") n = std::min(n, kHarmonicProbeNorm);
  }
  std::map<std::string, double> w2_sum;  // per probe: sum of squared noise weights (chi-square variance)
  std::vector<GapBreakdown::Top> all;
  for (const Pair& p : pairs) {
    double scale2 = p.r->scale * p.r->scale;
    if (noise != nullptr) {
      auto it = noise->find(p.r->probe + "/" + p.r->key);
      if (it != noise->end()) {
        const double w = it->second / (scale2 + it->second);  // share of the scale that is sampling noise
        scale2 += it->second;
        g.expected += w / count[p.r->probe];
        w2_sum[p.r->probe] += w * w;
      }
    }
    const double z = p.diff / std::sqrt(scale2);
    const double c = z * z / count[p.r->probe];
    g.total += c;
    g.by_probe[p.r->probe] += c;
    std::string band = "broadband";
    if (p.r->f_hi_hz > 0.0) {
      const double centre = std::sqrt(std::max(p.r->f_lo_hz, 1.0) * p.r->f_hi_hz);
      const double lo = std::pow(2.0, std::floor(std::log2(centre)));
      band = std::to_string(static_cast<long>(lo)) + "-" + std::to_string(static_cast<long>(2 * lo)) + " Hz";
    }
    g.by_band[band] += c;
    g.by_segment[segment_type_name(p.r->segment)] += c;
    g.by_stage[stage_name(p.r->stage)] += c;
    all.push_back({p.r->probe, p.r->key, p.r->value, p.s->value, z, c});
  }
  std::sort(all.begin(), all.end(),
            [](const auto& a, const auto& b) { return a.contribution > b.contribution; });
  if (all.size() > 12) all.resize(12);
  g.top = std::move(all);
  double var = 0.0;
  for (const auto& [probe, w2] : w2_sum) var += 2.0 * w2 / (static_cast<double>(count[probe]) * count[probe]);
  g.expected_sd = std::sqrt(var);
  return g;
}

std::vector<std::pair<double, double>> floor_excess_db(const ProbeSet& r, const ProbeSet& m, SegmentType type,
                                                       double offset_db) {
  std::map<std::string, double> sim_floor;
  for (const ProbeElement& e : m.elements) {
    if (e.probe == "noise_floor" && e.segment == type) sim_floor[e.key] = e.value;
  }
  std::vector<std::pair<double, double>> bands;
  for (const ProbeElement& e : r.elements) {
    if (e.probe != "noise_floor" || e.segment != type) continue;
    auto it = sim_floor.find(e.key);
    if (it == sim_floor.end()) continue;
    bands.emplace_back(std::sqrt(e.f_lo_hz * e.f_hi_hz), e.value - it->second - offset_db);
  }
  return bands;
}

std::vector<double> more_excess_peaks_hz(const ProbeSet& r, const ProbeSet& m, SegmentType type,
                                         double offset_db, double min_db, std::size_t max_peaks) {
  std::vector<std::pair<double, double>> bands = floor_excess_db(r, m, type, offset_db);  // (centre Hz, dB)
  std::erase_if(bands, [](const auto& b) { return !(b.first > 0.0); });
  std::sort(bands.begin(), bands.end());
  std::vector<std::pair<double, double>> maxima;  // (excess, centre)
  for (std::size_t i = 0; i < bands.size(); ++i) {
    const bool left = i == 0 || bands[i].second > bands[i - 1].second;
    const bool right = i + 1 == bands.size() || bands[i].second >= bands[i + 1].second;
    if (left && right && bands[i].second >= min_db) maxima.emplace_back(bands[i].second, bands[i].first);
  }
  std::sort(maxima.begin(), maxima.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  std::vector<double> taken, out;
  for (const auto& [d, f] : maxima) {
    bool near = false;
    for (double t : taken) near = near || std::fabs(std::log2(f / t)) < 1.0;
    if (near) continue;
    taken.push_back(f);
    if (taken.size() > 1) out.push_back(f);  // the first is excess_peak_hz's
    if (out.size() >= max_peaks) break;
  }
  return out;
}

double transient_excess_peak_hz(const ProbeSet& real, const ProbeSet& sim, double min_hz, double min_db) {
  const std::vector<double>& pr = real.transient_power;
  const std::vector<double>& pm = sim.transient_power;
  if (pr.size() != pm.size() || pr.size() < 8 || !(real.fs_hz > 0.0)) return 0.0;
  const double df = real.fs_hz / static_cast<double>(kTransientLen);
  const auto lo = static_cast<std::size_t>(std::max(2.0, std::ceil(min_hz / df)));
  const std::size_t hi = std::min(pr.size() - 3, static_cast<std::size_t>(0.45 * real.fs_hz / df));
  double best = -1e300, f = 0.0;
  for (std::size_t k = lo; k <= hi; ++k) {
    double r = 0.0, m = 0.0;
    for (std::size_t j = k - 2; j <= k + 2; ++j) {
      r += pr[j];
      m += pm[j];
    }
    if (!(r > 0.0 && m > 0.0)) continue;
    const double e = db(r) - db(m);
    if (e > best) {
      best = e;
      f = static_cast<double>(k) * df;
    }
  }
  return best >= min_db ? f : 0.0;
}

DriveCarrier drive_carrier(const std::vector<double>& real_power, const std::vector<double>& model_power,
                           double df_hz, double near_hz, double min_excess_db) {
  DriveCarrier out;
  const std::size_t n = std::min(real_power.size(), model_power.size());
  if (n < 5 || !(df_hz > 0.0) || !(near_hz > 0.0)) return out;
  const auto lo = static_cast<std::size_t>(std::max(2.0, std::floor((near_hz - kDriveSearchHz) / df_hz)));
  const auto hi = std::min(n - 2, static_cast<std::size_t>(std::ceil((near_hz + kDriveSearchHz) / df_hz)));
  struct Peak {
    double hz, excess_db;
  };
  std::vector<Peak> peaks;
  for (std::size_t k = lo; k <= hi; ++k) {
    const double p = real_power[k];
    if (!(p >= real_power[k - 1] && p >= real_power[k + 1] && p > 0.0 && model_power[k] > 0.0)) continue;
    const double excess = db(p) - db(model_power[k]);
    if (excess < min_excess_db) continue;
    double f = static_cast<double>(k) * df_hz;
    const double a = db(real_power[k - 1]), b = db(p), c = db(real_power[k + 1]);
    const double den = a - 2 * b + c;
    if (den < 0) f += 0.5 * (a - c) / den * df_hz;
    peaks.push_back({f, excess});
  }
  if (peaks.empty()) return out;
  const Peak carrier = *std::max_element(
      peaks.begin(), peaks.end(), [](const Peak& x, const Peak& y) { return x.excess_db < y.excess_db; });
  out.carrier_hz = carrier.hz;
  double best = -1e300;
  for (const Peak& p : peaks) {
    const double d = p.hz - carrier.hz;
    if (d < 2.0 * df_hz) continue;  // each pair once, from its upper member
    const double tol = std::max(2.0 * df_hz, 0.02 * d);
    for (const Peak& m : peaks) {
      if (std::fabs(m.hz - (carrier.hz - d)) > tol) continue;
      if (p.excess_db + m.excess_db > best) {
        best = p.excess_db + m.excess_db;
        out.side_hz = 0.5 * (p.hz - m.hz);
      }
    }
  }
  return out;
}

}  // namespace ptda::gap
