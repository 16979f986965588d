// Learning a class baseline from healthy windows: mean magnitude / mean waveform over all windows,
// thresholds from leave-one-group-out features. Offline code: allocates and throws ptda::Error.
#include "ptda/dsp/training.hpp"

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <cstdio>
#include <functional>
#include <initializer_list>
#include <map>
#include <memory>
#include <numbers>
#include <string>

#include "ptda/common/error.hpp"
#include "ptda/dsp/analyzer.hpp"
#include "ptda/dsp/band_energy.hpp"
#include "ptda/dsp/real_fft.hpp"
#include "ptda/dsp/spill.hpp"

namespace ptda::dsp {

double inverse_normal_cdf(double p) {
  if (!(p > 0.0 && p < 1.0)) {
    throw Error("inverse_normal_cdf: probability " + std::to_string(p) + " is not in (0, 1)");
  }
  // Work in the lower tail, where erfc keeps full relative precision; the upper tail by symmetry.
  if (p > 0.5) return -inverse_normal_cdf(1.0 - p);
  // Starting point: Abramowitz & Stegun 26.2.23 (|error| < 4.5e-4).
  const double t = std::sqrt(-2.0 * std::log(p));
  double x = -(t - (2.515517 + t * (0.802853 + t * 0.010328)) /
                       (1.0 + t * (1.432788 + t * (0.189269 + t * 0.001308))));
  // Halley steps on Phi(x) - p (cubic convergence: two steps already reach double precision).
  for (int i = 0; i < 6; ++i) {
    const double e = 0.5 * std::erfc(-x / std::numbers::sqrt2) - p;
    const double u = e * std::sqrt(2.0 * std::numbers::pi) * std::exp(0.5 * x * x);
    const double step = u / (1.0 + 0.5 * x * u);
    x -= step;
    if (std::abs(step) <= 1e-15 * std::max(1.0, std::abs(x))) break;
  }
  return x;
}

namespace {

// Statistics of values handed over in chunks (`chunks(f)` calls f(std::span<const double>) on each, in
// order). One chunk gives exactly the Eigen sums of feature_stats(span); more (spilled training values)
// sum each chunk with Eigen and add the chunks' sums, which differs only in rounding.
template <class Chunks>
FeatureStats chunked_stats(std::size_t n, Chunks&& chunks) {
  FeatureStats s;
  s.n = static_cast<std::uint32_t>(n);
  if (n == 0) return s;
  bool first = true;
  double sum = 0.0;
  chunks([&](std::span<const double> c) {
    if (c.empty()) return;
    const Eigen::Map<const Eigen::ArrayXd> v(c.data(), static_cast<Eigen::Index>(c.size()));
    s.min = first ? v.minCoeff() : std::min(s.min, v.minCoeff());
    s.max = first ? v.maxCoeff() : std::max(s.max, v.maxCoeff());
    sum = first ? v.sum() : sum + v.sum();
    first = false;
  });
  s.mean = sum / static_cast<double>(n);
  if (n > 1) {
    double ss = 0.0;
    bool first_ss = true;
    chunks([&](std::span<const double> c) {
      if (c.empty()) return;
      const Eigen::Map<const Eigen::ArrayXd> v(c.data(), static_cast<Eigen::Index>(c.size()));
      const double part = (v - s.mean).square().sum();
      ss = first_ss ? part : ss + part;
      first_ss = false;
    });
    s.stddev = std::sqrt(ss / static_cast<double>(n - 1));
  }
  return s;
}

}  // namespace

FeatureStats feature_stats(std::span<const double> values) {
  return chunked_stats(values.size(), [&](const auto& f) { f(values); });
}

FeatureStats feature_stats(const SpillVector<double>& values) {
  if (!values.spilled()) return feature_stats(values.memory());
  return chunked_stats(values.size(), [&](const auto& f) { values.for_each_chunk(f); });
}

namespace {

// Linear interpolation between order statistics (the "type 7" sample quantile): h = (n-1) q.
double sorted_quantile(const std::vector<double>& sorted, double q) {
  const double h = static_cast<double>(sorted.size() - 1) * q;
  const auto lo = static_cast<std::size_t>(std::floor(h));
  const std::size_t hi = std::min(lo + 1, sorted.size() - 1);
  return sorted[lo] + (h - static_cast<double>(lo)) * (sorted[hi] - sorted[lo]);
}

}  // namespace

namespace {

void check_tolerance_args(std::uint32_t n, double p, double confidence, const char* what) {
  if (n < 3) throw Error(std::string(what) + ": needs n >= 3 values, got " + std::to_string(n));
  if (!(p > 0.5 && p < 1.0)) {
    throw Error(std::string(what) + ": coverage " + std::to_string(p) + " is not in (0.5, 1)");
  }
  if (!(confidence > 0.5 && confidence < 1.0)) {
    throw Error(std::string(what) + ": confidence " + std::to_string(confidence) + " is not in (0.5, 1)");
  }
}

}  // namespace

double tolerance_factor_one_sided(std::uint32_t n, double p, double confidence) {
  check_tolerance_args(n, p, confidence, "tolerance_factor_one_sided");
  const double zp = inverse_normal_cdf(p);
  const double zg = inverse_normal_cdf(confidence);
  const auto nd = static_cast<double>(n);
  const double a = 1.0 - zg * zg / (2.0 * (nd - 1.0));
  const double b = zp * zp - zg * zg / nd;
  const double disc = zp * zp - a * b;
  if (!(a > 0.0) || !(disc >= 0.0)) {
    throw Error("tolerance_factor_one_sided: n = " + std::to_string(n) + " is too small for confidence " +
                std::to_string(confidence));
  }
  return (zp + std::sqrt(disc)) / a;
}

double tolerance_factor_two_sided(std::uint32_t n, double p, double confidence) {
  check_tolerance_args(n, p, confidence, "tolerance_factor_two_sided");
  const double nu = static_cast<double>(n) - 1.0;
  // Wilson-Hilferty: chi2_q(nu) = nu (1 - 2/(9 nu) + z_q sqrt(2/(9 nu)))^3, here q = 1 - confidence.
  const double c = 2.0 / (9.0 * nu);
  const double base = 1.0 - c + inverse_normal_cdf(1.0 - confidence) * std::sqrt(c);
  if (!(base > 0.0)) {
    throw Error("tolerance_factor_two_sided: n = " + std::to_string(n) + " is too small for confidence " +
                std::to_string(confidence));
  }
  const double chi2 = nu * base * base * base;
  const double z = inverse_normal_cdf(0.5 * (1.0 + p));
  return z * std::sqrt(nu * (1.0 + 1.0 / static_cast<double>(n)) / chi2);
}

double small_sample_scale(std::uint32_t n, const ThresholdPolicy& policy) noexcept {
  try {
    if (n < 3) return 1.0;
    const double alpha = policy.false_alarm_rate;
    return std::max(
        1.0, tolerance_factor_one_sided(n, 1.0 - alpha, policy.confidence) / inverse_normal_cdf(1.0 - alpha));
  } catch (const Error&) {
    return 1.0;
  }
}

void VarianceAccumulator::add(double value, std::uint32_t group) {
  if (last_ >= groups_.size() || groups_[last_].id != group) {
    last_ = 0;
    while (last_ < groups_.size() && groups_[last_].id != group) ++last_;
    if (last_ == groups_.size()) groups_.push_back(Group{group, 0, 0.0, 0.0, 0.0});
  }
  Group& g = groups_[last_];
  ++g.n;
  g.sum += value;
  const double d = value - g.mean;
  g.mean += d / static_cast<double>(g.n);
  g.m2 += d * (value - g.mean);
  total_ += value;
  ++n_;
}

VarianceComponents VarianceAccumulator::result() const {
  if (n_ == 0) throw Error("variance_components: no values");
  VarianceComponents vc;
  vc.n = static_cast<std::uint32_t>(n_);
  const auto n = static_cast<double>(n_);
  const auto r = static_cast<double>(groups_.size());
  vc.groups = static_cast<std::uint32_t>(groups_.size());
  vc.mean = total_ / n;
  // Within: the groups' own squared deviations; total = within + between (exact for any split).
  double ssw = 0.0;
  double ssb = 0.0;
  double sum_n2 = 0.0;
  for (const Group& g : groups_) {
    const auto ng = static_cast<double>(g.n);
    const double d = g.sum / ng - vc.mean;
    ssw += g.m2;
    ssb += ng * d * d;
    sum_n2 += ng * ng;
  }
  if (groups_.size() < 2 || n_ == groups_.size()) {
    vc.within_var = n_ > 1 ? (ssw + ssb) / (n - 1.0) : 0.0;
    return vc;
  }
  vc.within_var = ssw / (n - r);
  vc.msb = ssb / (r - 1.0);
  vc.n0 = (n - sum_n2 / n) / (r - 1.0);
  vc.between_var = std::max(0.0, (vc.msb - vc.within_var) / vc.n0);
  return vc;
}

VarianceComponents variance_components(std::span<const double> values,
                                       std::span<const std::uint32_t> groups) {
  if (!groups.empty() && groups.size() != values.size()) {
    throw Error("variance_components: " + std::to_string(groups.size()) + " group ids for " +
                std::to_string(values.size()) + " values");
  }
  VarianceAccumulator acc;
  for (std::size_t i = 0; i < values.size(); ++i) acc.add(values[i], groups.empty() ? 0U : groups[i]);
  return acc.result();
}

SeqScale sequential_scale(const ClassBaseline& c, Method method, const ThresholdPolicy& policy,
                          double day_allowance) noexcept {
  const auto mi = static_cast<std::size_t>(method);
  SeqScale s;
  s.log_rms = c.log_rms_stats[mi];
  s.entropy = c.entropy_stats[mi];
  s.scale = small_sample_scale(c.log_rms_stats[mi].n, policy);
  const DaySpread& d = c.day_spread[mi];
  if (d.recordings == 0) return s;  // format <= 3: the session-6 standardisation
  s.log_rms.stddev = d.log_rms_within_sd;
  s.entropy.stddev = d.entropy_within_sd;
  const double days = std::sqrt(1.0 + 1.0 / static_cast<double>(d.recordings));
  const auto allowance = [&](double between, const FeatureStats& st) {
    const double sd = s.scale * std::max(st.stddev, 1e-9 * std::max(1.0, std::abs(st.mean)));
    return day_allowance * between * days / sd;
  };
  s.rms_allowance = allowance(d.log_rms_between_sd, s.log_rms);
  s.entropy_allowance = allowance(d.entropy_between_sd, s.entropy);
  return s;
}

namespace {

// What fit_band() reads: the values in memory (one span) or in a spill vector (chunks; quantiles from
// a bounded-memory sort). The span source gives exactly the results of the in-memory code.
struct SpanSource {
  std::span<const double> v;
  [[nodiscard]] std::size_t size() const { return v.size(); }
  template <class F>
  void chunks(F&& f) const {
    f(v);
  }
  // Type-7 quantiles of the values.
  [[nodiscard]] std::vector<double> quantiles(std::initializer_list<double> qs) const {
    std::vector<double> sorted(v.begin(), v.end());
    std::sort(sorted.begin(), sorted.end());
    std::vector<double> out;
    for (const double q : qs) out.push_back(sorted_quantile(sorted, q));
    return out;
  }
};

struct SpillSource {
  const SpillVector<double>& v;
  [[nodiscard]] std::size_t size() const { return v.size(); }
  template <class F>
  void chunks(F&& f) const {
    v.for_each_chunk(f);
  }
  [[nodiscard]] std::vector<double> quantiles(std::initializer_list<double> qs) const {
    const SpillVector<double> s = sorted(v, std::less<>());
    std::vector<double> out;
    for (const double q : qs) {
      const double h = static_cast<double>(s.size() - 1) * q;
      const auto lo = static_cast<std::size_t>(std::floor(h));
      const std::size_t hi = std::min(lo + 1, s.size() - 1);
      const double a = s.at(lo);
      out.push_back(a + (h - static_cast<double>(lo)) * (s.at(hi) - a));
    }
    return out;
  }
};

template <class Source>
Band fit_band_from(const Source& src, const ThresholdPolicy& policy, FeatureScale scale, double day_ratio,
                   double within_ratio) {
  const std::size_t count = src.size();
  if (count < 2) {
    throw Error("fit_band: needs at least 2 feature values, got " + std::to_string(count));
  }
  {
    std::size_t i = 0;
    src.chunks([&](std::span<const double> c) {
      for (const double x : c) {
        if (!std::isfinite(x)) throw Error("fit_band: feature value " + std::to_string(i) + " is not finite");
        ++i;
      }
    });
  }
  const double alpha = policy.false_alarm_rate;
  if (!(alpha > 0.0 && alpha < 1.0)) {
    throw Error("fit_band: false_alarm_rate " + std::to_string(alpha) + " is not in (0, 1)");
  }
  if (!(policy.margin >= 0.0 && std::isfinite(policy.margin))) {
    throw Error("fit_band: margin " + std::to_string(policy.margin) + " must be finite and >= 0");
  }
  if (!(std::isfinite(day_ratio) && day_ratio >= 0.0 && std::isfinite(within_ratio) && within_ratio > 0.0)) {
    throw Error("fit_band: between-day ratio " + std::to_string(day_ratio) +
                " must be finite and >= 0, within ratio " + std::to_string(within_ratio) + " finite and > 0");
  }
  const auto stats = [&] { return chunked_stats(count, [&](const auto& f) { src.chunks(f); }); };
  // The sd of a new day's value: the within-day sd (within_ratio x the sample sd) with the between-day
  // part added, sqrt(w^2 + b^2) = w sqrt(1 + day_ratio^2).
  const double widen_sd = day_ratio > 0.0 ? within_ratio * std::sqrt(1.0 + day_ratio * day_ratio) : 1.0;
  const auto total_sd = [&](double sample_sd) { return widen_sd * sample_sd; };
  Band b;
  switch (policy.kind) {
    case ThresholdPolicy::Kind::kGaussian: {
      const FeatureStats s = stats();
      const double z = -inverse_normal_cdf(0.5 * alpha);  // two-sided: alpha/2 in each tail
      const double sd = total_sd(s.stddev);
      b = Band{s.mean - z * sd, s.mean + z * sd};
      break;
    }
    case ThresholdPolicy::Kind::kQuantile: {
      const std::vector<double> q = src.quantiles({0.5 * alpha, 1.0 - 0.5 * alpha, 0.5});
      b = Band{q[0], q[1]};
      if (day_ratio > 0.0) {  // both quantiles move away from the median by the same factor
        const double med = q[2];
        b = Band{med - widen_sd * (med - b.lo), med + widen_sd * (b.hi - med)};
      }
      break;
    }
    case ThresholdPolicy::Kind::kTolerance: {
      const auto n = static_cast<std::uint32_t>(count);
      if (scale == FeatureScale::kLog) {
        // The logs chunk by chunk (one chunk in memory: the same values as a whole log vector).
        std::vector<double> logs;
        const auto log_chunks = [&](const auto& f) {
          std::size_t i = 0;
          src.chunks([&](std::span<const double> c) {
            logs.resize(c.size());
            for (std::size_t j = 0; j < c.size(); ++j, ++i) {
              if (!(c[j] > 0.0)) {
                throw Error("fit_band: feature value " + std::to_string(i) + " = " + std::to_string(c[j]) +
                            " is not > 0 (the log-scale tolerance model needs positive values)");
              }
              logs[j] = std::log(c[j]);
            }
            f(std::span<const double>(logs));
          });
        };
        const FeatureStats s = chunked_stats(count, log_chunks);
        const double k1 = tolerance_factor_one_sided(n, 1.0 - alpha, policy.confidence);
        const double sd = total_sd(s.stddev);
        b = Band{std::exp(s.mean - k1 * sd), std::exp(s.mean + k1 * sd)};
      } else {
        const FeatureStats s = stats();
        const double k2 = tolerance_factor_two_sided(n, 1.0 - alpha, policy.confidence);
        const double sd = total_sd(s.stddev);
        b = Band{s.mean - k2 * sd, s.mean + k2 * sd};
      }
      break;
    }
    default:
      throw Error("fit_band: unknown threshold policy kind " + std::to_string(static_cast<int>(policy.kind)));
  }
  const double widen = policy.margin * (b.hi - b.lo);
  b.lo -= widen;
  b.hi += widen;
  return b;
}

}  // namespace

Band fit_band(std::span<const double> values, const ThresholdPolicy& policy, FeatureScale scale,
              double day_ratio, double within_ratio) {
  return fit_band_from(SpanSource{values}, policy, scale, day_ratio, within_ratio);
}

Band fit_band(const SpillVector<double>& values, const ThresholdPolicy& policy, FeatureScale scale,
              double day_ratio, double within_ratio) {
  if (!values.spilled()) return fit_band(values.memory(), policy, scale, day_ratio, within_ratio);
  return fit_band_from(SpillSource{values}, policy, scale, day_ratio, within_ratio);
}

Band cover_recordings(const Band& pooled, std::span<const double> values,
                      std::span<const std::uint32_t> recordings, const ThresholdPolicy& policy,
                      FeatureScale scale) {
  if (!recordings.empty() && recordings.size() != values.size()) {
    throw Error("cover_recordings: " + std::to_string(recordings.size()) + " recording ids for " +
                std::to_string(values.size()) + " values");
  }
  if (recordings.empty()) return pooled;
  std::map<std::uint32_t, std::vector<double>> by_recording;
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (scale == FeatureScale::kLog && !(values[i] > 0.0)) continue;  // as the pooled log model
    by_recording[recordings[i]].push_back(values[i]);
  }
  if (by_recording.size() < 2) return pooled;
  Band b = pooled;
  for (const auto& [id, v] : by_recording) {
    if (v.size() < 3) continue;
    Band r;
    try {
      r = fit_band(v, policy, scale);
    } catch (const Error& e) {
      throw Error("cover_recordings: recording " + std::to_string(id) + ": " + e.what());
    }
    b.lo = std::min(b.lo, r.lo);
    b.hi = std::max(b.hi, r.hi);
  }
  return b;
}

