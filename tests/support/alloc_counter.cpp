// Replaces the global allocation functions of the test binary that links this file, so tests can
// assert that steady-state paths do not allocate.
#include "alloc_counter.hpp"

#include <pthread.h>

#include <atomic>
#include <cstdlib>
#include <cstring>
#include <new>

namespace {
std::atomic<std::uint64_t> g_allocs{0};

// The daemon's MQTT publisher thread ("ptda-mqtt", named before its first allocation) formats JSON and
// may allocate by design: it is not a real-time thread. Its allocations are not counted.
bool counted_thread() noexcept {
  thread_local int counted = -1;
  if (counted < 0) {
    char name[16] = {};
    counted =
        pthread_getname_np(pthread_self(), name, sizeof name) == 0 && std::strcmp(name, "ptda-mqtt") == 0 ? 0
                                                                                                          : 1;
  }
  return counted == 1;
}

void* counted_alloc(std::size_t n) {
  if (counted_thread()) g_allocs.fetch_add(1, std::memory_order_relaxed);
  if (n == 0) n = 1;
  void* p = std::malloc(n);
  if (p == nullptr) throw std::bad_alloc();
  return p;
}
void* counted_alloc_aligned(std::size_t n, std::align_val_t al) {
  if (counted_thread()) g_allocs.fetch_add(1, std::memory_order_relaxed);
  const auto a = static_cast<std::size_t>(al);
  std::size_t size = (n + a - 1) / a * a;
  if (size == 0) size = a;
  void* p = std::aligned_alloc(a, size);
  if (p == nullptr) throw std::bad_alloc();
  return p;
}
}  // namespace

namespace ptda::test {
std::uint64_t alloc_count() noexcept {
  return g_allocs.load(std::memory_order_relaxed);
}
}  // namespace ptda::test

void* operator new(std::size_t n) {
  return counted_alloc(n);
}
void* operator new[](std::size_t n) {
  return counted_alloc(n);
}
void* operator new(std::size_t n, std::align_val_t al) {
  return counted_alloc_aligned(n, al);
}
void* operator new[](std::size_t n, std::align_val_t al) {
  return counted_alloc_aligned(n, al);
}
void* operator new(std::size_t n, const std::nothrow_t&) noexcept {
  try {
    return counted_alloc(n);
  } catch (...) {
    return nullptr;
  }
}
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept {
  try {
    return counted_alloc(n);
  } catch (...) {
    return nullptr;
  }
}
void operator delete(void* p) noexcept {
  std::free(p);
}
void operator delete[](void* p) noexcept {
  std::free(p);
}
void operator delete(void* p, std::size_t) noexcept {
  std::free(p);
}
void operator delete[](void* p, std::size_t) noexcept {
  std::free(p);
}
void operator delete(void* p, std::align_val_t) noexcept {
  std::free(p);
}
void operator delete[](void* p, std::align_val_t) noexcept {
  std::free(p);
}
void operator delete(void* p, std::size_t, std::align_val_t) noexcept {
  std::free(p);
}
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept {
  std::free(p);
}
