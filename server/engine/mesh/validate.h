// Mesh validation with precise errors (which element, how many): SPEC.md requires a
// 2-manifold triangle mesh with finite coordinates and no degenerate triangles.
#pragma once

#include "engine/mesh/mesh.h"

#include <string>
#include <vector>

namespace hdeform {

// A triangle whose area is ≤ kZeroAreaScale · (bbox diagonal)² counts as zero-area (relative to
// the model's size, so independent of its units). Shared with repair_mesh, which drops exactly
// the triangles validate_mesh refuses as zero-area.
inline constexpr double kZeroAreaScale = 1e-14;

// The mesh's edge graph as the lower triangle of a symmetric n × n pattern, by columns:
// column v lists the vertices w > v that share an edge with v, ascending, in
// rows[start[v] .. start[v + 1]). It is L's pattern without its diagonal, plus the edges
// whose cotangent weights cancel (L drops those zeros): what β = 0's order orders
// (vertex_ordering.h), known before L exists.
struct EdgePattern {
  std::vector<int> start;  // n + 1 offsets into rows
  std::vector<int> rows;
};

struct ValidationResult {
  std::vector<int> unreferenced;      // vertex ids no triangle uses (kept, pinned at rest)
  std::vector<std::string> warnings;  // human-readable, one per issue
  EdgePattern edges;                  // read off the edge check's sorted buckets: no extra pass
};

// Throws InvalidInput naming the first problem class found and how many elements it
// affects, with the first offending ids: empty mesh, index out of range, non-finite
// coordinates, zero-area triangles (area ≤ kZeroAreaScale · bbox diagonal²), non-manifold edges
// (> 2 triangles or inconsistent orientation), non-manifold vertices (more than one fan).
// Unreferenced vertices are not an error: they are reported and kept, so ids stay stable.
ValidationResult validate_mesh(const TriMesh& mesh);

}  // namespace hdeform