Band cover_recordings(const Band& pooled, const SpillVector<double>& values,
                      const SpillVector<std::uint32_t>& recordings, const ThresholdPolicy& policy,
                      FeatureScale scale) {
  if (!values.spilled() && !recordings.spilled())
    return cover_recordings(pooled, values.memory(), recordings.memory(), policy, scale);
  if (recordings.size() != values.size()) {
    throw Error("cover_recordings: " + std::to_string(recordings.size()) + " recording ids for " +
                std::to_string(values.size()) + " values");
  }
  // Each recording's values in a spill vector of its own (few recordings: days of training).
  std::map<std::uint32_t, SpillVector<double>> by_recording;
  {
    SpillVector<double>::Reader v(values);
    SpillVector<std::uint32_t>::Reader r(recordings);
    while (!v.done()) {
      const double x = v.next();
      const std::uint32_t id = r.next();
      if (scale == FeatureScale::kLog && !(x > 0.0)) continue;  // as the pooled log model
      by_recording.try_emplace(id, values.config()).first->second.push_back(x);
    }
  }
  if (by_recording.size() < 2) return pooled;
  Band b = pooled;
  for (const auto& [id, v] : by_recording) {
    if (v.size() < 3) continue;
    Band r;
    try {
      r = fit_band(v, policy, scale);
    } catch (const Error& e) {
      throw Error("cover_recordings: recording " + std::to_string(id) + ": " + e.what());
    }
    b.lo = std::min(b.lo, r.lo);
    b.hi = std::max(b.hi, r.hi);
  }
  return b;
}

