#include "ptda/config/toml_reader.hpp"

#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

#include "ptda/common/error.hpp"
#include "ptda/common/file_check.hpp"

namespace ptda::config {
namespace {

std::string format_number(double v) {
  std::ostringstream os;
  os.precision(12);
  os << v;
  return os.str();
}

// "an integer", "a string", ... for "must be X, not <article type>".
std::string with_article(toml::node_type type) {
  const std::string_view name = toml_type_name(type);
  const bool vowel = !name.empty() && std::string_view("aeiou").find(name.front()) != std::string_view::npos;
  return (vowel ? "an " : "a ") + std::string(name);
}

}  // namespace

SourceLocation location_of(const toml::source_region& region, const std::string& fallback_source) {
  SourceLocation loc;
  loc.source = (region.path && !region.path->empty()) ? *region.path : fallback_source;
  loc.line = static_cast<long>(region.begin.line);
  loc.column = static_cast<long>(region.begin.column);
  return loc;
}

void fail_at(const SourceLocation& where, const std::string& what) {
  throw Error(where.source.empty() ? std::string("<config>") : where.source, where.line, where.column, what);
}

toml::table parse_toml(std::string_view text, const std::string& source) {
  try {
    return toml::parse(text, source);
  } catch (const toml::parse_error& e) {
    fail_at(location_of(e.source(), source), "TOML syntax error: " + std::string(e.description()));
  }
}

toml::table read_toml_file(const std::filesystem::path& path) {
  // A regular file of bounded size: a FIFO or /dev/zero must not hang or flood configure (issue 14).
  // Root must not run a configuration others can write (issue 14 item 8).
  return parse_toml(read_regular_file(path, kMaxConfigFileBytes, "configuration file", ::geteuid()),
                    path.string());
}

std::string_view toml_type_name(toml::node_type type) noexcept {
  switch (type) {
    case toml::node_type::none:
      return "nothing";
    case toml::node_type::table:
      return "table";
    case toml::node_type::array:
      return "array";
    case toml::node_type::string:
      return "string";
    case toml::node_type::integer:
      return "integer";
    case toml::node_type::floating_point:
      return "float";
    case toml::node_type::boolean:
      return "boolean";
    case toml::node_type::date:
      return "date";
    case toml::node_type::time:
      return "time";
    case toml::node_type::date_time:
      return "date-time";
  }
  return "value";
}

TableReader::TableReader(const toml::table& table, std::string name, std::string source)
    : table_(table), name_(std::move(name)), source_(std::move(source)) {}

std::string TableReader::qualified(std::string_view key) const {
  return name_.empty() ? std::string(key) : name_ + "." + std::string(key);
}

const toml::node* TableReader::find(std::string_view key) {
  known_.emplace_back(key);
  return table_.get(key);
}

SourceLocation TableReader::location(std::string_view key, bool value_location) const {
  const auto it = table_.find(key);
  if (it == table_.end()) return location_of(table_.source(), source_);
  return value_location ? location_of(it->second.source(), source_)
                        : location_of(it->first.source(), source_);
}

void TableReader::fail_value(std::string_view key, const std::string& what) const {
  fail_at(location(key), qualified(key) + " " + what);
}

bool TableReader::read(std::string_view key, double& out, double lo, double hi) {
  const toml::node* node = find(key);
  if (node == nullptr) return false;
  double v = 0.0;
  if (const auto* f = node->as_floating_point()) {
    v = f->get();
  } else if (const auto* i = node->as_integer()) {
    v = static_cast<double>(i->get());
  } else {
    fail_value(key, "must be a number, not " + with_article(node->type()));
  }
  if (!std::isfinite(v)) fail_value(key, "must be a finite number");
  if (v < lo || v > hi) {
    fail_value(key, "= " + format_number(v) + " is outside " + format_number(lo) + ".." + format_number(hi));
  }
  out = v;
  return true;
}

bool TableReader::read(std::string_view key, std::uint32_t& out, std::uint32_t lo, std::uint32_t hi) {
  const toml::node* node = find(key);
  if (node == nullptr) return false;
  const auto* i = node->as_integer();
  if (i == nullptr) fail_value(key, "must be an integer, not " + with_article(node->type()));
  const std::int64_t v = i->get();
  if (v < static_cast<std::int64_t>(lo) || v > static_cast<std::int64_t>(hi)) {
    fail_value(key,
               "= " + std::to_string(v) + " is outside " + std::to_string(lo) + ".." + std::to_string(hi));
  }
  out = static_cast<std::uint32_t>(v);
  return true;
}

bool TableReader::read(std::string_view key, std::uint8_t& out, std::uint8_t lo, std::uint8_t hi) {
  std::uint32_t v = 0;
  if (!read(key, v, lo, hi)) return false;
  out = static_cast<std::uint8_t>(v);
  return true;
}

bool TableReader::read(std::string_view key, bool& out) {
  const toml::node* node = find(key);
  if (node == nullptr) return false;
  const auto* b = node->as_boolean();
  if (b == nullptr) {
    fail_value(key, "must be a boolean (true/false), not " + with_article(node->type()));
  }
  out = b->get();
  return true;
}

bool TableReader::read(std::string_view key, std::string& out) {
  const toml::node* node = find(key);
  if (node == nullptr) return false;
  const auto* s = node->as_string();
  if (s == nullptr) fail_value(key, "must be a string, not " + with_article(node->type()));
  // Every string is a path or a name: a NUL would cut it, megabytes of it are a mistake (item 8).
  if (const std::string problem = string_value_problem(s->get()); !problem.empty()) fail_value(key, problem);
  out = s->get();
  return true;
}

const toml::table* TableReader::table(std::string_view key) {
  const toml::node* node = find(key);
  if (node == nullptr) return nullptr;
  const auto* t = node->as_table();
  if (t == nullptr) fail_value(key, "must be a table, not " + with_article(node->type()));
  return t;
}

void TableReader::ignore(std::string_view key) {
  known_.emplace_back(key);
}

void TableReader::finish() const {
  // toml++ keeps keys sorted by name; report the unknown key that comes first in the file.
  const toml::key* first = nullptr;
  const toml::node* first_node = nullptr;
  for (const auto& [key, node] : table_) {
    bool is_known = false;
    for (const auto& k : known_) is_known = is_known || k == key.str();
    if (is_known) continue;
    const auto& pos = key.source().begin;
    if (first == nullptr || pos.line < first->source().begin.line ||
        (pos.line == first->source().begin.line && pos.column < first->source().begin.column)) {
      first = &key;
      first_node = &node;
    }
  }
  if (first == nullptr) return;
  std::string list;
  for (const auto& k : known_) list += (list.empty() ? "" : ", ") + k;
  const std::string where = name_.empty() ? std::string("at the top level") : "in [" + name_ + "]";
  const std::string kind = first_node->is_table() ? "table" : "key";
  fail_at(location_of(first->source(), source_),
          "unknown " + kind + " '" + std::string(first->str()) + "' " + where + " (known: " + list + ")");
}

}  // namespace ptda::config
