// Strict parser and writer for `candump -l` logs (can-utils "compact" frame syntax).
#include "ptda/formats/candump.hpp"

#include <array>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <limits>
#include <memory>

#include "ptda/common/error.hpp"
#include "ptda/common/file_check.hpp"
#include "ptda/common/time.hpp"

namespace ptda::formats {
namespace {

constexpr std::uint32_t kCanErrFlag = 0x20000000U;
constexpr std::uint32_t kCanEffMask = 0x1FFFFFFFU;
constexpr std::uint32_t kCanSffMask = 0x7FFU;
constexpr std::size_t kClassicMaxLen = 8;
constexpr std::size_t kFdMaxLen = 64;
constexpr std::size_t kXlMaxLen = 2048;
// Longest sensible line: a CAN XL frame with 2048 bytes and separators is about 6200 characters.
constexpr std::size_t kMaxLineChars = 16384;
// Bytes read from the file at a time by CandumpReader (issue 13: one read per chunk, not a getc per
// character). With the line limit the reader holds 48 KiB; the FILE itself is unbuffered.
constexpr std::size_t kReadChunk = 32768;

// Value of every byte as a hex digit, -1 for the bytes that are not one.
constexpr std::array<std::int8_t, 256> make_hex_table() noexcept {
  std::array<std::int8_t, 256> t{};
  for (int c = 0; c < 256; ++c) {
    int v = -1;
    if (c >= '0' && c <= '9') v = c - '0';
    if (c >= 'A' && c <= 'F') v = c - 'A' + 10;
    if (c >= 'a' && c <= 'f') v = c - 'a' + 10;
    t[static_cast<std::size_t>(c)] = static_cast<std::int8_t>(v);
  }
  return t;
}
constexpr std::array<std::int8_t, 256> kHexValue = make_hex_table();

int hex_val(char c) noexcept {
  return kHexValue[static_cast<unsigned char>(c)];
}
bool is_space(char c) noexcept {
  return c == ' ' || c == '\t';
}

// Carries where the line came from so each check can throw "<source>:<line>: <what>".
struct LineContext {
  const std::string& source;
  long line_no;
  [[noreturn]] void fail(const std::string& what) const { throw Error(source, line_no, 0, what); }
};

std::string show_text(std::string_view s) {
  constexpr std::size_t kMaxShown = 40;
  std::string q = "'";
  q.append(s.substr(0, kMaxShown));
  if (s.size() > kMaxShown) q += "...";
  q += "'";
  return q;
}

// Hex string of at most 8 digits to a number; fails on any non-hex character.
std::uint32_t parse_hex_u32(std::string_view s, const LineContext& ctx, const char* what) {
  std::uint32_t v = 0;
  for (const char c : s) {
    const int h = hex_val(c);
    if (h < 0) ctx.fail(std::string(what) + " " + show_text(s) + " is not hexadecimal");
    v = (v << 4) | static_cast<std::uint32_t>(h);
  }
  return v;
}

// Hex bytes with optional single '.' separators (before, between or after bytes), stopping at the end
// or at '_' when `stop_at_underscore`. Writes into dst when not null. Returns the bytes parsed and sets
// `used` to the characters consumed.
std::size_t parse_data(std::string_view s, std::uint8_t* dst, std::size_t max_len, bool stop_at_underscore,
                       const char* kind, const LineContext& ctx, std::size_t& used) {
  std::size_t n = 0;
  std::size_t i = 0;
  bool sep_ok = true;
  while (i < s.size()) {
    const char c = s[i];
    if (c == '.') {
      if (!sep_ok) ctx.fail(std::string("empty byte between '.' separators in ") + kind + " data");
      sep_ok = false;
      ++i;
      continue;
    }
    if (c == '_' && stop_at_underscore) break;
    const int hi = hex_val(c);
    if (hi < 0) ctx.fail(std::string("bad character '") + c + "' in " + kind + " data");
    if (i + 1 >= s.size() || hex_val(s[i + 1]) < 0)
      ctx.fail(std::string("odd number of hex digits in ") + kind + " data");
    if (n == max_len) ctx.fail(std::string(kind) + " data longer than " + std::to_string(max_len) + " bytes");
    if (dst != nullptr) dst[n] = static_cast<std::uint8_t>((hi << 4) | hex_val(s[i + 1]));
    ++n;
    i += 2;
    sep_ok = true;
  }
  used = i;
  return n;
}

// Newer can-utils append "_<dlc>" (9..F) after 8 data bytes to carry len8_dlc; we accept and ignore it.
void parse_len8_suffix(std::string_view rest, std::size_t len, const LineContext& ctx) {
  if (rest.empty()) return;
  if (rest[0] != '_') ctx.fail("unexpected " + show_text(rest) + " after the frame data");
  if (len != kClassicMaxLen) ctx.fail("'_<dlc>' suffix is only valid after 8 data bytes");
  if (rest.size() != 2 || hex_val(rest[1]) < 9)
    ctx.fail("bad '_<dlc>' suffix " + show_text(rest) + " (expected _9.._F)");
}

// CAN XL: <vcid:2hex><prio:3hex>#<flags:2hex>:<sdt:2hex>:<af:8hex>#<data>. Validated, then ignored.
void check_xl(std::string_view rest, const LineContext& ctx) {
  const auto hex_field = [&](std::size_t pos, std::size_t n) {
    if (rest.size() < pos + n) return false;
    for (std::size_t k = pos; k < pos + n; ++k) {
      if (hex_val(rest[k]) < 0) return false;
    }
    return true;
  };
  if (!hex_field(0, 2) || rest.size() < 3 || rest[2] != ':' || !hex_field(3, 2) || rest.size() < 6 ||
      rest[5] != ':' || !hex_field(6, 8) || rest.size() < 15 || rest[14] != '#')
    ctx.fail("malformed CAN XL frame (expected <vcid><prio>#<flags>:<sdt>:<af>#<data>)");
  std::size_t used = 0;
  parse_data(rest.substr(15), nullptr, kXlMaxLen, false, "CAN XL", ctx, used);
}

// Parses the frame token into out.frame (t_ns untouched). Returns false for an ignored CAN XL frame.
bool parse_frame(std::string_view tok, CanFrame& f, const LineContext& ctx) {
  const std::size_t hash = tok.find('#');
  if (hash == std::string_view::npos) ctx.fail("frame " + show_text(tok) + " has no '#'");
  const std::string_view id_str = tok.substr(0, hash);
  std::string_view rest = tok.substr(hash + 1);
  if (id_str.size() == 5 && rest.find(':') != std::string_view::npos) {
    parse_hex_u32(id_str, ctx, "CAN XL priority/VCID");
    check_xl(rest, ctx);
    return false;
  }
  f.flags = 0;
  f.len = 0;
  f.data.fill(0);  // bytes past len are zero, so frames compare equal however the record was reused
  bool is_err = false;
  if (id_str.size() == 3) {
    f.id = parse_hex_u32(id_str, ctx, "CAN id");
    // Three hex digits can reach 0xFFF; only 11 bits are a standard id.
    if (f.id > kCanSffMask) ctx.fail("standard CAN id " + show_text(id_str) + " exceeds 11 bits (max 7FF)");
  } else if (id_str.size() == 8) {
    const std::uint32_t v = parse_hex_u32(id_str, ctx, "CAN id");
    if ((v & kCanErrFlag) != 0) {
      if ((v & ~(kCanErrFlag | kCanEffMask)) != 0)
        ctx.fail("error frame id " + show_text(id_str) + " has bits above CAN_ERR_FLAG set");
      is_err = true;
      f.id = v & kCanEffMask;
      f.flags = kCanError;
    } else {
      if (v > kCanEffMask)
        ctx.fail("extended CAN id " + show_text(id_str) + " exceeds 29 bits (max 1FFFFFFF)");
      f.id = v;
      f.flags = kCanExtended;
    }
  } else {
    ctx.fail("bad CAN id length " + std::to_string(id_str.size()) + " in " + show_text(tok) +
             " (expected 3 or 8 hex digits)");
  }

  std::size_t used = 0;
  if (!rest.empty() && rest[0] == '#') {
    if (is_err) ctx.fail("error frames cannot be CAN FD frames");
    rest.remove_prefix(1);
    if (rest.empty()) ctx.fail("CAN FD frame without the flags nibble after '##'");
    const int fl = hex_val(rest[0]);
    if (fl < 0) ctx.fail(std::string("bad CAN FD flags nibble '") + rest[0] + "'");
    f.flags |= kCanFd;
    if ((fl & 1) != 0) f.flags |= kCanFdBrs;
    if ((fl & 2) != 0) f.flags |= kCanFdEsi;
    rest.remove_prefix(1);
    f.len = static_cast<std::uint8_t>(parse_data(rest, f.data.data(), kFdMaxLen, false, "CAN FD", ctx, used));
    return true;
  }
  if (!rest.empty() && rest[0] == 'R') {
    if (is_err) ctx.fail("error frames cannot be remote frames");
    f.flags |= kCanRtr;
    rest.remove_prefix(1);
    if (!rest.empty() && rest[0] != '_') {
      const int dlc = hex_val(rest[0]);
      if (dlc < 0) ctx.fail("bad remote frame DLC " + show_text(rest));
      if (dlc > static_cast<int>(kClassicMaxLen))
        ctx.fail("remote frame DLC " + std::to_string(dlc) + " exceeds 8");
      f.len = static_cast<std::uint8_t>(dlc);
      rest.remove_prefix(1);
    }
    parse_len8_suffix(rest, f.len, ctx);
    return true;
  }
  f.len = static_cast<std::uint8_t>(
      parse_data(rest, f.data.data(), kClassicMaxLen, true, "classic CAN", ctx, used));
  parse_len8_suffix(rest.substr(used), f.len, ctx);
  return true;
}

std::string_view next_token(std::string_view line, std::size_t& i) {
  const std::size_t start = i;
  while (i < line.size() && !is_space(line[i])) ++i;
  return line.substr(start, i - start);
}
bool skip_spaces(std::string_view line, std::size_t& i) {
  const std::size_t start = i;
  while (i < line.size() && is_space(line[i])) ++i;
  return i > start;
}

struct FileCloser {
  void operator()(std::FILE* f) const noexcept {
    if (f != nullptr) std::fclose(f);
  }
};

}  // namespace

namespace detail {

bool parse_common_candump_line(std::string_view line, CandumpRecord& out) {
  const std::size_t size = line.size();
  const char* const c = line.data();
  const auto digit = [c](std::size_t i) { return static_cast<unsigned>(c[i] - '0'); };
  if (size == 0 || c[0] != '(') return false;
  // "(<seconds>.<fraction>)": at most 18 digits of seconds (no overflow; more go to the full parser),
  // 1 to 9 of fraction.
  std::size_t i = 1;
  std::uint64_t sec = 0;
  while (i < size && digit(i) <= 9) {
    if (i == 19) return false;
    sec = sec * 10 + digit(i);
    ++i;
  }
  constexpr std::uint64_t kMaxSec =
      static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max() / kNsPerS) - 1;
  if (i == 1 || sec > kMaxSec || i >= size || c[i] != '.') return false;
  const std::size_t frac_start = ++i;
  std::int64_t frac_ns = 0;
  while (i < size && digit(i) <= 9) {
    if (i - frac_start == 9) return false;
    frac_ns = frac_ns * 10 + static_cast<std::int64_t>(digit(i));
    ++i;
  }
  const std::size_t n_frac = i - frac_start;
  if (n_frac == 0 || i + 1 >= size || c[i] != ')' || c[i + 1] != ' ') return false;
  for (std::size_t k = n_frac; k < 9; ++k) frac_ns *= 10;
  // " <iface> ": one space on either side, no tab.
  i += 2;
  const std::size_t iface_start = i;
  while (i < size && c[i] != ' ') {
    if (c[i] == '\t') return false;
    ++i;
  }
  if (i == iface_start || i + 1 >= size) return false;
  const std::size_t iface_len = i - iface_start;
  ++i;
  // "<id>#": 3 hex digits up to 7FF, or 8 up to 1FFFFFFF (no error flag).
  const std::size_t id_start = i;
  std::uint32_t id = 0;
  while (i < size && kHexValue[static_cast<unsigned char>(c[i])] >= 0) {
    if (i - id_start == 8) return false;
    id = (id << 4) | static_cast<std::uint32_t>(kHexValue[static_cast<unsigned char>(c[i])]);
    ++i;
  }
  const std::size_t id_len = i - id_start;
  if (i >= size || c[i] != '#') return false;
  std::uint8_t flags = 0;
  if (id_len == 3) {
    if (id > kCanSffMask) return false;
  } else if (id_len == 8) {
    if (id > kCanEffMask) return false;  // an error frame (or an out-of-range id)
    flags = kCanExtended;
  } else {
    return false;
  }
  ++i;
  // "<data>": up to 8 bytes as pairs of hex digits, no separators, then the end or " R" / " T".
  std::array<std::uint8_t, kClassicMaxLen> bytes{};
  std::size_t len = 0;
  while (i + 1 < size && c[i] != ' ') {
    const int hi = kHexValue[static_cast<unsigned char>(c[i])];
    const int lo = kHexValue[static_cast<unsigned char>(c[i + 1])];
    if (hi < 0 || lo < 0 || len == kClassicMaxLen) return false;
    bytes[len++] = static_cast<std::uint8_t>((hi << 4) | lo);
    i += 2;
  }
  char direction = 0;
  if (i != size) {
    if (i + 2 != size || c[i] != ' ' || (c[i + 1] != 'R' && c[i + 1] != 'T')) return false;
    direction = c[i + 1];
  }
  CanFrame& f = out.frame;
  f.t_ns = static_cast<std::int64_t>(sec) * kNsPerS + frac_ns;
  f.id = id;
  f.flags = flags;
  f.len = static_cast<std::uint8_t>(len);
  f.data.fill(0);
  std::memcpy(f.data.data(), bytes.data(), bytes.size());  // the bytes past len are 0
  out.direction = direction;
  out.iface.assign(c + iface_start, iface_len);
  return true;
}

}  // namespace detail

