// recording.toml: read with toml++, checked key by key so every error points at a file:line:column.
#include "ptda/formats/recording.hpp"

#include <toml++/toml.h>

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string_view>
#include <system_error>
#include <utility>

#include "ptda/common/error.hpp"
#include "ptda/common/file_check.hpp"
#include "ptda/common/time.hpp"
#include "ptda/formats/wav.hpp"

namespace ptda::formats {
namespace {

constexpr std::string_view kFormatName = "ptda-recording";
constexpr std::int64_t kFormatVersion = 1;
constexpr const char* kMetaFile = "recording.toml";

class Checker {
 public:
  explicit Checker(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void fail(const toml::source_region& where, const std::string& what) const {
    throw Error(file_, static_cast<long>(where.begin.line), static_cast<long>(where.begin.column), what);
  }

  // Rejects keys the format does not define (a typo must not silently fall back to a default).
  void only_keys(const toml::table& t, std::initializer_list<std::string_view> allowed,
                 const std::string& table) const {
    for (auto&& [k, v] : t) {
      bool ok = false;
      for (const auto a : allowed) ok = ok || k.str() == a;
      if (!ok) fail(k.source(), "unknown key '" + std::string(k.str()) + "' in " + table);
    }
  }

  const toml::node& need(const toml::table& t, std::string_view key, const std::string& table) const {
    const toml::node* n = t.get(key);
    if (n == nullptr) fail(t.source(), "missing key '" + std::string(key) + "' in " + table);
    return *n;
  }

  std::string need_string(const toml::table& t, std::string_view key, const std::string& table) const {
    const toml::node& n = need(t, key, table);
    if (!n.is_string()) fail(n.source(), "'" + std::string(key) + "' in " + table + " must be a string");
    std::string s = n.as_string()->get();
    if (s.empty()) fail(n.source(), "'" + std::string(key) + "' in " + table + " must not be empty");
    if (const std::string problem = string_value_problem(s); !problem.empty())
      fail(n.source(), "'" + std::string(key) + "' in " + table + " " + problem);
    return s;
  }

  std::int64_t need_integer(const toml::table& t, std::string_view key, const std::string& table) const {
    const toml::node& n = need(t, key, table);
    if (!n.is_integer()) fail(n.source(), "'" + std::string(key) + "' in " + table + " must be an integer");
    return n.as_integer()->get();
  }

  // Floats; integers are accepted too since "scale = 1" is an obvious way to write 1.0.
  double need_number(const toml::table& t, std::string_view key, const std::string& table) const {
    const toml::node& n = need(t, key, table);
    double v = 0.0;
    if (n.is_floating_point()) {
      v = n.as_floating_point()->get();
    } else if (n.is_integer()) {
      v = static_cast<double>(n.as_integer()->get());
    } else {
      fail(n.source(), "'" + std::string(key) + "' in " + table + " must be a number");
    }
    if (!std::isfinite(v)) fail(n.source(), "'" + std::string(key) + "' in " + table + " must be finite");
    return v;
  }

  const toml::table& need_table(const toml::table& t, std::string_view key) const {
    const toml::node& n = need(t, key, "the top level");
    if (!n.is_table())
      fail(n.source(), "'" + std::string(key) + "' must be a table ([" + std::string(key) + "])");
    return *n.as_table();
  }

  void need_file(const std::filesystem::path& dir, const toml::node& n, const std::string& rel) const {
    std::error_code ec;
    const std::filesystem::path p = dir / rel;
    if (!std::filesystem::is_regular_file(p, ec))
      fail(n.source(), "file '" + p.string() + "' does not exist or is not a regular file");
  }

 private:
  std::string file_;
};

// TOML basic string with the escapes the spec requires.
std::string toml_string(const std::string& s) {
  std::string out = "\"";
  for (const char c : s) {
    const auto u = static_cast<unsigned char>(c);
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (c == '\n') {
      out += "\\n";
    } else if (c == '\t') {
      out += "\\t";
    } else if (c == '\r') {
      out += "\\r";
    } else if (u < 0x20 || u == 0x7F) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04X", static_cast<unsigned>(u));
      out += buf;
    } else {
      out += c;
    }
  }
  return out + "\"";
}

// Shortest text that reads back to the same double, always a TOML float (never an integer literal).
std::string toml_float(double v, const char* key) {
  if (!std::isfinite(v)) throw Error(std::string("recording.toml: '") + key + "' must be finite");
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  std::string s(buf, r.ptr);
  if (s.find_first_of(".e") == std::string::npos) s += ".0";
  return s;
}

}  // namespace

RecordingMeta read_recording_meta(const std::filesystem::path& dir) {
  const std::filesystem::path file = dir / kMetaFile;
  const std::string name = file.string();
  std::error_code ec;
  if (!std::filesystem::exists(file, ec)) throw Error(name + ": recording.toml not found");
  const std::string text = read_regular_file(file, kMaxConfigFileBytes, "recording.toml");
  toml::table root;
  try {
    root = toml::parse(text, name);
  } catch (const toml::parse_error& e) {
    throw Error(name, static_cast<long>(e.source().begin.line), static_cast<long>(e.source().begin.column),
                std::string(e.description()));
  }
  const Checker ck(name);
  ck.only_keys(root, {"format", "version", "vibration", "can"}, "the top level");
  const std::string format = ck.need_string(root, "format", "the top level");
  if (format != kFormatName)
    ck.fail(root.get("format")->source(),
            "format is '" + format + "', expected '" + std::string(kFormatName) + "'");
  const std::int64_t version = ck.need_integer(root, "version", "the top level");
  if (version != kFormatVersion)
    ck.fail(root.get("version")->source(),
            "unsupported version " + std::to_string(version) + " (this build reads version 1)");

  RecordingMeta meta;
  const toml::table& vib = ck.need_table(root, "vibration");
  ck.only_keys(vib, {"file", "channel", "start_time", "scale", "unit"}, "[vibration]");
  meta.vibration_file = ck.need_string(vib, "file", "[vibration]");
  const std::int64_t channel = ck.need_integer(vib, "channel", "[vibration]");
  meta.start_time_s = ck.need_number(vib, "start_time", "[vibration]");
  if (meta.start_time_s < 0.0) ck.fail(vib.get("start_time")->source(), "start_time must not be negative");
  // Every consumer converts to int64 ns and adds durations: keep the sum representable (issue 14).
  if (meta.start_time_s > kMaxUnixTimeS)
    ck.fail(vib.get("start_time")->source(),
            "start_time " + toml_float(meta.start_time_s, "start_time") + " s is out of range (at most " +
                toml_float(kMaxUnixTimeS, "start_time") + " s UNIX time, year 2096)");
  meta.scale = ck.need_number(vib, "scale", "[vibration]");
  if (meta.scale == 0.0) ck.fail(vib.get("scale")->source(), "scale must not be zero");
  meta.unit = ck.need_string(vib, "unit", "[vibration]");

  const toml::table& can = ck.need_table(root, "can");
  ck.only_keys(can, {"file"}, "[can]");
  meta.can_file = ck.need_string(can, "file", "[can]");

  ck.need_file(dir, *vib.get("file"), meta.vibration_file);
  ck.need_file(dir, *can.get("file"), meta.can_file);

  // The channel is checked against the WAV's header, which also proves the WAV is readable.
  const toml::node& ch_node = *vib.get("channel");
  if (channel < 0) ck.fail(ch_node.source(), "channel " + std::to_string(channel) + " must not be negative");
  WavReader wav(dir / meta.vibration_file);
  if (channel >= wav.info().channels)
    ck.fail(ch_node.source(), "channel " + std::to_string(channel) + " out of range: " + meta.vibration_file +
                                  " has " + std::to_string(wav.info().channels) + " channel(s)");
  meta.channel = static_cast<std::uint16_t>(channel);
  return meta;
}

void write_recording_meta(const std::filesystem::path& dir, const RecordingMeta& meta) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw Error(dir.string() + ": cannot create recording directory: " + ec.message());
  const std::filesystem::path file = dir / kMetaFile;
  if (meta.vibration_file.empty() || meta.can_file.empty() || meta.unit.empty())
    throw Error(file.string() + ": vibration file, CAN file and unit must not be empty");
  if (!(meta.start_time_s >= 0.0 && meta.start_time_s <= kMaxUnixTimeS))
    throw Error(file.string() + ": start_time " + std::to_string(meta.start_time_s) +
                " s is out of range (0 to 4e9 s UNIX time)");
  std::string text;
  text += "# ptda recording, see docs/recording-format.md\n";
  text += "format = \"ptda-recording\"\n";
  text += "version = 1\n\n";
  text += "[vibration]\n";
  text += "file = " + toml_string(meta.vibration_file) + "\n";
  text += "channel = " + std::to_string(meta.channel) + "\n";
  text += "start_time = " + toml_float(meta.start_time_s, "start_time") + "\n";
  text += "scale = " + toml_float(meta.scale, "scale") + "\n";
  text += "unit = " + toml_string(meta.unit) + "\n\n";
  text += "[can]\n";
  text += "file = " + toml_string(meta.can_file) + "\n";
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  if (!out) throw Error(file.string() + ": cannot create: " + std::strerror(errno));
  out << text;
  out.close();
  if (!out) throw Error(file.string() + ": write failed");
}

}  // namespace ptda::formats
