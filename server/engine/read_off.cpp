// ASCII OFF reader. Own text parser rather than OpenMesh's: doubles round-trip (OpenMesh
// goes through float), every face is kept, and errors name the line. See mesh_readers.h.
// Header [ST][C][N]OFF, counts, one vertex per line, one face per line (k i1 .. ik
// [colour]). "OFF BINARY" goes to OpenMesh (read_openmesh.cpp).

#include "mesh_readers.h"

#include <limits>

namespace hdeform::detail {

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

}  // namespace hdeform::detail
