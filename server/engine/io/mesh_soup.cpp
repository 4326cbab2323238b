// Polygon soup and text-parser helpers shared by the mesh readers. See mesh_soup.h.

#include "engine/io/mesh_soup.h"

#include <cctype>
#include <climits>
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

namespace {
constexpr size_t kIntCap = static_cast<size_t>(INT_MAX) / 3;
std::string option_note(const std::string& option) {
  return option.empty() ? std::string() : " (" + option + ")";
}
// declared: a count known up front (n); otherwise a running count passed the cap.
[[noreturn]] void exceed(const ReadContext& c, unsigned long long n, bool declared, size_t limit,
                         const char* what, const std::string& option) {
  if (limit > 0 && limit <= kIntCap) {
    if (declared)
      throw LimitExceeded(c.name + ": " + std::to_string(n) + " " + what +
                          " exceed the server's limit of " + std::to_string(limit) +
                          option_note(option));
    throw LimitExceeded(c.name + ": more than " + std::to_string(limit) + " " + what +
                        ": the server's limit" + option_note(option));
  }
  fail(c.name + ": " + (declared ? std::to_string(n) : "more than " + std::to_string(kIntCap)) +
       " " + what + ": at most " + std::to_string(kIntCap) + " are supported");
}
}  // namespace

ReadContext::ReadContext(std::string n, const ReadLimits& l) : name(std::move(n)), limits(l) {
  // Vertex ids are ints and the soup stores 3 per vertex / triangle.
  vertex_cap_ = limits.max_vertices > 0 ? std::min(limits.max_vertices, kIntCap) : kIntCap;
  triangle_cap_ = limits.max_triangles > 0 ? std::min(limits.max_triangles, kIntCap) : kIntCap;
}

void ReadContext::poll() const {
  if ((limits.cancel && limits.cancel->load(std::memory_order_relaxed)) ||
      (limits.should_cancel && limits.should_cancel()))
    throw ReadCancelled(name + ": reading cancelled");
}

void ReadContext::declare_vertices(unsigned long long n) const {
  if (n > vertex_cap_) exceed(*this, n, true, limits.max_vertices, "vertices", limits.vertices_option);
}
void ReadContext::declare_triangles(unsigned long long n) const {
  if (n > triangle_cap_)
    exceed(*this, n, true, limits.max_triangles, "triangles", limits.triangles_option);
}
void ReadContext::too_many_vertices() const {
  exceed(*this, 0, false, limits.max_vertices, "vertices", limits.vertices_option);
}
void ReadContext::too_many_triangles() const {
  exceed(*this, 0, false, limits.max_triangles, "triangles", limits.triangles_option);
}

LoadedMesh to_loaded(Soup&& s, const ReadContext& ctx, const char* format) {
  if (s.num_vertices() == 0) fail(ctx.name + ": no vertices found in the " + format + " file");
  LoadedMesh out;
  const Eigen::Index n = s.num_vertices();
  const Eigen::Index m = static_cast<Eigen::Index>(s.tri.size() / 3);
  out.mesh.V = Eigen::Map<const Vertices>(s.xyz.data(), n, 3);
  out.mesh.F = Eigen::Map<const Triangles>(s.tri.data(), m, 3);
  out.input_to_engine.resize(static_cast<size_t>(n));
  for (Eigen::Index i = 0; i < n; ++i) out.input_to_engine[static_cast<size_t>(i)] = static_cast<int>(i);
  out.input_triangles = out.mesh.F;
  out.polygons = std::move(s.fans);
  out.warnings = ctx.warnings;
  if (s.polygons > 0)
    out.warnings.push_back(ctx.name + ": " + plural(s.polygons, "polygon", "polygons") +
                           " with more than 3 vertices triangulated (fan); OBJ/OFF/PLY "
                           "output writes them back as they were");
  return out;
}

std::string quoted(std::string_view t) {
  // Appends, not operator+: GCC 12 -O3 gives a false -Wrestrict on "'" + std::string(...).
  std::string q;
  q.reserve(std::min<size_t>(t.size(), 40) * 4 + 8);
  q += '\'';
  static const char* hex = "0123456789abcdef";
  for (const char ch : t.substr(0, 40)) {
    const auto u = static_cast<unsigned char>(ch);
    if (u >= 0x20 && u < 0x7f) {
      q += ch;
    } else {
      q += "\\x";
      q += hex[u >> 4];
      q += hex[u & 15];
    }
  }
  if (t.size() > 40) q += "…";
  q += '\'';
  return q;
}

std::string grouped(unsigned long long n) {
  std::string d = std::to_string(n), out;
  for (size_t i = 0; i < d.size(); ++i) {
    if (i > 0 && (d.size() - i) % 3 == 0) out += ',';
    out += d[i];
  }
  return out;
}

void read_xyz(Cursor& c, const std::string& name, int line, double out[3]) {
  for (int k = 0; k < 3; ++k) {
    if (c.at_end())
      fail_line(name, line, "expected 3 coordinates, found " + std::to_string(k));
    if (!c.read_double(out[k])) fail_line(name, line, "bad coordinate " + quoted(c.peek_token()));
  }
}

}  // namespace hdeform::detail
