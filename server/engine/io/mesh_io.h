// Mesh files: OBJ/OFF/PLY/STL by our own parsers, glTF/GLB through tinygltf.
// Vertex ids are the file's vertex order. glTF vertices split only by attributes (same
// position, e.g. UV seams) are welded into one surface; the map back keeps output in the
// input's layout. glTF: all triangle primitives of all meshes, in mesh-local coordinates
// (node transforms are not applied; a warning says so); see mesh_io.cpp for details.
// Every face of a text file is kept (even non-manifold ones) so validate_mesh can name them.
#pragma once

#include "engine/mesh/mesh.h"

#include <atomic>
#include <cstddef>
#include <functional>
#include <stdexcept>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace hdeform {

// A face of the input with more than 3 corners, as the readers triangulate it: a fan of
// corners − 2 triangles from `first_triangle` on, around its first corner. Its corners in
// order are F(t, 0), F(t, 1), F(t, 2), F(t + 1, 2), …, F(t + corners − 3, 2).
struct PolygonFan {
  int first_triangle = 0;
  int corners = 4;
};

struct LoadedMesh {
  TriMesh mesh;                       // welded surface, what the engine deforms
  // Input layout: one entry per input vertex → its engine vertex, always a valid engine id
  // (the frame writers index with it unchecked). Identity for OBJ/OFF/PLY/STL; the weld map
  // for glTF; see repair_loaded.h for a repaired mesh.
  std::vector<int> input_to_engine;
  Triangles input_triangles;          // triangles in input-vertex ids (triangulated)
  std::vector<std::string> warnings;  // e.g. polygons triangulated
  // OBJ/OFF/PLY faces with more than 3 corners (ascending first_triangle): what the writers
  // need to give the user's own polygons back (WriteOptions::polygons).
  std::vector<PolygonFan> polygons;
  // Set only when repair_loaded_mesh changed the mesh (empty otherwise: engine ids are the
  // ids as read). Engine vertex → the vertex of the mesh as read (the file's vertex id for
  // OBJ/OFF/PLY/STL, the welded id for glTF), and engine triangle → the triangle as read:
  // the map back to the user's ids.
  std::vector<int> repair_to_input;
  std::vector<int> repair_triangles_to_input;
  // The repair renumbered the input layout (it is the repaired mesh's): input-layout ids are
  // engine ids, mapped back by repair_to_input. False: they are still the ids as read.
  bool repair_renumbered = false;
  bool identity_layout() const;
  // Engine positions rearranged into the input layout (input vertex count × 3). Throws
  // std::invalid_argument when the row count or an input_to_engine entry does not fit.
  Vertices to_input_layout(const Vertices& engine_positions) const;
};

// Limits applied while a file is parsed (not after): a header that declares more vertices or
// triangles than allowed fails before anything is allocated, and formats without declared
// counts (OBJ, ASCII STL, glTF) fail as soon as the running count passes the limit. Every
// reader's work and memory are bounded by the input's size whatever the limits.
struct ReadLimits {
  std::size_t max_vertices = 0;   // 0 = unlimited; input vertices (glTF: before welding)
  std::size_t max_triangles = 0;  // 0 = unlimited; after fan triangulation
  // Named in the messages: "x.ply: 5000000 vertices exceed the server's limit of 2000000
  // (--max-vertices)". Empty: no parenthesis.
  std::string vertices_option = "--max-vertices";
  std::string triangles_option = "--max-triangles";
  // Cooperative cancellation, polled every few thousand rows/lines/elements: when
  // *cancel is true or should_cancel() returns true, the read throws ReadCancelled.
  const std::atomic<bool>* cancel = nullptr;
  std::function<bool()> should_cancel;
};

// A limit of ReadLimits was exceeded (a service maps it to RESOURCE_EXHAUSTED). An
// InvalidInput, so code that only knows InvalidInput still reports it.
class LimitExceeded : public InvalidInput {
 public:
  using InvalidInput::InvalidInput;
};
// The read was cancelled through ReadLimits::cancel / should_cancel. Not an InvalidInput:
// the file may be fine. Message: "NAME: reading cancelled".
class ReadCancelled : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Format from the extension (case-insensitive): .obj .off .ply .stl .gltf .glb.
// Throws InvalidInput naming the file, the format and where it failed ("x.obj:12: ...",
// "x.stl: binary STL truncated: ..."); LimitExceeded / ReadCancelled as above.
LoadedMesh read_mesh(const std::string& path, const ReadLimits& limits = {});
// Same for an in-memory upload; `filename` only picks the format and names errors.
LoadedMesh read_mesh_bytes(std::string_view bytes, const std::string& filename,
                           const ReadLimits& limits = {});

