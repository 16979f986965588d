// The binary baseline store. Every field is serialised explicitly as little-endian (never a struct
// dump), so files move between x86 and ARM gateways unchanged. Layout: docs/recording-format.md.
#include "ptda/formats/baseline_file.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>

#include "ptda/common/atomic_file.hpp"
#include "ptda/common/error.hpp"
#include "ptda/common/file_check.hpp"
#include "ptda/dsp/analyzer.hpp"
#include "ptda/dsp/mesh_modulation.hpp"
#include "ptda/dsp/real_fft.hpp"

namespace ptda::formats {
namespace {

constexpr std::array<char, 8> kMagic = {'P', 'T', 'D', 'A', 'B', 'A', 'S', 'E'};
// magic 8 + version 4 + file size 8
constexpr std::size_t kPreambleBytes = 20;
constexpr std::size_t kCrcBytes = 4;
// Version 3 option flags (u32 before the CRC).
constexpr std::uint32_t kOptionLineGain = 1U;
constexpr std::uint32_t kOptionFloorGain = 2U;
// Smallest possible class record (window_len 1: one magnitude and one mean sample); bounds n_classes
// before anything is allocated for it.
// id, direction, 3 speeds/duration, regions, n_windows, 2 x (count + one float), thresholds, stats.
constexpr std::size_t kMinClassBytes =
    4 + 1 + 8 * 3 + 4 + 4 + 2 * (4 + 4) + dsp::kMethodCount * (4 * 8) + 2 * dsp::kMethodCount * (4 * 8 + 4);

// Slicing by 8: t[0] is the byte-wise table; t[k][b] is the CRC register after byte b followed by k zero
// bytes, so eight table lookups advance the register by eight bytes at once (the same CRC as the
// byte-wise loop; `ptda monitor` fingerprints the first MiB of every recording with it).
constexpr std::array<std::array<std::uint32_t, 256>, 8> make_crc_tables() noexcept {
  std::array<std::array<std::uint32_t, 256>, 8> t{};
  for (std::uint32_t i = 0; i < 256; ++i) {
    std::uint32_t c = i;
    for (int k = 0; k < 8; ++k) c = (c & 1U) != 0 ? 0xEDB88320U ^ (c >> 1) : c >> 1;
    t[0][i] = c;
  }
  for (std::size_t k = 1; k < 8; ++k) {
    for (std::size_t i = 0; i < 256; ++i) t[k][i] = t[0][t[k - 1][i] & 0xFFU] ^ (t[k - 1][i] >> 8);
  }
  return t;
}
constexpr std::array<std::array<std::uint32_t, 256>, 8> kCrcTables = make_crc_tables();

class Writer {
 public:
  void u8(std::uint8_t v) { b_.push_back(v); }
  void u32(std::uint32_t v) {
    for (int i = 0; i < 4; ++i) b_.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
  }
  void u64(std::uint64_t v) {
    for (int i = 0; i < 8; ++i) b_.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
  }
  void f32(float v) { u32(std::bit_cast<std::uint32_t>(v)); }
  void f64(double v) { u64(std::bit_cast<std::uint64_t>(v)); }
  void bytes(const void* p, std::size_t n) {
    const auto* c = static_cast<const std::uint8_t*>(p);
    b_.insert(b_.end(), c, c + n);
  }
  void patch_u64(std::size_t at, std::uint64_t v) {
    for (int i = 0; i < 8; ++i)
      b_[at + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(v >> (8 * i));
  }
  std::vector<std::uint8_t>& buf() { return b_; }

 private:
  std::vector<std::uint8_t> b_;
};

class Reader {
 public:
  Reader(std::span<const std::uint8_t> b, const std::string& source) : b_(b), source_(source) {}
  [[noreturn]] void fail(const std::string& what) const {
    throw Error(source_ + ": inconsistent baseline at byte " + std::to_string(pos_) + ": " + what);
  }
  void need(std::size_t n) const {
    if (b_.size() - pos_ < n) fail("record runs past the end of the data");
  }
  std::uint8_t u8() {
    need(1);
    return b_[pos_++];
  }
  std::uint32_t u32() {
    need(4);
    std::uint32_t v = 0;
    for (int i = 0; i < 4; ++i)
      v |= static_cast<std::uint32_t>(b_[pos_ + static_cast<std::size_t>(i)]) << (8 * i);
    pos_ += 4;
    return v;
  }
  std::uint64_t u64() {
    need(8);
    std::uint64_t v = 0;
    for (int i = 0; i < 8; ++i)
      v |= static_cast<std::uint64_t>(b_[pos_ + static_cast<std::size_t>(i)]) << (8 * i);
    pos_ += 8;
    return v;
  }
  float f32() { return std::bit_cast<float>(u32()); }
  double f64() { return std::bit_cast<double>(u64()); }
  [[nodiscard]] std::size_t pos() const noexcept { return pos_; }
  [[nodiscard]] std::size_t left() const noexcept { return b_.size() - pos_; }
  void skip(std::size_t n) { pos_ += n; }

