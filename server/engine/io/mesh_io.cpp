// Mesh file I/O: the public functions of mesh_io.h and the format dispatch. The parsers
// live in read_*.cpp (overview and rationale: mesh_readers.h), the writers in
// write_mesh_formats.cpp.

#include "engine/io/mesh_io.h"

#include "engine/io/mesh_readers.h"
#include "engine/io/mesh_soup.h"
#include "engine/io/mesh_writers.h"

#include <Eigen/Geometry>

#include <bit>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

namespace hdeform {

bool LoadedMesh::identity_layout() const {
  if (input_to_engine.size() != static_cast<size_t>(mesh.num_vertices())) return false;
  for (size_t i = 0; i < input_to_engine.size(); ++i)
    if (input_to_engine[i] != static_cast<int>(i)) return false;
  return true;
}

Vertices LoadedMesh::to_input_layout(const Vertices& engine_positions) const {
  if (engine_positions.rows() != mesh.num_vertices())
    throw std::invalid_argument("to_input_layout: " + std::to_string(engine_positions.rows()) +
                                " positions for a mesh of " +
                                std::to_string(mesh.num_vertices()) + " vertices");
  Vertices out(static_cast<Eigen::Index>(input_to_engine.size()), 3);
  for (size_t i = 0; i < input_to_engine.size(); ++i) {
    const int e = input_to_engine[i];
    if (e < 0 || e >= engine_positions.rows())
      throw std::invalid_argument("to_input_layout: input vertex " + std::to_string(i) +
                                  " maps to engine vertex " + std::to_string(e) + ", outside [0, " +
                                  std::to_string(engine_positions.rows()) + ")");
    out.row(static_cast<Eigen::Index>(i)) = engine_positions.row(e);
  }
  return out;
}

namespace {

LoadedMesh read_any(std::string_view bytes, const std::string& name, const std::string* base_dir,
                    const ReadLimits& limits) {
  const std::string ext = detail::lower_extension(name);
  if (ext != "obj" && ext != "off" && ext != "ply" && ext != "stl" && ext != "gltf" && ext != "glb")
    detail::fail(name + ": unknown mesh format " +
                 (ext.empty() ? std::string("(no extension)") : "'." + ext + "'") +
                 " (expected .obj, .off, .ply, .stl, .gltf or .glb)");
  if (bytes.empty()) detail::fail(name + ": empty file");
  detail::ReadContext ctx(name, limits);
  ctx.poll();
  if (ext == "gltf" || ext == "glb") {
    LoadedMesh out = detail::read_gltf(bytes, ctx, ext == "glb", base_dir);
    out.warnings.insert(out.warnings.begin(), ctx.warnings.begin(), ctx.warnings.end());
    return out;
  }
  if (ext == "obj") return detail::to_loaded(detail::parse_obj(bytes, ctx), ctx, "OBJ");
  if (ext == "off") return detail::to_loaded(detail::parse_off(bytes, ctx), ctx, "OFF");
  if (ext == "ply") return detail::to_loaded(detail::parse_ply(bytes, ctx), ctx, "PLY");
  return detail::to_loaded(detail::parse_stl(bytes, ctx), ctx, "STL");
}

void check_write_input(const Vertices& V, const Triangles& F, const Vertices* N) {
  if (N && N->rows() != V.rows())
    throw std::invalid_argument("write_mesh: " + std::to_string(N->rows()) + " normals for " +
                                std::to_string(V.rows()) + " vertices");
  for (Eigen::Index t = 0; t < F.rows(); ++t)
    for (int k = 0; k < 3; ++k)
      if (F(t, k) < 0 || F(t, k) >= V.rows())
        throw std::invalid_argument("write_mesh: triangle " + std::to_string(t) + " uses vertex " +
                                    std::to_string(F(t, k)) + " of " + std::to_string(V.rows()));
}

std::string read_file(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) detail::fail(path + ": is a directory, not a mesh file");
  std::ifstream in(path, std::ios::binary);
  if (!in) detail::fail(path + ": cannot open file (" + std::strerror(errno) + ")");
  std::string data;
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  if (size < 0) detail::fail(path + ": cannot read file");
  in.seekg(0, std::ios::beg);
  data.resize(static_cast<size_t>(size));
  if (size > 0 && !in.read(data.data(), size)) detail::fail(path + ": cannot read file");
  return data;
}

}  // namespace

