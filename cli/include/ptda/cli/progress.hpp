// A progress bar on stderr, drawn only when stderr is a terminal (never in pipes, logs or tests).
// Thread: the one driving the long run. Allocates nothing after construction.
#pragma once

#include <cstdint>
#include <string>

namespace ptda::cli {

class Progress {
 public:
  /// label: what is running ("monitor run1"); total: units of work (e.g. samples). enabled = false
  /// forces the bar off; otherwise it is on when isatty(STDERR_FILENO).
  Progress(std::string label, std::uint64_t total, bool enabled = true);
  ~Progress();
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;

  /// Work done so far; redraws at most every 1 % (cheap to call per block).
  void update(std::uint64_t done);
  /// Clears the bar line (also done by the destructor).
  void done();
  [[nodiscard]] bool active() const noexcept { return active_; }

 private:
  std::string label_;
  std::uint64_t total_;
  bool active_;
  int last_permille_ = -1;
};

}  // namespace ptda::cli
