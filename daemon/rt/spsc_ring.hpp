// Bounded single-producer single-consumer ring with its capacity in the type.
//
//   head_ (written by the producer only)        tail_ (written by the consumer only)
//   ─────────────────────────────────────        ─────────────────────────────────────
//   Both are 64-bit indices that only ever grow (they would wrap after 2^64 items: centuries at any
//   sample rate, and the arithmetic below is modulo 2^64 anyway). Slot of index i is slots_[i & (N-1)].
//
//      tail_                 head_
//        │   readable items    │       free slots
//   ─────┴─────────────────────┴───────────────────────
//   size = head_ - tail_ (0 = empty, N = full; no spare slot is wasted)
//
// Memory ordering (acquire/release only, no fences: ThreadSanitizer does not model fences):
// - the producer copies items into free slots, then publishes them with head_.store(release);
//   the consumer's head_.load(acquire) makes those copies visible before it reads the slots.
// - the consumer copies items out, then frees the slots with tail_.store(release); the producer's
//   tail_.load(acquire) orders its later overwrites after the consumer's reads.
// Each side keeps a plain cached copy of the other side's index and reloads the shared atomic only
// when the cache says "full" (producer) or "empty" (consumer), which keeps the cache lines quiet.
//
// Layout: head_ with the producer's cache, tail_ with the consumer's cache, and the slots each start
// on their own kCacheLineBytes-aligned line, so the two threads never write the same line except
// through the slots themselves (the unit test pins sizeof).
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <type_traits>
#include <utility>

#include "ptda/common/cache_line.hpp"

namespace ptda::daemon {

template <typename T, std::size_t N>
class SpscRing {
  static_assert(N >= 2 && (N & (N - 1)) == 0, "SpscRing capacity must be a power of two >= 2");
  static_assert(std::is_trivially_copyable_v<T>, "SpscRing copies items with memcpy");
  static_assert(std::atomic<std::uint64_t>::is_always_lock_free, "64-bit atomics must be lock-free");

 public:
  using value_type = T;
  static constexpr std::size_t kCapacity = N;

  /// Empty ring. Thread: any, before the ring is shared. Never allocates (the storage is inline;
  /// rings of any size belong in static storage or a configure-time allocation, not on a stack).
  SpscRing() noexcept = default;

  /// Empty ring whose indices start at `start_index` instead of 0. A test hook to exercise index
  /// wrap-around (2^32, 2^64) without pushing billions of items. Thread: any, before sharing.
  explicit SpscRing(std::uint64_t start_index) noexcept
      : head_(start_index), tail_cache_(start_index), tail_(start_index), head_cache_(start_index) {}

  SpscRing(const SpscRing&) = delete;
  SpscRing& operator=(const SpscRing&) = delete;

  /// Appends one item when there is room. Returns false (nothing written) when full.
  /// Thread: the producer only. Never blocks or allocates.
  [[nodiscard]] bool try_push(const T& item) noexcept { return push(&item, 1) == 1; }

  /// Appends up to n items (fewer when the ring fills up); returns how many were appended. The first
  /// `returned` items of `items` are now in the ring in order; the rest were not touched (the caller
  /// decides whether that is a drop to count or a retry). Thread: the producer only. Never blocks or
  /// allocates; at most two memcpy and one release store.
  std::size_t push(const T* items, std::size_t n) noexcept {
    const std::uint64_t head = head_.load(std::memory_order_relaxed);  // only this thread writes it
    std::uint64_t free_slots = N - (head - tail_cache_);
    if (free_slots < n) {
      tail_cache_ = tail_.load(std::memory_order_acquire);
      free_slots = N - (head - tail_cache_);
    }
    const std::size_t count = n < free_slots ? n : static_cast<std::size_t>(free_slots);
    if (count == 0) return 0;
    const std::size_t start = static_cast<std::size_t>(head & kMask);
    const std::size_t first = count < N - start ? count : N - start;
    std::memcpy(&slots_[start], items, first * sizeof(T));
    if (count > first) std::memcpy(&slots_[0], items + first, (count - first) * sizeof(T));
    head_.store(head + count, std::memory_order_release);
    return count;
  }

  /// The next free slot, for the producer to fill in place (no copy of the whole item), or nullptr
  /// when the ring is full. Nothing is published until commit(); a slot claimed and not committed is
  /// claimed again (the same slot) by the next claim(). Thread: the producer only. Never blocks or
  /// allocates.
  [[nodiscard]] T* claim() noexcept {
    const std::uint64_t head = head_.load(std::memory_order_relaxed);  // only this thread writes it
    if (head - tail_cache_ >= N) {
      tail_cache_ = tail_.load(std::memory_order_acquire);  // orders the fill after the consumer's reads
      if (head - tail_cache_ >= N) return nullptr;
    }
    return &slots_[static_cast<std::size_t>(head & kMask)];
  }

