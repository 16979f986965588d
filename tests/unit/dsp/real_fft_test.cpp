// RealFft against closed forms: a naive double-precision DFT, cosines at bin k, round trips.
#include "ptda/dsp/real_fft.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "alloc_counter.hpp"
#include "ptda/common/error.hpp"

// KissFFT allocates with C malloc, which AllocScope (operator new) cannot see. This binary therefore
// also interposes malloc itself (the executable's definition wins over libc's for every shared
// library, libkissfft included) and forwards to glibc's __libc_malloc. Not under ASan/TSan, whose
// own malloc must stay in charge.
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define PTDA_COUNT_MALLOC 0
#else
#define PTDA_COUNT_MALLOC 1
#include <kiss_fftr.h>

#include <atomic>
#include <cstdint>

extern "C" void* __libc_malloc(std::size_t size);  // NOLINT(bugprone-reserved-identifier): glibc's own
namespace {
std::atomic<std::uint64_t> g_malloc_calls{0};
}
extern "C" void* malloc(std::size_t size) noexcept {
  g_malloc_calls.fetch_add(1, std::memory_order_relaxed);
  return __libc_malloc(size);
}
#endif

namespace ptda::dsp {
namespace {

std::vector<float> uniform_noise(std::size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0F, 1.0F);
  std::vector<float> x(n);
  for (float& v : x) v = u(rng);
  return x;
}

TEST(RealFft, SupportedLengths) {
  for (std::size_t n : {4U, 6U, 10U, 12U, 30U, 3200U, 10240U, 12800U, 25600U, 4096U, 2U * 243U * 125U}) {
    EXPECT_TRUE(RealFft::supported_length(n)) << n;
  }
  // Odd, too short, or with a prime factor KissFFT handles with its per-call allocating generic butterfly.
  for (std::size_t n : {0U, 1U, 2U, 3U, 5U, 15U, 14U, 22U, 26U, 3202U, 4096U * 7U, 12801U}) {
    EXPECT_FALSE(RealFft::supported_length(n)) << n;
  }
}

TEST(RealFft, UnsupportedLengthThrowsNamingTheLength) {
  for (std::size_t n : {0U, 7U, 14U, 3202U}) {
    try {
      RealFft fft(n);
      FAIL() << "no error for length " << n;
    } catch (const Error& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find("length " + std::to_string(n)), std::string::npos) << msg;
      EXPECT_NE(msg.find("prime factors are 2, 3 and 5"), std::string::npos) << msg;
    }
  }
}

// The full sign/scale convention of eq. 6 on a small mixed-radix length, against a naive double DFT.
TEST(RealFft, MatchesNaiveDftOnLength12) {
  const std::size_t n = 12;
  const std::vector<float> x = uniform_noise(n, 7);
  RealFft fft(n);
  ASSERT_EQ(fft.bins(), 7U);
  std::vector<std::complex<float>> X(fft.bins());
  fft.forward(x, X);
  for (std::size_t k = 0; k < fft.bins(); ++k) {
    std::complex<double> ref = 0.0;
    for (std::size_t t = 0; t < n; ++t) {
      const double a = -2.0 * std::numbers::pi * static_cast<double>(k * t) / static_cast<double>(n);
      ref += static_cast<double>(x[t]) * std::complex<double>(std::cos(a), std::sin(a));
    }
    EXPECT_NEAR(X[k].real(), ref.real(), 1e-5) << "bin " << k;
    EXPECT_NEAR(X[k].imag(), ref.imag(), 1e-5) << "bin " << k;
  }
}

class RealFftLengths : public ::testing::TestWithParam<std::size_t> {};

// cos(2 pi k n / N) has X[k] = N/2 and nothing elsewhere; sin has X[k] = -j N/2 (the e^{-j} sign).
TEST_P(RealFftLengths, CosineAndSineAtBinK) {
  const std::size_t n = GetParam();
  const std::size_t k0 = n / 8 + 1;  // strictly between DC and Nyquist for every length tested
  RealFft fft(n);
  std::vector<float> c(n), s(n);
  for (std::size_t t = 0; t < n; ++t) {
    const double a = 2.0 * std::numbers::pi * static_cast<double>((k0 * t) % n) / static_cast<double>(n);
    c[t] = static_cast<float>(std::cos(a));
    s[t] = static_cast<float>(std::sin(a));
  }
  std::vector<std::complex<float>> C(fft.bins()), S(fft.bins());
  fft.forward(c, C);
  fft.forward(s, S);
  const double half = static_cast<double>(n) / 2.0;
  // Float round-off: measured < 9e-8 relative (bin k0) and < 7e-8 (leakage) for every length here;
  // 1e-6 relative leaves ~10x headroom and is far below any real sign, scale or bin error.
  const double tol = 1e-6 * half;
  EXPECT_NEAR(C[k0].real(), half, tol);
  EXPECT_NEAR(C[k0].imag(), 0.0, tol);
  EXPECT_NEAR(S[k0].real(), 0.0, tol);
  EXPECT_NEAR(S[k0].imag(), -half, tol);
  double leak = 0.0;
  for (std::size_t k = 0; k < fft.bins(); ++k) {
    if (k != k0) leak = std::max(leak, static_cast<double>(std::abs(C[k])));
  }
  EXPECT_LT(leak, tol);
}

