// Mesh file I/O. See mesh_io.h.
//
// Readers:
// - OBJ, ASCII OFF and PLY (ASCII and binary) are parsed here, line by line: positions keep
//   full double precision (OpenMesh's readers go through float), every face is kept in file
//   order (no halfedge structure that would drop non-manifold faces, so validation can name
//   them), and parse errors name the file and the line ("cube.off:7: expected 3
//   coordinates, found 2").
// - STL and binary OFF go through OpenMesh's IO layer (IOManager) with our own importer
//   (SoupImporter), which records the raw polygon soup and builds no connectivity. OpenMesh's
//   STL reader merges corners with identical positions into one vertex.
// - glTF/GLB through tinygltf. Decision: primitives are taken as-is, in mesh-local
//   coordinates; node transforms are NOT applied (a warning says so when a node carries a
//   non-identity transform). The deformed positions then map straight back into the file's
//   own vertex buffers. All triangle primitives (TRIANGLES, TRIANGLE_STRIP, TRIANGLE_FAN) of
//   all meshes are used, in order meshes[i].primitives[j]; points and lines are skipped with
//   a warning. The input vertex layout is the concatenation of the distinct POSITION
//   accessors in first-use order (primitives sharing an accessor share its vertices).
//   Vertices with bit-identical positions (−0 = +0) are welded into one engine vertex, in
//   order of first occurrence: glTF splits vertices at UV/normal seams, the engine needs one
//   connected surface.
//
// Writers: text formats print doubles with std::to_chars (shortest representation that
// reads back to the same double, i.e. round-trips exactly like %.17g but stays readable).
// GLB: one buffer [POSITION float32 n×3 | NORMAL float32 n×3 | indices uint32 m×3], three
// buffer views in that order, one mesh with one TRIANGLES primitive, one node, one scene.

#include "mesh_io.h"

#include <Eigen/Geometry>

#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/IO/importer/BaseImporter.hh>
#include <OpenMesh/Core/System/omstream.hh>
#include <tiny_gltf.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <unordered_map>
#include <utility>

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
  for (size_t i = 0; i < input_to_engine.size(); ++i)
    out.row(static_cast<Eigen::Index>(i)) = engine_positions.row(input_to_engine[i]);
  return out;
}

namespace {

[[noreturn]] void fail(const std::string& msg) { throw InvalidInput(msg); }

[[noreturn]] void fail_line(const std::string& name, int line, const std::string& msg) {
  fail(name + ":" + std::to_string(line) + ": " + msg);
}

std::string lower_extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  if (!ext.empty() && ext[0] == '.') ext.erase(0, 1);
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

std::string plural(size_t n, const char* one, const char* many) {
  return std::to_string(n) + " " + (n == 1 ? one : many);
}

// ---------------------------------------------------------------------------------------
// Polygon soup: what every reader produces before it becomes a LoadedMesh.
struct Soup {
  std::vector<double> xyz;  // 3 per vertex
  std::vector<int> tri;     // 3 per triangle
  size_t polygons = 0;      // faces with more than 3 corners (fan-triangulated)

  int num_vertices() const { return static_cast<int>(xyz.size() / 3); }
  void add_vertex(double x, double y, double z) {
    xyz.push_back(x);
    xyz.push_back(y);
    xyz.push_back(z);
  }
  // Fan triangulation around the first corner.
  void add_polygon(const int* idx, size_t k) {
    if (k > 3) ++polygons;
    for (size_t c = 1; c + 1 < k; ++c) {
      tri.push_back(idx[0]);
      tri.push_back(idx[c]);
      tri.push_back(idx[c + 1]);
    }
  }
};

LoadedMesh to_loaded(Soup&& s, const std::string& name) {
  LoadedMesh out;
  const Eigen::Index n = s.num_vertices();
  const Eigen::Index m = static_cast<Eigen::Index>(s.tri.size() / 3);
  out.mesh.V = Eigen::Map<const Vertices>(s.xyz.data(), n, 3);
  out.mesh.F = Eigen::Map<const Triangles>(s.tri.data(), m, 3);
  out.input_to_engine.resize(static_cast<size_t>(n));
  for (Eigen::Index i = 0; i < n; ++i) out.input_to_engine[static_cast<size_t>(i)] = static_cast<int>(i);
  out.input_triangles = out.mesh.F;
  if (s.polygons > 0)
    out.warnings.push_back(name + ": " + plural(s.polygons, "polygon", "polygons") +
                           " with more than 3 vertices triangulated (fan)");
  return out;
}

// ---------------------------------------------------------------------------------------
// Line and token helpers for the text formats.
class Lines {
 public:
  explicit Lines(std::string_view s) : s_(s) {}
  bool next(std::string_view& line) {
    if (pos_ >= s_.size()) return false;
    size_t e = s_.find('\n', pos_);
    if (e == std::string_view::npos) e = s_.size();
    line = s_.substr(pos_, e - pos_);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    pos_ = e + 1;
    ++lineno_;
    return true;
  }
  int lineno() const { return lineno_; }
  size_t pos() const { return pos_; }