 private:
  std::span<const std::uint8_t> b_;
  const std::string& source_;
  std::size_t pos_ = 0;
};

std::string hex32(std::uint32_t v) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "0x%08X", v);
  return buf;
}

// Checks shared by writer and reader so a file that was written can always be read back.
void check_baseline(const dsp::Baseline& b, const std::string& where) {
  if (!(std::isfinite(b.fs_hz) && b.fs_hz > 0.0)) throw Error(where + ": fs_hz must be finite and positive");
  if (b.window_len == 0) throw Error(where + ": window_len must be positive");
  if (static_cast<std::uint8_t>(b.gearbox.kind) > static_cast<std::uint8_t>(dsp::GearboxInfo::Kind::kUnknown))
    throw Error(where + ": unknown gearbox kind " + std::to_string(static_cast<int>(b.gearbox.kind)));
  if (static_cast<std::uint8_t>(b.policy.kind) >
      static_cast<std::uint8_t>(dsp::ThresholdPolicy::Kind::kTolerance))
    throw Error(where + ": unknown threshold policy kind " + std::to_string(static_cast<int>(b.policy.kind)));
  const std::size_t n_mag = b.window_len / 2 + 1;
  for (std::size_t i = 0; i < b.classes.size(); ++i) {
    const auto& c = b.classes[i];
    const std::string cls =
        where + ": class " + std::to_string(i) + " (id " + std::to_string(c.segment.id) + ")";
    if (c.segment.direction != 1 && c.segment.direction != -1)
      throw Error(cls + ": direction must be +1 or -1, got " + std::to_string(c.segment.direction));
    if (c.mean_magnitude.size() != n_mag)
      throw Error(cls + ": mean_magnitude has " + std::to_string(c.mean_magnitude.size()) +
                  " values, window_len " + std::to_string(b.window_len) +
                  " needs N/2+1 = " + std::to_string(n_mag));
    if (c.tda_mean.size() != b.window_len)
      throw Error(cls + ": tda_mean has " + std::to_string(c.tda_mean.size()) + " values, window_len is " +
                  std::to_string(b.window_len));
    if (c.band_stats.size() != b.policy.band_count)
      throw Error(cls + ": " + std::to_string(c.band_stats.size()) +
                  " band statistics, the policy's band_count is " + std::to_string(b.policy.band_count));
    if (c.mesh_stats.size() != (b.policy.mesh_stats ? dsp::kMeshFeatureCount : 0U))
      throw Error(cls + ": " + std::to_string(c.mesh_stats.size()) + " mesh statistics, the policy " +
                  (b.policy.mesh_stats ? "has" : "has no") + " mesh detector");
  }
  if (b.policy.mesh_stats && b.domain != dsp::Domain::kTime)
    throw Error(where + ": mesh statistics need a time-domain baseline");
  if (b.policy.band_count > dsp::kMaxBands || b.policy.band_count > b.window_len / 2)
    throw Error(where + ": band_count " + std::to_string(b.policy.band_count) +
                " must be <= " + std::to_string(dsp::kMaxBands) + " and <= window_len / 2");
  // Widened first: on 32-bit targets (armhf) size_t cannot exceed the u32 length field, and comparing
  // it directly is an always-false -Wtype-limits error there.
  if (std::uint64_t{b.source.size()} > std::numeric_limits<std::uint32_t>::max())
    throw Error(where + ": source text too long");
  for (const dsp::TrainingRecording& t : b.training) {
    if (std::uint64_t{t.id.size()} > std::numeric_limits<std::uint32_t>::max() ||
        std::uint64_t{t.path.size()} > std::numeric_limits<std::uint32_t>::max())
      throw Error(where + ": training recording text too long");
  }
}

// Shortest text that reads back as the same double (for messages).
std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

// Semantic checks of one class: every value finite and in its physical range, bands with lo < hi,
// standard deviations > 0, counts that agree. `cls` names the class; throws at the first failure.
void check_class_values(const dsp::ClassBaseline& c, const std::string& cls) {
  const auto bad = [&](const std::string& what) { throw Error(cls + ": " + what); };
  const auto finite = [&](double v, const std::string& field) {
    if (!std::isfinite(v)) bad(field + " is " + num(v) + ", not a finite number");
  };
  const auto non_negative = [&](double v, const std::string& field) {
    finite(v, field);
    if (v < 0.0) bad(field + " is " + num(v) + ", must be >= 0");
  };
  finite(c.segment.speed_rad_s, "speed_rad_s");
  if (!(c.segment.speed_rad_s > 0.0))
    bad("speed_rad_s is " + num(c.segment.speed_rad_s) + ", must be > 0 (a constant-speed class)");
  non_negative(c.segment.speed_tol_rad_s, "speed_tol_rad_s");
  non_negative(c.segment.duration_s, "duration_s");
  non_negative(c.windows_per_hour, "windows_per_hour");
  if (c.n_windows == 0) bad("n_windows is 0 (a class is trained on at least one window)");
  // The field's name only for a failing bin: building it for each of the 2 x N/2 values of every class
  // was a measurable part of `ptda monitor`'s start-up.
  for (std::size_t k = 0; k < c.mean_magnitude.size(); ++k) {
    const double v = c.mean_magnitude[k];
    if (!std::isfinite(v) || v < 0.0) non_negative(v, "mean_magnitude[" + std::to_string(k) + "]");
  }
  for (std::size_t j = 0; j < c.tda_mean.size(); ++j) {
    if (!std::isfinite(c.tda_mean[j])) finite(c.tda_mean[j], "tda_mean[" + std::to_string(j) + "]");
  }
  for (std::size_t m = 0; m < dsp::kMethodCount; ++m) {
    const std::string method = "method " + std::string(dsp::method_name(static_cast<dsp::Method>(m))) + ", ";
    const auto band = [&](const dsp::Band& b, const std::string& name) {
      finite(b.lo, method + name + " band lo");
      finite(b.hi, method + name + " band hi");
      if (!(b.lo < b.hi))
        bad(method + name + " band is [" + num(b.lo) + ", " + num(b.hi) + "], needs lo < hi");
    };
    band(c.thresholds[m].rms, "rms_res");
    band(c.thresholds[m].entropy, "entropy_res");
    if (!(c.thresholds[m].rms.hi > 0.0))
      bad(method + "rms_res band hi is " + num(c.thresholds[m].rms.hi) + ", must be > 0 (rms_res >= 0)");
    const auto stats = [&](const dsp::FeatureStats& s, const std::string& name) {
      const std::string f = method + name + " ";
      finite(s.mean, f + "mean");
      finite(s.min, f + "min");
      finite(s.max, f + "max");
      non_negative(s.stddev, f + "stddev");
      if (s.n >= 2 && !(s.stddev > 0.0))
        bad(f + "stddev is 0 over " + std::to_string(s.n) + " windows, must be > 0");
      if (s.n > 0 && !(s.min <= s.max)) bad(f + "min " + num(s.min) + " is above max " + num(s.max));
      if (s.n > c.n_windows)
        bad(f + "n is " + std::to_string(s.n) + ", more than the class's " + std::to_string(c.n_windows) +
            " windows");
    };
    stats(c.rms_stats[m], "rms_res stats");
    stats(c.entropy_stats[m], "entropy_res stats");
    stats(c.log_rms_stats[m], "ln(rms_res) stats");
    const dsp::HoldoutStats& h = c.holdout[m];
    const std::string ho = method + "hold-out ";
    for (const auto& [count, name] :
         {std::pair{h.abnormal, "abnormal"}, std::pair{h.rms_high, "rms_high"},
          std::pair{h.rms_low, "rms_low"}, std::pair{h.entropy_out, "entropy_out"}}) {
      if (count > h.windows)
        bad(ho + name + " is " + std::to_string(count) + ", more than its " + std::to_string(h.windows) +
            " windows");
    }
    finite(h.z_rms_mean, ho + "z_rms_mean");
    non_negative(h.z_rms_sd, ho + "z_rms_sd");
    finite(h.z_entropy_mean, ho + "z_entropy_mean");
    non_negative(h.z_entropy_sd, ho + "z_entropy_sd");
    const dsp::DaySpread& d = c.day_spread[m];
    const std::string ds = method + "day spread ";
    for (const auto& [v, name] : {std::pair{d.log_rms_within_sd, "ln(rms_res) within sd"},
                                  std::pair{d.log_rms_between_est, "ln(rms_res) between estimate"},
                                  std::pair{d.log_rms_between_sd, "ln(rms_res) between sd"},
                                  std::pair{d.entropy_within_sd, "entropy within sd"},
                                  std::pair{d.entropy_between_est, "entropy between estimate"},
                                  std::pair{d.entropy_between_sd, "entropy between sd"}})
      non_negative(v, ds + name);
    if (d.recordings > c.n_windows)
      bad(ds + "recordings is " + std::to_string(d.recordings) + ", more than the class's " +
          std::to_string(c.n_windows) + " windows");
  }
}

void put_holdout(Writer& w, const dsp::HoldoutStats& h) {
  w.u32(h.windows);
  w.u32(h.abnormal);
  w.u32(h.rms_high);
  w.u32(h.rms_low);
  w.u32(h.entropy_out);
  w.f64(h.z_rms_mean);
  w.f64(h.z_rms_sd);
  w.f64(h.z_entropy_mean);
  w.f64(h.z_entropy_sd);
}
dsp::HoldoutStats get_holdout(Reader& r) {
  dsp::HoldoutStats h;
  h.windows = r.u32();
  h.abnormal = r.u32();
  h.rms_high = r.u32();
  h.rms_low = r.u32();
  h.entropy_out = r.u32();
  h.z_rms_mean = r.f64();
  h.z_rms_sd = r.f64();
  h.z_entropy_mean = r.f64();
  h.z_entropy_sd = r.f64();
  return h;
}

// Version 1 stored no ln(rms_res) statistics: the delta-method values from the linear ones
// (sd_log = sd / mean, mean_log = ln(mean) - sd_log^2 / 2), exact for a log-normal feature.
dsp::FeatureStats log_stats_from_linear(const dsp::FeatureStats& s) {
  dsp::FeatureStats l;
  l.n = s.n;
  if (s.mean > 0.0) {
    l.stddev = s.stddev / s.mean;
    l.mean = std::log(s.mean) - 0.5 * l.stddev * l.stddev;
    l.min = s.min > 0.0 ? std::log(s.min) : l.mean;
    l.max = s.max > 0.0 ? std::log(s.max) : l.mean;
  }
  return l;
}

void put_stats(Writer& w, const dsp::FeatureStats& s) {
  w.f64(s.mean);
  w.f64(s.stddev);
  w.f64(s.min);
  w.f64(s.max);
  w.u32(s.n);
}
dsp::FeatureStats get_stats(Reader& r) {
  dsp::FeatureStats s;
  s.mean = r.f64();
  s.stddev = r.f64();
  s.min = r.f64();
  s.max = r.f64();
  s.n = r.u32();
  return s;
}

}  // namespace

