// Offline containers whose memory does not grow with the data (up to the limit on sorted()): a
// SpillVector keeps at most
// SpillConfig::memory_bytes of its elements in memory and appends the rest to an anonymous file;
// sorted() sorts one with bounded memory (sorted runs on disk, then a k-way merge). Training uses them
// for its per-window values (docs/cli.md, `ptda train`, "Memory"). Offline code: every function
// allocates and throws ptda::Error (naming the directory and the system error) when the file cannot be
// created, written or read. Thread: one thread per container; readers of a container that is no longer
// appended to may run in any thread.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <queue>
#include <span>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace ptda::dsp {

struct SpillConfig {
  /// Where spill files are created (anonymous: nothing is left there once the process ends). Empty:
  /// $TMPDIR when set, else /tmp.
  std::string dir;
  /// Per container: the elements kept in memory (and the size of a read chunk) before it spills. A
  /// training keeps some 10 lists per class and a few readers alive at once: 32 KiB each keeps their sum
  /// to a few MiB, whatever the length (docs/benchmarks.md section 8, session 25).
  std::size_t memory_bytes = std::size_t{32} << 10;
};

namespace detail {

/// An anonymous file (O_TMPFILE, else mkostemp + unlink) created on the first append.
class SpillFile {
 public:
  explicit SpillFile(std::string dir) : dir_(std::move(dir)) {}
  ~SpillFile();
  SpillFile(const SpillFile&) = delete;
  SpillFile& operator=(const SpillFile&) = delete;
  SpillFile(SpillFile&& o) noexcept;
  SpillFile& operator=(SpillFile&& o) noexcept;

  /// Appends n bytes at the end. Throws ptda::Error.
  void append(const void* data, std::size_t n);
  /// Reads n bytes at off (off + n <= size()). Throws ptda::Error.
  void read(std::uint64_t off, void* data, std::size_t n) const;
  [[nodiscard]] std::uint64_t size() const noexcept { return size_; }
  /// The directory the file is (or would be) created in.
  [[nodiscard]] std::string directory() const;

 private:
  std::string dir_;
  int fd_ = -1;
  std::uint64_t size_ = 0;
};

}  // namespace detail

/// An append-only sequence of trivially copyable T: the first elements go to an anonymous file in
/// chunks, the newest (at most memory_bytes) stay in memory. Reading is sequential (for_each_chunk,
/// Reader) or one element at a time (at()).
template <class T>
class SpillVector {
  static_assert(std::is_trivially_copyable_v<T>, "SpillVector stores raw bytes");
  static_assert(std::is_default_constructible_v<T>, "reads fill default-constructed elements");

 public:
  explicit SpillVector(const SpillConfig& cfg = {})
      : cfg_(cfg), chunk_(std::max<std::size_t>(1, cfg.memory_bytes / sizeof(T))), file_(cfg.dir) {}
  SpillVector(const SpillVector&) = delete;
  SpillVector& operator=(const SpillVector&) = delete;
  /// A moved-from vector is empty (its file went with the elements).
  // NOLINTNEXTLINE(performance-move-constructor-init): the moved-from vector keeps its configuration
  SpillVector(SpillVector&& o) noexcept
      : cfg_(o.cfg_),
        chunk_(o.chunk_),
        file_(std::move(o.file_)),
        on_disk_(std::exchange(o.on_disk_, 0)),
        tail_(std::move(o.tail_)) {
    o.tail_.clear();
  }
  SpillVector& operator=(SpillVector&& o) noexcept {
    if (this != &o) {
      cfg_ = o.cfg_;
      chunk_ = o.chunk_;
      file_ = std::move(o.file_);
      on_disk_ = std::exchange(o.on_disk_, 0);
      tail_ = std::move(o.tail_);
      o.tail_.clear();
    }
    return *this;
  }
  ~SpillVector() = default;

  void push_back(const T& v) {
    if (tail_.size() == chunk_) {
      file_.append(tail_.data(), tail_.size() * sizeof(T));
      on_disk_ += tail_.size();
      tail_.clear();
    }
    if (tail_.size() == tail_.capacity()) {  // grow by doubling, never past one chunk
      tail_.reserve(std::min(chunk_, std::max<std::size_t>(16, 2 * tail_.capacity())));
    }
    tail_.push_back(v);
  }
  [[nodiscard]] std::size_t size() const noexcept { return on_disk_ + tail_.size(); }
  [[nodiscard]] bool empty() const noexcept { return size() == 0; }
  /// True when some elements are on disk: memory() then holds only the newest ones.
  [[nodiscard]] bool spilled() const noexcept { return on_disk_ > 0; }
  /// The elements in memory: all of them when !spilled().
  [[nodiscard]] std::span<const T> memory() const noexcept { return tail_; }
  /// Elements per chunk (in memory and per read).
  [[nodiscard]] std::size_t chunk() const noexcept { return chunk_; }
  [[nodiscard]] const SpillConfig& config() const noexcept { return cfg_; }

  /// Element i (< size()): one read from the file when it is on disk.
  [[nodiscard]] T at(std::size_t i) const {
    if (i >= on_disk_) return tail_[i - on_disk_];
    T v;
    file_.read(static_cast<std::uint64_t>(i) * sizeof(T), &v, sizeof(T));
    return v;
  }

