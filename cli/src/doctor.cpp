#include "ptda/cli/doctor.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <cstdio>
#include <map>
#include <numbers>
#include <ostream>

#include "ptda/cli/text.hpp"
#include "ptda/common/can_frame.hpp"
#include "ptda/common/error.hpp"
#include "ptda/config/speed_codec.hpp"
#include "ptda/dsp/angle_resampler.hpp"
#include "ptda/dsp/real_fft.hpp"
#include "ptda/dsp/window_slicer.hpp"
#include "ptda/formats/candump.hpp"

namespace ptda::cli {

namespace {

using Kind = DoctorFinding::Kind;

std::string id_text(std::uint32_t key) {
  const bool ext = (key & CanCounters::kExtendedIdKey) != 0;
  char buf[32];
  std::snprintf(buf, sizeof buf, ext ? "0x%08X (extended)" : "0x%03X", key & ~CanCounters::kExtendedIdKey);
  return buf;
}

std::string speed_text(double v) {
  return general(v, 4) + " rad/s";
}

// The largest FFT-friendly (factors 2, 3, 5; even) length <= n, or 0.
std::uint32_t fft_length_at_most(double n) {
  for (auto m = static_cast<std::int64_t>(std::floor(n)); m >= 4; --m) {
    if (dsp::RealFft::supported_length(static_cast<std::size_t>(m))) return static_cast<std::uint32_t>(m);
  }
  return 0;
}

double gmf_hz(const dsp::GearboxInfo& g, double speed_rad_s) {
  return static_cast<double>(g.z_in) * g.ratio * std::fabs(speed_rad_s) / (2.0 * std::numbers::pi);
}

// A uniform sample of at most kSampleSize values of a stream (reservoir sampling, algorithm R, with a
// fixed-seed splitmix64 generator: reproducible), for medians in bounded memory. It holds every value
// while fewer came (any recording under 2 min at 256 frames/s), so the median is then exact.
class ReservoirSample {
 public:
  static constexpr std::size_t kSampleSize = std::size_t{1} << 15;
  void add(double v) {
    if (values_.size() < kSampleSize) {
      values_.push_back(v);
    } else {
      // Value i (0-based) replaces a kept one with probability kSampleSize / (i + 1).
      rng_ += 0x9E3779B97F4A7C15ULL;
      std::uint64_t z = rng_;
      z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
      z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
      z ^= z >> 31;
      const std::uint64_t j = z % (seen_ + 1);
      if (j < kSampleSize) values_[static_cast<std::size_t>(j)] = v;
    }
    ++seen_;
  }
  [[nodiscard]] std::uint64_t seen() const noexcept { return seen_; }
  /// The sample's (size / 2)-th smallest value (the upper median); needs seen() > 0.
  [[nodiscard]] double median() const {
    std::vector<double> v = values_;
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    return v[v.size() / 2];
  }

 private:
  std::vector<double> values_;
  std::uint64_t seen_ = 0;
  std::uint64_t rng_ = 0x9E3779B97F4A7C15ULL;
};

// Decoded speeds of one id with the configured layout. How much they look like a joint speed is judged
// on all of them in bounded memory: the share in range and the range are counted, and the median step
// between consecutive values comes from a ReservoirSample of the steps. So the doctor's memory does not
// grow with the recording.
struct IdTrial {
  std::uint32_t key = 0;
  std::uint64_t frames = 0;
  double lo = 0.0, hi = 0.0;  // range of all decoded values (when decoded > 0)
  std::uint64_t decoded = 0;
  std::uint64_t in_range = 0;  // finite and within max_speed_rad_s
  double prev = 0.0;
  ReservoirSample steps;  // |consecutive differences|
  void add(double v, double max_speed_rad_s) {
    if (decoded == 0 || v < lo) lo = v;
    if (decoded == 0 || v > hi) hi = v;
    if (std::isfinite(v) && std::fabs(v) <= max_speed_rad_s) ++in_range;
    if (decoded > 0) steps.add(std::fabs(v - prev));
    prev = v;
    ++decoded;
  }
};

// How much a series of decoded values looks like a joint speed: in range, moving, and smooth
// (consecutive frames close compared with the range). 0..1.
double speed_likeness(const IdTrial& t, double min_speed_rad_s) {
  if (t.decoded < 10) return 0.0;
  const double range = t.hi - t.lo;
  if (!(range > min_speed_rad_s)) return 0.0;
  const double smooth = 1.0 - std::min(1.0, 20.0 * t.steps.median() / range);
  return static_cast<double>(t.in_range) / static_cast<double>(t.decoded) * smooth;
}

// Groups regions by direction and |speed| with the [classes] tolerance (sorted by speed, greedy).
struct Region {
  std::int8_t direction;
  double speed_rad_s;  // |mean speed|
  double duration_s;
  std::int64_t t_begin_ns, t_end_ns;
  std::uint64_t windows = 0;
  bool edge = false;  // cut by the start or the end of the recording
};

std::vector<std::vector<Region>> group_regions(std::vector<Region> regions,
                                               const dsp::ClassLearningConfig& c) {
  std::sort(regions.begin(), regions.end(), [](const Region& a, const Region& b) {
    return a.direction != b.direction ? a.direction < b.direction : a.speed_rad_s < b.speed_rad_s;
  });
  std::vector<std::vector<Region>> groups;
  double sum = 0.0;
  for (const Region& r : regions) {
    if (!groups.empty()) {
      const double mean = sum / static_cast<double>(groups.back().size());
      const double tol = std::max(c.speed_tol_abs_rad_s, c.speed_tol_rel * mean);
      if (groups.back().front().direction == r.direction && std::fabs(r.speed_rad_s - mean) <= tol) {
        groups.back().push_back(r);
        sum += r.speed_rad_s;
        continue;
      }
    }
    groups.push_back({r});
    sum = r.speed_rad_s;
  }
  return groups;
}

std::string signed_speed(std::int8_t direction, double speed_rad_s) {
  return std::string(direction < 0 ? "-" : "+") + general(speed_rad_s, 4);
}

// The CAN angle against the integral of the CAN speed (order domain), over stretches of 25 frames of
// motion in one direction: a unit or scale mistake in the angle shows as a ratio far from 1.
struct AngleCheck {
  static constexpr int kFramesPerStretch = 25;
  std::uint64_t frames = 0, with_angle = 0;
  std::uint64_t wraps = 0;  // steps that differ from the speed's integral by a whole turn (modulo-2 pi angle)
  double moving_s = 0.0;    // time between consecutive frames both above min_speed_rad_s
  ReservoirSample ratios;   // angle step / speed integral per stretch (a sample: bounded memory)
  bool have_prev = false;
  double prev_v = 0.0, prev_a = 0.0;
  std::int64_t prev_t = 0;
  double d_angle = 0.0, d_integral = 0.0;
  int n = 0;

