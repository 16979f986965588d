// k-of-n debouncing over a fixed ring of the last n verdicts.
#include "ptda/dsp/decision.hpp"

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

}  // namespace ptda::dsp
