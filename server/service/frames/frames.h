// The base layout a session's clients see: the base GLB (input vertex layout, float32
// POSITION/NORMAL, uint32 indices) and the float32 little-endian frame buffers in that
// same layout.
#pragma once

#include "engine/deform/deformer.h"
#include "engine/io/mesh_io.h"
#include "hdeform/v1/deform.pb.h"

#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <vector>

namespace hdeform::service {

class FrameLayout {
 public:
  // `layout` is the loaded file (its engine mesh may have been moved out already);
  // `mesh` the prepared engine mesh it maps to.
  FrameLayout(LoadedMesh layout, std::shared_ptr<const PreparedMesh> mesh);

  int vertex_count() const;    // base GLB vertices (input layout)
  int triangle_count() const;  // base GLB triangles

  // float32 LE, 3 per base-GLB vertex, from engine-order rows.
  std::string pack_vertices(const Vertices& engine_rows) const;
  // float64 LE, 3 per base-GLB vertex (FRAME_ENCODING_FLOAT64), from engine-order rows.
  std::string pack_vertices64(const Vertices& engine_rows) const;
  // float32 LE, 1 per base-GLB vertex, from column `col` of engine-order rows.
  std::string pack_vertex_scalars(const Eigen::MatrixXd& engine_rows, int col) const;
  // float32 LE, 1 per base-GLB triangle.
  std::string pack_triangles(const Eigen::VectorXf& per_triangle) const;
  // Fills positions / normals / energies / measures of a proto frame.
  void fill(const hdeform::Frame& frame, v1::Frame* out) const;

  // A mesh file of `engine_positions`: GLB in the input layout with normals (the base
  // layout); OBJ/OFF/PLY in engine order (the ids constraints use; text keeps %.17g).
  std::string mesh_file(MeshFileFormat format, const Vertices& engine_positions,
                        const WriteOptions& options = {}) const;
  // A glTF upload's own file with the deformed positions and normals (rewrite_gltf.h).
  std::string input_gltf(std::string_view original, const std::string& filename,
                         const Vertices& engine_positions) const;
  // Engine-order rows rearranged into the base-GLB layout (one row per base vertex), and
  // the base GLB's triangles.
  Eigen::MatrixXd to_base(const Eigen::MatrixXd& engine_rows) const;
  const Triangles& base_triangles() const { return layout_.input_triangles; }
  // The rest mesh as GLB, built once.
  const std::string& base_glb() const;

  // False when base-GLB vertex i is engine vertex i for every i (OBJ/OFF/PLY/STL, and glTF
  // files without split vertices).
  bool remapped() const { return !identity_; }
  // Base-GLB vertex → engine vertex (the weld map); empty when !remapped().
  std::span<const int> base_to_engine() const;
  // Sorted engine ids → every base-GLB vertex on them (sorted); the ids themselves when
  // !remapped().
  std::vector<int> base_vertices(const std::vector<int>& engine_ids) const;

 private:
  int input_vertex(int i) const { return identity_ ? i : layout_.input_to_engine[i]; }
  template <typename Scalar>
  std::string pack_rows(const Vertices& engine_rows) const;

  LoadedMesh layout_;
  std::shared_ptr<const PreparedMesh> mesh_;
  bool identity_;
  int input_vertices_;
  // Engine vertex e's base vertices: engine_to_base_[engine_offsets_[e] .. [e+1]) (remapped).
  std::vector<int> engine_offsets_, engine_to_base_;
  mutable std::once_flag glb_once_;
  mutable std::string glb_;
};

}  // namespace hdeform::service
