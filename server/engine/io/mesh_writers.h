// Internal header of the mesh writers (namespace detail), not part of the public API: use mesh_io.h.
// Each serialises V (+ optional per-vertex normals N) and F, already checked by write_mesh_bytes.
#pragma once

#include "engine/mesh/mesh.h"

#include <string>

namespace tinygltf {
class Model;
}

namespace hdeform::detail {

std::string write_obj(const Vertices& V, const Triangles& F, const Vertices* N);
std::string write_off(const Vertices& V, const Triangles& F, const Vertices* N);
std::string write_ply(const Vertices& V, const Triangles& F, const Vertices* N);
std::string write_ply_binary(const Vertices& V, const Triangles& F, const Vertices* N);
// N null: vertex_normals(V, F). up_z: a root node rotates the z-up model to glTF's y-up.
std::string write_glb(const Vertices& V, const Triangles& F, const Vertices* N, bool up_z);
// KHR_mesh_quantization, through EXT_meshopt_compression when `meshopt` (GlbCompression in
// mesh_io.h); N null: vertex_normals(V, F). Throws InvalidInput for a non-finite position.
std::string write_glb_compressed(const Vertices& V, const Triangles& F, const Vertices* N,
                                 bool up_z, bool meshopt);
// −90° about x as a glTF quaternion (x, y, z, w): (x, y, z) → (x, z, −y), z-up to y-up.
inline constexpr double kZUpToYUp[4] = {-0.70710678118654752440, 0.0, 0.0, 0.70710678118654752440};
// The GLB writers' shared end: the scene of node 0 (under a −90° x rotation when up_z; the
// buffers keep model coordinates), then the model serialised (throws std::runtime_error
// naming `who`).
void add_scene(tinygltf::Model& model, bool up_z);
std::string serialise_glb(tinygltf::Model& model, const char* who);

}  // namespace hdeform::detail