void validate_baseline(const dsp::Baseline& b, const std::string& where) {
  const std::string w = where + ": implausible baseline: ";
  if (!(std::isfinite(b.fs_hz) && b.fs_hz > 0.0 && b.fs_hz <= kMaxBaselineFsHz))
    throw Error(w + "fs_hz is " + num(b.fs_hz) + ", must be > 0 and <= " + num(kMaxBaselineFsHz));
  if (!dsp::RealFft::supported_length(b.window_len))
    throw Error(w + "window_len " + std::to_string(b.window_len) +
                " is not a supported FFT length (even, >= 4, prime factors 2, 3, 5 only)");
  if (b.window_len > kMaxBaselineWindowLen)
    throw Error(w + "window_len " + std::to_string(b.window_len) + " is above " +
                std::to_string(kMaxBaselineWindowLen));
  if (b.domain == dsp::Domain::kOrder) {
    // The angle axis: fs_hz is S, and a window is R revolutions of S samples.
    if (b.samples_per_rev < 16 || b.samples_per_rev % 2 != 0 || b.revolutions == 0 ||
        std::uint64_t{b.samples_per_rev} * b.revolutions != b.window_len ||
        b.fs_hz != static_cast<double>(b.samples_per_rev))
      throw Error(w + "order domain with samples_per_rev " + std::to_string(b.samples_per_rev) +
                  ", revolutions " + std::to_string(b.revolutions) + ", window_len " +
                  std::to_string(b.window_len) + " and fs_hz " + num(b.fs_hz) +
                  ": needs S even >= 16, R >= 1, window_len = R S and fs_hz = S");
    if (!(b.gearbox.ratio > 0.0))
      throw Error(w + "order domain needs the gearbox ratio (the resampler's shaft/joint angle), got " +
                  num(b.gearbox.ratio));
    // A speed law beyond |p| = 8 would scale a window by 2^8 for a factor-2 speed change: not physical.
    if (!(std::isfinite(b.speed_law_exponent) && std::fabs(b.speed_law_exponent) <= 8.0 &&
          std::isfinite(b.speed_law_fit) && std::isfinite(b.speed_law_se) && b.speed_law_se >= 0.0))
      throw Error(w + "speed law exponent " + num(b.speed_law_exponent) + " (fit " + num(b.speed_law_fit) +
                  " +- " + num(b.speed_law_se) + "): needs finite values, |exponent| <= 8, se >= 0");
  } else if (b.samples_per_rev != 0 || b.revolutions != 0 || b.speed_law_exponent != 0.0) {
    throw Error(w + "time domain with samples_per_rev " + std::to_string(b.samples_per_rev) +
                ", revolutions " + std::to_string(b.revolutions) + " and speed law exponent " +
                num(b.speed_law_exponent) + ": all must be 0");
  }
  if (!(std::isfinite(b.gearbox.ratio) && b.gearbox.ratio >= 0.0))
    throw Error(w + "gearbox ratio is " + num(b.gearbox.ratio) + ", must be finite and >= 0");
  const dsp::ThresholdPolicy& p = b.policy;
  if (!(p.false_alarm_rate > 0.0 && p.false_alarm_rate < 1.0))
    throw Error(w + "policy false_alarm_rate is " + num(p.false_alarm_rate) + ", must be in (0, 1)");
  if (!(std::isfinite(p.margin) && p.margin >= 0.0))
    throw Error(w + "policy margin is " + num(p.margin) + ", must be finite and >= 0");
  if (!(p.confidence > 0.0 && p.confidence < 1.0))
    throw Error(w + "policy confidence is " + num(p.confidence) + ", must be in (0, 1)");
  if (!(p.holdout_fraction >= 0.0 && p.holdout_fraction < 1.0))
    throw Error(w + "policy holdout_fraction is " + num(p.holdout_fraction) + ", must be in [0, 1)");
  if (!(std::isfinite(p.day_sd_floor) && p.day_sd_floor >= 0.0))
    throw Error(w + "policy day_sd_floor is " + num(p.day_sd_floor) + ", must be finite and >= 0");
  for (std::size_t i = 0; i < b.classes.size(); ++i) {
    const dsp::ClassBaseline& c = b.classes[i];
    const std::string cls = w + "class " + std::to_string(i) + " (id " + std::to_string(c.segment.id) + ")";
    check_class_values(c, cls);
    for (std::size_t k = 0; k < c.band_stats.size(); ++k) {
      const dsp::BandEnergyStats& st = c.band_stats[k];
      if (!(std::isfinite(st.mean) && std::isfinite(st.within_sd) && st.within_sd >= 0.0 &&
            std::isfinite(st.between_est) && st.between_est >= 0.0 && std::isfinite(st.between_sd) &&
            st.between_sd >= 0.0))
        throw Error(cls + ": band " + std::to_string(k) + " statistics (mean " + num(st.mean) + ", sds " +
                    num(st.within_sd) + ", " + num(st.between_est) + ", " + num(st.between_sd) +
                    "): need finite values and sds >= 0");
      if (st.clean_bins > b.window_len / 2)
        throw Error(cls + ": band " + std::to_string(k) + " has " + std::to_string(st.clean_bins) +
                    " clean bins, more than N/2");
    }
    for (std::size_t k = 0; k < c.mesh_stats.size(); ++k) {
      const dsp::MeshFeatureStats& st = c.mesh_stats[k];
      if (!(std::isfinite(st.mean) && std::isfinite(st.within_sd) && st.within_sd >= 0.0 &&
            std::isfinite(st.between_est) && st.between_est >= 0.0 && std::isfinite(st.between_sd) &&
            st.between_sd >= 0.0))
        throw Error(cls + ": mesh feature " + dsp::mesh_feature_name(k) + " statistics (mean " +
                    num(st.mean) + ", sds " + num(st.within_sd) + ", " + num(st.between_est) + ", " +
                    num(st.between_sd) + "): need finite values and sds >= 0");
      if (st.windows > 0 && !(st.within_sd > 0.0))
        throw Error(cls + ": mesh feature " + dsp::mesh_feature_name(k) + " has " +
                    std::to_string(st.windows) + " training windows and a within sd of " + num(st.within_sd) +
                    ", needs > 0");
      // am and pm are autocorrelations (about -1..1): a mean or sd far outside is not from training.
      if (!(std::fabs(st.mean) <= 2.0 && st.within_sd <= 10.0 && st.between_sd <= 10.0 &&
            st.between_est <= 10.0))
        throw Error(cls + ": mesh feature " + dsp::mesh_feature_name(k) + " statistics (mean " +
                    num(st.mean) + ", sds " + num(st.within_sd) + ", " + num(st.between_sd) +
                    ") are outside what an autocorrelation gives (|mean| <= 2, sds <= 10)");
      if (st.windows > 0 && c.mesh_recordings == 0)
        throw Error(cls + ": mesh feature " + dsp::mesh_feature_name(k) + " has " +
                    std::to_string(st.windows) + " training windows from 0 recordings");
    }
  }
  for (std::size_t i = 0; i < b.training.size(); ++i) {
    const dsp::TrainingRecording& t = b.training[i];
    const std::string tr = w + "training recording " + std::to_string(i) + ": ";
    if (!std::isfinite(t.from_unix_s) || !std::isfinite(t.to_unix_s))
      throw Error(tr + "time range " + num(t.from_unix_s) + " to " + num(t.to_unix_s) + " is not finite");
    if (t.to_unix_s < t.from_unix_s)
      throw Error(tr + "ends (" + num(t.to_unix_s) + " s) before it starts (" + num(t.from_unix_s) + " s)");
  }
}

