#include "constraint_options.h"

#include "output.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
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

std::string resolve_path(const std::string& path, const std::string& base_dir) {
  if (base_dir.empty() || path.empty() || fs::path(path).is_absolute()) return path;
  return (fs::path(base_dir) / path).lexically_normal().string();
}

namespace {

std::string trim(std::string s) {
  const auto b = s.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) return "";
  const auto e = s.find_last_not_of(" \t\r\n");
  return s.substr(b, e - b + 1);
}

double to_double(const std::string& token, const std::string& where) {
  const std::string t = trim(token);
  if (t.empty()) throw CliError(where + ": empty number");
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(t.c_str(), &end);
  if (end != t.c_str() + t.size() || errno == ERANGE)
    throw CliError(where + ": '" + t + "' is not a number");
  if (!std::isfinite(v)) throw CliError(where + ": '" + t + "' is not finite");
  return v;
}

pb::Vec3 vec3(const std::vector<double>& v, std::size_t at = 0) {
  pb::Vec3 r;
  r.set_x(v[at]);
  r.set_y(v[at + 1]);
  r.set_z(v[at + 2]);
  return r;
}

}  // namespace

std::vector<double> parse_numbers(const std::string& text, const std::string& where,
                                  std::size_t count) {
  std::vector<double> out;
  std::string token;
  std::istringstream ss(text);
  while (std::getline(ss, token, ',')) out.push_back(to_double(token, where));
  if (!text.empty() && text.back() == ',') throw CliError(where + ": trailing ','");
  if (count > 0 && out.size() != count)
    throw CliError(where + ": expected " + std::to_string(count) + " comma-separated numbers, got " +
                   std::to_string(out.size()) + " in '" + text + "'");
  return out;
}

pb::Selector parse_selector(const std::string& raw, const std::string& where,
                            const std::string& base_dir) {
  const std::string text = trim(raw);
  const auto colon = text.find(':');
  if (colon == std::string::npos)
    throw CliError(where + ": selector '" + text +
                   "' needs a kind: ids:, box:, sphere:, half: or sel:");
  const std::string kind = text.substr(0, colon);
  const std::string args = text.substr(colon + 1);
  const std::string w = where + " '" + text + "'";
  pb::Selector s;
  if (kind == "ids") {
    auto* ids = s.mutable_ids();
    for (double v : parse_numbers(args, w)) {
      if (v != std::floor(v) || v < 0 || v > 2147483647.0)
        throw CliError(w + ": vertex id " + std::to_string(v) + " is not a non-negative integer");
      ids->add_ids(static_cast<std::int32_t>(v));
    }
    if (ids->ids_size() == 0) throw CliError(w + ": no vertex ids");
  } else if (kind == "box") {
    const auto v = parse_numbers(args, w, 6);
    *s.mutable_box()->mutable_min() = vec3(v, 0);
    *s.mutable_box()->mutable_max() = vec3(v, 3);
  } else if (kind == "sphere") {
    const auto v = parse_numbers(args, w, 4);
    *s.mutable_sphere()->mutable_center() = vec3(v, 0);
    s.mutable_sphere()->set_radius(v[3]);
  } else if (kind == "half") {
    const auto v = parse_numbers(args, w, 4);
    *s.mutable_half_space()->mutable_normal() = vec3(v, 0);
    s.mutable_half_space()->set_offset(v[3]);
  } else if (kind == "sel") {
    const auto last = args.rfind(':');
    if (last == std::string::npos || last == 0)
      throw CliError(w + ": expected sel:FILE:LABEL");
    const std::string file = resolve_path(args.substr(0, last), base_dir);
    const double label = to_double(args.substr(last + 1), w);
    if (label != std::floor(label) || label < 0 || label > 2)
      throw CliError(w + ": label must be 0, 1 or 2");
    s.mutable_sel()->set_content(read_file(file));
    s.mutable_sel()->set_label(static_cast<std::int32_t>(label));
  } else {
    throw CliError(where + ": unknown selector kind '" + kind +
                   "' (ids, box, sphere, half or sel)");
  }
  return s;
}

pb::LocalBeta make_local_beta(pb::Region region, double beta, double radius,
                              const std::string& where) {
  if (!(beta >= 0 && beta < 1))
    throw CliError(where + ": beta " + g6(beta) + " is outside [0, 1)");
  if (!(radius >= 0)) throw CliError(where + ": radius must be >= 0");
  pb::LocalBeta e;
  *e.mutable_region() = std::move(region);
  e.set_beta(beta);
  e.set_falloff_radius(radius);
  return e;
}

