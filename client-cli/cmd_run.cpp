// hdeform run JOB.json: batch jobs — meshes × constraint sets × β × transforms → mesh files
// and a summary CSV, with a progress line per item on stderr. Schema: docs/cli.md.
#include "commands.h"
#include "constraint_options.h"
#include "output.h"

#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>
#include <set>

namespace hdeform::cli {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

struct RunOptions {
  std::string job;
  std::string output_dir;
  bool dry_run = false;
};

struct MeshEntry {
  std::string name;
  std::string source;  // file path or library name
};

struct ConstraintEntry {
  std::string name;
  json spec;
};

struct TransformEntry {
  std::string name;
  json spec;
};

struct Job {
  std::string file;  // for messages
  std::string dir;   // relative input paths resolve here
  std::string name;
  std::string output_dir;
  std::string summary = "summary.csv";
  std::string format = "glb";
  std::string beta_units = "area";
  std::vector<double> betas{0.0};
  std::vector<MeshEntry> meshes;
  std::vector<ConstraintEntry> constraints;
  std::vector<TransformEntry> transforms;
};

// Per mesh, resolved before any call: constraints and transforms with {mesh} substituted.
// A "betas" entry "auto": the server picks β per item, at the item's transforms.
constexpr double kAutoBeta = -1.0;
bool is_auto(double beta) { return beta == kAutoBeta; }

struct Resolved {
  pb::Constraints constraints;
  google::protobuf::RepeatedPtrField<pb::LocalBeta> local;  // the set's "local_beta"
  std::vector<std::vector<pb::HandleTransform>> transforms;  // [transform][handle]
};

std::string subst(std::string s, const std::string& mesh) {
  for (std::size_t at; (at = s.find("{mesh}")) != std::string::npos;) s.replace(at, 6, mesh);
  return s;
}

std::string line_of(const std::string& text, std::size_t byte) {
  const std::size_t end = std::min(byte, text.size());
  return std::to_string(1 + std::count(text.begin(), text.begin() + static_cast<long>(end), '\n'));
}

class JobParser {
 public:
  explicit JobParser(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void fail(const std::string& where, const std::string& problem) const {
    throw parse_error(file_, 0, (where.empty() ? "" : where + ": ") + problem);
  }

  void keys(const json& obj, const std::string& where, const std::set<std::string>& allowed) const {
    if (!obj.is_object()) fail(where, "expected an object");
    for (const auto& [k, v] : obj.items())
      if (!allowed.count(k)) fail(where, "unknown key '" + k + "'");
  }

  std::string str(const json& v, const std::string& where) const {
    if (!v.is_string()) fail(where, "expected a string");
    return v.get<std::string>();
  }

  double number(const json& v, const std::string& where) const {
    if (!v.is_number()) fail(where, "expected a number");
    return v.get<double>();
  }

  // A string, a number or an array of numbers → the CLI's comma syntax.
  std::string numbers_text(const json& v, const std::string& where) const {
    if (v.is_string()) return v.get<std::string>();
    if (v.is_number()) return g17(v.get<double>());
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

  // A region: "SEL|SEL" or ["SEL", "SEL"] (united).
  void region(pb::Region& r, const json& v, const std::string& where, const std::string& dir,
              const std::string& mesh) const {
    if (v.is_string()) {
      add_selectors(r, subst(v.get<std::string>(), mesh), where, dir);
    } else if (v.is_array()) {
      if (v.empty()) fail(where, "empty region");
      for (std::size_t i = 0; i < v.size(); ++i) {
        const std::string w = where + "[" + std::to_string(i) + "]";
        add_selectors(r, subst(str(v[i], w), mesh), w, dir);
      }
    } else {
      fail(where, "expected a selector string or an array of selector strings");
    }
  }

  TransformText transform_text(const json& t, const std::string& where,
                               const std::string& mesh) const {
    keys(t, where, {"rotate", "translate", "scale", "pivot", "def"});
    TransformText tt;
    if (t.contains("rotate")) tt.rotate = numbers_text(t["rotate"], where + ".rotate");
    if (t.contains("translate")) tt.translate = numbers_text(t["translate"], where + ".translate");
    if (t.contains("scale")) tt.scale = numbers_text(t["scale"], where + ".scale");
    if (t.contains("pivot")) tt.pivot = numbers_text(t["pivot"], where + ".pivot");
    if (t.contains("def")) tt.def_file = subst(str(t["def"], where + ".def"), mesh);
    return tt;
  }

  Job parse(const std::string& text) const {
    json doc;
    try {
      doc = json::parse(text);
    } catch (const json::parse_error& e) {
      std::string msg = e.what();
      // "[json.exception.parse_error.101] parse error at line 3, column 5: syntax error …"
      const auto colon = msg.find(": ", msg.find("column"));
      if (colon != std::string::npos) msg = msg.substr(colon + 2);
      throw FileError(file_ + ":" + line_of(text, e.byte > 0 ? e.byte - 1 : 0) + ": " + msg);
    }
    Job job;
    job.file = file_;
    job.dir = fs::path(file_).parent_path().string();
    keys(doc, "", {"name", "output_dir", "summary", "format", "beta_units", "betas", "meshes",
                   "constraints", "transforms", "description"});
    job.name = doc.contains("name") ? str(doc["name"], "name") : fs::path(file_).stem().string();
    job.output_dir = doc.contains("output_dir") ? str(doc["output_dir"], "output_dir")
                                                : "hdeform-out/" + job.name;
    if (doc.contains("summary")) job.summary = str(doc["summary"], "summary");
    if (doc.contains("format")) {
      job.format = str(doc["format"], "format");
      if (job.format != "glb" && job.format != "obj" && job.format != "off" &&
          job.format != "ply" && job.format != "none")
        fail("format", "'" + job.format + "' is not glb, obj, off, ply or none");
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
        if (b[i].is_string()) {
          if (b[i].get<std::string>() != "auto")
            fail("betas[" + std::to_string(i) + "]", "expected a number or \"auto\"");
          job.betas.push_back(kAutoBeta);
          continue;
        }
        const double v = number(b[i], "betas[" + std::to_string(i) + "]");
        if (v < 0 || v >= 1) fail("betas[" + std::to_string(i) + "]", g6(v) + " is outside [0, 1)");
        job.betas.push_back(v);
      }
    }

    if (!doc.contains("meshes") || !doc["meshes"].is_array() || doc["meshes"].empty())
      fail("meshes", "expected a non-empty array");
    for (std::size_t i = 0; i < doc["meshes"].size(); ++i) {
      const json& m = doc["meshes"][i];
      const std::string w = "meshes[" + std::to_string(i) + "]";
      MeshEntry e;
      if (m.is_string()) {
        const std::string s = m.get<std::string>();
        const std::string p = resolve_path(s, job.dir);
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
          e.source = resolve_path(str(m["file"], w + ".file"), job.dir);
          std::error_code ec;
          if (!fs::is_regular_file(e.source, ec)) fail(w + ".file", e.source + ": no such file");
          e.name = fs::path(e.source).stem().string();
        } else {
          e.source = e.name = str(m["library"], w + ".library");
        }
        if (m.contains("name")) e.name = str(m["name"], w + ".name");
      }
      job.meshes.push_back(e);
    }

    if (!doc.contains("constraints") || !doc["constraints"].is_array() ||
        doc["constraints"].empty())
      fail("constraints", "expected a non-empty array");
    for (std::size_t i = 0; i < doc["constraints"].size(); ++i) {
      const json& c = doc["constraints"][i];
      const std::string w = "constraints[" + std::to_string(i) + "]";
      keys(c, w, {"name", "sel", "fixed", "handles", "local_beta"});
      ConstraintEntry e{c.contains("name") ? str(c["name"], w + ".name") : "c" + std::to_string(i), c};
      job.constraints.push_back(e);
    }

    if (doc.contains("transforms")) {
      if (!doc["transforms"].is_array() || doc["transforms"].empty())
        fail("transforms", "expected a non-empty array");
      for (std::size_t i = 0; i < doc["transforms"].size(); ++i) {
        const json& t = doc["transforms"][i];
        const std::string w = "transforms[" + std::to_string(i) + "]";
        if (!t.is_object()) fail(w, "expected an object");
        TransformEntry e{t.contains("name") ? str(t["name"], w + ".name") : "t" + std::to_string(i),
                         t};
        job.transforms.push_back(e);
      }
    } else {
      job.transforms.push_back({"rest", json::object()});
    }
    for (const auto* list : {&job.constraints}) {
      std::set<std::string> seen;
      for (const auto& e : *list)
        if (!seen.insert(e.name).second) fail("constraints", "duplicate name '" + e.name + "'");
    }
    std::set<std::string> seen;
    for (const auto& e : job.transforms)
      if (!seen.insert(e.name).second) fail("transforms", "duplicate name '" + e.name + "'");
    return job;
  }

