// Internal header of the mesh readers (namespace detail), not part of the public API: use mesh_io.h.
// One parser per format; read_any in mesh_io.cpp picks one by extension.
//
// - OBJ, OFF (ASCII and binary), PLY (ASCII and binary) and STL (ASCII and binary) are
//   parsed by our own code (read_obj.cpp, read_off.cpp, read_ply.cpp, read_stl.cpp):
//   positions keep full double precision (OpenMesh's readers go through float), every face
//   is kept in file order (no halfedge structure that would drop non-manifold faces, so
//   validation can name them), and parse errors name the file, the format and the line
//   ("cube.off:7: expected 3 coordinates, found 2") or the byte/element for binary data.
// - glTF/GLB through tinygltf (read_gltf.cpp), with vertices welded by position.
//
// Bounded cost: every reader's work and memory are O(input size). A count read from a header
// is checked against the bytes that follow (count × smallest record ≤ bytes left) and against
// ReadLimits before anything is reserved; a record that takes no bytes (a PLY element
// without properties) is skipped in O(1). Loops poll ReadContext::tick() for cancellation.
// `ctx.name` names the file in errors and warnings; ctx.warnings collects non-fatal notes.
#pragma once

#include "engine/io/mesh_soup.h"

#include <string>
#include <string_view>
#include <vector>

namespace hdeform::detail {

// OBJ: v, f (with v/vt/vn corners, negative = relative indices); other statements ignored.
Soup parse_obj(std::string_view text, ReadContext& ctx);
// OFF: ASCII, and "[ST][C][N]OFF BINARY" (Geomview's big-endian binary variant).
Soup parse_off(std::string_view bytes, ReadContext& ctx);
// PLY (ascii, binary_little_endian, binary_big_endian): vertex x y z, face vertex_indices.
Soup parse_ply(std::string_view bytes, ReadContext& ctx);
// STL, binary (80-byte header, uint32 count, 50 bytes per triangle) or ASCII (solid ...
// endsolid). Corners with identical positions are merged into one vertex.
Soup parse_stl(std::string_view bytes, ReadContext& ctx);
// glTF (binary = false) or GLB. base_dir: where external buffers are resolved; null for an
// in-memory upload (external files are refused).
LoadedMesh read_gltf(std::string_view bytes, ReadContext& ctx, bool binary,
                     const std::string* base_dir);

}  // namespace hdeform::detail