LoadedMesh read_mesh(const std::string& path, const ReadLimits& limits) {
  const std::string ext = detail::lower_extension(path);
  if (ext != "obj" && ext != "off" && ext != "ply" && ext != "stl" && ext != "gltf" && ext != "glb")
    return read_any({}, path, nullptr, limits);  // throws the unknown-format error before touching the file
  const std::string data = read_file(path);
  std::string base = std::filesystem::path(path).parent_path().string();
  // push_back, not = ".": GCC 12 -O3 gives a false -Wrestrict on the assignment here.
  if (base.empty()) base.push_back('.');
  return read_any(data, path, &base, limits);
}

LoadedMesh read_mesh_bytes(std::string_view bytes, const std::string& filename,
                           const ReadLimits& limits) {
  return read_any(bytes, filename, nullptr, limits);
}

MeshFileFormat format_from_path(const std::string& path) {
  const std::string ext = detail::lower_extension(path);
  if (ext == "glb") return MeshFileFormat::glb;
  if (ext == "obj") return MeshFileFormat::obj;
  if (ext == "off") return MeshFileFormat::off;
  if (ext == "ply") return MeshFileFormat::ply;
  detail::fail(path + ": cannot write format " +
               (ext.empty() ? std::string("(no extension)") : "'." + ext + "'") +
               " (expected .glb, .obj, .off or .ply)");
}

std::string write_mesh_bytes(MeshFileFormat format, const Vertices& V, const Triangles& F,
                             const Vertices* N, const WriteOptions& options) {
  check_write_input(V, F, N);
  switch (format) {
    case MeshFileFormat::glb: {
      // A GLB always carries normals: vertex_normals() when none are given.
      const Vertices computed = N ? Vertices() : vertex_normals(V, F);
      const Vertices& normals = N ? *N : computed;
      if (options.glb_compression == GlbCompression::none)
        return detail::write_glb(V, F, normals, options.up_z);
      return detail::write_glb_compressed(V, F, normals, options.up_z,
                                          options.glb_compression == GlbCompression::meshopt);
    }
    case MeshFileFormat::obj: return detail::write_obj(V, F, N, options.polygons);
    case MeshFileFormat::off: return detail::write_off(V, F, N, options.polygons);
    case MeshFileFormat::ply:
      return options.binary_ply ? detail::write_ply_binary(V, F, N, options.polygons)
                                : detail::write_ply(V, F, N, options.polygons);
  }
  throw std::invalid_argument("write_mesh_bytes: unknown format");
}

void write_mesh(const std::string& path, const Vertices& V, const Triangles& F, const Vertices* N) {
  const std::string bytes = write_mesh_bytes(format_from_path(path), V, F, N);
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw std::runtime_error(path + ": cannot open for writing (" + std::strerror(errno) + ")");
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!out) throw std::runtime_error(path + ": write failed");
}

void vertex_normals(const Vertices& V, const Triangles& F, Vertices& N) {
  N.resize(V.rows(), 3);  // a no-op when N already has the size: no allocation on a move
  N.setZero();
  for (Eigen::Index t = 0; t < F.rows(); ++t) {
    const Eigen::RowVector3d a = V.row(F(t, 0)), b = V.row(F(t, 1)), c = V.row(F(t, 2));
    const Eigen::RowVector3d w = (b - a).cross(c - a);  // |w| = 2 · area: area weighting
    for (int k = 0; k < 3; ++k) N.row(F(t, k)) += w;
  }
  for (Eigen::Index i = 0; i < N.rows(); ++i) {
    const double len = N.row(i).norm();
    if (len > 0) N.row(i) /= len;
  }
}

Vertices vertex_normals(const Vertices& V, const Triangles& F) {
  Vertices N;
  vertex_normals(V, F, N);
  return N;
}

}  // namespace hdeform