 private:
  std::string_view s_;
  size_t pos_ = 0;
  int lineno_ = 0;
};

inline bool is_space(char c) { return c == ' ' || c == '\t' || c == '\v' || c == '\f' || c == '\r'; }

struct Cursor {
  const char* p;
  const char* e;
  explicit Cursor(std::string_view s) : p(s.data()), e(s.data() + s.size()) {}
  void skip_ws() {
    while (p < e && is_space(*p)) ++p;
  }
  bool at_end() {
    skip_ws();
    return p == e;
  }
  std::string_view token() {
    skip_ws();
    const char* b = p;
    while (p < e && !is_space(*p)) ++p;
    return {b, static_cast<size_t>(p - b)};
  }
  std::string_view peek_token() {
    Cursor c = *this;
    return c.token();
  }
  // A whole whitespace-delimited token that is a number.
  bool read_double(double& v) {
    skip_ws();
    const char* q = p;
    if (q < e && *q == '+') ++q;
    auto r = std::from_chars(q, e, v);
    if (r.ec != std::errc() || (r.ptr < e && !is_space(*r.ptr))) return false;
    p = r.ptr;
    return true;
  }
  bool read_int(long long& v) {
    skip_ws();
    const char* q = p;
    if (q < e && *q == '+') ++q;
    auto r = std::from_chars(q, e, v);
    if (r.ec != std::errc() || (r.ptr < e && !is_space(*r.ptr))) return false;
    p = r.ptr;
    return true;
  }
};

std::string quoted(std::string_view t) {
  // Appends, not operator+: GCC 12 -O3 gives a false -Wrestrict on "'" + std::string(...).
  std::string q;
  q.reserve(t.size() + 8);
  q += '\'';
  q.append(t.substr(0, 40));
  if (t.size() > 40) q += "…";
  q += '\'';
  return q;
}

// Reads 3 coordinates from `c`, or throws "NAME:LINE: expected 3 coordinates ...".
void read_xyz(Cursor& c, const std::string& name, int line, double out[3]) {
  for (int k = 0; k < 3; ++k) {
    if (c.at_end())
      fail_line(name, line, "expected 3 coordinates, found " + std::to_string(k));
    if (!c.read_double(out[k])) fail_line(name, line, "bad coordinate " + quoted(c.peek_token()));
  }
}

// ---------------------------------------------------------------------------------------
// OBJ: v, f (with v/vt/vn corners, negative = relative indices); everything else ignored.
Soup parse_obj(std::string_view text, const std::string& name, std::vector<std::string>& warnings) {
  Soup s;
  Lines lines(text);
  std::string_view line;
  std::vector<int> corners;
  std::vector<std::pair<long long, int>> forward;  // (0-based index, line) ≥ count at the time
  size_t lines_points = 0;
  while (lines.next(line)) {
    const int ln = lines.lineno();
    if (size_t h = line.find('#'); h != std::string_view::npos) line = line.substr(0, h);
    Cursor c(line);
    std::string_view kw = c.token();
    if (kw.empty()) continue;
    if (kw == "v") {
      double x[3];
      read_xyz(c, name, ln, x);
      s.add_vertex(x[0], x[1], x[2]);
    } else if (kw == "f") {
      corners.clear();
      while (!c.at_end()) {
        std::string_view tok = c.token();
        std::string_view vtok = tok.substr(0, tok.find('/'));
        long long idx = 0;
        const char* b = vtok.data();
        const char* e = b + vtok.size();
        if (b < e && *b == '+') ++b;
        auto r = std::from_chars(b, e, idx);
        if (vtok.empty() || r.ec != std::errc() || r.ptr != e)
          fail_line(name, ln, "bad face corner " + quoted(tok));
        const long long nv = s.num_vertices();
        long long zero_based;
        if (idx > 0) {
          zero_based = idx - 1;
        } else if (idx < 0) {
          zero_based = nv + idx;
          if (zero_based < 0)
            fail_line(name, ln, "relative vertex index " + std::to_string(idx) + " but only " +
                                    plural(static_cast<size_t>(nv), "vertex", "vertices") +
                                    " so far");
        } else {
          fail_line(name, ln, "vertex index 0 (OBJ indices start at 1)");
        }
        if (zero_based > std::numeric_limits<int>::max() - 1)
          fail_line(name, ln, "vertex index " + std::to_string(idx) + " too large");
        if (zero_based >= nv) forward.emplace_back(zero_based, ln);
        corners.push_back(static_cast<int>(zero_based));
      }
      if (corners.size() < 3)
        fail_line(name, ln, "face with " + std::to_string(corners.size()) +
                                " vertices (need at least 3)");
      s.add_polygon(corners.data(), corners.size());
    } else if (kw == "l" || kw == "p") {
      ++lines_points;
    }
  }
  for (const auto& [idx, ln] : forward)
    if (idx >= s.num_vertices())
      fail_line(name, ln, "vertex index " + std::to_string(idx + 1) + " out of range (file has " +
                              plural(static_cast<size_t>(s.num_vertices()), "vertex", "vertices") + ")");
  if (lines_points > 0)
    warnings.push_back(name + ": " + plural(lines_points, "line/point element", "line/point elements") +
                       " ignored");
  return s;
}

// ---------------------------------------------------------------------------------------
// OpenMesh IO layer with an importer that records the raw soup.
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

// ---------------------------------------------------------------------------------------
// OFF: [ST][C][N]OFF header, counts, one vertex per line, one face per line (k i1 .. ik
// [colour]). "OFF BINARY" goes to OpenMesh.
Soup parse_off(std::string_view text, const std::string& name, std::vector<std::string>& warnings) {
  Lines lines(text);
  std::string_view line;
  // Next line with content (comments and blank lines skipped); false at end of file.
  auto next_content = [&](Cursor& c) {
    while (lines.next(line)) {
      if (size_t h = line.find('#'); h != std::string_view::npos) line = line.substr(0, h);
      c = Cursor(line);
      if (!c.at_end()) return true;
    }
    return false;
  };
  Cursor c{std::string_view{}};
  if (!next_content(c)) fail(name + ": empty OFF file");
  std::string_view head = c.token();
  const int head_line = lines.lineno();
  if (head.size() < 3 || head.substr(head.size() - 3) != "OFF")
    fail_line(name, head_line, "not an OFF file (header " + quoted(head) + ")");
  std::string_view prefix = head.substr(0, head.size() - 3);
  if (prefix.find('4') != std::string_view::npos || prefix.find('n') != std::string_view::npos)
    fail_line(name, head_line, "unsupported OFF variant " + quoted(head) + " (need 3D vertices)");
  if (c.peek_token() == "BINARY") return read_with_openmesh(text, "off", name, true, warnings);
  if (c.at_end() && !next_content(c))
    fail_line(name, lines.lineno(), "missing vertex and face counts");
  long long nv = 0, nf = 0;
  const int count_line = lines.lineno();
  if (!c.read_int(nv) || !c.read_int(nf) || nv < 0 || nf < 0)
    fail_line(name, count_line, "expected vertex and face counts");
  if (nv > std::numeric_limits<int>::max() / 3 || nf > std::numeric_limits<int>::max() / 3)
    fail_line(name, count_line, "counts too large");

  Soup s;
  s.xyz.reserve(static_cast<size_t>(nv) * 3);
  s.tri.reserve(static_cast<size_t>(nf) * 3);
  for (long long i = 0; i < nv; ++i) {
    if (!next_content(c))
      fail_line(name, lines.lineno(), "unexpected end of file: expected " +
                                          plural(static_cast<size_t>(nv), "vertex", "vertices") +
                                          ", found " + std::to_string(i));
    double x[3];
    read_xyz(c, name, lines.lineno(), x);
    s.add_vertex(x[0], x[1], x[2]);
  }
  std::vector<int> corners;
  for (long long f = 0; f < nf; ++f) {
    if (!next_content(c))
      fail_line(name, lines.lineno(), "unexpected end of file: expected " +
                                          plural(static_cast<size_t>(nf), "face", "faces") +
                                          ", found " + std::to_string(f));
    const int ln = lines.lineno();
    long long k = 0;
    if (!c.read_int(k)) fail_line(name, ln, "bad face vertex count " + quoted(c.peek_token()));
    if (k < 3) fail_line(name, ln, "face with " + std::to_string(k) + " vertices (need at least 3)");
    corners.clear();
    for (long long j = 0; j < k; ++j) {
      long long idx = 0;
      if (c.at_end())
        fail_line(name, ln, "expected " + std::to_string(k) + " vertex indices, found " +
                                std::to_string(j));
      if (!c.read_int(idx)) fail_line(name, ln, "bad vertex index " + quoted(c.peek_token()));
      if (idx < 0 || idx >= nv)
        fail_line(name, ln, "vertex index " + std::to_string(idx) + " out of range (file has " +
                                plural(static_cast<size_t>(nv), "vertex", "vertices") + ")");
      corners.push_back(static_cast<int>(idx));
    }
    s.add_polygon(corners.data(), corners.size());  // anything after the indices: colour
  }
  return s;
}

// ---------------------------------------------------------------------------------------
// PLY (ascii, binary_little_endian, binary_big_endian): vertex x y z, face vertex_indices.
enum class PlyType { i8, u8, i16, u16, i32, u32, f32, f64, invalid };

PlyType ply_type(std::string_view t) {
  if (t == "char" || t == "int8") return PlyType::i8;
  if (t == "uchar" || t == "uint8") return PlyType::u8;
  if (t == "short" || t == "int16") return PlyType::i16;
  if (t == "ushort" || t == "uint16") return PlyType::u16;
  if (t == "int" || t == "int32") return PlyType::i32;
  if (t == "uint" || t == "uint32") return PlyType::u32;
  if (t == "float" || t == "float32") return PlyType::f32;
  if (t == "double" || t == "float64") return PlyType::f64;
  return PlyType::invalid;
}

size_t ply_size(PlyType t) {
  switch (t) {
    case PlyType::i8: case PlyType::u8: return 1;
    case PlyType::i16: case PlyType::u16: return 2;
    case PlyType::i32: case PlyType::u32: case PlyType::f32: return 4;
    case PlyType::f64: return 8;
    default: return 0;
  }
}

struct PlyProperty {
  std::string name;
  PlyType type = PlyType::invalid;       // value type
  PlyType count_type = PlyType::invalid; // list length type, invalid = scalar
};

struct PlyElement {
  std::string name;
  long long count = 0;
  int line = 0;
  std::vector<PlyProperty> props;
};

template <class T>
T load_raw(const unsigned char* p, bool swap) {
  unsigned char b[sizeof(T)];
  std::memcpy(b, p, sizeof(T));
  if (swap) std::reverse(b, b + sizeof(T));
  T v;
  std::memcpy(&v, b, sizeof(T));
  return v;
}

double load_ply_value(const unsigned char* p, PlyType t, bool swap) {
  switch (t) {
    case PlyType::i8: return static_cast<double>(static_cast<int8_t>(*p));
    case PlyType::u8: return static_cast<double>(*p);
    case PlyType::i16: return load_raw<int16_t>(p, swap);
    case PlyType::u16: return load_raw<uint16_t>(p, swap);
    case PlyType::i32: return load_raw<int32_t>(p, swap);
    case PlyType::u32: return load_raw<uint32_t>(p, swap);
    case PlyType::f32: return load_raw<float>(p, swap);
    case PlyType::f64: return load_raw<double>(p, swap);
    default: return 0;
  }
}

Soup parse_ply(std::string_view bytes, const std::string& name) {
  Lines lines(bytes);
  std::string_view line;
  if (!lines.next(line) || line != "ply") fail(name + ":1: not a PLY file (missing 'ply' header)");
  enum class Fmt { ascii, le, be } fmt = Fmt::ascii;
  bool have_format = false;
  std::vector<PlyElement> elements;
  bool ended = false;
  while (lines.next(line)) {
    const int ln = lines.lineno();
    Cursor c(line);
    std::string_view kw = c.token();
    if (kw.empty() || kw == "comment" || kw == "obj_info") continue;
    if (kw == "format") {
      std::string_view f = c.token();
      if (f == "ascii") fmt = Fmt::ascii;
      else if (f == "binary_little_endian") fmt = Fmt::le;
      else if (f == "binary_big_endian") fmt = Fmt::be;
      else fail_line(name, ln, "unknown PLY format " + quoted(f));
      have_format = true;
    } else if (kw == "element") {
      PlyElement el;
      el.name = std::string(c.token());
      el.line = ln;
      if (el.name.empty() || !c.read_int(el.count) || el.count < 0)
        fail_line(name, ln, "expected 'element NAME COUNT'");
      elements.push_back(std::move(el));
    } else if (kw == "property") {
      if (elements.empty()) fail_line(name, ln, "property before any element");
      PlyProperty p;
      std::string_view t = c.token();
      if (t == "list") {
        std::string_view ct = c.token();
        p.count_type = ply_type(ct);
        if (p.count_type == PlyType::invalid || p.count_type == PlyType::f32 ||
            p.count_type == PlyType::f64)
          fail_line(name, ln, "bad list count type " + quoted(ct));
        t = c.token();
      }
      p.type = ply_type(t);
      if (p.type == PlyType::invalid) fail_line(name, ln, "unknown property type " + quoted(t));
      p.name = std::string(c.token());
      if (p.name.empty()) fail_line(name, ln, "property without a name");
      elements.back().props.push_back(std::move(p));
    } else if (kw == "end_header") {
      ended = true;
      break;
    } else {
      fail_line(name, ln, "unknown header keyword " + quoted(kw));
    }
  }
  if (!ended) fail(name + ": PLY header without 'end_header'");
  if (!have_format) fail(name + ": PLY header without 'format'");

  // Where x, y, z and the face index list are.
  Soup s;
  long long nv = -1;
  for (const PlyElement& el : elements) {
    if (el.name == "vertex") {
      int found = 0;
      for (const char* axis : {"x", "y", "z"})
        for (const auto& p : el.props)
          if (p.name == axis) {
            if (p.count_type != PlyType::invalid)
              fail_line(name, el.line, std::string("vertex property ") + axis + " is a list");
            ++found;
          }
      if (found != 3) fail_line(name, el.line, "vertex element without x, y, z properties");
      nv = el.count;
    }
  }
  if (nv < 0) fail(name + ": PLY file without a vertex element");
  if (nv > std::numeric_limits<int>::max() / 3) fail(name + ": too many vertices");
  s.xyz.reserve(static_cast<size_t>(nv) * 3);

  auto axis_of = [](const std::string& n) { return n == "x" ? 0 : n == "y" ? 1 : n == "z" ? 2 : -1; };
  auto is_face_list = [](const PlyElement& el, const PlyProperty& p) {
    return el.name == "face" && p.count_type != PlyType::invalid &&
           (p.name == "vertex_indices" || p.name == "vertex_index");
  };
  std::vector<int> corners;
  auto add_corner = [&](double v, int ln, bool& ok) {
    if (!(v >= 0 && v < static_cast<double>(nv)) || v != std::floor(v)) {
      ok = false;
      if (ln > 0)
        fail_line(name, ln, "vertex index " + std::to_string(static_cast<long long>(v)) +
                                " out of range (file has " +
                                plural(static_cast<size_t>(nv), "vertex", "vertices") + ")");
      return;
    }
    corners.push_back(static_cast<int>(v));
  };
  auto finish_face = [&](int ln, long long face_no) {
    if (corners.size() < 3) {
      std::string where = ln > 0 ? name + ":" + std::to_string(ln) + ": " : name + ": face " + std::to_string(face_no) + ": ";
      fail(where + "face with " + std::to_string(corners.size()) + " vertices (need at least 3)");
    }
    s.add_polygon(corners.data(), corners.size());
  };

  if (fmt == Fmt::ascii) {
    for (const PlyElement& el : elements) {
      for (long long i = 0; i < el.count; ++i) {
        Cursor c{std::string_view{}};
        do {
          if (!lines.next(line))
            fail_line(name, lines.lineno(), "unexpected end of file: expected " +
                                                std::to_string(el.count) + " " + el.name +
                                                " elements, found " + std::to_string(i));
          c = Cursor(line);
        } while (c.at_end());
        const int ln = lines.lineno();
        double xyz[3] = {0, 0, 0};
        corners.clear();
        bool has_list = false;
        for (const PlyProperty& p : el.props) {
          if (p.count_type != PlyType::invalid) {
            long long k = 0;
            if (!c.read_int(k) || k < 0)
              fail_line(name, ln, "bad list length " + quoted(c.peek_token()) + " for " + p.name);
            const bool face_list = is_face_list(el, p);
            for (long long j = 0; j < k; ++j) {
              double v;
              if (c.at_end())
                fail_line(name, ln, "expected " + std::to_string(k) + " values for " + p.name +
                                        ", found " + std::to_string(j));
              if (!c.read_double(v)) fail_line(name, ln, "bad number " + quoted(c.peek_token()));
              if (face_list) {
                bool ok = true;
                add_corner(v, ln, ok);
              }
            }
            if (face_list) has_list = true;
          } else {
            double v;
            if (c.at_end()) fail_line(name, ln, "missing value for property " + p.name);
            if (!c.read_double(v)) fail_line(name, ln, "bad number " + quoted(c.peek_token()) + " for " + p.name);
            if (el.name == "vertex") {
              int a = axis_of(p.name);
              if (a >= 0) xyz[a] = v;
            }
          }
        }
        if (el.name == "vertex") s.add_vertex(xyz[0], xyz[1], xyz[2]);
        if (has_list) finish_face(ln, i);
      }
    }
  } else {
    const bool swap = (fmt == Fmt::le) != (std::endian::native == std::endian::little);
    const auto* p = reinterpret_cast<const unsigned char*>(bytes.data()) + std::min(lines.pos(), bytes.size());
    const auto* end = reinterpret_cast<const unsigned char*>(bytes.data()) + bytes.size();
    auto need = [&](size_t k, const PlyElement& el, long long i) {
      if (static_cast<size_t>(end - p) < k)
        fail(name + ": unexpected end of binary data in " + el.name + " element " +
             std::to_string(i) + " of " + std::to_string(el.count));
    };
    for (const PlyElement& el : elements) {
      for (long long i = 0; i < el.count; ++i) {
        double xyz[3] = {0, 0, 0};
        corners.clear();
        bool has_list = false;
        for (const PlyProperty& pr : el.props) {
          if (pr.count_type != PlyType::invalid) {
            need(ply_size(pr.count_type), el, i);
            const double kd = load_ply_value(p, pr.count_type, swap);
            p += ply_size(pr.count_type);
            if (kd < 0) fail(name + ": negative list length in " + el.name + " element " + std::to_string(i));
            const size_t k = static_cast<size_t>(kd);
            need(k * ply_size(pr.type), el, i);
            const bool face_list = is_face_list(el, pr);
            for (size_t j = 0; j < k; ++j, p += ply_size(pr.type)) {
              if (!face_list) continue;
              const double v = load_ply_value(p, pr.type, swap);
              bool ok = true;
              add_corner(v, 0, ok);
              if (!ok)
                fail(name + ": face " + std::to_string(i) + ": vertex index " +
                     std::to_string(static_cast<long long>(v)) + " out of range (file has " +
                     plural(static_cast<size_t>(nv), "vertex", "vertices") + ")");
            }
            if (face_list) has_list = true;
          } else {
            need(ply_size(pr.type), el, i);
            if (el.name == "vertex") {
              int a = axis_of(pr.name);
              if (a >= 0) xyz[a] = load_ply_value(p, pr.type, swap);
            }
            p += ply_size(pr.type);
          }
        }
        if (el.name == "vertex") s.add_vertex(xyz[0], xyz[1], xyz[2]);
        if (has_list) finish_face(0, i);
      }
    }
  }
  return s;
}

// ---------------------------------------------------------------------------------------
// glTF / GLB.
bool skip_image(tinygltf::Image*, const int, std::string*, std::string*, int, int,
                const unsigned char*, int, void*) {
  return true;  // geometry only: never decode textures
}

bool no_file_exists(const std::string&, void*) { return false; }
std::string no_expand(const std::string& p, void*) { return p; }
bool no_read(std::vector<unsigned char>*, std::string* err, const std::string& path, void*) {
  if (err) *err += "external file '" + path + "' not allowed for an in-memory glTF (embed buffers or use GLB)\n";
  return false;
}
bool no_write(std::string* err, const std::string&, const std::vector<unsigned char>&, void*) {
  if (err) *err += "writing files is disabled\n";
  return false;
}

std::string trim(std::string s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.pop_back();
  size_t b = 0;
  while (b < s.size() && std::isspace(static_cast<unsigned char>(s[b]))) ++b;
  return s.substr(b);
}

// Start of element 0 and the stride; validates the accessor lies inside its buffer.
const unsigned char* accessor_data(const tinygltf::Model& model, const tinygltf::Accessor& acc,
                                   const std::string& what, size_t& stride) {
  if (acc.sparse.isSparse) fail(what + ": sparse accessors are not supported");
  if (acc.bufferView < 0 || acc.bufferView >= static_cast<int>(model.bufferViews.size()))
    fail(what + ": accessor without a valid bufferView");
  const tinygltf::BufferView& bv = model.bufferViews[static_cast<size_t>(acc.bufferView)];
  if (bv.buffer < 0 || bv.buffer >= static_cast<int>(model.buffers.size()))
    fail(what + ": bufferView without a valid buffer");
  const tinygltf::Buffer& buf = model.buffers[static_cast<size_t>(bv.buffer)];
  const int s = acc.ByteStride(bv);
  if (s <= 0) fail(what + ": invalid byte stride");
  stride = static_cast<size_t>(s);
  const size_t elem = static_cast<size_t>(tinygltf::GetComponentSizeInBytes(static_cast<uint32_t>(acc.componentType))) *
                      static_cast<size_t>(tinygltf::GetNumComponentsInType(static_cast<uint32_t>(acc.type)));
  const size_t begin = bv.byteOffset + acc.byteOffset;
  const size_t need = acc.count == 0 ? 0 : stride * (acc.count - 1) + elem;
  if (begin + need > bv.byteOffset + bv.byteLength || bv.byteOffset + bv.byteLength > buf.data.size())
    fail(what + ": accessor reads past the end of its buffer");
  return buf.data.data() + begin;
}

bool node_has_transform(const tinygltf::Node& n) {
  if (!n.matrix.empty()) {
    for (size_t i = 0; i < n.matrix.size(); ++i)
      if (n.matrix[i] != ((i % 5 == 0) ? 1.0 : 0.0)) return true;
  }
  if (!n.translation.empty() && (n.translation[0] != 0 || n.translation[1] != 0 || n.translation[2] != 0)) return true;
  if (!n.scale.empty() && (n.scale[0] != 1 || n.scale[1] != 1 || n.scale[2] != 1)) return true;
  if (n.rotation.size() == 4 && (n.rotation[0] != 0 || n.rotation[1] != 0 || n.rotation[2] != 0)) return true;
  return false;
}

struct PosKey {
  std::array<uint64_t, 3> b;
  bool operator==(const PosKey&) const = default;
};
struct PosKeyHash {
  size_t operator()(const PosKey& k) const {
    uint64_t h = k.b[0] * 0x9E3779B97F4A7C15ULL;
    h ^= (k.b[1] + 0x632BE59BD9B4E019ULL + (h << 6) + (h >> 2));
    h ^= (k.b[2] * 0xC2B2AE3D27D4EB4FULL + (h << 6) + (h >> 2));
    return static_cast<size_t>(h ^ (h >> 29));
  }
};

LoadedMesh read_gltf(std::string_view bytes, const std::string& name, bool binary,
                     const std::string* base_dir) {
  tinygltf::TinyGLTF loader;
  loader.SetImageLoader(skip_image, nullptr);
  if (!base_dir) loader.SetFsCallbacks({no_file_exists, no_expand, no_read, no_write, nullptr});
  tinygltf::Model model;
  std::string err, warn;
  if (bytes.size() > std::numeric_limits<unsigned int>::max()) fail(name + ": file too large");
  const bool ok =
      binary ? loader.LoadBinaryFromMemory(&model, &err, &warn,
                                           reinterpret_cast<const unsigned char*>(bytes.data()),
                                           static_cast<unsigned int>(bytes.size()),
                                           base_dir ? *base_dir : std::string())
             : loader.LoadASCIIFromString(&model, &err, &warn, bytes.data(),
                                          static_cast<unsigned int>(bytes.size()),
                                          base_dir ? *base_dir : std::string());
  if (!ok) fail(name + ": invalid " + (binary ? "GLB" : "glTF") + ": " + trim(err.empty() ? warn : err));

  LoadedMesh out;
  std::vector<double> input_xyz;               // input layout positions
  std::vector<int> input_tri;                  // input vertex ids
  std::unordered_map<int, int> accessor_base;  // POSITION accessor → first input vertex
  size_t skipped = 0;
  for (size_t mi = 0; mi < model.meshes.size(); ++mi) {
    const tinygltf::Mesh& mesh = model.meshes[mi];
    for (size_t pi = 0; pi < mesh.primitives.size(); ++pi) {
      const tinygltf::Primitive& prim = mesh.primitives[pi];
      const std::string what = name + ": mesh " + std::to_string(mi) + " primitive " + std::to_string(pi);
      const int mode = prim.mode < 0 ? TINYGLTF_MODE_TRIANGLES : prim.mode;
      if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP &&
          mode != TINYGLTF_MODE_TRIANGLE_FAN) {
        ++skipped;
        continue;
      }
      auto it = prim.attributes.find("POSITION");
      if (it == prim.attributes.end()) fail(what + ": no POSITION attribute");
      if (it->second < 0 || it->second >= static_cast<int>(model.accessors.size()))
        fail(what + ": POSITION accessor " + std::to_string(it->second) + " does not exist");
      const tinygltf::Accessor& pacc = model.accessors[static_cast<size_t>(it->second)];
      if (pacc.type != TINYGLTF_TYPE_VEC3 || pacc.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT)
        fail(what + ": POSITION must be a float VEC3 accessor");
      const size_t count = pacc.count;
      auto [bit, fresh] = accessor_base.try_emplace(it->second, static_cast<int>(input_xyz.size() / 3));
      const int base = bit->second;
      if (fresh) {
        size_t stride = 0;
        const unsigned char* d = accessor_data(model, pacc, what + " POSITION", stride);
        if (input_xyz.size() / 3 + count > static_cast<size_t>(std::numeric_limits<int>::max()))
          fail(what + ": too many vertices");
        for (size_t v = 0; v < count; ++v) {
          float f[3];
          std::memcpy(f, d + v * stride, sizeof f);
          for (float x : f) input_xyz.push_back(static_cast<double>(x));
        }
      }
      // Index list (or implicit 0..count-1).
      std::vector<uint32_t> idx;
      if (prim.indices >= 0) {
        if (prim.indices >= static_cast<int>(model.accessors.size()))
          fail(what + ": indices accessor " + std::to_string(prim.indices) + " does not exist");
        const tinygltf::Accessor& iacc = model.accessors[static_cast<size_t>(prim.indices)];
        if (iacc.type != TINYGLTF_TYPE_SCALAR) fail(what + ": indices must be SCALAR");
        size_t stride = 0;
        const unsigned char* d = accessor_data(model, iacc, what + " indices", stride);
        idx.resize(iacc.count);
        for (size_t k = 0; k < iacc.count; ++k) {
          const unsigned char* q = d + k * stride;
          switch (iacc.componentType) {
            case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: idx[k] = *q; break;
            case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: idx[k] = load_raw<uint16_t>(q, false); break;
            case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: idx[k] = load_raw<uint32_t>(q, false); break;
            default: fail(what + ": indices must be unsigned byte, short or int");
          }
          if (idx[k] >= count)
            fail(what + ": index " + std::to_string(idx[k]) + " out of range (" +
                 plural(count, "vertex", "vertices") + ")");
        }
      } else {
        idx.resize(count);
        for (size_t k = 0; k < count; ++k) idx[k] = static_cast<uint32_t>(k);
      }
      auto push = [&](uint32_t a, uint32_t b, uint32_t c) {
        input_tri.push_back(base + static_cast<int>(a));
        input_tri.push_back(base + static_cast<int>(b));
        input_tri.push_back(base + static_cast<int>(c));
      };
      if (mode == TINYGLTF_MODE_TRIANGLES) {
        if (idx.size() % 3 != 0)
          out.warnings.push_back(what + ": " + std::to_string(idx.size()) +
                                 " indices is not a multiple of 3; the rest is ignored");
        for (size_t k = 0; k + 2 < idx.size(); k += 3) push(idx[k], idx[k + 1], idx[k + 2]);
      } else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
        for (size_t k = 0; k + 2 < idx.size(); ++k) {
          if (k % 2 == 0) push(idx[k], idx[k + 1], idx[k + 2]);
          else push(idx[k + 1], idx[k], idx[k + 2]);
        }
      } else {
        for (size_t k = 1; k + 1 < idx.size(); ++k) push(idx[0], idx[k], idx[k + 1]);
      }
    }
  }
  if (skipped > 0)
    out.warnings.push_back(name + ": " + plural(skipped, "point/line primitive", "point/line primitives") +
                           " skipped");
  for (const tinygltf::Node& n : model.nodes)
    if (n.mesh >= 0 && node_has_transform(n)) {
      out.warnings.push_back(name + ": node transforms are ignored; the mesh is deformed in its own (mesh-local) coordinates");
      break;
    }

  // Weld bit-identical positions, engine ids in order of first occurrence.
  const size_t n_in = input_xyz.size() / 3;
  out.input_to_engine.resize(n_in);
  std::unordered_map<PosKey, int, PosKeyHash> ids;
  ids.reserve(n_in);
  std::vector<double> engine_xyz;
  engine_xyz.reserve(input_xyz.size());
  for (size_t v = 0; v < n_in; ++v) {
    PosKey key;
    for (int k = 0; k < 3; ++k) {
      double x = input_xyz[3 * v + k];
      if (x == 0) x = 0;  // −0 and +0 weld
      key.b[k] = std::bit_cast<uint64_t>(x);
    }
    auto [it, fresh] = ids.try_emplace(key, static_cast<int>(engine_xyz.size() / 3));
    if (fresh)
      for (int k = 0; k < 3; ++k) engine_xyz.push_back(input_xyz[3 * v + k]);
    out.input_to_engine[v] = it->second;
  }
  const Eigen::Index m = static_cast<Eigen::Index>(input_tri.size() / 3);
  out.input_triangles = Eigen::Map<const Triangles>(input_tri.data(), m, 3);
  out.mesh.V = Eigen::Map<const Vertices>(engine_xyz.data(), static_cast<Eigen::Index>(engine_xyz.size() / 3), 3);
  out.mesh.F.resize(m, 3);
  for (Eigen::Index t = 0; t < m; ++t)
    for (int k = 0; k < 3; ++k) out.mesh.F(t, k) = out.input_to_engine[static_cast<size_t>(input_tri[3 * t + k])];
  if (static_cast<size_t>(out.mesh.num_vertices()) < n_in)
    out.warnings.push_back(name + ": welded " + std::to_string(n_in) + " glTF vertices with identical positions into " +
                           std::to_string(out.mesh.num_vertices()));
  return out;
}