  /// Publishes the slot the last claim() returned (which must not have returned nullptr).
  /// Thread: the producer only. Never blocks or allocates; one release store.
  void commit() noexcept {
    head_.store(head_.load(std::memory_order_relaxed) + 1, std::memory_order_release);
  }

  /// Removes the oldest item, handing it to take(const T&) in place before its slot is freed (the
  /// consumer copies what it needs, e.g. only the valid part of a block). Returns false (take not
  /// called) when empty. Thread: the consumer only. Never blocks or allocates unless take does.
  template <typename F>
  bool pop_with(F&& take) noexcept(noexcept(take(std::declval<const T&>()))) {
    const std::uint64_t tail = tail_.load(std::memory_order_relaxed);  // only this thread writes it
    if (head_cache_ == tail) {
      head_cache_ = head_.load(std::memory_order_acquire);
      if (head_cache_ == tail) return false;
    }
    take(static_cast<const T&>(slots_[static_cast<std::size_t>(tail & kMask)]));
    tail_.store(tail + 1, std::memory_order_release);
    return true;
  }

  /// Removes one item into `out` when there is one. Returns false (out untouched) when empty.
  /// Thread: the consumer only. Never blocks or allocates.
  [[nodiscard]] bool try_pop(T& out) noexcept { return pop(&out, 1) == 1; }

  /// Removes up to n items into out[0..returned) in order; returns how many (0 when empty).
  /// Thread: the consumer only. Never blocks or allocates; at most two memcpy and one release store.
  std::size_t pop(T* out, std::size_t n) noexcept {
    const std::uint64_t tail = tail_.load(std::memory_order_relaxed);  // only this thread writes it
    std::uint64_t available = head_cache_ - tail;
    if (available < n) {
      head_cache_ = head_.load(std::memory_order_acquire);
      available = head_cache_ - tail;
    }
    const std::size_t count = n < available ? n : static_cast<std::size_t>(available);
    if (count == 0) return 0;
    const std::size_t start = static_cast<std::size_t>(tail & kMask);
    const std::size_t first = count < N - start ? count : N - start;
    std::memcpy(out, &slots_[start], first * sizeof(T));
    if (count > first) std::memcpy(out + first, &slots_[0], (count - first) * sizeof(T));
    tail_.store(tail + count, std::memory_order_release);
    return count;
  }

  /// Number of items in the ring at some moment during the call, in [0, N]. Exact when called by
  /// either side while the other is idle; otherwise a snapshot that may already be stale.
  /// Thread: any. Never blocks or allocates.
  [[nodiscard]] std::size_t size_approx() const noexcept {
    // tail first: head only grows, so head >= this tail and the difference cannot underflow; a tail
    // that moved on after our load can make the difference exceed N, hence the clamp.
    const std::uint64_t tail = tail_.load(std::memory_order_acquire);
    const std::uint64_t head = head_.load(std::memory_order_acquire);
    const std::uint64_t size = head - tail;
    return size > N ? N : static_cast<std::size_t>(size);
  }

  /// Total items ever pushed (the producer's index, including the start_index offset).
  /// Thread: any. Never blocks or allocates.
  [[nodiscard]] std::uint64_t pushed_index() const noexcept { return head_.load(std::memory_order_acquire); }
  /// Total items ever popped (the consumer's index, including the start_index offset).
  /// Thread: any. Never blocks or allocates.
  [[nodiscard]] std::uint64_t popped_index() const noexcept { return tail_.load(std::memory_order_acquire); }

  [[nodiscard]] static constexpr std::size_t capacity() noexcept { return N; }

 private:
  static constexpr std::uint64_t kMask = N - 1;

  // Producer's line: its own index and its cached view of the consumer's.
  alignas(kCacheLineBytes) std::atomic<std::uint64_t> head_{0};
  std::uint64_t tail_cache_ = 0;
  // Consumer's line.
  alignas(kCacheLineBytes) std::atomic<std::uint64_t> tail_{0};
  std::uint64_t head_cache_ = 0;
  // Slots start on a fresh line. The class is kCacheLineBytes-aligned, so sizeof() is a multiple of a
  // line and whatever follows the ring never shares the last slot's line.
  alignas(kCacheLineBytes) std::array<T, N> slots_{};
};

}  // namespace ptda::daemon