struct ClassBaselineBuilder::State {
  State(const SegmentClass& seg, std::size_t n_in, const ThresholdPolicy& pol, const SpillConfig& spill_in)
      : where("class " + std::to_string(seg.id)),
        policy(pol),
        n(n_in),
        bins(n_in / 2 + 1),
        analyzer(n_in),
        fft(n_in),
        mag(bins),
        total_mag(bins, 0.0),
        total_x(n_in, 0.0),
        group_mag(bins),
        group_x(n_in),
        loo_mag(bins),
        loo_x(n_in),
        loo_x_spectrum(bins),
        spill(spill_in),
        value_recording(spill_in) {
    cls.segment = seg;
    for (auto& v : rms_values) v = SpillVector<double>(spill_in);
    for (auto& v : entropy_values) v = SpillVector<double>(spill_in);
  }
  std::string where;
  ThresholdPolicy policy;
  std::size_t n;
  std::size_t bins;
  WindowAnalyzer analyzer;
  RealFft fft;
  ClassBaseline cls;
  std::size_t m = 0;  // pass-1 windows
  bool mean_done = false;
  bool finished = false;
  std::size_t groups = 0;  // pass-2 groups scored
  std::vector<float> mag;
  // Sums over all windows, in double so subtracting one group's share loses nothing.
  std::vector<double> total_mag;
  std::vector<double> total_x;
  std::vector<double> group_mag;
  std::vector<double> group_x;
  std::vector<float> loo_mag;
  std::vector<float> loo_x;
  std::vector<std::complex<float>> loo_x_spectrum;
  SpillConfig spill;
  // The leave-one-out features, in scoring order: kept in memory up to spill.memory_bytes each.
  std::array<SpillVector<double>, kMethodCount> rms_values;
  std::array<SpillVector<double>, kMethodCount> entropy_values;
  SpillVector<std::uint32_t> value_recording;  // the recording of each value, in the values' order
  // Band CUSUM statistics (policy.band_count > 0): clean floor bins of the full mean, and per band the
  // leave-one-out ln band energies of the referred PTDA residual, in the values' order.
  std::vector<unsigned char> clean;
  std::vector<VarianceAccumulator> band_values;  ///< per band, added window by window (no value kept)
  std::array<double, kMaxBands> band_tmp{};
};