  // Constraints and transforms for one mesh ({mesh} substituted, files read).
  Resolved resolve(const Job& job, const ConstraintEntry& ce, const std::string& mesh) const {
    try {
      return resolve_unchecked(job, ce, mesh);
    } catch (const FileError&) {
      throw;
    } catch (const CliError& e) {
      throw parse_error(file_, 0, e.what());
    }
  }

  Resolved resolve_unchecked(const Job& job, const ConstraintEntry& ce,
                             const std::string& mesh) const {
    Resolved r;
    const std::size_t ci =
        static_cast<std::size_t>(&ce - job.constraints.data());
    const std::string w = "constraints[" + std::to_string(ci) + "]";
    const json& c = ce.spec;
    std::string sel;
    if (c.contains("sel")) {
      const std::string path = resolve_path(subst(str(c["sel"], w + ".sel"), mesh), job.dir);
      sel = read_file(path);
    }
    if (c.contains("fixed")) {
      region(*r.constraints.mutable_fixed(), c["fixed"], w + ".fixed", job.dir, mesh);
    } else if (!sel.empty()) {
      auto* s = r.constraints.mutable_fixed()->add_selectors()->mutable_sel();
      s->set_content(sel);
      s->set_label(0);
    }
    if (c.contains("handles")) {
      const json& hs = c["handles"];
      if (!hs.is_array() || hs.empty()) fail(w + ".handles", "expected a non-empty array of regions");
      for (std::size_t h = 0; h < hs.size(); ++h)
        region(*r.constraints.add_handles(), hs[h], w + ".handles[" + std::to_string(h) + "]",
               job.dir, mesh);
    } else if (!sel.empty()) {
      auto* s = r.constraints.add_handles()->add_selectors()->mutable_sel();
      s->set_content(sel);
      s->set_label(2);
    }
    if (r.constraints.handles_size() == 0) fail(w, "no handle: give \"sel\" or \"handles\"");
    if (c.contains("local_beta")) {
      // ["SEL@BETA[@RADIUS]", {"region": REGION, "beta": B, "radius": R}, …]
      const json& ls = c["local_beta"];
      if (!ls.is_array() || ls.empty())
        fail(w + ".local_beta", "expected a non-empty array of entries");
      for (std::size_t i = 0; i < ls.size(); ++i) {
        const std::string lw = w + ".local_beta[" + std::to_string(i) + "]";
        const json& e = ls[i];
        if (e.is_string()) {
          *r.local.Add() = parse_local_beta(subst(e.get<std::string>(), mesh), lw, job.dir);
          continue;
        }
        keys(e, lw, {"region", "beta", "radius"});
        if (!e.contains("region") || !e.contains("beta"))
          fail(lw, "expected \"region\" and \"beta\" (and optionally \"radius\")");
        pb::Region reg;
        region(reg, e["region"], lw + ".region", job.dir, mesh);
        *r.local.Add() = make_local_beta(
            std::move(reg), number(e["beta"], lw + ".beta"),
            e.contains("radius") ? number(e["radius"], lw + ".radius") : 0.0, lw);
      }
    }
    const std::size_t handles = static_cast<std::size_t>(r.constraints.handles_size());

    for (std::size_t ti = 0; ti < job.transforms.size(); ++ti) {
      const json& t = job.transforms[ti].spec;
      const std::string tw = "transforms[" + std::to_string(ti) + "]";
      std::vector<pb::HandleTransform> per_handle;
      if (t.contains("handles")) {
        keys(t, tw, {"name", "handles"});
        const json& hs = t["handles"];
        if (!hs.is_array()) fail(tw + ".handles", "expected an array, one transform per handle");
        if (hs.size() != handles)
          fail(tw + ".handles", std::to_string(hs.size()) + " transforms for " +
                                    std::to_string(handles) + " handles of constraints '" +
                                    ce.name + "'");
        for (std::size_t h = 0; h < hs.size(); ++h) {
          const std::string hw = tw + ".handles[" + std::to_string(h) + "]";
          per_handle.push_back(parse_transform(transform_text(hs[h], hw, mesh), hw,
                                               job.dir));
        }
      } else {
        json copy = t;
        copy.erase("name");
        const auto one = parse_transform(transform_text(copy, tw, mesh), tw, job.dir);
        per_handle.assign(handles, one);
      }
      r.transforms.push_back(std::move(per_handle));
    }
    return r;
  }

