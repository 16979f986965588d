#include "status/text_escape.hpp"

namespace ptda::daemon {

int utf8_sequence(std::string_view s) noexcept {
  if (s.empty()) return -1;
  const auto b0 = static_cast<unsigned char>(s[0]);
  if (b0 < 0x80) return 1;
  // Unicode Table 3-7 (well-formed UTF-8 byte sequences): the length, and the range of the second
  // byte, by the lead byte; the third and fourth bytes are always 80..BF.
  int len = 0;
  unsigned char lo = 0x80;
  unsigned char hi = 0xBF;
  if (b0 >= 0xC2 && b0 <= 0xDF) {
    len = 2;
  } else if (b0 == 0xE0) {
    len = 3;
    lo = 0xA0;  // below: overlong
  } else if (b0 == 0xED) {
    len = 3;
    hi = 0x9F;  // above: UTF-16 surrogates
  } else if (b0 >= 0xE1 && b0 <= 0xEF) {
    len = 3;
  } else if (b0 == 0xF0) {
    len = 4;
    lo = 0x90;  // below: overlong
  } else if (b0 == 0xF4) {
    len = 4;
    hi = 0x8F;  // above: beyond U+10FFFF
  } else if (b0 >= 0xF1 && b0 <= 0xF3) {
    len = 4;
  } else {
    return -1;  // 80..C1 (continuation, overlong 2-byte lead), F5..FF
  }
  for (int i = 1; i < len; ++i) {
    if (static_cast<std::size_t>(i) >= s.size()) return -i;  // cut short
    const auto b = static_cast<unsigned char>(s[static_cast<std::size_t>(i)]);
    if (b < lo || b > hi) return -i;
    lo = 0x80;
    hi = 0xBF;
  }
  return len;
}

bool is_valid_utf8(std::string_view s) noexcept {
  while (!s.empty()) {
    const int n = utf8_sequence(s);
    if (n < 0) return false;
    s.remove_prefix(static_cast<std::size_t>(n));
  }
  return true;
}

namespace {

/// Output into a fixed buffer; remembers overflow.
class Out {
 public:
  Out(char* data, std::size_t cap) noexcept : data_(data), cap_(cap) {}
  void put(std::string_view s) noexcept {
    if (len_ == kEscapeOverflow) return;
    if (s.size() > cap_ - len_) {
      len_ = kEscapeOverflow;
      return;
    }
    for (const char c : s) data_[len_++] = c;
  }
  [[nodiscard]] std::size_t result() const noexcept { return len_; }

 private:
  char* data_;
  std::size_t cap_;
  std::size_t len_ = 0;
};

/// Walks `in` by UTF-8 sequence: ill-formed subparts become U+FFFD, single bytes (ASCII) go through
/// `ascii`, well-formed multi-byte sequences are copied.
template <class Ascii>
std::size_t escape_utf8(std::string_view in, char* out, std::size_t cap, Ascii ascii) noexcept {
  Out o(out, cap);
  while (!in.empty()) {
    const int n = utf8_sequence(in);
    if (n < 0) {
      o.put(kReplacementChar);
      in.remove_prefix(static_cast<std::size_t>(-n));
    } else if (n == 1) {
      ascii(o, in[0]);
      in.remove_prefix(1);
    } else {
      o.put(in.substr(0, static_cast<std::size_t>(n)));
      in.remove_prefix(static_cast<std::size_t>(n));
    }
  }
  return o.result();
}

/// The escapes JSON and Prometheus share (\" \\ \n); false when `c` is none of them.
bool put_shared_escape(Out& o, char c) noexcept {
  switch (c) {
    case '"':
      o.put("\\\"");
      return true;
    case '\\':
      o.put("\\\\");
      return true;
    case '\n':
      o.put("\\n");
      return true;
    default:
      return false;
  }
}

}  // namespace

std::size_t escape_json_body(std::string_view in, char* out, std::size_t cap) noexcept {
  return escape_utf8(in, out, cap, [](Out& o, char c) noexcept {
    static constexpr char kHex[] = "0123456789abcdef";
    if (put_shared_escape(o, c)) return;
    switch (c) {
      case '\b':
        o.put("\\b");
        break;
      case '\f':
        o.put("\\f");
        break;
      case '\r':
        o.put("\\r");
        break;
      case '\t':
        o.put("\\t");
        break;
      default: {
        const auto u = static_cast<unsigned char>(c);
        if (u < 0x20) {
          const char esc[6] = {'\\', 'u', '0', '0', kHex[u >> 4], kHex[u & 0xF]};
          o.put(std::string_view(esc, 6));
        } else {
          o.put(std::string_view(&c, 1));
        }
      }
    }
  });
}

std::size_t escape_prom_label_value(std::string_view in, char* out, std::size_t cap) noexcept {
  return escape_utf8(in, out, cap, [](Out& o, char c) noexcept {
    if (put_shared_escape(o, c)) return;
    if (c == '\0') {
      o.put(kReplacementChar);
    } else {
      o.put(std::string_view(&c, 1));
    }
  });
}

}  // namespace ptda::daemon
