// hdeform sweep MESH <constraints> --betas 0,0.1,0.25 [--csv F] [--svg F]: the measures
// against β (one Sweep call), as a table, a CSV and an SVG chart of small multiples.
#include "commands.h"
#include "constraint_options.h"
#include "output.h"
#include "work_session.h"

#include <iostream>
#include <memory>

namespace hdeform::cli {

namespace {

struct SweepOptions {
  std::string mesh;
  std::string betas;
  std::string csv;
  std::string svg;
  std::string title;
  bool keep = false;
  ConstraintOptions c;
};

}  // namespace

Command add_sweep_command(CLI::App& app, const GlobalOptions& global) {
  auto opts = std::make_shared<SweepOptions>();
  auto* cmd = app.add_subcommand("sweep", "the seven measures and flips for a list of beta");
  cmd->add_option("MESH", opts->mesh, "mesh file or library name");
  add_constraint_options(*cmd, opts->c);
  add_beta_options(*cmd, opts->c, false);
  cmd->add_option("--betas", opts->betas, "comma-separated beta values, e.g. 0,0.1,0.25")
      ->required();
  cmd->add_option("--csv", opts->csv, "write the rows as CSV ('-' = stdout instead of the table)");
  cmd->add_option("--svg", opts->svg, "write an SVG chart: one panel per measure against beta");
  cmd->add_option("--title", opts->title, "chart title (default: MESH)");
  cmd->add_flag("--keep", opts->keep, "keep the session on the server and print its name");

  return [opts, &global]() -> int {
    const auto& o = *opts;
    check_mesh_or_session(o.mesh, o.c, global);
    const auto betas = parse_numbers(o.betas, "--betas");
    if (betas.empty()) throw CliError("--betas: no values");
    for (double b : betas)
      if (b < 0 || b >= 1) throw CliError("--betas: " + g6(b) + " is outside [0, 1)");
    const pb::BetaUnits units = parse_beta_units(o.c.beta_units);
    const pb::Beta local = build_beta(o.c);  // value 0 + the --local-beta entries
    const std::unique_ptr<ConstraintSpec> spec = constraint_spec_for(o.c);

    Connection conn(global);
    WorkSession w = open_work_session(conn, o.mesh, o.c);
    std::vector<SweepPoint> rows;
    run_in_work_session(conn, w, o.keep, std::cerr, [&](SessionClient& s) {
      if (spec) s.set_constraints(spec->constraints);
      // --local-beta: the session's local entries, applied at every swept β.
      if (!o.c.local_betas.empty()) s.set_beta(local);
      // An existing session without transform options sweeps at its current pose: no
      // transforms in the request (SweepRequest: empty = the session's current transforms).
      const auto transforms = keeps_pose(o.c, spec.get())
                                  ? std::vector<pb::HandleTransform>{}
                                  : transforms_for(o.c, s, spec.get());
      const pb::SweepResponse resp = s.sweep(betas, units, transforms);
      for (const auto& r : resp.rows()) rows.push_back({r.beta(), r.measures()});
    });

    const pb::Session& info = w.client->info();
    const std::string mesh_name = info.mesh_name().empty() ? o.mesh : info.mesh_name();
    // "wrote FILE" goes to stderr: stdout is the table or the CSV, for scripts to read.
    auto write = [](const std::string& path, const std::string& bytes) {
      write_file(path, bytes);
      std::cerr << "wrote " << path << " (" << bytes.size() << " bytes)\n";
    };
    if (o.csv == "-") {
      std::cout << sweep_csv(rows);
    } else {
      print_sweep_table(std::cout, rows);
      std::cout.flush();
      if (!o.csv.empty()) write(o.csv, sweep_csv(rows));
    }
    if (!o.svg.empty()) {
      const std::string title =
          !o.title.empty() ? o.title : mesh_name + ": measures against \u03b2";
      write(o.svg, sweep_svg(rows, title, o.c.beta_units));
    }
    std::cout.flush();
    return 0;
  };
}

}  // namespace hdeform::cli
