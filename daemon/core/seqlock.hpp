// Single-writer seqlock for publishing a small trivially copyable struct from a real-time thread to
// readers that may retry (the supervisor). The writer never waits; a reader retries while a write is
// in progress.
//
// The payload lives in atomic 64-bit words (not plain memory), so concurrent reads and writes are not
// data races in the C++ model and ThreadSanitizer has nothing to report. No fences (GCC refuses them
// under -fsanitize=thread): each word is stored with release and loaded with acquire (Boehm, "Can
// seqlocks get along with programming language memory models?", 2012):
//   writer: seq = s+1 (odd, relaxed); words (release: seq = s+1 is visible before any new word);
//           seq = s+2 (release)
//   reader: s1 = seq (acquire); words (acquire: the re-read of seq cannot move before them);
//           s2 = seq (relaxed); valid when s1 == s2 and even.
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <type_traits>

#include "ptda/common/cache_line.hpp"

namespace ptda::daemon {

template <typename T>
class Seqlock {
  static_assert(std::is_trivially_copyable_v<T>, "Seqlock copies T word by word");
  static_assert(std::atomic<std::uint64_t>::is_always_lock_free);

 public:
  static constexpr std::size_t kWords = (sizeof(T) + 7) / 8;

  Seqlock() noexcept { store(T{}); }

  /// Publishes value. Thread: the one writer. Never blocks or allocates.
  void store(const T& value) noexcept {
    std::array<std::uint64_t, kWords> buf{};
    std::memcpy(buf.data(), &value, sizeof(T));
    const std::uint64_t s = seq_.load(std::memory_order_relaxed);
    seq_.store(s + 1, std::memory_order_relaxed);
    for (std::size_t i = 0; i < kWords; ++i) words_[i].store(buf[i], std::memory_order_release);
    seq_.store(s + 2, std::memory_order_release);
  }

  /// Latest complete value. Thread: any. Never allocates; retries (spins) while a write is in
  /// progress, which lasts a few hundred ns.
  [[nodiscard]] T load() const noexcept {
    std::array<std::uint64_t, kWords> buf{};
    for (;;) {
      const std::uint64_t s1 = seq_.load(std::memory_order_acquire);
      if ((s1 & 1U) == 0) {
        for (std::size_t i = 0; i < kWords; ++i) buf[i] = words_[i].load(std::memory_order_acquire);
        if (seq_.load(std::memory_order_relaxed) == s1) break;
      }
    }
    T out;
    std::memcpy(static_cast<void*>(&out), buf.data(), sizeof(T));
    return out;
  }

  /// Number of completed stores. Thread: any.
  [[nodiscard]] std::uint64_t version() const noexcept { return seq_.load(std::memory_order_acquire) / 2; }

 private:
  alignas(kCacheLineBytes) std::atomic<std::uint64_t> seq_{0};
  std::array<std::atomic<std::uint64_t>, kWords> words_{};
};

}  // namespace ptda::daemon
