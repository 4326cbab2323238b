#include "engine/deform/auto_beta.h"

#include <cmath>
#include <limits>

namespace hdeform {

namespace {
double safe_log(double x) { return std::log(std::max(x, 1e-300)); }
}  // namespace

AutoBetaResult select_beta(const ConstraintSet& cs, std::span<const HandleTransform> transforms,
                           const AutoBetaParams& params) {
  if (params.grid.empty()) throw InvalidInput("automatic beta: empty sample grid");
  AutoBetaResult result;
  const UpdateOptions cheap{.energies = false, .normals = false};
  for (double beta : params.grid) {
    if (params.cancelled && params.cancelled())
      throw Cancelled("automatic beta: cancelled");
    // Transient: the samples never enter (or leave) the set's shared factorization cache.
    const Frame f = cs.update_transient(transforms, {beta, params.units}, cheap);
    result.samples.push_back({beta, f.measures, 0.0});
  }
  const Measures& m0 = result.samples.front().measures;
  double best = std::numeric_limits<double>::infinity();
  for (AutoBetaSample& s : result.samples) {
    const Measures& m = s.measures;
    const double artifacts =
        (safe_log(m.max_e_iso) + safe_log(m.max_e_conf) + safe_log(m.max_ef2)) / 3.0 +
        std::log1p(m.flips);
    const double global =
        0.5 * (safe_log(m.E / m0.E) + safe_log(m.E_iso_N / m0.E_iso_N));
    s.cost = artifacts + params.global_weight * (std::isfinite(global) ? global : 0.0);
    best = std::min(best, s.cost);
  }
  result.beta = {result.samples.back().beta, params.units};
  for (const AutoBetaSample& s : result.samples)
    if (s.cost <= best + params.tolerance) {
      result.beta.value = s.beta;
      break;
    }
  return result;
}

}  // namespace hdeform
