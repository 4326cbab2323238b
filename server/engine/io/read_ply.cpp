// PLY reader (ascii, binary_little_endian, binary_big_endian): vertex x y z, face
// vertex_indices (or vertex_index); other elements and properties are skipped. Own parser
// rather than OpenMesh's: doubles round-trip (OpenMesh goes through float), every face is
// kept, and ASCII errors name the line. See mesh_readers.h.

#include "engine/io/mesh_readers.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <cstdint>
#include <limits>

namespace hdeform::detail {
namespace {

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

// A face index as read (any PLY number type) for messages: no undefined double → integer
// conversion for NaN or huge values.
std::string index_text(double v) {
  if (v == std::floor(v) && std::fabs(v) < 9e15) return std::to_string(static_cast<long long>(v));
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

}  // namespace

Soup parse_ply(std::string_view bytes, ReadContext& ctx) {
  const std::string& name = ctx.name;
  Lines lines(bytes);
  std::string_view line;
  if (!lines.next(line) || line != "ply") fail(name + ":1: not a PLY file (missing 'ply' header)");
  enum class Fmt { ascii, le, be } fmt = Fmt::ascii;
  bool have_format = false;
  std::vector<PlyElement> elements;
  bool ended = false;
  while (lines.next(line)) {
    ctx.tick();
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
  long long nv = -1;
  for (const PlyElement& el : elements) {
    if (el.name == "vertex") {
      if (nv >= 0) fail_line(name, el.line, "second vertex element (a PLY file has one)");
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
  auto is_face_list = [](const PlyElement& el, const PlyProperty& p) {
    return el.name == "face" && p.count_type != PlyType::invalid &&
           (p.name == "vertex_indices" || p.name == "vertex_index");
  };
  unsigned long long nfaces = 0;
  for (const PlyElement& el : elements)
    for (const PlyProperty& p : el.props)
      if (is_face_list(el, p)) {
        nfaces += static_cast<unsigned long long>(el.count);
        break;
      }
  ctx.declare_vertices(static_cast<unsigned long long>(nv));
  ctx.declare_triangles(nfaces);  // each face gives at least one triangle
  // Binary: every element's rows against the bytes after the header: a row takes at least
  // its scalars' sizes plus its lists' length fields; the whole header must fit before
  // anything is reserved. ASCII: a row of P properties takes at least 2 P characters (a digit
  // and a separator each); memory is reserved only for what the bytes left can hold, and a
  // count larger than the file fails at the line where the data ends. An element without
  // properties takes no bytes and is skipped in O(1) whatever its count.
  const size_t data_bytes = bytes.size() - std::min(lines.pos(), bytes.size());
  unsigned long long need = 0;
  auto min_row = [&](const PlyElement& el) {
    unsigned long long row = 0;
    for (const PlyProperty& p : el.props)
      row += fmt == Fmt::ascii ? 2 : ply_size(p.count_type != PlyType::invalid ? p.count_type : p.type);
    return row;
  };
  if (fmt != Fmt::ascii) {
    for (const PlyElement& el : elements) {
      const unsigned long long row = min_row(el);
      const auto count = static_cast<unsigned long long>(el.count);
      // Overflow-free form of need + row × count > data_bytes.
      if (row > 0 && count > (data_bytes - need) / row)
        fail_line(name, el.line,
                  "binary PLY truncated: header declares " + std::to_string(el.count) + " " + el.name +
                      " elements of at least " + plural(static_cast<size_t>(row), "byte", "bytes") +
                      (need == 0 ? "" : " after " + grouped(need) + " bytes of earlier elements") +
                      " but " + grouped(data_bytes) + " bytes follow the header");
      need += row * count;
    }
  }
  size_t reserve_v = static_cast<size_t>(nv), reserve_f = static_cast<size_t>(nfaces);
  for (const PlyElement& el : elements)
    if (const unsigned long long row = min_row(el); row > 0 && fmt == Fmt::ascii) {
      const size_t fits = data_bytes / row + 1;
      if (el.name == "vertex") reserve_v = std::min(reserve_v, fits);
      if (el.name == "face") reserve_f = std::min(reserve_f, fits);
    }
  Soup s(ctx);
  s.reserve(reserve_v, reserve_f);

  auto axis_of = [](const std::string& n) { return n == "x" ? 0 : n == "y" ? 1 : n == "z" ? 2 : -1; };
  std::vector<int> corners;
  auto add_corner = [&](double v, int ln, bool& ok) {
    if (!(v >= 0 && v < static_cast<double>(nv)) || v != std::floor(v)) {
      ok = false;
      if (ln > 0)
        fail_line(name, ln, "vertex index " + index_text(v) +
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
      if (el.props.empty()) continue;  // rows without properties: nothing to read
      for (long long i = 0; i < el.count; ++i) {
        ctx.tick();
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
      if (el.props.empty()) continue;  // rows of 0 bytes: nothing to read
      for (long long i = 0; i < el.count; ++i) {
        ctx.tick();
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
                     index_text(v) + " out of range (file has " +
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

}  // namespace hdeform::detail
