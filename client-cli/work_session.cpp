#include "work_session.h"

#include <filesystem>
#include <ostream>

namespace hdeform::cli {

WorkSession open_work_session(Connection& conn, const std::string& mesh,
                              const ConstraintOptions& c) {
  WorkSession w;
  if (!c.session.empty()) {
    w.client = std::make_unique<SessionClient>(conn, c.session);
    w.client->get();
  } else {
    pb::MeshRepair repair;
    repair.set_merge_tolerance(c.merge_tolerance);
    w.client = std::make_unique<SessionClient>(
        SessionClient::create(conn, mesh, c.repair ? &repair : nullptr));
    w.created = true;
  }
  return w;
}

std::unique_ptr<ConstraintSpec> constraint_spec_for(const ConstraintOptions& c) {
  if (!has_constraints(c)) return nullptr;
  return std::make_unique<ConstraintSpec>(build_constraint_spec(c));
}

void run_in_work_session(const Connection& conn, WorkSession& w, bool keep,
                         std::ostream& keep_out, const std::function<void(SessionClient&)>& body) {
  SessionClient& s = *w.client;
  const bool ours = w.created && conn.remote();  // in-process sessions end with the process
  try {
    body(s);
    if (ours) {
      if (keep) {
        keep_out << "session " << s.name() << "\n";
        // The only time these are shown: whoever holds the edit token can change and delete
        // the session; the view token only reads it (GetSession, GetMesh, watch).
        if (const SessionTokens* t = s.tokens()) {
          keep_out << "edit token: " << t->edit << "\n";
          keep_out << "view token: " << t->view << "\n";
        }
      } else
        s.remove();
    }
  } catch (...) {
    if (ours && !keep) {
      try {
        s.remove();
      } catch (...) {
      }
    }
    throw;
  }
}

void check_mesh_or_session(const std::string& mesh, const ConstraintOptions& c,
                           const GlobalOptions& global) {
  if (!c.session.empty()) {
    if (!mesh.empty()) throw CliError("give either MESH or --session, not both");
    if (c.repair) throw CliError("--repair applies to an uploaded MESH, not to --session");
    if (global.server.empty()) throw CliError("--session needs --server HOST:PORT");
  } else {
    if (mesh.empty()) throw CliError("MESH is required (a file or a library name like cactus)");
    std::error_code ec;
    if (!std::filesystem::is_regular_file(mesh, ec) &&
        (mesh.find('/') != std::string::npos || std::filesystem::path(mesh).has_extension()))
      throw CliError(mesh + ": no such file");
    if (!has_constraints(c))
      throw CliError("no constraints: give --sel F.sel [--def F.def] or --fixed SEL --handle SEL");
  }
}

bool has_transform_options(const ConstraintOptions& c) {
  return !c.rotate.empty() || !c.translate.empty() || !c.scale.empty() || !c.pivot.empty() ||
         !c.def_file.empty();
}

bool keeps_pose(const ConstraintOptions& c, const ConstraintSpec* spec) {
  return !spec && !has_transform_options(c);
}

std::vector<pb::HandleTransform> transforms_for(const ConstraintOptions& c, SessionClient& s,
                                                const ConstraintSpec* spec) {
  if (spec) return spec->transforms;
  const int handles = s.info().constraints().handles_size();
  if (handles == 0) throw CliError(s.name() + " has no constraints: give --sel or --handle");
  // No transform options on an existing session: its current pose, not the rest pose.
  if (!has_transform_options(c) && s.info().transforms_size() == handles)
    return {s.info().transforms().begin(), s.info().transforms().end()};
  // Transform options replace the session's transforms (they do not compose with them).
  TransformText text{c.rotate, c.translate, c.scale, c.pivot, c.def_file};
  return std::vector<pb::HandleTransform>(static_cast<std::size_t>(handles),
                                          parse_transform(text, "transform"));
}

}  // namespace hdeform::cli
