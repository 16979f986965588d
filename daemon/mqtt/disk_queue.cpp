#include "mqtt/disk_queue.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <system_error>

#include "ptda/common/atomic_file.hpp"
#include "ptda/common/error.hpp"
#include "ptda/formats/baseline_file.hpp"

namespace ptda::daemon {
namespace {

namespace fs = std::filesystem;

constexpr std::uint32_t kMagic = 0x31515450;  // "PTQ1" little-endian
constexpr std::size_t kHeader = 20;           // magic, length, seq, kind + 3 zero bytes
constexpr std::size_t kTrailer = 4;           // CRC-32
constexpr std::uint32_t kMaxPayload = 1U << 20U;

std::string errno_text(int err) {
  return std::error_code(err, std::generic_category()).message();
}

void put_u32(unsigned char* p, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<unsigned char>(v >> (8 * i));
}
void put_u64(unsigned char* p, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) p[i] = static_cast<unsigned char>(v >> (8 * i));
}
std::uint32_t get_u32(const unsigned char* p) {
  std::uint32_t v = 0;
  for (int i = 0; i < 4; ++i) v |= static_cast<std::uint32_t>(p[i]) << (8 * i);
  return v;
}
std::uint64_t get_u64(const unsigned char* p) {
  std::uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v |= static_cast<std::uint64_t>(p[i]) << (8 * i);
  return v;
}

std::vector<unsigned char> encode(std::uint64_t seq, EventKind kind, std::string_view payload) {
  std::vector<unsigned char> r(kHeader + payload.size() + kTrailer, 0);
  put_u32(r.data(), kMagic);
  put_u32(r.data() + 4, static_cast<std::uint32_t>(payload.size()));
  put_u64(r.data() + 8, seq);
  r[16] = static_cast<unsigned char>(kind);
  std::memcpy(r.data() + kHeader, payload.data(), payload.size());
  put_u32(r.data() + kHeader + payload.size(), formats::crc32(r.data(), kHeader + payload.size()));
  return r;
}

void write_all(int fd, const unsigned char* p, std::size_t n, const fs::path& path) {
  while (n > 0) {
    const ssize_t w = ::write(fd, p, n);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) throw Error(path.string() + ": write failed: " + errno_text(w < 0 ? errno : EIO));
    p += w;
    n -= static_cast<std::size_t>(w);
  }
}

std::string segment_name(std::uint64_t first_seq) {
  char b[40];
  std::snprintf(b, sizeof b, "seg-%016llx.q", static_cast<unsigned long long>(first_seq));
  return b;
}

struct Parsed {
  std::uint64_t seq;
  EventKind kind;
  std::uint64_t offset;
  std::uint32_t len;
};

/// The valid records of a segment file from its start; `valid_end` = the offset after the last one.
std::vector<Parsed> parse_segment(const std::vector<unsigned char>& data, std::uint64_t& valid_end) {
  std::vector<Parsed> out;
  std::size_t at = 0;
  while (at + kHeader + kTrailer <= data.size()) {
    const unsigned char* p = data.data() + at;
    const std::uint32_t len = get_u32(p + 4);
    const auto kind = static_cast<EventKind>(p[16]);
    if (get_u32(p) != kMagic || len > kMaxPayload || at + kHeader + len + kTrailer > data.size()) break;
    if (p[16] < 1 || p[16] > 4) break;
    if (formats::crc32(p, kHeader + len) != get_u32(p + kHeader + len)) break;
    out.push_back({get_u64(p + 8), kind, at, len});
    at += kHeader + len + kTrailer;
  }
  valid_end = at;
  return out;
}

