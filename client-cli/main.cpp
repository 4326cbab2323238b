// hdeform — the command-line client of hdeform.v1 (docs/cli.md).
//
//   hdeform [--server HOST:PORT] [--token T] [--tls-ca F] [--log-level L] deform|sweep|run|watch|list|sessions|meshes …
//
// Without --server the same service runs in-process (hdeform::service::Server with no TCP
// port) and the commands talk to it over its in-process channel.
#include "commands.h"
#include "common.h"

#ifdef HDEFORM_CLI_IN_PROCESS
#include "engine/runtime/process_environment.h"
#endif

#include <CLI/CLI.hpp>
#include <grpc/support/log.h>
#include <spdlog/sinks/stdout_sinks.h>
#include <spdlog/spdlog.h>

#include <iostream>

namespace {

// gRPC's own log lines go through spdlog at debug level: a failed connection must not add
// lines to the single error line the CLI prints.
void grpc_log(gpr_log_func_args* args) {
  spdlog::debug("grpc {}:{}: {}", args->file ? args->file : "?", args->line,
                args->message ? args->message : "");
}

}  // namespace

int main(int argc, char** argv) {
#ifdef HDEFORM_CLI_IN_PROCESS
  hdeform::ensure_process_environment(argv);  // the in-process service's, as hdeform-server's
#endif
  using namespace hdeform::cli;
  gpr_set_log_function(grpc_log);

  CLI::App app{"hdeform: harmonic surface deformation (a client of hdeform-server; without "
               "--server it runs the service in-process)"};
  app.name("hdeform");
  app.require_subcommand(1);
  app.fallthrough(true);  // global options may follow the subcommand
  app.set_version_flag("--version", "hdeform 0.1.0");

  GlobalOptions global;
  app.add_option("--server", global.server,
                 "HOST:PORT of an hdeform-server (or nginx in front of several); default: "
                 "run the service in-process");
  app.add_option("--log-level", global.log_level, "trace, debug, info, warn, error or off")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error", "off"}))
      ->capture_default_str();
  app.add_option("--timeout", global.call_timeout_s, "deadline of each call, in seconds")
      ->capture_default_str();
  // No capture_default_str: a token is a secret and never shown (not even in --help).
  app.add_option("--token", global.token,
                 "a session's edit or view token (or the operator token), sent with every call "
                 "that names a session (prefer the variable: a command line is visible in ps)")
      ->envname("HDEFORM_TOKEN");
  auto* tls_ca = app.add_option("--tls-ca", global.tls_ca,
                                "root CA certificate (PEM): connect to --server over TLS")
                     ->envname("HDEFORM_TLS_CA")
                     ->check(CLI::ExistingFile);
  auto* tls_cert = app.add_option("--tls-cert", global.tls_cert,
                                  "client certificate chain (PEM), for a server that requires one")
                       ->envname("HDEFORM_TLS_CLIENT_CERT")
                       ->check(CLI::ExistingFile)
                       ->needs(tls_ca);
  auto* tls_key = app.add_option("--tls-key", global.tls_key,
                                 "the client certificate's private key (PEM)")
                      ->envname("HDEFORM_TLS_CLIENT_KEY")
                      ->check(CLI::ExistingFile);
  tls_cert->needs(tls_key);
  tls_key->needs(tls_cert);

  std::vector<std::pair<CLI::App*, Command>> commands;
  auto reg = [&](Command (*add)(CLI::App&, const GlobalOptions&)) {
    const std::size_t before = app.get_subcommands({}).size();
    Command cmd = add(app, global);
    commands.emplace_back(app.get_subcommands({})[before], std::move(cmd));
  };
  reg(add_deform_command);
  reg(add_sweep_command);
  reg(add_run_command);
  reg(add_animate_command);
  reg(add_rig_command);
  reg(add_watch_command);
  reg(add_list_command);
  reg(add_sessions_command);
  reg(add_meshes_command);

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::cerr << "hdeform: " << e.what() << " (see hdeform --help)" << std::endl;
    return e.get_exit_code() != 0 ? e.get_exit_code() : 2;
  }

  auto logger = spdlog::stderr_logger_mt("hdeform");
  logger->set_pattern("hdeform: [%l] %v");
  spdlog::set_default_logger(logger);
  spdlog::set_level(spdlog::level::from_str(global.log_level));

  try {
    for (auto& [sub, cmd] : commands)
      if (sub->parsed()) return cmd();
    std::cerr << "hdeform: no command (see hdeform --help)" << std::endl;
    return 2;
  } catch (const FileError& e) {
    std::cout.flush();
    std::cerr << e.what() << std::endl;
  } catch (const CliError& e) {
    std::cout.flush();
    std::cerr << "hdeform: " << e.what() << std::endl;
  } catch (const std::exception& e) {
    std::cout.flush();
    std::cerr << "hdeform: " << e.what() << std::endl;
  }
  return 1;
}
