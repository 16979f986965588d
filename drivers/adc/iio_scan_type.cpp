#include "adc/iio_scan_type.hpp"

#include <algorithm>
#include <charconv>
#include <cstring>

#include "ptda/common/error.hpp"

namespace ptda::drivers {
namespace {

/// Reads an unsigned decimal at the front of s; false when there is none or it exceeds max.
bool take_uint(std::string_view& s, unsigned max, unsigned& out) {
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
  if (ec != std::errc() || ptr == s.data() || out > max) return false;
  s.remove_prefix(static_cast<std::size_t>(ptr - s.data()));
  return true;
}

bool take(std::string_view& s, std::string_view prefix) {
  if (s.substr(0, prefix.size()) != prefix) return false;
  s.remove_prefix(prefix.size());
  return true;
}

std::size_t round_up(std::size_t v, std::size_t to) {
  return to == 0 ? v : (v + to - 1) / to * to;
}

}  // namespace

IioScanType parse_iio_scan_type(std::string_view text, const std::string& where) {
  while (!text.empty() && (text.back() == '\n' || text.back() == ' ' || text.back() == '\r'))
    text.remove_suffix(1);
  const std::string quoted = "'" + std::string(text) + "'";
  auto bad = [&](const std::string& what) -> Error {
    return Error(where, 0, 0, "bad IIO scan type " + quoted + ": " + what);
  };
  IioScanType t;
  std::string_view s = text;
  if (take(s, "le:")) {
    t.big_endian = false;
  } else if (take(s, "be:")) {
    t.big_endian = true;
  } else {
    throw bad("expected 'le:' or 'be:' first");
  }
  if (take(s, "s")) {
    t.is_signed = true;
  } else if (take(s, "u")) {
    t.is_signed = false;
  } else {
    throw bad("expected 's' or 'u' after the byte order");
  }
  unsigned bits = 0, storage = 0, repeat = 1, shift = 0;
  if (!take_uint(s, 64, bits) || bits == 0) throw bad("valid bits must be 1..64");
  if (!take(s, "/")) throw bad("expected '/' after the valid bits");
  if (!take_uint(s, 64, storage) || (storage != 8 && storage != 16 && storage != 32 && storage != 64))
    throw bad("storage bits must be 8, 16, 32 or 64");
  if (take(s, "X")) {
    if (!take_uint(s, 255, repeat) || repeat == 0) throw bad("repeat must be 1..255");
  }
  if (take(s, ">>")) {
    if (!take_uint(s, 63, shift)) throw bad("shift must be 0..63");
  }
  if (!s.empty()) throw bad("unexpected '" + std::string(s) + "' at the end");
  if (bits + shift > storage) throw bad("bits + shift exceed the storage bits");
  t.bits = static_cast<std::uint8_t>(bits);
  t.storage_bits = static_cast<std::uint8_t>(storage);
  t.repeat = static_cast<std::uint8_t>(repeat);
  t.shift = static_cast<std::uint8_t>(shift);
  return t;
}

std::string format_iio_scan_type(const IioScanType& t) {
  std::string s = t.big_endian ? "be:" : "le:";
  s += t.is_signed ? 's' : 'u';
  s += std::to_string(t.bits) + "/" + std::to_string(t.storage_bits);
  if (t.repeat > 1) s += "X" + std::to_string(t.repeat);
  s += ">>" + std::to_string(t.shift);
  return s;
}

int IioScanLayout::find(std::string_view name) const noexcept {
  for (std::size_t i = 0; i < elements.size(); ++i)
    if (elements[i].name == name) return static_cast<int>(i);
  return -1;
}

IioScanLayout compute_iio_scan_layout(std::span<const IioChannelSpec> channels) {
  if (channels.empty()) throw Error("IIO scan layout: no enabled channels");
  std::vector<IioChannelSpec> sorted(channels.begin(), channels.end());
  // Scan order: ascending _index, the timestamp always last (the kernel gives it the highest index).
  std::stable_sort(sorted.begin(), sorted.end(), [](const IioChannelSpec& a, const IioChannelSpec& b) {
    const bool at = a.name == "timestamp", bt = b.name == "timestamp";
    if (at != bt) return bt;
    return a.index < b.index;
  });
  IioScanLayout layout;
  std::size_t offset = 0, largest = 0;
  for (std::size_t i = 0; i < sorted.size(); ++i) {
    const IioChannelSpec& c = sorted[i];
    if (i > 0 && sorted[i - 1].index == c.index)
      throw Error("IIO scan layout: channels '" + sorted[i - 1].name + "' and '" + c.name +
                  "' share _index " + std::to_string(c.index));
    for (std::size_t j = 0; j < i; ++j)
      if (sorted[j].name == c.name) throw Error("IIO scan layout: channel '" + c.name + "' listed twice");
    if (c.name == "timestamp") {
      if (c.type.storage_bits != 64 || c.type.repeat != 1)
        throw Error("IIO scan layout: the timestamp channel must be a single 64-bit element, got " +
                    format_iio_scan_type(c.type));
      layout.timestamp_element = static_cast<int>(i);
    }
    const std::size_t len = c.type.total_bytes();
    offset = round_up(offset, len);
    layout.elements.push_back(IioScanElement{c.name, c.index, c.type, offset});
    offset += len;
    largest = std::max(largest, len);
  }
  layout.scan_bytes = round_up(offset, largest);
  return layout;
}

std::int64_t decode_iio_value(const std::uint8_t* scan, const IioScanElement& e, std::size_t rep) noexcept {
  const std::size_t n = e.type.storage_bytes();
  const std::uint8_t* p = scan + e.offset + rep * n;
  std::uint64_t raw = 0;
  if (e.type.big_endian) {
    for (std::size_t i = 0; i < n; ++i) raw = (raw << 8) | p[i];
  } else {
    for (std::size_t i = n; i-- > 0;) raw = (raw << 8) | p[i];
  }
  raw >>= e.type.shift;
  if (e.type.bits < 64) {
    const std::uint64_t mask = (std::uint64_t{1} << e.type.bits) - 1;
    raw &= mask;
    if (e.type.is_signed && (raw >> (e.type.bits - 1)) != 0) raw |= ~mask;  // sign-extend
  }
  return static_cast<std::int64_t>(raw);
}

void encode_iio_value(std::uint8_t* scan, const IioScanElement& e, std::int64_t value,
                      std::size_t rep) noexcept {
  const std::size_t n = e.type.storage_bytes();
  std::uint8_t* p = scan + e.offset + rep * n;
  std::uint64_t raw = static_cast<std::uint64_t>(value);
  if (e.type.bits < 64) raw &= (std::uint64_t{1} << e.type.bits) - 1;
  raw <<= e.type.shift;
  for (std::size_t i = 0; i < n; ++i) {
    const auto byte = static_cast<std::uint8_t>(raw >> (8 * i));
    p[e.type.big_endian ? n - 1 - i : i] = byte;
  }
}

}  // namespace ptda::drivers
