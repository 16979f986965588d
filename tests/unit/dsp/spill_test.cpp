// SpillVector and sorted() (dsp/include/ptda/dsp/spill.hpp) against std::vector and std::stable_sort:
// the in-memory/on-disk boundary, chunked and sequential reading, the bounded-memory stable sort, the
// anonymity of the spill file and the errors of an unusable spill directory.
#include "ptda/dsp/spill.hpp"

#include <gtest/gtest.h>
#include <stdlib.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <optional>
#include <random>
#include <span>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

#include "ptda/common/error.hpp"

namespace ptda::dsp {
namespace {

namespace fs = std::filesystem;

// A fresh directory /tmp/ptda-spill-test-XXXXXX, removed with its contents at the end.
class TempDir {
 public:
  TempDir() {
    std::string tmpl = "/tmp/ptda-spill-test-XXXXXX";
    if (::mkdtemp(tmpl.data()) == nullptr) throw std::system_error(errno, std::generic_category(), "mkdtemp");
    path_ = tmpl;
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  [[nodiscard]] const std::string& path() const { return path_; }

 private:
  std::string path_;
};

// The names in dir (hidden ones included).
std::vector<std::string> entries(const std::string& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  return names;
}

// How many of this process's file descriptors refer to a file in dir (an anonymous or unlinked file
// still shows as "<dir>/<name> (deleted)"); nullopt when /proc/self/fd cannot be listed.
std::optional<std::size_t> fds_in(const std::string& dir) {
  std::error_code ec;
  fs::directory_iterator it("/proc/self/fd", ec);
  if (ec) return std::nullopt;
  std::size_t n = 0;
  const std::string prefix = dir + "/";
  for (; it != fs::directory_iterator(); it.increment(ec)) {
    if (ec) return std::nullopt;
    std::error_code lec;
    const fs::path target = fs::read_symlink(it->path(), lec);
    if (!lec && target.string().compare(0, prefix.size(), prefix) == 0) ++n;
  }
  return n;
}

// Whether exactly expected descriptors refer to files in dir (true when /proc/self/fd is unavailable).
::testing::AssertionResult fds_in_are(const std::string& dir, std::size_t expected) {
  const std::optional<std::size_t> n = fds_in(dir);
  if (!n || *n == expected) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << *n << " open files in " << dir << ", expected " << expected;
}

// Sets an environment variable for a scope and restores it afterwards.
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const std::string& value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = std::string(old);
    ::setenv(name, value.c_str(), 1);
  }
  ~ScopedEnv() {
    if (old_) {
      ::setenv(name_, old_->c_str(), 1);
    } else {
      ::unsetenv(name_);
    }
  }
  ScopedEnv(const ScopedEnv&) = delete;
  ScopedEnv& operator=(const ScopedEnv&) = delete;

 private:
  const char* name_;
  std::optional<std::string> old_;
};

SpillConfig elements(std::size_t n, std::size_t element_size, std::string dir = {}) {
  SpillConfig c;
  c.dir = std::move(dir);
  c.memory_bytes = n * element_size;
  return c;
}

template <class T>
SpillVector<T> make(const std::vector<T>& xs, const SpillConfig& cfg) {
  SpillVector<T> v(cfg);
  for (const T& x : xs) v.push_back(x);
  return v;
}

template <class T>
std::vector<T> collect(const SpillVector<T>& v) {
  std::vector<T> out;
  v.for_each([&](const T& x) { out.push_back(x); });
  return out;
}

std::vector<double> random_doubles(std::size_t n, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 10.0);
  std::vector<double> xs(n);
  for (double& x : xs) x = g(rng);
  return xs;
}

// A key with many duplicates and the element's original index, to check stability.
struct Keyed {
  std::int32_t key;
  std::uint32_t index;
};
bool operator==(const Keyed& a, const Keyed& b) {
  return a.key == b.key && a.index == b.index;
}
const auto kByKey = [](const Keyed& a, const Keyed& b) { return a.key < b.key; };

std::vector<Keyed> keyed(std::size_t n, std::int32_t distinct_keys, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<std::int32_t> k(0, distinct_keys - 1);
  std::vector<Keyed> xs(n);
  for (std::size_t i = 0; i < n; ++i) xs[i] = Keyed{k(rng), static_cast<std::uint32_t>(i)};
  return xs;
}