  /// Calls f(std::span<const T>) on consecutive chunks, in order (at most chunk() elements each).
  template <class F>
  void for_each_chunk(F&& f) const {
    if (on_disk_ > 0) {
      std::vector<T> buf(std::min(chunk_, on_disk_));
      for (std::size_t i = 0; i < on_disk_; i += buf.size()) {
        const std::size_t n = std::min(buf.size(), on_disk_ - i);
        file_.read(static_cast<std::uint64_t>(i) * sizeof(T), buf.data(), n * sizeof(T));
        f(std::span<const T>(buf.data(), n));
      }
    }
    if (!tail_.empty()) f(std::span<const T>(tail_));
  }
  /// Calls f(const T&) on every element, in order.
  template <class F>
  void for_each(F&& f) const {
    for_each_chunk([&](std::span<const T> c) {
      for (const T& v : c) f(v);
    });
  }

  /// A sequential cursor (its own chunk buffer); the vector must outlive it and not grow meanwhile.
  class Reader {
   public:
    explicit Reader(const SpillVector& v) : v_(&v) {}
    [[nodiscard]] bool done() const noexcept { return pos_ >= v_->size(); }
    [[nodiscard]] std::size_t position() const noexcept { return pos_; }
    /// The next element without consuming it (!done()).
    [[nodiscard]] const T& peek() {
      if (pos_ >= v_->on_disk_) return v_->tail_[pos_ - v_->on_disk_];
      if (pos_ < buf_first_ || pos_ >= buf_first_ + buf_.size()) {
        buf_first_ = pos_;
        buf_.resize(std::min(v_->chunk_, v_->on_disk_ - pos_));
        v_->file_.read(static_cast<std::uint64_t>(pos_) * sizeof(T), buf_.data(), buf_.size() * sizeof(T));
      }
      return buf_[pos_ - buf_first_];
    }
    /// The next element (!done()).
    T next() {
      const T v = peek();
      ++pos_;
      return v;
    }

   private:
    const SpillVector* v_;
    std::size_t pos_ = 0;
    std::size_t buf_first_ = 0;
    std::vector<T> buf_;
  };

 private:
  SpillConfig cfg_;
  std::size_t chunk_;
  detail::SpillFile file_;
  std::size_t on_disk_ = 0;
  std::vector<T> tail_;
};

/// A stably sorted copy of v (equal elements keep their order), in bounded memory: runs of chunk()
/// elements are sorted in memory and written to one file, then merged. Memory: about two chunks plus
/// a read buffer per run of at least 64 elements, i.e. bounded by the chunk up to chunk^2 / 64
/// elements (262 144 doubles with the default 32 KiB: 3 days of windows at one a second; a year of them,
/// 31.5 million, takes 7700 runs and 3.9 MiB of run buffers).
template <class T, class Less>
[[nodiscard]] SpillVector<T> sorted(const SpillVector<T>& v, Less less) {
  SpillVector<T> out(v.config());
  if (!v.spilled()) {
    std::vector<T> all(v.memory().begin(), v.memory().end());
    std::stable_sort(all.begin(), all.end(), less);
    for (const T& x : all) out.push_back(x);
    return out;
  }
  // Runs: each chunk sorted and appended to one file; run r is [run_begin[r], run_begin[r + 1]).
  detail::SpillFile runs(v.config().dir);
  std::vector<std::size_t> run_begin{0};
  {
    std::vector<T> buf;
    v.for_each_chunk([&](std::span<const T> c) {
      buf.assign(c.begin(), c.end());
      std::stable_sort(buf.begin(), buf.end(), less);
      runs.append(buf.data(), buf.size() * sizeof(T));
      run_begin.push_back(run_begin.back() + buf.size());
    });
  }
  const std::size_t n_runs = run_begin.size() - 1;
  const std::size_t per_run = std::max<std::size_t>(64, v.chunk() / n_runs);
  struct Cursor {
    std::size_t pos = 0, end = 0, buf_first = 0;
    std::vector<T> buf;
  };
  std::vector<Cursor> cur(n_runs);
  const auto fill = [&](Cursor& c) {
    c.buf_first = c.pos;
    c.buf.resize(std::min(per_run, c.end - c.pos));
    runs.read(static_cast<std::uint64_t>(c.pos) * sizeof(T), c.buf.data(), c.buf.size() * sizeof(T));
  };
  // Min-heap on (element, run): ties go to the earlier run, which keeps the sort stable.
  const auto after = [&](std::size_t a, std::size_t b) {
    const T& x = cur[a].buf[cur[a].pos - cur[a].buf_first];
    const T& y = cur[b].buf[cur[b].pos - cur[b].buf_first];
    if (less(y, x)) return true;
    if (less(x, y)) return false;
    return a > b;
  };
  std::priority_queue<std::size_t, std::vector<std::size_t>, decltype(after)> heap(after);
  for (std::size_t r = 0; r < n_runs; ++r) {
    cur[r].pos = run_begin[r];
    cur[r].end = run_begin[r + 1];
    if (cur[r].pos < cur[r].end) {
      fill(cur[r]);
      heap.push(r);
    }
  }
  while (!heap.empty()) {
    const std::size_t r = heap.top();
    heap.pop();
    Cursor& c = cur[r];
    out.push_back(c.buf[c.pos - c.buf_first]);
    ++c.pos;
    if (c.pos < c.end) {
      if (c.pos >= c.buf_first + c.buf.size()) fill(c);
      heap.push(r);
    }
  }
  return out;
}

}  // namespace ptda::dsp
