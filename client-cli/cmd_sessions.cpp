// hdeform sessions list|get|delete|export|import: sessions on a remote server, for scripts.
// Tokens as everywhere (--token / HDEFORM_TOKEN, docs/cli.md "Access tokens"); errors are
// the server's status and message.
#include "commands.h"
#include "output.h"
#include "session_report.h"
#include "snapshot_file.h"

#include <iostream>
#include <memory>

namespace hdeform::cli {

namespace {

struct SessionsOptions {
  bool json = false;
  std::vector<std::string> names;  // get, delete: SESSION…; export: one
  std::string output;              // export -o FILE
  bool include_mesh = false;
  std::string input;               // import FILE
  std::string session_id;          // import --session-id
};

void need_server(const GlobalOptions& global, const std::string& what) {
  if (global.server.empty())
    throw CliError("sessions " + what +
                   " needs --server HOST:PORT (an in-process service ends with the command, "
                   "and its sessions with it)");
}

}  // namespace

Command add_sessions_command(CLI::App& app, const GlobalOptions& global) {
  auto o = std::make_shared<SessionsOptions>();
  auto* cmd = app.add_subcommand(
      "sessions", "the sessions of a server: list, get, delete, export, import (needs --server)");
  cmd->require_subcommand(1);

  auto* list = cmd->add_subcommand(
      "list", "one row per session that --token opens (every session with the operator token)");
  list->add_flag("--json", o->json, "a JSON array instead of the table");

  auto* get = cmd->add_subcommand("get", "one session in detail (the view token is enough)");
  get->add_option("SESSION", o->names, "sessions/ID or ID")->required()->expected(1);
  get->add_flag("--json", o->json, "a JSON object instead of text");

  auto* del = cmd->add_subcommand("delete", "delete sessions (their edit tokens)");
  del->add_option("SESSION", o->names, "sessions/ID or ID (several: each needs its token)")
      ->required();

  auto* exp = cmd->add_subcommand(
      "export", "write a session's snapshot (constraints, beta, pose, the mesh by reference)");
  exp->add_option("SESSION", o->names, "sessions/ID or ID")->required()->expected(1);
  exp->add_option("-o,--output", o->output,
                  "snapshot file: FILE.json = protobuf JSON, any other name = binary protobuf")
      ->required();
  exp->add_flag("--include-mesh", o->include_mesh,
                "embed the mesh file (else the snapshot names it by library name or hash)");

  auto* imp = cmd->add_subcommand(
      "import", "create a session from a snapshot file; prints its name and both tokens");
  imp->add_option("FILE", o->input, "a file from sessions export (binary or JSON)")
      ->required()
      ->check(CLI::ExistingFile);
  imp->add_option("--session-id", o->session_id,
                  "the new session's id (e.g. its old one); default: a random id");

  return [o, &global, list, get, del, exp, imp]() -> int {
    if (list->parsed()) {
      need_server(global, "list");
      Connection conn(global);
      const auto sessions = list_sessions(conn);
      if (o->json) {
        nlohmann::json a = nlohmann::json::array();
        for (const auto& s : sessions) a.push_back(session_json(s));
        std::cout << a.dump(2) << "\n";
      } else {
        print_table(std::cout, session_table(sessions), 2);
      }
    } else if (get->parsed()) {
      need_server(global, "get");
      Connection conn(global);
      SessionClient s(conn, o->names.front());
      const pb::Session info = s.get();
      if (o->json)
        std::cout << session_json(info).dump(2) << "\n";
      else
        print_session(std::cout, info);
    } else if (del->parsed()) {
      need_server(global, "delete");
      Connection conn(global);
      for (const auto& name : o->names) {
        SessionClient s(conn, name);
        s.remove();
        std::cout << "deleted " << s.name() << "\n";
      }
    } else if (exp->parsed()) {
      need_server(global, "export");
      Connection conn(global);
      SessionClient s(conn, o->names.front());
      const pb::Snapshot snap = s.export_snapshot(o->include_mesh);
      const std::size_t bytes = write_snapshot(o->output, snap);
      std::cout << "wrote " << o->output << " (" << bytes << " bytes, "
                << (snapshot_path_is_json(o->output) ? "JSON" : "binary") << " Snapshot"
                << (snap.mesh_bytes().empty() ? "" : ", with the mesh") << ")\n";
    } else if (imp->parsed()) {
      need_server(global, "import");
      const pb::Snapshot snap = read_snapshot(o->input);  // before connecting: bad files fail fast
      Connection conn(global);
      SessionClient s = o->session_id.empty()
                            ? SessionClient::import(conn, snap)
                            : SessionClient::import(conn, snap, o->session_id);
      // As deform --keep: the only time the tokens are shown.
      std::cout << "session " << s.name() << "\n";
      if (const SessionTokens* t = s.tokens()) {
        std::cout << "edit token: " << t->edit << "\n";
        std::cout << "view token: " << t->view << "\n";
      }
    }
    std::cout.flush();
    return 0;
  };
}

}  // namespace hdeform::cli
