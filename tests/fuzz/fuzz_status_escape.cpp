// libFuzzer target: the status.json and Prometheus string escaping (daemon/status/text_escape.cpp)
// and TextBuffer's use of it (status_writer.cpp). Checks: the JSON body is valid UTF-8, has no raw
// control character or quote, and every escape is one RFC 8259 allows; the Prometheus label value is
// valid UTF-8 with no raw NUL, newline or quote; for valid UTF-8 input (without NUL for Prometheus)
// unescaping gives the input back; the exact output size fits and one byte less is an overflow
// (ASan sees any write past the buffer); TextBuffer gives the same bytes in quotes.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "fuzz_support.hpp"
#include "status/status_writer.hpp"
#include "status/text_escape.hpp"

namespace {

using ptda::daemon::kEscapeOverflow;

int hex(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

/// The JSON string body `s` unescaped, or trap when it is not a valid body.
std::string json_unescape(std::string_view s) {
  std::string out;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const auto c = static_cast<unsigned char>(s[i]);
    if (c < 0x20 || c == '"') __builtin_trap();
    if (c != '\\') {
      out += s[i];
      continue;
    }
    if (++i >= s.size()) __builtin_trap();
    switch (s[i]) {
      case '"':
        out += '"';
        break;
      case '\\':
        out += '\\';
        break;
      case '/':
        out += '/';
        break;
      case 'b':
        out += '\b';
        break;
      case 'f':
        out += '\f';
        break;
      case 'n':
        out += '\n';
        break;
      case 'r':
        out += '\r';
        break;
      case 't':
        out += '\t';
        break;
      case 'u': {
        if (s.size() - i < 5) __builtin_trap();
        int v = 0;
        for (int k = 1; k <= 4; ++k) {
          const int h = hex(s[i + static_cast<std::size_t>(k)]);
          if (h < 0) __builtin_trap();
          v = v * 16 + h;
        }
        if (v >= 0x20) __builtin_trap();  // only C0 controls are written as \u
        out += static_cast<char>(v);
        i += 4;
        break;
      }
      default:
        __builtin_trap();
    }
  }
  return out;
}

/// The Prometheus label value `s` unescaped, or trap when it is not a valid one.
std::string prom_unescape(std::string_view s) {
  std::string out;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '\0' || s[i] == '\n' || s[i] == '"') __builtin_trap();
    if (s[i] != '\\') {
      out += s[i];
      continue;
    }
    if (++i >= s.size()) __builtin_trap();
    if (s[i] == 'n') {
      out += '\n';
    } else if (s[i] == '\\' || s[i] == '"') {
      out += s[i];
    } else {
      __builtin_trap();
    }
  }
  return out;
}

using EscapeFn = std::size_t (*)(std::string_view, char*, std::size_t) noexcept;

/// Escapes `in` into a buffer of 6 bytes per input byte (the largest expansion), then again into
/// buffers of exactly the size needed and one byte less (heap buffers, so ASan catches overruns).
std::string escape_checked(EscapeFn fn, std::string_view in) {
  std::vector<char> big(6 * in.size() + 1);
  const std::size_t n = fn(in, big.data(), big.size());
  if (n == kEscapeOverflow || n > 6 * in.size()) __builtin_trap();
  std::vector<char> exact(n);
  if (fn(in, exact.data(), n) != n || std::string_view(exact.data(), n) != std::string_view(big.data(), n))
    __builtin_trap();
  if (n > 0) {
    std::vector<char> shorter(n - 1);
    if (fn(in, shorter.data(), n - 1) != kEscapeOverflow) __builtin_trap();
  }
  return std::string(big.data(), n);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view in = ptda::fuzz::as_text(data, size);
  const bool valid = ptda::daemon::is_valid_utf8(in);

  const std::string json = escape_checked(ptda::daemon::escape_json_body, in);
  if (!ptda::daemon::is_valid_utf8(json)) __builtin_trap();
  const std::string json_back = json_unescape(json);
  if (valid && json_back != in) __builtin_trap();
  if (!valid && json_back == in) __builtin_trap();

  const std::string prom = escape_checked(ptda::daemon::escape_prom_label_value, in);
  if (!ptda::daemon::is_valid_utf8(prom)) __builtin_trap();
  const std::string prom_back = prom_unescape(prom);
  if (valid && in.find('\0') == std::string_view::npos && prom_back != in) __builtin_trap();

  // TextBuffer: the same bytes in quotes; one byte short is an overflow, never a partial string.
  std::vector<char> buf(json.size() + 2);
  ptda::daemon::TextBuffer b(buf.data(), buf.size());
  b.append_json_string(in);
  if (b.overflow() || b.view() != "\"" + json + "\"") __builtin_trap();
  ptda::daemon::TextBuffer shorter(buf.data(), buf.size() - 1);
  shorter.append_json_string(in);
  if (!shorter.overflow()) __builtin_trap();
  ptda::daemon::TextBuffer label(buf.data(), buf.size());
  label.append_label_value(in);
  if (prom.size() <= buf.size() && (label.overflow() || label.view() != prom)) __builtin_trap();
  return 0;
}
