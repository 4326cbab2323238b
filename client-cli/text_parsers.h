// The CLI's text syntax — numbers, selectors, local β entries, handle transforms — parsed
// into plain values and checked, without protobuf, gRPC or file access (the job-file parser
// and its fuzz target use these; constraint_options.h turns the values into messages).
// Every function throws CliError with `where` as the message's prefix.
#pragma once

#include "errors.h"

#include <array>
#include <optional>
#include <string>
#include <vector>

namespace hdeform::cli {

std::string trim(std::string s);

// `path` relative to `base_dir` (unchanged when absolute or base_dir is empty).
std::string resolve_path(const std::string& path, const std::string& base_dir);

// One finite number (strtod syntax; "inf", "nan" and overflowing values are rejected).
double to_double(const std::string& token, const std::string& where);

// Comma-separated numbers; `count` > 0 demands exactly that many.
std::vector<double> parse_numbers(const std::string& text, const std::string& where,
                                  std::size_t count = 0);

// One selector: ids:… box:… sphere:… half:… sel:FILE:LABEL (the file is not read).
struct SelectorSpec {
  std::string kind;             // ids, box, sphere, half, sel
  std::vector<double> numbers;  // ids: the ids; box: 6; sphere: 4; half: 4
  std::string file;             // sel: FILE as written
  int label = 0;                // sel: 0, 1 or 2
};
SelectorSpec parse_selector_spec(const std::string& text, const std::string& where);
// Selectors joined by '|' (at least one).
std::vector<SelectorSpec> parse_selectors_spec(const std::string& text, const std::string& where);

// SEL@BETA or SEL@BETA@RADIUS.
struct LocalBetaSpec {
  std::string selectors;  // the SEL text ('|' unites several)
  double beta = 0;
  double radius = 0;
};
LocalBetaSpec parse_local_beta_spec(const std::string& text, const std::string& where);
// 0 <= beta < 1, radius >= 0 (finite).
void check_local_beta(double beta, double radius, const std::string& where);

struct TransformText {
  std::string rotate;     // "AXIS,DEG": AXIS = x|y|z or "AX,AY,AZ"
  std::string translate;  // "X,Y,Z"
  std::string scale;      // "S" or "SX,SY,SZ"
  std::string pivot;      // "X,Y,Z"
  std::string def_file;   // a .def file (replaces rotate/scale/translate)
};

// A handle transform's numbers, checked: finite, a non-zero rotation axis, a .def file
// excluding rotate/translate/scale.
struct TransformValues {
  std::optional<std::array<double, 4>> rotation;  // unit quaternion w, x, y, z
  std::optional<std::array<double, 3>> translate;
  std::vector<double> scale;                      // empty, 1 (uniform) or 3 (per axis)
  std::optional<std::array<double, 3>> pivot;
  std::string def_file;
};
TransformValues parse_transform_values(const TransformText& text, const std::string& where);

}  // namespace hdeform::cli
