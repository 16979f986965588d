// k-of-n debouncing over a fixed ring of the last n verdicts; the per-class CUSUM and its ARL.
#include "ptda/dsp/decision.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "ptda/common/error.hpp"

namespace ptda::dsp {

KOfNDebouncer::KOfNDebouncer(std::uint32_t k, std::uint32_t n) : k_(k), n_(n) {
  if (k < 1 || n < 1 || k > n || n > kMaxN) {
    throw Error("KOfNDebouncer: invalid k-of-n " + std::to_string(k) + " of " + std::to_string(n) +
                " (need 1 <= k <= n <= " + std::to_string(kMaxN) + ")");
  }
}

bool KOfNDebouncer::push(bool abnormal) noexcept {
  if (filled_ == n_) {
    // The ring is full: the slot at pos_ holds the oldest verdict, which drops out now.
    if (hist_[pos_]) --count_;
  } else {
    ++filled_;
  }
  hist_[pos_] = abnormal;
  if (abnormal) ++count_;
  pos_ = (pos_ + 1 == n_) ? 0 : pos_ + 1;
  return active();
}

void KOfNDebouncer::reset() noexcept {
  hist_.fill(false);
  pos_ = 0;
  filled_ = 0;
  count_ = 0;
}

StandardScores standardize(const Features& f, const FeatureStats& log_rms, const FeatureStats& entropy,
                           double scale) noexcept {
  const auto sd = [scale](const FeatureStats& s) {
    return scale * std::max(s.stddev, 1e-9 * std::max(1.0, std::abs(s.mean)));
  };
  StandardScores z;
  if (f.rms_res > 0.0) {
    z.rms = (std::log(f.rms_res) - log_rms.mean) / sd(log_rms);
  } else {
    z.rms = f.rms_res == 0.0 ? -1e3 : std::numeric_limits<double>::quiet_NaN();
  }
  z.entropy = (f.entropy_res - entropy.mean) / sd(entropy);
  return z;
}

void check_sequential(const SequentialConfig& cfg) {
  if (!(cfg.k > 0.0 && cfg.k <= 10.0)) {
    throw Error("decision.cusum_k: must be > 0 and <= 10 standard deviations, got " + std::to_string(cfg.k));
  }
  if (!(cfg.h_warn > 0.0 && cfg.h_warn <= 1000.0)) {
    throw Error("decision.cusum_warn: must be > 0 and <= 1000, got " + std::to_string(cfg.h_warn));
  }
  if (!(cfg.h_alarm > 0.0 && cfg.h_alarm <= 1000.0)) {
    throw Error("decision.cusum_alarm: must be > 0 and <= 1000, got " + std::to_string(cfg.h_alarm));
  }
  if (!(cfg.day_allowance >= 0.0 && cfg.day_allowance <= 10.0)) {
    throw Error("decision.cusum_day_allowance: must be >= 0 and <= 10 between-day standard deviations, got " +
                std::to_string(cfg.day_allowance));
  }
  check_step_cap("cusum_step_cap", cfg.step_cap);
  if (cfg.h_warn > cfg.h_alarm) {
    throw Error("decision.cusum_warn: " + std::to_string(cfg.h_warn) + " must not exceed cusum_alarm " +
                std::to_string(cfg.h_alarm));
  }
}

void Cusum::update(double z_rms, double z_entropy, double k, double cap, double extra_rms,
                   double extra_entropy, double step_cap) noexcept {
  const bool rms_ok = std::isfinite(z_rms);
  const bool ent_ok = std::isfinite(z_entropy);
  const auto step = [&](double s, double x, double kk) { return cusum_step(s, x - kk, step_cap, cap); };
  const double k_rms = k + extra_rms;
  const double k_ent = k + extra_entropy;
  s_rms_ = step(s_rms_, rms_ok ? z_rms : k_rms + 1.0, k_rms);
  s_ent_hi_ = step(s_ent_hi_, ent_ok ? z_entropy : k_ent + 1.0, k_ent);
  s_ent_lo_ = step(s_ent_lo_, ent_ok ? -z_entropy : k_ent + 1.0, k_ent);
}

void check_step_cap(const char* key, double cap) {
  if (!(cap > 0.0 && cap <= kNoStepCap)) {
    throw Error(std::string("decision.") + key + ": must be > 0 and <= 1000 (1000: no cap), got " +
                std::to_string(cap));
  }
}

double Cusum::statistic() const noexcept {
  return std::max(s_rms_, std::max(s_ent_hi_, s_ent_lo_));
}

SeqFeature Cusum::feature() const noexcept {
  const double s = statistic();
  if (s <= 0.0) return SeqFeature::kNone;
  if (s == s_rms_) return SeqFeature::kRmsHigh;
  return s == s_ent_hi_ ? SeqFeature::kEntropyHigh : SeqFeature::kEntropyLow;
}

double cusum_arl(double mean, double sd, double k, double h) {
  if (!(sd > 0.0 && std::isfinite(sd)) || !(h > 0.0) || !std::isfinite(mean) || !std::isfinite(k)) {
    throw Error("cusum_arl: needs finite mean and k, sd > 0 and h > 0 (got mean " + std::to_string(mean) +
                ", sd " + std::to_string(sd) + ", k " + std::to_string(k) + ", h " + std::to_string(h) + ")");
  }
  const double delta = (mean - k) / sd;
  const double b = h / sd + 1.166;
  if (std::abs(delta) < 1e-9) return b * b;
  const double e = std::exp(-2.0 * delta * b);
  if (!std::isfinite(e)) return std::numeric_limits<double>::infinity();
  return (e + 2.0 * delta * b - 1.0) / (2.0 * delta * delta);
}

double class_cusum_arl(double z_rms_mean, double z_rms_sd, double z_entropy_mean, double z_entropy_sd,
                       double k, double h, double extra_rms, double extra_entropy) {
  const double inv = 1.0 / cusum_arl(z_rms_mean, z_rms_sd, k + extra_rms, h) +
                     1.0 / cusum_arl(z_entropy_mean, z_entropy_sd, k + extra_entropy, h) +
                     1.0 / cusum_arl(-z_entropy_mean, z_entropy_sd, k + extra_entropy, h);
  return inv > 0.0 ? 1.0 / inv : std::numeric_limits<double>::infinity();
}

}  // namespace ptda::dsp
