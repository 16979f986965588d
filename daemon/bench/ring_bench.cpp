// Throughput of the daemon's SpscRing (daemon/rt/spsc_ring.hpp) against the obvious alternative, a
// std::deque behind a std::mutex with the same capacity, for bulk sizes of 1, 64 and 1024 floats.
//
// One transfer moves kItems floats (the sequence 0, 1, 2, ...) from this thread to a consumer thread,
// which checks the sequence. Both queues hold kCapacity floats; a full producer or an empty consumer
// calls std::this_thread::yield() (the machine has 2 shared cores: a pure spin would measure the
// scheduler). Every iteration runs one transfer through each queue, alternating which goes first, so
// both see the same machine noise; the counters are the medians over the iterations of items per
// second of each and of the per-iteration ratio (spsc / mutex). Results: docs/benchmarks.md.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <deque>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include "rt/spsc_ring.hpp"

namespace {

constexpr std::size_t kCapacity = 8192;   // floats in either queue
constexpr std::size_t kItems = 1U << 22;  // floats per transfer (exact as float: < 2^24)

using Ring = ptda::daemon::SpscRing<float, kCapacity>;

/// The baseline: a bounded FIFO of floats behind one mutex (push/pop move up to n items per lock).
class MutexDeque {
 public:
  std::size_t push(const float* items, std::size_t n) {
    const std::lock_guard lock(mutex_);
    const std::size_t count = std::min(n, kCapacity - queue_.size());
    queue_.insert(queue_.end(), items, items + count);
    return count;
  }
  std::size_t pop(float* out, std::size_t n) {
    const std::lock_guard lock(mutex_);
    const std::size_t count = std::min(n, queue_.size());
    const auto first = queue_.begin();
    const auto last = first + static_cast<std::ptrdiff_t>(count);
    std::copy(first, last, out);
    queue_.erase(first, last);
    return count;
  }

 private:
  std::mutex mutex_;
  std::deque<float> queue_;
};

/// Seconds to move kItems floats through q in chunks of `bulk`; false in `ok` on a sequence error.
template <typename Q>
double transfer_s(Q& q, std::size_t bulk, bool& ok) {
  std::atomic<bool> go{false};
  std::atomic<bool> good{true};
  std::thread consumer([&] {
    std::vector<float> buf(bulk);
    while (!go.load(std::memory_order_acquire)) std::this_thread::yield();
    std::size_t got = 0;
    while (got < kItems) {
      const std::size_t n = q.pop(buf.data(), std::min(bulk, kItems - got));
      if (n == 0) {
        std::this_thread::yield();
        continue;
      }
      for (std::size_t i = 0; i < n; ++i) {
        if (buf[i] != static_cast<float>(got + i)) good.store(false, std::memory_order_relaxed);
      }
      got += n;
    }
  });
  std::vector<float> chunk(bulk);
  const auto t0 = std::chrono::steady_clock::now();
  go.store(true, std::memory_order_release);
  std::size_t sent = 0;
  while (sent < kItems) {
    const std::size_t m = std::min(bulk, kItems - sent);
    for (std::size_t i = 0; i < m; ++i) chunk[i] = static_cast<float>(sent + i);
    std::size_t done = 0;
    while (done < m) {
      const std::size_t k = q.push(chunk.data() + done, m - done);
      if (k == 0) std::this_thread::yield();
      done += k;
    }
    sent += m;
  }
  consumer.join();
  const auto t1 = std::chrono::steady_clock::now();
  ok = ok && good.load();
  return std::chrono::duration<double>(t1 - t0).count();
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n == 0 ? 0.0 : (n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]));
}

void BM_SpscVsMutexDeque(benchmark::State& state) {
  const auto bulk = static_cast<std::size_t>(state.range(0));
  auto ring = std::make_unique<Ring>();
  MutexDeque deque;
  std::vector<double> spsc_rate, mutex_rate, ratio;
  bool ok = true;
  std::int64_t iteration = 0;
  for (auto _ : state) {
    double a = 0.0, b = 0.0;
    if (iteration++ % 2 == 0) {
      a = transfer_s(*ring, bulk, ok);
      b = transfer_s(deque, bulk, ok);
    } else {
      b = transfer_s(deque, bulk, ok);
      a = transfer_s(*ring, bulk, ok);
    }
    spsc_rate.push_back(static_cast<double>(kItems) / a / 1e6);
    mutex_rate.push_back(static_cast<double>(kItems) / b / 1e6);
    ratio.push_back(b / a);
    state.SetIterationTime(a + b);
  }
  if (!ok) state.SkipWithError("sequence error: an item was lost, duplicated or reordered");
  // Medians over the iterations: a burst of noise from the other tenants hits one pair, not the result.
  state.counters["spsc_Mitems_s"] = median(spsc_rate);
  state.counters["mutex_Mitems_s"] = median(mutex_rate);
  state.counters["ratio"] = median(ratio);
  state.SetItemsProcessed(2 * static_cast<std::int64_t>(kItems) * iteration);
}

BENCHMARK(BM_SpscVsMutexDeque)
    ->ArgName("bulk")
    ->Arg(1)
    ->Arg(64)
    ->Arg(1024)
    ->Iterations(9)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

/// Seconds to move kItems floats through q from and to this thread (push `bulk`, pop `bulk`): the cost
/// of the operations themselves, without the scheduler.
template <typename Q>
double same_thread_s(Q& q, std::size_t bulk, bool& ok) {
  std::vector<float> chunk(bulk), out(bulk);
  const auto t0 = std::chrono::steady_clock::now();
  for (std::size_t sent = 0; sent < kItems; sent += bulk) {
    for (std::size_t i = 0; i < bulk; ++i) chunk[i] = static_cast<float>(sent + i);
    const std::size_t pushed = q.push(chunk.data(), bulk);
    const std::size_t popped = q.pop(out.data(), bulk);
    if (pushed != bulk || popped != bulk || out[bulk - 1] != chunk[bulk - 1]) ok = false;
  }
  const auto t1 = std::chrono::steady_clock::now();
  return std::chrono::duration<double>(t1 - t0).count();
}

void BM_SameThreadPushPop(benchmark::State& state) {
  const auto bulk = static_cast<std::size_t>(state.range(0));
  auto ring = std::make_unique<Ring>();
  MutexDeque deque;
  std::vector<double> spsc_rate, mutex_rate, ratio;
  bool ok = true;
  for (auto _ : state) {
    const double a = same_thread_s(*ring, bulk, ok);
    const double b = same_thread_s(deque, bulk, ok);
    spsc_rate.push_back(static_cast<double>(kItems) / a / 1e6);
    mutex_rate.push_back(static_cast<double>(kItems) / b / 1e6);
    ratio.push_back(b / a);
    state.SetIterationTime(a + b);
  }
  if (!ok) state.SkipWithError("push/pop mismatch");
  state.counters["spsc_Mitems_s"] = median(spsc_rate);
  state.counters["mutex_Mitems_s"] = median(mutex_rate);
  state.counters["ratio"] = median(ratio);
}

BENCHMARK(BM_SameThreadPushPop)
    ->ArgName("bulk")
    ->Arg(1)
    ->Arg(64)
    ->Arg(1024)
    ->Iterations(9)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
