// Internal header of the mesh readers (namespace detail), not part of the public API: use mesh_io.h.
// One parser per format; read_any in mesh_io.cpp picks one by extension.
//
// - OBJ, ASCII OFF and PLY (ASCII and binary) are parsed by our own code (read_obj.cpp,
//   read_off.cpp, read_ply.cpp), line by line: positions keep full double precision
//   (OpenMesh's readers go through float), every face is kept in file order (no halfedge
//   structure that would drop non-manifold faces, so validation can name them), and parse
//   errors name the file and the line ("cube.off:7: expected 3 coordinates, found 2").
// - STL and binary OFF go through OpenMesh's IO layer (read_openmesh.cpp).
// - glTF/GLB through tinygltf (read_gltf.cpp), with vertices welded by position.
// `name` is the file name used in errors and warnings; `warnings` collects non-fatal notes.
#pragma once

#include "mesh_soup.h"

#include <string>
#include <string_view>
#include <vector>

namespace hdeform::detail {

// OBJ: v, f (with v/vt/vn corners, negative = relative indices); everything else ignored.
Soup parse_obj(std::string_view text, const std::string& name, std::vector<std::string>& warnings);
// ASCII OFF; "OFF BINARY" is handed to read_with_openmesh.
Soup parse_off(std::string_view text, const std::string& name, std::vector<std::string>& warnings);
// PLY (ascii, binary_little_endian, binary_big_endian): vertex x y z, face vertex_indices.
Soup parse_ply(std::string_view bytes, const std::string& name);
// OpenMesh's reader for `ext` ("stl", "off") with an importer that records the raw soup.
Soup read_with_openmesh(std::string_view bytes, const std::string& ext, const std::string& name,
                        bool binary, std::vector<std::string>& warnings);
// glTF (binary = false) or GLB. base_dir: where external buffers are resolved; null for an
// in-memory upload (external files are refused).
LoadedMesh read_gltf(std::string_view bytes, const std::string& name, bool binary,
                     const std::string* base_dir);

}  // namespace hdeform::detail