std::vector<unsigned char> read_file(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  if (!in) throw Error(p.string() + ": cannot open");
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace

const char* event_kind_name(EventKind k) noexcept {
  switch (k) {
    case EventKind::kAlarm:
      return "alarm";
    case EventKind::kFault:
      return "fault";
    case EventKind::kState:
      return "state";
    case EventKind::kSummary:
      return "summary";
  }
  return "?";
}

DiskQueue::DiskQueue(DiskQueueConfig cfg) : cfg_(std::move(cfg)) {
  if (cfg_.dir.empty()) throw Error("queue: empty directory path");
  if (cfg_.segment_bytes < 4096 || cfg_.max_bytes < 2 * cfg_.segment_bytes) {
    throw Error("queue " + cfg_.dir.string() + ": max_bytes must be at least 2 segments of >= 4096 bytes");
  }
  std::error_code ec;
  if (!fs::is_directory(cfg_.dir, ec)) {
    fs::create_directories(cfg_.dir, ec);
    if (ec) throw Error("queue " + cfg_.dir.string() + ": cannot create: " + ec.message());
    fs::permissions(cfg_.dir, fs::perms(0750), ec);
  }
  recover();
  open_tail();
}

DiskQueue::~DiskQueue() {
  if (tail_fd_ >= 0) {
    ::fsync(tail_fd_);
    ::close(tail_fd_);
  }
}

std::uint64_t DiskQueue::bytes() const noexcept {
  std::uint64_t b = 0;
  for (const Segment& s : segments_) b += s.bytes;
  return b;
}

const DiskQueue::Segment& DiskQueue::segment_of(const Entry& e) const {
  for (const Segment& s : segments_) {
    if (s.first_seq == e.segment) return s;
  }
  throw Error("queue " + cfg_.dir.string() + ": internal: no segment for event " + std::to_string(e.seq));
}

void DiskQueue::recover() {
  const fs::path acked = cfg_.dir / "acked";
  if (fs::exists(acked)) {
    const std::vector<unsigned char> t = read_file(acked);
    const std::string text(t.begin(), t.end());
    char* end = nullptr;
    acked_seq_ = std::strtoull(text.c_str(), &end, 10);
    if (end == text.c_str()) throw Error(acked.string() + ": not a sequence number: '" + text + "'");
  }
  std::vector<std::pair<std::uint64_t, fs::path>> found;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(cfg_.dir, ec)) {
    const std::string n = e.path().filename().string();
    if (n.size() != 22 || n.rfind("seg-", 0) != 0 || n.substr(20) != ".q") continue;
    found.emplace_back(std::strtoull(n.substr(4, 16).c_str(), nullptr, 16), e.path());
  }
  if (ec) throw Error("queue " + cfg_.dir.string() + ": cannot list: " + ec.message());
  std::sort(found.begin(), found.end());
  // Temporary files of a compaction or an ack rewrite that a crash interrupted (outside the bound).
  (void)remove_stale_temp_files(cfg_.dir.c_str(), "acked");
  for (const auto& f : found) (void)remove_stale_temp_files(cfg_.dir.c_str(), f.second.filename().native());
  next_seq_ = acked_seq_ + 1;
  for (std::size_t i = 0; i < found.size(); ++i) {
    const auto& [first, path] = found[i];
    const std::vector<unsigned char> data = read_file(path);
    std::uint64_t valid_end = 0;
    const std::vector<Parsed> recs = parse_segment(data, valid_end);
    if (valid_end < data.size()) {
      if (i + 1 == found.size()) {
        counters_.torn_bytes += data.size() - valid_end;  // a crash mid-append: cut it off
        if (::truncate(path.c_str(), static_cast<off_t>(valid_end)) != 0) {
          throw Error(path.string() + ": cannot cut the torn record: " + errno_text(errno));
        }
      } else {
        ++counters_.corrupt_records;
      }
    }
    // An older segment keeps its whole size in the bound (its unreadable rest is still on disk).
    Segment s{first, path, i + 1 == found.size() ? valid_end : static_cast<std::uint64_t>(data.size())};
    segments_.push_back(s);
    for (const Parsed& r : recs) {
      next_seq_ = std::max(next_seq_, r.seq + 1);
      if (r.seq <= acked_seq_) continue;
      index_.push_back({r.seq, r.kind, first, r.offset, r.len});
    }
  }
  drop_acked_segments();
}

void DiskQueue::open_tail() {
  if (segments_.empty() || segments_.back().bytes >= cfg_.segment_bytes) {
    start_segment(next_seq_);
    return;
  }
  tail_fd_ = ::open(segments_.back().path.c_str(), O_WRONLY | O_APPEND | O_CLOEXEC | O_NOFOLLOW);
  if (tail_fd_ < 0) throw Error(segments_.back().path.string() + ": cannot open: " + errno_text(errno));
}