ClassBaselineBuilder::ClassBaselineBuilder(const SegmentClass& segment, std::size_t window_len,
                                           const ThresholdPolicy& policy, const SpillConfig& spill) {
  const std::string where = "class " + std::to_string(segment.id);
  if (!RealFft::supported_length(window_len)) {
    throw Error(where + ": window length " + std::to_string(window_len) +
                " is not supported (even, >= 4, prime factors 2, 3, 5 only)");
  }
  if (!(std::isfinite(policy.day_sd_floor) && policy.day_sd_floor >= 0.0)) {
    throw Error(where + ": thresholds.day_sd_floor must be finite and >= 0");
  }
  if (policy.band_count > kMaxBands || policy.band_count > window_len / 2) {
    throw Error(where + ": decision.band_count = " + std::to_string(policy.band_count) + " must be <= " +
                std::to_string(kMaxBands) + " and <= window_len / 2 = " + std::to_string(window_len / 2));
  }
  s_ = std::make_unique<State>(segment, window_len, policy, spill);
}

ClassBaselineBuilder::~ClassBaselineBuilder() = default;
ClassBaselineBuilder::ClassBaselineBuilder(ClassBaselineBuilder&&) noexcept = default;
ClassBaselineBuilder& ClassBaselineBuilder::operator=(ClassBaselineBuilder&&) noexcept = default;