  void add(std::int64_t t_ns, double v, bool has_angle, double a, double min_speed) {
    ++frames;
    if (!has_angle) {
      have_prev = false;
      n = 0;
      return;
    }
    ++with_angle;
    const bool moving = std::fabs(v) >= min_speed;
    if (have_prev && moving && std::fabs(prev_v) >= min_speed && (v > 0.0) == (prev_v > 0.0) &&
        t_ns > prev_t) {
      const double dt = static_cast<double>(t_ns - prev_t) * 1e-9;
      moving_s += dt;
      const double integral = 0.5 * (v + prev_v) * dt;
      // An angle sent modulo 2 pi jumps by a whole turn once per revolution: unwrapped here, counted.
      double step = a - prev_a;
      const double turns = std::round((step - integral) / (2.0 * std::numbers::pi));
      if (turns != 0.0 && std::fabs(step - integral - 2.0 * std::numbers::pi * turns) < 0.5) {
        step -= 2.0 * std::numbers::pi * turns;
        ++wraps;
      }
      d_angle += step;
      d_integral += integral;
      if (++n == kFramesPerStretch) {
        if (std::fabs(d_integral) > 1e-4) ratios.add(d_angle / d_integral);
        d_angle = d_integral = 0.0;
        n = 0;
      }
    } else {
      d_angle = d_integral = 0.0;
      n = 0;
    }
    have_prev = true;
    prev_v = v;
    prev_a = a;
    prev_t = t_ns;
  }
};

// Streams the recording: the speed samples, the regions of a relaxed slicer (any plateau of 0.12 s
// or more), the windows the configured slicer cuts, and the relaxed window at the highest speed.
class DoctorSink final : public PipelineSink {
 public:
  DoctorSink(const dsp::ExtractionConfig& configured, const dsp::ExtractionConfig& relaxed, double fs_hz,
             std::int64_t t0_ns)
      : configured_(configured, fs_hz, t0_ns),
        relaxed_(relaxed, fs_hz, t0_ns),
        buf_(configured.window_len),
        relaxed_buf_(relaxed.window_len) {}

  void on_speed(const dsp::SpeedSample& s) override {
    if (speeds == 0) first_speed_t_ns = s.t_ns;
    last_speed_t_ns = s.t_ns;
    if (speeds == 0 || s.speed_rad_s < speed_lo) speed_lo = s.speed_rad_s;
    if (speeds == 0 || s.speed_rad_s > speed_hi) speed_hi = s.speed_rad_s;
    ++speeds;
    configured_.push_speed(s);
    relaxed_.push_speed(s);
  }
  void on_samples(std::span<const float> block) override {
    configured_.push_samples(block);
    relaxed_.push_samples(block);
  }
  void on_block_end() override { drain(); }
  void on_finish() override {
    configured_.finish();
    relaxed_.finish();
    drain();
  }

  std::uint64_t speeds = 0;  // speed samples, and their range (kept as counts: memory stays flat)
  double speed_lo = 0.0, speed_hi = 0.0;
  std::int64_t first_speed_t_ns = 0, last_speed_t_ns = 0;
  // The plateaus are judged on the first kPlateauRegions (memory stays flat on long recordings; 2^12
  // is about 40 min of the arc-welding job's pieces, so a 1 h and a 24 h recording hold as much); the
  // windows are kept up to the end of the last of them.
  static constexpr std::size_t kPlateauRegions = std::size_t{1} << 12;
  static constexpr std::size_t kPlateauWindows = std::size_t{1} << 17;  // 1 MiB of window starts
  bool capped = false;  // regions beyond kPlateauRegions came: the last kept one is cut, like an edge
  std::vector<dsp::RegionInfo> regions;
  std::vector<std::int64_t> window_starts;  // t_start_ns of each configured window
  std::vector<float> fastest_window;
  double fastest_speed_rad_s = 0.0;

 private:
  void drain() {
    dsp::WindowRef ref;
    while (configured_.pop(ref, buf_)) {
      if ((regions.size() < kPlateauRegions || ref.t_start_ns <= regions.back().t_end_ns) &&
          window_starts.size() < kPlateauWindows) {
        window_starts.push_back(ref.t_start_ns);
      }
      // The configured windows are longer (a finer spectrum): preferred for the GMF check.
      if (!configured_fastest_ || std::fabs(ref.speed_rad_s) > fastest_speed_rad_s) {
        configured_fastest_ = true;
        fastest_speed_rad_s = std::fabs(ref.speed_rad_s);
        fastest_window = buf_;
      }
    }
    dsp::RegionInfo r;
    while (configured_.pop_region(r)) {
    }
    while (relaxed_.pop(ref, relaxed_buf_)) {
      if (!configured_fastest_ && std::fabs(ref.speed_rad_s) > fastest_speed_rad_s) {
        fastest_speed_rad_s = std::fabs(ref.speed_rad_s);
        fastest_window = relaxed_buf_;
      }
    }
    while (relaxed_.pop_region(r)) {
      if (regions.size() < kPlateauRegions) {
        regions.push_back(r);
      } else {
        capped = true;
      }
    }
  }

