// candump -l parser and writer: every frame kind, exact timestamps, malformed lines, round trips,
// no allocation per line, and a garbled-input robustness run.
#include "ptda/formats/candump.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "alloc_counter.hpp"
#include "ptda/common/error.hpp"

namespace fs = std::filesystem;
using ptda::CanFrame;
using ptda::Error;
using ptda::formats::CandumpRecord;
using ptda::formats::format_candump_line;
using ptda::formats::parse_candump_line;

namespace {

const fs::path kData = fs::path(PTDA_SOURCE_DIR) / "tests" / "data" / "formats";

fs::path temp_dir(const std::string& name) {
  const char* env = std::getenv("PTDA_TEST_TMP");
  fs::path d = (env != nullptr ? fs::path(env) : fs::temp_directory_path()) /
               ("formats_candump_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

// Expects a ptda::Error whose message is exactly "x.log:7: <what>".
void expect_line_error(const std::string& line, const std::string& what) {
  try {
    (void)parse_candump_line(line, "x.log", 7);
    ADD_FAILURE() << "no error for: " << line;
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "x.log:7: " + what) << "line: " << line;
  }
}

CandumpRecord parse_ok(const std::string& line) {
  auto r = parse_candump_line(line, "x.log", 1);
  EXPECT_TRUE(r.has_value()) << line;
  return r.value_or(CandumpRecord{});
}

}  // namespace

TEST(Candump, ParsesEveryFrameKindFromHandWrittenLog) {
  const auto recs = ptda::formats::read_candump(kData / "candump_all_kinds.log");
  // 14 frame lines minus the CAN XL line, which is accepted and skipped.
  ASSERT_EQ(recs.size(), 13U);
  constexpr std::int64_t kT0 = 1436509052'000000000;

  // (1436509052.249713) vcan0 044#2A366C2BBA: standard id, 5 bytes (the can-utils example line).
  EXPECT_EQ(recs[0].frame.t_ns, kT0 + 249713000);
  EXPECT_EQ(recs[0].iface, "vcan0");
  EXPECT_EQ(recs[0].frame.id, 0x044U);
  EXPECT_EQ(recs[0].frame.flags, 0);
  ASSERT_EQ(recs[0].frame.len, 5);
  EXPECT_EQ(recs[0].frame.data[0], 0x2A);
  EXPECT_EQ(recs[0].frame.data[4], 0xBA);
  EXPECT_EQ(recs[0].direction, 0);

  EXPECT_EQ(recs[1].frame.len, 0);  // 123#: empty data frame
  EXPECT_EQ(recs[1].frame.flags, 0);

  EXPECT_EQ(recs[2].frame.id, 0x12345678U);  // extended, direction R
  EXPECT_EQ(recs[2].frame.flags, ptda::kCanExtended);
  EXPECT_EQ(recs[2].frame.len, 4);
  EXPECT_EQ(recs[2].frame.data[3], 0xEF);
  EXPECT_EQ(recs[2].direction, 'R');

  EXPECT_EQ(recs[3].frame.id, 0x7FFU);  // 7FF#R
  EXPECT_EQ(recs[3].frame.flags, ptda::kCanRtr);
  EXPECT_EQ(recs[3].frame.len, 0);

  EXPECT_EQ(recs[4].frame.flags, ptda::kCanRtr);  // 123#R7 T
  EXPECT_EQ(recs[4].frame.len, 7);
  EXPECT_EQ(recs[4].direction, 'T');

  EXPECT_EQ(recs[5].frame.flags, ptda::kCanError);  // 20000080#...: class bits without CAN_ERR_FLAG
  EXPECT_EQ(recs[5].frame.id, 0x80U);
  EXPECT_EQ(recs[5].frame.len, 8);

  EXPECT_EQ(recs[6].frame.flags, ptda::kCanFd | ptda::kCanFdBrs);  // 123##1112233
  EXPECT_EQ(recs[6].frame.len, 3);
  EXPECT_EQ(recs[6].frame.data[0], 0x11);
  EXPECT_EQ(recs[6].frame.data[2], 0x33);

  EXPECT_EQ(recs[7].frame.flags, ptda::kCanFd | ptda::kCanFdBrs | ptda::kCanFdEsi | ptda::kCanExtended);
  EXPECT_EQ(recs[7].frame.id, 0x1FFFFFFFU);
  EXPECT_EQ(recs[7].frame.len, 0);

  EXPECT_EQ(recs[8].frame.len, 4);  // '.' separators
  EXPECT_EQ(recs[8].frame.data[3], 0x44);

  EXPECT_EQ(recs[9].frame.len, 8);  // _E len8_dlc suffix ignored
  EXPECT_EQ(recs[9].frame.data[7], 0x88);
  EXPECT_EQ(recs[9].frame.t_ns, kT0 + 250008000);

  EXPECT_EQ(recs[10].frame.flags, ptda::kCanRtr);  // 123#R8_9
  EXPECT_EQ(recs[10].frame.len, 8);

  // The XL line (…250010) is skipped: the next record is the 64-byte FD frame.
  EXPECT_EQ(recs[11].frame.t_ns, kT0 + 250011000);
  EXPECT_EQ(recs[11].iface, "vcan10");
  ASSERT_EQ(recs[11].frame.len, 64);
  for (int i = 0; i < 64; ++i) EXPECT_EQ(recs[11].frame.data[static_cast<std::size_t>(i)], i);
  EXPECT_EQ(recs[11].frame.flags, ptda::kCanFd);

  EXPECT_EQ(recs[12].frame.t_ns, 0);  // extra spaces between fields are accepted
  EXPECT_EQ(recs[12].iface, "can0");
  EXPECT_EQ(recs[12].frame.len, 1);
}

TEST(Candump, TimestampsAreExactIntegerNanoseconds) {
  // A double cannot hold 1436509052.249713 exactly; integer parsing must give the exact ns value.
  EXPECT_EQ(parse_ok("(1436509052.249713) c 123#").frame.t_ns, 1436509052249713000LL);
  // Largest accepted second: 9223372035 s plus a fraction still fits int64 ns.
  EXPECT_EQ(parse_ok("(9223372035.999999999) c 123#").frame.t_ns, 9223372035999999999LL);
  expect_line_error("(9223372036.0) c 123#", "timestamp: seconds out of range");
  EXPECT_EQ(parse_ok("(1.5) c 123#").frame.t_ns, 1500000000LL);
  EXPECT_EQ(parse_ok("(1.123456789) c 123#").frame.t_ns, 1123456789LL);
  EXPECT_EQ(parse_ok("(0.000001) c 123#").frame.t_ns, 1000LL);
}

TEST(Candump, CommentsBlankAndXlLinesAreSkipped) {
  EXPECT_FALSE(parse_candump_line("", "x", 1).has_value());
  EXPECT_FALSE(parse_candump_line("# comment (1.0) can0 123#", "x", 1).has_value());
  EXPECT_FALSE(parse_candump_line(" (1.0) can0 123#", "x", 1).has_value());  // canplayer: must start with '('
  EXPECT_FALSE(
      parse_candump_line("(1.000000) can0 45123#81:00:12345678#11223344.556677", "x", 1).has_value());
}

TEST(Candump, CrLfLineEndingsAccepted) {
  const auto recs = ptda::formats::read_candump(kData / "candump_crlf.log");
  ASSERT_EQ(recs.size(), 2U);
  EXPECT_EQ(recs[1].frame.id, 0x12345678U);
  EXPECT_EQ(recs[1].frame.len, 2);
}

TEST(Candump, MalformedLinesNameFileLineAndProblem) {
  expect_line_error("(1436509052.249713) can0 044#2A3", "odd number of hex digits in classic CAN data");
  expect_line_error("(1.0) can0 123#112233445566778899", "classic CAN data longer than 8 bytes");
  expect_line_error("(1.0) can0 1234#11", "bad CAN id length 4 in '1234#11' (expected 3 or 8 hex digits)");
  expect_line_error("(1.0) can0 12#11", "bad CAN id length 2 in '12#11' (expected 3 or 8 hex digits)");
  expect_line_error("(1.0) can0 800#11", "standard CAN id '800' exceeds 11 bits (max 7FF)");
  expect_line_error("(1.0) can0 C0000000#11", "extended CAN id 'C0000000' exceeds 29 bits (max 1FFFFFFF)");
  expect_line_error("(1.0) can0 E0000001#11", "error frame id 'E0000001' has bits above CAN_ERR_FLAG set");
  expect_line_error("(1.0) can0 12G#11", "CAN id '12G' is not hexadecimal");
  expect_line_error("(1.0) can0 123", "frame '123' has no '#'");
  expect_line_error("(1.0) can0", "missing frame after the interface name");
  expect_line_error("(1.0)", "expected a space after the timestamp");
  expect_line_error("(1.0) ", "missing interface name");
  expect_line_error("()", "timestamp: expected seconds digits after '('");
  expect_line_error("(12 can0 123#", "timestamp: expected '.' after the seconds");
  expect_line_error("(12.) can0 123#", "timestamp: expected fraction digits after '.'");
  expect_line_error("(12.1234567890) can0 123#", "timestamp: more than 9 fraction digits");
  expect_line_error("(12.5 can0 123#", "timestamp: expected ')' after the fraction");
  expect_line_error("(99999999999999999999.0) can0 123#", "timestamp: seconds out of range");
  expect_line_error("(1.0)can0 123#", "expected a space after the timestamp");
  expect_line_error("(1.0) can0 123#11 X", "unexpected 'X' after the frame (expected direction R or T)");
  expect_line_error("(1.0) can0 123#11 R extra", "unexpected trailing text 'extra'");
  expect_line_error("(1.0) can0 123#1Z", "odd number of hex digits in classic CAN data");
  expect_line_error("(1.0) can0 123#ZZ", "bad character 'Z' in classic CAN data");
  expect_line_error("(1.0) can0 123#11..22", "empty byte between '.' separators in classic CAN data");
  expect_line_error("(1.0) can0 123#R9", "remote frame DLC 9 exceeds 8");
  expect_line_error("(1.0) can0 123#RX", "bad remote frame DLC 'X'");
  expect_line_error("(1.0) can0 123#R77", "unexpected '7' after the frame data");
  expect_line_error("(1.0) can0 123#1122_9", "'_<dlc>' suffix is only valid after 8 data bytes");
  expect_line_error("(1.0) can0 123#1122334455667788_8", "bad '_<dlc>' suffix '_8' (expected _9.._F)");
  expect_line_error("(1.0) can0 123##", "CAN FD frame without the flags nibble after '##'");
  expect_line_error("(1.0) can0 123##X11", "bad CAN FD flags nibble 'X'");
  expect_line_error("(1.0) can0 123##0" + std::string(130, 'A'), "CAN FD data longer than 64 bytes");
  expect_line_error("(1.0) can0 20000004##011", "error frames cannot be CAN FD frames");
  expect_line_error("(1.0) can0 20000004#R", "error frames cannot be remote frames");
  expect_line_error("(1.0) can0 45123#81:00:1234#11",
                    "malformed CAN XL frame (expected <vcid><prio>#<flags>:<sdt>:<af>#<data>)");
}

TEST(Candump, ReaderReportsFileAndLineOfBadLine) {
  const fs::path p = kData / "candump_bad_line4.log";
  ptda::formats::CandumpReader reader(p);
  CandumpRecord rec;
  ASSERT_TRUE(reader.next(rec));
  ASSERT_TRUE(reader.next(rec));
  EXPECT_EQ(reader.line_no(), 3);
  try {
    (void)reader.next(rec);
    FAIL() << "line 4 is malformed";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), p.string() + ":4: odd number of hex digits in classic CAN data");
  }
}

