// The SocketCAN backend's pure parts (filters, error mask, cmsg parsing, frame conversion, the
// error-frame state machine) run everywhere. The live parts need AF_CAN and a vcan0 interface and
// skip with the reason otherwise (this workspace's kernel has CONFIG_CAN unset).
#include "can/socketcan_channel.hpp"

#include <gtest/gtest.h>
#include <linux/can.h>
#include <linux/can/error.h>
#include <net/if.h>
#include <sys/socket.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstring>
#include <string>
#include <vector>

#include "ptda/common/error.hpp"

namespace ptda::drivers {
namespace {

TEST(CanFilters, StandardAndExtendedIdsNeverMatchTheOtherFormat) {
  const std::vector<CanIdFilter> in{{0x184, false, 0}, {0x18FF0001, true, 0}, {0x700, false, 0x780}};
  const auto f = build_can_filters(in);
  ASSERT_EQ(f.size(), 3u);
  EXPECT_EQ(f[0].can_id, 0x184u);
  EXPECT_EQ(f[0].can_mask, 0x7FFu | CAN_EFF_FLAG);
  EXPECT_EQ(f[1].can_id, 0x18FF0001u | CAN_EFF_FLAG);
  EXPECT_EQ(f[1].can_mask, 0x1FFFFFFFu | CAN_EFF_FLAG);
  EXPECT_EQ(f[2].can_id, 0x700u);
  EXPECT_EQ(f[2].can_mask, 0x780u | CAN_EFF_FLAG);
  EXPECT_TRUE(build_can_filters({}).empty());
  EXPECT_THROW((void)build_can_filters(std::vector<CanIdFilter>{{0x800, false, 0}}), Error);
  EXPECT_THROW((void)build_can_filters(std::vector<CanIdFilter>{{0x20000000, true, 0}}), Error);
}

TEST(CanFilters, ErrorMaskSubscribesToStateChangesAndOptionallyBusErrors) {
  EXPECT_EQ(build_error_mask(false, true), 0u);
  EXPECT_EQ(build_error_mask(true, false), 0x155u);  // TX_TIMEOUT CRTL TRX BUSOFF RESTARTED
  EXPECT_EQ(build_error_mask(true, true), 0x1FFu);   // + LOSTARB PROT ACK BUSERROR
}

TEST(CanCmsg, ParsesTimestampNsAndDropCounter) {
  alignas(cmsghdr) unsigned char buf[kCanCmsgBytes] = {};
  msghdr msg{};
  msg.msg_control = buf;
  msg.msg_controllen = sizeof buf;
  cmsghdr* c = CMSG_FIRSTHDR(&msg);
  c->cmsg_level = SOL_SOCKET;
  c->cmsg_type = SCM_TIMESTAMPNS;
  c->cmsg_len = CMSG_LEN(sizeof(timespec));
  const timespec ts{1'700'000'000, 123'456'789};
  std::memcpy(CMSG_DATA(c), &ts, sizeof ts);
  c = CMSG_NXTHDR(&msg, c);
  ASSERT_NE(c, nullptr);
  c->cmsg_level = SOL_SOCKET;
  c->cmsg_type = SO_RXQ_OVFL;
  c->cmsg_len = CMSG_LEN(sizeof(std::uint32_t));
  const std::uint32_t drops = 7;
  std::memcpy(CMSG_DATA(c), &drops, sizeof drops);

  const CanRxMeta m = parse_rx_cmsgs(msg);
  EXPECT_TRUE(m.has_time);
  EXPECT_EQ(m.t_realtime_ns, 1'700'000'000'123'456'789);
  EXPECT_TRUE(m.has_drops);
  EXPECT_EQ(m.drops, 7u);
}

TEST(CanCmsg, ParsesMicrosecondTimestampsAndToleratesNone) {
  alignas(cmsghdr) unsigned char buf[kCanCmsgBytes] = {};
  msghdr msg{};
  msg.msg_control = buf;
  msg.msg_controllen = CMSG_SPACE(sizeof(timeval));
  cmsghdr* c = CMSG_FIRSTHDR(&msg);
  c->cmsg_level = SOL_SOCKET;
  c->cmsg_type = SCM_TIMESTAMP;
  c->cmsg_len = CMSG_LEN(sizeof(timeval));
  const timeval tv{1'436'509'052, 249'713};
  std::memcpy(CMSG_DATA(c), &tv, sizeof tv);
  const CanRxMeta m = parse_rx_cmsgs(msg);
  EXPECT_TRUE(m.has_time);
  EXPECT_EQ(m.t_realtime_ns, 1'436'509'052'249'713'000);
  EXPECT_FALSE(m.has_drops);

  msghdr empty{};
  const CanRxMeta n = parse_rx_cmsgs(empty);
  EXPECT_FALSE(n.has_time);
  EXPECT_FALSE(n.has_drops);
}

TEST(CanFrameConversion, ClassicExtendedRtrErrorAndFd) {
  canfd_frame k{};
  CanFrame f;
  k.can_id = 0x184;
  k.len = 8;
  for (int i = 0; i < 8; ++i) k.data[i] = static_cast<__u8>(0x10 + i);
  ASSERT_TRUE(from_kernel_frame(k, CAN_MTU, 42, f));
  EXPECT_EQ(f.id, 0x184u);
  EXPECT_EQ(f.flags, 0);
  EXPECT_EQ(f.len, 8);
  EXPECT_EQ(f.t_ns, 42);
  EXPECT_EQ(f.data[7], 0x17);

  k.can_id = 0x18FF0001 | CAN_EFF_FLAG;
  ASSERT_TRUE(from_kernel_frame(k, CAN_MTU, 0, f));
  EXPECT_EQ(f.id, 0x18FF0001u);
  EXPECT_TRUE(f.extended());

  k.can_id = 0x184 | CAN_RTR_FLAG;
  k.len = 2;
  ASSERT_TRUE(from_kernel_frame(k, CAN_MTU, 0, f));
  EXPECT_TRUE(f.rtr());
  EXPECT_EQ(f.len, 2);
  EXPECT_EQ(f.data[0], 0);  // RTR carries no data

  k.can_id = CAN_ERR_FLAG | CAN_ERR_CRTL;
  k.len = CAN_ERR_DLC;
  k.data[1] = CAN_ERR_CRTL_RX_PASSIVE;
  ASSERT_TRUE(from_kernel_frame(k, CAN_MTU, 0, f));
  EXPECT_TRUE(f.error());
  EXPECT_EQ(f.id, static_cast<std::uint32_t>(CAN_ERR_CRTL));
  EXPECT_EQ(f.data[1], CAN_ERR_CRTL_RX_PASSIVE);

  canfd_frame fd{};
  fd.can_id = 0x123;
  fd.len = 64;
  fd.flags = CANFD_BRS;
  fd.data[63] = 0xAB;
  ASSERT_TRUE(from_kernel_frame(fd, CANFD_MTU, 0, f));
  EXPECT_TRUE(f.fd());
  EXPECT_EQ(f.flags, kCanFd | kCanFdBrs);
  EXPECT_EQ(f.len, 64);
  EXPECT_EQ(f.data[63], 0xAB);

  k = canfd_frame{};
  k.len = 9;
  EXPECT_FALSE(from_kernel_frame(k, CAN_MTU, 0, f));
  EXPECT_FALSE(from_kernel_frame(k, 10, 0, f));

  // Found by fuzz_can_frame: an FD length between the FD sizes (9..11, 13..15, ...) was accepted,
  // and such a frame could not be converted back (to_kernel_frame refuses it).
  fd = canfd_frame{};
  fd.can_id = 0x123;
  for (const int len : {9, 11, 14, 33, 63, 65}) {
    fd.len = static_cast<__u8>(len);
    EXPECT_FALSE(from_kernel_frame(fd, CANFD_MTU, 0, f)) << len;
  }
  for (const int len : {0, 8, 12, 20, 48, 64}) {
    fd.len = static_cast<__u8>(len);
    ASSERT_TRUE(from_kernel_frame(fd, CANFD_MTU, 0, f)) << len;
    canfd_frame back{};
    EXPECT_EQ(to_kernel_frame(f, back), static_cast<std::size_t>(CANFD_MTU)) << len;
  }
}

TEST(CanFrameConversion, OutgoingFramesRoundTripAndInvalidOnesAreRefused) {
  CanFrame f;
  f.id = 0x3A0;
  f.len = 8;
  f.data = {1, 2, 3, 4, 5, 6, 7, 8};
  canfd_frame k{};
  ASSERT_EQ(to_kernel_frame(f, k), static_cast<std::size_t>(CAN_MTU));
  EXPECT_EQ(k.can_id, 0x3A0u);
  CanFrame back;
  ASSERT_TRUE(from_kernel_frame(k, CAN_MTU, 0, back));
  EXPECT_EQ(back.id, f.id);
  EXPECT_EQ(back.data, f.data);

  f.flags = kCanExtended;
  f.id = 0x1ABCDEF0;
  ASSERT_EQ(to_kernel_frame(f, k), static_cast<std::size_t>(CAN_MTU));
  EXPECT_EQ(k.can_id, 0x1ABCDEF0u | CAN_EFF_FLAG);

  CanFrame bad = f;
  bad.flags = 0;
  bad.id = 0x800;  // not an 11-bit id
  EXPECT_EQ(to_kernel_frame(bad, k), 0u);
  bad = f;
  bad.len = 9;
  EXPECT_EQ(to_kernel_frame(bad, k), 0u);
  bad = f;
  bad.flags = kCanError;
  EXPECT_EQ(to_kernel_frame(bad, k), 0u);
  bad = f;
  bad.flags = kCanFd | kCanExtended;
  bad.len = 13;  // not a CAN FD length
  EXPECT_EQ(to_kernel_frame(bad, k), 0u);
  bad.len = 12;
  EXPECT_EQ(to_kernel_frame(bad, k), static_cast<std::size_t>(CANFD_MTU));
}

CanFrame error_frame(std::uint32_t cls, std::uint8_t ctrl = 0) {
  CanFrame f;
  f.flags = kCanError;
  f.id = cls;
  f.len = 8;
  f.data[1] = ctrl;
  return f;
}

TEST(CanErrorFrames, WalkThroughTheFaultConfinementStates) {
  CanChannelStats s;
  EXPECT_EQ(s.state.load(), CanBusState::kErrorActive);
  apply_error_frame(error_frame(CAN_ERR_CRTL, CAN_ERR_CRTL_TX_WARNING), s);
  EXPECT_EQ(s.state.load(), CanBusState::kErrorWarning);
  apply_error_frame(error_frame(CAN_ERR_CRTL, CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_RX_WARNING), s);
  EXPECT_EQ(s.state.load(), CanBusState::kErrorPassive);
  apply_error_frame(error_frame(CAN_ERR_CRTL, CAN_ERR_CRTL_RX_PASSIVE), s);  // repeated: no new transition
  apply_error_frame(error_frame(CAN_ERR_BUSOFF), s);
  EXPECT_EQ(s.state.load(), CanBusState::kBusOff);
  apply_error_frame(error_frame(CAN_ERR_CRTL, CAN_ERR_CRTL_TX_WARNING), s);  // cannot leave bus-off so
  EXPECT_EQ(s.state.load(), CanBusState::kBusOff);
  apply_error_frame(error_frame(CAN_ERR_RESTARTED), s);
  EXPECT_EQ(s.state.load(), CanBusState::kErrorActive);
  apply_error_frame(error_frame(CAN_ERR_CRTL, CAN_ERR_CRTL_TX_PASSIVE), s);
  apply_error_frame(error_frame(CAN_ERR_CRTL, CAN_ERR_CRTL_ACTIVE), s);
  EXPECT_EQ(s.state.load(), CanBusState::kErrorActive);
  apply_error_frame(error_frame(CAN_ERR_CRTL, CAN_ERR_CRTL_RX_OVERFLOW), s);
  apply_error_frame(error_frame(CAN_ERR_PROT | CAN_ERR_BUSERROR), s);
  apply_error_frame(error_frame(CAN_ERR_ACK), s);

  const CanCounters c = s.snapshot();
  EXPECT_EQ(c.rx_error_frames, 11u);
  EXPECT_EQ(c.error_warning, 1u);
  EXPECT_EQ(c.error_passive, 2u);
  EXPECT_EQ(c.bus_off, 1u);
  EXPECT_EQ(c.restarts, 1u);
  EXPECT_EQ(c.controller_overflows, 1u);
  EXPECT_EQ(c.protocol_errors, 2u);

  CanFrame data;  // not an error frame: ignored
  data.id = CAN_ERR_BUSOFF;
  apply_error_frame(data, s);
  EXPECT_EQ(s.state.load(), CanBusState::kErrorActive);
  EXPECT_EQ(s.snapshot().rx_error_frames, 11u);
}

/// errno of socket(AF_CAN, SOCK_RAW, CAN_RAW), 0 when the kernel supports it.
int af_can_errno() {
  const int fd = ::socket(PF_CAN, SOCK_RAW | SOCK_CLOEXEC, CAN_RAW);
  if (fd < 0) return errno;
  ::close(fd);
  return 0;
}

TEST(SocketCanLive, WithoutAfCanConfigureFailsWithAnActionableError) {
  if (af_can_errno() == 0) GTEST_SKIP() << "kernel has AF_CAN; this test covers kernels without it";
  MonotonicClock clock;
  SocketCanChannel ch(SocketCanConfig{}, clock);
  try {
    ch.configure();
    FAIL() << "expected ptda::Error";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("socketcan can0"), std::string::npos) << what;
    EXPECT_NE(what.find("socket(AF_CAN"), std::string::npos) << what;
  }
  std::array<CanFrame, 4> out{};
  std::size_t n = 99;
  EXPECT_EQ(ch.receive(out, n, 0), CanStatus::kNotActive);
  EXPECT_EQ(n, 0u);
}

TEST(SocketCanLive, VcanLoopbackBetweenTwoChannels) {
  const int e = af_can_errno();
  if (e == EAFNOSUPPORT) GTEST_SKIP() << "kernel has no AF_CAN (CONFIG_CAN unset or can-raw not loaded)";
  if (e != 0) GTEST_SKIP() << "socket(AF_CAN) failed: " << std::strerror(e);
  if (::if_nametoindex("vcan0") == 0)
    GTEST_SKIP() << "no vcan0 (modprobe vcan; ip link add dev vcan0 type vcan; ip link set up vcan0)";

  MonotonicClock clock;
  SocketCanConfig rx_cfg;
  rx_cfg.interface = "vcan0";
  rx_cfg.filters = {{0x184, false, 0}};
  SocketCanChannel rx(rx_cfg, clock);
  SocketCanConfig tx_cfg;
  tx_cfg.interface = "vcan0";
  SocketCanChannel tx(tx_cfg, clock);
  rx.configure();
  tx.configure();
  rx.activate();
  tx.activate();

  CanFrame other;
  other.id = 0x185;
  other.len = 1;
  CanFrame speed;
  speed.id = 0x184;
  speed.len = 8;
  speed.data = {0x10, 0x27, 0, 0, 0, 0, 0, 0};
  const std::int64_t before = clock.now_ns();
  ASSERT_EQ(tx.send(other), CanStatus::kOk);
  ASSERT_EQ(tx.send(speed), CanStatus::kOk);
  std::array<CanFrame, 8> out{};
  std::size_t n = 0;
  ASSERT_EQ(rx.receive(out, n, 1'000'000'000), CanStatus::kOk);
  ASSERT_EQ(n, 1u);  // 0x185 filtered out by the kernel
  EXPECT_EQ(out[0].id, 0x184u);
  EXPECT_EQ(out[0].data, speed.data);
  // The kernel's rx stamp mapped onto the monotonic clock lies between send and now (+1 ms slack for
  // the realtime/monotonic offset sampling).
  EXPECT_GE(out[0].t_ns, before - 1'000'000);
  EXPECT_LE(out[0].t_ns, clock.now_ns() + 1'000'000);
  EXPECT_EQ(rx.counters().rx_frames, 1u);
  EXPECT_EQ(tx.counters().tx_frames, 2u);
  EXPECT_EQ(rx.receive(out, n, 0), CanStatus::kTimeout);
}

}  // namespace
}  // namespace ptda::drivers