LoadedMesh read_any(std::string_view bytes, const std::string& name, const std::string* base_dir) {
  const std::string ext = lower_extension(name);
  if (ext != "obj" && ext != "off" && ext != "ply" && ext != "stl" && ext != "gltf" && ext != "glb")
    fail(name + ": unknown mesh format " + (ext.empty() ? std::string("(no extension)") : "'." + ext + "'") +
         " (expected .obj, .off, .ply, .stl, .gltf or .glb)");
  if (bytes.empty()) fail(name + ": empty file");
  std::vector<std::string> warnings;
  LoadedMesh out;
  if (ext == "gltf" || ext == "glb") {
    out = read_gltf(bytes, name, ext == "glb", base_dir);
  } else {
    Soup s;
    if (ext == "obj") {
      s = parse_obj(bytes, name, warnings);
    } else if (ext == "off") {
      s = parse_off(bytes, name, warnings);
    } else if (ext == "ply") {
      s = parse_ply(bytes, name);
    } else {
      // Binary STL: 80-byte header, uint32 count, 50 bytes per triangle.
      bool binary = false;
      if (bytes.size() >= 84) {
        const uint32_t n = load_raw<uint32_t>(reinterpret_cast<const unsigned char*>(bytes.data()) + 80,
                                              std::endian::native != std::endian::little);
        binary = bytes.size() == 84 + 50 * static_cast<uint64_t>(n);
      }
      s = read_with_openmesh(bytes, "stl", name, binary, warnings);
    }
    out = to_loaded(std::move(s), name);
  }
  out.warnings.insert(out.warnings.begin(), warnings.begin(), warnings.end());
  return out;
}