 private:
  std::string file_;
};

std::string beta_tag(double b) { return is_auto(b) ? "auto" : g6(b); }

}  // namespace

Command add_run_command(CLI::App& app, const GlobalOptions& global) {
  auto opts = std::make_shared<RunOptions>();
  auto* cmd = app.add_subcommand(
      "run", "run a batch job (JSON, docs/cli.md): meshes x constraints x transforms x betas");
  cmd->add_option("JOB", opts->job, "job file (.json)")->required()->check(CLI::ExistingFile);
  cmd->add_option("-o,--output-dir", opts->output_dir, "override the job's output_dir");
  cmd->add_flag("--dry-run", opts->dry_run, "check the job and list its items; no server calls");

  return [opts, &global]() -> int {
    const auto& o = *opts;
    JobParser parser(o.job);
    Job job = parser.parse(read_file(o.job));
    if (!o.output_dir.empty()) job.output_dir = o.output_dir;
    const pb::BetaUnits units = parse_beta_units(job.beta_units);
    const bool write_meshes = job.format != "none";
    const pb::MeshFormat format =
        write_meshes ? mesh_format_for("x." + job.format) : pb::MESH_FORMAT_GLB;

    // Resolve everything up front: input errors stop the job before any work.
    std::map<std::pair<std::size_t, std::size_t>, Resolved> resolved;
    for (std::size_t mi = 0; mi < job.meshes.size(); ++mi)
      for (std::size_t ci = 0; ci < job.constraints.size(); ++ci)
        resolved[{mi, ci}] = parser.resolve(job, job.constraints[ci], job.meshes[mi].name);

    const std::size_t total =
        job.meshes.size() * job.constraints.size() * job.betas.size() * job.transforms.size();
    if (o.dry_run) {
      std::size_t n = 0;
      for (const auto& m : job.meshes)
        for (const auto& c : job.constraints)
          for (double b : job.betas)
            for (const auto& t : job.transforms)
              std::cout << "[" << ++n << "/" << total << "] " << m.name << " " << c.name << " "
                        << t.name << " beta=" << beta_tag(b) << "\n";
      return 0;
    }

    std::error_code ec;
    fs::create_directories(job.output_dir, ec);
    if (ec) throw CliError(job.output_dir + ": cannot create: " + ec.message());

    std::vector<std::vector<std::string>> summary;  // CSV rows
    std::vector<std::vector<std::string>> table;    // stdout
    {
      std::vector<std::string> h{"mesh", "constraints", "transform", "beta"};
      for (const auto& c : measure_columns()) h.emplace_back(c.label);
      h.emplace_back("ms");
      h.emplace_back("status");
      table.push_back(h);
    }

    Connection conn(global);
    std::size_t n = 0, failed = 0;
    const auto job_start = std::chrono::steady_clock::now();

    auto record = [&](const MeshEntry& m, const ConstraintEntry& c, const TransformEntry& t,
                      double beta, const pb::Frame* frame, double wall_ms,
                      const std::string& output, const std::string& status) {
      // An automatic β shows its pick (CSV: the number; table: "auto=PICK").
      const bool picked = is_auto(beta) && frame;
      std::vector<std::string> row{
          m.name, c.name, t.name,
          picked ? g17(frame->beta().value()) : is_auto(beta) ? "auto" : g17(beta)};
      std::vector<std::string> trow{
          m.name, c.name, t.name,
          picked ? "auto=" + g6(frame->beta().value()) : beta_tag(beta)};
      for (const auto& col : measure_columns()) {
        if (!frame) {
          row.emplace_back("");
          trow.emplace_back("-");
          continue;
        }
        const double v = col.get(frame->measures());
        row.push_back(col.integer ? std::to_string(static_cast<long long>(v)) : g17(v));
        trow.push_back(col.integer ? std::to_string(static_cast<long long>(v)) : g6(v));
      }
      row.push_back(frame ? g17(frame->solve_ms()) : "");
      row.push_back(g17(wall_ms));
      row.push_back(output);
      row.push_back(status);
      char ms[32];
      std::snprintf(ms, sizeof ms, "%.1f", wall_ms);
      trow.emplace_back(ms);
      trow.push_back(status == "ok" ? "ok" : "FAILED");
      summary.push_back(std::move(row));
      table.push_back(std::move(trow));
    };
    auto progress = [&](const MeshEntry& m, const ConstraintEntry& c, const TransformEntry& t,
                        double beta, const std::string& outcome) {
      std::cerr << "[" << n << "/" << total << "] " << m.name << " " << c.name << " " << t.name
                << " \u03b2=" << beta_tag(beta) << " \u2026 " << outcome << std::endl;
    };

    for (std::size_t mi = 0; mi < job.meshes.size(); ++mi) {
      const MeshEntry& m = job.meshes[mi];
      std::unique_ptr<SessionClient> s;
      std::string mesh_error;
      try {
        s = std::make_unique<SessionClient>(SessionClient::create(conn, m.source));
      } catch (const CliError& e) {
        mesh_error = e.what();
      }
      for (std::size_t ci = 0; ci < job.constraints.size(); ++ci) {
        const ConstraintEntry& c = job.constraints[ci];
        const Resolved& r = resolved[{mi, ci}];
        std::string set_error = mesh_error;
        double setup_ms = 0;  // SetConstraints + SetBeta, shown with the next item
        if (set_error.empty()) {
          const auto t0 = std::chrono::steady_clock::now();
          try {
            s->set_constraints(r.constraints);
          } catch (const CliError& e) {
            set_error = e.what();
          }
          setup_ms += ms_since(t0);
        }
        for (double beta : job.betas) {
          std::string beta_error = set_error;
          pb::Beta b;
          b.set_units(units);
          if (is_auto(beta))
            b.set_automatic(true);
          else
            b.set_value(beta);
          *b.mutable_local() = r.local;
          // An automatic β is picked per item, at its transforms (one Deform message each).
          if (beta_error.empty() && !is_auto(beta)) {
            const auto t0 = std::chrono::steady_clock::now();
            try {
              s->set_beta(b);
            } catch (const CliError& e) {
              beta_error = e.what();
            }
            setup_ms += ms_since(t0);
          }
          for (std::size_t ti = 0; ti < job.transforms.size(); ++ti) {
            const TransformEntry& t = job.transforms[ti];
            ++n;
            const auto start = std::chrono::steady_clock::now();
            if (!beta_error.empty()) {
              ++failed;
              record(m, c, t, beta, nullptr, 0, "", beta_error);
              progress(m, c, t, beta, "FAILED: " + beta_error);
              continue;
            }
            try {
              const auto seq = static_cast<std::int64_t>(n);
              const pb::Frame frame = is_auto(beta) ? s->deform(r.transforms[ti], seq, b)
                                                    : s->update(r.transforms[ti], seq);
              std::string output;
              if (write_meshes) {
                output = (fs::path(job.output_dir) /
                          (m.name + "-" + c.name + "-" + t.name + "-b" + beta_tag(beta) + "." +
                           job.format))
                             .string();
                s->download(output, format);
              }
              const double ms = ms_since(start);
              record(m, c, t, beta, &frame, ms, output, "ok");
              std::string outcome = "ok " + std::to_string(std::lround(ms)) + " ms";
              if (is_auto(beta)) outcome += " (picked \u03b2=" + g6(frame.beta().value()) + ")";
              if (setup_ms > 0.5)
                outcome += " (+" + std::to_string(std::lround(setup_ms)) + " ms constraints/\u03b2 setup)";
              setup_ms = 0;
              progress(m, c, t, beta, outcome);
            } catch (const CliError& e) {
              ++failed;
              record(m, c, t, beta, nullptr, ms_since(start), "", e.what());
              progress(m, c, t, beta, std::string("FAILED: ") + e.what());
            }
          }
        }
      }
      if (s && conn.remote()) {
        try {
          s->remove();
        } catch (const CliError& e) {
          spdlog::warn("{}", e.what());
        }
      }
    }

    // Summary CSV.
    std::string csv = "mesh,constraints,transform,beta";
    for (const auto& col : measure_columns()) csv += std::string(",") + col.csv;
    csv += ",solve_ms,wall_ms,output,status\n";
    for (const auto& row : summary) {
      for (std::size_t i = 0; i < row.size(); ++i) csv += (i ? "," : "") + csv_field(row[i]);
      csv += "\n";
    }
    const std::string summary_path = (fs::path(job.output_dir) / job.summary).string();
    write_file(summary_path, csv);

    print_table(std::cout, table, 3);
    std::cout << "summary: " << summary_path << "\n";
    std::cout.flush();
    if (failed > 0) {
      std::cerr << "hdeform: " << failed << " of " << total << " items failed (see "
                << summary_path << ")" << std::endl;
      return 1;
    }
    spdlog::info("{} items in {:.0f} ms", total, ms_since(job_start));
    return 0;
  };
}

}  // namespace hdeform::cli
