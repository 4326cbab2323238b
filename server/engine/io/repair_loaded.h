// repair_mesh (engine/mesh/repair.h) applied to a file as read, keeping the LoadedMesh
// consistent so every writer of its layout (to_input_layout, the frame layout, the text
// writers with polygons, the glTF rewrite) stays correct.
//
// When the repair changed nothing, the LoadedMesh is left as it was. Otherwise m.mesh becomes
// the repaired mesh, m.repair_to_input / m.repair_triangles_to_input map engine ids back to the
// ids as read (composed with an earlier repair's), the report's lines are appended to
// m.warnings, and the input layout is one of two:
//
//   - The repair only merged vertices and dropped triangles (no vertex dropped, every repaired
//     triangle is its input triangle through from_input): the layout is kept and composed with
//     the repair, like a glTF weld: input_to_engine[i] = the repaired vertex of input vertex i
//     (duplicates share one), input_triangles = the kept rows, still in input ids. Output in
//     the input layout (base GLB, frames, a glTF's own file rewritten) keeps the user's vertex
//     count and ids.
//   - Otherwise the layout becomes the identity over the repaired mesh (input_to_engine =
//     0…n−1, input_triangles = its F). A dropped input vertex has no engine vertex, and a split
//     one has several, so no map from input vertices could drive the writers (they index with
//     input_to_engine unchecked); −1 entries are never stored. A glTF's own file can then no
//     longer be rewritten (rewrite_gltf refuses the vertex count); its GLB export works.
//
// Polygons: a fan is kept (first_triangle shifted to the repaired numbering) when all its
// triangles survive and its corners stay distinct; others are dropped from m.polygons (those
// faces are written as their triangles) and a warning counts them.
//
// Throws InvalidInput as repair_mesh does; m is then unchanged.
#pragma once

#include "engine/io/mesh_io.h"
#include "engine/mesh/repair.h"

namespace hdeform {

RepairReport repair_loaded_mesh(LoadedMesh& m, const RepairOptions& options = {});

}  // namespace hdeform