bool parse_candump_line_into(std::string_view line, const std::string& source, long line_no,
                             CandumpRecord& out) {
  while (!line.empty() && (line.back() == '\n' || line.back() == '\r')) line.remove_suffix(1);
  if (line.empty() || line.front() != '(') return false;
  // Nearly every line of a log is a classic data frame in candump's own spelling: that shape has its
  // own parser (issue 13: candump parsing was about 6 % of `ptda monitor`); any other line, and any
  // line it does not accept, goes through the full parser, which decides and names the error.
  if (detail::parse_common_candump_line(line, out)) return true;
  return detail::parse_candump_line_full(line, source, line_no, out);
}

namespace detail {

bool parse_candump_line_full(std::string_view line, const std::string& source, long line_no,
                             CandumpRecord& out) {
  while (!line.empty() && (line.back() == '\n' || line.back() == '\r')) line.remove_suffix(1);
  if (line.empty() || line.front() != '(') return false;
  const LineContext ctx{source, line_no};

  // Timestamp "(<seconds>.<fraction>)", converted with integer arithmetic so no precision is lost.
  std::size_t i = 1;
  const std::size_t sec_start = i;
  while (i < line.size() && line[i] >= '0' && line[i] <= '9') ++i;
  if (i == sec_start) ctx.fail("timestamp: expected seconds digits after '('");
  std::uint64_t sec = 0;
  const auto r = std::from_chars(line.data() + sec_start, line.data() + i, sec);
  constexpr std::uint64_t kMaxSec =
      static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max() / kNsPerS) - 1;
  if (r.ec != std::errc{} || sec > kMaxSec) ctx.fail("timestamp: seconds out of range");
  if (i >= line.size() || line[i] != '.') ctx.fail("timestamp: expected '.' after the seconds");
  ++i;
  const std::size_t frac_start = i;
  std::int64_t frac_ns = 0;
  while (i < line.size() && line[i] >= '0' && line[i] <= '9') {
    if (i - frac_start == 9) ctx.fail("timestamp: more than 9 fraction digits");
    frac_ns = frac_ns * 10 + (line[i] - '0');
    ++i;
  }
  const std::size_t n_frac = i - frac_start;
  if (n_frac == 0) ctx.fail("timestamp: expected fraction digits after '.'");
  for (std::size_t k = n_frac; k < 9; ++k) frac_ns *= 10;
  if (i >= line.size() || line[i] != ')') ctx.fail("timestamp: expected ')' after the fraction");
  ++i;
  out.frame.t_ns = static_cast<std::int64_t>(sec) * kNsPerS + frac_ns;

