// hdeform list: the sessions the presented tokens open (ListSessions).
#include "commands.h"
#include "output.h"

#include <iostream>
#include <memory>

namespace hdeform::cli {

Command add_list_command(CLI::App& app, const GlobalOptions& global) {
  app.add_subcommand("list",
                     "list the sessions that --token opens (all of them with the operator token; "
                     "needs --server)");
  return [&global]() -> int {
    if (global.server.empty())
      throw CliError("list needs --server HOST:PORT (an in-process service has no sessions)");
    Connection conn(global);
    for (const pb::Session& s : list_sessions(conn))
      std::cout << s.name() << " mesh=" << s.mesh_name() << " vertices=" << s.vertex_count()
                << " triangles=" << s.triangle_count() << " version=" << s.version()
                << " handles=" << s.constraints().handles_size()
                << " beta=" << shortest(s.beta().value())
                << (s.beta().units() == pb::BETA_UNITS_RAW ? "(raw)" : "")
                << " observers=" << s.observers() << "\n";
    std::cout.flush();
    return 0;
  };
}

}  // namespace hdeform::cli
