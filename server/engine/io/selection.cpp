// Constraint selection. See selection.h.

#include "engine/io/selection.h"

#include "engine/io/mesh_soup.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <string>

namespace hdeform {
namespace {

// The text helpers of the mesh readers (mesh_soup.h).
using detail::Cursor;
using detail::fail_line;
using detail::is_space;
using detail::Lines;
using detail::quoted;

std::string_view trim(std::string_view s) {
  while (!s.empty() && is_space(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_space(s.back())) s.remove_suffix(1);
  return s;
}

// Calls f(line_number, trimmed_line) for every line that is neither blank nor a '#' comment.
// Returns the number of the last line.
template <class F>
int for_each_content_line(std::string_view content, F&& f) {
  Lines lines(content);
  for (std::string_view line; lines.next(line);) {
    line = trim(line);
    if (line.empty() || line.front() == '#') continue;
    f(lines.lineno(), line);
  }
  return std::max(lines.lineno(), 1);
}

}  // namespace

std::vector<int> parse_sel(std::string_view content, int num_vertices, const std::string& name) {
  std::vector<int> labels;
  labels.reserve(static_cast<size_t>(std::max(num_vertices, 0)));
  const int last = for_each_content_line(content, [&](int ln, std::string_view line) {
    int v = -1;
    auto r = std::from_chars(line.data(), line.data() + line.size(), v);
    if (r.ec != std::errc() || r.ptr != line.data() + line.size() || v < 0 || v > 2)
      fail_line(name, ln, "bad label " + quoted(line) + " (expected 0 = fixed, 1 = free or 2 = handle)");
    if (static_cast<int>(labels.size()) == num_vertices)
      fail_line(name, ln, "more labels than the mesh's " + std::to_string(num_vertices) + " vertices");
    labels.push_back(v);
  });
  if (static_cast<int>(labels.size()) != num_vertices)
    fail_line(name, last, std::to_string(labels.size()) + " labels but the mesh has " +
                              std::to_string(num_vertices) + " vertices");
  return labels;
}

Eigen::Matrix4d parse_def(std::string_view content, const std::string& name) {
  Eigen::Matrix4d M;
  int rows = 0;
  int last_row_line = 0;
  const int last = for_each_content_line(content, [&](int ln, std::string_view line) {
    if (rows == 4) fail_line(name, ln, "unexpected content after the 4×4 matrix: " + quoted(line));
    int k = 0;
    for (Cursor c(line); !c.at_end();) {
      const std::string_view tok = c.token();
      if (k == 4) fail_line(name, ln, "more than 4 numbers in matrix row " + std::to_string(rows + 1));
      double v = 0;
      const char* q = tok.data();
      if (!tok.empty() && *q == '+') ++q;
      auto r = std::from_chars(q, tok.data() + tok.size(), v);
      if (r.ec != std::errc() || r.ptr != tok.data() + tok.size())
        fail_line(name, ln, "bad number " + quoted(tok) + " in matrix row " + std::to_string(rows + 1));
      if (!std::isfinite(v)) fail_line(name, ln, "non-finite number " + quoted(tok) + " in matrix");
      M(rows, k++) = v;
    }
    if (k != 4)
      fail_line(name, ln, "matrix row " + std::to_string(rows + 1) + " has " + std::to_string(k) +
                              " numbers, expected 4");
    ++rows;
    last_row_line = ln;
  });
  if (rows < 4)
    fail_line(name, last, "expected a 4×4 matrix, found " + std::to_string(rows) +
                              (rows == 1 ? " row" : " rows"));
  const Eigen::RowVector4d affine(0, 0, 0, 1);
  if ((M.row(3) - affine).cwiseAbs().maxCoeff() > 1e-9)
    fail_line(name, last_row_line, "last matrix row must be 0 0 0 1 (an affine transform)");
  return M;
}

std::vector<int> select_label(const std::vector<int>& labels, int label) {
  std::vector<int> out;
  for (size_t i = 0; i < labels.size(); ++i)
    if (labels[i] == label) out.push_back(static_cast<int>(i));
  return out;
}

std::vector<int> select_box(const Vertices& V, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  std::vector<int> out;
  for (Eigen::Index i = 0; i < V.rows(); ++i) {
    bool in = true;
    for (int k = 0; k < 3; ++k) in = in && V(i, k) >= lo[k] && V(i, k) <= hi[k];
    if (in) out.push_back(static_cast<int>(i));
  }
  return out;
}

std::vector<int> select_sphere(const Vertices& V, const Eigen::Vector3d& center, double radius) {
  std::vector<int> out;
  const double r2 = radius * radius;
  if (!(radius >= 0)) return out;
  for (Eigen::Index i = 0; i < V.rows(); ++i)
    if ((V.row(i).transpose() - center).squaredNorm() <= r2) out.push_back(static_cast<int>(i));
  return out;
}

std::vector<int> select_half_space(const Vertices& V, const Eigen::Vector3d& normal, double offset) {
  std::vector<int> out;
  for (Eigen::Index i = 0; i < V.rows(); ++i)
    if (V.row(i).dot(normal.transpose()) >= offset) out.push_back(static_cast<int>(i));
  return out;
}

std::vector<int> unite(std::vector<int> a, const std::vector<int>& b) {
  a.insert(a.end(), b.begin(), b.end());
  std::sort(a.begin(), a.end());
  a.erase(std::unique(a.begin(), a.end()), a.end());
  return a;
}

}  // namespace hdeform