  if (!skip_spaces(line, i)) ctx.fail("expected a space after the timestamp");
  const std::string_view iface = next_token(line, i);
  if (iface.empty()) ctx.fail("missing interface name");
  skip_spaces(line, i);
  const std::string_view frame = next_token(line, i);
  if (frame.empty()) ctx.fail("missing frame after the interface name");
  skip_spaces(line, i);
  const std::string_view dir = next_token(line, i);
  out.direction = 0;
  if (!dir.empty()) {
    if (dir.size() != 1 || (dir[0] != 'R' && dir[0] != 'T'))
      ctx.fail("unexpected " + show_text(dir) + " after the frame (expected direction R or T)");
    out.direction = dir[0];
  }
  skip_spaces(line, i);
  if (i != line.size()) ctx.fail("unexpected trailing text " + show_text(line.substr(i)));

  if (!parse_frame(frame, out.frame, ctx)) return false;
  out.iface.assign(iface.data(), iface.size());
  return true;
}

}  // namespace detail

std::optional<CandumpRecord> parse_candump_line(std::string_view line, const std::string& source,
                                                long line_no) {
  CandumpRecord rec;
  if (!parse_candump_line_into(line, source, line_no, rec)) return std::nullopt;
  return rec;
}

CandumpReader::CandumpReader(const std::filesystem::path& path) : path_(path), source_(path.string()) {
  require_regular_file(path, kNoSizeLimit, "candump log");  // a FIFO would block, /dev/zero never end
  f_ = std::fopen(source_.c_str(), "rb");
  if (f_ == nullptr) throw Error(source_ + ": cannot open candump log: " + std::strerror(errno));
  // No stdio buffer: every fread() is a whole chunk, read straight into buf_ (if this fails, the FILE
  // keeps its own buffer, which only costs memory).
  (void)std::setvbuf(f_, nullptr, _IONBF, 0);
  // Room for the longest accepted line, its newline and one more chunk: next() never reallocates.
  buf_.resize(kReadChunk + kMaxLineChars + 1);
}

