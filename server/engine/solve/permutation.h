// Whether a vertex order from outside the solver (the state store) is one: every id in
// 0..n−1 exactly once. Header-only so the state store's record reader, which is fuzzed on
// its own, checks stored orders without linking the solver.
#pragma once

#include <cstddef>
#include <vector>

namespace hdeform {

inline bool is_permutation_of(const std::vector<int>& p, int n) {
  if (n < 0 || p.size() != static_cast<std::size_t>(n)) return false;
  std::vector<bool> seen(p.size(), false);
  for (const int v : p) {
    if (v < 0 || v >= n || seen[static_cast<std::size_t>(v)]) return false;
    seen[static_cast<std::size_t>(v)] = true;
  }
  return true;
}

}  // namespace hdeform
