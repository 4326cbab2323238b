// hdeform meshes: the server's mesh library (ListMeshes), the names MESH may take.
#include "commands.h"
#include "output.h"

#include <nlohmann/json.hpp>

#include <iostream>
#include <memory>

namespace hdeform::cli {

Command add_meshes_command(CLI::App& app, const GlobalOptions& global) {
  auto json = std::make_shared<bool>(false);
  auto* cmd = app.add_subcommand("meshes", "the server's mesh library (names for MESH)");
  cmd->add_flag("--json", *json, "a JSON array instead of the table");
  return [json, &global]() -> int {
    Connection conn(global);
    pb::ListMeshesRequest req;
    pb::ListMeshesResponse resp;
    const grpc::Status status = conn.call(
        "ListMeshes",
        [&](grpc::ClientContext& ctx) {
          conn.prepare(ctx, "", conn.options().call_timeout_s, TokenScope::kNone);
        },
        [&](grpc::ClientContext& ctx) {
          resp.Clear();
          return conn.stub().ListMeshes(&ctx, req, &resp);
        });
    if (!status.ok()) throw RpcError("ListMeshes", status);
    if (*json) {
      nlohmann::json a = nlohmann::json::array();
      for (const auto& m : resp.meshes())
        a.push_back({{"name", m.name()}, {"path", m.path()}, {"benchmark", m.has_benchmark()}});
      std::cout << a.dump(2) << "\n";
    } else {
      std::vector<std::vector<std::string>> t{{"name", "path", "benchmark"}};
      for (const auto& m : resp.meshes())
        t.push_back({m.name(), m.path(), m.has_benchmark() ? "yes" : "no"});
      print_table(std::cout, t, 3);
    }
    std::cout.flush();
    return 0;
  };
}

}  // namespace hdeform::cli
