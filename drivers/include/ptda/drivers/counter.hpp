// PX4-style event counter: written by one thread (the device's real-time thread), read by any (the
// supervisor that logs and publishes STATUS=). Relaxed atomics, so reading is race-free and costs
// nothing on the writer's side (no read-modify-write: there is only one writer).
#pragma once

#include <atomic>
#include <cstdint>

namespace ptda::drivers {

class Counter {
 public:
  /// Adds n. Thread: the single owning (writer) thread. Never blocks or allocates.
  void add(std::uint64_t n = 1) noexcept {
    v_.store(v_.load(std::memory_order_relaxed) + n, std::memory_order_relaxed);
  }
  /// Overwrites the value (for gauges such as a kernel's cumulative drop count). Thread: the writer.
  void set(std::uint64_t v) noexcept { v_.store(v, std::memory_order_relaxed); }
  /// Thread: any. Never blocks or allocates.
  [[nodiscard]] std::uint64_t get() const noexcept { return v_.load(std::memory_order_relaxed); }

 private:
  std::atomic<std::uint64_t> v_{0};
};

}  // namespace ptda::drivers
