// Output of the CLI: aligned tables, CSV (%.17g numbers) and an SVG chart of a β sweep.
#pragma once

#include "common.h"

#include <ostream>
#include <string>
#include <vector>

namespace hdeform::cli {

// The eight columns every report has, in the thesis's order (SPEC.md §Measures) + flips.
struct MeasureColumn {
  const char* label;  // for tables and charts, e.g. "E_iso^N"
  const char* csv;    // CSV header name, e.g. "E_iso_N"
  double (*get)(const pb::Measures&);
  bool integer;
};
const std::vector<MeasureColumn>& measure_columns();

// "%.17g"
std::string g17(double v);
// The shortest text that reads back as exactly v (std::to_chars): 0.1, not
// 0.10000000000000001. For β, which people type and compare.
std::string shortest(double v);
// A short human form ("%.6g").
std::string g6(double v);
// RFC 4180 quoting when needed.
std::string csv_field(const std::string& s);

// "name   value" lines, one per measure.
void print_measures(std::ostream& out, const pb::Measures& m);

struct SweepPoint {
  double beta;
  pb::Measures measures;
};

// The exact CSV header of `sweep`.
std::string sweep_csv_header();  // "beta,E,E_iso_N,...,flips"
std::string sweep_csv(const std::vector<SweepPoint>& rows);
void print_sweep_table(std::ostream& out, const std::vector<SweepPoint>& rows);
// Small multiples, one panel per measure against β.
std::string sweep_svg(const std::vector<SweepPoint>& rows, const std::string& title,
                      const std::string& beta_units);

// A generic aligned text table (first row = header): the first `left_columns` columns
// left-aligned, the rest (numbers) right-aligned.
void print_table(std::ostream& out, const std::vector<std::vector<std::string>>& rows,
                 std::size_t left_columns = 0);

}  // namespace hdeform::cli
