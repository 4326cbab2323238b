// Polygon soup and text-parser helpers shared by the mesh readers. See mesh_soup.h.

#include "mesh_soup.h"

#include <cctype>
#include <filesystem>

namespace hdeform::detail {

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

void read_xyz(Cursor& c, const std::string& name, int line, double out[3]) {
  for (int k = 0; k < 3; ++k) {
    if (c.at_end())
      fail_line(name, line, "expected 3 coordinates, found " + std::to_string(k));
    if (!c.read_double(out[k])) fail_line(name, line, "bad coordinate " + quoted(c.peek_token()));
  }
}

}  // namespace hdeform::detail
