// Store-and-forward queue of events the daemon could not deliver yet (issue 15 item 2): a bounded,
// crash-safe log of records on disk, delivered in order and acknowledged one by one.
//
//   DIR/seg-<first seq, 16 hex>.q   segments of at most segment_bytes, oldest first
//   DIR/acked                       the highest acknowledged sequence number (atomic, durable rewrite)
//
// Record: magic "PTQ1" (u32 LE), payload length (u32), sequence (u64), kind (u8), 3 zero bytes,
// payload, CRC-32 (u32, IEEE as zlib) of everything before it. Little-endian.
//
// Durability: a record of kind alarm, fault or state is fsync'ed before append() returns; summaries are
// fsync'ed with the next durable record, at a segment change and at close (a crash loses at most the
// summaries since the last fsync, never an alarm). On open, a torn record at the end of the newest
// segment (a crash mid-append) is cut off; a corrupt record elsewhere ends that segment's readable part.
// Both are counted, never silently skipped.
//
// Bound: the queue's files never exceed max_bytes. When a record does not fit, whole acknowledged
// segments go first, then the oldest segments lose their undelivered summaries (rewritten without
// them); alarms, faults and state changes are dropped only when nothing else is left, and counted apart.
//
// Delivery is at least once: after a crash between a publish and its ack the event is sent again with
// the same sequence number, which the receiver uses to drop the duplicate.
//
// Thread: one thread owns a DiskQueue (the MQTT publisher's). It allocates and blocks on I/O: never use it
// from a real-time thread.
#pragma once

#include <cstdint>
#include <deque>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace ptda::daemon {

enum class EventKind : std::uint8_t { kAlarm = 1, kFault = 2, kState = 3, kSummary = 4 };
[[nodiscard]] const char* event_kind_name(EventKind k) noexcept;

struct DiskQueueConfig {
  std::filesystem::path dir;
  std::uint64_t max_bytes = 64ULL << 20U;     ///< all segment files together
  std::uint64_t segment_bytes = 1ULL << 20U;  ///< a new segment starts past this size
};

struct DiskQueueCounters {
  std::uint64_t appended = 0;
  std::uint64_t acked = 0;
  std::uint64_t dropped_summaries = 0;  ///< undelivered summaries removed to make room
  std::uint64_t dropped_events = 0;     ///< undelivered alarms/faults/states removed (queue full of them)
  std::uint64_t torn_bytes = 0;         ///< cut from the newest segment's end on open (crash mid-append)
  std::uint64_t corrupt_records = 0;    ///< bad magic, length or CRC found on open (rest of segment unread)
  std::uint64_t compactions = 0;        ///< segments rewritten without their summaries
};

struct QueuedEvent {
  std::uint64_t seq = 0;
  EventKind kind = EventKind::kSummary;
  std::string payload;
};

class DiskQueue {
 public:
  /// Opens DIR (created 0750 when missing) and recovers what is in it. Throws ptda::Error naming the
  /// path when the directory or a segment cannot be read or written.
  explicit DiskQueue(DiskQueueConfig cfg);
  ~DiskQueue();
  DiskQueue(const DiskQueue&) = delete;
  DiskQueue& operator=(const DiskQueue&) = delete;

  /// Appends an event and returns its sequence number (0 when it was a summary dropped because the queue
  /// holds only undelivered alarms, faults and states). Throws ptda::Error on an I/O failure (the event
  /// is not queued).
  std::uint64_t append(EventKind kind, std::string_view payload);
  /// The oldest undelivered event; false when none.
  [[nodiscard]] bool front(QueuedEvent& out) const;
  /// Acknowledges the front event (its sequence number): it is not delivered again, not even after a
  /// restart. Acknowledging anything but the front is a logic error (ptda::Error).
  void ack(std::uint64_t seq);

  /// The oldest undelivered event's sequence number, 0 when none (no file access). Thread: the owner.
  [[nodiscard]] std::uint64_t front_seq() const noexcept { return index_.empty() ? 0 : index_.front().seq; }
  [[nodiscard]] std::size_t pending() const noexcept { return index_.size(); }
  [[nodiscard]] std::uint64_t bytes() const noexcept;
  [[nodiscard]] std::uint64_t next_seq() const noexcept { return next_seq_; }
  [[nodiscard]] const DiskQueueCounters& counters() const noexcept { return counters_; }

 private:
  struct Segment {
    std::uint64_t first_seq = 0;
    std::filesystem::path path;
    std::uint64_t bytes = 0;
  };
  struct Entry {
    std::uint64_t seq = 0;
    EventKind kind = EventKind::kSummary;
    std::uint64_t segment = 0;  ///< the segment's first_seq
    std::uint64_t offset = 0;
    std::uint32_t len = 0;
  };

  void recover();
  void open_tail();
  void start_segment(std::uint64_t first_seq);
  void make_room(std::uint64_t need, EventKind incoming, bool& drop_incoming);
  bool compact_oldest_with_summaries();
  void drop_acked_segments();
  void persist_acked();
  void sync_tail() const;
  [[nodiscard]] const Segment& segment_of(const Entry& e) const;

  DiskQueueConfig cfg_;
  std::vector<Segment> segments_;
  std::deque<Entry> index_;  ///< undelivered events, oldest first
  int tail_fd_ = -1;
  mutable bool tail_dirty_ = false;  ///< summaries written since the last fsync
  std::uint64_t next_seq_ = 1;
  std::uint64_t acked_seq_ = 0;
  DiskQueueCounters counters_;
};

}  // namespace ptda::daemon
