#include "ptda/cli/progress.hpp"

#include <unistd.h>

#include <algorithm>
#include <cstdio>

namespace ptda::cli {

Progress::Progress(std::string label, std::uint64_t total, bool enabled)
    : label_(std::move(label)), total_(total), active_(enabled && total > 0 && isatty(STDERR_FILENO) == 1) {}

Progress::~Progress() {
  done();
}

void Progress::update(std::uint64_t done_units) {
  if (!active_) return;
  const int permille = static_cast<int>(std::min<std::uint64_t>(1000, done_units * 1000 / total_));
  if (permille / 10 == last_permille_ / 10 && last_permille_ >= 0) return;
  last_permille_ = permille;
  constexpr int kWidth = 30;
  const int filled = permille * kWidth / 1000;
  char bar[kWidth + 1];
  for (int i = 0; i < kWidth; ++i) bar[i] = i < filled ? '#' : '.';
  bar[kWidth] = '\0';
  std::fprintf(stderr, "\r%s [%s] %3d%%", label_.c_str(), bar, permille / 10);
  std::fflush(stderr);
}

void Progress::done() {
  if (!active_) return;
  std::fprintf(stderr, "\r\033[K");
  std::fflush(stderr);
  active_ = false;
}

}  // namespace ptda::cli