std::uint32_t crc32(const void* data, std::size_t len, std::uint32_t crc) noexcept {
  const auto* p = static_cast<const std::uint8_t*>(data);
  const auto& t = kCrcTables;
  std::uint32_t c = ~crc;
  // Eight bytes per step: the register is xored into the first four (little-endian order, assembled
  // byte by byte so the host's byte order does not matter), then each byte's contribution after the
  // bytes that follow it is looked up.
  for (; len >= 8; len -= 8, p += 8) {
    const std::uint32_t lo =
        c ^ (static_cast<std::uint32_t>(p[0]) | (static_cast<std::uint32_t>(p[1]) << 8) |
             (static_cast<std::uint32_t>(p[2]) << 16) | (static_cast<std::uint32_t>(p[3]) << 24));
    c = t[7][lo & 0xFFU] ^ t[6][(lo >> 8) & 0xFFU] ^ t[5][(lo >> 16) & 0xFFU] ^ t[4][lo >> 24] ^ t[3][p[4]] ^
        t[2][p[5]] ^ t[1][p[6]] ^ t[0][p[7]];
  }
  for (; len > 0; --len, ++p) c = t[0][(c ^ *p) & 0xFFU] ^ (c >> 8);
  return ~c;
}

std::vector<std::uint8_t> serialize_baseline(const dsp::Baseline& b) {
  check_baseline(b, "baseline");
  validate_baseline(b, "baseline");
  Writer w;
  w.bytes(kMagic.data(), kMagic.size());
  // A time-domain baseline is written as version 4, byte for byte as before version 5 existed; only an
  // order-domain baseline needs (and gets) version 5.
  const bool order = b.domain == dsp::Domain::kOrder;
  const bool bands = b.policy.band_count > 0;
  const bool mesh = b.policy.mesh_stats;
  w.u32(mesh ? kBaselineFormatVersion
             : (bands ? kBaselineBandVersion
                      : (order ? kBaselineOrderDomainVersion : kBaselineTimeDomainVersion)));
  w.u64(0);  // total size, patched below
  w.f64(b.fs_hz);
  w.u32(b.window_len);
  w.u8(static_cast<std::uint8_t>(b.gearbox.kind));
  w.u32(b.gearbox.z_in);
  w.u32(b.gearbox.z_spur);
  w.u32(b.gearbox.z_pin);
  w.f64(b.gearbox.ratio);
  w.u8(static_cast<std::uint8_t>(b.policy.kind));
  w.f64(b.policy.false_alarm_rate);
  w.f64(b.policy.margin);
  w.f64(b.policy.confidence);        // v2
  w.f64(b.policy.holdout_fraction);  // v2
  w.u32(static_cast<std::uint32_t>(b.classes.size()));
  for (const auto& c : b.classes) {
    w.u32(c.segment.id);
    w.u8(static_cast<std::uint8_t>(c.segment.direction));
    w.f64(c.segment.speed_rad_s);
    w.f64(c.segment.speed_tol_rad_s);
    w.f64(c.segment.duration_s);
    w.u32(c.segment.regions);
    w.u32(c.n_windows);
    w.u32(static_cast<std::uint32_t>(c.mean_magnitude.size()));
    for (const float v : c.mean_magnitude) w.f32(v);
    w.u32(static_cast<std::uint32_t>(c.tda_mean.size()));
    for (const float v : c.tda_mean) w.f32(v);
    for (const auto& t : c.thresholds) {
      w.f64(t.rms.lo);
      w.f64(t.rms.hi);
      w.f64(t.entropy.lo);
      w.f64(t.entropy.hi);
    }
    for (const auto& s : c.rms_stats) put_stats(w, s);
    for (const auto& s : c.entropy_stats) put_stats(w, s);
    for (const auto& s : c.log_rms_stats) put_stats(w, s);  // v2 from here
    w.f64(c.windows_per_hour);
    for (const auto& h : c.holdout) put_holdout(w, h);
  }
  w.u32(static_cast<std::uint32_t>(b.source.size()));
  w.bytes(b.source.data(), b.source.size());
  // Version 2: the training recordings.
  w.u32(static_cast<std::uint32_t>(b.training.size()));
  for (const dsp::TrainingRecording& t : b.training) {
    w.u32(static_cast<std::uint32_t>(t.id.size()));
    w.bytes(t.id.data(), t.id.size());
    w.u32(static_cast<std::uint32_t>(t.path.size()));
    w.bytes(t.path.data(), t.path.size());
    w.f64(t.from_unix_s);
    w.f64(t.to_unix_s);
    w.u32(t.windows);
  }
  // Version 3: option flags (bit 0: PTDA line gain, bit 1: floor gain); appended so every earlier offset
  // stays put.
  w.u32((b.policy.ptda_line_gain ? kOptionLineGain : 0U) |
        (b.policy.ptda_floor_gain ? kOptionFloorGain : 0U));
  // Version 4: the between-day floors and, per class and method, the day spread.
  w.f64(b.policy.day_sd_floor);
  for (const auto& c : b.classes) {
    for (const dsp::DaySpread& d : c.day_spread) {
      w.u32(d.recordings);
      w.f64(d.log_rms_within_sd);
      w.f64(d.log_rms_between_est);
      w.f64(d.log_rms_between_sd);
      w.f64(d.entropy_within_sd);
      w.f64(d.entropy_between_est);
      w.f64(d.entropy_between_sd);
    }
  }
  // Version 5: the domain and the order windows' S and R; version 6: the speed law.
  if (order || bands || mesh) {
    w.u8(static_cast<std::uint8_t>(b.domain));
    w.u32(b.samples_per_rev);
    w.u32(b.revolutions);
  }
  if (order) {
    w.f64(b.speed_law_exponent);
    w.f64(b.speed_law_fit);
    w.f64(b.speed_law_se);
  }
  // Version 7: the band CUSUM's statistics (written only when trained with them; version 8 may say 0
  // bands, and then has no per-class band records).
  if (bands || mesh) w.u32(b.policy.band_count);
  if (bands) {
    for (const auto& c : b.classes) {
      w.u32(c.band_recordings);
      for (const dsp::BandEnergyStats& st : c.band_stats) {
        w.f64(st.mean);
        w.f64(st.within_sd);
        w.f64(st.between_est);
        w.f64(st.between_sd);
        w.u32(st.clean_bins);
      }
    }
  }
  // Version 8: the mesh detector's statistics.
  if (mesh) {
    for (const auto& c : b.classes) {
      w.u32(c.mesh_recordings);
      for (const dsp::MeshFeatureStats& st : c.mesh_stats) {
        w.f64(st.mean);
        w.f64(st.within_sd);
        w.f64(st.between_est);
        w.f64(st.between_sd);
        w.u32(st.windows);
      }
    }
  }
  w.patch_u64(kMagic.size() + 4, w.buf().size() + kCrcBytes);
  w.u32(crc32(w.buf().data(), w.buf().size()));
  return std::move(w.buf());
}

