#include "service/session/rig_export.h"

#include "engine/deform/skin_weights.h"
#include "engine/io/rig_glb.h"
#include "engine/io/mesh_io.h"
#include "service/infra/service_error.h"
#include "service/session/timeline.h"

#include <string>

namespace hdeform::service {

RigExport export_rig(const SessionPose& pose, const RequestLimits& limits,
                     const pb::ExportRigRequest& request,
                     const std::function<void()>& keep_going) {
  const char* op = "ExportRig";
  const int influences = request.influences() == 0 ? 4 : request.influences();
  if (influences != 4 && influences != 8)
    throw InvalidInput(std::string(op) + " influences: " + std::to_string(request.influences()) +
                       " is not 4 or 8 (joints per vertex; 0 means 4)");
  if (request.up() != pb::UP_AXIS_Y && request.up() != pb::UP_AXIS_Z)
    throw InvalidInput(std::string(op) + " up: unknown up axis " + std::to_string(request.up()));
  if (!pose.cs)
    fail(grpc::StatusCode::FAILED_PRECONDITION,
         std::string(op) + ": the session has no constraints yet: call SetConstraints first");
  const std::shared_ptr<const ConstraintSet>& cs = pose.cs;
  const SessionBeta& beta = pose.beta;
  const std::vector<HandleTransform>& transforms = pose.transforms;
  pb::Timeline timeline;
  if (!request.skip_animation()) timeline = *pose.timeline;
  RigExport out;
  out.report.set_version(pose.version);
  const int handles = cs->num_handles();
  if (1 + handles > kMaxRigJoints)
    fail(grpc::StatusCode::FAILED_PRECONDITION,
         std::string(op) + ": " + std::to_string(handles) + " handles; a glTF rig holds " +
             std::to_string(kMaxRigJoints - 1) + " (unsigned byte joints)");
  ParsedTimeline keys;
  if (timeline.keys_size() > 0) keys = parse_timeline(timeline, *cs);
  const FrameLayout& layout = *pose.mesh->layout;
  check_limit(rig_glb_bytes(static_cast<std::size_t>(layout.vertex_count()),
                            static_cast<std::size_t>(layout.triangle_count()), influences,
                            static_cast<std::size_t>(handles), keys.keys.size()),
              limits.max_animation_bytes, std::string(op) + " GLB bytes",
              "--max-animation-bytes");

  const PreparedMesh& pm = cs->mesh();
  RigGlbInput in;
  in.V = layout.to_base(pm.mesh().V);
  in.N = layout.to_base(vertex_normals(pm.mesh().V, pm.mesh().F));
  in.F = layout.base_triangles();
  in.influences = influences;
  const SkinWeights w = skin_weights(layout.to_base(cs->harmonic_basis()), influences);
  in.joints = w.joint;
  in.weights = w.weight;
  in.up_z = request.up() == pb::UP_AXIS_Z;
  const double diagonal =
      (in.V.colwise().maxCoeff() - in.V.colwise().minCoeff()).norm();
  out.report.set_joints(w.joints);
  out.report.set_influences(influences);
  out.report.set_bbox_diagonal(diagonal);

  auto pivots_of = [&](const std::vector<HandleTransform>& ts) {
    std::vector<Eigen::Vector3d> p(ts.size());
    for (std::size_t j = 0; j < ts.size(); ++j)
      p[j] = ts[j].pivot.value_or(cs->centroid(static_cast<int>(j)));
    return p;
  };
  // Each joint binds at the handle's pivot in the current pose.
  in.bind = pivots_of(transforms);
  // A pose's joints as glTF TRS, and the transforms those TRS stand for (what an engine plays
  // and what the report measures).
  auto trs_of = [&](const std::vector<HandleTransform>& ts, const std::string& pose,
                    std::vector<HandleTransform>* played) {
    const std::vector<Eigen::Vector3d> p = pivots_of(ts);
    std::vector<JointTrs> out_trs(ts.size());
    played->resize(ts.size());
    for (std::size_t j = 0; j < ts.size(); ++j) {
      const JointPose jp = joint_pose(ts[j], p[j], in.bind[j]);
      if (!jp.axis_aligned)
        fail(grpc::StatusCode::FAILED_PRECONDITION,
             std::string(op) + ": handle " + std::to_string(j) + " (" + pose +
                 ") has a stretch that is not axis-aligned; a glTF joint scales along its own "
                 "axes only: use a uniform or per-axis scale");
      out_trs[j] = {jp.translation, jp.rotation, jp.scale};
      (*played)[j] = as_transform(jp, in.bind[j]);
    }
    return out_trs;
  };
  // The exact solve of a pose against the LBS of what the joints play: the report's row.
  auto measure = [&](const std::vector<HandleTransform>& ts,
                     const std::vector<HandleTransform>& played, const SessionBeta& b,
                     pb::RigPoseError* row) {
    keep_going();
    const hdeform::Frame f =
        solve_at(*cs, ts, b, {.energies = false, .normals = false, .measures = false});
    const SkinError e = skin_error(skin_positions(in.V, w, played, in.bind),
                                   layout.to_base(f.positions));
    row->set_max(diagonal > 0 ? e.max / diagonal : e.max);
    row->set_rms(diagonal > 0 ? e.rms / diagonal : e.rms);
  };
  std::vector<HandleTransform> played;
  in.pose = trs_of(transforms, "the current pose", &played);
  auto* current = out.report.add_poses();
  current->set_current(true);
  measure(transforms, played, beta, current);
  for (std::size_t k = 0; k < keys.keys.size(); ++k) {
    const double t = keys.keys[k].time;
    const std::vector<HandleTransform> ts = keys.pose_at(t);
    in.key_times.push_back(t);
    in.keys.push_back(trs_of(ts, "key " + std::to_string(k), &played));
    SessionBeta b = beta;
    if (const auto key_beta = keys.beta_at(t)) {
      b = SessionBeta();
      b.uniform = *key_beta;
    }
    auto* row = out.report.add_poses();
    row->set_time_s(t);
    measure(ts, played, b, row);
  }
  keep_going();
  out.glb = rig_glb(in);
  return out;
}

}  // namespace hdeform::service