TEST(Candump, MissingFileIsAnError) {
  try {
    (void)ptda::formats::read_candump(kData / "no_such.log");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("no_such.log: cannot open candump log"), std::string::npos)
        << e.what();
  }
}

TEST(Candump, FormatsExactlyLikeCandumpL) {
  CandumpRecord r;
  r.iface = "can0";
  r.frame.t_ns = 12'000345'999;  // truncated to whole microseconds, as the kernel's timeval is
  r.frame.id = 0x123;
  r.frame.flags = ptda::kCanRtr;
  r.frame.len = 7;
  EXPECT_EQ(format_candump_line(r), "(0000000012.000345) can0 123#R7");
  r.frame.len = 0;
  EXPECT_EQ(format_candump_line(r), "(0000000012.000345) can0 123#R");

  r.frame.flags = ptda::kCanExtended;
  r.frame.id = 0x1ABCDEF;
  r.frame.len = 2;
  r.frame.data[0] = 0x0A;
  r.frame.data[1] = 0xF0;
  r.direction = 'T';
  EXPECT_EQ(format_candump_line(r), "(0000000012.000345) can0 01ABCDEF#0AF0 T");

  r.direction = 0;
  r.frame.flags = ptda::kCanError;
  r.frame.id = 0x80;
  r.frame.len = 0;
  EXPECT_EQ(format_candump_line(r), "(0000000012.000345) can0 20000080#");

  r.frame.flags = ptda::kCanFd | ptda::kCanFdEsi;
  r.frame.id = 0x7;
  r.frame.len = 1;
  r.frame.data[0] = 0x5;
  EXPECT_EQ(format_candump_line(r), "(0000000012.000345) can0 007##205");

  r.frame.flags = 0;
  r.frame.id = 0x800;
  EXPECT_THROW((void)format_candump_line(r), Error);
  r.frame.id = 1;
  r.frame.len = 9;
  EXPECT_THROW((void)format_candump_line(r), Error);
  r.frame.len = 1;
  r.frame.t_ns = -1;
  EXPECT_THROW((void)format_candump_line(r), Error);
}

