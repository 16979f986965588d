// Slow healthy drift (sim/include/ptda/sim/drift.hpp): closed forms of load, warm-up and pauses.
#include "ptda/sim/drift.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace ptda::sim {

DriftModel::DriftModel(const DriftSpec& spec, const std::vector<double>& pause_start_s) : spec_(spec) {
  if (!spec_.warmup_on()) return;
  // Walk through the pauses once, carrying the coldness from segment to segment.
  start_s_.push_back(0.0);
  c0_.push_back(std::clamp(spec_.initial_coldness, 0.0, 1.0));
  paused_.push_back(false);
  const double pause_s = spec_.pauses_on() ? spec_.pause_s : 0.0;
  for (double p0 : pause_start_s) {
    if (pause_s <= 0.0) break;
    // End of the working segment before the pause, then the pause itself.
    const double c_work = c0_.back() * std::exp(-(p0 - start_s_.back()) / spec_.warmup_tau_s);
    start_s_.push_back(p0);
    c0_.push_back(c_work);
    paused_.push_back(true);
    const double c_pause = spec_.cooldown_tau_s > 0.0
                               ? 1.0 - (1.0 - c_work) * std::exp(-pause_s / spec_.cooldown_tau_s)
                               : c_work;
    start_s_.push_back(p0 + pause_s);
    c0_.push_back(c_pause);
    paused_.push_back(false);
  }
}

double DriftModel::coldness_at(double t_s) const noexcept {
  if (start_s_.empty()) return 0.0;
  // Last segment starting at or before t_s.
  auto it = std::upper_bound(start_s_.begin(), start_s_.end(), t_s);
  const std::size_t j = it == start_s_.begin() ? 0 : static_cast<std::size_t>(it - start_s_.begin()) - 1;
  const double dt = std::max(0.0, t_s - start_s_[j]);
  if (!paused_[j]) return c0_[j] * std::exp(-dt / spec_.warmup_tau_s);
  if (spec_.cooldown_tau_s <= 0.0) return c0_[j];
  return 1.0 - (1.0 - c0_[j]) * std::exp(-dt / spec_.cooldown_tau_s);
}

DriftFactors DriftModel::at(double t_s) const noexcept {
  DriftFactors f;
  if (spec_.load_on()) {
    f.load = std::sin(2.0 * std::numbers::pi * (t_s + spec_.time_offset_s) / spec_.load_period_s +
                      spec_.load_phase_rad);
    f.mesh_gain = 1.0 + spec_.mesh_amplitude_rel * f.load;
    f.resonance_factor = 1.0 + spec_.resonance_shift_rel * f.load;
  }
  if (spec_.warmup_on()) {
    f.coldness = coldness_at(t_s);
    f.mesh_gain *= 1.0 + spec_.cold_amplitude_rel * f.coldness;
    f.noise_gain = 1.0 + spec_.cold_noise_rel * f.coldness;
  }
  return f;
}

}  // namespace ptda::sim
