// hdeform run JOB.json: batch jobs — meshes × constraint sets × β × transforms → mesh files
// and a summary CSV, with a progress line per item on stderr. Schema: docs/cli.md.
#include "commands.h"
#include "constraint_options.h"
#include "job_file.h"
#include "output.h"

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

namespace {

struct RunOptions {
  std::string job;
  std::string output_dir;
  bool dry_run = false;
  bool animations_only = false;  // hdeform animate: the job's "animation" items only
  MeshOutputOptions out;
};

// The job's timeline for one constraint set: each key's resolved per-handle transforms.
pb::Timeline timeline_for(const Job& job, const std::vector<std::vector<pb::HandleTransform>>& transforms,
                          int handles, pb::BetaUnits units) {
  pb::Timeline t;
  t.set_easing(job.animation.easing == "smoothstep" ? pb::EASING_SMOOTHSTEP : pb::EASING_LINEAR);
  for (const auto& key : job.animation.keys) {
    pb::Keyframe* k = t.add_keys();
    k->set_time_s(key.time);
    if (key.transform_index == kRestTransform) {
      for (int h = 0; h < handles; ++h) k->add_transforms();  // identity
    } else {
      for (const auto& tr : transforms[key.transform_index]) *k->add_transforms() = tr;
    }
    if (key.has_beta) {
      k->mutable_beta()->set_value(key.beta);
      k->mutable_beta()->set_units(units);
    }
  }
  return t;
}

// Per mesh and constraint set, resolved before any call: {mesh} substituted, files read.
struct Resolved {
  pb::Constraints constraints;
  google::protobuf::RepeatedPtrField<pb::LocalBeta> local;  // the set's "local_beta"
  std::vector<std::vector<pb::HandleTransform>> transforms;  // [transform][handle]
};

void add_region(pb::Region& r, const RegionText& region, const std::string& where,
                const Job& job, const std::string& mesh) {
  for (const auto& text : region) add_selectors(r, subst_mesh(text, mesh), where, job.dir);
}

Resolved resolve_unchecked(const Job& job, const ConstraintEntry& c, const std::string& mesh) {
  Resolved r;
  const std::string& w = c.where;
  const bool has_sel = !c.sel.empty();
  std::string sel;
  if (has_sel) sel = read_file(resolve_path(subst_mesh(c.sel, mesh), job.dir));
  if (c.has_fixed) {
    add_region(*r.constraints.mutable_fixed(), c.fixed, w + ".fixed", job, mesh);
  } else if (has_sel) {
    auto* s = r.constraints.mutable_fixed()->add_selectors()->mutable_sel();
    s->set_content(sel);
    s->set_label(0);
  }
  if (!c.handles.empty()) {
    for (std::size_t h = 0; h < c.handles.size(); ++h)
      add_region(*r.constraints.add_handles(), c.handles[h],
                 w + ".handles[" + std::to_string(h) + "]", job, mesh);
  } else {
    auto* s = r.constraints.add_handles()->add_selectors()->mutable_sel();
    s->set_content(sel);
    s->set_label(2);
  }
  for (const auto& l : c.local_beta) {
    if (!l.text.empty()) {
      *r.local.Add() = parse_local_beta(subst_mesh(l.text, mesh), l.where, job.dir);
    } else {
      pb::Region reg;
      add_region(reg, l.region, l.where + ".region", job, mesh);
      *r.local.Add() = make_local_beta(std::move(reg), l.beta, l.radius, l.where);
    }
  }
  const std::size_t handles = static_cast<std::size_t>(r.constraints.handles_size());
  for (const auto& t : job.transforms) {
    std::vector<pb::HandleTransform> per_handle;
    for (std::size_t h = 0; h < t.transforms.size(); ++h) {
      TransformText text = t.transforms[h];
      text.def_file = subst_mesh(text.def_file, mesh);
      const std::string where =
          t.per_handle ? t.where + ".handles[" + std::to_string(h) + "]" : t.where;
      per_handle.push_back(parse_transform(text, where, job.dir));
    }
    if (!t.per_handle) per_handle.assign(handles, per_handle.front());
    r.transforms.push_back(std::move(per_handle));
  }
  return r;
}

// Errors name the job file: "JOB: constraints[0].fixed …: problem".
Resolved resolve(const Job& job, const ConstraintEntry& c, const std::string& mesh) {
  try {
    return resolve_unchecked(job, c, mesh);
  } catch (const FileError&) {
    throw;
  } catch (const CliError& e) {
    throw parse_error(job.file, 0, e.what());
  }
}

// The session of one mesh: deleted (DeleteSession) as soon as its items are done, also
// in-process and when an error escapes, so a job never holds more than one session.
class MeshSession {
 public:
  MeshSession(Connection& conn, const std::string& source)
      : client_(SessionClient::create(conn, source)) {}
  ~MeshSession() { close(); }
  MeshSession(const MeshSession&) = delete;
  MeshSession& operator=(const MeshSession&) = delete;
  SessionClient& client() { return client_; }
  void close() {
    if (closed_) return;
    closed_ = true;
    try {
      client_.remove();
    } catch (const CliError& e) {
      spdlog::warn("{}", e.what());
    }
  }