TEST(Candump, RoundTripOfEveryFrameKind) {
  std::vector<CandumpRecord> recs;
  std::mt19937 rng(42);
  auto add = [&](std::uint32_t id, std::uint8_t flags, std::uint8_t len, char dir, const char* iface) {
    CandumpRecord r;
    r.iface = iface;
    r.direction = dir;
    r.frame.t_ns = 1700000000'000000000 + static_cast<std::int64_t>(recs.size()) * 1'234'000;
    r.frame.id = id;
    r.frame.flags = flags;
    r.frame.len = len;
    if ((flags & ptda::kCanRtr) == 0) {
      for (std::size_t i = 0; i < len; ++i) r.frame.data[i] = static_cast<std::uint8_t>(rng());
    }
    recs.push_back(r);
  };
  for (std::uint8_t len = 0; len <= 8; ++len) add(0x100U + len, 0, len, 0, "can0");
  add(0x7FF, 0, 8, 'R', "can0");
  add(0x000, 0, 0, 'T', "can1");
  add(0x1FFFFFFF, ptda::kCanExtended, 8, 0, "can0");
  add(0x0, ptda::kCanExtended, 3, 0, "can0");
  for (std::uint8_t len = 0; len <= 8; ++len) add(0x321, ptda::kCanRtr, len, 0, "can0");
  add(0x12345, ptda::kCanRtr | ptda::kCanExtended, 2, 0, "can0");
  add(0x80, ptda::kCanError, 8, 0, "can0");
  add(0x1FFFFFFF, ptda::kCanError, 0, 0, "can0");
  for (std::uint8_t len : {0, 1, 8, 12, 16, 20, 24, 32, 48, 64}) add(0x2A, ptda::kCanFd, len, 0, "vcan0");
  add(0x2A, ptda::kCanFd | ptda::kCanFdBrs, 64, 0, "vcan0");
  add(0xABCDE, ptda::kCanFd | ptda::kCanFdEsi | ptda::kCanExtended, 5, 'R', "vcan0");
  add(0x2A, ptda::kCanFd | ptda::kCanFdBrs | ptda::kCanFdEsi, 2, 0, "vcan0");

  const fs::path dir = temp_dir("roundtrip");
  ptda::formats::write_candump(dir / "x.log", recs);
  const auto back = ptda::formats::read_candump(dir / "x.log");
  ASSERT_EQ(back.size(), recs.size());
  for (std::size_t i = 0; i < recs.size(); ++i) {
    SCOPED_TRACE(format_candump_line(recs[i]));
    EXPECT_EQ(back[i].iface, recs[i].iface);
    EXPECT_EQ(back[i].direction, recs[i].direction);
    EXPECT_EQ(back[i].frame.t_ns, recs[i].frame.t_ns);
    EXPECT_EQ(back[i].frame.id, recs[i].frame.id);
    EXPECT_EQ(back[i].frame.flags, recs[i].frame.flags);
    EXPECT_EQ(back[i].frame.len, recs[i].frame.len);
    EXPECT_EQ(back[i].frame.data, recs[i].frame.data);
  }
  fs::remove_all(dir);
}

