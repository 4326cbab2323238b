#include "job_file.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <map>
#include <set>
#include <unordered_map>

namespace hdeform::cli {

namespace fs = std::filesystem;

std::string file_name_part(std::string_view name) {
  std::string out;
  out.reserve(std::min(name.size(), kMaxNamePart));
  for (const char ch : name) {
    const unsigned char c = static_cast<unsigned char>(ch);
    const bool keep = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') ||
                      c == '.' || c == '_' || c == '-';
    out += keep ? ch : '_';
  }
  for (char& c : out) {  // no leading '.' (hidden files, "." and "..") or '-' (options)
    if (c != '.' && c != '-') break;
    c = '_';
  }
  if (out.empty()) out = "_";
  if (out.size() > kMaxNamePart) {
    std::uint64_t h = 1469598103934665603ull;  // FNV-1a of the whole name: distinct long
    for (const char c : name) {                 // names stay distinct (collisions are checked)
      h ^= static_cast<unsigned char>(c);
      h *= 1099511628211ull;
    }
    char hex[17];
    std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(h));
    out = out.substr(0, kMaxNamePart - 17) + "_" + hex;
  }
  return out;
}

bool is_plain_file_name(std::string_view name) {
  if (name.empty() || name.size() > 255 || name[0] == '.' || name[0] == '-') return false;
  for (const char c : name)
    if (!((c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') ||
          c == '.' || c == '_' || c == '-'))
      return false;
  return true;
}

std::string subst_mesh(std::string s, const std::string& mesh) {
  for (std::size_t at = 0; (at = s.find("{mesh}", at)) != std::string::npos; at += mesh.size())
    s.replace(at, 6, mesh);
  return s;
}

std::string beta_tag(double beta) {
  if (is_auto(beta)) return "auto";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", beta);
  return buf;
}

std::string item_file_name(const Job& job, const MeshEntry& m, const ConstraintEntry& c,
                           const TransformEntry& t, double beta) {
  return m.file_part + "-" + c.file_part + "-" + t.file_part + "-b" + beta_tag(beta) + "." +
         job.format;
}

std::string animation_file_name(const Job& job, const MeshEntry& m, const ConstraintEntry& c,
                                double beta) {
  return m.file_part + "-" + c.file_part + "-" + job.animation.file_part + "-b" + beta_tag(beta) +
         ".glb";
}

fs::path output_path_inside(const fs::path& dir, const std::string& file_name) {
  if (!is_plain_file_name(file_name))
    throw CliError("'" + file_name + "' is not a plain file name");
  std::error_code ec;
  const fs::path root = fs::canonical(dir, ec);
  if (ec) throw CliError(dir.string() + ": " + ec.message());
  const fs::path path = root / file_name;
  if (fs::is_symlink(fs::symlink_status(path, ec)))
    throw CliError(path.string() + ": is a symbolic link; not writing through it");
  const fs::path parent = fs::weakly_canonical(path, ec).parent_path();
  if (ec || parent != root)
    throw CliError(path.string() + ": not inside the output folder " + root.string());
  return path;
}

namespace {

using json = nlohmann::json;

std::string line_of(std::string_view text, std::size_t byte) {
  const std::size_t end = std::min(byte, text.size());
  return std::to_string(1 + std::count(text.begin(), text.begin() + static_cast<long>(end), '\n'));
}

std::string lower(std::string s) {
  for (char& c : s)
    if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
  return s;
}

std::string g17(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

// Quotes a name for a message: printable ASCII as is, other bytes as \xHH.
std::string quote_name(std::string_view s) {
  std::string out = "'";
  std::size_t n = 0;
  for (const char ch : s) {
    if (++n > 80) {
      out += "…";
      break;
    }
    const unsigned char c = static_cast<unsigned char>(ch);
    if (c >= 0x20 && c < 0x7f) {
      out += ch;
    } else {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02x", c);
      out += buf;
    }
  }
  return out + "'";
}

class Parser {
 public:
  Parser(std::string file, std::string dir) : file_(std::move(file)), dir_(std::move(dir)) {}

  [[noreturn]] void fail(const std::string& where, const std::string& problem) const {
    throw parse_error(file_, 0, (where.empty() ? "" : where + ": ") + problem);
  }

  // Runs a text parser; its CliError becomes "FILE: message".
  template <class F>
  auto checked(F&& f) const -> decltype(f()) {
    try {
      return f();
    } catch (const FileError&) {
      throw;
    } catch (const CliError& e) {
      throw parse_error(file_, 0, e.what());
    }
  }

  void keys(const json& obj, const std::string& where, const std::set<std::string>& allowed) const {
    if (!obj.is_object()) fail(where, "expected an object");
    for (const auto& [k, v] : obj.items())
      if (!allowed.count(k)) fail(where, "unknown key " + quote_name(k));
  }

  std::string str(const json& v, const std::string& where) const {
    if (!v.is_string()) fail(where, "expected a string");
    return v.get<std::string>();
  }

  std::string name(const json& v, const std::string& where) const {
    std::string s = str(v, where);
    if (s.empty()) fail(where, "empty name");
    return s;
  }

  double number(const json& v, const std::string& where) const {
    if (!v.is_number()) fail(where, "expected a number");
    const double d = v.get<double>();
    if (!std::isfinite(d)) fail(where, "not a finite number");
    return d;
  }

  const json& array(const json& v, const std::string& where, const char* of) const {
    if (!v.is_array() || v.empty()) fail(where, std::string("expected a non-empty array of ") + of);
    return v;
  }

  // A string, a number or an array of numbers → the command line's comma syntax.
  std::string numbers_text(const json& v, const std::string& where) const {
    if (v.is_string()) return v.get<std::string>();
    if (v.is_number()) return g17(number(v, where));
    if (v.is_array()) {
      std::string s;
      for (std::size_t i = 0; i < v.size(); ++i) {
        if (i) s += ",";
        s += g17(number(v[i], where + "[" + std::to_string(i) + "]"));
      }
      return s;
    }
    fail(where, "expected a string, a number or an array of numbers");
  }

  // "SEL|SEL" or ["SEL", "SEL"] (united); each string's syntax checked.
  RegionText region(const json& v, const std::string& where) const {
    RegionText r;
    if (v.is_string()) {
      r.push_back(v.get<std::string>());
      checked([&] { return parse_selectors_spec(r.back(), where); });
    } else if (v.is_array()) {
      if (v.empty()) fail(where, "empty region");
      for (std::size_t i = 0; i < v.size(); ++i) {
        const std::string w = where + "[" + std::to_string(i) + "]";
        r.push_back(str(v[i], w));
        checked([&] { return parse_selectors_spec(r.back(), w); });
      }
    } else {
      fail(where, "expected a selector string or an array of selector strings");
    }
    return r;
  }

  TransformText transform_text(const json& t, const std::string& where, bool with_name) const {
    if (with_name)
      keys(t, where, {"name", "rotate", "translate", "scale", "pivot", "def"});
    else
      keys(t, where, {"rotate", "translate", "scale", "pivot", "def"});
    TransformText tt;
    if (t.contains("rotate")) tt.rotate = numbers_text(t["rotate"], where + ".rotate");
    if (t.contains("translate")) tt.translate = numbers_text(t["translate"], where + ".translate");
    if (t.contains("scale")) tt.scale = numbers_text(t["scale"], where + ".scale");
    if (t.contains("pivot")) tt.pivot = numbers_text(t["pivot"], where + ".pivot");
    if (t.contains("def")) {
      tt.def_file = str(t["def"], where + ".def");
      if (tt.def_file.empty()) fail(where + ".def", "empty file name");
    }
    checked([&] { return parse_transform_values(tt, where); });
    return tt;
  }

  json parse_json(std::string_view text) const {
    if (text.size() > kMaxJobBytes)
      fail("", "larger than " + std::to_string(kMaxJobBytes >> 20) + " MiB");
    const json::parser_callback_t depth_limit = [this](int depth, json::parse_event_t,
                                                       json&) -> bool {
      if (depth > kMaxJobDepth)
        fail("", "nested deeper than " + std::to_string(kMaxJobDepth) + " levels");
      return true;
    };
    try {
      return json::parse(text.begin(), text.end(), depth_limit);
    } catch (const json::parse_error& e) {
      std::string msg = e.what();
      // "[json.exception.parse_error.101] parse error at line 3, column 5: syntax error …"
      const auto column = msg.find("column");
      const auto colon = column == std::string::npos ? column : msg.find(": ", column);
      if (colon != std::string::npos) msg = msg.substr(colon + 2);
      throw FileError(file_ + ":" + line_of(text, e.byte > 0 ? e.byte - 1 : 0) + ": " + msg);
    } catch (const json::exception& e) {
      // e.g. out_of_range.406 "number overflow parsing '1e400'"
      std::string msg = e.what();
      const auto bracket = msg.find("] ");
      if (bracket != std::string::npos) msg = msg.substr(bracket + 2);
      throw parse_error(file_, 0, msg);
    }
  }

  Job parse(std::string_view text) const {
    const json doc = parse_json(text);
    Job job;
    job.file = file_;
    job.dir = dir_;
    keys(doc, "", {"name", "output_dir", "summary", "format", "beta_units", "betas", "meshes",
                   "constraints", "transforms", "description", "animation"});
    if (doc.contains("description")) str(doc["description"], "description");
    job.name = doc.contains("name") ? name(doc["name"], "name") : fs::path(file_).stem().string();
    if (job.name.empty()) job.name = "job";
    if (doc.contains("output_dir")) {
      job.output_dir = str(doc["output_dir"], "output_dir");
      const fs::path p(job.output_dir);
      if (job.output_dir.empty()) fail("output_dir", "empty");
      if (job.output_dir.find('\0') != std::string::npos) fail("output_dir", "contains a NUL byte");
      if (p.is_absolute() || p.has_root_name() || p.has_root_directory())
        fail("output_dir", quote_name(job.output_dir) +
                               " is absolute: a job writes below the working directory (use -o)");
      for (const auto& part : p)
        if (part == "..")
          fail("output_dir", quote_name(job.output_dir) +
                                 " leaves the working directory ('..'); use -o");
    } else {
      job.output_dir = "hdeform-out/" + file_name_part(job.name);
    }
    if (doc.contains("summary")) {
      job.summary = str(doc["summary"], "summary");
      if (job.summary.empty() || job.summary != file_name_part(job.summary))
        fail("summary", quote_name(job.summary) +
                            " is not a plain file name ([A-Za-z0-9._-], no leading '.' or '-', "
                            "at most " + std::to_string(kMaxNamePart) + " characters)");
    }
    if (doc.contains("format")) {
      job.format = str(doc["format"], "format");
      if (job.format != "glb" && job.format != "obj" && job.format != "off" &&
          job.format != "ply" && job.format != "none")
        fail("format", quote_name(job.format) + " is not glb, obj, off, ply or none");
    }
    if (doc.contains("beta_units")) {
      job.beta_units = str(doc["beta_units"], "beta_units");
      if (job.beta_units != "area" && job.beta_units != "raw")
        fail("beta_units", "expected \"area\" or \"raw\"");
    }
    if (doc.contains("betas")) {
      const json& b = doc["betas"];
      if (!b.is_array() || b.empty())
        fail("betas", "expected a non-empty array of numbers (or \"auto\")");
      job.betas.clear();
      for (std::size_t i = 0; i < b.size(); ++i) {
        const std::string w = "betas[" + std::to_string(i) + "]";
        if (b[i].is_string()) {
          if (b[i].get<std::string>() != "auto") fail(w, "expected a number or \"auto\"");
          job.betas.push_back(kAutoBeta);
          continue;
        }
        if (!b[i].is_number()) fail(w, "expected a number or \"auto\"");
        const double v = number(b[i], w);
        if (v < 0 || v >= 1) fail(w, beta_tag(v) + " is outside [0, 1)");
        job.betas.push_back(v);
      }
    }

    if (!doc.contains("meshes")) fail("meshes", "missing (a non-empty array)");
    const json& meshes = array(doc["meshes"], "meshes", "meshes");
    for (std::size_t i = 0; i < meshes.size(); ++i)
      job.meshes.push_back(mesh(meshes[i], "meshes[" + std::to_string(i) + "]"));

    if (!doc.contains("constraints")) fail("constraints", "missing (a non-empty array)");
    const json& constraints = array(doc["constraints"], "constraints", "constraint sets");
    for (std::size_t i = 0; i < constraints.size(); ++i)
      job.constraints.push_back(constraint(constraints[i], i));

    if (doc.contains("transforms")) {
      const json& transforms = array(doc["transforms"], "transforms", "transforms");
      for (std::size_t i = 0; i < transforms.size(); ++i)
        job.transforms.push_back(transform(transforms[i], i));
    } else {
      TransformEntry rest;
      rest.name = rest.file_part = "rest";
      rest.where = "transforms";
      rest.transforms.emplace_back();
      job.transforms.push_back(rest);
    }

    for (const auto& t : job.transforms) {
      if (!t.per_handle) continue;
      for (const auto& c : job.constraints)
        if (t.transforms.size() != c.handle_count())
          fail(t.where + ".handles", std::to_string(t.transforms.size()) + " transforms for " +
                                         std::to_string(c.handle_count()) +
                                         " handles of constraints " + quote_name(c.name));
    }
    if (doc.contains("animation")) job.animation = animation(doc["animation"], job);
    check_names(job);
    return job;
  }

  AnimationEntry animation(const json& a, const Job& job) const {
    const std::string w = "animation";
    keys(a, w, {"name", "fps", "easing", "energies", "up", "keys"});
    AnimationEntry e;
    e.present = true;
    if (a.contains("name")) {
      e.name = name(a["name"], w + ".name");
      e.file_part = file_name_part(e.name);
    }
    if (a.contains("fps")) {
      e.fps = number(a["fps"], w + ".fps");
      if (e.fps <= 0 || e.fps > kMaxAnimationFps) fail(w + ".fps", g17(e.fps) + " is not in (0, 120]");
    }
    if (a.contains("easing")) {
      e.easing = str(a["easing"], w + ".easing");
      if (e.easing != "linear" && e.easing != "smoothstep")
        fail(w + ".easing", "expected \"linear\" or \"smoothstep\"");
    }
    if (a.contains("energies")) {
      if (!a["energies"].is_boolean()) fail(w + ".energies", "expected true or false");
      e.energies = a["energies"].get<bool>();
    }
    if (a.contains("up")) {
      e.up = str(a["up"], w + ".up");
      if (e.up != "y" && e.up != "z") fail(w + ".up", "expected \"y\" or \"z\"");
    }
    if (!a.contains("keys")) fail(w + ".keys", "missing (a non-empty array)");
    const json& ks = array(a["keys"], w + ".keys", "keys");
    for (std::size_t i = 0; i < ks.size(); ++i) {
      AnimationKey k;
      k.where = w + ".keys[" + std::to_string(i) + "]";
      keys(ks[i], k.where, {"time", "transform", "beta"});
      if (!ks[i].contains("time") || !ks[i].contains("transform"))
        fail(k.where, "expected \"time\" and \"transform\" (and optionally \"beta\")");
      k.time = number(ks[i]["time"], k.where + ".time");
      if (k.time < 0) fail(k.where + ".time", g17(k.time) + " is negative");
      if (i > 0 && !(k.time > e.keys.back().time))
        fail(k.where + ".time", g17(k.time) + " is not after the previous key's " +
                                    g17(e.keys.back().time));
      k.transform = name(ks[i]["transform"], k.where + ".transform");
      k.transform_index = kRestTransform;
      for (std::size_t t = 0; t < job.transforms.size(); ++t)
        if (job.transforms[t].name == k.transform) k.transform_index = t;
      if (k.transform_index == kRestTransform && k.transform != "rest")
        fail(k.where + ".transform", quote_name(k.transform) +
                                         " is not the name of a \"transforms\" entry (or \"rest\")");
      if (ks[i].contains("beta")) {
        k.has_beta = true;
        k.beta = number(ks[i]["beta"], k.where + ".beta");
        if (k.beta < 0 || k.beta >= 1) fail(k.where + ".beta", beta_tag(k.beta) + " is outside [0, 1)");
      }
      e.keys.push_back(std::move(k));
    }
    for (double b : job.betas)
      if (is_auto(b))
        fail("betas", "\"auto\" cannot be animated (the timeline needs one β per item); give "
                      "numbers, or β per key");
    if (job.format == "glb")
      for (const auto& t : job.transforms)
        if (lower(t.file_part) == lower(e.file_part))
          fail(w + ".name", quote_name(e.name) + " gives the same file names as " + t.where +
                                ": rename one");
    return e;
  }

  MeshEntry mesh(const json& m, const std::string& w) const {
    MeshEntry e;
    if (m.is_string()) {
      const std::string s = m.get<std::string>();
      if (s.empty()) fail(w, "empty mesh name");
      const std::string p = resolve(s);
      std::error_code ec;
      if (fs::is_regular_file(p, ec)) {
        e.source = p;
        e.name = fs::path(p).stem().string();
      } else if (s.find('/') != std::string::npos || fs::path(s).has_extension()) {
        fail(w, p + ": no such file");
      } else {
        e.source = e.name = s;
      }
    } else {
      keys(m, w, {"name", "file", "library"});
      if (m.contains("file") == m.contains("library"))
        fail(w, "give exactly one of \"file\" and \"library\"");
      if (m.contains("file")) {
        const std::string f = str(m["file"], w + ".file");
        if (f.empty()) fail(w + ".file", "empty file name");
        e.source = resolve(f);
        std::error_code ec;
        if (!fs::is_regular_file(e.source, ec)) fail(w + ".file", e.source + ": no such file");
        e.name = fs::path(e.source).stem().string();
      } else {
        e.source = e.name = name(m["library"], w + ".library");
      }
      if (m.contains("name")) e.name = name(m["name"], w + ".name");
    }
    if (e.name.empty()) e.name = "mesh";
    e.file_part = file_name_part(e.name);
    return e;
  }

  ConstraintEntry constraint(const json& c, std::size_t i) const {
    ConstraintEntry e;
    e.where = "constraints[" + std::to_string(i) + "]";
    const std::string& w = e.where;
    keys(c, w, {"name", "sel", "fixed", "handles", "local_beta"});
    e.name = c.contains("name") ? name(c["name"], w + ".name") : "c" + std::to_string(i);
    e.file_part = file_name_part(e.name);
    if (c.contains("sel")) {
      e.sel = str(c["sel"], w + ".sel");
      if (e.sel.empty()) fail(w + ".sel", "empty file name");
    }
    if (c.contains("fixed")) {
      e.has_fixed = true;
      e.fixed = region(c["fixed"], w + ".fixed");
    }
    if (c.contains("handles")) {
      const json& hs = array(c["handles"], w + ".handles", "regions");
      for (std::size_t h = 0; h < hs.size(); ++h)
        e.handles.push_back(region(hs[h], w + ".handles[" + std::to_string(h) + "]"));
    }
    if (e.handles.empty() && e.sel.empty()) fail(w, "no handle: give \"sel\" or \"handles\"");
    if (c.contains("local_beta")) {
      // ["SEL@BETA[@RADIUS]", {"region": REGION, "beta": B, "radius": R}, …]
      const json& ls = array(c["local_beta"], w + ".local_beta", "entries");
      for (std::size_t k = 0; k < ls.size(); ++k) {
        LocalBetaEntry l;
        l.where = w + ".local_beta[" + std::to_string(k) + "]";
        const json& v = ls[k];
        if (v.is_string()) {
          l.text = v.get<std::string>();
          const LocalBetaSpec spec = checked([&] { return parse_local_beta_spec(l.text, l.where); });
          l.beta = spec.beta;
          l.radius = spec.radius;
        } else {
          keys(v, l.where, {"region", "beta", "radius"});
          if (!v.contains("region") || !v.contains("beta"))
            fail(l.where, "expected \"region\" and \"beta\" (and optionally \"radius\")");
          l.region = region(v["region"], l.where + ".region");
          l.beta = number(v["beta"], l.where + ".beta");
          l.radius = v.contains("radius") ? number(v["radius"], l.where + ".radius") : 0.0;
          checked([&] {
            check_local_beta(l.beta, l.radius, l.where);
            return 0;
          });
        }
        e.local_beta.push_back(std::move(l));
      }
    }
    return e;
  }

  TransformEntry transform(const json& t, std::size_t i) const {
    TransformEntry e;
    e.where = "transforms[" + std::to_string(i) + "]";
    const std::string& w = e.where;
    if (!t.is_object()) fail(w, "expected an object");
    e.name = t.contains("name") ? name(t["name"], w + ".name") : "t" + std::to_string(i);
    e.file_part = file_name_part(e.name);
    if (t.contains("handles")) {
      keys(t, w, {"name", "handles"});
      const json& hs = t["handles"];
      if (!hs.is_array() || hs.empty())
        fail(w + ".handles", "expected a non-empty array, one transform per handle");
      e.per_handle = true;
      for (std::size_t h = 0; h < hs.size(); ++h)
        e.transforms.push_back(
            transform_text(hs[h], w + ".handles[" + std::to_string(h) + "]", false));
    } else {
      e.transforms.push_back(transform_text(t, w, true));
    }
    return e;
  }

  // Names in output file names: no two entries of a list may give the same file name part
  // (compared without case: some file systems ignore it), and no two items the same file.
  void check_names(const Job& job) const {
    auto unique = [&](auto const& entries, auto where_of) {
      std::unordered_map<std::string, std::size_t> seen;
      for (std::size_t i = 0; i < entries.size(); ++i) {
        const auto [it, fresh] = seen.emplace(lower(entries[i].file_part), i);
        if (fresh) continue;
        const auto& a = entries[it->second];
        const auto& b = entries[i];
        if (a.name == b.name)
          fail(where_of(i), "duplicate name " + quote_name(b.name) + " (as " + where_of(it->second) +
                                ")");
        fail(where_of(i), "name " + quote_name(b.name) + " and " + where_of(it->second) + " name " +
                              quote_name(a.name) + " give the same output file name part " +
                              quote_name(b.file_part) + "; rename one");
      }
    };
    unique(job.meshes, [](std::size_t i) { return "meshes[" + std::to_string(i) + "]"; });
    unique(job.constraints,
           [&](std::size_t i) { return job.constraints[i].where; });
    unique(job.transforms, [&](std::size_t i) { return job.transforms[i].where; });
    std::map<std::string, std::size_t> tags;
    for (std::size_t i = 0; i < job.betas.size(); ++i) {
      const auto [it, fresh] = tags.emplace(beta_tag(job.betas[i]), i);
      if (!fresh)
        fail("betas[" + std::to_string(i) + "]",
             "same as betas[" + std::to_string(it->second) + "] (" + it->first +
                 ") in output file names");
    }

    double items = 1;
    for (const double n : {double(job.meshes.size()), double(job.constraints.size()),
                           double(job.betas.size()), double(job.transforms.size())})
      items *= n;
    if (items > double(kMaxJobItems))
      fail("", g17(items) + " items (meshes x constraints x betas x transforms); at most " +
                   std::to_string(kMaxJobItems));

    if (job.format == "none") return;
    // Parts without '-' split unambiguously; with one, "a-b"+"c" and "a"+"b-c" may meet.
    bool dashes = false;
    for (const auto& m : job.meshes) dashes |= m.file_part.find('-') != std::string::npos;
    for (const auto& c : job.constraints) dashes |= c.file_part.find('-') != std::string::npos;
    for (const auto& t : job.transforms) dashes |= t.file_part.find('-') != std::string::npos;
    const std::string summary = lower(job.summary);
    const bool summary_like_item =
        summary.size() > job.format.size() &&
        summary.compare(summary.size() - job.format.size() - 1, std::string::npos,
                        "." + job.format) == 0;
    if (!dashes && !summary_like_item) return;
    std::unordered_map<std::string, std::string> files;  // lower-case file name → item
    for (const auto& m : job.meshes)
      for (const auto& c : job.constraints)
        for (const double b : job.betas)
          for (const auto& t : job.transforms) {
            const std::string f = item_file_name(job, m, c, t, b);
            const std::string item = "item (" + quote_name(m.name) + ", " + quote_name(c.name) + ", " +
                                     quote_name(t.name) + ", beta " + beta_tag(b) + ")";
            if (lower(f) == summary)
              fail("summary", quote_name(job.summary) + " is also the output file of " + item);
            const auto [it, fresh] = files.emplace(lower(f), item);
            if (!fresh)
              fail("", it->second + " and " + item + " would both write " + quote_name(f) +
                           "; rename one");
          }
  }

 private:
  std::string resolve(const std::string& path) const { return resolve_path(path, dir_); }

  std::string file_;
  std::string dir_;
};

}  // namespace

Job parse_job(std::string_view text, const std::string& file, const std::string& dir) {
  return Parser(file, dir).parse(text);
}

}  // namespace hdeform::cli