  bool configured_fastest_ = false;
  dsp::WindowSlicer configured_;
  dsp::WindowSlicer relaxed_;
  std::vector<float> buf_;
  std::vector<float> relaxed_buf_;
};

}  // namespace

bool DoctorReport::problems() const noexcept {
  return std::any_of(findings.begin(), findings.end(),
                     [](const DoctorFinding& f) { return f.kind == Kind::kProblem; });
}

ScaleCheck check_speed_scale(std::span<const float> window, double fs_hz, double speed_rad_s,
                             const dsp::GearboxInfo& gearbox) {
  ScaleCheck s;
  s.can_speed_rad_s = std::fabs(speed_rad_s);
  s.expected_gmf_hz = gmf_hz(gearbox, speed_rad_s);
  const std::size_t n = window.size();
  if (gearbox.z_in == 0 || !(gearbox.ratio > 0.0) || !(s.expected_gmf_hz > 0.0) ||
      !dsp::RealFft::supported_length(n))
    return s;
  // Hann-windowed magnitude spectrum and its median level.
  std::vector<float> x(window.begin(), window.end());
  double mean = 0.0;
  for (float v : x) mean += v;
  mean /= static_cast<double>(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double w =
        0.5 - 0.5 * std::cos(2.0 * std::numbers::pi * static_cast<double>(i) / static_cast<double>(n));
    x[i] = static_cast<float>((x[i] - mean) * w);
  }
  dsp::RealFft fft(n);
  std::vector<std::complex<float>> spec(fft.bins());
  fft.forward(x, spec);
  std::vector<double> mag(spec.size());
  for (std::size_t k = 0; k < spec.size(); ++k) mag[k] = std::abs(spec[k]);
  std::vector<double> sorted(mag.begin() + 1, mag.end());
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2),
                   sorted.end());
  const double floor = std::max(sorted[sorted.size() / 2], 1e-30);
  const double bin_hz = fs_hz / static_cast<double>(n);

  // Mean over the comb's harmonics of the largest bin within +-max(1.5 bins, 1 %) of k * f.
  const auto comb = [&](double f, double* peak_hz) {
    double sum = 0.0;
    int terms = 0;
    double best = 0.0;
    for (int k = 1; k <= 12; ++k) {
      const double fk = k * f;
      if (fk >= 0.45 * fs_hz) break;
      const double half = std::max(1.5 * bin_hz, 0.01 * fk);
      const auto lo = static_cast<std::size_t>(std::max(1.0, std::floor((fk - half) / bin_hz)));
      const auto hi = std::min(mag.size() - 1, static_cast<std::size_t>(std::ceil((fk + half) / bin_hz)));
      double m = 0.0;
      std::size_t at = lo;
      for (std::size_t b = lo; b <= hi; ++b) {
        if (mag[b] > m) {
          m = mag[b];
          at = b;
        }
      }
      sum += m / floor;
      ++terms;
      if (m > best && peak_hz != nullptr) {
        best = m;
        *peak_hz = static_cast<double>(at) * bin_hz / k;
      }
    }
    return terms >= 3 ? sum / terms : 0.0;
  };
  constexpr double kTwoPi = 2.0 * std::numbers::pi;
  const double factors[] = {1.0, 10.0, 0.1, 100.0, 0.01, 1000.0, 0.001, kTwoPi, 1.0 / kTwoPi};
  s.checked = true;
  double peak_hz = s.expected_gmf_hz;
  s.score_at_1 = comb(s.expected_gmf_hz, &peak_hz);
  s.score = s.score_at_1;
  s.measured_gmf_hz = peak_hz;
  for (double f : factors) {
    if (f == 1.0) continue;
    double p = 0.0;
    const double score = comb(f * s.expected_gmf_hz, &p);
    if (score > s.score && score >= 2.0 * s.score_at_1 && score >= 4.0) {
      s.score = score;
      s.factor = f;
      s.measured_gmf_hz = p;
    }
  }
  return s;
}

std::string scale_mismatch_text(const ScaleCheck& s, const config::PipelineConfig& cfg,
                                const std::string& config_source) {
  const double scale = cfg.speed_frame.speed.scale;
  return "the vibration's GMF comb is at " + general(s.measured_gmf_hz, 5) + " Hz, " +
         general(s.measured_gmf_hz / s.expected_gmf_hz, 4) + " times the " + general(s.expected_gmf_hz, 5) +
         " Hz that the CAN speed " + speed_text(s.can_speed_rad_s) +
         " and [gearbox] (GMF = z_in x ratio x speed / 2 pi) predict: the joint really turns at about " +
         speed_text(s.can_speed_rad_s * s.factor) + ", so the speed scale is off by a factor " +
         general(s.factor, 4) + ". Fix: set [can.speed_frame.speed] scale = " + general(scale * s.factor, 6) +
         " (now " + general(scale, 6) + ") in " + config_source +
         " (if the scale is right, check the [gearbox] teeth instead)";
}