TEST_P(RealFftLengths, RoundTripIsIdentity) {
  const std::size_t n = GetParam();
  const std::vector<float> x = uniform_noise(n, 11);
  RealFft fft(n);
  std::vector<std::complex<float>> X(fft.bins());
  std::vector<float> y(n);
  fft.forward(x, X);
  const std::vector<std::complex<float>> X_copy = X;
  fft.inverse(X, y);
  EXPECT_EQ(X, X_copy) << "inverse must not modify its input";
  double max_err = 0.0;
  for (std::size_t t = 0; t < n; ++t) max_err = std::max(max_err, std::abs(static_cast<double>(y[t] - x[t])));
  // Samples in [-1, 1]: measured max error < 5.4e-7 for every length here (a few float ulp per stage).
  EXPECT_LT(max_err, 2e-6);
}

TEST_P(RealFftLengths, ForwardAndInverseDoNotAllocate) {
  const std::size_t n = GetParam();
  const std::vector<float> x = uniform_noise(n, 3);
  RealFft fft(n);
  std::vector<std::complex<float>> X(fft.bins());
  std::vector<float> y(n);
  test::AllocScope scope;
  for (int i = 0; i < 3; ++i) {
    fft.forward(x, X);
    fft.inverse(X, y);
  }
  EXPECT_EQ(scope.count(), 0U);
}

#if PTDA_COUNT_MALLOC
// C-level allocations (what KissFFT would do): none in forward/inverse for any supported length.
TEST_P(RealFftLengths, ForwardAndInverseDoNotCallMalloc) {
  const std::size_t n = GetParam();
  const std::vector<float> x = uniform_noise(n, 3);
  RealFft fft(n);
  std::vector<std::complex<float>> X(fft.bins());
  std::vector<float> y(n);
  const std::uint64_t before = g_malloc_calls.load();
  for (int i = 0; i < 3; ++i) {
    fft.forward(x, X);
    fft.inverse(X, y);
  }
  EXPECT_EQ(g_malloc_calls.load() - before, 0U);
}
#endif

INSTANTIATE_TEST_SUITE_P(Lengths, RealFftLengths,
                         ::testing::Values(std::size_t{4}, std::size_t{6}, std::size_t{30}, std::size_t{3200},
                                           std::size_t{10240}, std::size_t{12800}, std::size_t{25600}));

#if PTDA_COUNT_MALLOC
// Why other radices are refused, and proof that the malloc counter sees KissFFT: a length-14 real FFT
// (complex length 7, KissFFT's generic butterfly) mallocs scratch on every call.
TEST(RealFft, KissFftGenericRadixMallocsPerCallWhichIsWhyItIsRefused) {
  const int n = 14;
  std::size_t len = 0;
  kiss_fftr_alloc(n, 0, nullptr, &len);
  std::vector<std::max_align_t> mem(len / sizeof(std::max_align_t) + 1);
  kiss_fftr_cfg cfg = kiss_fftr_alloc(n, 0, mem.data(), &len);
  ASSERT_NE(cfg, nullptr);
  std::vector<float> x(n, 1.0F);
  std::vector<kiss_fft_cpx> X(n / 2 + 1);
  const std::uint64_t before = g_malloc_calls.load();
  kiss_fftr(cfg, x.data(), X.data());
  EXPECT_GE(g_malloc_calls.load() - before, 1U);
  EXPECT_NEAR(X[0].r, 14.0F, 1e-5F);  // the transform itself still works
}
#endif

TEST(RealFft, WrongSizesLeaveOutputUntouched) {
  RealFft fft(16);
  std::vector<float> x(15, 1.0F);
  std::vector<std::complex<float>> X(9, {42.0F, 0.0F});
  fft.forward(x, X);
  for (const auto& v : X) EXPECT_EQ(v, std::complex<float>(42.0F, 0.0F));
  std::vector<std::complex<float>> X_short(8);
  std::vector<float> y(16, 5.0F);
  fft.inverse(X_short, y);
  for (const float v : y) EXPECT_EQ(v, 5.0F);
}

TEST(RealFft, MovedObjectKeepsWorking) {
  RealFft a(64);
  RealFft b(std::move(a));
  EXPECT_EQ(b.size(), 64U);
  std::vector<float> x(64, 0.0F);
  x[0] = 1.0F;  // impulse: flat spectrum of ones
  std::vector<std::complex<float>> X(b.bins());
  b.forward(x, X);
  for (const auto& v : X) EXPECT_EQ(v, std::complex<float>(1.0F, 0.0F));
}

}  // namespace
}  // namespace ptda::dsp