void DiskQueue::start_segment(std::uint64_t first_seq) {
  sync_tail();
  if (tail_fd_ >= 0) ::close(tail_fd_);
  Segment s{first_seq, cfg_.dir / segment_name(first_seq), 0};
  tail_fd_ = ::open(s.path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_APPEND | O_CLOEXEC | O_NOFOLLOW, 0640);
  if (tail_fd_ < 0) throw Error(s.path.string() + ": cannot create: " + errno_text(errno));
  segments_.push_back(s);
  // The new name must survive a crash too.
  const int dfd = ::open(cfg_.dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd >= 0) {
    ::fsync(dfd);
    ::close(dfd);
  }
}

void DiskQueue::sync_tail() const {
  if (tail_fd_ >= 0 && tail_dirty_) {
    if (::fsync(tail_fd_) != 0) {
      throw Error(segments_.back().path.string() + ": fsync failed: " + errno_text(errno));
    }
  }
  tail_dirty_ = false;
}

std::uint64_t DiskQueue::append(EventKind kind, std::string_view payload) {
  if (payload.size() > kMaxPayload) {
    throw Error("queue: a " + std::string(event_kind_name(kind)) + " event of " +
                std::to_string(payload.size()) + " bytes is over the 1 MiB record limit");
  }
  const std::uint64_t need = kHeader + payload.size() + kTrailer;
  bool drop_incoming = false;
  make_room(need, kind, drop_incoming);
  if (drop_incoming) {
    ++counters_.dropped_summaries;
    return 0;
  }
  if (tail_fd_ < 0) open_tail();
  if (segments_.back().bytes + need > cfg_.segment_bytes && segments_.back().bytes > 0)
    start_segment(next_seq_);
  const std::uint64_t seq = next_seq_;
  const std::vector<unsigned char> rec = encode(seq, kind, payload);
  Segment& tail = segments_.back();
  try {
    write_all(tail_fd_, rec.data(), rec.size(), tail.path);
  } catch (const Error&) {
    // Part of the record may be in the file: cut it back so the next record lands where the index
    // says; if even that fails, continue in a new segment.
    if (::ftruncate(tail_fd_, static_cast<off_t>(tail.bytes)) != 0) {
      ::close(tail_fd_);
      tail_fd_ = -1;
      start_segment(next_seq_);
    }
    throw;
  }
  index_.push_back({seq, kind, tail.first_seq, tail.bytes, static_cast<std::uint32_t>(payload.size())});
  tail.bytes += rec.size();
  ++next_seq_;
  ++counters_.appended;
  tail_dirty_ = true;
  if (kind != EventKind::kSummary) sync_tail();  // an alarm is on disk before append() returns
  return seq;
}