namespace {

/// Unit and scale mistakes an angle signal is likely to have, as factors of the integrated speed.
struct AngleHypothesis {
  double factor;
  const char* why;
};

// The order domain's checks (docs/method.md §9): the CAN angle against the speed, the shaft speeds
// against the resampler's band, the windows of R revolutions the recording gives, the baseline's classes.
void diagnose_order(const RecordingInfo& rec, const config::PipelineConfig& cfg,
                    const std::string& config_source, const dsp::Baseline* baseline,
                    const std::string& baseline_source, const AngleCheck& angle, DoctorReport& rep) {
  const auto add = [&](Kind k, const char* topic, std::string text) {
    rep.findings.push_back(DoctorFinding{k, topic, std::move(text)});
  };
  const double fs_hz = static_cast<double>(rec.wav.sample_rate_hz);
  const dsp::GearboxInfo& g = cfg.gearbox;
  // ---- the angle against the integrated speed ----
  if (angle.with_angle == 0) {
    add(Kind::kProblem, "angle",
        "none of the " + std::to_string(angle.frames) +
            " speed frames carries an angle, and the order domain resamples by it. Fix: describe the angle "
            "signal in [can.speed_frame.angle] of " +
            config_source + " (or use domain = \"time\")");
    return;
  }
  if (angle.ratios.seen() < 3) {
    add(Kind::kNote, "angle",
        "the joint never moved long enough in one direction (" +
            std::to_string(AngleCheck::kFramesPerStretch) +
            " frames) to compare the CAN angle with the integrated speed");
  } else {
    const double m = angle.ratios.median();
    const std::string measured =
        "the CAN angle moves " + (std::fabs(m) < 100.0 ? fixed(m, 4) : general(m, 5)) +
        " times the integral of the CAN speed (median over " + std::to_string(angle.ratios.seen()) +
        (angle.ratios.seen() > ReservoirSample::kSampleSize
             ? " stretches, from a sample of " + std::to_string(ReservoirSample::kSampleSize) + ", of "
             : " stretches of ") +
        std::to_string(AngleCheck::kFramesPerStretch) + " frames)";
    const double scale = cfg.speed_frame.angle.scale;
    if (std::fabs(m - 1.0) <= 0.03) {
      add(Kind::kOk, "angle", "the CAN angle follows the integrated CAN speed: " + measured);
    } else {
      const double pi = std::numbers::pi;
      const std::array<AngleHypothesis, 13> hyps = {
          {{-1.0, "the angle counts the other way than the speed"},
           {180.0 / pi, "the angle is in degrees"},
           {pi / 180.0, "the speed is in degrees per second"},
           {g.ratio > 0.0 ? g.ratio : 1.0, "the angle is the motor's (input shaft's), not the joint's"},
           {g.ratio > 0.0 ? 1.0 / g.ratio : 1.0, "the speed is the motor's (input shaft's), not the joint's"},
           {2.0 * pi, "the angle is in revolutions"},
           {1.0 / (2.0 * pi), "the speed is in revolutions per second"},
           {10.0, "the angle scale is 10 times too large"},
           {0.1, "the angle scale is 10 times too small"},
           {100.0, "the angle scale is 100 times too large"},
           {0.01, "the angle scale is 100 times too small"},
           {1000.0, "the angle scale is 1000 times too large"},
           {0.001, "the angle scale is 1000 times too small"}}};
      const AngleHypothesis* best = nullptr;
      for (const AngleHypothesis& h : hyps) {
        if (h.factor == 1.0 || !(m / h.factor > 0.0)) continue;
        if (std::fabs(std::log(m / h.factor)) <= std::log(1.03) &&
            (best == nullptr || std::fabs(std::log(m / h.factor)) < std::fabs(std::log(m / best->factor))))
          best = &h;
      }
      if (best != nullptr) {
        add(Kind::kProblem, "angle",
            measured + ": " + best->why + ". Fix: set [can.speed_frame.angle] scale = " +
                general(scale / best->factor, 6) + " (now " + general(scale, 6) + ") in " + config_source +
                (best->factor == 1.0 / (2.0 * pi) || best->factor == pi / 180.0 ||
                         (g.ratio > 0.0 && best->factor == 1.0 / g.ratio)
                     ? " if the speed is right; else fix [can.speed_frame.speed] scale (ptda doctor's speed "
                       "and "
                       "GMF findings say which)"
                     : std::string()));
      } else {
        add(Kind::kProblem, "angle",
            measured +
                ", which is no unit mistake this check knows: the order domain needs the two to agree. "
                "Check [can.speed_frame.angle] (start_byte, length, signedness, scale) in " +
                config_source);
      }
    }
  }
  // ---- the shaft speeds against the resampler's band ----
  const dsp::AngleResamplerConfig rc = config::angle_resampler_config(cfg);
  const dsp::AngleResampler probe(rc, fs_hz, rec.t0_ns);
  const double peak = std::max(std::fabs(rep.speed_min_rad_s), std::fabs(rep.speed_max_rad_s));
  const double peak_shaft_hz = g.ratio * peak / (2.0 * std::numbers::pi);
  const std::string band =
      "[" + general(rc.min_shaft_hz, 4) + ", " + general(probe.max_shaft_hz(), 4) + "] Hz";
  if (peak_shaft_hz > probe.max_shaft_hz()) {
    // S such that the stop band stays below fs/2 at the peak, rounded down to an even number.
    const double s_fit =
        static_cast<double>(cfg.order.samples_per_rev) * probe.max_shaft_hz() / peak_shaft_hz;
    add(Kind::kNote, "shaft",
        "the input shaft reaches " + general(peak_shaft_hz, 4) + " Hz, above the " +
            general(probe.max_shaft_hz(), 4) +
            " Hz that samples_per_rev = " + std::to_string(cfg.order.samples_per_rev) + " allows at " +
            general(fs_hz, 6) + " Hz (fs / (2 x " + general(probe.stop_order(), 4) +
            ")): the stretches above it are not judged. To judge them, lower samples_per_rev to " +
            std::to_string(2 * static_cast<std::uint32_t>(s_fit / 2.0)) + " or less in " + config_source +
            " (its pass band, " + general(probe.pass_order() * s_fit / cfg.order.samples_per_rev, 4) +
            " orders, must still cover the mesh order z_in = " + std::to_string(g.z_in) + ")");
  } else {
    add(Kind::kOk, "shaft",
        "the input shaft turns at up to " + general(peak_shaft_hz, 4) + " Hz, inside the resampler's band " +
            band + " (pass band " + general(probe.pass_order(), 4) + " orders, GMF order " +
            std::to_string(g.z_in) + ")");
  }
  // ---- the windows of R revolutions ----
  RunOptions opts;
  opts.progress = false;
  opts.config_source = config_source;
  std::uint64_t windows = 0, matched = 0;
  double judged_s = 0.0;
  std::map<std::pair<int, long>, std::uint64_t> unmatched;  // (direction, speed in 0.01 rad/s) -> windows
  const OrderCollectResult c = collect_order_windows(
      rec, cfg, fs_hz, opts, [&](const dsp::OrderWindowRef& ref, std::span<const float>) {
        ++windows;
        judged_s += static_cast<double>(ref.t_end_ns - ref.t_start_ns) * 1e-9;
        if (baseline == nullptr) return;
        if (baseline->match(ref.joint_speed_rad_s) != nullptr) {
          ++matched;
        } else {
          ++unmatched[{ref.direction, std::lround(std::fabs(ref.joint_speed_rad_s) * 100.0)}];
        }
      });
  const dsp::AngleResamplerCounters& rs = c.resampler;
  if (angle.wraps > 0) {
    add(Kind::kNote, "angle",
        "the angle wraps modulo 2 pi (" + std::to_string(angle.wraps) +
            " whole-turn steps between frames): fine, the resampler takes the speed's integral across a "
            "wrap");
  }
  // The resampler counts a wrap as an inconsistent step too; only the rest is a problem.
  const std::uint64_t bad_steps =
      rs.angle_inconsistent > angle.wraps ? rs.angle_inconsistent - angle.wraps : 0;
  if (rs.frames > 0 && bad_steps * 100 > rs.frames) {
    add(Kind::kProblem, "angle",
        std::to_string(bad_steps) + " of " + std::to_string(rs.frames) +
            " angle steps disagree with the speed by more than half of it (the resampler used the speed's "
            "integral instead): a wrong angle scale (above), lost frames or a corrupt angle signal");
  } else if (bad_steps > 0) {
    add(Kind::kNote, "angle",
        std::to_string(bad_steps) + " of " + std::to_string(rs.frames) +
            " angle steps disagree with the speed (a bad frame or log-time jitter; the speed's integral was "
            "used)");
  }
  const double revs = static_cast<double>(rs.outputs) / static_cast<double>(cfg.order.samples_per_rev);
  const std::string cov = angle.moving_s > 0.0
                              ? " (" + general(100.0 * std::min(1.0, judged_s / angle.moving_s), 3) +
                                    " % of the " + fixed(angle.moving_s, 2) + " s the joint moved)"
                              : std::string();
  const std::string win = "[extraction] revolutions = " + std::to_string(cfg.order.revolutions) +
                          " x samples_per_rev = " + std::to_string(cfg.order.samples_per_rev);
  if (windows == 0) {
    add(Kind::kProblem, "windows",
        win + ": no window is cut from " + general(revs, 4) + " resampled input-shaft revolutions in " +
            std::to_string(rs.breaks + (rs.outputs > 0 ? 1 : 0)) + " unbroken stretch(es) of motion (" +
            general(
                revs / static_cast<double>(std::max<std::uint64_t>(1, rs.breaks + (rs.outputs > 0 ? 1 : 0))),
                3) +
            " revolutions on average; broken at standstill, reversal, a CAN gap or a shaft speed outside " +
            band + "). Fix: fewer revolutions per window (R x S must be an FFT length) in " + config_source);
  } else {
    add(Kind::kOk, "windows",
        win + ": " + std::to_string(windows) + " windows, " + fixed(judged_s, 2) + " s judged" + cov +
            ", from " + general(revs, 4) + " resampled revolutions");
  }
  // ---- the baseline ----
  if (baseline == nullptr) return;
  if (baseline->domain != dsp::Domain::kOrder || baseline->samples_per_rev != cfg.order.samples_per_rev ||
      baseline->revolutions != cfg.order.revolutions) {
    add(Kind::kProblem, "baseline",
        baseline_source +
            (baseline->domain != dsp::Domain::kOrder
                 ? std::string(" was trained in the time domain")
                 : " was trained with samples_per_rev = " + std::to_string(baseline->samples_per_rev) +
                       ", revolutions = " + std::to_string(baseline->revolutions)) +
            ", but " + config_source +
            " sets the order domain with samples_per_rev = " + std::to_string(cfg.order.samples_per_rev) +
            ", revolutions = " + std::to_string(cfg.order.revolutions) +
            ". Fix: use the configuration the baseline was trained with, or retrain");
    return;
  }
  std::string classes;
  for (const dsp::ClassBaseline& k : baseline->classes)
    classes += (classes.empty() ? "" : ", ") + signed_speed(k.segment.direction, k.segment.speed_rad_s);
  std::string missed;
  for (const auto& [key, n] : unmatched)
    missed += (missed.empty() ? "" : ", ") +
              signed_speed(static_cast<std::int8_t>(key.first), key.second / 100.0) + " x " +
              std::to_string(n);
  if (windows == 0) {
    // Nothing to compare: the window finding says why.
  } else if (matched == 0) {
    add(Kind::kProblem, "baseline",
        "none of the " + std::to_string(windows) + " windows' speeds (" + missed + ") matches a class of " +
            baseline_source + " (" + classes +
            " rad/s): nothing would be judged. Fix: train a baseline on this job (ptda train --recording "
            "<healthy recording of this job> --config " +
            config_source + " --out <baseline>)");
  } else if (matched < windows) {
    add(Kind::kNote, "baseline",
        std::to_string(windows - matched) + " of " + std::to_string(windows) + " windows match no class of " +
            baseline_source + " (" + classes + " rad/s; unmatched, rad/s x windows: " + missed +
            "): they are not judged; retrain on recordings that include those speeds to cover them");
  } else {
    add(Kind::kOk, "baseline",
        "every window's speed matches a class of " + baseline_source + " (" + classes + " rad/s)");
  }
}

}  // namespace

