// hdeform rig MESH <constraints> -o OUT.glb: the session as a skinned GLB (handles as joints,
// harmonic fields as skin weights; docs/cli.md "Rig export"), and how far its linear blend
// skinning is from the exact deformation at each exported pose.
#include "commands.h"
#include "constraint_options.h"
#include "output.h"
#include "work_session.h"

#include <fstream>
#include <iostream>
#include <memory>

namespace hdeform::cli {

namespace {

struct RigOptions {
  std::string mesh;
  std::string output;
  std::string report;
  int influences = 4;
  double animate_s = 0;
  bool no_animation = false;
  bool keep = false;
  ConstraintOptions c;
  MeshOutputOptions out;
};

std::string pose_name(const pb::RigPoseError& p) {
  return p.current() ? "current" : "key t=" + shortest(p.time_s()) + " s";
}

}  // namespace

Command add_rig_command(CLI::App& app, const GlobalOptions& global) {
  auto opts = std::make_shared<RigOptions>();
  auto* cmd = app.add_subcommand(
      "rig", "export the deformation as a skinned .glb (handles as joints, harmonic weights as "
             "skin weights) and report how far linear blend skinning is from the exact result");
  cmd->add_option("MESH", opts->mesh, "mesh file (.obj .off .ply .stl .glb .gltf) or library name");
  add_constraint_options(*cmd, opts->c);
  add_beta_options(*cmd, opts->c, true);
  cmd->add_option("-o,--output", opts->output, "the rig (.glb)")->required();
  cmd->add_option("--influences", opts->influences, "joints per vertex: 4, or 8")
      ->check(CLI::IsMember({4, 8}))
      ->capture_default_str();
  cmd->add_option("--animate", opts->animate_s,
                  "also an animation: the rest pose at 0 s, the given pose at SECONDS (a new "
                  "session's timeline)")
      ->check(CLI::PositiveNumber);
  cmd->add_flag("--no-animation", opts->no_animation,
                "leave out the animation of a --session's timeline");
  cmd->add_option("--report", opts->report,
                  "write pose,time_s,max,rms (LBS vs exact, fractions of the bbox diagonal) as CSV");
  add_mesh_output_options(*cmd, opts->out);
  cmd->add_flag("--keep", opts->keep, "keep the session on the server and print its name");
  auto* beta_opt = cmd->get_option("--beta");

  return [opts, &global, beta_opt]() -> int {
    const auto& o = *opts;
    check_mesh_or_session(o.mesh, o.c, global);
    if (mesh_format_for(o.output) != pb::MESH_FORMAT_GLB)
      throw CliError("rig: --output must be a .glb (a skinned glTF), not " + o.output);
    if (o.animate_s > 0 && o.mesh.empty())
      throw CliError("rig: --animate makes a timeline for a new session; a --session keeps its "
                     "own timeline (or leave it out with --no-animation)");
    const pb::Beta beta = build_beta(o.c);
    if (beta_is_auto(o.c))
      throw CliError("rig: --beta auto picks β per pose; a rig exports one β: give a value");
    const std::unique_ptr<ConstraintSpec> spec = constraint_spec_for(o.c);

    Connection conn(global);
    WorkSession w = open_work_session(conn, o.mesh, o.c);
    run_in_work_session(conn, w, o.keep, std::cout, [&](SessionClient& s) {
      if (spec) s.set_constraints(spec->constraints);
      const auto transforms = transforms_for(o.c, s, spec.get());
      if (w.created || beta_opt->count() > 0) s.set_beta(beta);
      const pb::Frame frame = s.update(transforms, 1);
      check_frame_finite(frame, "transform");
      if (o.animate_s > 0) {
        pb::Timeline timeline;
        auto* rest = timeline.add_keys();
        rest->set_time_s(0);
        for (std::size_t j = 0; j < transforms.size(); ++j) rest->add_transforms();
        auto* posed = timeline.add_keys();
        posed->set_time_s(o.animate_s);
        for (const auto& t : transforms) *posed->add_transforms() = t;
        s.set_timeline(timeline);
      }
      pb::ExportRigRequest req;
      req.set_influences(o.influences);
      req.set_up(o.out.up);
      req.set_skip_animation(o.no_animation);
      std::size_t bytes = 0;
      const pb::RigReport report = s.export_rig(o.output, req, &bytes);
      const int keys = report.poses_size() - 1;
      std::cout << "wrote " << o.output << " (" << bytes << " bytes; " << report.joints()
                << " joints: the fixed region and " << report.joints() - 1 << " handle(s); "
                << report.influences() << " influences per vertex; "
                << (keys > 0 ? std::to_string(keys) + " animation keys" : "no animation")
                << ")\n";
      std::cout << "LBS vs exact, as fractions of the bbox diagonal (" << g6(report.bbox_diagonal())
                << "):\n";
      for (const auto& p : report.poses())
        std::cout << "  " << pose_name(p) << ": max " << g6(p.max()) << ", rms " << g6(p.rms())
                  << "\n";
      if (!o.report.empty()) {
        std::string csv = "pose,time_s,max,rms\n";
        for (const auto& p : report.poses())
          csv += std::string(p.current() ? "current" : "key") + "," +
                 (p.current() ? "" : shortest(p.time_s())) + "," + shortest(p.max()) + "," +
                 shortest(p.rms()) + "\n";
        write_file(o.report, csv);
        std::cout << "wrote " << o.report << "\n";
      }
    });
    std::cout.flush();
    return 0;
  };
}

}  // namespace hdeform::cli
