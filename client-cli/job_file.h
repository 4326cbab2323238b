// `hdeform run` job files (docs/cli.md, "Job schema"): JSON → Job, with every check that
// needs neither a server nor the .sel/.def files. Pure: no protobuf, no gRPC (the library
// hdeform_cli_job; the fuzz target tests/fuzz/fuzz_job_file.cpp links only it).
#pragma once

#include "errors.h"
#include "text_parsers.h"

#include <cstddef>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace hdeform::cli {

// A "betas" entry "auto": the server picks β per item, at the item's transforms.
constexpr double kAutoBeta = -1.0;
inline bool is_auto(double beta) { return beta == kAutoBeta; }

// Limits of a job (each breach is a FileError naming it).
constexpr std::size_t kMaxJobBytes = 16u << 20;  // the job file's size
constexpr int kMaxJobDepth = 32;                 // JSON nesting
constexpr std::size_t kMaxJobItems = 100000;     // meshes × constraints × betas × transforms
constexpr std::size_t kMaxNamePart = 64;         // a name's part of an output file name

struct MeshEntry {
  std::string name;       // as given (or the file's stem)
  std::string file_part;  // name, made safe for file names (file_name_part)
  std::string source;     // a file path (resolved against the job's folder) or a library name
};

// A region: selector strings ('|' inside unites too), united; {mesh} not yet substituted.
using RegionText = std::vector<std::string>;

struct LocalBetaEntry {
  std::string where;  // "constraints[0].local_beta[1]"
  std::string text;   // the SEL@BETA[@RADIUS] form, or empty for the object form:
  RegionText region;  // the object form's region, beta and radius
  double beta = 0;
  double radius = 0;
};

struct ConstraintEntry {
  std::string name;
  std::string file_part;
  std::string where;              // "constraints[0]"
  std::string sel;                // a .sel path, or empty
  bool has_fixed = false;
  RegionText fixed;               // replaces the .sel's label 0
  std::vector<RegionText> handles;  // one region per handle; empty: the .sel's label 2
  std::vector<LocalBetaEntry> local_beta;
  std::size_t handle_count() const { return handles.empty() ? 1 : handles.size(); }
};

struct TransformEntry {
  std::string name;
  std::string file_part;
  std::string where;                     // "transforms[0]"
  bool per_handle = false;               // "handles": one transform per handle
  std::vector<TransformText> transforms;  // one (for every handle) or one per handle; the
                                          // numbers are checked, def files not yet read
};

// "animation": keyframes that name entries of "transforms" (docs/cli.md "Animations"). Each
// mesh × constraint set × β gets one animated GLB (SetTimeline + ExportAnimation).
struct AnimationKey {
  std::string where;      // "animation.keys[1]"
  double time = 0;        // seconds
  std::string transform;  // a "transforms" entry's name, or "rest" (identity)
  std::size_t transform_index = 0;  // into Job::transforms; kRestTransform for "rest"
  bool has_beta = false;  // β from this key on (in the job's beta_units)
  double beta = 0;
};
inline constexpr std::size_t kRestTransform = static_cast<std::size_t>(-1);
constexpr double kMaxAnimationFps = 120;

struct AnimationEntry {
  bool present = false;
  std::string name = "animation";
  std::string file_part = "animation";
  double fps = 24;
  std::string easing = "linear";  // linear | smoothstep
  bool energies = false;
  std::string up = "y";           // y | z
  std::vector<AnimationKey> keys;
};

struct Job {
  std::string file;  // for messages
  std::string dir;   // relative input paths resolve here
  std::string name;
  std::string output_dir;
  std::string summary = "summary.csv";  // a plain file name inside output_dir
  std::string format = "glb";
  std::string beta_units = "area";
  std::vector<double> betas{0.0};
  std::vector<MeshEntry> meshes;
  std::vector<ConstraintEntry> constraints;
  std::vector<TransformEntry> transforms;
  AnimationEntry animation;

  std::size_t item_count() const {
    return meshes.size() * constraints.size() * betas.size() * transforms.size();
  }
};

// Parses and checks a job: the schema, names, numbers, selector and transform syntax, the
// number of per-handle transforms against every constraint set, and that no two items write
// the same output file. `file` names the job in messages; `dir` is the folder relative paths
// resolve against (mesh paths are looked up there: a string mesh entry is a file when such
// a file exists). Throws FileError ("FILE: where: problem" or "FILE:LINE: problem") on any
// bad input, and nothing else for any input (std::bad_alloc aside).
Job parse_job(std::string_view text, const std::string& file, const std::string& dir);

// A name's part of an output file name: [A-Za-z0-9._-] kept, every other byte '_', no
// leading '.' or '-', never empty, at most kMaxNamePart characters (a longer name keeps
// its start and gets a hash of the whole name).
std::string file_name_part(std::string_view name);

// A plain file name: 1 to 255 bytes of [A-Za-z0-9._-], not starting with '.' or '-'.
bool is_plain_file_name(std::string_view name);

// "{mesh}" replaced by `mesh` everywhere.
std::string subst_mesh(std::string s, const std::string& mesh);

// The output file of one item: MESH-CONSTRAINTS-TRANSFORM-bBETA.EXT (a plain file name).
std::string item_file_name(const Job& job, const MeshEntry& m, const ConstraintEntry& c,
                           const TransformEntry& t, double beta);
// The animated GLB of one mesh × constraints × β: MESH-CONSTRAINTS-ANIMATION-bBETA.glb.
std::string animation_file_name(const Job& job, const MeshEntry& m, const ConstraintEntry& c,
                                double beta);
// "auto" or %.6g.
std::string beta_tag(double beta);

// dir / file_name, after checking that the file's canonical parent is the canonical `dir`
// (which must exist) and that the path is not a symbolic link. Throws CliError.
std::filesystem::path output_path_inside(const std::filesystem::path& dir,
                                         const std::string& file_name);

}  // namespace hdeform::cli
