// hdeform deform MESH <constraints> [--beta B] [-o OUT]: one deformation, its measures, a file.
#include "commands.h"
#include "constraint_options.h"
#include "output.h"
#include "work_session.h"

#include <spdlog/spdlog.h>

#include <iostream>
#include <memory>

namespace hdeform::cli {

namespace {

struct DeformOptions {
  std::string mesh;
  std::string output;
  bool keep = false;
  ConstraintOptions c;
  MeshOutputOptions out;
};

}  // namespace

Command add_deform_command(CLI::App& app, const GlobalOptions& global) {
  auto opts = std::make_shared<DeformOptions>();
  auto* cmd = app.add_subcommand(
      "deform", "deform a mesh once: print the seven measures and flips, write the result");
  cmd->add_option("MESH", opts->mesh, "mesh file (.obj .off .ply .stl .glb .gltf) or library name");
  add_constraint_options(*cmd, opts->c);
  add_beta_options(*cmd, opts->c, true);
  cmd->add_option("-o,--output", opts->output, "write the deformed mesh (.glb .obj .off .ply)");
  add_mesh_output_options(*cmd, opts->out);
  cmd->add_flag("--keep", opts->keep, "keep the session on the server and print its name");
  auto* beta_opt = cmd->get_option("--beta");

  return [opts, &global, beta_opt]() -> int {
    const auto& o = *opts;
    check_mesh_or_session(o.mesh, o.c, global);
    pb::MeshFormat format = pb::MESH_FORMAT_GLB;
    if (!o.output.empty()) format = mesh_format_for(o.output);
    const pb::Beta beta = build_beta(o.c);  // syntax errors before any call
    const bool automatic = beta_is_auto(o.c);
    const std::unique_ptr<ConstraintSpec> spec = constraint_spec_for(o.c);

    Connection conn(global);
    WorkSession w = open_work_session(conn, o.mesh, o.c);
    run_in_work_session(conn, w, o.keep, std::cout, [&](SessionClient& s) {
      if (spec) s.set_constraints(spec->constraints);
      const auto transforms = transforms_for(o.c, s, spec.get());
      pb::Frame frame;
      if (automatic) {
        // One Deform message: the server picks β at exactly these transforms.
        frame = s.deform(transforms, 1, beta);
      } else {
        if (w.created || beta_opt->count() > 0 || o.c.beta_units != "area" ||
            !o.c.local_betas.empty())
          s.set_beta(beta);
        frame = s.update(transforms, 1);
      }
      check_frame_finite(frame, "transform");  // NaN/Inf: no report, no file
      const pb::Session& info = s.info();
      const char* units_name = frame.beta().units() == pb::BETA_UNITS_RAW ? "raw" : "area";

      std::cout << (info.mesh_name().empty() ? o.mesh : info.mesh_name()) << ": "
                << info.vertex_count() << " vertices, " << info.triangle_count()
                << " triangles, " << info.constraints().fixed().ids_size() << " fixed, "
                << info.constraints().handles_size() << " handle(s); beta "
                << shortest(frame.beta().value()) << " (" << units_name
                << (frame.beta().automatic() ? ", automatic" : "") << ")";
      if (!o.c.local_betas.empty())
        std::cout << " + " << o.c.local_betas.size() << " local beta region(s)";
      std::cout << "; solve " << g6(frame.solve_ms()) << " ms\n";
      if (frame.beta().automatic())
        std::cout << "automatic beta: picked " << shortest(frame.beta().value()) << " (" << units_name
                  << " units)\n";
      print_measures(std::cout, frame.measures());
      if (!o.output.empty()) {
        const std::size_t bytes = s.download(o.output, format, false, o.out);
        std::cout << "wrote " << o.output << " (" << bytes << " bytes)\n";
      }
    });
    std::cout.flush();
    return 0;
  };
}

}  // namespace hdeform::cli
