// Least-squares fits of the calibration, with Eigen.
#include "ptda/gap/fit.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <map>

namespace ptda::gap {

SpeedLawFit fit_speed_law(const std::vector<LevelObservation>& obs) {
  SpeedLawFit out;
  std::vector<const LevelObservation*> use;
  std::map<int, Eigen::Index> order_col;
  bool has_fwd = false, has_rev = false;
  for (const LevelObservation& o : obs) {
    if (!std::isfinite(o.speed_rad_s) || o.speed_rad_s == 0.0 || !std::isfinite(o.diff_db)) continue;
    use.push_back(&o);
    order_col.emplace(o.order, 0);
    (o.speed_rad_s > 0.0 ? has_fwd : has_rev) = true;
  }
  if (use.size() < 3) return out;
  Eigen::Index cols = 0;
  for (auto& [k, c] : order_col) c = cols++;
  // One level per direction beyond the first: the per-order columns already carry a common level.
  const bool dir_col = has_fwd && has_rev;
  const Eigen::Index n_nuisance = cols + (dir_col ? 1 : 0);
  const auto n = static_cast<Eigen::Index>(use.size());
  Eigen::MatrixXd nuisance = Eigen::MatrixXd::Zero(n, n_nuisance);
  Eigen::VectorXd x(n), d(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const LevelObservation& o = *use[static_cast<std::size_t>(i)];
    nuisance(i, order_col.at(o.order)) = 1.0;
    if (dir_col && o.speed_rad_s < 0.0) nuisance(i, cols) = 1.0;
    x(i) = 20.0 * std::log10(std::fabs(o.speed_rad_s));
    d(i) = o.diff_db;
  }
  const Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> cod(nuisance);
  const Eigen::VectorXd x_res = x - nuisance * cod.solve(x);
  const Eigen::VectorXd d_res = d - nuisance * cod.solve(d);
  out.speed_ss_db2 = x_res.squaredNorm();
  // Speeds within one direction that differ by less than about 0.01 dB carry no slope: treat the
  // remainder as rounding.
  const double floor_db2 = 1e-4 * static_cast<double>(n);
  if (!(out.speed_ss_db2 > floor_db2)) {
    out.speed_ss_db2 = 0.0;
    return out;
  }
  out.identifiable = true;
  out.exponent_step = x_res.dot(d_res) / out.speed_ss_db2;
  return out;
}

}  // namespace ptda::gap