DoctorReport diagnose_commissioning(const RecordingInfo& rec, const config::PipelineConfig& cfg,
                                    const std::string& config_source, const dsp::Baseline* baseline,
                                    const std::string& baseline_source) {
  DoctorReport rep;
  const auto add = [&](Kind k, const char* topic, std::string text) {
    rep.findings.push_back(DoctorFinding{k, topic, std::move(text)});
  };
  const double fs_hz = static_cast<double>(rec.wav.sample_rate_hz);
  if (cfg.fs_hz != 0.0 && std::fabs(cfg.fs_hz - fs_hz) > 1e-9 * fs_hz) {
    add(Kind::kProblem, "recording",
        "[acquisition] fs_hz = " + general(cfg.fs_hz, 10) + " Hz but the recording is sampled at " +
            general(fs_hz, 10) + " Hz. Fix: set fs_hz = " + general(fs_hz, 10) + " (or 0) in " +
            config_source);
    return rep;
  }

  // ---- CAN: frames per id, frames decoded, the most likely speed id ----
  const config::SpeedFrameSpec& spec = cfg.speed_frame;
  const std::uint32_t configured_key = spec.id | (spec.extended ? CanCounters::kExtendedIdKey : 0U);
  std::map<std::uint32_t, IdTrial> trials;
  AngleCheck angle;
  {
    formats::CandumpReader can(rec.can_path);
    formats::CandumpRecord record;
    while (can.next(record)) {
      ++rep.can_frames;
      if ((record.frame.flags & kCanError) != 0) continue;
      const std::uint32_t key =
          record.frame.id | (record.frame.extended() ? CanCounters::kExtendedIdKey : 0U);
      ++rep.can_ids[key];
      IdTrial& t = trials[key];
      t.key = key;
      ++t.frames;
      config::SpeedFrameSpec s = spec;
      s.id = record.frame.id;
      s.extended = record.frame.extended();
      config::DecodedSpeed d;
      if (config::decode_speed(record.frame, s, d) == config::DecodeResult::kOk) {
        t.add(d.speed_rad_s, cfg.extraction.max_speed_rad_s);
        if (key == configured_key) {
          ++rep.speed_frames;
          angle.add(record.frame.t_ns, d.speed_rad_s, d.has_angle, d.angle_rad,
                    cfg.extraction.min_speed_rad_s);
        }
      }
    }
  }
  if (rep.can_frames > 0) {
    std::string ids;
    for (const auto& [key, n] : rep.can_ids)
      ids += (ids.empty() ? "" : ", ") + id_text(key) + " x " + std::to_string(n);
    add(Kind::kOk, "can",
        std::to_string(rep.can_frames) + " CAN frames (" + ids + "); " + std::to_string(rep.speed_frames) +
            " decoded as speed with id " + id_text(configured_key) + " and the configured layout");
  }
  const IdTrial* best = nullptr;
  double best_score = 0.0;
  for (const auto& [key, t] : trials) {
    const double score = speed_likeness(t, cfg.extraction.min_speed_rad_s);
    if (score > best_score) {
      best_score = score;
      best = &t;
    }
  }

  // The recording itself (check_can_input's messages for CAN input that cannot work).
  dsp::ExtractionConfig relaxed = cfg.extraction;
  relaxed.window_len = std::max<std::uint32_t>(64, fft_length_at_most(std::min(0.1 * fs_hz, 65536.0)));
  relaxed.hop = relaxed.window_len;
  relaxed.max_windows_per_region = 0;
  relaxed.guard_s = 0.0;
  relaxed.min_duration_s = 1.2 * relaxed.window_len / fs_hz;
  DoctorSink sink(cfg.extraction, relaxed, fs_hz, rec.t0_ns);
  RunOptions opts;
  opts.progress = false;
  opts.config_source = config_source;
  try {
    (void)run_recording(rec, cfg, sink, opts);
  } catch (const Error& e) {
    std::string text = e.what();
    if (best != nullptr && best->key != configured_key && best_score > 0.5) {
      const double* lo = &best->lo;
      const double* hi = &best->hi;
      text += ". The most likely speed frame is " + id_text(best->key) + " (" + std::to_string(best->frames) +
              " frames, decoding to " + general(*lo, 4) + " .. " + general(*hi, 4) +
              " rad/s with the configured layout): set id = 0x" +
              [&] {
                char b[16];
                std::snprintf(b, sizeof b, "%X", best->key & ~CanCounters::kExtendedIdKey);
                return std::string(b);
              }() +
              ((best->key & CanCounters::kExtendedIdKey) != 0 ? " and extended = true" : "") +
              " in [can.speed_frame]";
    }
    add(Kind::kProblem, "can", text);
    return rep;
  }

  // ---- speed range against [extraction] and [gearbox] ----
  if (sink.speeds > 0) {
    const double* lo = &sink.speed_lo;
    const double* hi = &sink.speed_hi;
    rep.speed_min_rad_s = *lo;
    rep.speed_max_rad_s = *hi;
    const double peak = std::max(std::fabs(*lo), std::fabs(*hi));
    std::string text = "decoded speed " + general(*lo, 4) + " .. " + general(*hi, 4) + " rad/s";
    const dsp::GearboxInfo& g = cfg.gearbox;
    if (g.z_in > 0 && g.ratio > 0.0) {
      const double f_in = g.ratio * peak / (2.0 * std::numbers::pi);
      text += "; at " + speed_text(peak) + " the input shaft turns at " + general(f_in, 4) + " Hz (" +
              general(60.0 * f_in, 5) + " rpm) and the GMF is " + general(gmf_hz(g, peak), 5) + " Hz";
      if (gmf_hz(g, peak) >= 0.5 * fs_hz) {
        add(Kind::kProblem, "speed",
            text + ", above half the sample rate (" + general(0.5 * fs_hz, 6) +
                " Hz): the speed scale or the [gearbox] teeth in " + config_source + " are wrong");
      } else if (60.0 * f_in > 20000.0) {
        add(Kind::kProblem, "speed",
            text + ": no motor turns that fast; check [can.speed_frame.speed] scale and [gearbox] ratio in " +
                config_source);
      } else {
        add(Kind::kOk, "speed", text);
      }
    } else {
      add(Kind::kNote, "speed",
          text + "; [gearbox] gives no teeth, so the GMF check is skipped (set z_in, z_spur, z_pin in " +
              config_source + ")");
    }
    if (peak < cfg.extraction.min_speed_rad_s) {
      add(Kind::kProblem, "speed",
          "the joint never turns faster than " + speed_text(peak) +
              ", below [extraction] min_speed_rad_s = " + general(cfg.extraction.min_speed_rad_s) +
              ": everything counts as standstill. Check the speed scale, or lower min_speed_rad_s in " +
              config_source);
    }
  }

  // ---- the vibration's own GMF against the CAN speed ----
  if (!sink.fastest_window.empty()) {
    rep.scale = check_speed_scale(sink.fastest_window, fs_hz, sink.fastest_speed_rad_s, cfg.gearbox);
    if (rep.scale.mismatch()) {
      add(Kind::kProblem, "scale", scale_mismatch_text(rep.scale, cfg, config_source));
    } else if (rep.scale.checked && rep.scale.score_at_1 >= 4.0) {
      add(Kind::kOk, "scale",
          "the vibration's GMF comb (" + general(rep.scale.measured_gmf_hz, 5) + " Hz at " +
              speed_text(rep.scale.can_speed_rad_s) + ") matches the CAN speed and [gearbox]");
    } else if (rep.scale.checked) {
      add(Kind::kNote, "scale",
          "no clear GMF comb near the " + general(rep.scale.expected_gmf_hz, 5) + " Hz expected at " +
              speed_text(rep.scale.can_speed_rad_s) +
              " (nor at 10, 100 or 2 pi times it): check the [gearbox] teeth in " + config_source);
    }
  }

  if (cfg.domain == dsp::Domain::kOrder) {
    diagnose_order(rec, cfg, config_source, baseline, baseline_source, angle, rep);
    return rep;
  }

  // ---- plateaus per speed against the window ----
  std::vector<Region> regions;
  // Plateaus cut by the start or the end of the recording are not plateau lengths.
  const auto edge_ns = static_cast<std::int64_t>(3.0 * cfg.speed_frame.period_s * 1e9);
  for (const dsp::RegionInfo& r : sink.regions) {
    regions.push_back(Region{
        r.direction, std::fabs(r.mean_speed_rad_s), (r.t_end_ns - r.t_begin_ns) * 1e-9, r.t_begin_ns,
        r.t_end_ns, 0,
        r.t_begin_ns <= sink.first_speed_t_ns + edge_ns || r.t_end_ns >= sink.last_speed_t_ns - edge_ns});
  }
  // Plateaus beyond kPlateauRegions were not kept: the last kept piece may continue in them.
  if (sink.capped && !regions.empty()) regions.back().edge = true;
  // Pieces of one plateau (broken by a single speed outlier) are merged back: same direction and
  // speed, at most 3 speed periods apart.
  {
    std::vector<Region> merged;
    for (const Region& r : regions) {
      if (!merged.empty()) {
        Region& p = merged.back();
        const double tol =
            std::max(cfg.classes.speed_tol_abs_rad_s, cfg.classes.speed_tol_rel * p.speed_rad_s);
        if (p.direction == r.direction && std::fabs(p.speed_rad_s - r.speed_rad_s) <= tol &&
            r.t_begin_ns - p.t_end_ns <= edge_ns) {
          p.speed_rad_s =
              (p.speed_rad_s * p.duration_s + r.speed_rad_s * r.duration_s) / (p.duration_s + r.duration_s);
          p.t_end_ns = r.t_end_ns;
          p.edge = p.edge || r.edge;
          p.duration_s = (p.t_end_ns - p.t_begin_ns) * 1e-9;
          continue;
        }
      }
      merged.push_back(r);
    }
    regions = std::move(merged);
  }
  for (const std::int64_t t_start_ns : sink.window_starts) {
    for (Region& r : regions) {
      if (t_start_ns >= r.t_begin_ns - 1000000 && t_start_ns <= r.t_end_ns) {
        ++r.windows;
        break;
      }
    }
  }
  const double window_s = cfg.extraction.window_len / fs_hz;
  const std::uint32_t min_regions = std::max<std::uint32_t>(1, cfg.classes.min_regions);
  double shortest_all = 0.0;
  std::uint32_t dropped_all = 0, plateaus_all = 0;
  for (auto g : group_regions(regions, cfg.classes)) {
    // Plateaus cut by the start or the end of the recording are not plateau lengths (unless nothing
    // else is left, e.g. a constant-speed recording).
    if (std::any_of(g.begin(), g.end(), [](const Region& r) { return !r.edge; }))
      std::erase_if(g, [](const Region& r) { return r.edge; });
    if (g.size() < min_regions) continue;  // a blend's short constant stretch, not a plateau
    // Pieces under half the median length are fragments (a plateau broken by a speed outlier or a CAN
    // gap), not plateaus of their own.
    std::vector<double> lengths;
    for (const Region& r : g) lengths.push_back(r.duration_s);
    std::nth_element(lengths.begin(), lengths.begin() + static_cast<std::ptrdiff_t>(lengths.size() / 2),
                     lengths.end());
    const double half_median = 0.5 * lengths[lengths.size() / 2];
    std::erase_if(g, [&](const Region& r) { return r.duration_s < half_median && r.windows == 0; });
    PlateauGroup pg;
    pg.direction = g.front().direction;
    std::vector<double> d;
    for (const Region& r : g) {
      pg.speed_rad_s += r.speed_rad_s / static_cast<double>(g.size());
      d.push_back(r.duration_s);
      pg.windows += r.windows;
      if (r.windows > 0) ++pg.plateaus_with_windows;
    }
    std::sort(d.begin(), d.end());
    pg.plateaus = static_cast<std::uint32_t>(g.size());
    pg.shortest_s = d.front();
    pg.median_s = d[d.size() / 2];
    pg.longest_s = d.back();
    shortest_all = shortest_all == 0.0 ? pg.shortest_s : std::min(shortest_all, pg.shortest_s);
    dropped_all += pg.plateaus - pg.plateaus_with_windows;
    plateaus_all += pg.plateaus;
    rep.groups.push_back(pg);
  }
  std::string plateau_text;
  for (const PlateauGroup& pg : rep.groups) {
    plateau_text += std::string(plateau_text.empty() ? "" : "; ") +
                    signed_speed(pg.direction, pg.speed_rad_s) + " rad/s: " + std::to_string(pg.plateaus) +
                    " plateaus of " + fixed(pg.shortest_s, 3) + " .. " + fixed(pg.longest_s, 3) +
                    " s (median " + fixed(pg.median_s, 3) + " s), " + std::to_string(pg.windows) +
                    " windows from " + std::to_string(pg.plateaus_with_windows);
  }
  if (rep.groups.empty()) {
    add(Kind::kProblem, "plateaus",
        "no constant-speed plateau repeats at least " + std::to_string(min_regions) +
            " times (speed tolerance [extraction] speed_tol_rel = " + general(cfg.extraction.speed_tol_rel) +
            ", speed_tol_abs_rad_s = " + general(cfg.extraction.speed_tol_abs_rad_s) +
            "): record the joint moving at constant speeds, or widen the tolerance in " + config_source);
  } else {
    const std::uint32_t fit_len = fft_length_at_most((shortest_all - cfg.extraction.guard_s) * fs_hz * 0.95);
    const std::string fix =
        fit_len == 0
            ? std::string("the plateaus are too short for any window")
            : "window_len = " + std::to_string(fit_len) + " (" + fixed(fit_len / fs_hz, 3) +
                  " s) with min_duration_s = " + fixed(fit_len / fs_hz + cfg.extraction.guard_s + 0.01, 3) +
                  " fits every plateau (guard_s " + general(cfg.extraction.guard_s) + ")";
    const std::string window = "[extraction] window_len = " + std::to_string(cfg.extraction.window_len) +
                               " (" + fixed(window_s, 3) +
                               " s), min_duration_s = " + general(cfg.extraction.min_duration_s);
    if (dropped_all == plateaus_all) {
      add(Kind::kProblem, "plateaus",
          window + " is longer than every plateau (" + plateau_text + "): no window is cut. Fix: " + fix +
              " in " + config_source);
    } else if (dropped_all > 0) {
      add(Kind::kProblem, "plateaus",
          window + " fits only some plateaus: " + std::to_string(dropped_all) + " of " +
              std::to_string(plateaus_all) + " give no window (" + plateau_text + "). Fix: " + fix + " in " +
              config_source);
    } else {
      add(Kind::kOk, "plateaus", window + " fits every plateau: " + plateau_text);
    }
  }

  // ---- the baseline's classes against the recording's speeds ----
  if (baseline != nullptr) {
    if (std::fabs(baseline->fs_hz - fs_hz) > 1e-9 * fs_hz ||
        baseline->window_len != cfg.extraction.window_len) {
      add(Kind::kProblem, "baseline",
          baseline_source + " was trained at " + general(baseline->fs_hz, 10) + " Hz with window_len " +
              std::to_string(baseline->window_len) + ", but the recording is at " + general(fs_hz, 10) +
              " Hz and " + config_source + " sets window_len " + std::to_string(cfg.extraction.window_len) +
              ". Fix: use the configuration the baseline was trained with, or retrain");
    }
    std::string classes;
    std::uint32_t matched_groups = 0;
    for (const dsp::ClassBaseline& c : baseline->classes) {
      classes += (classes.empty() ? "" : ", ") + signed_speed(c.segment.direction, c.segment.speed_rad_s);
    }
    std::string unmatched;
    for (const PlateauGroup& pg : rep.groups) {
      bool match = false;
      for (const dsp::ClassBaseline& c : baseline->classes) {
        match = match || (c.segment.direction == pg.direction &&
                          std::fabs(pg.speed_rad_s - c.segment.speed_rad_s) <= c.segment.speed_tol_rad_s);
      }
      if (match) {
        ++matched_groups;
      } else {
        unmatched += (unmatched.empty() ? "" : ", ") + signed_speed(pg.direction, pg.speed_rad_s);
      }
    }
    if (rep.groups.empty()) {
      // Nothing to compare: the plateau finding says why.
    } else if (matched_groups == 0) {
      add(Kind::kProblem, "baseline",
          "none of the recording's plateau speeds (" + unmatched + " rad/s) matches a class of " +
              baseline_source + " (" + classes +
              " rad/s): the baseline belongs to another job or speed scale, so nothing would be "
              "judged. Fix: train a baseline on this job (ptda train --recording <healthy recording of this "
              "job> "
              "--config " +
              config_source + " --out <baseline>)");
    } else if (!unmatched.empty()) {
      add(Kind::kNote, "baseline",
          "plateau speeds " + unmatched + " rad/s have no class in " + baseline_source + " (" + classes +
              " rad/s): their windows are not judged; retrain on recordings that include them to cover them");
    } else {
      add(Kind::kOk, "baseline",
          "every plateau speed of the recording matches a class of " + baseline_source + " (" + classes +
              " rad/s)");
    }
  }
  return rep;
}

void print_diagnosis(std::ostream& out, const DoctorReport& report) {
  for (const DoctorFinding& f : report.findings) {
    const char* tag = f.kind == Kind::kProblem ? "PROBLEM" : f.kind == Kind::kNote ? "note" : "ok";
    out << tag << " (" << f.topic << "): " << f.text << "\n";
  }
}

}  // namespace ptda::cli
