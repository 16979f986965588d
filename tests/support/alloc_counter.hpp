// Counts heap allocations made through global operator new/new[] (and malloc via the same hook is not
// possible on glibc 2.36: __malloc_hook is gone, so C++ code paths are what this measures).
#pragma once

#include <cstdint>

namespace ptda::test {

/// Allocations through operator new since program start, on any thread.
[[nodiscard]] std::uint64_t alloc_count() noexcept;

/// Counts allocations in a scope: `AllocScope s; work(); EXPECT_EQ(s.count(), 0u);`
class AllocScope {
 public:
  AllocScope() noexcept : start_(alloc_count()) {}
  [[nodiscard]] std::uint64_t count() const noexcept { return alloc_count() - start_; }

 private:
  std::uint64_t start_;
};

}  // namespace ptda::test