 private:
  SessionClient client_;
  bool closed_ = false;
};

// A name as shown in progress lines, the table and the CSV: control characters as \xHH
// (a job's names must not drive the terminal).
std::string shown(const std::string& name) {
  std::string out;
  for (const char ch : name) {
    const unsigned char c = static_cast<unsigned char>(ch);
    if (c < 0x20 || c == 0x7f) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02x", c);
      out += buf;
    } else {
      out += ch;
    }
  }
  return out;
}

// `run` and `animate` share one implementation: animate runs only the "animation" items.
Command run_job(std::shared_ptr<RunOptions> opts, const GlobalOptions& global);

}  // namespace

Command add_run_command(CLI::App& app, const GlobalOptions& global) {
  auto opts = std::make_shared<RunOptions>();
  auto* cmd = app.add_subcommand(
      "run", "run a batch job (JSON, docs/cli.md): meshes x constraints x transforms x betas");
  cmd->add_option("JOB", opts->job, "job file (.json)")->required()->check(CLI::ExistingFile);
  cmd->add_option("-o,--output-dir", opts->output_dir, "override the job's output_dir");
  add_mesh_output_options(*cmd, opts->out);
  cmd->add_flag("--dry-run", opts->dry_run, "check the job and list its items; no server calls");
  return run_job(opts, global);
}

Command add_animate_command(CLI::App& app, const GlobalOptions& global) {
  auto opts = std::make_shared<RunOptions>();
  opts->animations_only = true;
  auto* cmd = app.add_subcommand(
      "animate", "a job's \"animation\" (docs/cli.md \"Animations\"): keyframes -> animated .glb "
                 "per mesh x constraints x beta");
  cmd->add_option("JOB", opts->job, "job file (.json) with an \"animation\"")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("-o,--output-dir", opts->output_dir, "override the job's output_dir");
  cmd->add_flag("--dry-run", opts->dry_run, "check the job and list its items; no server calls");
  return run_job(opts, global);
}

