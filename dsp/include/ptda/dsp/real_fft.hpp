// Real FFT over KissFFT (C API) with memory owned by this object: nothing is allocated after
// construction, for any even length whose prime factors are 2, 3 and 5 (KissFFT's fast radices;
// other radices make KissFFT allocate per call, so they are refused).
#pragma once

#include <complex>
#include <cstddef>
#include <memory>
#include <span>

namespace ptda::dsp {

class RealFft {
 public:
  /// True when n is even, >= 4, <= 2^30 (KissFFT takes an int) and has no prime factor other
  /// than 2, 3, 5.
  /// Thread: any. Never allocates.
  [[nodiscard]] static bool supported_length(std::size_t n) noexcept;

  /// Sets up forward and inverse plans in buffers owned by this object.
  /// Thread: any (setup). Allocates. Throws ptda::Error naming the length when unsupported.
  explicit RealFft(std::size_t n);
  ~RealFft();
  RealFft(const RealFft&) = delete;
  RealFft& operator=(const RealFft&) = delete;
  RealFft(RealFft&&) noexcept;
  RealFft& operator=(RealFft&&) noexcept;

  [[nodiscard]] std::size_t size() const noexcept { return n_; }
  [[nodiscard]] std::size_t bins() const noexcept { return n_ / 2 + 1; }

  /// spectrum[k] = X[k] = sum_n x[n] e^{-j 2 pi k n / N}, k = 0..N/2 (eq. 6).
  /// x.size() == size(), spectrum.size() == bins(); wrong sizes (or a moved-from object) leave
  /// spectrum untouched. Thread: the owner's. Never allocates or blocks.
  void forward(std::span<const float> x, std::span<std::complex<float>> spectrum) noexcept;
  /// x[n] = (1/N) sum_k X[k] e^{+j 2 pi k n / N} with X = spectrum (eq. 9, scaled so
  /// inverse(forward(x)) == x). spectrum is not modified; wrong sizes leave x untouched.
  /// Thread: the owner's. Never allocates or blocks.
  void inverse(std::span<const std::complex<float>> spectrum, std::span<float> x) noexcept;

 private:
  struct Impl;
  std::size_t n_ = 0;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ptda::dsp
