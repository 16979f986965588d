// Real FFT over KissFFT's C API. The plans live in memory this object owns (KissFFT's dry-run
// `lenmem` protocol), and transforms are always out of place: in-place kiss_fft mallocs per call.
#include "ptda/dsp/real_fft.hpp"

#include <kiss_fftr.h>

#include <string>

#include "ptda/common/error.hpp"

namespace ptda::dsp {

static_assert(sizeof(std::complex<float>) == sizeof(kiss_fft_cpx),
              "std::complex<float> must be layout-compatible with kiss_fft_cpx");

struct RealFft::Impl {
  // new[] storage is aligned for any fundamental type, which is all KissFFT's structs need.
  std::unique_ptr<unsigned char[]> forward_mem;
  std::unique_ptr<unsigned char[]> inverse_mem;
  kiss_fftr_cfg forward_cfg = nullptr;
  kiss_fftr_cfg inverse_cfg = nullptr;
  float inv_n = 0.0F;
};

namespace {

kiss_fftr_cfg make_plan(std::size_t n, bool inverse, std::unique_ptr<unsigned char[]>& mem) {
  std::size_t len_bytes = 0;
  // Dry run: with mem == nullptr KissFFT only reports the bytes it needs.
  kiss_fftr_alloc(static_cast<int>(n), inverse ? 1 : 0, nullptr, &len_bytes);
  if (len_bytes == 0) {
    throw Error("RealFft: KissFFT reported no plan size for length " + std::to_string(n));
  }
  mem = std::make_unique<unsigned char[]>(len_bytes);
  std::size_t have = len_bytes;
  kiss_fftr_cfg cfg = kiss_fftr_alloc(static_cast<int>(n), inverse ? 1 : 0, mem.get(), &have);
  if (cfg == nullptr) {
    throw Error("RealFft: KissFFT could not build a plan of length " + std::to_string(n) + " in " +
                std::to_string(len_bytes) + " bytes");
  }
  return cfg;
}

}  // namespace

bool RealFft::supported_length(std::size_t n) noexcept {
  if (n < 4 || n % 2 != 0 || n > static_cast<std::size_t>(1) << 30) return false;
  std::size_t m = n;
  for (std::size_t p : {2U, 3U, 5U}) {
    while (m % p == 0) m /= p;
  }
  return m == 1;
}

RealFft::RealFft(std::size_t n) : n_(n) {
  if (!supported_length(n)) {
    throw Error("RealFft: unsupported length " + std::to_string(n) +
                " (needs an even length >= 4 whose only prime factors are 2, 3 and 5; other radices make "
                "KissFFT allocate on every call)");
  }
  impl_ = std::make_unique<Impl>();
  impl_->forward_cfg = make_plan(n, false, impl_->forward_mem);
  impl_->inverse_cfg = make_plan(n, true, impl_->inverse_mem);
  impl_->inv_n = 1.0F / static_cast<float>(n);
}

RealFft::~RealFft() = default;
RealFft::RealFft(RealFft&&) noexcept = default;
RealFft& RealFft::operator=(RealFft&&) noexcept = default;

void RealFft::forward(std::span<const float> x, std::span<std::complex<float>> spectrum) noexcept {
  // Contract violations leave the output untouched rather than reading/writing out of bounds.
  if (!impl_ || x.size() != n_ || spectrum.size() != bins()) return;
  kiss_fftr(impl_->forward_cfg, x.data(), reinterpret_cast<kiss_fft_cpx*>(spectrum.data()));
}

void RealFft::inverse(std::span<const std::complex<float>> spectrum, std::span<float> x) noexcept {
  if (!impl_ || x.size() != n_ || spectrum.size() != bins()) return;
  // kiss_fftri only reads its input (it works in the plan's own scratch buffer).
  kiss_fftri(impl_->inverse_cfg, reinterpret_cast<const kiss_fft_cpx*>(spectrum.data()), x.data());
  const float s = impl_->inv_n;
  for (float& v : x) v *= s;
}

}  // namespace ptda::dsp
