#include "adc/iio_sysfs_value.hpp"

#include <gtest/gtest.h>

#include <string>
#include <string_view>

#include "ptda/common/error.hpp"

namespace ptda::drivers {
namespace {

using namespace std::string_view_literals;

std::string rate_error(std::string_view text) {
  try {
    (void)parse_sysfs_rate_hz(text, "dev/sampling_frequency");
  } catch (const Error& e) {
    return e.what();
  }
  return "accepted";
}

std::string index_error(std::string_view text) {
  try {
    (void)parse_sysfs_index(text, "se/in_x_index");
  } catch (const Error& e) {
    return e.what();
  }
  return "accepted";
}

TEST(IioSysfsValue, RatesAsTheKernelPrintsThem) {
  EXPECT_EQ(parse_sysfs_rate_hz("25600\n", "f"), 25600.0);
  EXPECT_EQ(parse_sysfs_rate_hz("1600.500000\n", "f"), 1600.5);
  EXPECT_EQ(parse_sysfs_rate_hz("1.6e3", "f"), 1600.0);
  EXPECT_EQ(parse_sysfs_rate_hz("0.5 \n\n", "f"), 0.5);
}

TEST(IioSysfsValue, BadRatesNameTheFileAndText) {
  EXPECT_EQ(rate_error("4000 Hz\n"), "dev/sampling_frequency: not a positive sample rate: '4000 Hz'");
  EXPECT_EQ(rate_error("fast"), "dev/sampling_frequency: not a positive sample rate: 'fast'");
  EXPECT_EQ(rate_error(""), "dev/sampling_frequency: not a positive sample rate: ''");
  for (const std::string_view bad : {"0"sv, "0.0"sv, "-100"sv, "+100"sv, " 100"sv, "inf"sv, "nan"sv,
                                     "1e999"sv, "0x10"sv, ".5"sv, "100\t"sv, "1\0002"sv, "1,5"sv}) {
    EXPECT_NE(rate_error(bad), "accepted") << testing::PrintToString(std::string(bad));
  }
  // Non-printable bytes are not copied into the message; long texts are cut.
  EXPECT_EQ(rate_error("\x01\xff"sv),
            "dev/sampling_frequency: not a positive sample rate: '?"
            "?'");
  EXPECT_EQ(rate_error(std::string(100, 'x')),
            "dev/sampling_frequency: not a positive sample rate: '" + std::string(64, 'x') + "...'");
}

TEST(IioSysfsValue, Indices) {
  EXPECT_EQ(parse_sysfs_index("0\n", "i"), 0U);
  EXPECT_EQ(parse_sysfs_index("17", "i"), 17U);
  EXPECT_EQ(parse_sysfs_index("4294967295\n", "i"), 4294967295U);
  EXPECT_EQ(index_error("-1\n"), "se/in_x_index: not a scan index: '-1'");
  EXPECT_EQ(index_error("4294967296"), "se/in_x_index: not a scan index: '4294967296'");
  for (const std::string_view bad : {""sv, "+1"sv, " 1"sv, "1 2"sv, "0x1"sv, "1.0"sv, "one"sv, "1\0"sv}) {
    EXPECT_NE(index_error(bad), "accepted") << testing::PrintToString(std::string(bad));
  }
}

}  // namespace
}  // namespace ptda::drivers
