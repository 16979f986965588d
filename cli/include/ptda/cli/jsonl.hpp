// JSON Lines output written by hand: one object per line, strings escaped per RFC 8259, numbers in
// the shortest form that reads back to the same double (std::to_chars), NaN/Inf written as null
// (JSON has no such numbers). Thread: any. Allocates.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace ptda::cli {

/// s as a JSON string literal including the quotes: ", \ and control characters escaped
/// (\n \r \t \b \f, others as \u00XX); bytes >= 0x80 are copied (UTF-8 passes through).
[[nodiscard]] std::string json_string(std::string_view s);
/// Shortest round-trip decimal form of v; "null" when v is NaN or infinite.
[[nodiscard]] std::string json_number(double v);

/// Builds one JSON object: `JsonObject o; o.add("n", 3); line = o.str();` -> {"n":3}
class JsonObject {
 public:
  JsonObject& add(std::string_view key, double v);
  JsonObject& add(std::string_view key, std::int64_t v);
  JsonObject& add(std::string_view key, std::uint64_t v);
  JsonObject& add(std::string_view key, int v) { return add(key, static_cast<std::int64_t>(v)); }
  JsonObject& add(std::string_view key, unsigned v) { return add(key, static_cast<std::uint64_t>(v)); }
  JsonObject& add(std::string_view key, bool v);
  JsonObject& add(std::string_view key, std::string_view v);
  JsonObject& add(std::string_view key, const char* v) { return add(key, std::string_view(v)); }
  JsonObject& add_null(std::string_view key);
  /// A two-element number array [a, b] (e.g. a band).
  JsonObject& add_pair(std::string_view key, double a, double b);
  /// Integer or null.
  JsonObject& add_optional(std::string_view key, std::optional<std::int64_t> v);

  /// The object text without a trailing newline.
  [[nodiscard]] std::string str() const { return body_ + "}"; }

 private:
  void key(std::string_view k);
  std::string body_ = "{";
};

}  // namespace ptda::cli

#include <map>
#include <memory>
#include <vector>

namespace ptda::cli {

/// A parsed JSON value (reader for our own JSONL output: tests and tools read it back).
struct JsonValue {
  enum class Kind : std::uint8_t { kNull, kBool, kNumber, kString, kArray, kObject };
  Kind kind = Kind::kNull;
  bool boolean = false;
  double number = 0.0;
  std::string string;
  std::vector<JsonValue> array;
  std::map<std::string, JsonValue, std::less<>> object;

  [[nodiscard]] bool is_null() const noexcept { return kind == Kind::kNull; }
  /// Member of an object; throws ptda::Error naming the key when absent or not an object.
  [[nodiscard]] const JsonValue& at(std::string_view key) const;
  /// The number; throws ptda::Error when not a number.
  [[nodiscard]] double as_number() const;
  [[nodiscard]] bool as_bool() const;
  [[nodiscard]] const std::string& as_string() const;
};

/// Parses one complete JSON text (e.g. one JSONL line). Throws ptda::Error "<source>: column N: what".
[[nodiscard]] JsonValue parse_json(std::string_view text, const std::string& source);

}  // namespace ptda::cli
