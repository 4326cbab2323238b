// The session `deform` and `sweep` work on: created from MESH (deleted afterwards unless
// --keep) or an existing --session on a remote server.
#pragma once

#include "common.h"
#include "constraint_options.h"

#include <functional>
#include <iosfwd>
#include <memory>
#include <string>
#include <vector>

namespace hdeform::cli {

struct WorkSession {
  std::unique_ptr<SessionClient> client;
  bool created = false;
};

// Throws CliError when MESH/--session/constraints do not fit together.
void check_mesh_or_session(const std::string& mesh, const ConstraintOptions& c,
                           const GlobalOptions& global);
WorkSession open_work_session(Connection& conn, const std::string& mesh,
                              const ConstraintOptions& c);
// The constraint spec the options give (regions were given), else nullptr: an existing
// --session keeps its own.
std::unique_ptr<ConstraintSpec> constraint_spec_for(const ConstraintOptions& c);
// Runs body on the session; then a session this command created on a remote server is
// removed, or with keep its name and tokens are printed to keep_out ("session NAME",
// "edit token: T", "view token: T"). When anything
// throws, the created session is removed (unless keep) and the exception goes on.
void run_in_work_session(const Connection& conn, WorkSession& w, bool keep,
                         std::ostream& keep_out, const std::function<void(SessionClient&)>& body);
// One transform per handle: the spec's when regions were given (spec != nullptr); else, on an
// existing session, the transform options' transform for each of its handles (replacing its
// current ones), or its current transforms when no transform option was given.
std::vector<pb::HandleTransform> transforms_for(const ConstraintOptions& c, SessionClient& s,
                                                const ConstraintSpec* spec);
// Any of --rotate/--translate/--scale/--pivot/--def given?
bool has_transform_options(const ConstraintOptions& c);
// True when an existing session is used as it stands: no regions, no transform options.
bool keeps_pose(const ConstraintOptions& c, const ConstraintSpec* spec);

}  // namespace hdeform::cli
