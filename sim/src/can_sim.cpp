// CAN bus as the robot controller produces it: speed frames from a free-running clock (not locked to
// the ADC), a transport delay and jitter on the log timestamps, and optional unrelated traffic.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <memory>

#include "ptda/common/error.hpp"
#include "ptda/common/time.hpp"
#include "ptda/sim/random.hpp"
#include "ptda/sim/simulator.hpp"
#include "ptda/sim/stream.hpp"
#include "sim_internal.hpp"

namespace ptda::sim {
namespace {

// candump logs carry microseconds; rounding here keeps in-memory frames equal to what is read back.
std::int64_t round_to_us(std::int64_t t_ns) {
  return (t_ns + 500) / 1000 * 1000;
}

// A few typical neighbours: CANopen SYNC (no data), a PDO with 8 bytes, a heartbeat.
struct Other {
  std::uint32_t id;
  std::uint8_t len;
};
constexpr std::array<Other, 3> kOthers{{{0x080, 0}, {0x201, 8}, {0x701, 1}}};

/// The speed frames: the free-running controller clock sampled through motion_at(), one at a time.
struct SpeedFrames {
  const CanSpec& c;
  const MotionProfile& m;
  config::SpeedFrameSpec spec;
  std::int64_t start_ns;
  double period_true_s;
  Rng rng;
  std::uint64_t k = 0;
  PieceCursor cursor;  // the speed frames' instants increase

  SpeedFrames(const Scenario& s, const MotionProfile& mp, std::uint64_t seed)
      : c(s.can),
        m(mp),
        spec(s.can.speed_frame),
        start_ns(seconds_to_ns(s.start_time_s)),
        period_true_s(s.can.period_s * (1.0 + s.can.clock_drift_ppm * 1e-6)),
        rng(seed, kStreamCan),
        cursor(mp) {
    spec.period_s = c.period_s;
  }
  bool next(SimCanFrame& f) {
    const double t = c.clock_offset_s + static_cast<double>(k) * period_true_s;
    if (t > m.duration_s) return false;
    ++k;
    const MotionState st = motion_at(m, cursor, t);
    const double jitter = c.jitter_s * rng.uniform();
    const std::int64_t t_ns = round_to_us(start_ns + seconds_to_ns(t + c.delay_s + jitter));
    f.frame = config::encode_speed(spec, t_ns, st.speed_rad_s, st.angle_rad);
    f.true_time_s = t;
    f.is_speed = true;
    return true;
  }
};

/// The unrelated frames in the order they are drawn (not sorted): frame i of `count`.
struct OtherFrames {
  const config::SpeedFrameSpec& spec;
  double duration_s;
  std::int64_t start_ns;
  Rng rng;
  /// Draws frame i (in order from 0); false when it is skipped (it would look like a speed frame).
  bool next(std::uint64_t i, SimCanFrame& f) {
    const double t = rng.uniform() * duration_s;
    const Other& o = kOthers[static_cast<std::size_t>(i % kOthers.size())];
    if (o.id == spec.id && !spec.extended) return false;  // never fake a speed frame
    f = SimCanFrame{};
    f.frame.t_ns = round_to_us(start_ns + seconds_to_ns(t));
    f.frame.id = o.id;
    f.frame.len = o.len;
    for (std::uint8_t b = 0; b < o.len; ++b)
      f.frame.data[b] = static_cast<std::uint8_t>(rng.next_u64() & 0xFFU);
    if (o.id == 0x701) f.frame.data[0] = 0x05;  // NMT state "operational"
    f.true_time_s = std::numeric_limits<double>::quiet_NaN();
    f.is_speed = false;
    return true;
  }
};

std::uint64_t other_frame_count(const CanSpec& c, const MotionProfile& m) {
  return static_cast<std::uint64_t>(std::floor(c.other_frames_per_s * m.duration_s));
}

}  // namespace

std::vector<SimCanFrame> generate_can(const Scenario& s, const MotionProfile& m, std::uint64_t seed) {
  const CanSpec& c = s.can;
  SpeedFrames speed(s, m, seed);
  std::vector<SimCanFrame> out;
  out.reserve(static_cast<std::size_t>(m.duration_s / speed.period_true_s) + 2);
  SimCanFrame f;
  while (speed.next(f)) out.push_back(f);

  if (c.other_frames_per_s > 0) {
    OtherFrames others{speed.spec, m.duration_s, speed.start_ns, Rng(seed, kStreamOtherFrames)};
    const std::uint64_t count = other_frame_count(c, m);
    for (std::uint64_t i = 0; i < count; ++i) {
      if (others.next(i, f)) out.push_back(f);
    }
    std::stable_sort(out.begin(), out.end(),
                     [](const SimCanFrame& a, const SimCanFrame& b) { return a.frame.t_ns < b.frame.t_ns; });
  }
  return out;
}

struct CanStream::Impl {
  const Scenario& s;
  const MotionProfile& m;
  std::uint64_t seed;
  SpeedFrames speed;
  bool speed_pending = false;
  SimCanFrame speed_frame;
  std::int64_t last_speed_ns = std::numeric_limits<std::int64_t>::min();
  // The unrelated frames, window by window of log time [win_lo_ns, win_lo_ns + win_ns): each window
  // draws all of them again and keeps its own, sorted stably (ties in drawing order, as the whole-log
  // stable sort leaves them).
  bool with_others = false;
  std::uint64_t count = 0;
  std::int64_t win_ns = 0;
  std::int64_t win_lo_ns = 0;
  std::int64_t end_ns = 0;  // beyond every unrelated frame
  // An unrelated frame as the window keeps it (24 bytes instead of a SimCanFrame's 96).
  struct Other {
    std::int64_t t_ns;
    std::uint32_t id;
    std::uint8_t len;
    std::array<std::uint8_t, 8> data;
  };
  std::vector<Other> window;
  std::size_t win_pos = 0;

