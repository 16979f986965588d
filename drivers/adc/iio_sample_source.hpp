// IIO buffered capture backend of SampleSource (kernel Documentation/driver-api/iio/buffers.rst).
// configure(): through the device's sysfs directory: buffer/enable=0, sampling_frequency,
// current_timestamp_clock=monotonic, scan_elements/*_en (only the wanted channels), trigger,
// buffer/length and watermark; then the scan layout from the channels' _index and _type, and the
// character device opened non-blocking. activate(): buffer/enable=1. read(): poll() + read() packed
// scans, decode the selected channel, timestamp from the in_timestamp channel when enabled.
// The sysfs root and device path are configuration, so tests run against a fake tree and a FIFO.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "adc/iio_scan_type.hpp"
#include "ptda/drivers/clock.hpp"
#include "ptda/drivers/sample_source.hpp"

namespace ptda::drivers {

struct IioSourceConfig {
  std::filesystem::path sysfs_dir = "/sys/bus/iio/devices/iio:device0";
  std::filesystem::path dev_path = "/dev/iio:device0";
  std::string channel = "accel_x";          ///< delivered channel: scan_elements/in_<channel>_*
  std::vector<std::string> extra_channels;  ///< also enabled (other axes), not delivered
  bool timestamp = true;                    ///< enable in_timestamp when the device offers it
  double fs_hz = 25600.0;                   ///< written to sampling_frequency; 0 = keep the device's
  std::string trigger;                      ///< written to trigger/current_trigger; "" = keep
  std::uint32_t buffer_length = 4096;       ///< buffer/length in scans; 0 = keep
  std::uint32_t watermark = 0;              ///< buffer/watermark (when present); 0 = keep
  std::uint32_t block_len = 256;            ///< scans per SampleBlock, 1..kMaxBlock
  float scale = 1.0F;                       ///< sample = raw code * scale
  double gap_tolerance = 0.5;               ///< a timestamp step > (1 + tol) / fs is a gap
};

class IioSampleSource final : public SampleSource {
 public:
  /// `clock` stamps blocks when there is no timestamp channel; it must outlive the source.
  IioSampleSource(IioSourceConfig config, const Clock& clock);
  ~IioSampleSource() override;

  /// Throws ptda::Error "<sysfs file>: <what>" (missing attribute, unknown channel with the list of
  /// available ones, bad _type, unreadable device...). Thread: main, start-up. Blocks and allocates.
  void configure() override;
  /// buffer/enable = 1. Throws ptda::Error.
  void activate() override;
  SourceStatus read(SampleBlock& out, std::int64_t timeout_ns) noexcept override;
  /// buffer/enable = 0 (best effort). The device stays open for a later activate().
  void deactivate() noexcept override;
  [[nodiscard]] double fs_hz() const noexcept override { return fs_hz_; }

  /// The scan layout found by configure(). Thread: any after configure().
  [[nodiscard]] const IioScanLayout& layout() const noexcept { return layout_; }

 private:
  [[nodiscard]] std::filesystem::path buffer_attr(const char* name) const;

  IioSourceConfig config_;
  const Clock& clock_;
  double fs_hz_ = 0.0;
  double period_ns_ = 0.0;
  IioScanLayout layout_;
  int value_element_ = -1;
  int fd_ = -1;
  bool active_ = false;
  std::filesystem::path buffer_dir_;
  std::string enable_path_;        ///< buffer/enable, kept as a string so deactivate() need not allocate
  std::vector<std::uint8_t> buf_;  ///< block_len scans plus room for a partial one
  std::size_t have_ = 0;           ///< bytes in buf_
  bool short_read_pending_ = false;
  std::uint64_t next_index_ = 0;
  bool have_last_ts_ = false;
  std::int64_t last_ts_ = 0;
};

}  // namespace ptda::drivers
