// OFF reader, ASCII and binary. Own parser rather than OpenMesh's: doubles round-trip
// (OpenMesh goes through float), every face is kept, errors name the line, and OpenMesh's
// binary OFF path accepted no file at all. See mesh_readers.h.
// ASCII: header [ST][C][N]OFF, counts, one vertex per line, one face per line (k i1 .. ik
// [colour]). Binary (Geomview): "[ST][C][N]OFF BINARY", then from the byte after the next
// newline big-endian int32 counts nv nf ne, nv vertices of float32 (x y z, then nx ny nz
// with N, r g b a with C, s t with ST), nf faces of int32 k, k int32 indices, int32 colour
// count c (0–4) and c float32 colour components.

#include "engine/io/mesh_readers.h"

#include <bit>
#include <cstdint>
#include <limits>

namespace hdeform::detail {
namespace {

Soup parse_off_binary(std::string_view bytes, size_t start, std::string_view head, ReadContext& ctx) {
  const std::string& name = ctx.name;
  const std::string_view prefix = head.substr(0, head.size() - 3);
  size_t floats_per_vertex = 3;
  if (prefix.find('N') != std::string_view::npos) floats_per_vertex += 3;
  if (prefix.find('C') != std::string_view::npos) floats_per_vertex += 4;
  if (prefix.find("ST") != std::string_view::npos) floats_per_vertex += 2;
  const size_t vertex_bytes = 4 * floats_per_vertex;
  constexpr size_t kMinFaceBytes = 4 + 3 * 4 + 4;  // k = 3, three indices, no colour

  const auto* b = reinterpret_cast<const unsigned char*>(bytes.data());
  const size_t size = bytes.size();
  size_t pos = std::min(start, size);
  const bool swap = std::endian::native != std::endian::big;
  auto left = [&] { return size - pos; };
  auto int_at = [&](size_t p) { return load_raw<int32_t>(b + p, swap); };
  if (left() < 12)
    fail(name + ": binary OFF truncated: " + std::to_string(left()) +
         " bytes after the header line, need 12 for the vertex, face and edge counts");
  const int32_t nv = int_at(pos), nf = int_at(pos + 4);
  pos += 12;  // the edge count is not used
  if (nv < 0 || nf < 0)
    fail(name + ": binary OFF: negative counts (" + std::to_string(nv) + " vertices, " +
         std::to_string(nf) + " faces) at byte " + std::to_string(pos - 12));
  ctx.declare_vertices(static_cast<unsigned long long>(nv));
  ctx.declare_triangles(static_cast<unsigned long long>(nf));
  const unsigned long long need = static_cast<unsigned long long>(nv) * vertex_bytes +
                                  static_cast<unsigned long long>(nf) * kMinFaceBytes;
  if (need > left())
    fail(name + ": binary OFF truncated: header declares " +
         plural(static_cast<size_t>(nv), "vertex", "vertices") + " (" + grouped(static_cast<unsigned long long>(nv) * vertex_bytes) +
         " bytes) and " + plural(static_cast<size_t>(nf), "face", "faces") + " (at least " +
         grouped(static_cast<unsigned long long>(nf) * kMinFaceBytes) + " bytes) but " +
         grouped(left()) + " bytes follow the counts");

  Soup s(ctx);
  s.reserve(static_cast<size_t>(nv), static_cast<size_t>(nf));
  for (int32_t i = 0; i < nv; ++i, pos += vertex_bytes) {
    float x[3];
    for (int k = 0; k < 3; ++k) x[k] = load_raw<float>(b + pos + 4 * k, swap);
    s.add_vertex(x[0], x[1], x[2]);
  }
  std::vector<int> corners;
  for (int32_t f = 0; f < nf; ++f) {
    const size_t face_at = pos;
    auto where = [&] { return name + ": binary OFF face " + std::to_string(f) + " (byte " + std::to_string(face_at) + "): "; };
    if (left() < 4) fail(where() + "truncated: the file ends before the face's vertex count");
    const int32_t k = int_at(pos);
    pos += 4;
    if (k < 3) fail(where() + "face with " + std::to_string(k) + " vertices (need at least 3)");
    if (static_cast<unsigned long long>(k) * 4 + 4 > left())
      fail(where() + "truncated: " + std::to_string(k) + " vertex indices and a colour count need " +
           grouped(static_cast<unsigned long long>(k) * 4 + 4) + " bytes, " + grouped(left()) + " left");
    corners.clear();
    for (int32_t j = 0; j < k; ++j, pos += 4) {
      const int32_t idx = int_at(pos);
      if (idx < 0 || idx >= nv)
        fail(where() + "vertex index " + std::to_string(idx) + " out of range (file has " +
             plural(static_cast<size_t>(nv), "vertex", "vertices") + ")");
      corners.push_back(idx);
    }
    const int32_t nc = int_at(pos);
    pos += 4;
    if (nc < 0 || nc > 4) fail(where() + "colour with " + std::to_string(nc) + " components (expected 0 to 4)");
    if (static_cast<size_t>(nc) * 4 > left())
      fail(where() + "truncated: the file ends inside the face's colour");
    pos += static_cast<size_t>(nc) * 4;
    s.add_polygon(corners.data(), corners.size());
  }
  return s;
}

}  // namespace

Soup parse_off(std::string_view text, ReadContext& ctx) {
  const std::string& name = ctx.name;
  Lines lines(text);
  std::string_view line;
  // Next line with content (comments and blank lines skipped); false at end of file.
  auto next_content = [&](Cursor& c) {
    while (lines.next(line)) {
      ctx.tick();
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
  if (c.peek_token() == "BINARY") return parse_off_binary(text, lines.pos(), head, ctx);
  if (c.at_end() && !next_content(c))
    fail_line(name, lines.lineno(), "missing vertex and face counts");
  long long nv = 0, nf = 0;
  const int count_line = lines.lineno();
  if (!c.read_int(nv) || !c.read_int(nf) || nv < 0 || nf < 0)
    fail_line(name, count_line, "expected vertex and face counts");
  ctx.declare_vertices(static_cast<unsigned long long>(nv));
  ctx.declare_triangles(static_cast<unsigned long long>(nf));
  // Memory before the data is seen: one vertex per line ("0 0 0\n", 6 bytes at least) and
  // one face per line ("3 0 1 2\n", 8): reserve no more than the bytes left can hold. A
  // count larger than the file fails at the line where the data ends.
  const size_t left = text.size() - std::min(lines.pos(), text.size());
  Soup s(ctx);
  s.reserve(std::min(static_cast<size_t>(nv), left / 6 + 1), std::min(static_cast<size_t>(nf), left / 8 + 1));
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

}  // namespace hdeform::detail
