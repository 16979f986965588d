// CAN bus as the robot controller produces it: speed frames from a free-running clock (not locked to
// the ADC), a transport delay and jitter on the log timestamps, and optional unrelated traffic.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "ptda/common/time.hpp"
#include "ptda/sim/random.hpp"
#include "ptda/sim/simulator.hpp"
#include "sim_internal.hpp"

namespace ptda::sim {
namespace {

// candump logs carry microseconds; rounding here keeps in-memory frames equal to what is read back.
std::int64_t round_to_us(std::int64_t t_ns) {
  return (t_ns + 500) / 1000 * 1000;
}

}  // namespace

std::vector<SimCanFrame> generate_can(const Scenario& s, const MotionProfile& m, std::uint64_t seed) {
  const CanSpec& c = s.can;
  config::SpeedFrameSpec spec = c.speed_frame;
  spec.period_s = c.period_s;
  const std::int64_t start_ns = seconds_to_ns(s.start_time_s);
  const double period_true_s = c.period_s * (1.0 + c.clock_drift_ppm * 1e-6);
  std::vector<SimCanFrame> out;
  out.reserve(static_cast<std::size_t>(m.duration_s / period_true_s) + 2);

  Rng rng(seed, kStreamCan);
  for (std::uint64_t k = 0;; ++k) {
    const double t = c.clock_offset_s + static_cast<double>(k) * period_true_s;
    if (t > m.duration_s) break;
    const MotionState st = motion_at(m, t);
    const double jitter = c.jitter_s * rng.uniform();
    const std::int64_t t_ns = round_to_us(start_ns + seconds_to_ns(t + c.delay_s + jitter));
    SimCanFrame f;
    f.frame = config::encode_speed(spec, t_ns, st.speed_rad_s, st.angle_rad);
    f.true_time_s = t;
    f.is_speed = true;
    out.push_back(f);
  }

  if (c.other_frames_per_s > 0) {
    // A few typical neighbours: CANopen SYNC (no data), a PDO with 8 bytes, a heartbeat.
    struct Other {
      std::uint32_t id;
      std::uint8_t len;
    };
    constexpr std::array<Other, 3> kOthers{{{0x080, 0}, {0x201, 8}, {0x701, 1}}};
    Rng orng(seed, kStreamOtherFrames);
    const auto count = static_cast<std::uint64_t>(std::floor(c.other_frames_per_s * m.duration_s));
    for (std::uint64_t i = 0; i < count; ++i) {
      const double t = orng.uniform() * m.duration_s;
      const Other& o = kOthers[static_cast<std::size_t>(i % kOthers.size())];
      if (o.id == spec.id && !spec.extended) continue;  // never fake a speed frame
      SimCanFrame f;
      f.frame.t_ns = round_to_us(start_ns + seconds_to_ns(t));
      f.frame.id = o.id;
      f.frame.len = o.len;
      for (std::uint8_t b = 0; b < o.len; ++b)
        f.frame.data[b] = static_cast<std::uint8_t>(orng.next_u64() & 0xFFU);
      if (o.id == 0x701) f.frame.data[0] = 0x05;  // NMT state "operational"
      f.true_time_s = std::numeric_limits<double>::quiet_NaN();
      f.is_speed = false;
      out.push_back(f);
    }
    std::stable_sort(out.begin(), out.end(),
                     [](const SimCanFrame& a, const SimCanFrame& b) { return a.frame.t_ns < b.frame.t_ns; });
  }
  return out;
}

}  // namespace ptda::sim