void ClassBaselineBuilder::add_to_mean(std::span<const float> x) {
  State& s = *s_;
  if (s.mean_done) throw Error(s.where + ": add_to_mean() after finish_mean()");
  if (x.size() != s.n) {
    throw Error(s.where + ": window " + std::to_string(s.m) + " has " + std::to_string(x.size()) +
                " samples, expected " + std::to_string(s.n));
  }
  for (std::size_t j = 0; j < s.n; ++j) {
    if (!std::isfinite(x[j])) {
      throw Error(s.where + ": window " + std::to_string(s.m) + " sample " + std::to_string(j) +
                  " is not finite");
    }
  }
  const auto nb = static_cast<Eigen::Index>(s.bins);
  const auto nn = static_cast<Eigen::Index>(s.n);
  s.analyzer.magnitude(x, s.mag);
  Eigen::Map<Eigen::ArrayXd>(s.total_mag.data(), nb) +=
      Eigen::Map<const Eigen::ArrayXf>(s.mag.data(), nb).cast<double>();
  Eigen::Map<Eigen::ArrayXd>(s.total_x.data(), nn) +=
      Eigen::Map<const Eigen::ArrayXf>(x.data(), nn).cast<double>();
  ++s.m;
}

void ClassBaselineBuilder::finish_mean() {
  State& s = *s_;
  if (s.mean_done) throw Error(s.where + ": finish_mean() called twice");
  if (s.m == 0) throw Error(s.where + ": no training windows");
  s.mean_done = true;
  const auto nb = static_cast<Eigen::Index>(s.bins);
  const auto nn = static_cast<Eigen::Index>(s.n);
  ClassBaseline& cls = s.cls;
  cls.n_windows = static_cast<std::uint32_t>(s.m);
  cls.mean_magnitude.resize(s.bins);
  cls.tda_mean.resize(s.n);
  Eigen::Map<Eigen::ArrayXf>(cls.mean_magnitude.data(), nb) =
      (Eigen::Map<const Eigen::ArrayXd>(s.total_mag.data(), nb) / static_cast<double>(s.m)).cast<float>();
  Eigen::Map<Eigen::ArrayXf>(cls.tda_mean.data(), nn) =
      (Eigen::Map<const Eigen::ArrayXd>(s.total_x.data(), nn) / static_cast<double>(s.m)).cast<float>();
  // The line groups come from the mean of all the class's windows and are used for every
  // leave-one-out residual too (a group's gain is fitted per window, so the grouping barely depends on
  // the one window left out).
  if (s.policy.ptda_line_gain) cls.line_groups = find_line_groups(cls.mean_magnitude);
  cls.floor_gain = s.policy.ptda_floor_gain;
  cls.tda_spectrum.resize(s.bins);
  s.fft.forward(cls.tda_mean, cls.tda_spectrum);
  if (s.policy.band_count > 0) {
    // From the mean of all the class's windows, like the line groups (docs/method.md §6, band detector).
    s.clean = clean_floor_bins(cls.mean_magnitude);
    s.band_values.assign(s.policy.band_count, VarianceAccumulator{});
  }
}

const ClassBaseline& ClassBaselineBuilder::means() const noexcept {
  return s_->cls;
}