CandumpReader::~CandumpReader() {
  if (f_ != nullptr) std::fclose(f_);
}

void CandumpReader::rewind() noexcept {
  std::rewind(f_);
  begin_ = 0;
  end_ = 0;
  eof_ = false;
  line_no_ = 0;
  comment_lines_ = 0;
  first_comment_line_ = 0;
}

bool CandumpReader::next_line(std::string_view& line) {
  std::size_t scanned = 0;  // bytes after begin_ already known to hold no '\n'
  for (;;) {
    const char* const start = buf_.data() + begin_;
    const std::size_t avail = end_ - begin_;
    const void* const nl = std::memchr(start + scanned, '\n', avail - scanned);
    if (nl != nullptr) {
      const auto len = static_cast<std::size_t>(static_cast<const char*>(nl) - start);
      if (len > kMaxLineChars) break;
      line = std::string_view(start, len);
      begin_ += len + 1;
      return true;
    }
    if (avail > kMaxLineChars) break;
    if (eof_) {
      if (avail == 0) return false;
      line = std::string_view(start, avail);  // the last line has no newline
      begin_ = end_;
      return true;
    }
    // Keep the partial line at the front of the buffer, then append one more chunk after it.
    if (begin_ != 0) {
      std::memmove(buf_.data(), start, avail);
      begin_ = 0;
      end_ = avail;
    }
    scanned = avail;
    const std::size_t got = std::fread(buf_.data() + end_, 1, buf_.size() - end_, f_);
    end_ += got;
    if (got == 0) {
      if (std::ferror(f_) != 0)
        throw Error(source_, line_no_ + 1, 0, std::string("read error: ") + std::strerror(errno));
      eof_ = true;
    }
  }
  throw Error(source_, line_no_ + 1, 0, "line longer than " + std::to_string(kMaxLineChars) + " characters");
}

