// Small deterministic PRNG for the simulator: xoshiro256** seeded by splitmix64, Box-Muller normals
// (their cos/sin of 2 pi u by turn(), not libm).
// Our own so that a seed gives the same bytes on every platform and standard library
// (std::normal_distribution's output is implementation-defined).
#pragma once

#include <cmath>
#include <cstdint>
#include <numbers>

namespace ptda::sim {

/// One splitmix64 step (state advanced in place). Any thread; no allocation.
[[nodiscard]] constexpr std::uint64_t splitmix64(std::uint64_t& state) noexcept {
  state += 0x9E3779B97F4A7C15ULL;
  std::uint64_t z = state;
  z = (z ^ (z >> 30U)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27U)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31U);
}

/// sin x and cos x as their Taylor series to x^15 / x^16 (Horner in x^2), for |x| <= 0.8: the first
/// omitted terms are below 7e-17. Shared by Rng::turn() and the synthesis' phase rotor
/// (sim/src/vibration.cpp). Any thread; no allocation.
inline void sin_cos_series(double x, double& s, double& c) noexcept {
  const double x2 = x * x;
  s = x * (1.0 + x2 * (-1.0 / 6.0 +
                       x2 * (1.0 / 120.0 +
                             x2 * (-1.0 / 5040.0 +
                                   x2 * (1.0 / 362880.0 +
                                         x2 * (-1.0 / 39916800.0 + x2 * (1.0 / 6227020800.0 +
                                                                         x2 * (-1.0 / 1307674368000.0))))))));
  c = 1.0 +
      x2 * (-0.5 + x2 * (1.0 / 24.0 +
                         x2 * (-1.0 / 720.0 +
                               x2 * (1.0 / 40320.0 + x2 * (-1.0 / 3628800.0 +
                                                           x2 * (1.0 / 479001600.0 +
                                                                 x2 * (-1.0 / 87178291200.0 +
                                                                       x2 * (1.0 / 20922789888000.0))))))));
}

/// xoshiro256** with a Gaussian helper. Not thread-safe (one instance per thread); no allocation.
class Rng {
 public:
  /// `stream` separates independent draws (jitter, noise, CAN) made from one scenario seed, so adding
  /// draws to one of them does not change the others.
  explicit constexpr Rng(std::uint64_t seed, std::uint64_t stream = 0) noexcept {
    std::uint64_t sm = seed ^ (stream * 0xD1B54A32D192ED03ULL);
    for (auto& w : s_) w = splitmix64(sm);
  }

  constexpr std::uint64_t next_u64() noexcept {
    const std::uint64_t result = rotl(s_[1] * 5U, 7) * 9U;
    const std::uint64_t t = s_[1] << 17U;
    s_[2] ^= s_[0];
    s_[3] ^= s_[1];
    s_[1] ^= s_[2];
    s_[0] ^= s_[3];
    s_[2] ^= t;
    s_[3] = rotl(s_[3], 45);
    return result;
  }

  /// Uniform in [0, 1) with 53 random bits.
  constexpr double uniform() noexcept { return static_cast<double>(next_u64() >> 11U) * 0x1.0p-53; }

  /// Standard normal (Box-Muller; the second value of each pair is kept for the next call).
  double normal() noexcept {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    const double u1 = 1.0 - uniform();  // (0, 1]: log is finite
    const double u2 = uniform();
    const double r = std::sqrt(-2.0 * std::log(u1));
    double c = 1.0;
    double s = 0.0;
    turn(u2, c, s);
    spare_ = r * s;
    has_spare_ = true;
    return r * c;
  }

  /// cos and sin of 2 pi u for u in [0, 1), within a few units in the last place of libm's
  /// cos(2 pi u) and sin(2 pi u) (which this replaced: glibc's sincos, with its rounding-mode save and
  /// restore, was about a sixth of `ptda gap`'s time in the simulator's noise). The quarter turn is
  /// found exactly (4u and its fraction are exact), the rest folded into [0, pi/4] and summed as Taylor
  /// series to x^15 / x^16 (first omitted terms below 5e-17). Any thread; no allocation.
  static void turn(double u, double& c, double& s) noexcept {
    const double t = 4.0 * u;
    const double q_floor = std::floor(t);
    double f = t - q_floor;  // in [0, 1): the fraction of the quarter turn
    const bool upper = f > 0.5;
    if (upper) f = 1.0 - f;  // exact (Sterbenz): the complementary angle, sin and cos swap
    double sx = 0.0;
    double cx = 1.0;
    sin_cos_series(f * (std::numbers::pi / 2.0), sx, cx);
    // Angle within the quarter: a = upper ? pi/2 - x : x.
    const double ca = upper ? sx : cx;
    const double sa = upper ? cx : sx;
    switch (static_cast<int>(q_floor) & 3) {  // turn (ca, sa) by q quarter turns
      case 0:
        c = ca;
        s = sa;
        break;
      case 1:
        c = -sa;
        s = ca;
        break;
      case 2:
        c = -ca;
        s = -sa;
        break;
      default:
        c = sa;
        s = -ca;
        break;
    }
  }

 private:
  static constexpr std::uint64_t rotl(std::uint64_t x, int k) noexcept {
    return (x << static_cast<unsigned>(k)) | (x >> static_cast<unsigned>(64 - k));
  }
  std::uint64_t s_[4]{};
  double spare_ = 0.0;
  bool has_spare_ = false;
};

}  // namespace ptda::sim
