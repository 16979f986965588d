#include "can/candump_replay_channel.hpp"

#include <gtest/gtest.h>
#include <malloc.h>
#include <unistd.h>

#include <array>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "alloc_counter.hpp"
#include "ptda/common/error.hpp"

namespace fs = std::filesystem;

namespace ptda::drivers {
namespace {

// 0x184 speed frames every 4 ms on can0, a frame on can1, a transmitted (T) frame, an error-passive
// error frame and a bus-off error frame.
constexpr const char* kLog =
    "# golden log: comment lines are ignored as by canplayer\n"
    "(1000.000000) can0 184#1027000000000000 R\n"
    "(1000.002000) can1 123#11 R\n"
    "(1000.004000) can0 184#2027000000000000 R\n"
    "(1000.005000) can0 3A0#0200FF0000000000 T\n"
    "(1000.006000) can0 20000004#0010000000000000 R\n"
    "(1000.008000) can0 184#3027000000000000 R\n"
    "(1000.012000) can0 20000040#0000000000000000 R\n";

class CandumpReplay : public ::testing::Test {
 protected:
  void SetUp() override {
    const char* base = std::getenv("PTDA_TEST_TMP");
    const fs::path root = base != nullptr ? fs::path(base) : fs::temp_directory_path();
    dir_ = root / ("candump_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) +
                   "_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    log_ = dir_ / "can.log";
    std::ofstream(log_) << kLog;
    cfg_.path = log_;
    cfg_.interface = "can0";
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path dir_, log_;
  CandumpReplayConfig cfg_;
};

TEST_F(CandumpReplay, AsFastAsPossibleMapsLogTimesOntoTheDaemonClock) {
  cfg_.pace = ReplayPace::kAsFastAsPossible;
  cfg_.timeline.origin_mono_ns = 7'000'000'000;
  ManualClock clock(0);
  CandumpReplayChannel ch(cfg_, clock);
  ch.configure();
  EXPECT_EQ(ch.frame_count(), 5u);  // can1 and the 'T' frame skipped
  ch.activate();
  std::array<CanFrame, 3> out{};
  std::size_t n = 0;
  ASSERT_EQ(ch.receive(out, n, 0), CanStatus::kOk);
  ASSERT_EQ(n, 3u);
  EXPECT_EQ(out[0].id, 0x184u);
  EXPECT_EQ(out[0].t_ns, 7'000'000'000);
  EXPECT_EQ(out[1].t_ns, 7'004'000'000);
  EXPECT_EQ(out[1].data[0], 0x20);
  EXPECT_TRUE(out[2].error());
  EXPECT_EQ(ch.bus_state(), CanBusState::kErrorPassive);
  ASSERT_EQ(ch.receive(out, n, 0), CanStatus::kOk);
  ASSERT_EQ(n, 2u);
  EXPECT_EQ(out[1].t_ns, 7'012'000'000);
  EXPECT_EQ(ch.bus_state(), CanBusState::kBusOff);
  EXPECT_EQ(ch.receive(out, n, 0), CanStatus::kEndOfStream);
  EXPECT_EQ(n, 0u);
  EXPECT_EQ(clock.now_ns(), 0);

  const CanCounters c = ch.counters();
  EXPECT_EQ(c.rx_frames, 5u);
  EXPECT_EQ(c.rx_error_frames, 2u);
  EXPECT_EQ(c.error_passive, 1u);
  EXPECT_EQ(c.bus_off, 1u);
}

// ptdad drains the replay in bursts after its own burst timer: a zero timeout polls and never sleeps.
TEST_F(CandumpReplay, ZeroTimeoutDrainsWhatIsDueWithoutSleeping) {
  ManualClock clock(100'000'000);
  CandumpReplayChannel ch(cfg_, clock);
  ch.configure();
  ch.activate();  // log 1000.000 at the clock's 0.1 s
  std::array<CanFrame, 8> out{};
  std::size_t n = 0;
  clock.advance_ns(9'000'000);  // a burst timer at +9 ms: the frames of 0, 4, 6 and 8 ms are due
  ASSERT_EQ(ch.receive(out, n, 0), CanStatus::kOk);
  EXPECT_EQ(n, 4u);
  EXPECT_EQ(ch.receive(out, n, 0), CanStatus::kTimeout);  // the 12 ms frame is not due yet
  EXPECT_EQ(n, 0u);
  EXPECT_EQ(clock.sleeps(), 0u);
  EXPECT_EQ(clock.now_ns(), 109'000'000);
}

TEST_F(CandumpReplay, RealTimeReleasesFramesWhenTheClockReachesThem) {
  ManualClock clock(100'000'000);
  CandumpReplayChannel ch(cfg_, clock);
  ch.configure();
  ch.activate();  // first frame (log 1000.000) at the clock's 0.1 s
  std::array<CanFrame, 8> out{};
  std::size_t n = 0;
  ASSERT_EQ(ch.receive(out, n, 0), CanStatus::kOk);
  ASSERT_EQ(n, 1u);
  EXPECT_EQ(out[0].t_ns, 100'000'000);
  // Next is due 4 ms later: a 1 ms timeout sleeps 1 ms and returns empty-handed.
  EXPECT_EQ(ch.receive(out, n, 1'000'000), CanStatus::kTimeout);
  EXPECT_EQ(n, 0u);
  EXPECT_EQ(clock.now_ns(), 101'000'000);
  ASSERT_EQ(ch.receive(out, n, 50'000'000), CanStatus::kOk);
  EXPECT_EQ(clock.now_ns(), 104'000'000);  // woke when due, released only what was due
  ASSERT_EQ(n, 1u);
  EXPECT_EQ(out[0].t_ns, 104'000'000);
  clock.set_ns(110'000'000);  // the reader fell behind: everything due comes at once
  ASSERT_EQ(ch.receive(out, n, 0), CanStatus::kOk);
  EXPECT_EQ(n, 2u);
  EXPECT_EQ(ch.position(), 4u);
}

TEST_F(CandumpReplay, SharedTimelineAndAllInterfaces) {
  cfg_.interface.clear();
  cfg_.skip_transmitted = false;
  cfg_.pace = ReplayPace::kAsFastAsPossible;
  cfg_.timeline.origin_unix_ns = 999'000'000'000;  // e.g. the WAV's start, 1 s before the log
  cfg_.timeline.origin_mono_ns = 0;
  ManualClock clock(0);
  CandumpReplayChannel ch(cfg_, clock);
  ch.configure();
  EXPECT_EQ(ch.frame_count(), 7u);
  ch.activate();
  std::array<CanFrame, 2> out{};
  std::size_t n = 0;
  ASSERT_EQ(ch.receive(out, n, 0), CanStatus::kOk);
  EXPECT_EQ(out[0].t_ns, 1'000'000'000);
  EXPECT_EQ(out[1].id, 0x123u);
  EXPECT_EQ(out[1].t_ns, 1'002'000'000);
}

TEST_F(CandumpReplay, SentFramesAreKeptUpToTheCapacity) {
  cfg_.tx_capacity = 2;
  ManualClock clock(5);
  CandumpReplayChannel ch(cfg_, clock);
  ch.configure();
  CanFrame f;
  f.id = 0x3A0;
  EXPECT_EQ(ch.send(f), CanStatus::kNotActive);
  ch.activate();
  EXPECT_EQ(ch.send(f), CanStatus::kOk);
  f.data[0] = 2;
  EXPECT_EQ(ch.send(f), CanStatus::kOk);
  EXPECT_EQ(ch.send(f), CanStatus::kTxFull);
  ASSERT_EQ(ch.sent_frames().size(), 2u);
  EXPECT_EQ(ch.sent_frames()[1].data[0], 2);
  EXPECT_EQ(ch.sent_frames()[1].t_ns, 5);
  EXPECT_EQ(ch.counters().tx_frames, 2u);
  EXPECT_EQ(ch.counters().tx_full, 1u);
}

TEST_F(CandumpReplay, ConfigureErrors) {
  ManualClock clock(0);
  std::ofstream(log_, std::ios::app) << "(1000.020000) can0 184#ZZ\n";
  CandumpReplayChannel malformed(cfg_, clock);
  try {
    malformed.configure();  // validated up front, not in the run state
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("can.log:9"), std::string::npos) << e.what();
  }
  CandumpReplayChannel not_configured(cfg_, clock);
  EXPECT_THROW(not_configured.activate(), Error);
  cfg_.path = dir_ / "missing.log";
  CandumpReplayChannel missing(cfg_, clock);
  EXPECT_THROW(missing.configure(), Error);
}

TEST_F(CandumpReplay, ReceiveNeverAllocates) {
  ManualClock clock(0);
  CandumpReplayChannel ch(cfg_, clock);
  ch.configure();
  ch.activate();
  std::array<CanFrame, 2> out{};
  std::size_t n = 0, total = 0;
  test::AllocScope scope;
  while (ch.receive(out, n, 1'000'000'000) == CanStatus::kOk) total += n;
  EXPECT_EQ(scope.count(), 0u);
  EXPECT_EQ(total, 5u);
}

// ---- the kernel timer's emulation (CAN_BCM TX_SETUP, Linux net/can/bcm.c) ------------------------

std::array<CanFrame, 3> cyclic_frames(std::uint8_t tag) {
  std::array<CanFrame, 3> f{};
  for (std::size_t i = 0; i < f.size(); ++i) {
    f[i].id = 0x3A0;
    f[i].len = 8;
    f[i].data[0] = static_cast<std::uint8_t>(i);  // the frame's place in the turn
    f[i].data[1] = tag;                           // the content
  }
  return f;
}

TEST_F(CandumpReplay, CyclicTransmissionFollowsTheKernelTimer) {
  cfg_.cyclic = true;
  ManualClock clock(1'000);
  CandumpReplayChannel ch(cfg_, clock);
  ch.configure();
  ch.activate();
  ASSERT_TRUE(ch.cyclic_supported());
  const auto a = cyclic_frames(0xA);
  CanCyclicTx tx;
  tx.frames = a;
  tx.period_ns = 100;
  tx.count = 5;
  // The first set-up starts the timer and sends one frame at once, whatever `start` says.
  ASSERT_EQ(ch.set_cyclic(tx), CanStatus::kOk);
  ASSERT_EQ(ch.sent_frames().size(), 1U);
  EXPECT_EQ(ch.sent_frames()[0].t_ns, 1'000);
  clock.set_ns(1'250);  // two expiries: 1100 and 1200
  ch.deactivate();
  ASSERT_EQ(ch.sent_frames().size(), 3U);
  EXPECT_EQ(ch.sent_frames()[1].t_ns, 1'100);
  EXPECT_EQ(ch.sent_frames()[2].t_ns, 1'200);
  EXPECT_EQ(ch.sent_frames()[1].data[0], 1);
  EXPECT_EQ(ch.sent_frames()[2].data[0], 2);

  // Renewals: a content change keeps the turn and the timer's phase; the lease (count) runs out.
  ch.activate();
  clock.set_ns(10'000);
  ASSERT_EQ(ch.set_cyclic(tx), CanStatus::kOk);  // a new operation after deactivate: starts, sends 1
  const std::size_t base = ch.sent_frames().size();
  clock.set_ns(10'150);  // expiry 10100
  const auto b = cyclic_frames(0xB);
  tx.frames = b;
  tx.start = CanCyclicTx::Start::kKeepTimer;
  tx.count = 3;
  ASSERT_EQ(ch.set_cyclic(tx), CanStatus::kOk);  // nothing sent now
  EXPECT_EQ(ch.sent_frames().size(), base + 1);
  clock.set_ns(11'000);  // expiries 10200, 10300, 10400 send the 3 of the lease, then it stops
  ch.deactivate();
  const auto sent = ch.sent_frames();
  ASSERT_EQ(sent.size(), base + 4);
  EXPECT_EQ(sent[base].t_ns, 10'100);
  EXPECT_EQ(sent[base].data[1], 0xA);
  EXPECT_EQ(sent[base].data[0], 1);
  for (std::size_t i = 1; i <= 3; ++i) {
    EXPECT_EQ(sent[base + i].t_ns, static_cast<std::int64_t>(10'100 + 100 * i));
    EXPECT_EQ(sent[base + i].data[1], 0xB);
    EXPECT_EQ(sent[base + i].data[0], static_cast<std::uint8_t>((1 + i) % 3));  // the turn goes on
  }
}

TEST_F(CandumpReplay, CyclicAnnounceSendsAtOnceAndRestartMovesThePhase) {
  cfg_.cyclic = true;
  ManualClock clock(0);
  CandumpReplayChannel ch(cfg_, clock);
  ch.configure();
  ch.activate();
  const auto a = cyclic_frames(1);
  CanCyclicTx tx;
  tx.frames = a;
  tx.period_ns = 100;
  tx.count = 100;
  ASSERT_EQ(ch.set_cyclic(tx), CanStatus::kOk);  // t 0
  clock.set_ns(130);                             // expiry 100
  tx.start = CanCyclicTx::Start::kAnnounce;
  ASSERT_EQ(ch.set_cyclic(tx), CanStatus::kOk);  // t 130, phase kept: next expiry 200
  clock.set_ns(260);                             // expiry 200
  tx.start = CanCyclicTx::Start::kRestart;
  ASSERT_EQ(ch.set_cyclic(tx), CanStatus::kOk);  // t 260, next expiry 360
  clock.set_ns(370);
  ch.deactivate();
  const auto s = ch.sent_frames();
  ASSERT_EQ(s.size(), 6U);
  const std::int64_t t[] = {0, 100, 130, 200, 260, 360};
  for (std::size_t i = 0; i < 6; ++i) {
    EXPECT_EQ(s[i].t_ns, t[i]) << i;
    EXPECT_EQ(s[i].data[0], i % 3) << i;
  }
}

TEST_F(CandumpReplay, CyclicTransmissionIsRefusedWhereTheKernelCouldNotDoIt) {
  ManualClock clock(0);
  const auto a = cyclic_frames(1);
  CanCyclicTx tx;
  tx.frames = a;
  tx.period_ns = 100;
  tx.count = 2;
  {
    CandumpReplayChannel off(cfg_, clock);  // not asked for
    off.configure();
    off.activate();
    EXPECT_FALSE(off.cyclic_supported());
    EXPECT_EQ(off.set_cyclic(tx), CanStatus::kError);
  }
  cfg_.cyclic = true;
  cfg_.pace = ReplayPace::kAsFastAsPossible;  // no timer can follow a replay faster than real time
  CandumpReplayChannel fast(cfg_, clock);
  fast.configure();
  fast.activate();
  EXPECT_FALSE(fast.cyclic_supported());
  EXPECT_EQ(fast.set_cyclic(tx), CanStatus::kError);
  cfg_.pace = ReplayPace::kRealTime;
  CandumpReplayChannel ch(cfg_, clock);
  ch.configure();
  EXPECT_EQ(ch.set_cyclic(tx), CanStatus::kNotActive);
  ch.activate();
  auto mixed = cyclic_frames(1);
  mixed[2].id = 0x3A1;  // one operation is one id
  tx.frames = mixed;
  EXPECT_EQ(ch.set_cyclic(tx), CanStatus::kError);
  tx.frames = a;
  tx.count = 0;
  EXPECT_EQ(ch.set_cyclic(tx), CanStatus::kError);
  tx.count = 2;
  tx.period_ns = 0;
  EXPECT_EQ(ch.set_cyclic(tx), CanStatus::kError);
  EXPECT_EQ(ch.counters().tx_errors, 3U);
  EXPECT_TRUE(ch.sent_frames().empty());
}

}  // namespace
}  // namespace ptda::drivers

namespace ptda::drivers {
namespace {

std::size_t heap_bytes() {
  const struct mallinfo2 m = ::mallinfo2();
  return m.uordblks + m.hblkhd;  // in use from the arenas + mmapped blocks
}

// The log is streamed: memory does not grow with its length (it used to be loaded whole: 1 h of a
// 250 Hz speed frame is 900,000 frames, ~158 MB in ptdad).
TEST_F(CandumpReplay, StreamsALongLogInMemoryIndependentOfItsLength) {
  constexpr std::size_t kFrames = 200'000;
  {
    std::ofstream out(log_);
    char line[64];
    for (std::size_t i = 0; i < kFrames; ++i) {
      std::snprintf(line, sizeof line, "(%zu.%06zu) can0 184#%04zX000000000000 R\n", 1000 + i / 250,
                    (i % 250) * 4000, i & 0xFFFF);
      out << line;
    }
  }
  cfg_.pace = ReplayPace::kAsFastAsPossible;
  cfg_.tx_capacity = 16;
  ManualClock clock(0);
  const std::size_t before = heap_bytes();
  CandumpReplayChannel ch(cfg_, clock);
  ch.configure();
  const std::size_t held = heap_bytes() - before;
  EXPECT_EQ(ch.frame_count(), kFrames);
  // The reader (FILE buffer, line) and 16 tx frames; loaded whole, 200,000 frames took > 10 MB.
  EXPECT_LT(held, 64U * 1024U) << "bytes held after configure()";
  ch.activate();
  std::array<CanFrame, 64> out{};
  std::size_t n = 0, total = 0;
  std::int64_t last_t = -1;
  bool ordered = true;
  ptda::test::AllocScope scope;
  while (ch.receive(out, n, 0) == CanStatus::kOk) {
    for (std::size_t i = 0; i < n; ++i) {
      ordered = ordered && out[i].t_ns > last_t && out[i].data[1] == ((total + i) & 0xFF);
      last_t = out[i].t_ns;
    }
    total += n;
  }
  EXPECT_EQ(scope.count(), 0U);
  EXPECT_EQ(total, kFrames);
  EXPECT_TRUE(ordered);
  EXPECT_EQ(ch.position(), kFrames);
  // activate() rewinds: the first frame again.
  ch.activate();
  ASSERT_EQ(ch.receive(out, n, 0), CanStatus::kOk);
  EXPECT_EQ(out[0].t_ns, 0);
  EXPECT_EQ(out[0].data[1], 0);
}

// A log rewritten under a running replay does not throw in the run state: the stream ends there and
// the read error is counted.
TEST_F(CandumpReplay, ALogThatStopsParsingEndsTheStreamAndIsCounted) {
  cfg_.pace = ReplayPace::kAsFastAsPossible;
  ManualClock clock(0);
  CandumpReplayChannel ch(cfg_, clock);
  ch.configure();
  std::ofstream(log_) << "(1000.000000) can0 184#1027000000000000 R\n(1000.004000) can0 184#ZZ\n";
  ch.activate();
  std::array<CanFrame, 8> out{};
  std::size_t n = 0;
  ASSERT_EQ(ch.receive(out, n, 0), CanStatus::kOk);
  EXPECT_EQ(n, 1U);
  EXPECT_EQ(ch.receive(out, n, 0), CanStatus::kEndOfStream);
  EXPECT_EQ(ch.counters().rx_errors, 1U);
}

}  // namespace
}  // namespace ptda::drivers