bool CandumpReader::next(CandumpRecord& out) {
  std::string_view line;
  while (next_line(line)) {
    ++line_no_;
    if (parse_candump_line_into(line, source_, line_no_, out)) return true;
    if (!line.empty() && line[0] != '(' &&
        line.find_first_not_of(" \t\r") != std::string_view::npos) {  // a comment, not a blank line
      if (comment_lines_ == 0) first_comment_line_ = line_no_;
      ++comment_lines_;
    }
  }
  return false;
}

std::vector<CandumpRecord> read_candump(const std::filesystem::path& path) {
  CandumpReader reader(path);
  std::vector<CandumpRecord> out;
  CandumpRecord rec;
  while (reader.next(rec)) out.push_back(rec);
  return out;
}

std::string format_candump_line(const CandumpRecord& rec) {
  const CanFrame& f = rec.frame;
  if (f.t_ns < 0)
    throw Error("candump: cannot write a negative timestamp (" + std::to_string(f.t_ns) + " ns)");
  if (rec.iface.empty() || rec.iface.find_first_of(" \t\r\n") != std::string::npos)
    throw Error("candump: interface name " + show_text(rec.iface) + " is empty or contains whitespace");
  if (rec.direction != 0 && rec.direction != 'R' && rec.direction != 'T')
    throw Error(std::string("candump: bad direction '") + rec.direction + "' (R, T or none)");
  static constexpr char kHex[] = "0123456789ABCDEF";
  char ts[48];
  const int n = std::snprintf(ts, sizeof ts, "(%010lld.%06lld) ", static_cast<long long>(f.t_ns / kNsPerS),
                              static_cast<long long>((f.t_ns % kNsPerS) / 1000));
  std::string s(ts, static_cast<std::size_t>(n));
  s += rec.iface;
  s += ' ';
  const auto put_id = [&s](std::uint32_t id, int digits) {
    for (int k = digits - 1; k >= 0; --k) s += kHex[(id >> (4 * k)) & 0xFU];
  };
  if (f.error()) {
    if (f.id > kCanEffMask) throw Error("candump: error frame class bits exceed 29 bits");
    put_id(f.id | kCanErrFlag, 8);
  } else if (f.extended()) {
    if (f.id > kCanEffMask) throw Error("candump: extended id exceeds 29 bits");
    put_id(f.id, 8);
  } else {
    if (f.id > kCanSffMask) throw Error("candump: standard id exceeds 11 bits (set kCanExtended?)");
    put_id(f.id, 3);
  }
  s += '#';
  if (f.fd()) {
    if (f.rtr() || f.error()) throw Error("candump: a CAN FD frame cannot be a remote or error frame");
    if (f.len > kFdMaxLen) throw Error("candump: CAN FD payload longer than 64 bytes");
    s += '#';
    s += kHex[((f.flags & kCanFdBrs) != 0 ? 1 : 0) | ((f.flags & kCanFdEsi) != 0 ? 2 : 0)];
  } else if (f.rtr()) {
    if (f.error()) throw Error("candump: an error frame cannot be a remote frame");
    if (f.len > kClassicMaxLen) throw Error("candump: remote frame DLC exceeds 8");
    s += 'R';
    if (f.len > 0) s += kHex[f.len];
  } else if (f.len > kClassicMaxLen) {
    throw Error("candump: classic CAN payload longer than 8 bytes");
  }
  if (!f.rtr()) {
    for (std::size_t k = 0; k < f.len; ++k) {
      s += kHex[f.data[k] >> 4];
      s += kHex[f.data[k] & 0xFU];
    }
  }
  if (rec.direction != 0) {
    s += ' ';
    s += rec.direction;
  }
  return s;
}

