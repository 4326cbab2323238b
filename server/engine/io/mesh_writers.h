// Internal header of the mesh writers (namespace detail), not part of the public API: use mesh_io.h.
// Each serialises V (+ optional per-vertex normals N) and F, already checked by write_mesh_bytes.
#pragma once

#include "engine/io/mesh_io.h"
#include "engine/mesh/mesh.h"

#include <span>
#include <string>

namespace hdeform::detail {

std::string write_obj(const Vertices& V, const Triangles& F, const Vertices* N,
                      std::span<const PolygonFan> polygons = {});
std::string write_off(const Vertices& V, const Triangles& F, const Vertices* N,
                      std::span<const PolygonFan> polygons = {});
std::string write_ply(const Vertices& V, const Triangles& F, const Vertices* N,
                      std::span<const PolygonFan> polygons = {});
std::string write_ply_binary(const Vertices& V, const Triangles& F, const Vertices* N,
                             std::span<const PolygonFan> polygons = {});
// The GLB writers (these two and AnimationGlb) share glb_builder.h; a GLB always has normals
// (write_mesh_bytes computes them when none are given). up_z: a root node rotates the z-up
// model to glTF's y-up.
std::string write_glb(const Vertices& V, const Triangles& F, const Vertices& N, bool up_z);
// KHR_mesh_quantization, through EXT_meshopt_compression when `meshopt` (GlbCompression in
// mesh_io.h). Throws InvalidInput for a non-finite position.
std::string write_glb_compressed(const Vertices& V, const Triangles& F, const Vertices& N,
                                 bool up_z, bool meshopt);

}  // namespace hdeform::detail