namespace {

Command run_job(std::shared_ptr<RunOptions> opts, const GlobalOptions& global) {
  return [opts, &global]() -> int {
    const auto& o = *opts;
    Job job = parse_job(read_file(o.job), o.job, fs::path(o.job).parent_path().string());
    if (!o.output_dir.empty()) job.output_dir = o.output_dir;
    const pb::BetaUnits units = parse_beta_units(job.beta_units);
    const bool write_meshes = job.format != "none";
    const pb::MeshFormat format =
        write_meshes ? mesh_format_for("x." + job.format) : pb::MESH_FORMAT_GLB;

    // Resolve everything up front: input errors stop the job before any work.
    std::map<std::pair<std::size_t, std::size_t>, Resolved> resolved;
    for (std::size_t mi = 0; mi < job.meshes.size(); ++mi)
      for (std::size_t ci = 0; ci < job.constraints.size(); ++ci)
        resolved[{mi, ci}] = resolve(job, job.constraints[ci], job.meshes[mi].name);

    if (o.animations_only && !job.animation.present)
      throw CliError(o.job + ": no \"animation\" in this job (docs/cli.md \"Animations\")");
    // The "animation" entry as an item's transform column.
    TransformEntry animation;
    animation.name = "animation:" + job.animation.name;
    animation.where = "animation";
    const bool stills = !o.animations_only;
    const std::size_t animations =
        job.animation.present ? job.meshes.size() * job.constraints.size() * job.betas.size() : 0;
    const std::size_t total = (stills ? job.item_count() : 0) + animations;
    if (o.dry_run) {
      std::size_t n = 0;
      for (const auto& m : job.meshes)
        for (const auto& c : job.constraints)
          for (double b : job.betas) {
            auto line = [&](const TransformEntry& t) {
              std::cout << "[" << ++n << "/" << total << "] " << shown(m.name) << " "
                        << shown(c.name) << " " << shown(t.name) << " \u03b2=" << beta_tag(b)
                        << "\n";
            };
            if (stills)
              for (const auto& t : job.transforms) line(t);
            if (job.animation.present) line(animation);
          }
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
          shown(m.name), shown(c.name), shown(t.name),
          picked ? shortest(frame->beta().value()) : is_auto(beta) ? "auto" : shortest(beta)};
      std::vector<std::string> trow{
          shown(m.name), shown(c.name), shown(t.name),
          picked ? "auto=" + shortest(frame->beta().value()) : beta_tag(beta)};
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
      std::cerr << "[" << n << "/" << total << "] " << shown(m.name) << " " << shown(c.name)
                << " " << shown(t.name) << " \u03b2=" << beta_tag(beta) << " \u2026 " << outcome
                << std::endl;
    };

    for (std::size_t mi = 0; mi < job.meshes.size(); ++mi) {
      const MeshEntry& m = job.meshes[mi];
      std::unique_ptr<MeshSession> session;
      std::string mesh_error;
      try {
        session = std::make_unique<MeshSession>(conn, m.source);
      } catch (const CliError& e) {
        mesh_error = e.what();
      }
      SessionClient* s = session ? &session->client() : nullptr;
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
          for (std::size_t ti = 0; stills && ti < job.transforms.size(); ++ti) {
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
              check_frame_finite(frame, t.where + " '" + shown(t.name) + "'");
              std::string output, wrote;
              if (write_meshes) {
                // A plain file name (names sanitized, collisions rejected by parse_job),
                // checked again to land inside the output folder.
                const std::string file = item_file_name(job, m, c, t, beta);
                const fs::path path = output_path_inside(job.output_dir, file);
                output = (fs::path(job.output_dir) / file).string();
                const std::size_t bytes = s->download(path.string(), format, false, o.out);
                wrote = "wrote " + output + " (" + std::to_string(bytes) + " bytes)";
              }
              const double ms = ms_since(start);
              record(m, c, t, beta, &frame, ms, output, "ok");
              std::string outcome = "ok " + std::to_string(std::lround(ms)) + " ms";
              if (is_auto(beta)) outcome += " (picked \u03b2=" + shortest(frame.beta().value()) + ")";
              if (setup_ms > 0.5)
                outcome += " (+" + std::to_string(std::lround(setup_ms)) + " ms constraints/\u03b2 setup)";
              setup_ms = 0;
              progress(m, c, t, beta, outcome);
              if (!wrote.empty()) std::cerr << wrote << std::endl;
            } catch (const CliError& e) {
              ++failed;
              record(m, c, t, beta, nullptr, ms_since(start), "", e.what());
              progress(m, c, t, beta, std::string("FAILED: ") + e.what());
            }
          }
          if (!job.animation.present) continue;
          // The animation of this mesh × constraints × β: each sampled frame is a full
          // deformation on the server (SetTimeline + ExportAnimation).
          ++n;
          const auto start = std::chrono::steady_clock::now();
          if (!beta_error.empty()) {
            ++failed;
            record(m, c, animation, beta, nullptr, 0, "", beta_error);
            progress(m, c, animation, beta, "FAILED: " + beta_error);
            continue;
          }
          try {
            s->set_timeline(
                timeline_for(job, r.transforms, r.constraints.handles_size(), units));
            pb::ExportAnimationRequest req;
            req.set_fps(job.animation.fps);
            req.set_energies(job.animation.energies);
            req.set_up(job.animation.up == "z" ? pb::UP_AXIS_Z : pb::UP_AXIS_Y);
            const std::string file = animation_file_name(job, m, c, beta);
            const fs::path path = output_path_inside(job.output_dir, file);
            const std::string output = (fs::path(job.output_dir) / file).string();
            const std::size_t bytes = s->export_animation(path.string(), req);
            const double ms = ms_since(start);
            record(m, c, animation, beta, nullptr, ms, output, "ok");
            progress(m, c, animation, beta, "ok " + std::to_string(std::lround(ms)) + " ms");
            std::cerr << "wrote " << output << " (" << bytes << " bytes)" << std::endl;
          } catch (const CliError& e) {
            ++failed;
            record(m, c, animation, beta, nullptr, ms_since(start), "", e.what());
            progress(m, c, animation, beta, std::string("FAILED: ") + e.what());
          }
        }
      }
      if (session) session->close();  // before the next mesh's session is created
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
    write_file(output_path_inside(job.output_dir, job.summary).string(), csv);
    std::cerr << "wrote " << summary_path << " (" << csv.size() << " bytes)" << std::endl;

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

}  // namespace

}  // namespace hdeform::cli