// Sorts xs with sorted() on a vector of the given config and checks the result against
// std::stable_sort, the input against xs (unchanged) and the output's chunking.
template <class T, class Less>
void expect_sorted_like_stable_sort(const std::vector<T>& xs, const SpillConfig& cfg, Less less) {
  const SpillVector<T> v = make(xs, cfg);
  const SpillVector<T> s = sorted(v, less);
  std::vector<T> expected = xs;
  std::stable_sort(expected.begin(), expected.end(), less);
  EXPECT_EQ(s.size(), xs.size());
  EXPECT_EQ(s.chunk(), v.chunk());
  EXPECT_EQ(s.spilled(), v.spilled());
  EXPECT_TRUE(collect(s) == expected) << "n " << xs.size() << ", chunk " << v.chunk();
  EXPECT_TRUE(collect(v) == xs) << "sorted() changed its input";
}

// --- push_back, size, at, spilled, memory ------------------------------------------------------

// Pushes xs one by one and checks after every push everything the vector exposes.
void check_boundary(const std::vector<double>& xs, const SpillConfig& cfg, std::size_t expected_chunk) {
  SpillVector<double> v(cfg);
  EXPECT_EQ(v.chunk(), expected_chunk);
  EXPECT_TRUE(v.empty());
  EXPECT_FALSE(v.spilled());
  EXPECT_TRUE(v.memory().empty());
  for (std::size_t n = 1; n <= xs.size(); ++n) {
    v.push_back(xs[n - 1]);
    ASSERT_EQ(v.size(), n);
    EXPECT_FALSE(v.empty());
    // Spills only when the memory holds more than one chunk's worth.
    ASSERT_EQ(v.spilled(), n > expected_chunk) << "n " << n;
    const std::span<const double> mem = v.memory();
    ASSERT_GE(mem.size(), 1u);
    ASSERT_LE(mem.size(), expected_chunk);
    if (!v.spilled()) {
      ASSERT_EQ(mem.size(), n);
    }
    // Whole chunks on disk; the memory holds the newest elements.
    ASSERT_EQ((n - mem.size()) % expected_chunk, 0u) << "n " << n;
    for (std::size_t j = 0; j < mem.size(); ++j) ASSERT_EQ(mem[j], xs[n - mem.size() + j]);
    // The newest and the oldest element, one on disk once spilled.
    ASSERT_EQ(v.at(n - 1), xs[n - 1]);
    ASSERT_EQ(v.at(0), xs[0]);
  }
  // Every element, from the end backwards and then in a random order.
  for (std::size_t i = xs.size(); i-- > 0;) ASSERT_EQ(v.at(i), xs[i]) << "i " << i;
  std::vector<std::size_t> order(xs.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::shuffle(order.begin(), order.end(), std::mt19937(7));
  for (std::size_t i : order) ASSERT_EQ(v.at(i), xs[i]) << "i " << i;
}

TEST(SpillVector, ThreeElementChunks) {
  check_boundary(random_doubles(40, 1), elements(3, sizeof(double)), 3);
}

TEST(SpillVector, OneByteMeansOneElementPerChunk) {
  SpillConfig cfg;
  cfg.memory_bytes = 1;
  check_boundary(random_doubles(25, 2), cfg, 1);
}

TEST(SpillVector, ZeroBytesMeansOneElementPerChunk) {
  SpillConfig cfg;
  cfg.memory_bytes = 0;
  check_boundary(random_doubles(10, 3), cfg, 1);
}

TEST(SpillVector, MemoryBytesNotAMultipleOfTheElementRoundsDown) {
  SpillConfig cfg;
  cfg.memory_bytes = 5 * sizeof(double) - 1;
  check_boundary(random_doubles(30, 4), cfg, 4);
}

TEST(SpillVector, DefaultConfigKeepsItsChunkInMemory) {
  const SpillConfig def;
  const std::size_t chunk = def.memory_bytes / sizeof(double);
  ASSERT_GT(chunk, 1u);
  const std::vector<double> xs = random_doubles(chunk + chunk / 2, 5);
  SpillVector<double> v;
  EXPECT_EQ(v.chunk(), chunk);
  EXPECT_EQ(v.config().memory_bytes, def.memory_bytes);
  EXPECT_TRUE(v.config().dir.empty());
  for (std::size_t i = 0; i < chunk; ++i) v.push_back(xs[i]);
  EXPECT_FALSE(v.spilled());
  EXPECT_EQ(v.memory().size(), chunk);
  EXPECT_TRUE(std::equal(v.memory().begin(), v.memory().end(), xs.begin()));
  v.push_back(xs[chunk]);
  EXPECT_TRUE(v.spilled());
  EXPECT_EQ(v.memory().size(), 1u);
  EXPECT_EQ(v.memory()[0], xs[chunk]);
  for (std::size_t i = chunk + 1; i < xs.size(); ++i) v.push_back(xs[i]);
  EXPECT_EQ(v.size(), xs.size());
  EXPECT_EQ(v.memory().size(), xs.size() - chunk);
  EXPECT_TRUE(collect(v) == xs);
  for (std::size_t i : {std::size_t{0}, chunk / 3, chunk - 1, chunk, xs.size() - 1}) {
    EXPECT_EQ(v.at(i), xs[i]) << "i " << i;
  }
}

TEST(SpillVector, MoveKeepsTheElements) {
  const std::vector<double> xs = random_doubles(20, 6);
  SpillVector<double> a = make(xs, elements(3, sizeof(double)));
  ASSERT_TRUE(a.spilled());
  SpillVector<double> b(std::move(a));
  EXPECT_EQ(b.size(), xs.size());
  EXPECT_TRUE(collect(b) == xs);
  SpillVector<double> c(elements(3, sizeof(double)));
  c.push_back(1.0);
  c = std::move(b);
  EXPECT_TRUE(collect(c) == xs);
  for (std::size_t i = 0; i < xs.size(); ++i) EXPECT_EQ(c.at(i), xs[i]);
}

// --- for_each_chunk, for_each --------------------------------------------------------------------

TEST(SpillVector, ChunksComeInOrderAndFull) {
  for (const std::size_t chunk : {std::size_t{1}, std::size_t{3}, std::size_t{8}}) {
    for (std::size_t n = 0; n <= 4 * chunk + 1; ++n) {
      const std::vector<double> xs = random_doubles(n, static_cast<std::uint32_t>(100 + n));
      const SpillVector<double> v = make(xs, elements(chunk, sizeof(double)));
      std::vector<std::size_t> sizes;
      std::vector<double> seen;
      v.for_each_chunk([&](std::span<const double> c) {
        sizes.push_back(c.size());
        seen.insert(seen.end(), c.begin(), c.end());
      });
      EXPECT_TRUE(seen == xs) << "chunk " << chunk << ", n " << n;
      // ceil(n / chunk) chunks, all full but the last, none empty.
      ASSERT_EQ(sizes.size(), (n + chunk - 1) / chunk) << "chunk " << chunk << ", n " << n;
      for (std::size_t k = 0; k < sizes.size(); ++k) {
        EXPECT_GE(sizes[k], 1u);
        if (k + 1 < sizes.size()) {
          EXPECT_EQ(sizes[k], chunk) << "chunk " << chunk << ", n " << n;
        } else {
          EXPECT_LE(sizes[k], chunk);
        }
      }
      std::vector<double> each;
      v.for_each([&](const double& x) { each.push_back(x); });
      EXPECT_TRUE(each == xs) << "chunk " << chunk << ", n " << n;
    }
  }
}

TEST(SpillVector, ChunksOfAnOddSizedStruct) {
  struct Odd {
    std::uint16_t a;
    std::uint8_t b[3];
  };
  static_assert(sizeof(Odd) == 6);  // padded, and not a divisor of the default memory size
  SpillVector<Odd> v(elements(4, sizeof(Odd)));
  std::vector<Odd> xs;
  for (std::uint16_t i = 0; i < 23; ++i) {
    Odd o{};
    o.a = static_cast<std::uint16_t>(1000 + i);
    for (std::uint8_t k = 0; k < 3; ++k) o.b[k] = static_cast<std::uint8_t>(i * 7 + k);
    xs.push_back(o);
    v.push_back(o);
  }
  ASSERT_EQ(v.chunk(), 4u);
  std::size_t i = 0;
  v.for_each([&](const Odd& o) {
    ASSERT_LT(i, xs.size());
    EXPECT_EQ(o.a, xs[i].a);
    for (std::size_t k = 0; k < 3; ++k) EXPECT_EQ(o.b[k], xs[i].b[k]);
    ++i;
  });
  EXPECT_EQ(i, xs.size());
  for (std::size_t j = 0; j < xs.size(); ++j) EXPECT_EQ(v.at(j).a, xs[j].a);
}

// --- Reader --------------------------------------------------------------------------------------

TEST(SpillReader, PeekAndNextAcrossChunks) {
  for (const std::size_t chunk : {std::size_t{1}, std::size_t{3}, std::size_t{5}}) {
    for (const std::size_t n : {std::size_t{0}, std::size_t{1}, chunk, chunk + 1, 3 * chunk, 3 * chunk + 2}) {
      const std::vector<double> xs = random_doubles(n, static_cast<std::uint32_t>(200 + n));
      const SpillVector<double> v = make(xs, elements(chunk, sizeof(double)));
      SpillVector<double>::Reader r(v);
      for (std::size_t i = 0; i < n; ++i) {
        ASSERT_FALSE(r.done()) << "chunk " << chunk << ", n " << n << ", i " << i;
        ASSERT_EQ(r.position(), i);
        ASSERT_EQ(r.peek(), xs[i]);
        ASSERT_EQ(r.peek(), xs[i]);  // peek does not consume
        ASSERT_EQ(r.position(), i);
        ASSERT_EQ(r.next(), xs[i]);
        ASSERT_EQ(r.position(), i + 1);
      }
      EXPECT_TRUE(r.done());
      EXPECT_EQ(r.position(), n);
    }
  }
}

TEST(SpillReader, NextWithoutPeek) {
  const std::vector<double> xs = random_doubles(50, 8);
  const SpillVector<double> v = make(xs, elements(7, sizeof(double)));
  SpillVector<double>::Reader r(v);
  std::vector<double> seen;
  while (!r.done()) seen.push_back(r.next());
  EXPECT_TRUE(seen == xs);
}

TEST(SpillReader, TwoReadersInLockstep) {
  const std::vector<double> xs = random_doubles(40, 9);
  const SpillVector<double> v = make(xs, elements(3, sizeof(double)));
  SpillVector<double>::Reader a(v);
  SpillVector<double>::Reader b(v);
  for (std::size_t i = 0; i < xs.size(); ++i) {
    ASSERT_EQ(a.peek(), xs[i]);
    ASSERT_EQ(b.peek(), xs[i]);
    ASSERT_EQ(a.next(), b.next());
    ASSERT_EQ(a.position(), b.position());
  }
  EXPECT_TRUE(a.done());
  EXPECT_TRUE(b.done());
}

TEST(SpillReader, TwoReadersApart) {
  // b trails a by more than a chunk: each reader's buffer is its own.
  const std::vector<double> xs = random_doubles(60, 10);
  const SpillVector<double> v = make(xs, elements(4, sizeof(double)));
  SpillVector<double>::Reader a(v);
  SpillVector<double>::Reader b(v);
  const std::size_t lag = 6;
  for (std::size_t i = 0; i < lag; ++i) ASSERT_EQ(a.next(), xs[i]);
  for (std::size_t i = lag; i < xs.size(); ++i) {
    ASSERT_EQ(a.peek(), xs[i]);
    ASSERT_EQ(b.peek(), xs[i - lag]);
    ASSERT_EQ(a.next(), xs[i]);
    ASSERT_EQ(b.next(), xs[i - lag]);
  }
  EXPECT_TRUE(a.done());
  for (std::size_t i = xs.size() - lag; i < xs.size(); ++i) ASSERT_EQ(b.next(), xs[i]);
  EXPECT_TRUE(b.done());
}

// --- sorted() ------------------------------------------------------------------------------------

TEST(SpillSorted, RandomDoubles) {
  const std::vector<double> xs = random_doubles(1000, 11);
  // One-element, three-element and larger chunks; several runs with refilled run buffers (chunk 1000,
  // 5 runs: 200 elements per buffer); the in-memory path (default config).
  for (const std::size_t chunk : {std::size_t{1}, std::size_t{3}, std::size_t{64}, std::size_t{300}}) {
    expect_sorted_like_stable_sort(xs, elements(chunk, sizeof(double)), std::less<double>());
  }
  const std::vector<double> ys = random_doubles(5000, 12);
  expect_sorted_like_stable_sort(ys, elements(1000, sizeof(double)), std::less<double>());
  expect_sorted_like_stable_sort(ys, elements(2600, sizeof(double)), std::less<double>());
  expect_sorted_like_stable_sort(ys, SpillConfig{}, std::less<double>());
}

TEST(SpillSorted, DescendingComparator) {
  const std::vector<double> xs = random_doubles(700, 13);
  expect_sorted_like_stable_sort(xs, elements(10, sizeof(double)), std::greater<double>());
  expect_sorted_like_stable_sort(xs, SpillConfig{}, std::greater<double>());
}

TEST(SpillSorted, DuplicatesKeepTheirOrder) {
  for (const std::int32_t distinct : {1, 2, 5, 50}) {
    const std::vector<Keyed> xs = keyed(2000, distinct, static_cast<std::uint32_t>(300 + distinct));
    for (const std::size_t chunk : {std::size_t{1}, std::size_t{7}, std::size_t{100}, std::size_t{1500}}) {
      expect_sorted_like_stable_sort(xs, elements(chunk, sizeof(Keyed)), kByKey);
    }
    expect_sorted_like_stable_sort(xs, SpillConfig{}, kByKey);
    // Directly: equal keys in increasing index.
    const SpillVector<Keyed> s = sorted(make(xs, elements(7, sizeof(Keyed))), kByKey);
    const std::vector<Keyed> out = collect(s);
    for (std::size_t i = 1; i < out.size(); ++i) {
      ASSERT_LE(out[i - 1].key, out[i].key);
      if (out[i - 1].key == out[i].key) {
        ASSERT_LT(out[i - 1].index, out[i].index) << "i " << i;
      }
    }
  }
}

TEST(SpillSorted, AlreadySortedAndReversed) {
  std::vector<Keyed> up = keyed(1000, 30, 14);
  std::stable_sort(up.begin(), up.end(), kByKey);
  std::vector<Keyed> down = up;
  std::reverse(down.begin(), down.end());
  for (const std::size_t chunk : {std::size_t{1}, std::size_t{3}, std::size_t{50}, std::size_t{999}}) {
    expect_sorted_like_stable_sort(up, elements(chunk, sizeof(Keyed)), kByKey);
    expect_sorted_like_stable_sort(down, elements(chunk, sizeof(Keyed)), kByKey);
  }
  expect_sorted_like_stable_sort(up, SpillConfig{}, kByKey);
  expect_sorted_like_stable_sort(down, SpillConfig{}, kByKey);
}

TEST(SpillSorted, EmptyAndSingle) {
  for (const SpillConfig& cfg : {elements(1, sizeof(double)), elements(3, sizeof(double)), SpillConfig{}}) {
    const SpillVector<double> empty(cfg);
    const SpillVector<double> s0 = sorted(empty, std::less<double>());
    EXPECT_EQ(s0.size(), 0u);
    EXPECT_TRUE(s0.empty());
    EXPECT_FALSE(s0.spilled());
    expect_sorted_like_stable_sort(std::vector<double>{}, cfg, std::less<double>());
    expect_sorted_like_stable_sort(std::vector<double>{-2.5}, cfg, std::less<double>());
    expect_sorted_like_stable_sort(std::vector<double>{3.0, -1.0}, cfg, std::less<double>());
  }
}

TEST(SpillSorted, SizesAroundMultiplesOfTheChunk) {
  for (const std::size_t chunk : {std::size_t{1}, std::size_t{3}, std::size_t{16}, std::size_t{100}}) {
    for (const std::size_t runs : {std::size_t{1}, std::size_t{2}, std::size_t{5}}) {
      for (const std::size_t n : {runs * chunk - 1, runs * chunk, runs * chunk + 1}) {
        const std::vector<Keyed> xs = keyed(n, 4, static_cast<std::uint32_t>(400 + n));
        expect_sorted_like_stable_sort(xs, elements(chunk, sizeof(Keyed)), kByKey);
      }
    }
  }
}

TEST(SpillSorted, ManyShortRuns) {
  // 625 runs of 16: each run's read buffer is the 64-element floor, longer than the run.
  const std::vector<double> xs = random_doubles(10000, 15);
  expect_sorted_like_stable_sort(xs, elements(16, sizeof(double)), std::less<double>());
  const std::vector<Keyed> ks = keyed(10000, 20, 16);
  expect_sorted_like_stable_sort(ks, elements(16, sizeof(Keyed)), kByKey);
  // 157 runs of 64 (exactly the floor) and 79 runs of 128 (two buffer fills per run).
  expect_sorted_like_stable_sort(ks, elements(64, sizeof(Keyed)), kByKey);
  expect_sorted_like_stable_sort(ks, elements(128, sizeof(Keyed)), kByKey);
}

struct Sample {
  float level;
  std::int16_t channel;
  char tag;
};
bool operator==(const Sample& a, const Sample& b) {
  return a.level == b.level && a.channel == b.channel && a.tag == b.tag;
}

TEST(SpillSorted, StructWithCustomComparator) {
  // Channel descending, then level ascending; tag records the original order for stability.
  std::mt19937 rng(17);
  std::uniform_int_distribution<int> ch(0, 5);
  std::uniform_int_distribution<int> lv(0, 9);
  std::vector<Sample> xs(3000);
  for (std::size_t i = 0; i < xs.size(); ++i) {
    xs[i] = Sample{static_cast<float>(lv(rng)) * 0.25f, static_cast<std::int16_t>(ch(rng)),
                   static_cast<char>('a' + static_cast<int>(i % 26))};
  }
  const auto less = [](const Sample& a, const Sample& b) {
    if (a.channel != b.channel) return a.channel > b.channel;
    return a.level < b.level;
  };
  for (const std::size_t chunk : {std::size_t{1}, std::size_t{9}, std::size_t{200}, std::size_t{4000}}) {
    expect_sorted_like_stable_sort(xs, elements(chunk, sizeof(Sample)), less);
  }
}

TEST(SpillSorted, OutputIsASpillVectorLikeAnyOther) {
  const std::vector<double> xs = random_doubles(100, 18);
  const SpillVector<double> v = make(xs, elements(6, sizeof(double)));
  const SpillVector<double> s = sorted(v, std::less<double>());
  std::vector<double> expected = xs;
  std::stable_sort(expected.begin(), expected.end());
  ASSERT_EQ(s.size(), expected.size());
  EXPECT_TRUE(s.spilled());
  EXPECT_LE(s.memory().size(), s.chunk());
  for (std::size_t i = 0; i < expected.size(); ++i) ASSERT_EQ(s.at(i), expected[i]) << "i " << i;
  SpillVector<double>::Reader r(s);
  for (std::size_t i = 0; i < expected.size(); ++i) ASSERT_EQ(r.next(), expected[i]) << "i " << i;
  EXPECT_TRUE(r.done());
  // Sorting the sorted output again changes nothing.
  EXPECT_TRUE(collect(sorted(s, std::less<double>())) == expected);
}

// --- the spill file ------------------------------------------------------------------------------

TEST(SpillFile, SpillingLeavesTheDirectoryEmpty) {
  const TempDir dir;
  const std::vector<double> xs = random_doubles(500, 19);
  {
    SpillVector<double> v(elements(8, sizeof(double), dir.path()));
    for (double x : xs) v.push_back(x);
    ASSERT_TRUE(v.spilled());
    EXPECT_TRUE(entries(dir.path()).empty());
    // The file is there nonetheless: an open descriptor into dir.
    EXPECT_TRUE(fds_in_are(dir.path(), 1));
    const SpillVector<double> s = sorted(v, std::less<double>());
    ASSERT_TRUE(s.spilled());
    EXPECT_TRUE(entries(dir.path()).empty());
    EXPECT_TRUE(fds_in_are(dir.path(), 2));  // v's and s's (the runs file is closed)
    std::vector<double> expected = xs;
    std::stable_sort(expected.begin(), expected.end());
    EXPECT_TRUE(collect(s) == expected);
    EXPECT_TRUE(collect(v) == xs);
  }
  EXPECT_TRUE(entries(dir.path()).empty());
  EXPECT_TRUE(fds_in_are(dir.path(), 0));  // closed with the vectors
}

TEST(SpillFile, NothingIsCreatedBeforeTheFirstSpill) {
  const TempDir dir;
  SpillVector<double> v(elements(4, sizeof(double), dir.path()));
  for (int i = 0; i < 4; ++i) v.push_back(i);
  EXPECT_FALSE(v.spilled());
  EXPECT_TRUE(fds_in_are(dir.path(), 0));
  v.push_back(4);
  EXPECT_TRUE(v.spilled());
  EXPECT_TRUE(fds_in_are(dir.path(), 1));
  EXPECT_TRUE(entries(dir.path()).empty());
}

TEST(SpillFile, EmptyDirMeansTmpdir) {
  const TempDir dir;
  const ScopedEnv env("TMPDIR", dir.path());
  const std::vector<double> xs = random_doubles(30, 20);
  const SpillVector<double> v = make(xs, elements(3, sizeof(double)));
  ASSERT_TRUE(v.spilled());
  EXPECT_TRUE(entries(dir.path()).empty());
  EXPECT_TRUE(fds_in_are(dir.path(), 1));
  EXPECT_TRUE(collect(v) == xs);
}

// --- errors --------------------------------------------------------------------------------------

TEST(SpillErrors, MissingDirectoryThrowsAtTheFirstSpill) {
  const TempDir parent;
  const std::string missing = parent.path() + "/no-such-dir";
  SpillVector<double> v(elements(3, sizeof(double), missing));  // construction does not touch the disk
  v.push_back(1.0);
  v.push_back(2.0);
  v.push_back(3.0);  // a full chunk, still in memory
  EXPECT_FALSE(v.spilled());
  try {
    v.push_back(4.0);
    ADD_FAILURE() << "no ptda::Error at the first spill";
  } catch (const ptda::Error& e) {
    EXPECT_NE(std::string(e.what()).find(missing), std::string::npos) << e.what();
  }
  // Nothing was created and the vector still holds what it held.
  EXPECT_TRUE(entries(parent.path()).empty());
  EXPECT_FALSE(v.spilled());
  EXPECT_EQ(v.size(), 3u);
  EXPECT_EQ(v.at(0), 1.0);
  EXPECT_EQ(v.at(2), 3.0);
  EXPECT_THROW(v.push_back(4.0), ptda::Error);  // still unusable, still an Error
}

TEST(SpillErrors, OneByteChunksThrowAtTheSecondPush) {
  const TempDir parent;
  const std::string missing = parent.path() + "/gone";
  SpillConfig cfg;
  cfg.dir = missing;
  cfg.memory_bytes = 1;
  SpillVector<double> v(cfg);
  EXPECT_NO_THROW(v.push_back(1.0));
  EXPECT_THROW(v.push_back(2.0), ptda::Error);
}

TEST(SpillErrors, MissingTmpdirIsNamed) {
  const TempDir parent;
  const std::string missing = parent.path() + "/no-tmpdir";
  const ScopedEnv env("TMPDIR", missing);
  SpillVector<double> v(elements(2, sizeof(double)));
  v.push_back(1.0);
  v.push_back(2.0);
  try {
    v.push_back(3.0);
    ADD_FAILURE() << "no ptda::Error at the first spill";
  } catch (const ptda::Error& e) {
    EXPECT_NE(std::string(e.what()).find(missing), std::string::npos) << e.what();
  }
}

TEST(SpillErrors, SortThrowsWhenTheDirectoryIsGone) {
  // The input spilled into dir, which is then removed (possible: the file is anonymous); sorted() needs
  // a new file for its runs and must report the directory.
  std::optional<TempDir> dir;
  dir.emplace();
  const std::string path = dir->path();
  const std::vector<double> xs = random_doubles(20, 21);
  const SpillVector<double> v = make(xs, elements(4, sizeof(double), path));
  ASSERT_TRUE(v.spilled());
  ASSERT_EQ(::rmdir(path.c_str()), 0) << "the spill directory is not empty";
  try {
    (void)sorted(v, std::less<double>());
    ADD_FAILURE() << "no ptda::Error";
  } catch (const ptda::Error& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
  }
  // The input is still readable from its open file.
  EXPECT_TRUE(collect(v) == xs);
  dir.reset();
}

}  // namespace
}  // namespace ptda::dsp