void write_candump(const std::filesystem::path& path, const std::vector<CandumpRecord>& records) {
  CandumpWriter w(path);
  for (const CandumpRecord& r : records) w.write(r);
  w.close();
}

CandumpWriter::CandumpWriter(const std::filesystem::path& path) : name_(path.string()) {
  f_ = std::fopen(name_.c_str(), "wb");
  if (f_ == nullptr) throw Error(name_ + ": cannot create candump log: " + std::strerror(errno));
}

CandumpWriter::~CandumpWriter() {
  if (f_ != nullptr) std::fclose(f_);
}

void CandumpWriter::write(const CandumpRecord& rec) {
  if (f_ == nullptr) throw Error(name_ + ": write after close");
  std::string line;
  try {
    line = format_candump_line(rec);
  } catch (const Error& e) {
    throw Error(name_ + ": record " + std::to_string(written_) + ": " + e.what());
  }
  line += '\n';
  if (std::fwrite(line.data(), 1, line.size(), f_) != line.size())
    throw Error(name_ + ": write failed: " + std::strerror(errno));
  ++written_;
}

void CandumpWriter::close() {
  if (f_ == nullptr) return;
  std::FILE* f = f_;
  f_ = nullptr;
  if (std::fclose(f) != 0) throw Error(name_ + ": close failed: " + std::strerror(errno));
}

}  // namespace ptda::formats