// ---------------------------------------------------------------------------------------
// Writers.
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

std::string write_obj(const Vertices& V, const Triangles& F, const Vertices* N) {
  std::string out = "# hdeform\n";
  out.reserve(static_cast<size_t>(V.rows()) * (N ? 120 : 60) + static_cast<size_t>(F.rows()) * 30);
  for (Eigen::Index i = 0; i < V.rows(); ++i) {
    append_row(out, "v ", V, i);
    out += '\n';
  }
  if (N)
    for (Eigen::Index i = 0; i < N->rows(); ++i) {
      append_row(out, "vn ", *N, i);
      out += '\n';
    }
  for (Eigen::Index t = 0; t < F.rows(); ++t) {
    out += 'f';
    for (int k = 0; k < 3; ++k) {
      out += ' ';
      append_int(out, F(t, k) + 1LL);
      if (N) {
        out += "//";
        append_int(out, F(t, k) + 1LL);
      }
    }
    out += '\n';
  }
  return out;
}

std::string write_off(const Vertices& V, const Triangles& F, const Vertices* N) {
  std::string out = N ? "NOFF\n" : "OFF\n";
  out.reserve(static_cast<size_t>(V.rows()) * (N ? 120 : 60) + static_cast<size_t>(F.rows()) * 30);
  append_int(out, V.rows());
  out += ' ';
  append_int(out, F.rows());
  out += " 0\n";
  for (Eigen::Index i = 0; i < V.rows(); ++i) {
    append_row(out, "", V, i);
    if (N) append_row(out, " ", *N, i);
    out += '\n';
  }
  for (Eigen::Index t = 0; t < F.rows(); ++t) {
    out += '3';
    for (int k = 0; k < 3; ++k) {
      out += ' ';
      append_int(out, F(t, k));
    }
    out += '\n';
  }
  return out;
}

