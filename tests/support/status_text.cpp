#include "status_text.hpp"

#include <cctype>
#include <fstream>
#include <sstream>

namespace ptda::test {

std::string read_text(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

bool JsonChecker::valid() {
  ws();
  if (!value()) return false;
  ws();
  return i_ == s_.size();
}

void JsonChecker::ws() {
  while (i_ < s_.size() && (s_[i_] == ' ' || s_[i_] == '\n' || s_[i_] == '\r' || s_[i_] == '\t')) ++i_;
}

bool JsonChecker::lit(std::string_view w) {
  if (s_.substr(i_, w.size()) != w) return false;
  i_ += w.size();
  return true;
}

bool JsonChecker::value() {
  if (i_ >= s_.size()) return false;
  switch (s_[i_]) {
    case '{':
      return object();
    case '[':
      return array();
    case '"':
      return string();
    case 't':
      return lit("true");
    case 'f':
      return lit("false");
    case 'n':
      return lit("null");
    default:
      return number();
  }
}

bool JsonChecker::object() {
  ++i_;
  ws();
  if (i_ < s_.size() && s_[i_] == '}') return ++i_, true;
  for (;;) {
    ws();
    if (!string()) return false;
    ws();
    if (!lit(":")) return false;
    ws();
    if (!value()) return false;
    ws();
    if (lit("}")) return true;
    if (!lit(",")) return false;
  }
}

bool JsonChecker::array() {
  ++i_;
  ws();
  if (i_ < s_.size() && s_[i_] == ']') return ++i_, true;
  for (;;) {
    ws();
    if (!value()) return false;
    ws();
    if (lit("]")) return true;
    if (!lit(",")) return false;
  }
}

bool JsonChecker::string() {
  if (!lit("\"")) return false;
  while (i_ < s_.size()) {
    const auto c = static_cast<unsigned char>(s_[i_++]);
    if (c == '"') return true;
    if (c < 0x20) return false;
    if (c == '\\') {
      if (i_ >= s_.size()) return false;
      const char e = s_[i_++];
      if (e == 'u') {
        for (int k = 0; k < 4; ++k) {
          if (i_ >= s_.size() || std::isxdigit(static_cast<unsigned char>(s_[i_++])) == 0) return false;
        }
      } else if (std::string_view("\"\\/bfnrt").find(e) == std::string_view::npos) {
        return false;
      }
    }
  }
  return false;
}

bool JsonChecker::number() {
  const std::size_t start = i_;
  if (i_ < s_.size() && s_[i_] == '-') ++i_;
  if (i_ >= s_.size() || !std::isdigit(static_cast<unsigned char>(s_[i_]))) return false;
  if (s_[i_] == '0') {
    ++i_;
  } else {
    while (i_ < s_.size() && std::isdigit(static_cast<unsigned char>(s_[i_]))) ++i_;
  }
  if (i_ < s_.size() && s_[i_] == '.') {
    ++i_;
    if (i_ >= s_.size() || !std::isdigit(static_cast<unsigned char>(s_[i_]))) return false;
    while (i_ < s_.size() && std::isdigit(static_cast<unsigned char>(s_[i_]))) ++i_;
  }
  if (i_ < s_.size() && (s_[i_] == 'e' || s_[i_] == 'E')) {
    ++i_;
    if (i_ < s_.size() && (s_[i_] == '+' || s_[i_] == '-')) ++i_;
    if (i_ >= s_.size() || !std::isdigit(static_cast<unsigned char>(s_[i_]))) return false;
    while (i_ < s_.size() && std::isdigit(static_cast<unsigned char>(s_[i_]))) ++i_;
  }
  return i_ > start;
}

std::vector<std::string> prom_samples(std::string_view text, std::string_view name) {
  std::vector<std::string> out;
  std::istringstream in{std::string(text)};
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind(std::string(name), 0) == 0 &&
        (line.size() > name.size() && (line[name.size()] == ' ' || line[name.size()] == '{'))) {
      out.push_back(line);
    }
  }
  return out;
}

}  // namespace ptda::test