pb::LocalBeta parse_local_beta(const std::string& raw, const std::string& where,
                               const std::string& base_dir) {
  const std::string text = trim(raw);
  const std::string w = where + " '" + text + "'";
  std::vector<std::string> parts;
  std::size_t start = 0;
  for (std::size_t at; (at = text.find('@', start)) != std::string::npos; start = at + 1)
    parts.push_back(text.substr(start, at - start));
  parts.push_back(text.substr(start));
  if (parts.size() < 2) throw CliError(w + ": expected SEL@BETA or SEL@BETA@RADIUS");
  auto is_number = [](const std::string& s) {
    const std::string t = trim(s);
    char* end = nullptr;
    std::strtod(t.c_str(), &end);
    return !t.empty() && end == t.c_str() + t.size();
  };
  // From the right: BETA[@RADIUS] are numbers; everything before is the selector text.
  const std::size_t numbers =
      parts.size() >= 3 && is_number(parts.back()) && is_number(parts[parts.size() - 2]) ? 2 : 1;
  std::string sel;
  for (std::size_t i = 0; i + numbers < parts.size(); ++i) sel += (i ? "@" : "") + parts[i];
  const double beta = parse_numbers(parts[parts.size() - numbers], w + ": BETA", 1)[0];
  const double radius = numbers == 2 ? parse_numbers(parts.back(), w + ": RADIUS", 1)[0] : 0.0;
  if (trim(sel).empty()) throw CliError(w + ": no selector before '@'");
  pb::Region region;
  add_selectors(region, sel, where, base_dir);
  return make_local_beta(std::move(region), beta, radius, w);
}

void add_selectors(pb::Region& region, const std::string& text, const std::string& where,
                   const std::string& base_dir) {
  std::string part;
  std::istringstream ss(text);
  bool any = false;
  while (std::getline(ss, part, '|')) {
    if (trim(part).empty()) continue;
    *region.add_selectors() = parse_selector(part, where, base_dir);
    any = true;
  }
  if (!any) throw CliError(where + ": empty selector");
}

pb::HandleTransform parse_transform(const TransformText& t, const std::string& where,
                                    const std::string& base_dir) {
  pb::HandleTransform out;
  if (!t.def_file.empty()) {
    if (!t.rotate.empty() || !t.translate.empty() || !t.scale.empty())
      throw CliError(where + ": a .def matrix excludes rotate/translate/scale");
    const std::string path = resolve_path(t.def_file, base_dir);
    for (double v : parse_def(read_file(path), path)) out.add_matrix(v);
  }
  if (!t.rotate.empty()) {
    const std::string w = where + " rotate";
    std::vector<double> axis_deg;
    const std::string r = trim(t.rotate);
    const auto comma = r.find(',');
    const std::string first = comma == std::string::npos ? r : trim(r.substr(0, comma));
    double ax = 0, ay = 0, az = 0, deg = 0;
    if (first == "x" || first == "y" || first == "z" || first == "X" || first == "Y" ||
        first == "Z") {
      if (comma == std::string::npos) throw CliError(w + ": expected AXIS,DEG");
      deg = parse_numbers(r.substr(comma + 1), w, 1)[0];
      (first == "x" || first == "X" ? ax : first == "y" || first == "Y" ? ay : az) = 1;
    } else {
      const auto v = parse_numbers(r, w, 4);
      ax = v[0], ay = v[1], az = v[2], deg = v[3];
    }
    const double n = std::sqrt(ax * ax + ay * ay + az * az);
    if (n == 0) throw CliError(w + ": the rotation axis is zero");
    const double half = deg * M_PI / 360.0;
    auto* q = out.mutable_rotation();
    q->set_w(std::cos(half));
    q->set_x(std::sin(half) * ax / n);
    q->set_y(std::sin(half) * ay / n);
    q->set_z(std::sin(half) * az / n);
  }
  if (!t.translate.empty())
    *out.mutable_translation() = vec3(parse_numbers(t.translate, where + " translate", 3));
  if (!t.scale.empty()) {
    const auto v = parse_numbers(t.scale, where + " scale");
    if (v.size() == 1)
      out.set_uniform_scale(v[0]);
    else if (v.size() == 3)
      *out.mutable_axis_scale() = vec3(v);
    else
      throw CliError(where + " scale: expected S or SX,SY,SZ");
  }
  if (!t.pivot.empty()) *out.mutable_pivot() = vec3(parse_numbers(t.pivot, where + " pivot", 3));
  return out;
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

}  // namespace hdeform::cli