dsp::Baseline parse_baseline(std::span<const std::uint8_t> bytes, const std::string& source) {
  const std::size_t size = bytes.size();
  const std::size_t magic_seen = std::min(size, kMagic.size());
  // size is tested first: memcmp must not see the null data() of an empty span.
  if (size == 0 || std::memcmp(bytes.data(), kMagic.data(), magic_seen) != 0)
    throw Error(source + ": not a ptda baseline (bad magic, expected \"PTDABASE\")");
  if (size < kPreambleBytes + kCrcBytes)
    throw Error(source + ": truncated: " + std::to_string(size) + " bytes, shorter than the header");
  Reader r(bytes, source);
  r.skip(kMagic.size());
  const std::uint32_t version = r.u32();
  if (version < kBaselineOldestReadableVersion || version > kBaselineFormatVersion)
    throw Error(source + ": unsupported baseline format version " + std::to_string(version) +
                " (this build reads " + std::to_string(kBaselineOldestReadableVersion) + " to " +
                std::to_string(kBaselineFormatVersion) + ")");
  const std::uint64_t declared = r.u64();
  if (declared > size)
    throw Error(source + ": truncated: header says " + std::to_string(declared) + " bytes, file has " +
                std::to_string(size));
  if (declared < size)
    throw Error(source + ": corrupt: header says " + std::to_string(declared) + " bytes, file has " +
                std::to_string(size) + " (trailing bytes)");
  std::uint32_t stored = 0;
  for (std::size_t i = 0; i < 4; ++i) stored |= static_cast<std::uint32_t>(bytes[size - 4 + i]) << (8 * i);
  const std::uint32_t computed = crc32(bytes.data(), size - kCrcBytes);
  if (stored != computed)
    throw Error(source + ": corrupt: CRC-32 mismatch (stored " + hex32(stored) + ", computed " +
                hex32(computed) + ")");

  // From here the bytes are what the writer produced; the checks catch writer bugs and hand-made files.
  Reader body(bytes.first(size - kCrcBytes), source);
  body.skip(kPreambleBytes);
  dsp::Baseline b;
  b.fs_hz = body.f64();
  b.window_len = body.u32();
  const std::uint8_t gk = body.u8();
  if (gk > static_cast<std::uint8_t>(dsp::GearboxInfo::Kind::kUnknown))
    body.fail("unknown gearbox kind " + std::to_string(gk));
  b.gearbox.kind = static_cast<dsp::GearboxInfo::Kind>(gk);
  b.gearbox.z_in = body.u32();
  b.gearbox.z_spur = body.u32();
  b.gearbox.z_pin = body.u32();
  b.gearbox.ratio = body.f64();
  const std::uint8_t pk = body.u8();
  const auto last_kind =
      version == 1 ? dsp::ThresholdPolicy::Kind::kQuantile : dsp::ThresholdPolicy::Kind::kTolerance;
  if (pk > static_cast<std::uint8_t>(last_kind))
    body.fail("unknown threshold policy kind " + std::to_string(pk) + " for format version " +
              std::to_string(version));
  b.policy.kind = static_cast<dsp::ThresholdPolicy::Kind>(pk);
  b.policy.false_alarm_rate = body.f64();
  b.policy.margin = body.f64();
  if (version >= 2) {
    b.policy.confidence = body.f64();
    b.policy.holdout_fraction = body.f64();
  }
  const std::uint32_t n_classes = body.u32();
  if (n_classes > body.left() / kMinClassBytes)
    body.fail(std::to_string(n_classes) + " classes cannot fit in the remaining " +
              std::to_string(body.left()) + " bytes");
  const std::size_t n_mag = b.window_len / 2 + 1;
  b.classes.resize(n_classes);
  for (std::uint32_t i = 0; i < n_classes; ++i) {
    auto& c = b.classes[i];
    const std::string cls = "class " + std::to_string(i) + ": ";
    c.segment.id = body.u32();
    c.segment.direction = static_cast<std::int8_t>(body.u8());
    if (c.segment.direction != 1 && c.segment.direction != -1)
      body.fail(cls + "direction must be +1 or -1, got " + std::to_string(c.segment.direction));
    c.segment.speed_rad_s = body.f64();
    c.segment.speed_tol_rad_s = body.f64();
    c.segment.duration_s = body.f64();
    c.segment.regions = body.u32();
    c.n_windows = body.u32();
    const std::uint32_t n_m = body.u32();
    if (n_m != n_mag)
      body.fail(cls + "mean_magnitude has " + std::to_string(n_m) + " values, window_len " +
                std::to_string(b.window_len) + " needs N/2+1 = " + std::to_string(n_mag));
    body.need(std::size_t{4} * n_m);
    c.mean_magnitude.resize(n_m);
    for (auto& v : c.mean_magnitude) v = body.f32();
    const std::uint32_t n_t = body.u32();
    if (n_t != b.window_len)
      body.fail(cls + "tda_mean has " + std::to_string(n_t) + " values, window_len is " +
                std::to_string(b.window_len));
    body.need(std::size_t{4} * n_t);
    c.tda_mean.resize(n_t);
    for (auto& v : c.tda_mean) v = body.f32();
    for (auto& t : c.thresholds) {
      t.rms.lo = body.f64();
      t.rms.hi = body.f64();
      t.entropy.lo = body.f64();
      t.entropy.hi = body.f64();
    }
    for (auto& s : c.rms_stats) s = get_stats(body);
    for (auto& s : c.entropy_stats) s = get_stats(body);
    if (version >= 2) {
      for (auto& s : c.log_rms_stats) s = get_stats(body);
      c.windows_per_hour = body.f64();
      for (auto& h : c.holdout) h = get_holdout(body);
    } else {
      for (std::size_t m = 0; m < dsp::kMethodCount; ++m)
        c.log_rms_stats[m] = log_stats_from_linear(c.rms_stats[m]);
    }
  }
  const std::uint32_t n_src = body.u32();
  body.need(n_src);
  b.source.assign(reinterpret_cast<const char*>(bytes.data() + body.pos()), n_src);
  body.skip(n_src);
  if (version >= 2) {
    const auto text = [&] {
      const std::uint32_t n = body.u32();
      body.need(n);
      std::string t(reinterpret_cast<const char*>(bytes.data() + body.pos()), n);
      body.skip(n);
      return t;
    };
    const std::uint32_t n_training = body.u32();
    // id and path lengths, two times, the window count: at least 28 bytes each.
    if (n_training > body.left() / 28)
      body.fail(std::to_string(n_training) + " training recordings cannot fit in the remaining " +
                std::to_string(body.left()) + " bytes");
    b.training.resize(n_training);
    for (dsp::TrainingRecording& t : b.training) {
      t.id = text();
      t.path = text();
      t.from_unix_s = body.f64();
      t.to_unix_s = body.f64();
      t.windows = body.u32();
    }
  }
  b.policy.ptda_line_gain = false;  // versions 1 and 2 were trained with the paper's PTDA
  b.policy.ptda_floor_gain = false;
  if (version >= 3) {
    const std::uint32_t options = body.u32();
    constexpr std::uint32_t kKnown = kOptionLineGain | kOptionFloorGain;
    if ((options & ~kKnown) != 0U)
      body.fail("unknown option bits " + hex32(options & ~kKnown) +
                " (this build knows bit 0, line_gain, and bit 1, floor_gain)");
    b.policy.ptda_line_gain = (options & kOptionLineGain) != 0U;
    b.policy.ptda_floor_gain = (options & kOptionFloorGain) != 0U;
  }
  // Versions 1 to 3 know no between-day spread: floor 0 and every DaySpread zero, which the sequential
  // detector reads as the session-6 standardisation (dsp::sequential_scale).
  b.policy.day_sd_floor = 0.0;
  if (version >= 4) {
    b.policy.day_sd_floor = body.f64();
    // 3 methods x (u32 + 6 f64) per class.
    if (std::uint64_t{n_classes} * dsp::kMethodCount * 52U > body.left())
      body.fail("the day spread of " + std::to_string(n_classes) + " classes cannot fit in the remaining " +
                std::to_string(body.left()) + " bytes");
    for (auto& c : b.classes) {
      for (dsp::DaySpread& d : c.day_spread) {
        d.recordings = body.u32();
        d.log_rms_within_sd = body.f64();
        d.log_rms_between_est = body.f64();
        d.log_rms_between_sd = body.f64();
        d.entropy_within_sd = body.f64();
        d.entropy_between_est = body.f64();
        d.entropy_between_sd = body.f64();
      }
    }
  }
  // Versions 1 to 4 are time domain.
  if (version >= 5) {
    const std::uint8_t d = body.u8();
    if (d > static_cast<std::uint8_t>(dsp::Domain::kOrder))
      body.fail("unknown domain " + std::to_string(d) + " (this build knows 0, time, and 1, order)");
    b.domain = static_cast<dsp::Domain>(d);
    b.samples_per_rev = body.u32();
    b.revolutions = body.u32();
  }
  if (version >= 6 && b.domain == dsp::Domain::kOrder) {
    b.speed_law_exponent = body.f64();
    b.speed_law_fit = body.f64();
    b.speed_law_se = body.f64();
  }
  if (version >= 7) {
    const std::uint32_t count = body.u32();
    const std::uint32_t least = version >= 8 ? 0U : 1U;  // version 8 may carry mesh statistics alone
    if (count < least || count > dsp::kMaxBands || count > b.window_len / 2)
      body.fail("band_count " + std::to_string(count) + " must be " + std::to_string(least) + ".." +
                std::to_string(dsp::kMaxBands) + " and <= window_len / 2");
    // Per class: u32 + count x (4 f64 + u32).
    if (std::uint64_t{n_classes} * (4U + std::uint64_t{count} * 36U) > body.left())
      body.fail("the band statistics of " + std::to_string(n_classes) +
                " classes cannot fit in the remaining " + std::to_string(body.left()) + " bytes");
    b.policy.band_count = count;
    for (auto& c : b.classes) {
      if (count == 0) break;
      c.band_recordings = body.u32();
      c.band_stats.resize(count);
      for (dsp::BandEnergyStats& st : c.band_stats) {
        st.mean = body.f64();
        st.within_sd = body.f64();
        st.between_est = body.f64();
        st.between_sd = body.f64();
        st.clean_bins = body.u32();
      }
    }
  }
  if (version >= 8) {
    // Per class: u32 + 2 x (4 f64 + u32).
    if (std::uint64_t{n_classes} * (4U + dsp::kMeshFeatureCount * 36U) > body.left())
      body.fail("the mesh statistics of " + std::to_string(n_classes) +
                " classes cannot fit in the remaining " + std::to_string(body.left()) + " bytes");
    if (b.domain != dsp::Domain::kTime) body.fail("mesh statistics in an order-domain baseline");
    b.policy.mesh_stats = true;
    for (auto& c : b.classes) {
      c.mesh_recordings = body.u32();
      c.mesh_stats.resize(dsp::kMeshFeatureCount);
      for (dsp::MeshFeatureStats& st : c.mesh_stats) {
        st.mean = body.f64();
        st.within_sd = body.f64();
        st.between_est = body.f64();
        st.between_sd = body.f64();
        st.windows = body.u32();
      }
    }
  }
  if (body.left() != 0) body.fail(std::to_string(body.left()) + " unexpected bytes before the CRC");
  // A CRC only proves the bytes are what some writer produced: a forged or buggy file with NaN,
  // inverted bands or a zero spread would blind the monitor, so the values are checked too.
  validate_baseline(b, source);
  dsp::prepare_line_groups(b);
  return b;
}

