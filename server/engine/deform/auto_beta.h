// Automatic β (beyond the thesis, its "future work"): sample β, score each result by its
// artifact measures against its global cost, pick the smallest β close to the best score.
#pragma once

#include "engine/deform/deformer.h"

#include <functional>
#include <span>
#include <vector>

namespace hdeform {

struct AutoBetaParams {
  // Sampled β values (in `units`), ascending, roughly geometric where β acts most.
  std::vector<double> grid{0.0, 0.01, 0.025, 0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.4, 0.5, 0.75};
  BetaUnits units = BetaUnits::area;
  double global_weight = 2.0;  // λ
  double tolerance = 0.1;      // τ, in the cost's log units (≈ 10 % of the best artifact level)
  // Polled before each sample; true → throws Cancelled (a client left, the server stops).
  std::function<bool()> cancelled;
};

struct AutoBetaSample {
  double beta;
  Measures measures;
  double cost;
};

struct AutoBetaResult {
  Beta beta;                           // the pick, in the params' units
  std::vector<AutoBetaSample> samples;
};

// cost(β) = artifacts(β) + λ · global(β), with
//   artifacts = mean(ln max e_iso, ln max e_conf, ln max e_f²) + ln(1 + flips)
//   global    = ½ (ln E(β)/E(0) + ln E_iso^N(β)/E_iso^N(0))
// and the pick is the smallest sampled β with cost(β) ≤ min cost + τ: where β removes
// spikes the artifact terms fall by orders of magnitude; where it has nothing to remove
// they stay flat or rise while the global term rises, and β = 0 wins.
// Samples are solved with update_transient: the set's shared cache is left as it was.
AutoBetaResult select_beta(const ConstraintSet& cs, std::span<const HandleTransform> transforms,
                           const AutoBetaParams& params = {});

}  // namespace hdeform
