#include "service/frames/frames.h"

#include "engine/io/rewrite_gltf.h"

#include <algorithm>
#include <bit>
#include <cstring>

namespace hdeform::service {

static_assert(std::endian::native == std::endian::little,
              "frame buffers are written as native float32: little-endian hosts only");

FrameLayout::FrameLayout(LoadedMesh layout, std::shared_ptr<const PreparedMesh> mesh)
    : layout_(std::move(layout)), mesh_(std::move(mesh)) {
  identity_ = layout_.input_to_engine.empty();
  if (!identity_) {
    identity_ = static_cast<int>(layout_.input_to_engine.size()) == mesh_->n();
    for (int i = 0; identity_ && i < mesh_->n(); ++i)
      identity_ = layout_.input_to_engine[i] == i;
  }
  input_vertices_ = identity_ ? mesh_->n() : static_cast<int>(layout_.input_to_engine.size());
  if (layout_.input_triangles.rows() == 0) layout_.input_triangles = mesh_->mesh().F;
  if (!identity_) {
    const int n = mesh_->n();
    engine_offsets_.assign(static_cast<std::size_t>(n) + 1, 0);
    for (int e : layout_.input_to_engine) ++engine_offsets_[static_cast<std::size_t>(e) + 1];
    for (int e = 0; e < n; ++e) engine_offsets_[e + 1] += engine_offsets_[e];
    engine_to_base_.resize(layout_.input_to_engine.size());
    std::vector<int> next(engine_offsets_.begin(), engine_offsets_.end() - 1);
    for (int i = 0; i < input_vertices_; ++i)  // ascending i: each list comes out sorted
      engine_to_base_[next[layout_.input_to_engine[i]]++] = i;
  }
}

std::span<const int> FrameLayout::base_to_engine() const {
  if (identity_) return {};
  return layout_.input_to_engine;
}

std::vector<int> FrameLayout::base_vertices(const std::vector<int>& engine_ids) const {
  if (identity_) return engine_ids;
  std::vector<int> out;
  out.reserve(engine_ids.size());
  for (int e : engine_ids)
    out.insert(out.end(), engine_to_base_.begin() + engine_offsets_[e],
               engine_to_base_.begin() + engine_offsets_[e + 1]);
  std::sort(out.begin(), out.end());
  return out;
}

int FrameLayout::vertex_count() const { return input_vertices_; }
Eigen::MatrixXd FrameLayout::to_base(const Eigen::MatrixXd& engine_rows) const {
  if (identity_) return engine_rows;
  Eigen::MatrixXd out(input_vertices_, engine_rows.cols());
  for (int i = 0; i < input_vertices_; ++i) out.row(i) = engine_rows.row(input_vertex(i));
  return out;
}

int FrameLayout::triangle_count() const { return static_cast<int>(layout_.input_triangles.rows()); }

template <typename Scalar>
std::string FrameLayout::pack_rows(const Vertices& rows) const {
  std::string out(sizeof(Scalar) * 3 * static_cast<std::size_t>(input_vertices_), '\0');
  auto* f = reinterpret_cast<Scalar*>(out.data());
  for (int i = 0; i < input_vertices_; ++i) {
    const int e = input_vertex(i);
    f[3 * i + 0] = static_cast<Scalar>(rows(e, 0));
    f[3 * i + 1] = static_cast<Scalar>(rows(e, 1));
    f[3 * i + 2] = static_cast<Scalar>(rows(e, 2));
  }
  return out;
}

std::string FrameLayout::pack_vertices(const Vertices& rows) const { return pack_rows<float>(rows); }

std::string FrameLayout::pack_vertices64(const Vertices& rows) const {
  return pack_rows<double>(rows);
}

std::string FrameLayout::pack_vertex_scalars(const Eigen::MatrixXd& rows, int col) const {
  std::string out(sizeof(float) * static_cast<std::size_t>(input_vertices_), '\0');
  float* f = reinterpret_cast<float*>(out.data());
  for (int i = 0; i < input_vertices_; ++i) f[i] = static_cast<float>(rows(input_vertex(i), col));
  return out;
}

std::string FrameLayout::pack_triangles(const Eigen::VectorXf& per_triangle) const {
  // Base-GLB triangle l is engine triangle l (the loader keeps the triangle order).
  std::string out(sizeof(float) * static_cast<std::size_t>(per_triangle.size()), '\0');
  std::memcpy(out.data(), per_triangle.data(), out.size());
  return out;
}

void FrameLayout::fill(const hdeform::Frame& frame, v1::Frame* out) const {
  out->set_positions(pack_vertices(frame.positions));
  if (frame.normals.rows() == frame.positions.rows())
    out->set_normals(pack_vertices(frame.normals));
  else
    out->clear_normals();
  if (frame.energies.size() > 0)
    out->set_energies(pack_triangles(frame.energies));
  else
    out->clear_energies();
  out->set_exact(frame.exact);
  if (!frame.has_measures) {
    out->clear_measures();
    return;
  }
  auto* m = out->mutable_measures();
  m->set_e(frame.measures.E);
  m->set_e_iso_n(frame.measures.E_iso_N);
  m->set_e_conf_n(frame.measures.E_conf_N);
  m->set_e_area_pct(frame.measures.E_area_pct);
  m->set_max_e_iso(frame.measures.max_e_iso);
  m->set_max_e_conf(frame.measures.max_e_conf);
  m->set_max_ef2(frame.measures.max_ef2);
  m->set_flips(frame.measures.flips);
}

std::string FrameLayout::input_gltf(std::string_view original, const std::string& filename,
                                    const Vertices& V) const {
  const Vertices N = vertex_normals(V, mesh_->mesh().F);
  Vertices Vi(input_vertices_, 3), Ni(input_vertices_, 3);
  for (int i = 0; i < input_vertices_; ++i) {
    Vi.row(i) = V.row(input_vertex(i));
    Ni.row(i) = N.row(input_vertex(i));
  }
  return rewrite_gltf(original, filename, Vi, Ni);
}

std::string FrameLayout::mesh_file(MeshFileFormat format, const Vertices& V,
                                   const WriteOptions& options) const {
  const Triangles& F = mesh_->mesh().F;
  if (format != MeshFileFormat::glb) {
    // The input's own polygons back (OBJ/OFF/PLY uploads keep their vertex order).
    WriteOptions with_polygons = options;
    if (!remapped()) with_polygons.polygons = layout_.polygons;
    return write_mesh_bytes(format, V, F, nullptr, with_polygons);
  }
  const Vertices N = vertex_normals(V, F);
  if (identity_) return write_mesh_bytes(format, V, layout_.input_triangles, &N, options);
  // Not LoadedMesh::to_input_layout: layout_'s engine mesh was moved into the PreparedMesh
  // (its row check would see 0 vertices).
  auto to_base = [&](const Vertices& rows) {
    Vertices out(input_vertices_, 3);
    for (int i = 0; i < input_vertices_; ++i) out.row(i) = rows.row(input_vertex(i));
    return out;
  };
  const Vertices Vi = to_base(V);
  const Vertices Ni = to_base(N);
  return write_mesh_bytes(format, Vi, layout_.input_triangles, &Ni, options);
}

const std::string& FrameLayout::base_glb() const {
  std::call_once(glb_once_, [&] { glb_ = mesh_file(MeshFileFormat::glb, mesh_->mesh().V); });
  return glb_;
}

}  // namespace hdeform::service
