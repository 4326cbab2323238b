// glTF output that keeps the input (docs/cli.md "Outputs"): the uploaded glTF/GLB with only
// the deformed triangle primitives' POSITION and NORMAL replaced, everything else as given.
#pragma once

#include "engine/mesh/mesh.h"

#include <string>
#include <string_view>

namespace hdeform {

// Reads `original` (a .glb or .gltf with embedded buffers, as read_mesh accepted it) and
// returns a GLB in which every triangle primitive points at new float32 POSITION (with
// min/max) and NORMAL accessors holding `positions` / `normals` (input-vertex order: the
// order of LoadedMesh's input layout, one row per input vertex), appended to the binary
// buffer. TANGENT is dropped from those primitives (it would no longer match the surface;
// viewers recompute it). UVs, colours, skins, materials, textures, node names and
// transforms, other primitives and extensions stay as they were. Throws InvalidInput if the
// file no longer reads or its vertex count differs from `positions`.
std::string rewrite_gltf(std::string_view original, const std::string& filename,
                         const Vertices& positions, const Vertices& normals);

}  // namespace hdeform