bool DiskQueue::front(QueuedEvent& out) const {
  if (index_.empty()) return false;
  const Entry& e = index_.front();
  // A record leaves the queue only once it is on disk: after a crash its sequence number is never
  // given to another event (a receiver drops repeated numbers as duplicates).
  if (e.segment == segments_.back().first_seq) sync_tail();
  const Segment& s = segment_of(e);
  const int fd = ::open(s.path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw Error(s.path.string() + ": cannot open: " + errno_text(errno));
  std::vector<unsigned char> rec(kHeader + e.len + kTrailer);
  const ssize_t n = ::pread(fd, rec.data(), rec.size(), static_cast<off_t>(e.offset));
  const int err = errno;
  ::close(fd);
  if (n != static_cast<ssize_t>(rec.size())) {
    throw Error(s.path.string() + ": cannot read event " + std::to_string(e.seq) + ": " +
                errno_text(n < 0 ? err : EIO));
  }
  if (get_u32(rec.data()) != kMagic || get_u64(rec.data() + 8) != e.seq ||
      formats::crc32(rec.data(), kHeader + e.len) != get_u32(rec.data() + kHeader + e.len)) {
    throw Error(s.path.string() + ": event " + std::to_string(e.seq) + " at offset " +
                std::to_string(e.offset) + " does not read back (CRC or sequence mismatch)");
  }
  out.seq = e.seq;
  out.kind = e.kind;
  out.payload.assign(reinterpret_cast<const char*>(rec.data()) + kHeader, e.len);
  return true;
}

void DiskQueue::ack(std::uint64_t seq) {
  if (index_.empty() || index_.front().seq != seq) {
    throw Error("queue: ack of event " + std::to_string(seq) + ", but the front is " +
                (index_.empty() ? std::string("empty") : std::to_string(index_.front().seq)));
  }
  index_.pop_front();
  acked_seq_ = seq;
  ++counters_.acked;
  persist_acked();
  drop_acked_segments();
}

void DiskQueue::persist_acked() {
  const std::string text = std::to_string(acked_seq_) + "\n";
  AtomicWriteOptions opt;
  opt.mode = 0640;
  opt.durable = true;
  const fs::path p = cfg_.dir / "acked";
  const AtomicWriteResult r = write_file_atomic(p.c_str(), text.data(), text.size(), opt);
  if (!r.ok()) throw Error(p.string() + ": " + r.step + " failed: " + errno_text(r.err));
}

void DiskQueue::drop_acked_segments() {
  // Whole segments every record of which is acknowledged, except the one being appended to.
  while (segments_.size() > 1) {
    const Segment& s = segments_.front();
    const std::uint64_t next_first = segments_[1].first_seq;
    const bool pending_here = !index_.empty() && index_.front().segment == s.first_seq;
    if (pending_here || next_first - 1 > acked_seq_) break;
    std::error_code ec;
    fs::remove(s.path, ec);
    segments_.erase(segments_.begin());
  }
}

void DiskQueue::make_room(std::uint64_t need, EventKind incoming, bool& drop_incoming) {
  while (bytes() + need > cfg_.max_bytes) {
    drop_acked_segments();
    if (bytes() + need <= cfg_.max_bytes) return;
    if (compact_oldest_with_summaries()) continue;
    if (incoming == EventKind::kSummary) {
      drop_incoming = true;
      return;
    }
    // Only alarms, faults and states are left: the oldest goes (sized so that this does not happen
    // within 24 h of them; counted apart).
    if (index_.empty() || segments_.size() < 2) {
      throw Error("queue " + cfg_.dir.string() + ": full, and nothing can be dropped for a " +
                  event_kind_name(incoming) + " event");
    }
    const Segment oldest = segments_.front();
    std::uint64_t dropped = 0;
    while (!index_.empty() && index_.front().segment == oldest.first_seq) {
      index_.pop_front();
      ++dropped;
    }
    counters_.dropped_events += dropped;
    acked_seq_ = std::max(acked_seq_, segments_[1].first_seq - 1);  // skipped, not delivered
    persist_acked();
    drop_acked_segments();
  }
}

bool DiskQueue::compact_oldest_with_summaries() {
  for (std::size_t i = 0; i < segments_.size(); ++i) {
    Segment& s = segments_[i];
    const bool has_summary = std::any_of(index_.begin(), index_.end(), [&](const Entry& e) {
      return e.segment == s.first_seq && e.kind == EventKind::kSummary;
    });
    if (!has_summary) continue;
    const bool is_tail = i + 1 == segments_.size();
    if (is_tail) {
      sync_tail();
      ::close(tail_fd_);
      tail_fd_ = -1;
    }
    // The tail is reopened whatever happens below (a failed rewrite must not leave appends on a closed
    // descriptor).
    struct Reopen {
      DiskQueue* q;
      bool on;
      ~Reopen() {
        if (on && q->tail_fd_ < 0) {
          try {
            q->open_tail();
          } catch (const Error&) {  // append() tries again and reports it
          }
        }
      }
    } reopen{this, is_tail};
    const std::vector<unsigned char> data = read_file(s.path);
    std::vector<unsigned char> kept;
    std::deque<Entry> index;
    std::uint64_t dropped = 0;
    for (const Entry& e : index_) {
      if (e.segment != s.first_seq) {
        index.push_back(e);
        continue;
      }
      if (e.kind == EventKind::kSummary) {
        ++dropped;
        continue;
      }
      Entry moved = e;
      moved.offset = kept.size();
      kept.insert(kept.end(), data.begin() + static_cast<std::ptrdiff_t>(e.offset),
                  data.begin() + static_cast<std::ptrdiff_t>(e.offset + kHeader + e.len + kTrailer));
      index.push_back(moved);
    }
    AtomicWriteOptions opt;
    opt.mode = 0640;
    opt.durable = true;
    const AtomicWriteResult r = write_file_atomic(s.path.c_str(), kept.data(), kept.size(), opt);
    if (!r.ok()) throw Error(s.path.string() + ": compaction " + r.step + " failed: " + errno_text(r.err));
    std::sort(index.begin(), index.end(), [](const Entry& a, const Entry& b) { return a.seq < b.seq; });
    index_ = std::move(index);
    s.bytes = kept.size();
    counters_.dropped_summaries += dropped;
    ++counters_.compactions;
    return true;
  }
  return false;
}

}  // namespace ptda::daemon
