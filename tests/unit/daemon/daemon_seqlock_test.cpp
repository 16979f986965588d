// The seqlock that carries PipelineStatus from the processing thread to the supervisor: a reader
// never sees a torn value, also under ThreadSanitizer (-DPTDA_SANITIZE=thread).
#include <gtest/gtest.h>

#include <atomic>
#include <thread>

#include "alloc_counter.hpp"
#include "core/seqlock.hpp"

namespace ptda::daemon {
namespace {

struct Payload {
  std::uint64_t a = 0;
  double b = 0.0;
  std::uint32_t c[37] = {};
  std::uint64_t d = 0;
};

TEST(Seqlock, SingleThreadRoundTrip) {
  Seqlock<Payload> lock;
  EXPECT_EQ(lock.version(), 1U);  // the constructor publishes a default value
  Payload p;
  p.a = 7;
  p.b = 2.5;
  p.c[36] = 9;
  p.d = 11;
  ptda::test::AllocScope scope;
  lock.store(p);
  const Payload q = lock.load();
  EXPECT_EQ(scope.count(), 0U);
  EXPECT_EQ(q.a, 7U);
  EXPECT_EQ(q.b, 2.5);
  EXPECT_EQ(q.c[36], 9U);
  EXPECT_EQ(q.d, 11U);
  EXPECT_EQ(lock.version(), 2U);
}

TEST(Seqlock, ReaderNeverSeesATornValue) {
  Seqlock<Payload> lock;
  constexpr std::uint64_t kWrites = 200000;
  std::atomic<bool> done{false};
  std::thread writer([&] {
    Payload p;
    for (std::uint64_t i = 1; i <= kWrites; ++i) {
      p.a = i;
      p.b = static_cast<double>(i);
      for (auto& c : p.c) c = static_cast<std::uint32_t>(i);
      p.d = i;
      lock.store(p);
    }
    done = true;
  });
  std::uint64_t reads = 0, torn = 0, last = 0, backwards = 0;
  while (!done.load() || reads == 0) {
    const Payload q = lock.load();
    bool ok = q.b == static_cast<double>(q.a) && q.d == q.a;
    for (const auto c : q.c) ok = ok && c == static_cast<std::uint32_t>(q.a);
    torn += ok ? 0 : 1;
    backwards += q.a < last ? 1 : 0;
    last = q.a;
    ++reads;
  }
  writer.join();
  EXPECT_EQ(torn, 0U);
  EXPECT_EQ(backwards, 0U);
  EXPECT_EQ(lock.load().a, kWrites);
  EXPECT_GT(reads, 0U);
}

}  // namespace
}  // namespace ptda::daemon