void ClassBaselineBuilder::score_group(std::span<const std::span<const float>> windows,
                                       std::span<const std::uint32_t> recordings) {
  State& s = *s_;
  if (!s.mean_done || s.finished) throw Error(s.where + ": score_group() outside pass 2");
  if (windows.empty()) throw Error(s.where + ": score_group() with no windows");
  if (!recordings.empty() && recordings.size() != windows.size()) {
    throw Error(s.where + ": " + std::to_string(recordings.size()) + " recording ids for a group of " +
                std::to_string(windows.size()) + " windows");
  }
  if (windows.size() >= s.m) {
    throw Error(s.where + ": a group of " + std::to_string(windows.size()) + " windows leaves none of the " +
                std::to_string(s.m) + " windows of the mean");
  }
  for (const auto& w : windows) {
    if (w.size() != s.n) {
      throw Error(s.where + ": a window of " + std::to_string(w.size()) + " samples, expected " +
                  std::to_string(s.n));
    }
  }
  // Leave-one-group-out: each window is scored against the means of the windows of the other groups.
  // One group's sums are formed at a time (O(N) extra memory). Forward transforms per window: one for
  // the totals of pass 1, one for its group's sums, one for the three methods' features (none when the
  // group is that one window: the group pass's transform is reused); plus one per group for the
  // leave-one-out TDA mean (was 8 per window: 2 magnitudes, raw 1, TDA 2, PTDA 2 + 1 inverse).
  const auto nb = static_cast<Eigen::Index>(s.bins);
  const auto nn = static_cast<Eigen::Index>(s.n);
  const Eigen::Map<const Eigen::ArrayXf> mag_a(s.mag.data(), nb);
  const Eigen::Map<const Eigen::ArrayXd> total_mag_a(s.total_mag.data(), nb);
  const Eigen::Map<const Eigen::ArrayXd> total_x_a(s.total_x.data(), nn);
  Eigen::Map<Eigen::ArrayXd> group_mag_a(s.group_mag.data(), nb);
  Eigen::Map<Eigen::ArrayXd> group_x_a(s.group_x.data(), nn);
  group_mag_a.setZero();
  group_x_a.setZero();
  for (const auto& w : windows) {
    s.analyzer.magnitude(w, s.mag);
    group_mag_a += mag_a.cast<double>();
    group_x_a += Eigen::Map<const Eigen::ArrayXf>(w.data(), nn).cast<double>();
  }
  const auto others = static_cast<double>(s.m - windows.size());
  Eigen::Map<Eigen::ArrayXf>(s.loo_mag.data(), nb) = ((total_mag_a - group_mag_a) / others).cast<float>();
  Eigen::Map<Eigen::ArrayXf>(s.loo_x.data(), nn) = ((total_x_a - group_x_a) / others).cast<float>();
  s.fft.forward(s.loo_x, s.loo_x_spectrum);
  const bool reuse = windows.size() == 1;  // the analyzer still holds that window's transform
  std::array<Features, kMethodCount> f{};
  for (std::size_t k = 0; k < windows.size(); ++k) {
    s.analyzer.analyze_all(windows[k], s.loo_mag, s.loo_x_spectrum, s.cls.line_groups, f, reuse,
                           s.cls.floor_gain);
    s.value_recording.push_back(recordings.empty() ? 0U : recordings[k]);
    for (std::size_t mi = 0; mi < kMethodCount; ++mi) {
      s.rms_values[mi].push_back(f[mi].rms_res);
      s.entropy_values[mi].push_back(f[mi].entropy_res);
    }
    if (!s.band_values.empty()) {
      // analyze_all() ends with PTDA: the analyzer's energies are its (leave-one-out, referred) residual.
      band_log_energies(s.analyzer.residual_energy(), s.clean, s.band_values.size(), s.band_tmp);
      for (std::size_t b = 0; b < s.band_values.size(); ++b) {
        s.band_values[b].add(s.band_tmp[b], recordings.empty() ? 0U : recordings[k]);
      }
    }
  }
  ++s.groups;
}

