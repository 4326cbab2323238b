// OBJ reader. Own text parser rather than OpenMesh's: doubles round-trip (OpenMesh goes
// through float), every face is kept, and errors name the line. See mesh_readers.h.

#include "engine/io/mesh_readers.h"

#include <charconv>
#include <limits>
#include <utility>

namespace hdeform::detail {

namespace {

// Statements of the OBJ specification (and common extensions) that carry no triangle
// geometry: ignored. Anything else in a file without vertices means it is not an OBJ file.
bool known_statement(std::string_view kw) {
  static constexpr std::string_view known[] = {
      "vt", "vn", "vp", "g", "o", "s", "mg", "usemtl", "mtllib", "usemap", "maplib", "cstype",
      "deg", "bmat", "step", "curv", "curv2", "surf", "parm", "trim", "hole", "scrv", "sp",
      "end", "con", "bevel", "c_interp", "d_interp", "lod", "shadow_obj", "trace_obj", "ctech",
      "stech", "call", "csh"};
  for (std::string_view k : known)
    if (kw == k) return true;
  return false;
}

}  // namespace

Soup parse_obj(std::string_view text, ReadContext& ctx) {
  const std::string& name = ctx.name;
  Soup s(ctx);
  Lines lines(text);
  std::string_view line;
  std::vector<int> corners;
  std::vector<std::pair<long long, int>> forward;  // (0-based index, line) ≥ count at the time
  size_t lines_points = 0;
  int first_unknown_line = 0;
  std::string_view first_unknown;
  while (lines.next(line)) {
    ctx.tick();
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
    } else if (first_unknown_line == 0 && !known_statement(kw)) {
      first_unknown_line = ln;
      first_unknown = kw;
    }
  }
  if (s.num_vertices() == 0 && first_unknown_line > 0)
    fail_line(name, first_unknown_line, "not an OBJ file: unknown statement " + quoted(first_unknown));
  for (const auto& [idx, ln] : forward)
    if (idx >= s.num_vertices())
      fail_line(name, ln, "vertex index " + std::to_string(idx + 1) + " out of range (file has " +
                              plural(static_cast<size_t>(s.num_vertices()), "vertex", "vertices") + ")");
  if (lines_points > 0)
    ctx.warnings.push_back(name + ": " + plural(lines_points, "line/point element", "line/point elements") +
                       " ignored");
  return s;
}

}  // namespace hdeform::detail