TEST(Candump, ReaderDoesNotAllocatePerLine) {
  const fs::path dir = temp_dir("alloc");
  {
    std::ofstream out(dir / "a.log");
    for (int i = 0; i < 500; ++i)
      out << "(1700000000." << 100000 + i << ") can0 12345678##1" << std::string(128, 'A') << "\n";
  }
  ptda::formats::CandumpReader reader(dir / "a.log");
  CandumpRecord rec;
  ASSERT_TRUE(reader.next(rec));  // warm-up: line buffer and iface grow once
  int n = 1;
  ptda::test::AllocScope scope;
  while (reader.next(rec)) ++n;
  EXPECT_EQ(scope.count(), 0U);
  EXPECT_EQ(n, 500);
  EXPECT_EQ(rec.frame.t_ns, 1700000000'100499000);
  fs::remove_all(dir);
}

// Random and mutated lines must either parse or throw ptda::Error: never crash, never another exception.
TEST(Candump, GarbledLinesOnlyThrowPtdaError) {
  const std::vector<std::string> seeds = {"(1436509052.249713) vcan0 044#2A366C2BBA",
                                          "(1.000001) can0 12345678#DEADBEEF R",
                                          "(1.0) can0 123#R7 T",
                                          "(1.0) can0 20000080#0000000000000000",
                                          "(1.0) can0 123##1112233",
                                          "(1.0) can0 123#1122334455667788_E",
                                          "(1.0) can0 45123#81:00:12345678#11223344.556677"};
  const std::string alphabet = "0123456789ABCDEFabcdefRT#._:() \t\r-xZ";
  std::mt19937 rng(1234);
  int parsed = 0;
  int errors = 0;
  for (int iter = 0; iter < 40000; ++iter) {
    std::string line;
    if (iter % 4 == 0) {
      const std::size_t n = rng() % 80;
      line = "(";
      for (std::size_t i = 0; i < n; ++i) line += alphabet[rng() % alphabet.size()];
    } else {
      line = seeds[rng() % seeds.size()];
      const int edits = 1 + static_cast<int>(rng() % 4);
      for (int e = 0; e < edits && !line.empty(); ++e) {
        const std::size_t pos = rng() % line.size();
        switch (rng() % 4) {
          case 0:
            line[pos] = alphabet[rng() % alphabet.size()];
            break;
          case 1:
            line.insert(pos, 1, alphabet[rng() % alphabet.size()]);
            break;
          case 2:
            line.erase(pos, 1);
            break;
          default:
            line[pos] = static_cast<char>(rng() % 256);
            break;
        }
      }
    }
    try {
      if (parse_candump_line(line, "fuzz", iter)) ++parsed;
    } catch (const Error&) {
      ++errors;
    } catch (...) {
      ADD_FAILURE() << "non-ptda exception for line: " << line;
    }
  }
  // Both outcomes must occur, otherwise the generator is not exercising the parser.
  EXPECT_GT(parsed, 100);
  EXPECT_GT(errors, 100);
}

// The reader reads the file in 32 KiB chunks and splits lines itself (issue 13). Reference: split the
// same bytes at '\n' and parse each line alone. A ~400 KB log of random lines (classic, FD, remote,
// error frames, CRLF endings, blank and comment lines up to the 16384-character limit, no newline after
// the last line) puts lines across every chunk boundary; records, line numbers and comment counts must
// match the reference exactly.
TEST(Candump, ReaderMatchesLineByLineParsingAcrossChunkBoundaries) {
  const fs::path dir = temp_dir("chunks");
  std::mt19937 rng(77);
  const auto hex_bytes = [&rng](std::size_t n) {
    static constexpr char kHex[] = "0123456789ABCDEF";
    std::string s;
    for (std::size_t i = 0; i < 2 * n; ++i) s += kHex[rng() % 16];
    return s;
  };
  std::string text;
  int lines = 0;
  while (text.size() < 400000) {
    std::string line;
    switch (rng() % 8) {
      case 0:
        line = "(1700000000." + std::to_string(100000 + lines) + ") can0 123#" + hex_bytes(rng() % 9);
        break;
      case 1:
        line = "(1700000001.5) vcan1 12345678##1" + hex_bytes(rng() % 65) + " R";
        break;
      case 2:
        line = "(2.000001) can0 7FF#R" + std::to_string(rng() % 9) + " T";
        break;
      case 3:
        line = "(3.0) can0 20000080#" + hex_bytes(8);
        break;
      case 4:
        line = "";  // blank
        break;
      case 5:
        line =
            "# comment " + std::string(rng() % 40 == 0 ? 16384 - 11 : rng() % 200, 'c');  // + CR: the limit
        break;
      case 6:
        line = "  \t";  // blank (whitespace only)
        break;
      default:
        line = "(4.25) can0 044#" + hex_bytes(rng() % 9);
        break;
    }
    if (rng() % 5 == 0) line += '\r';
    text += line;
    text += '\n';
    ++lines;
  }
  text += "(5.5) can0 001#0102";  // the last line has no newline
  ++lines;
  {
    std::ofstream out(dir / "r.log", std::ios::binary);
    out << text;
  }

  std::vector<CandumpRecord> want;
  std::vector<long> want_line;
  std::uint64_t want_comments = 0;
  long want_first_comment = 0;
  long line_no = 0;
  for (std::size_t pos = 0; pos < text.size();) {
    const std::size_t nl = text.find('\n', pos);
    const std::size_t end = nl == std::string::npos ? text.size() : nl;
    const std::string line = text.substr(pos, end - pos);
    pos = end + 1;
    ++line_no;
    if (auto r = parse_candump_line(line, "r", line_no)) {
      want.push_back(*r);
      want_line.push_back(line_no);
    } else if (!line.empty() && line[0] != '(' && line.find_first_not_of(" \t\r") != std::string::npos) {
      if (want_comments++ == 0) want_first_comment = line_no;
    }
  }
  ASSERT_EQ(line_no, lines);
  ASSERT_GT(want.size(), 2000U);
  ASSERT_GT(want_comments, 100U);

  ptda::formats::CandumpReader reader(dir / "r.log");
  for (int pass = 0; pass < 2; ++pass) {  // the second pass after rewind() from the middle
    CandumpRecord rec;
    std::size_t i = 0;
    while (reader.next(rec)) {
      ASSERT_LT(i, want.size());
      EXPECT_EQ(reader.line_no(), want_line[i]);
      EXPECT_EQ(rec.frame.t_ns, want[i].frame.t_ns);
      EXPECT_EQ(rec.frame.id, want[i].frame.id);
      EXPECT_EQ(rec.frame.flags, want[i].frame.flags);
      EXPECT_EQ(rec.frame.len, want[i].frame.len);
      EXPECT_EQ(rec.frame.data, want[i].frame.data);
      EXPECT_EQ(rec.iface, want[i].iface);
      EXPECT_EQ(rec.direction, want[i].direction);
      ++i;
      if (pass == 0 && i == want.size() / 2) {
        reader.rewind();
        break;
      }
    }
    if (pass == 0) continue;
    EXPECT_EQ(i, want.size());
    EXPECT_EQ(reader.line_no(), lines);
    EXPECT_EQ(reader.comment_lines(), want_comments);
    EXPECT_EQ(reader.first_comment_line(), want_first_comment);
    EXPECT_FALSE(reader.next(rec));  // stays at the end
  }
  fs::remove_all(dir);
}

namespace {

// Writes `text` to dir/name, reads it to the end and returns the error message ("" when none).
std::string reader_error(const fs::path& dir, const std::string& name, const std::string& text,
                         std::size_t* records = nullptr) {
  {
    std::ofstream out(dir / name, std::ios::binary);
    out << text;
  }
  ptda::formats::CandumpReader reader(dir / name);
  CandumpRecord rec;
  std::size_t n = 0;
  try {
    while (reader.next(rec)) ++n;
  } catch (const Error& e) {
    if (records != nullptr) *records = n;
    return e.what();
  }
  if (records != nullptr) *records = n;
  return "";
}

}  // namespace

// Edge cases of the chunked reader, each error naming file:line: CRLF, no final newline, a line at and
// just over the length limit (also as the last line and across a chunk boundary), bad hex far into the
// file.
TEST(Candump, ReaderEdgeCasesNameFileAndLine) {
  const fs::path dir = temp_dir("edges");
  const std::string ok = "(1.5) can0 123#11\n";
  std::size_t n = 0;

  EXPECT_EQ(reader_error(dir, "crlf.log", "(1.5) can0 123#11\r\n(1.6) can0 124#2233\r\n", &n), "");
  EXPECT_EQ(n, 2U);
  EXPECT_EQ(reader_error(dir, "nonl.log", ok + "(1.6) can0 124#2233", &n), "");
  EXPECT_EQ(n, 2U);
  EXPECT_EQ(reader_error(dir, "nonl_cr.log", ok + "(1.6) can0 124#2233\r", &n), "");
  EXPECT_EQ(n, 2U);
  EXPECT_EQ(reader_error(dir, "empty.log", "", &n), "");
  EXPECT_EQ(n, 0U);
  EXPECT_EQ(reader_error(dir, "nl_only.log", "\n\n", &n), "");
  EXPECT_EQ(n, 0U);

  // 16384 characters (without the '\n') is the limit; one more is an error on that line.
  const std::string at_limit = "#" + std::string(16383, 'x');
  const std::string over = at_limit + "y";
  EXPECT_EQ(reader_error(dir, "at_limit.log", ok + at_limit + "\n" + ok, &n), "");
  EXPECT_EQ(n, 2U);
  EXPECT_EQ(reader_error(dir, "at_limit_last.log", ok + at_limit, &n), "");
  EXPECT_EQ(n, 1U);
  const std::string too_long = ":2: line longer than 16384 characters";
  EXPECT_EQ(reader_error(dir, "over.log", ok + over + "\n" + ok, &n), (dir / "over.log").string() + too_long);
  EXPECT_EQ(n, 1U);
  EXPECT_EQ(reader_error(dir, "over_last.log", ok + over), (dir / "over_last.log").string() + too_long);
  // A CR counts as a character of the line, as before.
  EXPECT_EQ(reader_error(dir, "over_cr.log", ok + at_limit + "\r\n"),
            (dir / "over_cr.log").string() + too_long);

  // Lines that fill most of a 32 KiB chunk and more, then the over-long line across a boundary.
  std::string filler;
  long filler_lines = 0;
  while (filler.size() < 60000) {
    filler += ok;
    ++filler_lines;
  }
  EXPECT_EQ(reader_error(dir, "over_boundary.log", filler + over + "\n" + ok, &n),
            (dir / "over_boundary.log").string() + ":" + std::to_string(filler_lines + 1) +
                ": line longer than 16384 characters");
  EXPECT_EQ(n, static_cast<std::size_t>(filler_lines));
  EXPECT_EQ(reader_error(dir, "limit_boundary.log", filler + at_limit + "\n" + ok, &n), "");
  EXPECT_EQ(n, static_cast<std::size_t>(filler_lines + 1));

  // Bad hex on a line in the third chunk, with CRLF endings.
  std::string crlf;
  long crlf_lines = 0;
  while (crlf.size() < 150000) {
    crlf += "(1.5) can0 123#11\r\n";
    ++crlf_lines;
  }
  EXPECT_EQ(reader_error(dir, "bad_hex.log", crlf + "(1.6) can0 124#1G\r\n" + ok, &n),
            (dir / "bad_hex.log").string() + ":" + std::to_string(crlf_lines + 1) +
                ": odd number of hex digits in classic CAN data");
  EXPECT_EQ(n, static_cast<std::size_t>(crlf_lines));
  EXPECT_EQ(reader_error(dir, "bad_char.log", crlf + "(1.6) can0 124#ZZ"),
            (dir / "bad_char.log").string() + ":" + std::to_string(crlf_lines + 1) +
                ": bad character 'Z' in classic CAN data");
  // A NUL byte is an ordinary character of a line (here: bad data).
  EXPECT_EQ(reader_error(dir, "nul.log", ok + std::string("(1.6) can0 124#1\0", 17) + "\n"),
            (dir / "nul.log").string() + ":2: odd number of hex digits in classic CAN data");
  fs::remove_all(dir);
}

namespace {

std::string record_text(const CandumpRecord& r);

// The full parser's outcome on one line: "error: <message>", "skipped", or the record's fields.
std::string full_outcome(const std::string& line) {
  CandumpRecord r;
  try {
    if (!ptda::formats::detail::parse_candump_line_full(line, "x.log", 3, r)) return "skipped";
  } catch (const Error& e) {
    return std::string("error: ") + e.what();
  }
  return record_text(r);
}

std::string record_text(const CandumpRecord& r) {
  std::string s = std::to_string(r.frame.t_ns) + " " + r.iface + " " + std::to_string(r.frame.id) + " " +
                  std::to_string(r.frame.flags) + " " + std::to_string(r.frame.len) + " " +
                  std::to_string(static_cast<int>(r.direction)) + " ";
  for (const std::uint8_t b : r.frame.data) s += std::to_string(b) + ",";
  return s;
}

}  // namespace

// The fast path decodes candump's classic frames to the values written out here by hand.
TEST(Candump, CommonLineParserGivesTheFrameOfCandumpsClassicLines) {
  using ptda::formats::detail::parse_common_candump_line;
  CandumpRecord r;
  r.frame.data.fill(0xEE);  // a reused record: bytes past len must come back as 0
  ASSERT_TRUE(parse_common_candump_line("(1700000000.001824) can0 184#3E810B004A260000", r));
  EXPECT_EQ(r.frame.t_ns, 1700000000001824000LL);
  EXPECT_EQ(r.iface, "can0");
  EXPECT_EQ(r.frame.id, 0x184U);
  EXPECT_EQ(r.frame.flags, 0);
  ASSERT_EQ(r.frame.len, 8);
  const std::uint8_t want[8] = {0x3E, 0x81, 0x0B, 0x00, 0x4A, 0x26, 0x00, 0x00};
  for (std::size_t k = 0; k < 8; ++k) EXPECT_EQ(r.frame.data[k], want[k]) << k;
  EXPECT_EQ(r.direction, 0);

  ASSERT_TRUE(parse_common_candump_line("(0.5) vcan12 1FFFFFFF#aB T", r));
  EXPECT_EQ(r.frame.t_ns, 500000000);
  EXPECT_EQ(r.iface, "vcan12");
  EXPECT_EQ(r.frame.id, 0x1FFFFFFFU);
  EXPECT_EQ(r.frame.flags, ptda::kCanExtended);
  ASSERT_EQ(r.frame.len, 1);
  EXPECT_EQ(r.frame.data[0], 0xAB);
  for (std::size_t k = 1; k < r.frame.data.size(); ++k) EXPECT_EQ(r.frame.data[k], 0) << k;
  EXPECT_EQ(r.direction, 'T');

  ASSERT_TRUE(parse_common_candump_line("(9223372035.999999999) c 7FF# R", r));
  EXPECT_EQ(r.frame.t_ns, 9223372035999999999LL);  // the largest seconds the full parser accepts
  EXPECT_EQ(r.frame.id, 0x7FFU);
  EXPECT_EQ(r.frame.len, 0);
  EXPECT_EQ(r.direction, 'R');

  // Other shapes are declined and leave the record as it was.
  const std::string before = record_text(r);
  for (const char* line : {"(9223372036.0) c 7FF#", "(1.5) can0 800#11", "(1.5) can0 20000080#11",
                           "(1.5) can0 123#R", "(1.5) can0 123##011", "(1.5) can0 123#11.22",
                           "(1.5) can0 123#1122334455667788_9", "(1.5)  can0 123#11", "(1.5) can0 123#11 ",
                           "(1.5)\tcan0 123#11", "(1.5) can0 123#112", "(1.5) can0 1234#11", "(1.) c 123#",
                           "(1.5) can0 123#112233445566778899", "(.5) c 123#", "(1.5) c 123#11 X"}) {
    EXPECT_FALSE(parse_common_candump_line(line, r)) << line;
    EXPECT_EQ(record_text(r), before) << line;
  }
}

// Every line the fast path accepts, the full parser accepts with the same record; lines of every frame
// kind and every one-character substitution, deletion and insertion of them (which the full parser
// rejects, skips or accepts) are tried. The fast path must also take the classic lines themselves.
TEST(Candump, CommonLineParserAgreesWithTheFullParser) {
  using ptda::formats::detail::parse_common_candump_line;
  const std::vector<std::string> bases = {
      "(1700000000.001824) can0 184#3E810B004A260000",
      "(1436509052.249713) vcan0 044#2A366C2BBA",
      "(0000000001.5) c 123#",
      "(1.123456789) can1 12345678#DEADBEEF R",
      "(12.25) can0 7ff#0a T",
      "(3.0) can0 20000080#0011223344556677",
      "(1.5) can0 123#R7 T",
      "(1.5) can0 123##1112233",
      "(1.5) can0 123#11.22.33",
      "(1.5) can0 123#1122334455667788_E",
      "(1.5) can0 12345#00:11:22334455#AA",
  };
  const std::string alphabet = std::string(" \t#._RTGgFf09():\r\x80") + '\0';
  std::vector<std::string> lines = bases;
  for (const std::string& b : bases) {
    for (std::size_t i = 0; i <= b.size(); ++i) {
      if (i < b.size()) lines.push_back(b.substr(0, i) + b.substr(i + 1));
      for (const char c : alphabet) {
        lines.push_back(b.substr(0, i) + c + b.substr(i));
        if (i < b.size()) {
          std::string t = b;
          t[i] = c;
          lines.push_back(t);
        }
      }
    }
  }
  std::size_t taken = 0;
  for (const std::string& line : lines) {
    CandumpRecord r;
    if (!parse_common_candump_line(line, r)) continue;
    ++taken;
    EXPECT_EQ(record_text(r), full_outcome(line)) << line;
  }
  for (std::size_t k = 0; k < 5; ++k) {
    CandumpRecord r;
    EXPECT_TRUE(parse_common_candump_line(bases[k], r)) << bases[k];
  }
  EXPECT_GT(taken, 1000U);  // the mutations of the classic lines that are still classic lines
}
