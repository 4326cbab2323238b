#include "engine/solve/supernodal_tree.h"

#include <algorithm>
#include <numeric>

namespace hdeform {

std::vector<int> supernode_parents(const cholmod_factor& L) {
  const int nsuper = static_cast<int>(L.nsuper);
  const int* super = static_cast<const int*>(L.super);
  const int* pi = static_cast<const int*>(L.pi);
  const int* Ls = static_cast<const int*>(L.s);
  std::vector<int> super_of(L.n);
  for (int s = 0; s < nsuper; ++s)
    for (int k = super[s]; k < super[s + 1]; ++k) super_of[static_cast<std::size_t>(k)] = s;
  std::vector<int> parent(static_cast<std::size_t>(nsuper), -1);
  for (int s = 0; s < nsuper; ++s) {
    const int nc = super[s + 1] - super[s];
    if (pi[s + 1] - pi[s] > nc) parent[static_cast<std::size_t>(s)] = super_of[Ls[pi[s] + nc]];
  }
  return parent;
}

TreeSplit split_supernodal_tree(const cholmod_factor& L, const std::vector<double>& work,
                                int max_parts, double max_critical,
                                const std::vector<double>* top_work) {
  const std::vector<double>& on_top = top_work ? *top_work : work;
  TreeSplit out;
  const int nsuper = static_cast<int>(L.nsuper);
  if (nsuper < 2 || max_parts < 2) return out;
  const std::vector<int> parent = supernode_parents(L);
  // Children lists and subtree work (children come before their parent).
  std::vector<int> head(nsuper, -1), next(nsuper, -1), roots;
  std::vector<double> subtree(nsuper);
  for (int s = 0; s < nsuper; ++s) {
    subtree[s] += work[s];
    if (parent[s] >= 0) {
      next[s] = head[parent[s]];
      head[parent[s]] = s;
      subtree[parent[s]] += subtree[s];
    } else {
      roots.push_back(s);
    }
  }
  double total = 0;
  for (int r : roots) total += subtree[r];

  std::vector<int> cand = roots;
  std::vector<std::vector<int>> best;
  std::vector<double> best_work;
  double top_sum = 0, moved = 0, best_cost = total, best_top = 0;
  // Later steps cost at least top + (total − moved) / 2: stop once that cannot win.
  for (int step = 0; step < 256 && !cand.empty() && top_sum + (total - moved) / 2 < best_cost;
       ++step) {
    std::sort(cand.begin(), cand.end(), [&](int a, int b) {
      return subtree[a] != subtree[b] ? subtree[a] > subtree[b] : a < b;
    });
    const int K = std::min<int>(max_parts, static_cast<int>(cand.size()));
    if (K >= 2) {
      std::vector<std::vector<int>> bins(K);
      std::vector<double> w(K, 0.0);
      for (int c : cand) {
        const int b = static_cast<int>(std::min_element(w.begin(), w.end()) - w.begin());
        w[b] += subtree[c];
        bins[b].push_back(c);
      }
      std::vector<int> order(K);
      std::iota(order.begin(), order.end(), 0);
      std::sort(order.begin(), order.end(), [&](int a, int b) { return w[a] > w[b]; });
      double t[2] = {0, 0};
      for (int b : order) t[t[1] < t[0] ? 1 : 0] += w[b];
      const double cost = std::max(t[0], t[1]) + top_sum;
      if (cost < best_cost) {
        best_cost = cost;
        best.clear();
        best_work.clear();
        for (int b : order) {
          best.push_back(std::move(bins[b]));
          best_work.push_back(w[b]);
        }
        best_top = top_sum;
      }
    }
    const int h = cand.front();
    if (head[h] < 0) break;  // the heaviest is a leaf: no finer split
    cand.erase(cand.begin());
    top_sum += on_top[h];
    moved += work[h];
    for (int c = head[h]; c >= 0; c = next[c]) cand.push_back(c);
  }
  if (best.empty() || best_cost > max_critical * total) return out;

  const int K = static_cast<int>(best.size());
  out.parts.resize(K);
  std::vector<char> in_part(nsuper, 0);
  std::vector<int> stack;
  for (int p = 0; p < K; ++p) {
    for (int r : best[p]) {
      stack.push_back(r);
      while (!stack.empty()) {
        const int s = stack.back();
        stack.pop_back();
        out.parts[p].push_back(s);
        in_part[s] = 1;
        for (int c = head[s]; c >= 0; c = next[c]) stack.push_back(c);
      }
    }
    std::sort(out.parts[p].begin(), out.parts[p].end());
  }
  for (int s = 0; s < nsuper; ++s)
    if (!in_part[s]) out.top.push_back(s);
  out.work = std::move(best_work);
  out.work.push_back(best_top);
  out.critical = best_cost;
  return out;
}

}  // namespace hdeform
