#include "ptda/sim/noise_tilt.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <utility>

namespace ptda::sim {

double noise_tilt_pivot_hz(double fs_hz) noexcept {
  return std::sqrt(20.0 * 0.45 * std::max(fs_hz, 1.0));
}

namespace {
std::size_t block_for(double fs_hz) {
  std::size_t n = 1024;
  while (static_cast<double>(n) < fs_hz / 4.0 && n < (std::size_t{1} << 20)) n *= 2;
  return n;
}
}  // namespace

TiltedNoise::TiltedNoise(double tilt_db_per_decade, double fs_hz)
    : TiltedNoise(tilt_db_per_decade, fs_hz, {}, {}) {}

TiltedNoise::TiltedNoise(double tilt_db_per_decade, double fs_hz, std::vector<double> shape_hz,
                         std::vector<double> shape_db)
    : tilt_(tilt_db_per_decade),
      fs_hz_(fs_hz),
      shape_hz_(std::move(shape_hz)),
      shape_db_(std::move(shape_db)),
      n_(block_for(fs_hz)),
      fft_(n_) {
  if (shape_db_.size() != shape_hz_.size()) {  // the reader refuses this; a direct caller gets no shape
    shape_hz_.clear();
    shape_db_.clear();
  }
  const std::size_t bins = n_ / 2 + 1;
  gain_.resize(bins);
  for (std::size_t k = 0; k < bins; ++k) gain_[k] = static_cast<float>(gain_at(k * fs_hz / n_));
  window_.resize(n_);
  for (std::size_t t = 0; t < n_; ++t)
    window_[t] = static_cast<float>(std::sin(std::numbers::pi * (static_cast<double>(t) + 0.5) / n_));
  spec_.resize(bins);
  block_.resize(n_);
  tail_.assign(n_ / 2, 0.0F);
  out_.assign(n_ / 2, 0.0F);
  pos_ = n_ / 2;  // empty: the first next() refills
}

double TiltedNoise::shape_db(double f_hz) const noexcept {
  if (shape_hz_.empty()) return 0.0;
  if (f_hz <= shape_hz_.front()) return shape_db_.front();
  if (f_hz >= shape_hz_.back()) return shape_db_.back();
  const std::size_t i = static_cast<std::size_t>(std::upper_bound(shape_hz_.begin(), shape_hz_.end(), f_hz) -
                                                 shape_hz_.begin());  // 1..size-1
  const double u = std::log(f_hz / shape_hz_[i - 1]) / std::log(shape_hz_[i] / shape_hz_[i - 1]);
  return shape_db_[i - 1] + u * (shape_db_[i] - shape_db_[i - 1]);
}

double TiltedNoise::gain_at(double f_hz) const noexcept {
  const double f = std::max(f_hz, 10.0);
  const double pivot = noise_tilt_pivot_hz(fs_hz_);
  return std::pow(f / pivot, tilt_ / 20.0) * std::pow(10.0, (shape_db(f) - shape_db(pivot)) / 20.0);
}

void TiltedNoise::refill(Rng& rng) noexcept {
  // One-sided spectrum of unit-variance white noise (E|X_k|^2 = N), shaped per bin.
  const double n = static_cast<double>(n_);
  const std::size_t bins = n_ / 2 + 1;
  const double s_edge = std::sqrt(n), s_mid = std::sqrt(n / 2.0);
  for (std::size_t k = 0; k < bins; ++k) {
    const bool edge = k == 0 || k + 1 == bins;
    const double re = rng.normal() * (edge ? s_edge : s_mid);
    const double im = edge ? 0.0 : rng.normal() * s_mid;
    spec_[k] = std::complex<float>(static_cast<float>(re * gain_[k]), static_cast<float>(im * gain_[k]));
  }
  fft_.inverse(spec_, block_);
  const std::size_t h = n_ / 2;
  for (std::size_t t = 0; t < h; ++t) {
    out_[t] = tail_[t] + window_[t] * block_[t];
    tail_[t] = window_[t + h] * block_[t + h];
  }
  pos_ = 0;
}

double TiltedNoise::next(Rng& rng) noexcept {
  if (!primed_) {  // the first block only fills the tail, so the output starts at full variance
    refill(rng);
    primed_ = true;
  }
  if (pos_ >= n_ / 2) refill(rng);
  return out_[pos_++];
}

}  // namespace ptda::sim
