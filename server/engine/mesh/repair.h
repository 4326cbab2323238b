// Opt-in mesh repair: turns the common defects of exported meshes into the 2-manifold
// triangle mesh SPEC.md requires. Blender and scanner exports often carry faces written with
// their own copies of shared vertices (every face separate, or split at UV/normal seams),
// slivers of zero area, the same face twice, bowties (two surface sheets touching at one
// vertex) and stray vertices; validate_mesh refuses all but the last. repair_mesh fixes them
// by pure geometry, in this order:
//   1. merge coincident vertices: each vertex joins the earliest surviving vertex at the same
//      position (merge_tolerance = 0: equal coordinates, +0 and −0 alike; > 0: within that
//      distance of the survivor, never through a chain of near ones).
//   2. drop degenerate triangles (a corner repeated after merging, or area ≤ kZeroAreaScale ·
//      (bbox diagonal)², validate_mesh's threshold) and duplicate triangles (the same three
//      vertices as an earlier triangle, in any order or orientation; the first is kept).
//   3. fans: around each merged vertex, its triangles' corners are grouped into fans, joined
//      across an edge that is manifold after merging (two triangles, opposite directions) or
//      that the triangles already shared before merging. Each fan becomes one vertex: the
//      earliest input vertex among the fan's own corners that no earlier fan took and that
//      has exactly the merged position; failing that (a bowtie: one input vertex, k > 1 fans;
//      or, with a tolerance, a fan whose own vertices were only near), a new copy at the
//      merged position, appended after the other vertices. So merging sticks where it
//      connects the surface manifoldly (a seam closes), while sheets that merely touch, at a
//      vertex or along an edge, keep their own vertices.
//   4. drop vertices no triangle uses and renumber: surviving vertices keep their relative
//      order, then the copies of step 3 in the order they were made.
// Units: no position is computed: each output row is an input row, bit for bit (a tolerance
// merge puts a vertex on its survivor). The tolerance is relative to the input's bounding-box
// diagonal, so it means the same at any scale.
//
// Not repaired (validate_mesh still refuses them, with its own message): non-manifold edges
// (more than two triangles on one edge) and inconsistently oriented edges of the input. Their
// triangles stay joined at both endpoints (step 3), so no split cuts such an edge apart.
//
// Preconditions: indices in range and finite coordinates; otherwise validate_mesh's own
// InvalidInput is thrown (repair does not fix these: no position is invented). A negative or
// non-finite merge_tolerance is InvalidInput too.
//
// Identity: a mesh that validate_mesh accepts, with no unreferenced vertex and no seam
// (coincident vertices whose merge joins fans across an edge), comes back identical: same V
// bits, same F, identity maps, report.changed() false. That includes every repaired mesh:
// repairing twice changes nothing (a split's copies sit on their original but in other fans,
// so step 3 gives them back their own ids; the bounding box can only shrink, so the area
// threshold too).
//
// Cost: O(n + m) expected time and memory (hash maps; tolerance merging compares a vertex with
// the survivors of the 27 grid cells around it, a few per cell since survivors are more than the
// tolerance apart; edges grouped by counting sort). No recursion.
#pragma once

#include "engine/mesh/mesh.h"

#include <string>
#include <vector>

namespace hdeform {

struct RepairOptions {
  // Vertices closer than merge_tolerance · (bbox diagonal) are merged (distance ≤ it);
  // 0 merges only vertices with equal coordinates.
  double merge_tolerance = 0;
};

struct RepairReport {
  int merged_vertices = 0;        // input vertices merged into a coincident one (mapped to it)
  int degenerate_triangles = 0;   // dropped: repeated corner after merging, or zero area
  int duplicate_triangles = 0;    // dropped: same three vertices as an earlier triangle
  int unreferenced_vertices = 0;  // dropped: no remaining triangle uses them (nor a merged twin)
  int split_vertices = 0;         // non-manifold input vertices that needed copies (bowties)
  int added_vertices = 0;         // the copies appended for them (one per extra fan)
  // One human-readable line per kind that changed, with its count and the first few input
  // ids, e.g. "merged 12 duplicate vertices into a coincident one (same position) (first:
  // 5→0, 9→1, …)".
  std::vector<std::string> lines;
  bool changed() const;
};

struct RepairResult {
  TriMesh mesh;  // the repaired mesh
  // Repaired vertex → the input vertex it came from (its row of V, bit for bit): the map back
  // to the user's ids. A split's copies map to the split vertex.
  std::vector<int> to_input;
  // Input vertex → repaired vertex: −1 when dropped (unreferenced); a vertex that kept its id
  // maps to itself renumbered (a split vertex: the fan it kept, its earliest); a merged one to
  // the vertex its earliest remaining corner went to (none left: its merged vertex's first fan).
  std::vector<int> from_input;
  // Repaired triangle → input triangle (ascending). Corners keep their order.
  std::vector<int> kept_triangles;
  RepairReport report;
};

RepairResult repair_mesh(const TriMesh& input, const RepairOptions& options = {});

}  // namespace hdeform
