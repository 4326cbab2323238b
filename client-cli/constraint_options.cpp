#include "constraint_options.h"

#include "output.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <sstream>

namespace hdeform::cli {

namespace fs = std::filesystem;

void add_constraint_options(CLI::App& cmd, ConstraintOptions& o) {
  auto* sel = cmd.add_option("--sel", o.sel_file,
                             "Botsch-Sorkine .sel file: label 0 = fixed, label 2 = the handle")
                  ->check(CLI::ExistingFile);
  auto* def = cmd.add_option("--def", o.def_file,
                             "Botsch-Sorkine .def file: the handles' 4x4 matrix")
                  ->check(CLI::ExistingFile);
  (void)sel;
  cmd.add_option("--fixed", o.fixed,
                 "fixed-region selector (repeatable, united): ids:1,2 | box:x0,y0,z0,x1,y1,z1 | "
                 "sphere:cx,cy,cz,r | half:nx,ny,nz,offset | sel:FILE:LABEL; join several "
                 "with '|'")
      ->allow_extra_args(false)
      ->type_name("SEL");
  cmd.add_option("--handle", o.handles,
                 "handle-region selector; each --handle is one handle (same syntax as --fixed)")
      ->allow_extra_args(false)
      ->type_name("SEL");
  auto* rot = cmd.add_option("--rotate", o.rotate,
                             "rotation of every handle: AXIS,DEG (AXIS = x, y, z or AX,AY,AZ)");
  auto* tr = cmd.add_option("--translate", o.translate, "translation of every handle: X,Y,Z");
  auto* sc = cmd.add_option("--scale", o.scale, "scale of every handle: S or SX,SY,SZ");
  cmd.add_option("--pivot", o.pivot,
                 "pivot of every handle: X,Y,Z (default: each handle's rest centroid)");
  def->excludes(rot)->excludes(tr)->excludes(sc);
  cmd.add_option("--session", o.session,
                 "use this existing session (needs --server) instead of creating one; MESH is "
                 "then optional");
  auto* repair = cmd.add_flag(
      "--repair", o.repair,
      "repair the uploaded MESH before it is checked: merge coincident vertices, drop "
      "degenerate and duplicate triangles and unused vertices, split bowtie vertices (what "
      "changed is printed on stderr)");
  cmd.add_option("--merge-tolerance", o.merge_tolerance,
                 "with --repair: merge vertices this close, as a fraction of the bounding-box "
                 "diagonal (0 to 0.01; default 0: equal positions only)")
      ->needs(repair)
      ->check(CLI::Range(0.0, 0.01));
}

void add_beta_options(CLI::App& cmd, ConstraintOptions& o, bool with_beta_value) {
  if (with_beta_value)
    cmd.add_option("--beta", o.beta,
                   "regularization weight, 0 <= beta < 1, or 'auto': the server picks it at "
                   "the handles' transforms")
        ->capture_default_str()
        ->type_name("B|auto");
  cmd.add_option("--local-beta", o.local_betas,
                 "local regularization (repeatable): SEL@BETA[@RADIUS] - triangles touching "
                 "the region SEL get BETA; with RADIUS > 0 every triangle within RADIUS (model "
                 "units) of it gets BETA*(1-d/RADIUS)^2; beta = max(--beta, entries)")
      ->allow_extra_args(false)
      ->type_name("SEL@BETA[@R]");
  cmd.add_option("--beta-units", o.beta_units,
                 "area (scale-invariant, default) or raw (the thesis's model units)")
      ->check(CLI::IsMember({"area", "raw"}))
      ->capture_default_str();
}

bool beta_is_auto(const ConstraintOptions& o) { return o.beta == "auto"; }

pb::Beta build_beta(const ConstraintOptions& o) {
  pb::Beta b;
  b.set_units(parse_beta_units(o.beta_units));
  if (beta_is_auto(o))
    b.set_automatic(true);
  else
    b.set_value(parse_numbers(o.beta, "--beta (a number or 'auto')", 1)[0]);
  for (const auto& text : o.local_betas) *b.add_local() = parse_local_beta(text, "--local-beta");
  return b;
}

bool has_constraints(const ConstraintOptions& o) {
  return !o.sel_file.empty() || !o.fixed.empty() || !o.handles.empty();
}

ConstraintSpec build_constraint_spec(const ConstraintOptions& o) {
  ConstraintSpec spec;
  std::string sel_content;
  if (!o.sel_file.empty()) sel_content = read_file(o.sel_file);

  auto* fixed = spec.constraints.mutable_fixed();
  if (!o.fixed.empty()) {
    for (const auto& f : o.fixed) add_selectors(*fixed, f, "--fixed");
  } else if (!o.sel_file.empty()) {
    auto* s = fixed->add_selectors()->mutable_sel();
    s->set_content(sel_content);
    s->set_label(0);
  }

  if (!o.handles.empty()) {
    for (const auto& h : o.handles) add_selectors(*spec.constraints.add_handles(), h, "--handle");
  } else if (!o.sel_file.empty()) {
    auto* s = spec.constraints.add_handles()->add_selectors()->mutable_sel();
    s->set_content(sel_content);
    s->set_label(2);
  }
  if (spec.constraints.handles_size() == 0)
    throw CliError("no handle: give --sel FILE.sel (label 2) or --handle SEL");

  TransformText text{o.rotate, o.translate, o.scale, o.pivot, o.def_file};
  const pb::HandleTransform t = parse_transform(text, "transform");
  spec.transforms.assign(static_cast<std::size_t>(spec.constraints.handles_size()), t);
  return spec;
}

namespace {

pb::Vec3 vec3(double x, double y, double z) {
  pb::Vec3 r;
  r.set_x(x);
  r.set_y(y);
  r.set_z(z);
  return r;
}
pb::Vec3 vec3(const std::array<double, 3>& v) { return vec3(v[0], v[1], v[2]); }

}  // namespace

pb::Selector parse_selector(const std::string& text, const std::string& where,
                            const std::string& base_dir) {
  const SelectorSpec spec = parse_selector_spec(text, where);
  const auto& v = spec.numbers;
  pb::Selector s;
  if (spec.kind == "ids") {
    auto* ids = s.mutable_ids();
    for (double id : v) ids->add_ids(static_cast<std::int32_t>(id));
  } else if (spec.kind == "box") {
    *s.mutable_box()->mutable_min() = vec3(v[0], v[1], v[2]);
    *s.mutable_box()->mutable_max() = vec3(v[3], v[4], v[5]);
  } else if (spec.kind == "sphere") {
    *s.mutable_sphere()->mutable_center() = vec3(v[0], v[1], v[2]);
    s.mutable_sphere()->set_radius(v[3]);
  } else if (spec.kind == "half") {
    *s.mutable_half_space()->mutable_normal() = vec3(v[0], v[1], v[2]);
    s.mutable_half_space()->set_offset(v[3]);
  } else {  // sel
    s.mutable_sel()->set_content(read_file(resolve_path(spec.file, base_dir)));
    s.mutable_sel()->set_label(spec.label);
  }
  return s;
}

pb::LocalBeta make_local_beta(pb::Region region, double beta, double radius,
                              const std::string& where) {
  check_local_beta(beta, radius, where);
  pb::LocalBeta e;
  *e.mutable_region() = std::move(region);
  e.set_beta(beta);
  e.set_falloff_radius(radius);
  return e;
}

pb::LocalBeta parse_local_beta(const std::string& text, const std::string& where,
                               const std::string& base_dir) {
  const LocalBetaSpec spec = parse_local_beta_spec(text, where);
  pb::Region region;
  add_selectors(region, spec.selectors, where, base_dir);
  return make_local_beta(std::move(region), spec.beta, spec.radius,
                         where + " '" + trim(text) + "'");
}

void add_selectors(pb::Region& region, const std::string& text, const std::string& where,
                   const std::string& base_dir) {
  parse_selectors_spec(text, where);  // the whole text's syntax first, then read files
  std::string part;
  std::istringstream ss(text);
  while (std::getline(ss, part, '|'))
    if (!trim(part).empty()) *region.add_selectors() = parse_selector(part, where, base_dir);
}

pb::HandleTransform make_transform(const TransformValues& t, const std::string& /*where*/,
                                   const std::string& base_dir) {
  pb::HandleTransform out;
  if (!t.def_file.empty()) {
    const std::string path = resolve_path(t.def_file, base_dir);
    for (double v : parse_def(read_file(path), path)) out.add_matrix(v);
  }
  if (t.rotation) {
    auto* q = out.mutable_rotation();
    q->set_w((*t.rotation)[0]);
    q->set_x((*t.rotation)[1]);
    q->set_y((*t.rotation)[2]);
    q->set_z((*t.rotation)[3]);
  }
  if (t.translate) *out.mutable_translation() = vec3(*t.translate);
  if (t.scale.size() == 1)
    out.set_uniform_scale(t.scale[0]);
  else if (t.scale.size() == 3)
    *out.mutable_axis_scale() = vec3(t.scale[0], t.scale[1], t.scale[2]);
  if (t.pivot) *out.mutable_pivot() = vec3(*t.pivot);
  return out;
}

pb::HandleTransform parse_transform(const TransformText& t, const std::string& where,
                                    const std::string& base_dir) {
  return make_transform(parse_transform_values(t, where), where, base_dir);
}

std::array<double, 16> parse_def(const std::string& content, const std::string& file) {
  std::array<double, 16> m{};
  std::size_t count = 0;
  std::istringstream in(content);
  std::string line;
  int lineno = 0;
  while (std::getline(in, line)) {
    ++lineno;
    const std::string t = trim(line);
    if (t.empty() || t[0] == '#') continue;
    std::istringstream ls(t);
    std::string tok;
    while (ls >> tok) {
      if (count == 16) throw parse_error(file, lineno, "more than 16 numbers in the matrix");
      char* end = nullptr;
      errno = 0;
      const double v = std::strtod(tok.c_str(), &end);
      if (end != tok.c_str() + tok.size() || errno == ERANGE || !std::isfinite(v))
        throw parse_error(file, lineno, "'" + tok + "' is not a finite number");
      m[count++] = v;
    }
  }
  if (count != 16)
    throw parse_error(file, lineno,
                      "expected a 4x4 matrix (16 numbers), got " + std::to_string(count));
  return m;
}

void add_mesh_output_options(CLI::App& cmd, MeshOutputOptions& o) {
  cmd.add_option("--up", o.up,
                 "the model's up axis: z writes a .glb with a root node turning it to glTF's "
                 "y-up (the buffer keeps the model's own coordinates)")
      ->transform(CLI::CheckedTransformer(
          std::map<std::string, pb::UpAxis>{{"y", pb::UP_AXIS_Y}, {"z", pb::UP_AXIS_Z}},
          CLI::ignore_case))
      ->default_str("y");
  cmd.add_option("--ply", o.ply,
                 "PLY output encoding: auto (binary when the input was a binary PLY), ascii or "
                 "binary")
      ->transform(CLI::CheckedTransformer(
          std::map<std::string, pb::PlyEncoding>{{"auto", pb::PLY_ENCODING_AS_INPUT},
                                                 {"ascii", pb::PLY_ENCODING_ASCII},
                                                 {"binary", pb::PLY_ENCODING_BINARY}},
          CLI::ignore_case))
      ->default_str("auto");
  cmd.add_option("--glb-compression", o.glb_compression,
                 "GLB output geometry: none (float32), quantized (KHR_mesh_quantization: 16-bit "
                 "positions, error <= box side / 131070) or meshopt (the same through "
                 "EXT_meshopt_compression); see docs/api.md 'Compressed GLB'")
      ->transform(CLI::CheckedTransformer(
          std::map<std::string, pb::GlbCompression>{
              {"none", pb::GLB_COMPRESSION_NONE},
              {"quantized", pb::GLB_COMPRESSION_QUANTIZED},
              {"meshopt", pb::GLB_COMPRESSION_MESHOPT}},
          CLI::ignore_case))
      ->default_str("none");
}

}  // namespace hdeform::cli
