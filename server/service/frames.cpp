#include "frames.h"

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
}

int FrameLayout::vertex_count() const { return input_vertices_; }
int FrameLayout::triangle_count() const { return static_cast<int>(layout_.input_triangles.rows()); }

std::string FrameLayout::pack_vertices(const Vertices& rows) const {
  std::string out(sizeof(float) * 3 * static_cast<std::size_t>(input_vertices_), '\0');
  auto* f = reinterpret_cast<float*>(out.data());
  for (int i = 0; i < input_vertices_; ++i) {
    const int e = input_vertex(i);
    f[3 * i + 0] = static_cast<float>(rows(e, 0));
    f[3 * i + 1] = static_cast<float>(rows(e, 1));
    f[3 * i + 2] = static_cast<float>(rows(e, 2));
  }
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

std::string FrameLayout::mesh_file(MeshFileFormat format, const Vertices& V) const {
  const Triangles& F = mesh_->mesh().F;
  if (format != MeshFileFormat::glb) return write_mesh_bytes(format, V, F);
  const Vertices N = vertex_normals(V, F);
  if (identity_) return write_mesh_bytes(format, V, layout_.input_triangles, &N);
  const Vertices Vi = layout_.to_input_layout(V);
  const Vertices Ni = layout_.to_input_layout(N);
  return write_mesh_bytes(format, Vi, layout_.input_triangles, &Ni);
}

const std::string& FrameLayout::base_glb() const {
  std::call_once(glb_once_, [&] { glb_ = mesh_file(MeshFileFormat::glb, mesh_->mesh().V); });
  return glb_;
}

}  // namespace hdeform::service
