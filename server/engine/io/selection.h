// Constraint selection: by ids, Botsch–Sorkine .sel/.def files, or geometric selectors.
#pragma once

#include "engine/mesh/mesh.h"

#include <Eigen/Core>

#include <string>
#include <string_view>
#include <vector>

namespace hdeform {

// .sel: two '#' header lines, then one label per vertex (0 fixed, 1 free, 2 handle).
// Throws InvalidInput "NAME:LINE: problem" (bad label, wrong count vs num_vertices).
std::vector<int> parse_sel(std::string_view content, int num_vertices,
                           const std::string& name = "<sel>");
// .def: after a '#' line, a 4×4 row-major homogeneous matrix. Throws InvalidInput.
Eigen::Matrix4d parse_def(std::string_view content, const std::string& name = "<def>");

// Vertex ids (ascending) whose label equals `label`.
std::vector<int> select_label(const std::vector<int>& labels, int label);
// Vertices inside the closed axis-aligned box [lo, hi].
std::vector<int> select_box(const Vertices& V, const Eigen::Vector3d& lo,
                            const Eigen::Vector3d& hi);
// Vertices with |x − center| ≤ radius.
std::vector<int> select_sphere(const Vertices& V, const Eigen::Vector3d& center, double radius);
// Vertices with dot(normal, x) ≥ offset.
std::vector<int> select_half_space(const Vertices& V, const Eigen::Vector3d& normal,
                                   double offset);

// Sorted union without duplicates.
std::vector<int> unite(std::vector<int> a, const std::vector<int>& b);

}  // namespace hdeform