enum class MeshFileFormat { glb, obj, off, ply };
MeshFileFormat format_from_path(const std::string& path);  // throws InvalidInput

// Serialises positions (+ optional per-vertex normals) and triangles. Text formats write
// doubles in their shortest round-trip form (std::to_chars; reads back bit-identical, like
// %.17g). GLB carries float32 POSITION, NORMAL (vertex_normals() when N is null) and uint32
// indices in one buffer laid out [POSITION n×12 B | NORMAL n×12 B | indices m×12 B] (the
// base layout that service frames refer to). format_from_path throws InvalidInput; a file
// that cannot be written throws std::runtime_error.
// GLB compression (WriteOptions::glb_compression); the file stays one TRIANGLES primitive with
// POSITION, NORMAL and indices, in the same vertex and triangle order as the plain GLB.
//   quantized: KHR_mesh_quantization (required). POSITION as uint16 VEC3 on one uniform grid
//     over the bounding box; the mesh node's translation (the box's min) and uniform scale
//     (extent / 65535, extent = the box's largest side) give model coordinates back, so the
//     error is ≤ extent / 131070 per axis (+ float32 rounding). A uniform scale keeps normals
//     right under the node transform. NORMAL as normalized int8 VEC3: ≤ 0.5 / 127 per
//     component. Indices uint16 when the vertices fit, else uint32. 4-byte strides (8 B a
//     position, 4 B a normal) so both streams can go through meshopt's codec.
//   meshopt: the same streams through meshoptimizer's codecs as EXT_meshopt_compression
//     (required; vertex codec "ATTRIBUTES", index codec "TRIANGLES"; no fallback data). The
//     decoded vertex streams are exactly the quantized file's; the index codec keeps the
//     triangle order and winding but may start a triangle at another corner. three.js reads it with
//     GLTFLoader.setMeshoptDecoder.
// hdeform's own reader reads neither back (it wants float32 POSITION and ignores node
// transforms); these are for shipping a result, the plain GLB for round trips.
enum class GlbCompression { none, quantized, meshopt };

// How a file is written beyond its format.
struct WriteOptions {
  // GLB: the model's up axis is +z (the cactus; CAD and scan data). glTF is y-up, so the GLB
  // gets a root node rotating −90° about x (z → y): Blender and three.js show it upright, and
  // the buffer keeps the model's own coordinates exactly (read_mesh ignores node transforms,
  // so a round trip gives the same positions and ids). Other formats: no effect.
  bool up_z = false;
  // PLY: binary little-endian (doubles, int indices) instead of ASCII; reads back identical.
  bool binary_ply = false;
  // GLB only (see GlbCompression). Non-finite positions throw InvalidInput: a grid holds none.
  GlbCompression glb_compression = GlbCompression::none;
  // OBJ/OFF/PLY: the input's polygons (LoadedMesh::polygons, for these triangles): each is
  // written as the one face it was, not as its fan. A fan that does not match F (or, in PLY,
  // has over 255 corners) is written as its triangles. GLB: no effect (triangles only).
  std::span<const PolygonFan> polygons;
};
std::string write_mesh_bytes(MeshFileFormat format, const Vertices& V, const Triangles& F,
                             const Vertices* N = nullptr, const WriteOptions& options = {});
void write_mesh(const std::string& path, const Vertices& V, const Triangles& F,
                const Vertices* N = nullptr);

// Area-weighted unit vertex normals (n×3); vertices without triangles get zero.
Vertices vertex_normals(const Vertices& V, const Triangles& F);
// The same into N (resized to V's rows; reusing N of that size allocates nothing).
void vertex_normals(const Vertices& V, const Triangles& F, Vertices& N);

}  // namespace hdeform
