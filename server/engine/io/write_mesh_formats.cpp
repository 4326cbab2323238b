// Mesh writers: OBJ, OFF, PLY (ASCII) and GLB. See mesh_writers.h.
//
// Text formats print doubles with std::to_chars (shortest representation that reads back to
// the same double, i.e. round-trips exactly like %.17g but stays readable).
// GLB (glb_builder.h): one buffer [POSITION float32 n×3 | NORMAL float32 n×3 | indices uint32
// m×3], three buffer views in that order, one mesh with one TRIANGLES primitive, one node, one
// scene.

#include "engine/io/mesh_writers.h"

#include "engine/io/glb_builder.h"

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <span>
#include <vector>

namespace hdeform::detail {
namespace {

void append_double(std::string& out, double v) {
  char buf[32];
  auto r = std::to_chars(buf, buf + sizeof buf, v);
  out.append(buf, r.ptr);
}
void append_int(std::string& out, long long v) {
  char buf[24];
  auto r = std::to_chars(buf, buf + sizeof buf, v);
  out.append(buf, r.ptr);
}
void append_row(std::string& out, const char* prefix, const Vertices& V, Eigen::Index i) {
  out += prefix;
  for (int k = 0; k < 3; ++k) {
    if (k > 0) out += ' ';
    append_double(out, V(i, k));
  }
}

// The faces to write: each PolygonFan that matches F as one face of its corners, every other
// triangle as itself. `max_corners`: larger polygons are written as their triangles.
class Faces {
 public:
  Faces(const Triangles& F, std::span<const PolygonFan> fans, int max_corners)
      : F_(F), fans_(fans), max_corners_(max_corners) {}
  Eigen::Index count() const {
    Eigen::Index n = F_.rows();
    for (const PolygonFan& p : fans_)
      if (usable(p)) n -= p.corners - 3;
    return n;
  }
  // fn(corners, k) per face, in triangle order.
  template <class Fn>
  void each(Fn&& fn) const {
    std::vector<int> corners;
    std::size_t next = 0;
    for (Eigen::Index t = 0; t < F_.rows();) {
      while (next < fans_.size() && fans_[next].first_triangle < t) ++next;
      if (next < fans_.size() && fans_[next].first_triangle == t && usable(fans_[next])) {
        const int k = fans_[next].corners;
        corners.assign({F_(t, 0), F_(t, 1), F_(t, 2)});
        for (int i = 1; i < k - 2; ++i) corners.push_back(F_(t + i, 2));
        fn(corners.data(), k);
        t += k - 2;
        ++next;
        continue;
      }
      const int tri[3] = {F_(t, 0), F_(t, 1), F_(t, 2)};
      fn(tri, 3);
      ++t;
    }
  }

 private:
  // A fan of F: corners − 2 triangles in range sharing the first corner, each starting where
  // the one before ended; and not over the format's limit.
  bool usable(const PolygonFan& p) const {
    if (p.corners < 4 || p.corners > max_corners_ || p.first_triangle < 0 ||
        p.first_triangle + static_cast<Eigen::Index>(p.corners) - 2 > F_.rows())
      return false;
    const Eigen::Index t = p.first_triangle;
    for (int i = 1; i < p.corners - 2; ++i)
      if (F_(t + i, 0) != F_(t, 0) || F_(t + i, 1) != F_(t + i - 1, 2)) return false;
    return true;
  }