std::string write_ply(const Vertices& V, const Triangles& F, const Vertices* N) {
  std::string out = "ply\nformat ascii 1.0\ncomment hdeform\nelement vertex ";
  out.reserve(static_cast<size_t>(V.rows()) * (N ? 120 : 60) + static_cast<size_t>(F.rows()) * 30);
  append_int(out, V.rows());
  out += "\nproperty double x\nproperty double y\nproperty double z\n";
  if (N) out += "property double nx\nproperty double ny\nproperty double nz\n";
  out += "element face ";
  append_int(out, F.rows());
  out += "\nproperty list uchar int vertex_indices\nend_header\n";
  for (Eigen::Index i = 0; i < V.rows(); ++i) {
    append_row(out, "", V, i);
    if (N) append_row(out, " ", *N, i);
    out += '\n';
  }
  for (Eigen::Index t = 0; t < F.rows(); ++t) {
    out += '3';
    for (int k = 0; k < 3; ++k) {
      out += ' ';
      append_int(out, F(t, k));
    }
    out += '\n';
  }
  return out;
}

std::string write_glb(const Vertices& V, const Triangles& F, const Vertices* N) {
  Vertices computed;
  if (!N) {
    computed = vertex_normals(V, F);
    N = &computed;
  }
  const size_t n = static_cast<size_t>(V.rows());
  const size_t m = static_cast<size_t>(F.rows());
  tinygltf::Model model;
  model.asset.version = "2.0";
  model.asset.generator = "hdeform";
  tinygltf::Buffer buffer;
  buffer.data.resize(n * 24 + m * 12);
  float* pos = reinterpret_cast<float*>(buffer.data.data());
  float* nrm = pos + 3 * n;
  std::vector<double> lo(3, std::numeric_limits<double>::infinity());
  std::vector<double> hi(3, -std::numeric_limits<double>::infinity());
  for (size_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) {
      const float p = static_cast<float>(V(static_cast<Eigen::Index>(i), k));
      pos[3 * i + k] = p;
      nrm[3 * i + k] = static_cast<float>((*N)(static_cast<Eigen::Index>(i), k));
      lo[k] = std::min(lo[k], static_cast<double>(p));
      hi[k] = std::max(hi[k], static_cast<double>(p));
    }
  uint32_t* ind = reinterpret_cast<uint32_t*>(buffer.data.data() + n * 24);
  for (size_t t = 0; t < m; ++t)
    for (int k = 0; k < 3; ++k) ind[3 * t + k] = static_cast<uint32_t>(F(static_cast<Eigen::Index>(t), k));
  model.buffers.push_back(std::move(buffer));

  auto view = [&](size_t offset, size_t length, int target) {
    tinygltf::BufferView bv;
    bv.buffer = 0;
    bv.byteOffset = offset;
    bv.byteLength = length;
    bv.target = target;
    model.bufferViews.push_back(bv);
  };
  view(0, n * 12, TINYGLTF_TARGET_ARRAY_BUFFER);
  view(n * 12, n * 12, TINYGLTF_TARGET_ARRAY_BUFFER);
  view(n * 24, m * 12, TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);

  tinygltf::Accessor ap;
  ap.bufferView = 0;
  ap.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
  ap.count = n;
  ap.type = TINYGLTF_TYPE_VEC3;
  if (n > 0) {
    ap.minValues = lo;
    ap.maxValues = hi;
  }
  tinygltf::Accessor an = ap;
  an.bufferView = 1;
  an.minValues.clear();
  an.maxValues.clear();
  tinygltf::Accessor ai;
  ai.bufferView = 2;
  ai.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
  ai.count = 3 * m;
  ai.type = TINYGLTF_TYPE_SCALAR;
  model.accessors = {ap, an, ai};

  tinygltf::Primitive prim;
  prim.attributes["POSITION"] = 0;
  prim.attributes["NORMAL"] = 1;
  prim.indices = 2;
  prim.mode = TINYGLTF_MODE_TRIANGLES;
  tinygltf::Mesh mesh;
  mesh.primitives.push_back(prim);
  model.meshes.push_back(mesh);
  tinygltf::Node node;
  node.mesh = 0;
  model.nodes.push_back(node);
  tinygltf::Scene scene;
  scene.nodes.push_back(0);
  model.scenes.push_back(scene);
  model.defaultScene = 0;

  tinygltf::TinyGLTF writer;
  std::ostringstream os;
  if (!writer.WriteGltfSceneToStream(&model, os, false, true))
    throw std::runtime_error("write_mesh: tinygltf failed to serialise the GLB");
  return os.str();
}

