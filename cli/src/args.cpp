#include "ptda/cli/args.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <numbers>
#include <optional>
#include <sstream>
#include <system_error>

namespace ptda::cli {

namespace {

std::string quoted(std::string_view s) {
  return "'" + std::string(s) + "'";
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front())) != 0) s.remove_prefix(1);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back())) != 0) s.remove_suffix(1);
  return s;
}

std::string lower(std::string_view s) {
  std::string out(s);
  std::transform(out.begin(), out.end(), out.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return out;
}

// Parses the longest numeric prefix of s; returns the number of characters used (0: none).
std::size_t parse_number_prefix(std::string_view s, double& out) {
  const char* begin = s.data();
  const char* end = s.data() + s.size();
  if (begin != end && *begin == '+') ++begin;  // from_chars refuses a leading '+'
  const auto r = std::from_chars(begin, end, out);
  if (r.ec != std::errc{}) return 0;
  return static_cast<std::size_t>(r.ptr - s.data());
}

}  // namespace

bool ParsedArgs::has(std::string_view name) const {
  return values_.find(name) != values_.end();
}

const std::string& ParsedArgs::value(std::string_view name) const {
  const auto it = values_.find(name);
  if (it == values_.end() || it->second.empty()) {
    throw UsageError("missing required option --" + std::string(name));
  }
  return it->second.back();
}

std::string ParsedArgs::value_or(std::string_view name, std::string_view fallback) const {
  const auto it = values_.find(name);
  if (it == values_.end() || it->second.empty()) return std::string(fallback);
  return it->second.back();
}

std::vector<std::string> ParsedArgs::values(std::string_view name) const {
  const auto it = values_.find(name);
  if (it == values_.end()) return {};
  return it->second;
}

ArgParser::ArgParser(std::string command, std::string synopsis, std::string description)
    : command_(std::move(command)), synopsis_(std::move(synopsis)), description_(std::move(description)) {}

ArgParser& ArgParser::option(std::string name, std::string value_name, std::string help, bool required,
                             bool repeatable) {
  options_.push_back(
      OptionSpec{std::move(name), std::move(value_name), std::move(help), required, repeatable});
  return *this;
}

ArgParser& ArgParser::flag(std::string name, std::string help) {
  options_.push_back(OptionSpec{std::move(name), "", std::move(help), false, false});
  return *this;
}

const OptionSpec* ArgParser::find(std::string_view name) const noexcept {
  for (const auto& o : options_) {
    if (o.name == name) return &o;
  }
  return nullptr;
}

ParsedArgs ArgParser::parse(std::span<const std::string> args) const {
  ParsedArgs parsed;
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string_view arg = args[i];
    if (arg == "-h" || arg == "--help") {
      parsed.help_ = true;
      continue;
    }
    if (arg.size() < 3 || arg.substr(0, 2) != "--") {
      throw UsageError("unexpected argument " + quoted(arg) + " (options start with --)");
    }
    std::string_view name = arg.substr(2);
    std::optional<std::string_view> inline_value;
    if (const auto eq = name.find('='); eq != std::string_view::npos) {
      inline_value = name.substr(eq + 1);
      name = name.substr(0, eq);
    }
    const OptionSpec* spec = find(name);
    if (spec == nullptr) throw UsageError("unknown option --" + std::string(name));
    auto& slot = parsed.values_[spec->name];
    if (spec->value_name.empty()) {
      if (inline_value) throw UsageError("option --" + spec->name + " takes no value");
      if (!slot.empty()) throw UsageError("option --" + spec->name + " given twice");
      slot.emplace_back("");
      continue;
    }
    std::string value;
    if (inline_value) {
      value = std::string(*inline_value);
    } else {
      if (i + 1 >= args.size()) {
        throw UsageError("option --" + spec->name + " needs a value (" + spec->value_name + ")");
      }
      value = args[++i];
    }
    if (value.empty()) throw UsageError("option --" + spec->name + " has an empty value");
    if (!spec->repeatable && !slot.empty()) {
      throw UsageError("option --" + spec->name + " given twice (it takes one value)");
    }
    slot.push_back(std::move(value));
  }
  if (!parsed.help_) {
    for (const auto& o : options_) {
      if (o.required && !parsed.has(o.name)) {
        throw UsageError("missing required option --" + o.name + " " + o.value_name);
      }
    }
  }
  return parsed;
}

