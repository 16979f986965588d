// Gearbox kinematics (paper eqs. 1, 3, 4) and the joint motion: Craig's linear segments with parabolic
// blends through via points (paper section 2.1), repeated as job cycles with dwell and start jitter.
#include <algorithm>
#include <cmath>
#include <numbers>
#include <sstream>
#include <string>

#include "ptda/common/error.hpp"
#include "ptda/sim/random.hpp"
#include "ptda/sim/simulator.hpp"
#include "sim_internal.hpp"

namespace ptda::sim {

double reduction_ratio(const GearboxSpec& g) noexcept {
  if (g.z_in == 0) return 0.0;
  const double z_in = g.z_in;
  if (g.kind == GearboxKind::kParallel) return static_cast<double>(g.z_spur) / z_in;
  return 1.0 + static_cast<double>(g.z_spur) / z_in * static_cast<double>(g.z_pin);  // eq. 1
}

double gmf_hz(const GearboxSpec& g, double output_speed_rad_s) noexcept {
  const double f_in_hz = reduction_ratio(g) * std::fabs(output_speed_rad_s) / (2.0 * std::numbers::pi);
  return static_cast<double>(g.z_in) * f_in_hz;  // eq. 3
}

double dmf_hz(const GearboxSpec& g, double output_speed_rad_s) noexcept {
  if (g.kind != GearboxKind::kCycloidal) return 0.0;
  return static_cast<double>(g.z_pin) * std::fabs(output_speed_rad_s) / (2.0 * std::numbers::pi);  // eq. 4
}

dsp::GearboxInfo to_gearbox_info(const GearboxSpec& g) noexcept {
  dsp::GearboxInfo info;
  info.kind = g.kind == GearboxKind::kCycloidal ? dsp::GearboxInfo::Kind::kCycloidal
                                                : dsp::GearboxInfo::Kind::kParallel;
  info.z_in = g.z_in;
  info.z_spur = g.z_spur;
  info.z_pin = g.kind == GearboxKind::kCycloidal ? g.z_pin : 0;
  info.ratio = reduction_ratio(g);
  return info;
}

double fault_severity(const FaultSpec& f, std::uint32_t cycle) noexcept {
  if (cycle < f.onset_cycle) return 0.0;
  if (f.ramp_cycles == 0) return f.severity;
  const double grown = static_cast<double>(cycle - f.onset_cycle + 1) / static_cast<double>(f.ramp_cycles);
  return f.severity * std::min(1.0, grown);
}

namespace {

std::string fmt(double v) {
  std::ostringstream ss;
  ss.precision(6);
  ss << v;
  return ss.str();
}

// Per-segment via-to-via durations from whichever timing the scenario gave. For speeds, the first and
// last segments need v/(2a) extra because they start/end at rest (Craig's end-segment formulas).
std::vector<double> segment_durations(const MotionSpec& m) {
  const std::size_t n = m.via_points_rad.size() - 1;
  if (!m.segment_durations_s.empty()) return m.segment_durations_s;
  std::vector<double> td(n);
  const double a = m.accel_rad_s2;
  for (std::size_t j = 0; j < n; ++j) {
    const double v = m.segment_speeds_rad_s.empty() ? m.max_speed_rad_s : m.segment_speeds_rad_s[j];
    const double d = std::fabs(m.via_points_rad[j + 1] - m.via_points_rad[j]);
    if (d == 0.0) {
      throw Error("segment " + std::to_string(j) +
                  " has no travel (equal via points); use segment_durations_s "
                  "to hold still");
    }
    double t = d / v;
    if (n == 1) {
      t += v / a;
    } else if (j == 0 || j == n - 1) {
      t += v / (2.0 * a);
    }
    td[j] = t;
  }
  return td;
}

// Pieces following a measured speed trace over [0, duration_s] (see build_motion()).
void measured_pieces(const MotionSpec& m, const std::string& where, MotionProfile& prof) {
  const std::vector<double>& ts = m.measured_t_s;
  const std::vector<double>& ws = m.measured_speed_rad_s;
  if (ts.size() != ws.size() || ts.size() < 2) {
    throw Error(where + ": measured motion needs >= 2 speed points with one time each (got " +
                std::to_string(ts.size()) + " times, " + std::to_string(ws.size()) + " speeds)");
  }
  for (std::size_t i = 0; i < ts.size(); ++i) {
    if (!std::isfinite(ts[i]) || !std::isfinite(ws[i]))
      throw Error(where + ": measured motion point " + std::to_string(i) + " is not finite");
    if (i > 0 && ts[i] <= ts[i - 1])
      throw Error(where + ": measured motion times must ascend (point " + std::to_string(i) + " at " +
                  fmt(ts[i]) + " s after " + fmt(ts[i - 1]) + " s)");
  }
  if (!(m.duration_s > 0.0)) throw Error(where + ": measured motion needs duration_s > 0");
  // The trace restricted to [0, duration_s]: held before the first and after the last point,
  // interpolated at the ends.
  auto speed_at = [&](double t) {
    if (t <= ts.front()) return ws.front();
    if (t >= ts.back()) return ws.back();
    const std::size_t j = static_cast<std::size_t>(std::upper_bound(ts.begin(), ts.end(), t) - ts.begin());
    const double u = (t - ts[j - 1]) / (ts[j] - ts[j - 1]);
    return ws[j - 1] + u * (ws[j] - ws[j - 1]);
  };
  std::vector<double> pt{0.0}, pw{speed_at(0.0)};
  for (std::size_t i = 0; i < ts.size(); ++i) {
    if (ts[i] > 0.0 && ts[i] < m.duration_s) {
      pt.push_back(ts[i]);
      pw.push_back(ws[i]);
    }
  }
  pt.push_back(m.duration_s);
  pw.push_back(speed_at(m.duration_s));
  const double deadband = measured_motion_deadband(ts, ws);
  const std::vector<double>& starts = m.measured_cycle_start_s;
  double angle = 0.0;
  for (std::size_t i = 0; i + 1 < pt.size(); ++i) {
    const double dt = pt[i + 1] - pt[i];
    if (dt <= 0.0) continue;
    const double a = (pw[i + 1] - pw[i]) / dt;
    MotionPiece p;
    p.t0_s = pt[i];
    p.t1_s = pt[i + 1];
    p.angle0_rad = angle;
    if (std::fabs(a) < deadband) {
      p.speed0_rad_s = 0.5 * (pw[i] + pw[i + 1]);  // same angle advance as the linear interpolation
      p.accel_rad_s2 = 0.0;
    } else {
      p.speed0_rad_s = pw[i];
      p.accel_rad_s2 = a;
    }
    const auto c =
        static_cast<std::size_t>(std::upper_bound(starts.begin(), starts.end(), p.t0_s) - starts.begin());
    p.cycle = static_cast<std::uint32_t>(c == 0 ? 0 : c - 1);
    prof.pieces.push_back(p);
    angle += p.speed0_rad_s * dt + 0.5 * p.accel_rad_s2 * dt * dt;
  }
  prof.cycle_start_s = starts.empty() ? std::vector<double>{0.0} : starts;
  prof.cycles = static_cast<std::uint32_t>(std::max<std::size_t>(1, starts.size()));
  prof.duration_s = m.duration_s;
}

}  // namespace

double measured_motion_deadband(const std::vector<double>& t_s, const std::vector<double>& speed_rad_s) {
  std::vector<double> acc;
  double top = 0.0;
  for (std::size_t i = 0; i < t_s.size() && i < speed_rad_s.size(); ++i) {
    top = std::max(top, std::fabs(speed_rad_s[i]));
    if (i > 0 && t_s[i] > t_s[i - 1])
      acc.push_back(std::fabs(speed_rad_s[i] - speed_rad_s[i - 1]) / (t_s[i] - t_s[i - 1]));
  }
  double p99 = 0.0;
  if (!acc.empty()) {
    const auto k = static_cast<std::size_t>(0.99 * static_cast<double>(acc.size() - 1));
    std::nth_element(acc.begin(), acc.begin() + static_cast<std::ptrdiff_t>(k), acc.end());
    p99 = acc[k];
  }
  return std::max(0.2 * p99, 0.02 * top);
}

CyclePlan plan_cycle(const MotionSpec& m) {
  const auto& via = m.via_points_rad;
  if (via.size() < 2) throw Error("needs at least 2 via points");
  const std::size_t n = via.size() - 1;
  const double a = m.accel_rad_s2;
  const std::vector<double> td = segment_durations(m);
  std::vector<double> d(n);
  for (std::size_t j = 0; j < n; ++j) d[j] = via[j + 1] - via[j];

  // Segment speeds v[j] and blend durations tau[k] at via point k (k = 0..n).
  std::vector<double> v(n, 0.0);
  std::vector<double> tau(n + 1, 0.0);
  auto too_short = [&](std::size_t j, const std::string& why) {
    return Error("segment " + std::to_string(j) + " (via " + std::to_string(j) + " -> " +
                 std::to_string(j + 1) + ", " + fmt(d[j]) + " rad in " + fmt(td[j]) +
                 " s) is too short for accel_rad_s2 = " + fmt(a) + ": " + why);
  };
  if (n == 1) {
    // Single segment, rest to rest: symmetric trapezoid.
    const double disc = a * a * td[0] * td[0] - 4.0 * a * std::fabs(d[0]);
    if (disc < -1e-9 * a * a * td[0] * td[0]) throw too_short(0, "the blends would overlap");
    const double tb = td[0] / 2.0 - std::sqrt(std::max(0.0, disc)) / (2.0 * a);
    tau[0] = tb;
    tau[1] = tb;
    v[0] = d[0] == 0.0 ? 0.0 : d[0] / (td[0] - tb);
  } else {
    auto end_blend = [&](std::size_t j) {
      if (d[j] == 0.0) return 0.0;
      const double disc = td[j] * td[j] - 2.0 * std::fabs(d[j]) / a;
      if (disc < -1e-12 * td[j] * td[j]) throw too_short(j, "it cannot start or stop in time");
      return td[j] - std::sqrt(std::max(0.0, disc));
    };
    tau[0] = end_blend(0);
    v[0] = d[0] / (td[0] - tau[0] / 2.0);
    tau[n] = end_blend(n - 1);
    v[n - 1] = d[n - 1] / (td[n - 1] - tau[n] / 2.0);
    for (std::size_t j = 1; j + 1 < n; ++j) v[j] = d[j] / td[j];
    for (std::size_t k = 1; k < n; ++k) tau[k] = std::fabs(v[k] - v[k - 1]) / a;
  }

  // A speed given by the scenario must be reached; Craig's formulas otherwise quietly return a lower one.
  if (m.segment_durations_s.empty()) {
    for (std::size_t j = 0; j < n; ++j) {
      const double want = m.segment_speeds_rad_s.empty() ? m.max_speed_rad_s : m.segment_speeds_rad_s[j];
      if (std::fabs(std::fabs(v[j]) - want) > 1e-9 * want) {
        throw too_short(j, "it cannot reach " + fmt(want) + " rad/s (reaches " + fmt(std::fabs(v[j])) + ")");
      }
    }
  }

  // Linear (cruise) durations between the blends.
  std::vector<double> lin(n);
  for (std::size_t j = 0; j < n; ++j) {
    const double before = (j == 0) ? tau[0] : tau[j] / 2.0;
    const double after = (j == n - 1) ? tau[n] : tau[j + 1] / 2.0;
    lin[j] = td[j] - before - after;
    if (lin[j] < -1e-9) {
      throw too_short(
          j, "the blends overlap by " + fmt(-lin[j]) + " s (lower the speed or raise the acceleration)");
    }
    lin[j] = std::max(0.0, lin[j]);
  }

  CyclePlan plan;
  double t = 0.0;
  double angle = 0.0;
  double speed = 0.0;
  auto push = [&](double dur, double accel) {
    if (dur <= 0.0) return;
    MotionPiece p;
    p.t0_s = t;
    p.t1_s = t + dur;
    p.angle0_rad = angle;
    p.speed0_rad_s = speed;
    p.accel_rad_s2 = accel;
    plan.pieces.push_back(p);
    angle += speed * dur + 0.5 * accel * dur * dur;
    speed += accel * dur;
    t += dur;
  };
  // The blend accelerations are (v_after - v_before) / tau so the speed is exactly continuous; their
  // magnitude is the configured limit up to rounding.
  for (std::size_t j = 0; j < n; ++j) {
    const double v_before = j == 0 ? 0.0 : v[j - 1];
    const double blend = j == 0 ? tau[0] : tau[j];
    if (blend > 0.0) push(blend, (v[j] - v_before) / blend);
    speed = v[j];  // removes rounding left by the blend
    if (lin[j] > 1e-9 && v[j] != 0.0) plan.plateaus.push_back(Plateau{0, t, t + lin[j], v[j]});
    push(lin[j], 0.0);
  }
  if (tau[n] > 0.0) push(tau[n], -v[n - 1] / tau[n]);
  plan.duration_s = t;
  return plan;
}

MotionProfile build_motion_plan(const Scenario& s, std::uint64_t seed) {
  const MotionSpec& m = s.motion;
  const std::string where = s.source.empty() ? std::string("scenario") : s.source;
  MotionProfile prof;
  prof.fs_hz = s.sensor.fs_hz;
  prof.cycles = m.cycles;
  if (m.cycles == 0 && m.kind != MotionKind::kMeasured) throw Error(where + ": [motion] cycles must be >= 1");

  if (m.kind == MotionKind::kMeasured) {
    measured_pieces(m, where, prof);
  } else if (m.kind == MotionKind::kConstant) {
    const double ratio = reduction_ratio(s.gearbox);
    if (ratio <= 0.0) throw Error(where + ": [gearbox] tooth counts give no reduction ratio");
    const double w_out = 2.0 * std::numbers::pi * m.shaft_speed_hz / ratio;
    const double block_s = m.duration_s / m.cycles;
    for (std::uint32_t c = 0; c < m.cycles; ++c) {
      const double t0 = block_s * c;
      const double t1 = c + 1 == m.cycles ? m.duration_s : block_s * (c + 1);
      prof.pieces.push_back(MotionPiece{t0, t1, w_out * t0, w_out, 0.0, c});
      prof.plateaus.push_back(Plateau{c, t0, t1, w_out});
      prof.cycle_start_s.push_back(t0);
    }
    prof.duration_s = m.duration_s;
  } else {
    CyclePlan plan;
    try {
      plan = plan_cycle(m);
    } catch (const Error& e) {
      throw Error(where + ": [motion] " + e.what());
    }
    // The plan is what a streamed simulation keeps for its whole length: reserved exactly (at most a
    // pause, a jitter wait and a dwell besides the cycle's pieces), not grown by doubling.
    prof.pieces.reserve(static_cast<std::size_t>(m.cycles) * (plan.pieces.size() + 3) + 1);
    prof.plateaus.reserve(static_cast<std::size_t>(m.cycles) * plan.plateaus.size());
    prof.cycle_start_s.reserve(m.cycles);
    const LazyMotionPlan lp{m, s.drift, std::move(plan), seed};
    CycleWalker walker(lp);
    PlanCycle cyc;
    double pause_start = -1.0;
    while (walker.next(cyc, &pause_start)) {
      if (pause_start >= 0.0) prof.pause_start_s.push_back(pause_start);
      prof.cycle_start_s.push_back(cyc.start_s);
      prof.pieces.insert(prof.pieces.end(), cyc.pieces.begin(), cyc.pieces.end());
      prof.plateaus.insert(prof.plateaus.end(), cyc.plateaus.begin(), cyc.plateaus.end());
    }
    const double t = walker.t_s();
    prof.duration_s = t;
  }
  if (prof.duration_s <= 0.0 || prof.pieces.empty()) throw Error(where + ": the motion has zero duration");
  const double samples = std::round(prof.duration_s * prof.fs_hz);
  if (samples > 2.0e9) throw Error(where + ": the recording would exceed 2e9 samples");

  return prof;
}

CycleWalker::CycleWalker(const LazyMotionPlan& lp)
    : lp_(&lp), rng_(lp.seed, kStreamJitter), angle_(lp.motion.via_points_rad.front()) {}

bool CycleWalker::next(PlanCycle& out, double* pause_start_s) {
  const MotionSpec& m = lp_->motion;
  const CyclePlan& plan = lp_->plan;
  if (pause_start_s != nullptr) *pause_start_s = -1.0;
  if (c_ >= m.cycles) return false;
  const std::uint32_t c = c_++;
  out.cycle = c;
  out.pieces.clear();
  out.plateaus.clear();
  auto hold = [&](double dur) {
    if (dur <= 0.0) return;
    out.pieces.push_back(MotionPiece{t_, t_ + dur, angle_, 0.0, 0.0, c});
    t_ += dur;
  };
  if (c == 0) hold(m.lead_in_s);
  // [drift] program pause: the robot stands still before every pause_every_cycles-th cycle.
  if (lp_->drift.pauses_on() && c > 0 && c % lp_->drift.pause_every_cycles == 0) {
    if (pause_start_s != nullptr) *pause_start_s = t_;
    hold(lp_->drift.pause_s);
  }
  hold(m.start_jitter_s * rng_.uniform());
  const double t_cycle = t_;
  const double a_cycle = angle_;
  out.start_s = t_cycle;
  for (const MotionPiece& p : plan.pieces) {
    out.pieces.push_back(MotionPiece{t_cycle + p.t0_s, t_cycle + p.t1_s, a_cycle + p.angle0_rad,
                                     p.speed0_rad_s, p.accel_rad_s2, c});
  }
  for (const Plateau& p : plan.plateaus) {
    out.plateaus.push_back(Plateau{c, t_cycle + p.t_start_s, t_cycle + p.t_end_s, p.speed_rad_s});
  }
  if (!plan.pieces.empty()) {
    const MotionPiece& last = plan.pieces.back();
    const double dur = last.t1_s - last.t0_s;
    angle_ = a_cycle + last.angle0_rad + last.speed0_rad_s * dur + 0.5 * last.accel_rad_s2 * dur * dur;
  }
  t_ = t_cycle + plan.duration_s;
  hold(m.dwell_s);
  return true;
}

MotionProfile build_motion_lazy(const Scenario& s, std::uint64_t seed) {
  if (s.motion.kind != MotionKind::kLspb) return build_motion_plan(s, seed);
  const MotionSpec& m = s.motion;
  const std::string where = s.source.empty() ? std::string("scenario") : s.source;
  MotionProfile prof;
  prof.fs_hz = s.sensor.fs_hz;
  prof.cycles = m.cycles;
  if (m.cycles == 0) throw Error(where + ": [motion] cycles must be >= 1");
  auto lp = std::make_shared<LazyMotionPlan>();
  try {
    lp->plan = plan_cycle(m);
  } catch (const Error& e) {
    throw Error(where + ": [motion] " + e.what());
  }
  lp->motion = m;
  lp->drift = s.drift;
  lp->seed = seed;
  // One walk for the duration and the pauses (what build_motion_plan stores besides the cycles' parts).
  CycleWalker walker(*lp);
  PlanCycle cyc;
  double pause_start = -1.0;
  bool any_piece = false;
  while (walker.next(cyc, &pause_start)) {
    if (pause_start >= 0.0) prof.pause_start_s.push_back(pause_start);
    any_piece = any_piece || !cyc.pieces.empty();
  }
  prof.duration_s = walker.t_s();
  if (prof.duration_s <= 0.0 || !any_piece) throw Error(where + ": the motion has zero duration");
  const double samples = std::round(prof.duration_s * prof.fs_hz);
  if (samples > 2.0e9) throw Error(where + ": the recording would exceed 2e9 samples");
  prof.lazy = std::move(lp);
  return prof;
}

void for_each_cycle(const MotionProfile& m, const std::function<bool(const PlanCycle&)>& fn) {
  PlanCycle cyc;
  if (m.lazy) {
    CycleWalker walker(*m.lazy);
    while (walker.next(cyc)) {
      if (!fn(cyc)) return;
    }
    return;
  }
  // Stored: the pieces and plateaus of each cycle (the lead-in with cycle 0).
  std::size_t k = 0;
  std::size_t q = 0;
  for (std::uint32_t c = 0; c < m.cycle_start_s.size(); ++c) {
    cyc.cycle = c;
    cyc.start_s = m.cycle_start_s[c];
    cyc.pieces.clear();
    cyc.plateaus.clear();
    for (; k < m.pieces.size() && m.pieces[k].cycle == c; ++k) cyc.pieces.push_back(m.pieces[k]);
    for (; q < m.plateaus.size() && m.plateaus[q].cycle == c; ++q) cyc.plateaus.push_back(m.plateaus[q]);
    if (!fn(cyc)) return;
  }
}

struct PieceCursor::Walk {
  explicit Walk(const LazyMotionPlan& lp) : walker(lp) {}
  CycleWalker walker;
  PlanCycle cycle;
  std::vector<MotionPiece> buf;  // pieces of the cycles walked, from the current one on
  std::size_t pos = 0;
  bool done = false;
  /// Makes buf[pos + 1] available if there is a next piece.
  bool fill_next() {
    while (pos + 1 >= buf.size() && !done) {
      if (pos > 0) {  // drop what has been passed
        buf.erase(buf.begin(), buf.begin() + static_cast<std::ptrdiff_t>(pos));
        pos = 0;
      }
      if (!walker.next(cycle)) {
        done = true;
        break;
      }
      buf.insert(buf.end(), cycle.pieces.begin(), cycle.pieces.end());
    }
    return pos + 1 < buf.size();
  }
};

PieceCursor::PieceCursor(const MotionProfile& m) : m_(&m) {
  if (m.lazy) {
    walk_ = std::make_unique<Walk>(*m.lazy);
    walk_->fill_next();  // the first piece (and the next one when there is one)
  }
}

PieceCursor::~PieceCursor() = default;
PieceCursor::PieceCursor(PieceCursor&&) noexcept = default;
PieceCursor& PieceCursor::operator=(PieceCursor&&) noexcept = default;

const MotionPiece& PieceCursor::current() const noexcept {
  return walk_ ? walk_->buf[walk_->pos] : m_->pieces[k_];
}

bool PieceCursor::has_next() {
  return walk_ ? walk_->fill_next() : k_ + 1 < m_->pieces.size();
}

void PieceCursor::advance() {
  if (walk_) {
    walk_->fill_next();
    ++walk_->pos;
  } else {
    ++k_;
  }
}

MotionState motion_at(const MotionProfile& m, PieceCursor& cursor, double t_s) {
  // As motion_at(m, t): clamped to the plan (it starts at 0 and ends at duration_s), then the first piece
  // ending after t_s, else the last.
  t_s = std::clamp(t_s, 0.0, m.duration_s);
  while (cursor.has_next() && t_s >= cursor.current().t1_s) cursor.advance();
  const MotionPiece& p = cursor.current();
  const double tau = t_s - p.t0_s;
  return MotionState{p.angle0_rad + p.speed0_rad_s * tau + 0.5 * p.accel_rad_s2 * tau * tau,
                     p.speed0_rad_s + p.accel_rad_s2 * tau, p.accel_rad_s2, p.cycle};
}

std::size_t motion_samples(const MotionProfile& m) noexcept {
  return static_cast<std::size_t>(std::round(m.duration_s * m.fs_hz));
}

MotionState MotionSampler::at(std::size_t i) {
  const double t = static_cast<double>(i) / fs_hz_;
  while (pieces_.has_next() && t >= pieces_.current().t1_s) pieces_.advance();
  const MotionPiece& p = pieces_.current();
  const double tau = t - p.t0_s;
  return MotionState{p.angle0_rad + p.speed0_rad_s * tau + 0.5 * p.accel_rad_s2 * tau * tau,
                     p.speed0_rad_s + p.accel_rad_s2 * tau, p.accel_rad_s2, p.cycle};
}

double max_abs_speed_rad_s(const MotionProfile& m) {
  double w_max = 0.0;
  if (!m.speed_rad_s.empty()) {
    for (double w : m.speed_rad_s) w_max = std::max(w_max, std::fabs(w));
    return w_max;
  }
  MotionSampler sampler(m);
  const std::size_t n = motion_samples(m);
  for (std::size_t i = 0; i < n; ++i) w_max = std::max(w_max, std::fabs(sampler.at(i).speed_rad_s));
  return w_max;
}

MotionProfile build_motion(const Scenario& s, std::uint64_t seed) {
  MotionProfile prof = build_motion_plan(s, seed);
  const std::size_t n = motion_samples(prof);
  prof.angle_rad.resize(n);
  prof.speed_rad_s.resize(n);
  prof.accel_rad_s2.resize(n);
  prof.cycle.resize(n);
  MotionSampler sampler(prof);
  for (std::size_t i = 0; i < n; ++i) {
    const MotionState st = sampler.at(i);
    prof.angle_rad[i] = st.angle_rad;
    prof.speed_rad_s[i] = st.speed_rad_s;
    prof.accel_rad_s2[i] = st.accel_rad_s2;
    prof.cycle[i] = st.cycle;
  }
  return prof;
}

MotionState motion_at(const MotionProfile& m, double t_s) noexcept {
  if (m.pieces.empty()) return {};
  t_s = std::clamp(t_s, m.pieces.front().t0_s, m.pieces.back().t1_s);
  auto it = std::upper_bound(m.pieces.begin(), m.pieces.end(), t_s,
                             [](double t, const MotionPiece& p) { return t < p.t1_s; });
  if (it == m.pieces.end()) --it;
  const MotionPiece& p = *it;
  const double tau = t_s - p.t0_s;
  return MotionState{p.angle0_rad + p.speed0_rad_s * tau + 0.5 * p.accel_rad_s2 * tau * tau,
                     p.speed0_rad_s + p.accel_rad_s2 * tau, p.accel_rad_s2, p.cycle};
}

}  // namespace ptda::sim
