// Triangle mesh as the engine sees it: rest positions X (n×3) and triangles (m×3).
#pragma once

#include <Eigen/Core>

#include <stdexcept>
#include <string>

namespace hdeform {

// One row per vertex, in the input file's vertex order (ids stay valid across I/O).
using Vertices = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
// One row per triangle (i, j, k), counter-clockwise seen from outside.
using Triangles = Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>;
// The guidance field g (3m × 3, block l = rows 3l…3l+2 = g_l), row-major: each g_l is nine
// contiguous doubles, and the right-hand side (GᵀW_β)_F · g reads each of g's rows once.
using GuidanceField = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
// n × 3 row-major: the drag refinement's residual and correction (Factorization::solve3_rows).
using Rows3 = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

struct TriMesh {
  Vertices V;
  Triangles F;
  int num_vertices() const { return static_cast<int>(V.rows()); }
  int num_triangles() const { return static_cast<int>(F.rows()); }
};

// Input the engine refuses: the message names the element and the count.
class InvalidInput : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

// Long work stopped by its cancellation hook (the client left, its deadline passed, or the
// server is shutting down). Not an input error: the service maps it to CANCELLED.
class Cancelled : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace hdeform
