// Command-line parsing of the ptda subcommands: options, value parsers, speed units, --windows ranges,
// and the exit codes/messages run_cli() gives for usage errors.
#include "ptda/cli/args.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#include "ptda/cli/commands.hpp"

namespace ptda::cli {
namespace {

ArgParser make_parser() {
  ArgParser p("train", "--recording DIR --config FILE", "test parser");
  p.option("recording", "DIR", "recording", true, true)
      .option("config", "FILE", "config", true)
      .option("windows", "FROM:TO", "fraction")
      .flag("quiet", "quiet");
  return p;
}

std::string usage_message(const ArgParser& p, const std::vector<std::string>& args) {
  try {
    (void)p.parse(args);
  } catch (const UsageError& e) {
    return e.what();
  }
  return "<no error>";
}

TEST(ArgParser, ParsesValuesFlagsRepeatsAndEqualsForm) {
  const auto p = make_parser();
  const std::vector<std::string> args = {"--recording", "a", "--config=c.toml", "--recording=b", "--quiet"};
  const ParsedArgs a = p.parse(args);
  EXPECT_FALSE(a.help());
  EXPECT_EQ(a.values("recording"), (std::vector<std::string>{"a", "b"}));
  EXPECT_EQ(a.value("config"), "c.toml");
  EXPECT_TRUE(a.has("quiet"));
  EXPECT_FALSE(a.has("windows"));
  EXPECT_EQ(a.value_or("windows", "0:1"), "0:1");
}

TEST(ArgParser, UnknownOptionIsNamed) {
  EXPECT_EQ(usage_message(make_parser(), {"--recording", "a", "--config", "c", "--bogus", "1"}),
            "unknown option --bogus");
}

TEST(ArgParser, MissingValueIsNamed) {
  EXPECT_EQ(usage_message(make_parser(), {"--recording", "a", "--config"}),
            "option --config needs a value (FILE)");
}

TEST(ArgParser, MissingRequiredOptionIsNamed) {
  EXPECT_EQ(usage_message(make_parser(), {"--recording", "a"}), "missing required option --config FILE");
}

TEST(ArgParser, SingleValueOptionGivenTwiceIsAnError) {
  EXPECT_EQ(usage_message(make_parser(), {"--recording", "a", "--config", "x", "--config", "y"}),
            "option --config given twice (it takes one value)");
}

TEST(ArgParser, PositionalArgumentAndFlagValueAreErrors) {
  EXPECT_EQ(usage_message(make_parser(), {"stray"}), "unexpected argument 'stray' (options start with --)");
  EXPECT_EQ(usage_message(make_parser(), {"--quiet=1"}), "option --quiet takes no value");
}

TEST(ArgParser, HelpSkipsRequiredCheckAndListsOptions) {
  const auto p = make_parser();
  const std::vector<std::string> args = {"--help"};
  EXPECT_TRUE(p.parse(args).help());
  const std::string h = p.help_text();
  EXPECT_NE(h.find("usage: ptda train --recording DIR --config FILE"), std::string::npos);
  EXPECT_NE(h.find("--recording DIR"), std::string::npos);
  EXPECT_NE(h.find("(required) (repeatable)"), std::string::npos);
  EXPECT_NE(h.find("-h, --help"), std::string::npos);
}

TEST(ValueParsers, Numbers) {
  EXPECT_DOUBLE_EQ(parse_double_arg("64500", "rate"), 64500.0);
  EXPECT_DOUBLE_EQ(parse_double_arg("+2.5e-3", "scale"), 2.5e-3);
  EXPECT_EQ(parse_u64_arg("18446744073709551615", "seed"), 18446744073709551615ULL);
  try {
    (void)parse_double_arg("12x", "rate");
    FAIL() << "no error";
  } catch (const UsageError& e) {
    EXPECT_STREQ(e.what(), "--rate: not a number '12x'");
  }
  EXPECT_THROW((void)parse_double_arg("inf", "rate"), UsageError);
  EXPECT_THROW((void)parse_double_arg("", "rate"), UsageError);
  EXPECT_THROW((void)parse_u64_arg("-1", "seed"), UsageError);
  EXPECT_THROW((void)parse_u64_arg("18446744073709551616", "seed"), UsageError);
}

TEST(SpeedUnits, AllUnitsGiveRadPerSecond) {
  constexpr double kTwoPi = 2.0 * std::numbers::pi;
  EXPECT_DOUBLE_EQ(parse_speed_rad_s("30Hz", "s"), 30.0 * kTwoPi);  // 188.4955592153876
  EXPECT_DOUBLE_EQ(parse_speed_rad_s("30 rev/s", "s"), 30.0 * kTwoPi);
  EXPECT_DOUBLE_EQ(parse_speed_rad_s("1800rpm", "s"), 30.0 * kTwoPi);
  EXPECT_DOUBLE_EQ(parse_speed_rad_s("188.5rad/s", "s"), 188.5);
  EXPECT_DOUBLE_EQ(parse_speed_rad_s("30HZ", "s"), 30.0 * kTwoPi);
  EXPECT_DOUBLE_EQ(parse_speed_rad_s("-2.5RAD/S", "s"), -2.5);
  EXPECT_NEAR(parse_speed_rad_s("30Hz", "s"), 188.49555921538757, 1e-12);
}

TEST(SpeedUnits, ErrorsSayWhatIsWrong) {
  auto msg = [](const char* text) {
    try {
      (void)parse_speed_rad_s(text, "shaft-speed");
    } catch (const UsageError& e) {
      return std::string(e.what());
    }
    return std::string("<no error>");
  };
  EXPECT_EQ(msg("30"), "--shaft-speed: speed '30' needs a unit (Hz, rev/s, rpm or rad/s)");
  EXPECT_EQ(msg("30 furlongs"),
            "--shaft-speed: unknown speed unit 'furlongs' in '30 furlongs' (use Hz, rev/s, rpm or rad/s)");
  EXPECT_EQ(msg("Hz"), "--shaft-speed: speed does not start with a number 'Hz'");
  EXPECT_EQ(msg("0rpm"), "--shaft-speed: speed must be finite and non-zero, got '0rpm'");
}

TEST(FractionRangeParse, FirstHalfAndBounds) {
  const FractionRange r = parse_fraction_range("0:0.5", "windows");
  EXPECT_EQ(r.from, 0.0);
  EXPECT_EQ(r.to, 0.5);
  EXPECT_FALSE(r.whole());
  EXPECT_EQ(r.first(41), 0U);
  EXPECT_EQ(r.last(41), 20U);  // floor(20.5)
  const FractionRange s = parse_fraction_range("0.5:1", "windows");
  EXPECT_EQ(s.first(41), 20U);
  EXPECT_EQ(s.last(41), 41U);  // the two halves partition the windows
  EXPECT_TRUE(parse_fraction_range("0:1", "windows").whole());
}

TEST(FractionRangeParse, Errors) {
  auto msg = [](const char* text) {
    try {
      (void)parse_fraction_range(text, "windows");
    } catch (const UsageError& e) {
      return std::string(e.what());
    }
    return std::string("<no error>");
  };
  EXPECT_EQ(msg("0.5"), "--windows: expected FROM:TO fractions such as 0:0.5, got '0.5'");
  EXPECT_EQ(msg("0.6:0.5"),
            "--windows: need 0 <= FROM < TO <= 1 (fractions of the window count), got '0.6:0.5'");
  EXPECT_EQ(msg("0:1.5"), "--windows: need 0 <= FROM < TO <= 1 (fractions of the window count), got '0:1.5'");
  EXPECT_EQ(msg("a:1"), "--windows: not a number 'a'");
}

// Usage errors through the dispatcher: exit code 2 and "ptda <cmd>: <what>" on stderr, nothing run.
int run(const std::vector<std::string>& args, std::string& out, std::string& err) {
  std::ostringstream o, e;
  const int rc = run_cli(args, o, e);
  out = o.str();
  err = e.str();
  return rc;
}

TEST(RunCli, UsageErrorsExitTwoWithMessage) {
  std::string out, err;
  EXPECT_EQ(
      run({"monitor", "--recording", "r", "--config", "c", "--baseline", "b", "--method", "fft"}, out, err),
      kExitUsage);
  EXPECT_EQ(err,
            "ptda monitor: --method: expected ptda, tda or raw, got 'fft'\n(try 'ptda monitor --help')\n");
  EXPECT_EQ(run({"train", "--config", "c", "--out", "b"}, out, err), kExitUsage);
  EXPECT_EQ(err, "ptda train: missing required option --recording DIR\n(try 'ptda train --help')\n");
  EXPECT_EQ(run({"import", "--csv", "x.csv", "--column", "a1", "--rate", "64500", "--shaft-speed", "30",
                 "--out", "o"},
                out, err),
            kExitUsage);
  EXPECT_NE(err.find("ptda import: --shaft-speed: speed '30' needs a unit"), std::string::npos);
  EXPECT_EQ(run({"import", "--csv", "x.csv", "--column", "a1", "--rate", "64500.5", "--shaft-speed", "30Hz",
                 "--out", "o"},
                out, err),
            kExitUsage);
  EXPECT_NE(err.find("--rate: need a positive whole number of Hz"), std::string::npos);
  EXPECT_EQ(run({"frobnicate"}, out, err), kExitUsage);
  EXPECT_EQ(err, "ptda: unknown command 'frobnicate' (try 'ptda --help')\n");
  EXPECT_EQ(run({"simulate", "--scenario", "s.toml", "--out", "d", "--seed", "x"}, out, err), kExitUsage);
  EXPECT_EQ(err, "ptda simulate: --seed: not a non-negative integer 'x'\n(try 'ptda simulate --help')\n");
}

TEST(RunCli, HelpOnEveryCommandExitsZero) {
  std::string out, err;
  EXPECT_EQ(run({"--help"}, out, err), kExitOk);
  for (const char* cmd : {"simulate", "import", "train", "monitor", "report"}) {
    EXPECT_NE(out.find(std::string("  ") + cmd), std::string::npos) << cmd;
  }
  for (const char* cmd : {"simulate", "import", "train", "monitor", "report"}) {
    EXPECT_EQ(run({cmd, "--help"}, out, err), kExitOk) << cmd;
    EXPECT_EQ(out.rfind(std::string("usage: ptda ") + cmd, 0), 0U) << out;
    EXPECT_TRUE(err.empty()) << err;
  }
}

}  // namespace
}  // namespace ptda::cli
