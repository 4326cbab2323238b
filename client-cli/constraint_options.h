// Constraint options shared by `deform` and `sweep` (and the parsers `run` reuses):
// selectors, .sel/.def files, one handle transform, β.
#pragma once

#include "common.h"
#include "text_parsers.h"

#include <CLI/CLI.hpp>

#include <array>
#include <optional>
#include <string>
#include <vector>

namespace hdeform::cli {

struct ConstraintOptions {
  std::string sel_file;                // Botsch–Sorkine .sel: label 0 fixed, label 2 handle
  std::string def_file;                // Botsch–Sorkine .def: the handles' 4×4 matrix
  std::vector<std::string> fixed;      // selectors; all united into the fixed region
  std::vector<std::string> handles;    // one handle region per occurrence
  std::string rotate, translate, scale, pivot;
  std::string beta = "0";              // a number, or "auto" (picked by the server)
  std::string beta_units = "area";
  std::vector<std::string> local_betas;  // SEL@BETA[@RADIUS], repeatable
  std::string session;                 // use this existing session instead of creating one
  bool repair = false;                 // repair the uploaded MESH (CreateSessionHeader.repair)
  double merge_tolerance = 0;          // with repair: fraction of the bounding-box diagonal
};

void add_constraint_options(CLI::App& cmd, ConstraintOptions& options);
// --up z|y and --ply auto|ascii|binary (MeshOutputOptions, common.h).
void add_mesh_output_options(CLI::App& cmd, MeshOutputOptions& o);
void add_beta_options(CLI::App& cmd, ConstraintOptions& options, bool with_beta_value);

struct ConstraintSpec {
  pb::Constraints constraints;
  std::vector<pb::HandleTransform> transforms;  // one per handle
};

// --beta auto?
bool beta_is_auto(const ConstraintOptions& options);
// The β the options describe: value (or automatic), units and the --local-beta entries.
// Throws CliError on bad syntax.
pb::Beta build_beta(const ConstraintOptions& options);

// True when the options name any region (else an existing --session keeps its own).
bool has_constraints(const ConstraintOptions& options);
ConstraintSpec build_constraint_spec(const ConstraintOptions& options);

// --- parsers into messages (`where` prefixes error messages, e.g. "--handle" or
// "job.json: transforms[0]"); the syntax is text_parsers.h's; these add the messages and
// read the .sel/.def files.

// One selector: ids:… box:… sphere:… half:… sel:FILE:LABEL (FILE relative to base_dir).
pb::Selector parse_selector(const std::string& text, const std::string& where,
                            const std::string& base_dir = "");
// Selectors joined by '|' → one region (their union).
void add_selectors(pb::Region& region, const std::string& text, const std::string& where,
                   const std::string& base_dir = "");

// A local regularization entry: SEL@BETA or SEL@BETA@RADIUS (SEL as --fixed, '|' unites;
// RADIUS > 0: falloff β·max(0, 1 − d/RADIUS)² around the region; 0 or omitted: the region's
// triangles).
pb::LocalBeta parse_local_beta(const std::string& text, const std::string& where,
                               const std::string& base_dir = "");
pb::LocalBeta make_local_beta(pb::Region region, double beta, double radius,
                              const std::string& where);

pb::HandleTransform parse_transform(const TransformText& text, const std::string& where,
                                    const std::string& base_dir = "");
pb::HandleTransform make_transform(const TransformValues& values, const std::string& where,
                                   const std::string& base_dir = "");

// A .def file's 4×4 row-major matrix; errors are "FILE:LINE: problem".
std::array<double, 16> parse_def(const std::string& content, const std::string& file);

}  // namespace hdeform::cli
