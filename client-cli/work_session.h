// The session `deform` and `sweep` work on: created from MESH (deleted afterwards unless
// --keep) or an existing --session on a remote server.
#pragma once

#include "common.h"
#include "constraint_options.h"

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
// One transform per handle: the spec's when regions were given (spec != nullptr), else the
// options' transform for each handle the existing session already has.
std::vector<pb::HandleTransform> transforms_for(const ConstraintOptions& c, SessionClient& s,
                                                const ConstraintSpec* spec);

}  // namespace hdeform::cli