ClassBaseline ClassBaselineBuilder::finish() {
  State& s = *s_;
  if (!s.mean_done || s.finished) throw Error(s.where + ": finish() outside pass 2");
  if (s.groups < 3) {
    throw Error(s.where +
                ": leave-one-group-out training needs windows from at least 3 groups (regions), got " +
                std::to_string(s.groups));
  }
  s.finished = true;
  ClassBaseline& cls = s.cls;
  const ThresholdPolicy& policy = s.policy;
  const std::string& where = s.where;
  const auto& rms_values = s.rms_values;
  const auto& entropy_values = s.entropy_values;
  const auto& value_recording = s.value_recording;

  for (std::size_t mi = 0; mi < kMethodCount; ++mi) {
    const std::string what = where + ", method " + std::string(method_name(static_cast<Method>(mi)));
    const SpillVector<double>& rms = rms_values[mi];
    const SpillVector<double>& entropy = entropy_values[mi];
    // Within- and between-day spread of the leave-one-out features, recordings as groups (docs/method.md
    // §5). A zero residual is left out of the log values, as below. Streamed: the accumulators take the
    // values in order (the same sums as variance_components() of whole vectors).
    VarianceAccumulator log_acc;
    VarianceAccumulator entropy_acc;
    std::size_t n_logs = 0;
    {
      SpillVector<double>::Reader r(rms);
      SpillVector<double>::Reader e(entropy);
      SpillVector<std::uint32_t>::Reader rec(value_recording);
      while (!r.done()) {
        const double v = r.next();
        const std::uint32_t id = rec.next();
        if (v > 0.0) {
          log_acc.add(std::log(v), id);
          ++n_logs;
        }
        entropy_acc.add(e.next(), id);
      }
    }
    // The positive values' logs chunk by chunk (one chunk in memory: the whole log vector as before).
    std::vector<double> log_buf;
    const auto log_chunks = [&](const auto& f) {
      rms.for_each_chunk([&](std::span<const double> c) {
        log_buf.clear();
        for (const double v : c) {
          if (v > 0.0) log_buf.push_back(std::log(v));
        }
        f(std::span<const double>(log_buf));
      });
    };
    const FeatureStats log_stats = chunked_stats(n_logs, log_chunks);
    DaySpread& day = cls.day_spread[mi];
    if (n_logs > 0) {
      const VarianceComponents vl = log_acc.result();
      day.log_rms_within_sd = std::sqrt(vl.within_var);
      day.log_rms_between_est = std::sqrt(vl.between_var);
    }
    const VarianceComponents ve = entropy_acc.result();
    day.recordings = ve.groups;
    day.entropy_within_sd = std::sqrt(ve.within_var);
    day.entropy_between_est = std::sqrt(ve.between_var);
    // One recording shows no between-day spread: the prior (day_sd_floor x within sd) stands in for it.
    // With R recordings the estimate has R - 1 degrees of freedom; the prior counts as one more:
    // between_var = ((R - 1) estimate^2 + prior^2) / R.
    const auto pooled = [&](double est, double within) {
      const double prior = policy.day_sd_floor * within;
      const double r = static_cast<double>(std::max<std::uint32_t>(1, ve.groups));
      return std::sqrt(((r - 1.0) * est * est + prior * prior) / r);
    };
    day.log_rms_between_sd = pooled(day.log_rms_between_est, day.log_rms_within_sd);
    day.entropy_between_sd = pooled(day.entropy_between_est, day.entropy_within_sd);
    const FeatureStats entropy_stats = feature_stats(entropy);
    try {
      // Ratios, so the widening holds in whatever units the policy fits (ln or linear rms_res).
      const auto ratio = [](double num, double den) { return den > 0.0 && num > 0.0 ? num / den : 0.0; };
      const auto within = [](double w, double sample) { return w > 0.0 && sample > 0.0 ? w / sample : 1.0; };
      cls.thresholds[mi].rms =
          fit_band(rms, policy, FeatureScale::kLog, ratio(day.log_rms_between_sd, day.log_rms_within_sd),
                   within(day.log_rms_within_sd, log_stats.stddev));
      cls.thresholds[mi].entropy = fit_band(entropy, policy, FeatureScale::kLinear,
                                            ratio(day.entropy_between_sd, day.entropy_within_sd),
                                            within(day.entropy_within_sd, entropy_stats.stddev));
      if (policy.cover_recordings && ve.groups >= 2) {
        cls.thresholds[mi].rms =
            cover_recordings(cls.thresholds[mi].rms, rms, value_recording, policy, FeatureScale::kLog);
        cls.thresholds[mi].entropy = cover_recordings(cls.thresholds[mi].entropy, entropy, value_recording,
                                                      policy, FeatureScale::kLinear);
      }
    } catch (const Error& e) {
      throw Error(what + ": " + e.what());
    }
    // Both features are >= 0 by construction: a negative lower bound only makes reports confusing.
    cls.thresholds[mi].rms.lo = std::max(0.0, cls.thresholds[mi].rms.lo);
    cls.thresholds[mi].entropy.lo = std::max(0.0, cls.thresholds[mi].entropy.lo);
    cls.rms_stats[mi] = feature_stats(rms);
    cls.entropy_stats[mi] = entropy_stats;
    // A zero residual (possible only for a window identical to the mean) is left out of the log stats.
    cls.log_rms_stats[mi] = log_stats;
  }
  // Band CUSUM statistics: per band the random-effects split of the leave-one-out ln band energies with
  // the recordings as groups; the between-day sd used is floored at day_sd_floor x within sd (one
  // recording: the floor alone), as the session-11 study standardised them (docs/method.md §8).
  if (!s.band_values.empty()) {
    std::array<std::uint32_t, kMaxBands> clean_n{};
    clean_bins_per_band(s.clean, s.band_values.size(), clean_n);
    cls.band_stats.assign(s.band_values.size(), BandEnergyStats{});
    for (std::size_t b = 0; b < s.band_values.size(); ++b) {
      BandEnergyStats& st = cls.band_stats[b];
      st.clean_bins = clean_n[b];
      const VarianceComponents v = s.band_values[b].result();
      cls.band_recordings = v.groups;
      st.mean = v.mean;
      st.within_sd = std::sqrt(v.within_var);
      st.between_est = std::sqrt(v.between_var);
      st.between_sd = std::max(st.between_est, policy.day_sd_floor * st.within_sd);
    }
  }
  return std::move(cls);
}

