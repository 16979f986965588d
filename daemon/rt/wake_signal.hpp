// A doorbell for one sleeping consumer: producers ring it after they publish work (into an SpscRing),
// the consumer sleeps on it with a timeout instead of polling.
//
// Protocol (no lost wake-up): the consumer takes a ticket (the current sequence number) BEFORE it looks
// for work; when it found none it calls wait(ticket, timeout). A producer that published work after the
// ticket was taken has incremented the sequence, so the kernel's futex check (value != ticket) returns
// at once; one that rings later wakes the sleeper. Producers always issue the wake system call (no
// "someone is waiting" flag, which would need a seq_cst Dekker handshake): a FUTEX_WAKE with nobody
// waiting costs well under a microsecond, and ptdad rings a few hundred times per second.
//
// The doorbell orders nothing itself: the data travels through the rings' acquire/release indices.
#pragma once

#include <linux/futex.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <atomic>
#include <cstdint>
#include <ctime>

#include "ptda/common/cache_line.hpp"

namespace ptda::daemon {

class WakeSignal {
  static_assert(sizeof(std::atomic<std::uint32_t>) == sizeof(std::uint32_t), "futex word must be 32 bits");
  static_assert(std::atomic<std::uint32_t>::is_always_lock_free, "futex word must be lock-free");

 public:
  /// The current sequence number, to be taken before checking for work. Thread: the consumer.
  /// Never blocks or allocates.
  [[nodiscard]] std::uint32_t ticket() const noexcept { return seq_.load(std::memory_order_acquire); }

  /// Signals that work was published. Thread: any producer. Never blocks or allocates (one system call).
  void ring() noexcept {
    seq_.fetch_add(1, std::memory_order_release);
    ::syscall(SYS_futex, word(), FUTEX_WAKE_PRIVATE, 1, nullptr, nullptr, 0);
  }

  /// Sleeps until ring() is called after `ticket` was taken, or `timeout_ns` passes, or a signal
  /// arrives (spurious returns are allowed: the caller re-checks for work). Thread: the one consumer.
  /// Blocks (this is the consumer's one wait); never allocates.
  void wait(std::uint32_t ticket, std::int64_t timeout_ns) const noexcept {
    if (seq_.load(std::memory_order_acquire) != ticket) return;
    timespec ts{};
    ts.tv_sec = static_cast<time_t>(timeout_ns / 1'000'000'000);
    ts.tv_nsec = static_cast<long>(timeout_ns % 1'000'000'000);
    // FUTEX_WAIT's timeout is relative (CLOCK_MONOTONIC); it returns at once when *word != ticket.
    ::syscall(SYS_futex, word(), FUTEX_WAIT_PRIVATE, ticket, &ts, nullptr, 0);
  }

 private:
  [[nodiscard]] std::uint32_t* word() const noexcept {
    // The kernel reads the 32-bit word behind the atomic (same size, lock-free: asserted above).
    return reinterpret_cast<std::uint32_t*>(const_cast<std::atomic<std::uint32_t>*>(&seq_));
  }

  alignas(kCacheLineBytes) std::atomic<std::uint32_t> seq_{0};
};

}  // namespace ptda::daemon
