// Per-triangle β fields for local regularization (ConstraintSet::update_local).
#pragma once

#include <Eigen/Core>

#include <vector>

namespace hdeform {

class PreparedMesh;

// β_l = beta · max(0, 1 − d_l / radius)², d_l the distance from triangle l's centroid to
// the nearest vertex of `around` (e.g. the handle vertices): strong near them, exactly 0
// beyond `radius` (model units). O(m + |around|) with a grid of cell size `radius`.
Eigen::VectorXd falloff_beta(const PreparedMesh& mesh, const std::vector<int>& around,
                             double beta, double radius);

// β_l = beta on every triangle with a vertex in `region`, 0 elsewhere.
Eigen::VectorXd region_beta(const PreparedMesh& mesh, const std::vector<int>& region,
                            double beta);

}  // namespace hdeform