  Impl(const Scenario& sc, const MotionProfile& mp, std::uint64_t sd, std::size_t window_frames)
      : s(sc), m(mp), seed(sd), speed(sc, mp, sd) {
    with_others = s.can.other_frames_per_s > 0;
    if (with_others) {
      count = other_frame_count(s.can, m);
      const double w_s = static_cast<double>(std::max<std::size_t>(window_frames, 1)) /
                         static_cast<double>(s.can.other_frames_per_s);
      win_ns = std::max<std::int64_t>(seconds_to_ns(w_s), 1000);
      window.reserve(std::min<std::uint64_t>(count, window_frames + window_frames / 8 + 64));
      win_lo_ns = speed.start_ns - 1000;  // rounding to microseconds moves a frame by at most 500 ns
      end_ns = speed.start_ns + seconds_to_ns(m.duration_s) + 1000;
    }
    advance_speed();
  }

  void advance_speed() {
    speed_pending = speed.next(speed_frame);
    if (speed_pending && with_others) {
      if (speed_frame.frame.t_ns < last_speed_ns)
        throw Error("CAN simulation: speed frames out of order (jitter_s must stay below period_s)");
      last_speed_ns = speed_frame.frame.t_ns;
    }
  }

  /// Fills `window` with the next non-empty window's frames; false when there are no more.
  bool refill() {
    while (win_pos >= window.size()) {
      if (win_lo_ns >= end_ns) return false;
      const std::int64_t lo = win_lo_ns;
      const std::int64_t hi = win_lo_ns + win_ns;
      win_lo_ns = hi;
      window.clear();
      win_pos = 0;
      OtherFrames others{speed.spec, m.duration_s, speed.start_ns, Rng(seed, kStreamOtherFrames)};
      SimCanFrame f;
      for (std::uint64_t i = 0; i < count; ++i) {
        if (others.next(i, f) && f.frame.t_ns >= lo && f.frame.t_ns < hi) {
          Other o{f.frame.t_ns, f.frame.id, f.frame.len, {}};
          std::copy_n(f.frame.data.begin(), std::min<std::size_t>(f.frame.len, o.data.size()),
                      o.data.begin());
          window.push_back(o);
        }
      }
      std::stable_sort(window.begin(), window.end(),
                       [](const Other& a, const Other& b) { return a.t_ns < b.t_ns; });
    }
    return true;
  }
};

CanStream::CanStream(const Scenario& s, const MotionProfile& m, std::uint64_t seed, std::size_t window_frames)
    : impl_(std::make_unique<Impl>(s, m, seed, window_frames)) {}

CanStream::~CanStream() = default;

bool CanStream::next(SimCanFrame& out) {
  Impl& im = *impl_;
  const bool other = im.with_others && im.refill();
  if (!im.speed_pending && !other) return false;
  if (im.speed_pending && (!other || im.speed_frame.frame.t_ns <= im.window[im.win_pos].t_ns)) {
    out = im.speed_frame;
    im.advance_speed();
    return true;
  }
  const Impl::Other& o = im.window[im.win_pos++];
  out = SimCanFrame{};
  out.frame.t_ns = o.t_ns;
  out.frame.id = o.id;
  out.frame.len = o.len;
  std::copy_n(o.data.begin(), std::min<std::size_t>(o.len, o.data.size()), out.frame.data.begin());
  out.true_time_s = std::numeric_limits<double>::quiet_NaN();
  out.is_speed = false;
  return true;
}

}  // namespace ptda::sim