dsp::Baseline read_baseline(const std::filesystem::path& path) {
  const std::string name = path.string();
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw Error(name + ": baseline file not found");
  // No FIFO, device or directory; not writable by others when running as root (issue 14 item 8).
  require_trusted_file(path, kMaxBaselineFileBytes, "baseline file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(name + ": cannot open baseline: " + std::strerror(errno));
  std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw Error(name + ": read error");
  return parse_baseline(bytes, name);
}

void write_baseline(const std::filesystem::path& path, const dsp::Baseline& baseline) {
  const std::string name = path.string();
  std::vector<std::uint8_t> bytes;
  try {
    bytes = serialize_baseline(baseline);
  } catch (const Error& e) {
    throw Error(name + ": not written: " + e.what());
  }
  // "<name>.tmp-<random>" in the same directory, O_EXCL|O_NOFOLLOW, fsync, rename, fsync of the
  // directory (common/atomic_file.hpp). Mode 0644 minus the umask (0600 under ptdad's UMask=0077).
  AtomicWriteOptions opt;
  opt.mode = 0644;
  opt.durable = true;
  const AtomicWriteResult r = write_file_atomic(name.c_str(), bytes.data(), bytes.size(), opt);
  if (!r.ok()) {
    throw WriteError(name + ": writing baseline failed at " + r.step + ": " + std::strerror(r.err), r.err);
  }
}

}  // namespace ptda::formats
