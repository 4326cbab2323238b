// STL and binary OFF through OpenMesh's IO layer (IOManager) with our own importer
// (SoupImporter), which records the raw polygon soup and builds no connectivity. OpenMesh's
// STL reader merges corners with identical positions into one vertex. See mesh_readers.h.

#include "mesh_readers.h"

#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/IO/importer/BaseImporter.hh>
#include <OpenMesh/Core/System/omstream.hh>

#include <sstream>

namespace hdeform::detail {
namespace {

class SoupImporter : public OpenMesh::IO::BaseImporter {
 public:
  explicit SoupImporter(Soup& s) : s_(s) {}
  using VH = OpenMesh::VertexHandle;
  using HH = OpenMesh::HalfedgeHandle;
  using FH = OpenMesh::FaceHandle;
  using EH = OpenMesh::EdgeHandle;

  VH add_vertex(const OpenMesh::Vec3f& p) override {
    s_.add_vertex(p[0], p[1], p[2]);
    return VH(s_.num_vertices() - 1);
  }
  VH add_vertex(const OpenMesh::Vec3d& p) override {
    s_.add_vertex(p[0], p[1], p[2]);
    return VH(s_.num_vertices() - 1);
  }
  VH add_vertex() override {
    s_.add_vertex(0, 0, 0);
    return VH(s_.num_vertices() - 1);
  }
  HH add_edge(VH, VH) override { return HH(); }
  FH add_face(const VHandles& idx) override {
    corners_.clear();
    for (const auto& vh : idx) {
      if (vh.idx() < 0 || vh.idx() >= s_.num_vertices()) {
        bad_index_ = true;
        return FH();
      }
      corners_.push_back(vh.idx());
    }
    if (corners_.size() < 3) {
      ++short_faces_;
      return FH();
    }
    s_.add_polygon(corners_.data(), corners_.size());
    return FH(static_cast<int>(faces_++));
  }
  FH add_face(HH) override { return FH(); }
  void add_face_texcoords(FH, VH, const std::vector<OpenMesh::Vec2f>&) override {}
  void add_face_texcoords(FH, VH, const std::vector<OpenMesh::Vec3f>&) override {}
  void set_face_texindex(FH, int) override {}
  void set_point(VH vh, const OpenMesh::Vec3f& p) override {
    if (vh.idx() < 0 || vh.idx() >= s_.num_vertices()) return;
    for (int k = 0; k < 3; ++k) s_.xyz[3 * static_cast<size_t>(vh.idx()) + k] = p[k];
  }
  void set_halfedge(VH, HH) override {}
  void set_normal(VH, const OpenMesh::Vec3f&) override {}
  void set_normal(VH, const OpenMesh::Vec3d&) override {}
  void set_color(VH, const OpenMesh::Vec3uc&) override {}
  void set_color(VH, const OpenMesh::Vec4uc&) override {}
  void set_color(VH, const OpenMesh::Vec3f&) override {}
  void set_color(VH, const OpenMesh::Vec4f&) override {}
  void set_texcoord(VH, const OpenMesh::Vec2f&) override {}
  void set_status(VH, const OpenMesh::Attributes::StatusInfo&) override {}
  void set_next(HH, HH) override {}
  void set_face(HH, FH) override {}
  void request_face_texcoords2D() override {}
  void set_texcoord(HH, const OpenMesh::Vec2f&) override {}
  void set_texcoord(VH, const OpenMesh::Vec3f&) override {}
  void set_texcoord(HH, const OpenMesh::Vec3f&) override {}
  void set_status(HH, const OpenMesh::Attributes::StatusInfo&) override {}
  void set_color(EH, const OpenMesh::Vec3uc&) override {}
  void set_color(EH, const OpenMesh::Vec4uc&) override {}
  void set_color(EH, const OpenMesh::Vec3f&) override {}
  void set_color(EH, const OpenMesh::Vec4f&) override {}
  void set_status(EH, const OpenMesh::Attributes::StatusInfo&) override {}
  void set_normal(FH, const OpenMesh::Vec3f&) override {}
  void set_normal(FH, const OpenMesh::Vec3d&) override {}
  void set_color(FH, const OpenMesh::Vec3uc&) override {}
  void set_color(FH, const OpenMesh::Vec4uc&) override {}
  void set_color(FH, const OpenMesh::Vec3f&) override {}
  void set_color(FH, const OpenMesh::Vec4f&) override {}
  void set_status(FH, const OpenMesh::Attributes::StatusInfo&) override {}
  void add_texture_information(int, std::string) override {}
  size_t n_vertices() const override { return static_cast<size_t>(s_.num_vertices()); }
  size_t n_faces() const override { return faces_; }
  size_t n_edges() const override { return 0; }

  bool bad_index() const { return bad_index_; }
  size_t short_faces() const { return short_faces_; }

 private:
  Soup& s_;
  std::vector<int> corners_;
  size_t faces_ = 0;
  size_t short_faces_ = 0;
  bool bad_index_ = false;
};

}  // namespace

Soup read_with_openmesh(std::string_view bytes, const std::string& ext, const std::string& name,
                        bool binary, std::vector<std::string>& warnings) {
  ::omerr().disable();  // OpenMesh reports on std::cerr; we throw precise errors.
  Soup s;
  SoupImporter importer(s);
  OpenMesh::IO::Options opt;
  if (binary) opt += OpenMesh::IO::Options::Binary;
  std::istringstream in{std::string(bytes)};
  if (!OpenMesh::IO::IOManager().read(in, ext, importer, opt))
    fail(name + ": cannot parse " + ext + " file");
  if (importer.bad_index()) fail(name + ": face with a vertex index out of range");
  if (importer.short_faces() > 0)
    warnings.push_back(name + ": " + plural(importer.short_faces(), "face", "faces") +
                       " with fewer than 3 vertices ignored");
  return s;
}

}  // namespace hdeform::detail
