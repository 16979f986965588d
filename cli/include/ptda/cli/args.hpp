// Command-line parsing for the `ptda` subcommands: a small declarative option table, value parsers
// that say which option was wrong, and the usage error that maps to exit code 2.
// Thread: any (offline tool). Everything here may allocate and throws on bad input.
#pragma once

#include <cstdint>
#include <map>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "ptda/common/error.hpp"

namespace ptda::cli {

/// The command line itself is wrong (unknown option, missing value, malformed number...): exit code 2.
class UsageError : public Error {
 public:
  explicit UsageError(const std::string& what) : Error(what) {}
};

struct OptionSpec {
  std::string name;        ///< without the leading "--"
  std::string value_name;  ///< empty: a flag without value
  std::string help;
  bool required = false;
  bool repeatable = false;
};

/// The options of one parsed command line.
class ParsedArgs {
 public:
  [[nodiscard]] bool help() const noexcept { return help_; }
  [[nodiscard]] bool has(std::string_view name) const;
  /// The single value of a value option; throws UsageError when absent.
  [[nodiscard]] const std::string& value(std::string_view name) const;
  /// The value or `fallback` when the option was not given.
  [[nodiscard]] std::string value_or(std::string_view name, std::string_view fallback) const;
  /// Every value of a repeatable option, in command-line order (empty when absent).
  [[nodiscard]] std::vector<std::string> values(std::string_view name) const;

 private:
  friend class ArgParser;
  bool help_ = false;
  std::map<std::string, std::vector<std::string>, std::less<>> values_;
};

/// Declares the options of one subcommand, parses its arguments and formats its --help.
class ArgParser {
 public:
  ArgParser(std::string command, std::string synopsis, std::string description);

  /// An option taking a value ("--name VALUE" or "--name=VALUE").
  ArgParser& option(std::string name, std::string value_name, std::string help, bool required = false,
                    bool repeatable = false);
  /// A flag without value ("--name").
  ArgParser& flag(std::string name, std::string help);

  /// Parses args (without the program and subcommand names). "-h"/"--help" anywhere sets help()
  /// and skips the required-option check. Throws UsageError naming the offending argument.
  [[nodiscard]] ParsedArgs parse(std::span<const std::string> args) const;

  [[nodiscard]] std::string help_text() const;
  [[nodiscard]] const std::string& command() const noexcept { return command_; }

 private:
  [[nodiscard]] const OptionSpec* find(std::string_view name) const noexcept;

  std::string command_;
  std::string synopsis_;
  std::string description_;
  std::vector<OptionSpec> options_;
};

// ---- value parsers: each throws UsageError "--<option>: <what> '<text>'" ----------------------------

/// A finite decimal number (the whole text, no trailing characters).
[[nodiscard]] double parse_double_arg(std::string_view text, std::string_view option);
/// A non-negative integer that fits in 64 bits.
[[nodiscard]] std::uint64_t parse_u64_arg(std::string_view text, std::string_view option);

/// A shaft speed with unit: "30Hz" or "30rev/s" (revolutions per second), "1800rpm", "188.5rad/s";
/// spaces between number and unit are allowed, units are case-insensitive. Returns rad/s.
/// Zero, non-finite or unitless values are errors.
[[nodiscard]] double parse_speed_rad_s(std::string_view text, std::string_view option);

/// A fraction range "FROM:TO" with 0 <= FROM < TO <= 1 (e.g. "0:0.5" = first half).
struct FractionRange {
  double from = 0.0;
  double to = 1.0;
  /// Indices [first, last) of `count` items the range keeps: floor(from*count) .. floor(to*count),
  /// with to == 1 always reaching count.
  [[nodiscard]] std::uint64_t first(std::uint64_t count) const noexcept;
  [[nodiscard]] std::uint64_t last(std::uint64_t count) const noexcept;
  [[nodiscard]] bool whole() const noexcept { return from == 0.0 && to == 1.0; }
};
[[nodiscard]] FractionRange parse_fraction_range(std::string_view text, std::string_view option);

}  // namespace ptda::cli
