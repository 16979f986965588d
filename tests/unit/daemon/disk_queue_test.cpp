// The store-and-forward queue (daemon/mqtt/disk_queue.hpp): order, acknowledgement across restarts,
// crash recovery (torn tail, corrupt record, a process killed without closing), the size bound and what
// it drops.
#include "mqtt/disk_queue.hpp"

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "ptda/common/error.hpp"

namespace fs = std::filesystem;

namespace ptda::daemon {
namespace {

fs::path scratch(const std::string& name) {
  const char* base = std::getenv("PTDA_TEST_TMP");
  const fs::path dir = fs::path(base != nullptr ? base : "/tmp") / "disk_queue_test" / name;
  fs::remove_all(dir);
  return dir;
}

DiskQueueConfig small(const fs::path& dir) {
  DiskQueueConfig c;
  c.dir = dir;
  c.segment_bytes = 4096;
  c.max_bytes = 4 * 4096;
  return c;
}

std::vector<fs::path> segments(const fs::path& dir) {
  std::vector<fs::path> out;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (e.path().extension() == ".q") out.push_back(e.path());
  }
  std::sort(out.begin(), out.end());
  return out;
}

std::uint64_t files_bytes(const fs::path& dir) {
  std::uint64_t b = 0;
  for (const fs::path& p : segments(dir)) b += fs::file_size(p);
  return b;
}

/// Delivers (front + ack) everything pending; returns the payloads in order.
std::vector<std::string> drain(DiskQueue& q) {
  std::vector<std::string> out;
  QueuedEvent e;
  while (q.front(e)) {
    out.push_back(e.payload);
    q.ack(e.seq);
  }
  return out;
}

TEST(DiskQueue, DeliversInOrderAndRemembersAcknowledgementsAcrossRestarts) {
  const fs::path dir = scratch("order");
  {
    DiskQueue q(small(dir));
    EXPECT_EQ(q.append(EventKind::kState, "s1"), 1U);
    EXPECT_EQ(q.append(EventKind::kAlarm, "a2"), 2U);
    EXPECT_EQ(q.append(EventKind::kSummary, "w3"), 3U);
    EXPECT_EQ(q.append(EventKind::kFault, "f4"), 4U);
    QueuedEvent e;
    ASSERT_TRUE(q.front(e));
    EXPECT_EQ(e.seq, 1U);
    EXPECT_EQ(e.kind, EventKind::kState);
    EXPECT_EQ(e.payload, "s1");
    q.ack(1);
    ASSERT_TRUE(q.front(e));
    EXPECT_THROW(q.ack(3), Error);  // only the front can be acknowledged
    q.ack(2);
    EXPECT_EQ(q.pending(), 2U);
  }
  DiskQueue q(small(dir));  // a restart: the acknowledged ones are not sent again
  EXPECT_EQ(q.pending(), 2U);
  EXPECT_EQ(q.next_seq(), 5U);
  EXPECT_EQ(q.append(EventKind::kAlarm, "a5"), 5U);
  EXPECT_EQ(drain(q), (std::vector<std::string>{"w3", "f4", "a5"}));
  EXPECT_EQ(q.counters().acked, 3U);
}

TEST(DiskQueue, ATornLastRecordIsCutAndCountedTheRestDelivered) {
  const fs::path dir = scratch("torn");
  {
    DiskQueue q(small(dir));
    for (int i = 1; i <= 3; ++i) q.append(EventKind::kAlarm, "alarm " + std::to_string(i));
  }
  // A crash in the middle of the 4th append: its first 13 bytes reached the file.
  {
    std::ofstream out(segments(dir).back(), std::ios::binary | std::ios::app);
    out.write("PTQ1\x05\x00\x00\x00\x04\x00\x00\x00\x00", 13);
  }
  DiskQueue q(small(dir));
  EXPECT_EQ(q.counters().torn_bytes, 13U);
  EXPECT_EQ(q.pending(), 3U);
  EXPECT_EQ(q.append(EventKind::kAlarm, "alarm 4"), 4U);
  EXPECT_EQ(drain(q), (std::vector<std::string>{"alarm 1", "alarm 2", "alarm 3", "alarm 4"}));
}

TEST(DiskQueue, ACorruptRecordInAnOlderSegmentIsCounted) {
  const fs::path dir = scratch("corrupt");
  const std::string big(1500, 'x');
  {
    DiskQueue q(small(dir));
    for (int i = 1; i <= 6; ++i) q.append(EventKind::kAlarm, std::to_string(i) + big);  // 2 per segment
  }
  const std::vector<fs::path> segs = segments(dir);
  ASSERT_EQ(segs.size(), 3U);
  {
    std::fstream f(segs[0], std::ios::binary | std::ios::in | std::ios::out);
    f.seekp(1524 + 30);  // inside the second record's payload: its CRC no longer matches
    f.put('!');
  }
  DiskQueue q(small(dir));
  EXPECT_EQ(q.counters().corrupt_records, 1U);
  std::vector<std::string> got = drain(q);
  ASSERT_EQ(got.size(), 5U);
  EXPECT_EQ(got.front().substr(0, 1), "1");
  EXPECT_EQ(got[1].substr(0, 1), "3");  // the corrupt second is not delivered
}

TEST(DiskQueue, AKilledProcessLosesNoAlarm) {
  const fs::path dir = scratch("killed");
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    DiskQueue q(small(dir));
    for (int i = 1; i <= 20; ++i) q.append(EventKind::kAlarm, "alarm " + std::to_string(i));
    std::_Exit(0);  // no destructor, no close: as kill -9 right after the last append returned
  }
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status));
  DiskQueue q(small(dir));
  const std::vector<std::string> got = drain(q);
  ASSERT_EQ(got.size(), 20U);
  for (int i = 0; i < 20; ++i) EXPECT_EQ(got[static_cast<std::size_t>(i)], "alarm " + std::to_string(i + 1));
}

