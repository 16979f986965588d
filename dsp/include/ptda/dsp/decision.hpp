// Window decision and k-of-n alarm debouncing (fixed capacity, allocation-free).
#pragma once

#include <array>
#include <cstdint>

#include "ptda/dsp/baseline.hpp"
#include "ptda/dsp/types.hpp"

namespace ptda::dsp {

struct Verdict {
  bool rms_out = false;      ///< rms_res outside its band
  bool entropy_out = false;  ///< entropy_res outside its band
  [[nodiscard]] bool abnormal() const noexcept { return rms_out || entropy_out; }
};

/// A window is abnormal when either feature leaves its band (paper section 3.4).
[[nodiscard]] inline Verdict judge(const Features& f, const FeatureThresholds& t) noexcept {
  return Verdict{!t.rms.contains(f.rms_res), !t.entropy.contains(f.entropy_res)};
}

/// Alarm when at least k of the last n judged windows were abnormal. n <= kMaxN.
class KOfNDebouncer {
 public:
  static constexpr std::uint32_t kMaxN = 64;
  /// Throws ptda::Error unless 1 <= k <= n <= kMaxN. Thread: any (setup).
  KOfNDebouncer(std::uint32_t k, std::uint32_t n);
  /// Records one window; returns whether the k-of-n condition holds now (fewer than n windows seen:
  /// counts over those). Thread: the owner's. Never allocates or blocks.
  bool push(bool abnormal) noexcept;
  [[nodiscard]] bool active() const noexcept { return count_ >= k_; }
  [[nodiscard]] std::uint32_t abnormal_in_window() const noexcept { return count_; }
  /// Forgets all history (e.g. after a class change or a gap). Thread: the owner's. Never allocates.
  void reset() noexcept;

 private:
  std::uint32_t k_, n_;
  std::array<bool, kMaxN> hist_{};
  std::uint32_t pos_ = 0, filled_ = 0, count_ = 0;
};

}  // namespace ptda::dsp
