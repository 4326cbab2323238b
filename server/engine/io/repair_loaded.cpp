// A file's mesh repaired with its layout kept consistent. See repair_loaded.h.

#include "engine/io/repair_loaded.h"

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

namespace hdeform {

RepairReport repair_loaded_mesh(LoadedMesh& m, const RepairOptions& options) {
  RepairResult r = repair_mesh(m.mesh, options);
  if (!r.report.changed()) return std::move(r.report);

  const int old_n = m.mesh.num_vertices();
  const Eigen::Index old_m = m.mesh.F.rows();
  const bool old_identity = m.input_to_engine.empty() || m.identity_layout();
  // The input triangles in input ids, row for row with the old engine triangles.
  const bool rows_match = m.input_triangles.rows() == old_m;
  // The layout survives when the repair is a function of the input vertices: none dropped,
  // and every repaired corner is from_input of its input corner (a split, or a fan given to
  // another coincident vertex, breaks that).
  bool keep_layout = r.report.unreferenced_vertices == 0 && (rows_match || old_identity);
  for (size_t t = 0; keep_layout && t < r.kept_triangles.size(); ++t)
    for (int k = 0; k < 3; ++k)
      if (r.mesh.F(static_cast<Eigen::Index>(t), k) !=
          r.from_input[static_cast<size_t>(m.mesh.F(r.kept_triangles[t], k))])
        keep_layout = false;

  if (keep_layout) {
    if (m.input_to_engine.empty()) {
      m.input_to_engine.resize(static_cast<size_t>(old_n));
      for (int i = 0; i < old_n; ++i) m.input_to_engine[static_cast<size_t>(i)] = i;
    }
    for (int& e : m.input_to_engine) e = r.from_input[static_cast<size_t>(e)];
    const Triangles& base = rows_match ? m.input_triangles : m.mesh.F;
    Triangles kept(static_cast<Eigen::Index>(r.kept_triangles.size()), 3);
    for (size_t t = 0; t < r.kept_triangles.size(); ++t)
      kept.row(static_cast<Eigen::Index>(t)) = base.row(r.kept_triangles[t]);
    m.input_triangles = std::move(kept);
  } else {
    m.input_to_engine.resize(r.to_input.size());
    for (size_t i = 0; i < r.to_input.size(); ++i) m.input_to_engine[i] = static_cast<int>(i);
    m.input_triangles = r.mesh.F;
    m.repair_renumbered = true;
  }

  m.warnings.insert(m.warnings.end(), r.report.lines.begin(), r.report.lines.end());

  // Polygons: triangle as read → repaired triangle (−1: dropped).
  {
    std::vector<int> new_triangle(static_cast<size_t>(old_m), -1);
    for (size_t t = 0; t < r.kept_triangles.size(); ++t)
      new_triangle[static_cast<size_t>(r.kept_triangles[t])] = static_cast<int>(t);
    const Triangles& F = r.mesh.F;
    std::vector<int> stamp(static_cast<size_t>(r.mesh.num_vertices()), -1);  // last polygon seen
    std::vector<PolygonFan> kept;
    kept.reserve(m.polygons.size());
    for (size_t p = 0; p < m.polygons.size(); ++p) {
      const PolygonFan& fan = m.polygons[p];
      const int tris = fan.corners - 2;
      bool ok = tris >= 1 && fan.first_triangle >= 0 && fan.first_triangle + static_cast<Eigen::Index>(tris) <= old_m;
      for (int i = 0; ok && i < tris; ++i)
        ok = new_triangle[static_cast<size_t>(fan.first_triangle + i)] >= 0;
      if (ok) {
        // All its triangles survive, hence they are consecutive in the repaired numbering.
        const int t = new_triangle[static_cast<size_t>(fan.first_triangle)];
        auto fresh = [&](int v) {
          int& s = stamp[static_cast<size_t>(v)];
          if (s == static_cast<int>(p)) return false;
          s = static_cast<int>(p);
          return true;
        };
        ok = fresh(F(t, 0)) && fresh(F(t, 1)) && fresh(F(t, 2));
        for (int i = 1; ok && i < tris; ++i) ok = fresh(F(t + i, 2));
        if (ok) kept.push_back({t, fan.corners});
      }
    }
    const size_t dropped = m.polygons.size() - kept.size();
    m.polygons = std::move(kept);
    if (dropped > 0)
      m.warnings.push_back(std::to_string(dropped) + (dropped == 1 ? " polygon" : " polygons") +
                           " changed by the repair " + (dropped == 1 ? "is" : "are") +
                           " written back as triangles");
  }

  // The map back to the ids as read, through an earlier repair's when there was one.
  if (!m.repair_to_input.empty())
    for (int& v : r.to_input) v = m.repair_to_input[static_cast<size_t>(v)];
  if (!m.repair_triangles_to_input.empty())
    for (int& t : r.kept_triangles) t = m.repair_triangles_to_input[static_cast<size_t>(t)];
  m.repair_to_input = std::move(r.to_input);
  m.repair_triangles_to_input = std::move(r.kept_triangles);

  m.mesh = std::move(r.mesh);
  return std::move(r.report);
}

}  // namespace hdeform