ClassBaseline build_class_baseline(const SegmentClass& segment,
                                   const std::vector<std::vector<float>>& windows,
                                   std::span<const std::uint64_t> groups, const ThresholdPolicy& policy,
                                   std::span<const std::uint32_t> recordings) {
  const std::string where = "class " + std::to_string(segment.id);
  if (windows.empty()) throw Error(where + ": no training windows");
  const std::size_t m = windows.size();
  const std::size_t n = windows[0].size();
  if (!RealFft::supported_length(n)) {
    throw Error(where + ": window length " + std::to_string(n) +
                " is not supported (even, >= 4, prime factors 2, 3, 5 only)");
  }
  for (std::size_t i = 0; i < m; ++i) {
    if (windows[i].size() != n) {
      throw Error(where + ": window " + std::to_string(i) + " has " + std::to_string(windows[i].size()) +
                  " samples, expected " + std::to_string(n));
    }
    for (std::size_t j = 0; j < n; ++j) {
      if (!std::isfinite(windows[i][j])) {
        throw Error(where + ": window " + std::to_string(i) + " sample " + std::to_string(j) +
                    " is not finite");
      }
    }
  }
  if (!groups.empty() && groups.size() != m) {
    throw Error(where + ": " + std::to_string(groups.size()) + " group ids for " + std::to_string(m) +
                " windows");
  }
  if (!recordings.empty() && recordings.size() != m) {
    throw Error(where + ": " + std::to_string(recordings.size()) + " recording ids for " + std::to_string(m) +
                " windows");
  }
  if (!(std::isfinite(policy.day_sd_floor) && policy.day_sd_floor >= 0.0)) {
    throw Error(where + ": thresholds.day_sd_floor must be finite and >= 0");
  }
  // Window indices per group (ordered map: deterministic processing order).
  std::map<std::uint64_t, std::vector<std::size_t>> members;
  for (std::size_t i = 0; i < m; ++i) members[groups.empty() ? i : groups[i]].push_back(i);
  if (members.size() < 3) {
    throw Error(where +
                ": leave-one-group-out training needs windows from at least 3 groups (regions), got " +
                std::to_string(members.size()));
  }
  ClassBaselineBuilder builder(segment, n, policy);
  for (const auto& w : windows) builder.add_to_mean(w);
  builder.finish_mean();
  std::vector<std::span<const float>> group_windows;
  std::vector<std::uint32_t> group_recordings;
  for (const auto& [group, idx] : members) {
    group_windows.clear();
    group_recordings.clear();
    for (const std::size_t i : idx) {
      group_windows.emplace_back(windows[i]);
      if (!recordings.empty()) group_recordings.push_back(recordings[i]);
    }
    builder.score_group(group_windows, group_recordings);
  }
  return builder.finish();
}

std::vector<std::string> training_warnings(const Baseline& baseline, std::string_view more_days_how) {
  std::vector<std::string> out;
  const ThresholdPolicy& p = baseline.policy;
  const double alpha = p.false_alarm_rate;
  const auto g = [](double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.3g", v);
    return std::string(buf);
  };
  const std::string rate = g(alpha);
  // Smallest n whose one-sided tolerance factor is within 20 % of the asymptotic z: beyond it the
  // estimate of the band itself stops dominating (kGaussian's promise, kTolerance's width).
  const auto n_needed = [&](double confidence) -> std::uint32_t {
    const double z = inverse_normal_cdf(1.0 - alpha);
    for (std::uint32_t n = 3; n < 100000; n = n < 64 ? n + 1 : n + n / 8) {
      try {
        if (tolerance_factor_one_sided(n, 1.0 - alpha, confidence) <= 1.2 * z) return n;
      } catch (const Error&) {
      }
    }
    return 100000;
  };
  const std::uint32_t need_param =
      p.kind == ThresholdPolicy::Kind::kQuantile
          ? 0
          : n_needed(p.kind == ThresholdPolicy::Kind::kTolerance ? p.confidence : 0.9);
  for (const ClassBaseline& c : baseline.classes) {
    const std::uint32_t n = c.rms_stats[static_cast<std::size_t>(Method::kPtda)].n;
    const std::string cls =
        "class " + std::to_string(c.segment.id) + ": " + std::to_string(n) + " training windows";
    if (p.kind == ThresholdPolicy::Kind::kQuantile) {
      const auto need = static_cast<std::uint32_t>(std::ceil(2.0 / alpha));
      if (n < need) {
        out.push_back(cls + " cannot resolve the alpha/2 = " + g(alpha / 2) +
                      " quantiles of false_alarm_rate " + rate + ": the band is about the sample range; " +
                      "needs >= " + std::to_string(need) + " windows");
      }
    } else if (n < need_param) {
      out.push_back(cls +
                    (p.kind == ThresholdPolicy::Kind::kGaussian
                         ? " give a Gaussian band whose real false-alarm rate is uncertain far "
                           "beyond the promised " +
                               rate
                         : " make the tolerance band more than 20 % wider than with ample data") +
                    "; needs >= " + std::to_string(need_param) + " windows (cycles) for rate " + rate);
    }
    const HoldoutStats& h = c.holdout[static_cast<std::size_t>(Method::kPtda)];
    if (h.windows > 0 && 3.0 / h.windows > 2.0 * alpha) {
      out.push_back("class " + std::to_string(c.segment.id) + ": the hold-out of " +
                    std::to_string(h.windows) + " windows can only show a false-alarm rate >= " +
                    g(3.0 / h.windows) + " (95 %); confirming " + rate + " per feature needs >= " +
                    std::to_string(static_cast<std::uint64_t>(std::ceil(1.5 / alpha))) + " held-out windows");
    }
  }
  // A class seen in one training recording only: its spread between days is assumed (the day_sd_floor
  // prior), not measured. 0 recordings = a baseline of format <= 3, which does not say.
  std::string single;
  std::size_t singles = 0;
  for (const ClassBaseline& c : baseline.classes) {
    std::uint32_t days = 0;
    for (const DaySpread& d : c.day_spread) days = std::max(days, d.recordings);
    if (days != 1) continue;
    single += (singles == 0 ? "" : ", ") + std::to_string(c.segment.id);
    ++singles;
  }
  if (singles > 0) {
    const std::string why =
        "the spread between days is not measured but assumed (day_sd_floor = " + g(p.day_sd_floor) +
        " of the within-day sd), so a healthy day that differs more can raise the alarm (docs/method.md §8: "
        "2 of 20 development machines with one training day, none with three); train on recordings of at "
        "least 3 different days (" +
        std::string(more_days_how) + ")";
    out.push_back(singles == baseline.classes.size() ? "trained on one recording: " + why
                                                     : (singles == 1 ? "class " : "classes ") + single +
                                                           " seen in one training recording only: " + why);
  }
  return out;
}

}  // namespace ptda::dsp
