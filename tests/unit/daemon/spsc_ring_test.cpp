#include "rt/spsc_ring.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <limits>
#include <memory>
#include <numeric>
#include <random>
#include <thread>
#include <vector>

#include "alloc_counter.hpp"

namespace ptda::daemon {
namespace {

// Layout: indices and slots each on their own 64-byte line; 16 x 4-byte slots fill exactly one line.
static_assert(alignof(SpscRing<std::uint32_t, 16>) == 64);
static_assert(sizeof(SpscRing<std::uint32_t, 16>) == 3 * 64);
static_assert(sizeof(SpscRing<std::uint32_t, 32>) == 4 * 64);
static_assert(SpscRing<float, 4096>::capacity() == 4096);

TEST(SpscRing, StartsEmptyAndPopsNothing) {
  SpscRing<std::uint32_t, 8> ring;
  std::uint32_t out = 77;
  EXPECT_EQ(ring.size_approx(), 0u);
  EXPECT_FALSE(ring.try_pop(out));
  EXPECT_EQ(out, 77u);
  std::array<std::uint32_t, 4> buf{};
  EXPECT_EQ(ring.pop(buf.data(), buf.size()), 0u);
  EXPECT_EQ(ring.push(buf.data(), 0), 0u);
  EXPECT_EQ(ring.pushed_index(), 0u);
}

TEST(SpscRing, FillsToCapacityWithoutASpareSlotThenRefuses) {
  SpscRing<std::uint32_t, 8> ring;
  for (std::uint32_t i = 0; i < 8; ++i) ASSERT_TRUE(ring.try_push(i)) << i;
  EXPECT_EQ(ring.size_approx(), 8u);
  EXPECT_FALSE(ring.try_push(99));
  const std::uint32_t more[3] = {100, 101, 102};
  EXPECT_EQ(ring.push(more, 3), 0u);
  std::uint32_t v = 0;
  ASSERT_TRUE(ring.try_pop(v));
  EXPECT_EQ(v, 0u);
  // One slot free: a bulk push of 3 appends exactly one (the first) item.
  EXPECT_EQ(ring.push(more, 3), 1u);
  std::array<std::uint32_t, 16> out{};
  ASSERT_EQ(ring.pop(out.data(), out.size()), 8u);
  const std::array<std::uint32_t, 8> expected{1, 2, 3, 4, 5, 6, 7, 100};
  for (std::size_t i = 0; i < 8; ++i) EXPECT_EQ(out[i], expected[i]) << i;
  EXPECT_EQ(ring.size_approx(), 0u);
  EXPECT_EQ(ring.pushed_index(), 9u);
  EXPECT_EQ(ring.popped_index(), 9u);
}

TEST(SpscRing, BulkCopiesSplitAcrossTheEndOfTheSlotArray) {
  SpscRing<std::uint32_t, 8> ring;
  std::array<std::uint32_t, 6> a{10, 11, 12, 13, 14, 15};
  ASSERT_EQ(ring.push(a.data(), a.size()), 6u);
  std::array<std::uint32_t, 5> out{};
  ASSERT_EQ(ring.pop(out.data(), 5), 5u);  // tail at slot 5
  std::array<std::uint32_t, 7> b{20, 21, 22, 23, 24, 25, 26};
  ASSERT_EQ(ring.push(b.data(), b.size()), 7u);  // slots 6,7 then 0..4
  EXPECT_EQ(ring.size_approx(), 8u);
  std::array<std::uint32_t, 8> all{};
  ASSERT_EQ(ring.pop(all.data(), all.size()), 8u);
  const std::array<std::uint32_t, 8> expected{15, 20, 21, 22, 23, 24, 25, 26};
  EXPECT_EQ(all, expected);
}

// Indices are 64-bit and never reset: crossing 2^32 (where a 32-bit index would wrap) and 2^64
// (where the 64-bit one does) must not change what comes out.
class SpscRingIndexWrap : public ::testing::TestWithParam<std::uint64_t> {};

TEST_P(SpscRingIndexWrap, SequenceSurvivesIndexOverflowBoundary) {
  const std::uint64_t start = GetParam();
  SpscRing<std::uint64_t, 16> ring(start);
  EXPECT_EQ(ring.size_approx(), 0u);
  std::uint64_t next_in = 0, next_out = 0;
  std::array<std::uint64_t, 16> buf{};
  // 50 rounds of pushing 7 and popping 5/9 alternately: ~300 items cross the boundary at 5.
  for (int round = 0; round < 50; ++round) {
    std::array<std::uint64_t, 7> in{};
    for (auto& v : in) v = next_in++;
    const std::size_t pushed = ring.push(in.data(), in.size());
    next_in -= in.size() - pushed;  // items not taken are retried next round
    const std::size_t want = (round % 2 == 0) ? 5 : 9;
    const std::size_t got = ring.pop(buf.data(), want);
    for (std::size_t i = 0; i < got; ++i) ASSERT_EQ(buf[i], next_out++) << "round " << round;
    ASSERT_LE(ring.size_approx(), 16u);
  }
  const std::size_t rest = ring.pop(buf.data(), buf.size());
  for (std::size_t i = 0; i < rest; ++i) ASSERT_EQ(buf[i], next_out++);
  EXPECT_EQ(next_out, next_in);
  EXPECT_EQ(ring.pushed_index() - start, next_in);  // modulo 2^64
  EXPECT_EQ(ring.size_approx(), 0u);
}

INSTANTIATE_TEST_SUITE_P(Boundaries, SpscRingIndexWrap,
                         ::testing::Values(std::uint64_t{0}, (std::uint64_t{1} << 32) - 5,
                                           std::numeric_limits<std::uint64_t>::max() - 5));

TEST(SpscRing, FullAndEmptyAreDistinguishedAcross2Pow64) {
  SpscRing<std::uint8_t, 4> ring(std::numeric_limits<std::uint64_t>::max() - 1);
  const std::uint8_t in[4] = {1, 2, 3, 4};
  ASSERT_EQ(ring.push(in, 4), 4u);  // head wraps to 2 while tail is 2^64-2
  EXPECT_EQ(ring.pushed_index(), 2u);
  EXPECT_EQ(ring.size_approx(), 4u);
  EXPECT_FALSE(ring.try_push(5));
  std::uint8_t out[4] = {};
  ASSERT_EQ(ring.pop(out, 4), 4u);
  EXPECT_EQ(out[3], 4);
  EXPECT_EQ(ring.size_approx(), 0u);
}

TEST(SpscRing, PushAndPopNeverAllocate) {
  auto ring = std::make_unique<SpscRing<float, 1024>>();
  std::vector<float> in(700, 1.5F), out(700);
  test::AllocScope scope;
  for (int i = 0; i < 100; ++i) {
    ASSERT_EQ(ring->push(in.data(), in.size()), 700u);
    ASSERT_EQ(ring->pop(out.data(), out.size()), 700u);
    float one = 2.0F;
    ASSERT_TRUE(ring->try_push(one));
    ASSERT_TRUE(ring->try_pop(one));
  }
  EXPECT_EQ(scope.count(), 0u);
}

// claim()/commit() fill a slot in place; pop_with() hands the oldest slot to a function before freeing
// it. Order, capacity, an uncommitted claim (the same slot again) and mixing with push/pop.
TEST(SpscRing, ClaimCommitAndPopWithKeepOrderAndCapacity) {
  SpscRing<std::uint32_t, 4> ring(std::numeric_limits<std::uint64_t>::max() - 1);  // across the 2^64 wrap
  std::uint32_t* s = ring.claim();
  ASSERT_NE(s, nullptr);
  *s = 99;  // claimed, not committed: invisible, and the next claim is the same slot
  EXPECT_EQ(ring.size_approx(), 0u);
  EXPECT_EQ(ring.claim(), s);
  *s = 10;
  ring.commit();
  ASSERT_TRUE(ring.try_push(11));
  for (std::uint32_t v : {12u, 13u}) {
    std::uint32_t* t = ring.claim();
    ASSERT_NE(t, nullptr);
    *t = v;
    ring.commit();
  }
  EXPECT_EQ(ring.claim(), nullptr);  // full: 4 items
  EXPECT_EQ(ring.size_approx(), 4u);
  std::vector<std::uint32_t> seen;
  const auto take = [&seen](const std::uint32_t& v) noexcept { seen.push_back(v); };
  ASSERT_TRUE(ring.pop_with(take));
  EXPECT_NE(ring.claim(), nullptr);  // one slot free again
  std::uint32_t out = 0;
  ASSERT_TRUE(ring.try_pop(out));
  EXPECT_EQ(out, 11u);
  ASSERT_TRUE(ring.pop_with(take));
  ASSERT_TRUE(ring.pop_with(take));
  EXPECT_FALSE(ring.pop_with(take));  // empty: take not called
  EXPECT_EQ(seen, (std::vector<std::uint32_t>{10u, 12u, 13u}));
  EXPECT_EQ(ring.pushed_index(), ring.popped_index());
  EXPECT_EQ(ring.popped_index(), std::numeric_limits<std::uint64_t>::max() - 1 + 4);
}

// Two threads: the producer fills claimed slots in place, the consumer checks each slot inside
// pop_with (a torn or stale slot, i.e. a missing acquire/release, shows up as a mismatch; and under
// ThreadSanitizer as a race).
TEST(SpscRingStress, TwoThreadsClaimCommitAndPopWithKeepTheSequence) {
  struct Slot {
    std::uint64_t seq;
    std::uint64_t check;
  };
  auto ring = std::make_unique<SpscRing<Slot, 64>>();
  constexpr std::uint64_t kTotal = 2'000'000;
  std::uint64_t errors = 0;
  std::thread consumer([&] {
    std::uint64_t expected = 0;
    while (expected < kTotal) {
      const bool got = ring->pop_with([&](const Slot& x) noexcept {
        if (x.seq != expected || x.check != ~x.seq * 0x9E3779B97F4A7C15ULL) ++errors;
        ++expected;
      });
      if (!got) std::this_thread::yield();
    }
  });
  for (std::uint64_t next = 0; next < kTotal;) {
    Slot* s = ring->claim();
    if (s == nullptr) {
      std::this_thread::yield();
      continue;
    }
    s->seq = next;
    s->check = ~next * 0x9E3779B97F4A7C15ULL;
    ring->commit();
    ++next;
  }
  consumer.join();
  EXPECT_EQ(errors, 0u);
  EXPECT_EQ(ring->popped_index(), kTotal);
}

// Two threads, random bulk sizes on both sides, every item checked: a sequence number plus a
// checksum word so that a torn or stale slot (missing acquire/release) shows up as a mismatch.
struct Item {
  std::uint64_t seq;
  std::uint64_t check;  // ~seq * golden ratio: differs from seq in every byte position
};
constexpr std::uint64_t item_check(std::uint64_t seq) {
  return ~seq * 0x9E3779B97F4A7C15ULL;
}

void run_stress(std::uint64_t start_index, std::uint64_t total_items, std::uint32_t seed) {
  using Ring = SpscRing<Item, 512>;
  auto ring = std::make_unique<Ring>(start_index);
  std::uint64_t consumer_errors = 0, consumer_seen = 0;
  std::size_t max_seen_size = 0;

  std::thread consumer([&] {
    std::mt19937 rng(seed + 1);
    std::uniform_int_distribution<std::size_t> bulk(1, 700);  // sometimes more than the capacity
    std::vector<Item> buf(700);
    std::uint64_t expected = 0;
    while (expected < total_items) {
      const std::size_t got = ring->pop(buf.data(), bulk(rng));
      if (got == 0) {
        std::this_thread::yield();
        continue;
      }
      for (std::size_t i = 0; i < got; ++i) {
        if (buf[i].seq != expected || buf[i].check != item_check(expected)) ++consumer_errors;
        ++expected;
      }
      const std::size_t s = ring->size_approx();
      if (s > max_seen_size) max_seen_size = s;
    }
    consumer_seen = expected;
  });

  std::mt19937 rng(seed);
  std::uniform_int_distribution<std::size_t> bulk(1, 300);
  std::vector<Item> buf(300);
  std::uint64_t next = 0;
  std::uint64_t full_events = 0;
  while (next < total_items) {
    std::size_t n = bulk(rng);
    if (n > total_items - next) n = static_cast<std::size_t>(total_items - next);
    for (std::size_t i = 0; i < n; ++i) buf[i] = Item{next + i, item_check(next + i)};
    std::size_t done = 0;
    while (done < n) {
      const std::size_t k = ring->push(buf.data() + done, n - done);
      if (k == 0) {
        ++full_events;
        std::this_thread::yield();
      }
      done += k;
    }
    next += n;
  }
  consumer.join();

  EXPECT_EQ(consumer_errors, 0u);
  EXPECT_EQ(consumer_seen, total_items);
  EXPECT_LE(max_seen_size, 512u);
  EXPECT_EQ(ring->pushed_index() - start_index, total_items);
  EXPECT_EQ(ring->popped_index() - start_index, total_items);
  EXPECT_EQ(ring->size_approx(), 0u);
  ::testing::Test::RecordProperty("full_events",
                                  static_cast<int>(full_events > 1000000 ? 1000000 : full_events));
}

TEST(SpscRingStress, TwoThreadsRandomBulkSizesKeepTheSequence) {
  run_stress(0, 10'000'000, 1234);
}

TEST(SpscRingStress, TwoThreadsAcrossThe2Pow64IndexWrap) {
  run_stress(std::numeric_limits<std::uint64_t>::max() - 1'000'000, 2'000'000, 99);
}

}  // namespace
}  // namespace ptda::daemon
