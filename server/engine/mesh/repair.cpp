// Mesh repair. See repair.h for what it does and why.
//
// Every step works in input ids: after merging a vertex is named by its survivor's input id,
// and the output numbering is made once at the end, so every report line names input ids.
// Fans are found as in validate.cpp (union-find over corners, joined across edges), but the
// joins differ (see step 3) so that merging can only add manifold connections and an edge
// the input already shared is never cut.

#include "engine/mesh/repair.h"

#include "engine/mesh/union_find.h"

#include "engine/mesh/validate.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <bit>
#include <cfloat>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <numeric>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

namespace hdeform {

bool RepairReport::changed() const {
  return merged_vertices > 0 || degenerate_triangles > 0 || duplicate_triangles > 0 ||
         unreferenced_vertices > 0 || split_vertices > 0;
}

namespace {

constexpr size_t kShow = 5;  // how many input ids a report line lists

std::string count_of(size_t n, const char* one, const char* many) {
  return std::to_string(n) + " " + (n == 1 ? one : many);
}

std::string number(double x) {
  char s[32];
  std::snprintf(s, sizeof s, "%.3g", x);
  return s;
}

// "a, b, c, …": the first kShow of `total` items, already formatted.
std::string first_of(const std::vector<std::string>& items, size_t total) {
  std::string s;
  for (size_t i = 0; i < items.size(); ++i) s += (i > 0 ? ", " : "") + items[i];
  if (total > items.size()) s += ", …";
  return s;
}

// Collects the first kShow examples of one kind of change and counts all of them.
struct Examples {
  size_t total = 0;
  std::vector<std::string> first;
  template <class Make>
  void add(Make&& make) {
    if (total++ < kShow) first.push_back(make());
  }
  std::string list() const { return first_of(first, total); }
};

uint64_t splitmix(uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

// Three 64-bit words as a hash key: a position's coordinate bits, a grid cell, a sorted triangle.
struct Key3 {
  uint64_t a, b, c;
  bool operator==(const Key3&) const = default;
};
struct Key3Hash {
  size_t operator()(const Key3& k) const {
    return static_cast<size_t>(splitmix(k.a ^ splitmix(k.b ^ splitmix(k.c))));
  }
};

// Equal coordinates give equal bits, except that −0 and +0 compare equal: both become +0.
uint64_t coordinate_bits(double x) { return std::bit_cast<uint64_t>(x == 0 ? 0.0 : x); }

// rep[i] = the earliest vertex with equal coordinates (i itself if none).
std::vector<int> merge_exact(const Vertices& V) {
  const int n = static_cast<int>(V.rows());
  std::vector<int> rep(static_cast<size_t>(n));
  std::unordered_map<Key3, int, Key3Hash> first;
  first.reserve(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    const Key3 k{coordinate_bits(V(i, 0)), coordinate_bits(V(i, 1)), coordinate_bits(V(i, 2))};
    rep[static_cast<size_t>(i)] = first.try_emplace(k, i).first->second;
  }
  return rep;
}

// rep[i] = the earliest survivor within distance eps of vertex i (i itself if none; it then
// survives). Survivors sit in a uniform grid of cells at least 2·eps wide, so a survivor within
// eps is in one of the 27 cells around i's even after rounding of the cell coordinates (the
// width also covers that rounding, relative to the largest coordinate). Survivors are more than
// eps apart, so a cell 2·eps wide holds only a few; the floors on the width only matter for a
// tolerance near the coordinates' own rounding.
std::vector<int> merge_within(const Vertices& V, double eps, const Eigen::RowVector3d& lo, double diag) {
  const int n = static_cast<int>(V.rows());
  const double max_abs = V.cwiseAbs().maxCoeff();
  // Also at least diag · 2⁻⁴⁰: cell coordinates stay below 2⁴¹ whatever the tolerance.
  const double cell = 2 * std::max({eps, std::ldexp(diag, -40), 16 * DBL_EPSILON * max_abs});
  auto cell_of = [&](int i, int k) {
    return static_cast<int64_t>(std::floor((V(i, k) - lo(k)) / cell));
  };
  std::unordered_map<Key3, int, Key3Hash> head;  // cell → its latest survivor
  head.reserve(static_cast<size_t>(n));
  std::vector<int> next(static_cast<size_t>(n), -1);  // the survivor before it in its cell
  std::vector<int> rep(static_cast<size_t>(n));
  const double eps2 = eps * eps;
  for (int i = 0; i < n; ++i) {
    const int64_t c[3] = {cell_of(i, 0), cell_of(i, 1), cell_of(i, 2)};
    int best = -1;
    for (int64_t dx = -1; dx <= 1; ++dx)
      for (int64_t dy = -1; dy <= 1; ++dy)
        for (int64_t dz = -1; dz <= 1; ++dz) {
          const auto it = head.find(Key3{static_cast<uint64_t>(c[0] + dx), static_cast<uint64_t>(c[1] + dy),
                                         static_cast<uint64_t>(c[2] + dz)});
          if (it == head.end()) continue;
          for (int s = it->second; s >= 0; s = next[static_cast<size_t>(s)])
            if ((best < 0 || s < best) && (V.row(i) - V.row(s)).squaredNorm() <= eps2) best = s;
        }
    if (best >= 0) {
      rep[static_cast<size_t>(i)] = best;
      continue;
    }
    rep[static_cast<size_t>(i)] = i;
    int& h = head.try_emplace(Key3{static_cast<uint64_t>(c[0]), static_cast<uint64_t>(c[1]),
                                   static_cast<uint64_t>(c[2])}, -1).first->second;
    next[static_cast<size_t>(i)] = h;
    h = i;
  }
  return rep;
}

// Calls fn(group) for each edge of the triangles `ids` (3 per triangle, vertex ids < n) with
// the halfedges on it (h = 3t + k runs from ids[h] to ids[3t + (k + 1) % 3]), in O(n + size):
// halfedges bucketed by their smaller endpoint (counting sort), grouped within a bucket by
// their larger one through a scratch head per vertex that is reset after the bucket.
template <class Fn>
void for_each_edge(const std::vector<int>& ids, int n, Fn&& fn) {
  const size_t H = ids.size();
  auto lo = [&](size_t h) { return std::min(ids[h], ids[3 * (h / 3) + (h % 3 + 1) % 3]); };
  auto hi = [&](size_t h) { return std::max(ids[h], ids[3 * (h / 3) + (h % 3 + 1) % 3]); };
  std::vector<int> start(static_cast<size_t>(n) + 1, 0);
  for (size_t h = 0; h < H; ++h) ++start[static_cast<size_t>(lo(h)) + 1];
  for (int i = 0; i < n; ++i) start[static_cast<size_t>(i) + 1] += start[static_cast<size_t>(i)];
  std::vector<int> bucket(H);
  {
    std::vector<int> fill(start.begin(), start.end() - 1);
    for (size_t h = 0; h < H; ++h) bucket[static_cast<size_t>(fill[static_cast<size_t>(lo(h))]++)] = static_cast<int>(h);
  }
  std::vector<int> head(static_cast<size_t>(n), -1), next(H, -1), group;
  for (int v = 0; v < n; ++v) {
    const size_t b = static_cast<size_t>(start[static_cast<size_t>(v)]), e = static_cast<size_t>(start[static_cast<size_t>(v) + 1]);
    for (size_t j = e; j-- > b;) {  // backwards, so each list comes out in halfedge order
      const size_t h = static_cast<size_t>(bucket[j]);
      int& first = head[static_cast<size_t>(hi(h))];
      next[h] = first;
      first = static_cast<int>(h);
    }
    for (size_t j = b; j < e; ++j) {
      const size_t h = static_cast<size_t>(bucket[j]);
      int& first = head[static_cast<size_t>(hi(h))];
      if (first != static_cast<int>(h)) continue;  // not the edge's first halfedge, or done
      group.clear();
      for (int g = first; g >= 0; g = next[static_cast<size_t>(g)]) group.push_back(g);
      first = -1;
      fn(group);
    }
  }
}

// Throws validate_mesh's own InvalidInput when an index is out of range or a coordinate is
// not finite: repair cannot fix either, and the user should see the same message as without it.
void check_preconditions(const TriMesh& mesh) {
  const int n = mesh.num_vertices();
  bool bad = !mesh.V.allFinite();
  for (int t = 0; !bad && t < mesh.num_triangles(); ++t)
    for (int k = 0; k < 3; ++k)
      if (mesh.F(t, k) < 0 || mesh.F(t, k) >= n) bad = true;
  if (!bad) return;
  validate_mesh(mesh);  // checks range and finiteness before anything repair fixes
  throw InvalidInput("repair_mesh: index out of range or non-finite coordinates");
}

}  // namespace

RepairResult repair_mesh(const TriMesh& input, const RepairOptions& options) {
  if (!std::isfinite(options.merge_tolerance) || options.merge_tolerance < 0)
    throw InvalidInput("merge tolerance must be finite and ≥ 0 (got " + number(options.merge_tolerance) + ")");
  check_preconditions(input);

  const int n = input.num_vertices();
  const int m = input.num_triangles();
  const Vertices& V = input.V;
  const Triangles& F = input.F;
  RepairResult result;
  RepairReport& report = result.report;
  auto at = [](const std::vector<int>& v, int i) -> int { return v[static_cast<size_t>(i)]; };

  Eigen::RowVector3d lo = Eigen::RowVector3d::Zero(), hi = Eigen::RowVector3d::Zero();
  if (n > 0) {
    lo = V.colwise().minCoeff();
    hi = V.colwise().maxCoeff();
  }
  const double diag = (hi - lo).norm();

  // 1. Merge coincident vertices: rep[i] = the earliest vertex i is merged with (a survivor).
  const double eps = options.merge_tolerance * diag;
  const std::vector<int> rep = eps > 0 ? merge_within(V, eps, lo, diag) : merge_exact(V);

  // 2. Drop degenerate and duplicate triangles, on the merged ids. The area is computed as
  // validate_mesh does, on coordinates equal to the output's, so a kept triangle passes its
  // zero-area check.
  std::vector<int>& kept = result.kept_triangles;
  kept.reserve(static_cast<size_t>(m));
  std::vector<int> G, O;  // kept triangles' corners: merged ids (survivors), input ids
  G.reserve(3 * static_cast<size_t>(m));
  O.reserve(3 * static_cast<size_t>(m));
  const double min_area = kZeroAreaScale * diag * diag;
  Examples degenerate, duplicate;
  {
    std::unordered_map<Key3, int, Key3Hash> seen;  // sorted corners → first input triangle
    seen.reserve(static_cast<size_t>(m));
    for (int t = 0; t < m; ++t) {
      const int a = at(rep, F(t, 0)), b = at(rep, F(t, 1)), c = at(rep, F(t, 2));
      bool zero = a == b || b == c || a == c;
      if (!zero) {
        const Eigen::RowVector3d A = V.row(a), B = V.row(b), C = V.row(c);
        zero = 0.5 * (B - A).cross(C - A).norm() <= min_area;
      }
      if (zero) {
        degenerate.add([&] { return std::to_string(t); });
        continue;
      }
      int s[3] = {a, b, c};
      std::sort(s, s + 3);
      const int earlier = seen.try_emplace(
          Key3{static_cast<uint64_t>(s[0]), static_cast<uint64_t>(s[1]), static_cast<uint64_t>(s[2])}, t).first->second;
      if (earlier != t) {
        duplicate.add([&] { return std::to_string(t) + " repeats " + std::to_string(earlier); });
        continue;
      }
      kept.push_back(t);
      G.insert(G.end(), {a, b, c});
      O.insert(O.end(), {F(t, 0), F(t, 1), F(t, 2)});
    }
  }

  // 3. Fans: corners at one merged vertex joined across an edge that is manifold after
  // merging (two triangles, opposite directions), or that two triangles already shared before
  // merging (any count or orientation: a defect of the input is left for validate_mesh, never
  // cut apart). Corner h sits at G[h] (input vertex O[h]).
  const size_t H = G.size();
  auto next_corner = [](size_t h) { return 3 * (h / 3) + (h % 3 + 1) % 3; };
  auto corner_at = [&](const std::vector<int>& ids, size_t h, int v) {
    return static_cast<int>(ids[h] == v ? h : next_corner(h));
  };
  UnionFind corners(H);
  auto join = [&](const std::vector<int>& ids, size_t h1, size_t h2) {
    const int a = ids[h1], b = ids[next_corner(h1)];
    corners.unite(corner_at(ids, h1, a), corner_at(ids, h2, a));
    corners.unite(corner_at(ids, h1, b), corner_at(ids, h2, b));
  };
  for_each_edge(G, n, [&](const std::vector<int>& g) {
    if (g.size() == 2 && G[static_cast<size_t>(g[0])] != G[static_cast<size_t>(g[1])])
      join(G, static_cast<size_t>(g[0]), static_cast<size_t>(g[1]));
  });
  for_each_edge(O, n, [&](const std::vector<int>& g) {
    for (size_t j = 1; j < g.size(); ++j) join(O, static_cast<size_t>(g[0]), static_cast<size_t>(g[j]));
  });

  // Fans numbered by their earliest corner; fan_corners lists each fan's corners.
  std::vector<int> fan_of(H, -1);  // by union-find root, then by corner
  std::vector<int> fan_start(1, 0);
  for (size_t c = 0; c < H; ++c) {
    int& f = fan_of[static_cast<size_t>(corners.find(static_cast<int>(c)))];
    if (f < 0) {
      f = static_cast<int>(fan_start.size()) - 1;
      fan_start.push_back(0);
    }
  }
  const int fans = static_cast<int>(fan_start.size()) - 1;
  std::vector<int> corner_fan(H);
  for (size_t c = 0; c < H; ++c) {
    corner_fan[c] = fan_of[static_cast<size_t>(corners.find(static_cast<int>(c)))];
    ++fan_start[static_cast<size_t>(corner_fan[c]) + 1];
  }
  for (int f = 0; f < fans; ++f) fan_start[static_cast<size_t>(f) + 1] += fan_start[static_cast<size_t>(f)];
  std::vector<int> fan_corners(H);
  {
    std::vector<int> fill(fan_start.begin(), fan_start.end() - 1);
    for (size_t c = 0; c < H; ++c) fan_corners[static_cast<size_t>(fill[static_cast<size_t>(corner_fan[c])]++)] = static_cast<int>(c);
  }

  // Each fan becomes one vertex: the earliest input vertex among its corners that no earlier
  // fan took and that sits exactly where the merged vertex does (equal coordinates), else a
  // new copy of the merged vertex. Separate sheets that merging made touch thus keep their own
  // vertices; only a vertex without enough such ids (a bowtie) is split.
  auto same_place = [&](int a, int b) {
    for (int k = 0; k < 3; ++k)
      if (coordinate_bits(V(a, k)) != coordinate_bits(V(b, k))) return false;
    return true;
  };
  std::vector<int> owner(static_cast<size_t>(fans), -1);  // fan → input vertex, −1: a copy
  std::vector<int> owned(static_cast<size_t>(n), -1);     // input vertex → its fan
  std::vector<int> class_fans(static_cast<size_t>(n), 0), class_copies(static_cast<size_t>(n), 0);
  std::vector<int> class_first_fan(static_cast<size_t>(n), -1);
  for (int f = 0; f < fans; ++f) {
    const int s = G[static_cast<size_t>(fan_corners[static_cast<size_t>(fan_start[static_cast<size_t>(f)])])];
    ++class_fans[static_cast<size_t>(s)];
    if (at(class_first_fan, s) < 0) class_first_fan[static_cast<size_t>(s)] = f;
    int best = -1;
    for (int j = fan_start[static_cast<size_t>(f)]; j < fan_start[static_cast<size_t>(f) + 1]; ++j) {
      const int o = O[static_cast<size_t>(fan_corners[static_cast<size_t>(j)])];
      if ((best < 0 || o < best) && at(owned, o) < 0 && (o == s || same_place(o, s))) best = o;
    }
    if (best >= 0) {
      owner[static_cast<size_t>(f)] = best;
      owned[static_cast<size_t>(best)] = f;
    } else {
      ++class_copies[static_cast<size_t>(s)];
    }
  }

  // 4. Renumber: the input vertices that own a fan, in input order, then the copies in fan
  // order. Everything else is merged (it maps to a fan of its merged vertex) or dropped.
  std::vector<int> fan_vertex(static_cast<size_t>(fans));
  std::vector<int>& to_input = result.to_input;
  for (int i = 0; i < n; ++i)
    if (at(owned, i) >= 0) {
      fan_vertex[static_cast<size_t>(at(owned, i))] = static_cast<int>(to_input.size());
      to_input.push_back(i);
    }
  for (int f = 0; f < fans; ++f)
    if (owner[static_cast<size_t>(f)] < 0) {
      fan_vertex[static_cast<size_t>(f)] = static_cast<int>(to_input.size());
      to_input.push_back(G[static_cast<size_t>(fan_corners[static_cast<size_t>(fan_start[static_cast<size_t>(f)])])]);
    }
  // A vertex that owns nothing maps to the fan of its earliest corner, or (no corner left) to
  // its merged vertex's first fan.
  std::vector<int> first_corner(static_cast<size_t>(n), -1);
  for (size_t c = H; c-- > 0;) first_corner[static_cast<size_t>(O[c])] = static_cast<int>(c);
  std::vector<int>& from_input = result.from_input;
  from_input.assign(static_cast<size_t>(n), -1);
  Examples merged, unreferenced, split;
  for (int i = 0; i < n; ++i) {
    int f = at(owned, i);
    if (f < 0) f = at(first_corner, i) >= 0 ? corner_fan[static_cast<size_t>(at(first_corner, i))] : at(class_first_fan, at(rep, i));
    if (f < 0) {
      unreferenced.add([&] { return std::to_string(i); });
      continue;
    }
    from_input[static_cast<size_t>(i)] = fan_vertex[static_cast<size_t>(f)];
    if (at(owned, i) < 0)
      merged.add([&] { return std::to_string(i) + "→" + std::to_string(at(to_input, at(from_input, i))); });
    if (at(class_copies, i) > 0)
      split.add([&] { return "vertex " + std::to_string(i) + " (" + std::to_string(at(class_fans, i)) + " fans)"; });
  }

  TriMesh& out = result.mesh;
  out.V.resize(static_cast<Eigen::Index>(to_input.size()), 3);
  for (size_t i = 0; i < to_input.size(); ++i) out.V.row(static_cast<Eigen::Index>(i)) = V.row(to_input[i]);
  out.F.resize(static_cast<Eigen::Index>(kept.size()), 3);
  for (size_t c = 0; c < H; ++c)
    out.F(static_cast<Eigen::Index>(c / 3), static_cast<Eigen::Index>(c % 3)) = fan_vertex[static_cast<size_t>(corner_fan[c])];

  report.merged_vertices = static_cast<int>(merged.total);
  report.degenerate_triangles = static_cast<int>(degenerate.total);
  report.duplicate_triangles = static_cast<int>(duplicate.total);
  report.unreferenced_vertices = static_cast<int>(unreferenced.total);
  report.split_vertices = static_cast<int>(split.total);
  report.added_vertices = static_cast<int>(std::count(owner.begin(), owner.end(), -1));
  if (merged.total > 0)
    report.lines.push_back("merged " + count_of(merged.total, "duplicate vertex", "duplicate vertices") +
                           " into a coincident one " +
                           (eps > 0 ? "(within " + number(options.merge_tolerance) + " × bbox diagonal = " + number(eps) + ")"
                                    : std::string("(same position)")) +
                           " (first: " + merged.list() + ")");
  if (degenerate.total > 0)
    report.lines.push_back("dropped " + count_of(degenerate.total, "degenerate triangle", "degenerate triangles") +
                           " (a repeated corner, or area ≤ " + number(kZeroAreaScale) + "·(bbox diagonal)² = " +
                           number(min_area) + ") (first: triangles " + degenerate.list() + ")");
  if (duplicate.total > 0)
    report.lines.push_back("dropped " + count_of(duplicate.total, "duplicate triangle", "duplicate triangles") +
                           " (the same three vertices as an earlier one) (first: triangle " + duplicate.list() + ")");
  if (split.total > 0)
    report.lines.push_back("split " + count_of(split.total, "non-manifold vertex", "non-manifold vertices") +
                           " (triangles forming more than one fan), one vertex a fan: " +
                           count_of(static_cast<size_t>(report.added_vertices), "copy", "copies") +
                           " appended (first: " + split.list() + ")");
  if (unreferenced.total > 0)
    report.lines.push_back("dropped " + count_of(unreferenced.total, "unreferenced vertex", "unreferenced vertices") +
                           " (no remaining triangle uses " + (unreferenced.total == 1 ? "it" : "them") +
                           ") (first: " + unreferenced.list() + ")");
  return result;
}

}  // namespace hdeform