std::string ArgParser::help_text() const {
  std::ostringstream s;
  s << "usage: ptda " << command_ << " " << synopsis_ << "\n\n" << description_ << "\n\noptions:\n";
  std::size_t width = 0;
  std::vector<std::string> heads;
  for (const auto& o : options_) {
    std::string head = "  --" + o.name;
    if (!o.value_name.empty()) head += " " + o.value_name;
    width = std::max(width, head.size());
    heads.push_back(std::move(head));
  }
  heads.emplace_back("  -h, --help");
  width = std::max(width, heads.back().size());
  for (std::size_t i = 0; i < options_.size(); ++i) {
    const auto& o = options_[i];
    std::string help = o.help;
    if (o.required) help += " (required)";
    if (o.repeatable) help += " (repeatable)";
    s << heads[i] << std::string(width - heads[i].size() + 2, ' ') << help << "\n";
  }
  s << heads.back() << std::string(width - heads.back().size() + 2, ' ') << "show this help\n";
  return s.str();
}

double parse_double_arg(std::string_view text, std::string_view option) {
  const std::string_view t = trim(text);
  double v = 0.0;
  const std::size_t used = parse_number_prefix(t, v);
  if (t.empty() || used != t.size()) {
    throw UsageError("--" + std::string(option) + ": not a number " + quoted(text));
  }
  if (!std::isfinite(v))
    throw UsageError("--" + std::string(option) + ": not a finite number " + quoted(text));
  return v;
}

std::uint64_t parse_u64_arg(std::string_view text, std::string_view option) {
  const std::string_view t = trim(text);
  std::uint64_t v = 0;
  const auto r = std::from_chars(t.data(), t.data() + t.size(), v);
  if (t.empty() || r.ec == std::errc::invalid_argument || r.ptr != t.data() + t.size()) {
    throw UsageError("--" + std::string(option) + ": not a non-negative integer " + quoted(text));
  }
  if (r.ec == std::errc::result_out_of_range) {
    throw UsageError("--" + std::string(option) + ": integer out of range " + quoted(text));
  }
  return v;
}

double parse_speed_rad_s(std::string_view text, std::string_view option) {
  const std::string opt = "--" + std::string(option);
  const std::string_view t = trim(text);
  double v = 0.0;
  const std::size_t used = parse_number_prefix(t, v);
  if (used == 0) throw UsageError(opt + ": speed does not start with a number " + quoted(text));
  const std::string unit = lower(trim(t.substr(used)));
  if (unit.empty()) {
    throw UsageError(opt + ": speed " + quoted(text) + " needs a unit (Hz, rev/s, rpm or rad/s)");
  }
  constexpr double kTwoPi = 2.0 * std::numbers::pi;
  double rad_s = 0.0;
  if (unit == "hz" || unit == "rev/s" || unit == "rps") {
    rad_s = v * kTwoPi;
  } else if (unit == "rpm" || unit == "rev/min") {
    rad_s = v * kTwoPi / 60.0;
  } else if (unit == "rad/s") {
    rad_s = v;
  } else {
    throw UsageError(opt + ": unknown speed unit " + quoted(unit) + " in " + quoted(text) +
                     " (use Hz, rev/s, rpm or rad/s)");
  }
  if (!std::isfinite(rad_s) || rad_s == 0.0) {
    throw UsageError(opt + ": speed must be finite and non-zero, got " + quoted(text));
  }
  return rad_s;
}

std::uint64_t FractionRange::first(std::uint64_t count) const noexcept {
  return static_cast<std::uint64_t>(std::floor(from * static_cast<double>(count)));
}

std::uint64_t FractionRange::last(std::uint64_t count) const noexcept {
  if (to >= 1.0) return count;
  return std::min<std::uint64_t>(count,
                                 static_cast<std::uint64_t>(std::floor(to * static_cast<double>(count))));
}

FractionRange parse_fraction_range(std::string_view text, std::string_view option) {
  const std::string opt = "--" + std::string(option);
  const auto colon = text.find(':');
  if (colon == std::string_view::npos) {
    throw UsageError(opt + ": expected FROM:TO fractions such as 0:0.5, got " + quoted(text));
  }
  FractionRange r;
  r.from = parse_double_arg(text.substr(0, colon), option);
  r.to = parse_double_arg(text.substr(colon + 1), option);
  if (r.from < 0.0 || r.to > 1.0 || !(r.from < r.to)) {
    throw UsageError(opt + ": need 0 <= FROM < TO <= 1 (fractions of the window count), got " + quoted(text));
  }
  return r;
}

}  // namespace ptda::cli
