// libFuzzer target: the IIO sysfs values (drivers/adc/iio_sysfs_value.cpp) and the whole sysfs setup
// of the IIO backend (IioSampleSource::configure() on a fake device tree, then reads of the device).
// The input is split at lines "#---" into: sampling_frequency, in_accel_x_index, in_accel_x_type,
// in_timestamp_index, in_timestamp_type, in_accel_y_index, in_accel_y_type, and the bytes of the
// character device; a channel whose parts are missing is not in the tree.
// Checks: an accepted rate is finite, > 0 and reads back from its shortest text; an accepted index is
// decimal digits and reads back from std::to_string; a configured source has the rate of its file
// and a scan layout whose elements lie inside the scan without overlapping; reads end.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "adc/iio_sample_source.hpp"
#include "adc/iio_sysfs_value.hpp"
#include "fuzz_support.hpp"
#include "ptda/common/error.hpp"
#include "ptda/drivers/clock.hpp"

namespace fs = std::filesystem;

namespace {

void check_rate(std::string_view text) {
  double v = 0.0;
  try {
    v = ptda::drivers::parse_sysfs_rate_hz(text, "fuzz");
  } catch (const ptda::Error&) {
    return;
  }
  if (!std::isfinite(v) || !(v > 0.0)) __builtin_trap();
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  if (ptda::drivers::parse_sysfs_rate_hz(buf, "fuzz-roundtrip") != v) __builtin_trap();
}

void check_index(std::string_view text) {
  std::uint32_t v = 0;
  try {
    v = ptda::drivers::parse_sysfs_index(text, "fuzz");
  } catch (const ptda::Error&) {
    return;
  }
  const std::string_view t = ptda::drivers::trim_sysfs_text(text);
  if (t.empty() || !std::all_of(t.begin(), t.end(), [](char c) { return c >= '0' && c <= '9'; }))
    __builtin_trap();
  if (ptda::drivers::parse_sysfs_index(std::to_string(v), "fuzz-roundtrip") != v) __builtin_trap();
}

void put(const fs::path& p, std::string_view text) {
  fs::create_directories(p.parent_path());
  std::ofstream(p, std::ios::binary).write(text.data(), static_cast<std::streamsize>(text.size()));
}

void check_layout(const ptda::drivers::IioScanLayout& l) {
  std::vector<std::pair<std::size_t, std::size_t>> spans;
  for (const auto& e : l.elements) {
    if (e.type.storage_bytes() == 0 || e.offset % e.type.storage_bytes() != 0) __builtin_trap();
    if (e.offset + e.type.total_bytes() > l.scan_bytes) __builtin_trap();
    spans.emplace_back(e.offset, e.offset + e.type.total_bytes());
  }
  std::sort(spans.begin(), spans.end());
  for (std::size_t i = 1; i < spans.size(); ++i) {
    if (spans[i].first < spans[i - 1].second) __builtin_trap();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::vector<std::string_view> parts = ptda::fuzz::split_parts(ptda::fuzz::as_text(data, size), 8);
  check_rate(parts[0]);
  if (parts.size() > 1) check_index(parts[1]);

  // The tree is rewritten in place (no remove_all per run): a channel without its parts has its
  // files removed.
  const fs::path dir = ptda::fuzz::scratch_dir() / "iio:device0";
  put(dir / "sampling_frequency", parts[0]);
  put(dir / "buffer" / "enable", "0\n");
  static constexpr const char* kChannels[] = {"accel_x", "timestamp", "accel_y"};
  for (std::size_t c = 0; c < 3; ++c) {
    const std::size_t i = 1 + 2 * c;
    const fs::path stem = dir / "scan_elements" / (std::string("in_") + kChannels[c]);
    if (parts.size() > i + 1) {
      put(stem.string() + "_en", "0\n");
      put(stem.string() + "_index", parts[i]);
      put(stem.string() + "_type", parts[i + 1]);
    } else {
      std::error_code ec;
      for (const char* suffix : {"_en", "_index", "_type"}) fs::remove(stem.string() + suffix, ec);
    }
  }
  const fs::path dev = ptda::fuzz::write_scratch("iio_dev", parts.size() > 7 ? parts[7] : std::string_view());

  ptda::drivers::IioSourceConfig cfg;
  cfg.sysfs_dir = dir;
  cfg.dev_path = dev;
  cfg.channel = "accel_x";
  cfg.fs_hz = 0.0;  // keep the device's rate: the file is the input
  cfg.buffer_length = 0;
  cfg.block_len = 4;
  ptda::drivers::ManualClock clock(0);
  ptda::drivers::IioSampleSource src(cfg, clock);
  try {
    src.configure();
  } catch (const ptda::Error&) {
    return 0;
  }
  if (src.fs_hz() != ptda::drivers::parse_sysfs_rate_hz(parts[0], "fuzz")) __builtin_trap();
  check_layout(src.layout());
  if (src.layout().find("accel_x") < 0) __builtin_trap();
  try {
    src.activate();
  } catch (const ptda::Error&) {
    __builtin_trap();  // buffer/enable exists: activate must work
  }
  auto block = std::make_unique<ptda::drivers::SampleBlock>();
  for (int n = 0; n < 64; ++n) {
    const auto st = src.read(*block, 0);
    if (st != ptda::drivers::SourceStatus::kOk) break;
    if (block->count == 0 || block->count > cfg.block_len) __builtin_trap();
  }
  return 0;
}