std::string read_file(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) fail(path + ": is a directory, not a mesh file");
  std::ifstream in(path, std::ios::binary);
  if (!in) fail(path + ": cannot open file (" + std::strerror(errno) + ")");
  std::string data;
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  if (size < 0) fail(path + ": cannot read file");
  in.seekg(0, std::ios::beg);
  data.resize(static_cast<size_t>(size));
  if (size > 0 && !in.read(data.data(), size)) fail(path + ": cannot read file");
  return data;
}

}  // namespace

LoadedMesh read_mesh(const std::string& path) {
  const std::string ext = lower_extension(path);
  if (ext != "obj" && ext != "off" && ext != "ply" && ext != "stl" && ext != "gltf" && ext != "glb")
    return read_any({}, path, nullptr);  // throws the unknown-format error before touching the file
  const std::string data = read_file(path);
  std::string base = std::filesystem::path(path).parent_path().string();
  if (base.empty()) base = ".";
  return read_any(data, path, &base);
}

LoadedMesh read_mesh_bytes(std::string_view bytes, const std::string& filename) {
  return read_any(bytes, filename, nullptr);
}

MeshFileFormat format_from_path(const std::string& path) {
  const std::string ext = lower_extension(path);
  if (ext == "glb") return MeshFileFormat::glb;
  if (ext == "obj") return MeshFileFormat::obj;
  if (ext == "off") return MeshFileFormat::off;
  if (ext == "ply") return MeshFileFormat::ply;
  fail(path + ": cannot write format " + (ext.empty() ? std::string("(no extension)") : "'." + ext + "'") +
       " (expected .glb, .obj, .off or .ply)");
}

std::string write_mesh_bytes(MeshFileFormat format, const Vertices& V, const Triangles& F,
                             const Vertices* N) {
  check_write_input(V, F, N);
  switch (format) {
    case MeshFileFormat::glb: return write_glb(V, F, N);
    case MeshFileFormat::obj: return write_obj(V, F, N);
    case MeshFileFormat::off: return write_off(V, F, N);
    case MeshFileFormat::ply: return write_ply(V, F, N);
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

Vertices vertex_normals(const Vertices& V, const Triangles& F) {
  Vertices N = Vertices::Zero(V.rows(), 3);
  for (Eigen::Index t = 0; t < F.rows(); ++t) {
    const Eigen::RowVector3d a = V.row(F(t, 0)), b = V.row(F(t, 1)), c = V.row(F(t, 2));
    const Eigen::RowVector3d w = (b - a).cross(c - a);  // |w| = 2 · area: area weighting
    for (int k = 0; k < 3; ++k) N.row(F(t, k)) += w;
  }
  for (Eigen::Index i = 0; i < N.rows(); ++i) {
    const double len = N.row(i).norm();
    if (len > 0) N.row(i) /= len;
  }
  return N;
}

}  // namespace hdeform
