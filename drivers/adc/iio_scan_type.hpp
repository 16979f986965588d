// IIO buffered-capture scan layout: parse scan_elements/*_type strings, place the enabled channels in
// a packed scan exactly as the kernel does (industrialio-buffer.c iio_compute_scan_bytes), and decode
// one channel's value from a scan. Pure functions: unit-tested with synthetic byte buffers.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace ptda::drivers {

/// One `_type` attribute: "[be|le]:[s|u]bits/storagebits[Xrepeat][>>shift]", e.g. "le:s24/32>>0".
struct IioScanType {
  bool big_endian = false;
  bool is_signed = false;
  std::uint8_t bits = 0;          ///< valid bits, 1..storage_bits
  std::uint8_t storage_bits = 0;  ///< 8, 16, 32 or 64
  std::uint8_t repeat = 1;        ///< elements per channel (X suffix), >= 1
  std::uint8_t shift = 0;         ///< right shift before masking; shift + bits <= storage_bits

  [[nodiscard]] std::size_t storage_bytes() const noexcept { return storage_bits / 8U; }
  /// Bytes the channel occupies in a scan (all repeats).
  [[nodiscard]] std::size_t total_bytes() const noexcept { return storage_bytes() * repeat; }
  friend bool operator==(const IioScanType&, const IioScanType&) = default;
};

/// Parses a `_type` string (trailing newline/space allowed, as read from sysfs). Throws ptda::Error
/// "<where>: <what>" for anything malformed or inconsistent. Thread: any. Allocates only to throw.
[[nodiscard]] IioScanType parse_iio_scan_type(std::string_view text, const std::string& where);
/// The canonical text the kernel prints for `t` (X only when repeat > 1). Thread: any. Allocates.
[[nodiscard]] std::string format_iio_scan_type(const IioScanType& t);

/// An enabled channel as configured: its sysfs name ("accel_x", "voltage0", "timestamp"), _index and _type.
struct IioChannelSpec {
  std::string name;
  std::uint32_t index = 0;
  IioScanType type;
};

/// Where a channel sits in a scan.
struct IioScanElement {
  std::string name;
  std::uint32_t index = 0;
  IioScanType type;
  std::size_t offset = 0;  ///< byte offset of the first repeat within a scan
};

struct IioScanLayout {
  std::vector<IioScanElement> elements;  ///< in scan order (ascending _index, timestamp last)
  std::size_t scan_bytes = 0;            ///< size of one scan including the tail padding
  int timestamp_element = -1;            ///< index into elements of the "timestamp" channel, or -1

  /// The element named `name`, or -1. Thread: any. Never allocates.
  [[nodiscard]] int find(std::string_view name) const noexcept;
};

/// Places `channels` (any order) like the kernel: sorted by _index; each element aligned to its own
/// size (storage bytes x repeat); the "timestamp" channel (s64) last whatever its index; the scan
/// padded to a multiple of its largest element. Throws ptda::Error for no channels, duplicate indices
/// or names, or a timestamp that is not 64-bit. Thread: any. Allocates.
[[nodiscard]] IioScanLayout compute_iio_scan_layout(std::span<const IioChannelSpec> channels);

/// Decodes repeat `rep` of element `e` from one scan (scan.size() >= layout.scan_bytes): byte order,
/// then >> shift, then mask to `bits`, then sign extension when signed. Thread: any. Never allocates.
[[nodiscard]] std::int64_t decode_iio_value(const std::uint8_t* scan, const IioScanElement& e,
                                            std::size_t rep = 0) noexcept;

/// Inverse of decode_iio_value (for tests and simulators): writes `value` into the scan. Thread: any.
void encode_iio_value(std::uint8_t* scan, const IioScanElement& e, std::int64_t value,
                      std::size_t rep = 0) noexcept;

}  // namespace ptda::drivers
