// Building a compressed-column sparse matrix straight from a per-column rule, on all OpenMP
// threads, without triplets. Eigen's setFromTriplets holds every entry
// twice (the triplets and an unsorted copy) and runs serially; here each column is computed
// twice (once to count, once to fill) into a small per-thread accumulator and written in
// place. Each column is computed by one thread in a fixed order, so the result has the same
// bits for any thread count.
#pragma once

#include "engine/operators/operators.h"

#include <algorithm>
#include <cstdint>
#include <vector>

namespace hdeform {

// The entries of one column while it is being computed: add(row, v) sums into row's entry.
// The first add of a row assigns, later ones accumulate in call order — what Eigen's
// sparse-sparse product does, so a rule that adds terms in the product's order reproduces
// its values bit for bit (including the sign of a zero).
class ColumnAccumulator {
 public:
  explicit ColumnAccumulator(Eigen::Index rows)
      : mark_(static_cast<std::size_t>(rows), -1), value_(static_cast<std::size_t>(rows)) {}
  // Begins a column (every call a fresh one, even for a column computed before).
  // `values` false: only the rows are wanted (a rule may then add any value).
  void start(bool values = true) {
    ++stamp_;
    rows_.clear();
    values_ = values;
  }
  bool values() const { return values_; }
  void add(int row, double v) {
    const auto r = static_cast<std::size_t>(row);
    if (mark_[r] != stamp_) {
      mark_[r] = stamp_;
      value_[r] = v;
      rows_.push_back(row);
    } else {
      value_[r] += v;
    }
  }
  // The rows added since start(), in first-add order; sort_rows() sorts them.
  const std::vector<int>& rows() const { return rows_; }
  void sort_rows() { std::sort(rows_.begin(), rows_.end()); }
  double value(int row) const { return value_[static_cast<std::size_t>(row)]; }

 private:
  std::vector<std::int64_t> mark_;  // the start() that last touched each row
  std::vector<double> value_;
  std::vector<int> rows_;
  std::int64_t stamp_ = 0;
  bool values_ = true;
};

// A (rows × cols) with column c given by column(c, acc) calling acc.add(row, value). With
// drop_zeros, entries that sum to exactly 0 are left out (Eigen's pruned(0, 0)); otherwise
// every added row is an entry. `column` must be thread-safe and deterministic: it is called
// twice per column, possibly from different threads; without drop_zeros the first call only
// counts rows (acc.values() false), so a rule may skip computing values there.
template <class Column>
SparseMatrix assemble_columns(Eigen::Index rows, Eigen::Index cols, bool drop_zeros,
                              Column&& column) {
  SparseMatrix A(rows, cols);  // compressed; outer index all zero
  int* outer = A.outerIndexPtr();
#pragma omp parallel
  {
    ColumnAccumulator acc(rows);
#pragma omp for schedule(static)
    for (Eigen::Index c = 0; c < cols; ++c) {
      acc.start(drop_zeros);
      column(c, acc);
      int count = static_cast<int>(acc.rows().size());
      if (drop_zeros)
        for (int r : acc.rows()) count -= acc.value(r) == 0.0;
      outer[c + 1] = count;
    }
#pragma omp single
    {
      for (Eigen::Index c = 0; c < cols; ++c) outer[c + 1] += outer[c];
      A.resizeNonZeros(outer[cols]);
    }  // implicit barrier: every thread sees the offsets and the storage
    int* inner = A.innerIndexPtr();
    double* values = A.valuePtr();
#pragma omp for schedule(static)
    for (Eigen::Index c = 0; c < cols; ++c) {
      acc.start();
      column(c, acc);
      acc.sort_rows();
      int k = outer[c];
      for (int r : acc.rows()) {
        const double v = acc.value(r);
        if (drop_zeros && v == 0.0) continue;
        inner[k] = r;
        values[k++] = v;
      }
    }
  }
  return A;
}

}  // namespace hdeform
