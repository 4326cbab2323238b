// The hdeform subcommands. Each add_* registers its options and returns the function that
// runs it (after parsing); it returns the process exit code and throws CliError on bad input.
#pragma once

#include "common.h"

#include <CLI/CLI.hpp>

#include <functional>

namespace hdeform::cli {

using Command = std::function<int()>;

Command add_deform_command(CLI::App& app, const GlobalOptions& global);
Command add_rig_command(CLI::App& app, const GlobalOptions& global);
Command add_sweep_command(CLI::App& app, const GlobalOptions& global);
Command add_run_command(CLI::App& app, const GlobalOptions& global);
Command add_animate_command(CLI::App& app, const GlobalOptions& global);
Command add_watch_command(CLI::App& app, const GlobalOptions& global);
Command add_list_command(CLI::App& app, const GlobalOptions& global);
Command add_sessions_command(CLI::App& app, const GlobalOptions& global);
Command add_meshes_command(CLI::App& app, const GlobalOptions& global);

}  // namespace hdeform::cli
