#include "status/text_escape.hpp"

#include <gtest/gtest.h>

#include <string>
#include <string_view>

namespace ptda::daemon {
namespace {

using namespace std::string_view_literals;

constexpr std::string_view kFffd = "\xEF\xBF\xBD";

std::string json(std::string_view in) {
  char buf[256];
  const std::size_t n = escape_json_body(in, buf, sizeof buf);
  EXPECT_NE(n, kEscapeOverflow);
  return n == kEscapeOverflow ? std::string() : std::string(buf, n);
}

std::string prom(std::string_view in) {
  char buf[256];
  const std::size_t n = escape_prom_label_value(in, buf, sizeof buf);
  EXPECT_NE(n, kEscapeOverflow);
  return n == kEscapeOverflow ? std::string() : std::string(buf, n);
}

std::string fffd(int count) {
  std::string s;
  for (int i = 0; i < count; ++i) s += kFffd;
  return s;
}

// Expected bytes: one U+FFFD per maximal subpart (Unicode §3.9), the same as Python's
// bytes.decode("utf-8", "replace").encode() gives for each input.
struct Case {
  std::string_view in;
  std::string out;
};

TEST(TextEscape, IllFormedUtf8BecomesReplacementCharacters) {
  const Case cases[] = {
      {"\xC0\x80"sv, fffd(2)},          // overlong NUL
      {"\xC1\xBF"sv, fffd(2)},          // overlong 2-byte
      {"\xE0\x80\x80"sv, fffd(3)},      // overlong 3-byte
      {"\xE0\x9F\xBF"sv, fffd(3)},      // overlong 3-byte (U+07FF)
      {"\xF0\x8F\xBF\xBF"sv, fffd(4)},  // overlong 4-byte (U+FFFF)
      {"\xED\xA0\x80"sv, fffd(3)},      // surrogate U+D800
      {"\xED\xBF\xBF"sv, fffd(3)},      // surrogate U+DFFF
      {"\xF4\x90\x80\x80"sv, fffd(4)},  // U+110000
      {"\xF5\x80"sv, fffd(2)},          // lead byte never valid
      {"\xFF"sv, fffd(1)},              //
      {"\x80\xBF"sv, fffd(2)},          // stray continuation bytes
      {"\xE2\x82"sv, fffd(1)},          // cut short at the end
      {"\xF0\x9F\x98"sv, fffd(1)},      // cut short at the end
      {"a\xE2\x82"
       "b"sv,
       "a" + fffd(1) + "b"},                                     // cut short by ASCII
      {"\xF0\x9F\x98\xE2\x82\xAC"sv, fffd(1) + "\xE2\x82\xAC"},  // cut short by a valid sequence
  };
  for (const Case& c : cases) {
    EXPECT_EQ(json(c.in), c.out) << testing::PrintToString(std::string(c.in));
    EXPECT_EQ(prom(c.in), c.out) << testing::PrintToString(std::string(c.in));
    EXPECT_FALSE(is_valid_utf8(c.in));
    EXPECT_TRUE(is_valid_utf8(json(c.in)));
  }
}

TEST(TextEscape, WellFormedUtf8IsCopied) {
  for (const std::string_view s : {"\xC3\xA9"sv, "\xE2\x82\xAC"sv, "\xED\x9F\xBF"sv, "\xEE\x80\x80"sv,
                                   "\xF0\x9F\x98\x80"sv, "\xF4\x8F\xBF\xBF"sv, "\xC2\x80"sv}) {
    EXPECT_TRUE(is_valid_utf8(s));
    EXPECT_EQ(json(s), s);
    EXPECT_EQ(prom(s), s);
  }
  EXPECT_EQ(utf8_sequence("\xF0\x9F\x98\x80"), 4);
  EXPECT_EQ(utf8_sequence("\xF0\x9F\x98"), -3);
  EXPECT_EQ(utf8_sequence("\xE0\x80"), -1);
  EXPECT_EQ(utf8_sequence("a"), 1);
}

TEST(TextEscape, JsonControlCharactersAndNul) {
  EXPECT_EQ(json("a\0b"sv), "a\\u0000b");
  EXPECT_EQ(json("\"\\\b\f\n\r\t"sv), "\\\"\\\\\\b\\f\\n\\r\\t");
  EXPECT_EQ(json("\x01\x1f\x7f/"sv), "\\u0001\\u001f\x7f/");
  EXPECT_EQ(json("C:\\x \"q\""sv), "C:\\\\x \\\"q\\\"");
}

TEST(TextEscape, PrometheusEscapesAndNul) {
  EXPECT_EQ(prom("a\"b\\c\nd\te\r"sv), "a\\\"b\\\\c\\nd\te\r");
  EXPECT_EQ(prom("a\0b"sv), "a" + fffd(1) + "b");
}

TEST(TextEscape, OverflowIsReported) {
  char buf[8];
  EXPECT_EQ(escape_json_body("1234567", buf, 7), 7U);
  EXPECT_EQ(escape_json_body("12345678", buf, 7), kEscapeOverflow);
  EXPECT_EQ(escape_json_body("123456\n", buf, 7), kEscapeOverflow);  // the escape does not fit
  EXPECT_EQ(escape_prom_label_value("\0"sv, buf, 2), kEscapeOverflow);
  EXPECT_EQ(escape_prom_label_value("\0"sv, buf, 3), 3U);
  EXPECT_EQ(escape_json_body("", buf, 0), 0U);
}

}  // namespace
}  // namespace ptda::daemon
