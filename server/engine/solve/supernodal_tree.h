// A split of a supernodal factor's elimination tree for two threads, shared by the solve
// (supernodal_solve.h) and the numeric factorization (supernodal_factorize.h).
//
// The parent of supernode s is the supernode holding s's first off-diagonal row (CHOLMOD's
// supernodal etree; parent > child). The split is up to max_parts "parts", each a set of
// disjoint subtrees, and the "top": every other supernode (the parts' ancestors). Parts are
// independent of each other; the top depends on all of them.
#pragma once

#include <cholmod.h>

#include <vector>

namespace hdeform {

struct TreeSplit {
  std::vector<std::vector<int>> parts;  // supernodes of each part, ascending; heaviest first
  std::vector<int> top;                 // the other supernodes, ascending
  std::vector<double> work;             // each part's work, then the top's (its top_work)
  double critical = 0;                  // work on the two-thread critical path
  bool split() const { return !parts.empty(); }
};

// The parent of every supernode (−1 for a root). Precondition: L is supernodal (int).
std::vector<int> supernode_parents(const cholmod_factor& L);

// Greedy: the heaviest candidate subtree's root moves to the top and its children become
// candidates, step after step; each step's candidates are packed into ≤ max_parts parts
// (largest first into the lightest), and the step whose two-thread critical path (parts
// list-scheduled heaviest first, as claimed at run time, then the top) is shortest wins.
// work[s] ≥ 0 is supernode s's own cost in any unit; top_work[s] (default: work) its cost
// when it is in the top (less when the top runs it on both threads). Returns an empty split
// (no parts) when there is nothing to split or the best critical path exceeds
// max_critical × total work.
TreeSplit split_supernodal_tree(const cholmod_factor& L, const std::vector<double>& work,
                                int max_parts, double max_critical = 0.8,
                                const std::vector<double>* top_work = nullptr);

}  // namespace hdeform