  const Triangles& F_;
  std::span<const PolygonFan> fans_;
  int max_corners_;
};

constexpr int kAnyCorners = 1 << 30, kPlyCorners = 255;  // PLY: a uchar-counted list

// Room for a text mesh: about 60 characters a vertex (120 with normals), 30 a triangle.
void reserve_text(std::string& out, const Vertices& V, const Triangles& F, const Vertices* N) {
  out.reserve(static_cast<size_t>(V.rows()) * (N ? 120 : 60) + static_cast<size_t>(F.rows()) * 30);
}

// The body OFF and ASCII PLY share: a line per vertex ("x y z", then " nx ny nz" with
// normals), then a line per face "k a b c …" (0-based).
void append_vertices_and_faces(std::string& out, const Vertices& V, const Faces& faces,
                               const Vertices* N) {
  for (Eigen::Index i = 0; i < V.rows(); ++i) {
    append_row(out, "", V, i);
    if (N) append_row(out, " ", *N, i);
    out += '\n';
  }
  faces.each([&](const int* c, int k) {
    append_int(out, k);
    for (int i = 0; i < k; ++i) {
      out += ' ';
      append_int(out, c[i]);
    }
    out += '\n';
  });
}

}  // namespace

std::string write_obj(const Vertices& V, const Triangles& F, const Vertices* N,
                      std::span<const PolygonFan> polygons) {
  const Faces faces(F, polygons, kAnyCorners);
  std::string out = "# hdeform\n";
  reserve_text(out, V, F, N);
  for (Eigen::Index i = 0; i < V.rows(); ++i) {
    append_row(out, "v ", V, i);
    out += '\n';
  }
  if (N)
    for (Eigen::Index i = 0; i < N->rows(); ++i) {
      append_row(out, "vn ", *N, i);
      out += '\n';
    }
  faces.each([&](const int* c, int k) {
    out += 'f';
    for (int i = 0; i < k; ++i) {
      out += ' ';
      append_int(out, c[i] + 1LL);
      if (N) {
        out += "//";
        append_int(out, c[i] + 1LL);
      }
    }
    out += '\n';
  });
  return out;
}

std::string write_off(const Vertices& V, const Triangles& F, const Vertices* N,
                      std::span<const PolygonFan> polygons) {
  const Faces faces(F, polygons, kAnyCorners);
  std::string out = N ? "NOFF\n" : "OFF\n";
  reserve_text(out, V, F, N);
  append_int(out, V.rows());
  out += ' ';
  append_int(out, faces.count());
  out += " 0\n";
  append_vertices_and_faces(out, V, faces, N);
  return out;
}

namespace {

// The PLY header both encodings share: doubles per vertex, a uchar-counted int list per face.
void append_ply_header(std::string& out, const char* format, const Vertices& V,
                       const Faces& faces, const Vertices* N) {
  out += "ply\nformat ";
  out += format;
  out += " 1.0\ncomment hdeform\nelement vertex ";
  append_int(out, V.rows());
  out += "\nproperty double x\nproperty double y\nproperty double z\n";
  if (N) out += "property double nx\nproperty double ny\nproperty double nz\n";
  out += "element face ";
  append_int(out, faces.count());
  out += "\nproperty list uchar int vertex_indices\nend_header\n";
}

}  // namespace

std::string write_ply(const Vertices& V, const Triangles& F, const Vertices* N,
                      std::span<const PolygonFan> polygons) {
  const Faces faces(F, polygons, kPlyCorners);
  std::string out;
  reserve_text(out, V, F, N);
  append_ply_header(out, "ascii", V, faces, N);
  append_vertices_and_faces(out, V, faces, N);
  return out;
}

std::string write_ply_binary(const Vertices& V, const Triangles& F, const Vertices* N,
                             std::span<const PolygonFan> polygons) {
  const Faces faces(F, polygons, kPlyCorners);
  std::string out;
  append_ply_header(out, "binary_little_endian", V, faces, N);
  static_assert(std::endian::native == std::endian::little, "binary PLY is written as is");
  const int per_vertex = N ? 6 : 3;
  const std::size_t header = out.size();
  // Faces: a count byte and 4 bytes per corner; a fan's corners are its triangles + 2.
  out.resize(header + static_cast<std::size_t>(V.rows()) * per_vertex * 8 +
             static_cast<std::size_t>(faces.count()) + static_cast<std::size_t>(F.rows()) * 12);
  char* p = out.data() + header;
  for (Eigen::Index i = 0; i < V.rows(); ++i)
    for (int k = 0; k < per_vertex; ++k) {
      const double v = k < 3 ? V(i, k) : (*N)(i, k - 3);
      std::memcpy(p, &v, 8);
      p += 8;
    }
  faces.each([&](const int* c, int k) {
    *p++ = static_cast<char>(k);
    for (int i = 0; i < k; ++i) {
      const std::int32_t idx = c[i];
      std::memcpy(p, &idx, 4);
      p += 4;
    }
  });
  out.resize(static_cast<std::size_t>(p - out.data()));
  return out;
}

std::string write_glb(const Vertices& V, const Triangles& F, const Vertices& N, bool up_z) {
  const size_t n = static_cast<size_t>(V.rows());
  const size_t m = static_cast<size_t>(F.rows());
  GlbBuilder glb(GlbBuilder::ZeroOffset::omitted);
  const size_t pos_at = glb.grow(n * 12), nrm_at = glb.grow(n * 12), ind_at = glb.grow(m * 12);
  float* pos = reinterpret_cast<float*>(glb.data() + pos_at);
  float* nrm = reinterpret_cast<float*>(glb.data() + nrm_at);
  std::vector<double> lo(3, std::numeric_limits<double>::infinity());
  std::vector<double> hi(3, -std::numeric_limits<double>::infinity());
  for (size_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) {
      const float p = static_cast<float>(V(static_cast<Eigen::Index>(i), k));
      pos[3 * i + k] = p;
      nrm[3 * i + k] = static_cast<float>(N(static_cast<Eigen::Index>(i), k));
      lo[k] = std::min(lo[k], static_cast<double>(p));
      hi[k] = std::max(hi[k], static_cast<double>(p));
    }
  uint32_t* ind = reinterpret_cast<uint32_t*>(glb.data() + ind_at);
  for (size_t t = 0; t < m; ++t)
    for (int k = 0; k < 3; ++k) ind[3 * t + k] = static_cast<uint32_t>(F(static_cast<Eigen::Index>(t), k));

  using json = GlbBuilder::json;
  const int position = glb.add_accessor(glb.add_view(pos_at, n * 12, kTargetArrayBuffer),
                                        kComponentFloat, n, "VEC3", n > 0 ? json(lo) : nullptr,
                                        n > 0 ? json(hi) : nullptr);
  const int normal = glb.add_accessor(glb.add_view(nrm_at, n * 12, kTargetArrayBuffer),
                                      kComponentFloat, n, "VEC3");
  const int indices = glb.add_accessor(glb.add_view(ind_at, m * 12, kTargetElementArrayBuffer),
                                       kComponentUnsignedInt, 3 * m, "SCALAR");
  glb.set_mesh(triangles({{"POSITION", position}, {"NORMAL", normal}}, indices), up_z);
  return glb.finish("write_mesh");
}

}  // namespace hdeform::detail