TEST(DiskQueue, TheBoundDropsSummariesBeforeAnyAlarm) {
  const fs::path dir = scratch("bound");
  const DiskQueueConfig c = small(dir);
  DiskQueue q(c);
  const std::string summary(200, 's');
  std::vector<std::string> alarms;
  for (int i = 0; i < 400; ++i) {
    if (i % 10 == 0) {
      alarms.push_back("alarm " + std::to_string(i));
      EXPECT_GT(q.append(EventKind::kAlarm, alarms.back()), 0U);
    } else {
      q.append(EventKind::kSummary, summary);
    }
    ASSERT_LE(files_bytes(dir), c.max_bytes) << "after event " << i;
    ASSERT_EQ(q.bytes(), files_bytes(dir));
  }
  EXPECT_GT(q.counters().dropped_summaries, 0U);
  EXPECT_GT(q.counters().compactions, 0U);
  EXPECT_EQ(q.counters().dropped_events, 0U);
  std::vector<std::string> got_alarms;
  std::size_t summaries = 0;
  for (const std::string& p : drain(q)) {
    if (p == summary) {
      ++summaries;
    } else {
      got_alarms.push_back(p);
    }
  }
  EXPECT_EQ(got_alarms, alarms);  // every alarm, in order
  EXPECT_EQ(summaries + q.counters().dropped_summaries, 360U);
}

// The MQTT publisher's summary queue holds summaries only: full, the oldest go (a segment's worth at a
// time), the newest are kept in order, every drop counted.
TEST(DiskQueue, ASummaryOnlyQueueDropsTheOldestAndKeepsTheNewestInOrder) {
  const fs::path dir = scratch("summaries");
  const DiskQueueConfig c = small(dir);
  std::uint64_t acked = 0;
  {
    DiskQueue q(c);
    for (int i = 1; i <= 400; ++i) {
      ASSERT_EQ(q.append(EventKind::kSummary, "summary " + std::to_string(i) + std::string(180, 's')),
                static_cast<std::uint64_t>(i));
      ASSERT_LE(files_bytes(dir), c.max_bytes) << "after summary " << i;
      if (i == 3) {  // one delivered early: not counted as a drop
        QueuedEvent e;
        ASSERT_TRUE(q.front(e));
        EXPECT_EQ(q.front_seq(), 1U);
        q.ack(e.seq);
        ++acked;
      }
    }
    EXPECT_GT(q.counters().dropped_summaries, 0U);
    EXPECT_EQ(q.counters().dropped_events, 0U);
    EXPECT_EQ(q.pending() + q.counters().dropped_summaries + acked, 400U);
  }
  DiskQueue q(c);  // after a restart: the same newest summaries, in order, ending at the last one
  const std::size_t pending = q.pending();
  ASSERT_GT(pending, 10U);
  const std::vector<std::string> got = drain(q);
  ASSERT_EQ(got.size(), pending);
  for (std::size_t i = 0; i < got.size(); ++i) {
    EXPECT_EQ(got[i].substr(0, got[i].find('s', 1)), "summary " + std::to_string(400 - pending + 1 + i)) << i;
  }
}

TEST(DiskQueue, FullOfAlarmsTheOldestGoAndANewSummaryIsRefused) {
  const fs::path dir = scratch("full");
  const DiskQueueConfig c = small(dir);
  DiskQueue q(c);
  const std::string payload(900, 'a');
  for (int i = 0; i < 40; ++i) {
    q.append(EventKind::kAlarm, std::to_string(i) + payload);
    ASSERT_LE(files_bytes(dir), c.max_bytes);
  }
  EXPECT_GT(q.counters().dropped_events, 0U);
  // A summary larger than the room left: no summary to compact, so the summary is what goes.
  const std::string late(c.max_bytes - q.bytes(), 'l');
  EXPECT_EQ(q.append(EventKind::kSummary, late), 0U);
  EXPECT_EQ(q.counters().dropped_summaries, 1U);
  const std::vector<std::string> got = drain(q);
  ASSERT_FALSE(got.empty());
  EXPECT_EQ(got.size() + q.counters().dropped_events, 40U);
  EXPECT_EQ(got.back().substr(0, 2), "39");  // the newest kept
}

TEST(DiskQueue, ARecordChangedOnDiskIsNotDeliveredAndCrashLeftoversAreRemoved) {
  const fs::path dir = scratch("leftovers");
  {
    DiskQueue q(small(dir));
    q.append(EventKind::kAlarm, "first alarm");
  }
  const fs::path seg = segments(dir).front();
  // Leftovers of a compaction and of an ack rewrite that a crash interrupted.
  std::ofstream(seg.string() + ".tmp-abcdefghijkl") << "half a segment";
  std::ofstream(dir / "acked.tmp-abcdefghijkl") << "1";
  DiskQueue q(small(dir));
  EXPECT_FALSE(fs::exists(seg.string() + ".tmp-abcdefghijkl"));
  EXPECT_FALSE(fs::exists(dir / "acked.tmp-abcdefghijkl"));
  {
    std::fstream f(seg, std::ios::binary | std::ios::in | std::ios::out);
    f.seekp(20 + 3);  // inside the payload, after the queue read the file
    f.put('X');
  }
  QueuedEvent e;
  try {
    (void)q.front(e);
    FAIL() << "a changed record was delivered: " << e.payload;
  } catch (const Error& err) {
    EXPECT_NE(std::string(err.what()).find("event 1 at offset 0 does not read back"), std::string::npos)
        << err.what();
  }
}

TEST(DiskQueue, BadConfigurationAndPathsAreErrors) {
  const fs::path dir = scratch("errors");
  DiskQueueConfig c = small(dir);
  c.max_bytes = 4096;
  EXPECT_THROW(DiskQueue{c}, Error);
  fs::create_directories(dir);
  std::ofstream(dir / "acked") << "not a number";
  try {
    DiskQueue q(small(dir));
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find((dir / "acked").string() + ": not a sequence number"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace ptda::daemon
