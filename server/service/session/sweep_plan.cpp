#include "service/session/sweep_plan.h"

#include "service/infra/service_error.h"
#include "service/session/convert.h"
#include "service/session/session_detail.h"

#include <string>

namespace hdeform::service {

SweepPlan plan_sweep(const SessionPose& pose, const RequestLimits& limits,
                     const pb::SweepRequest& request) {
  if (request.betas_size() == 0) throw InvalidInput("Sweep: betas is empty");
  check_limit(static_cast<std::size_t>(request.betas_size()), limits.max_sweep_betas,
              "Sweep betas", "--max-sweep-betas");
  SweepPlan plan;
  if (!pose.cs) fail(grpc::StatusCode::FAILED_PRECONDITION, detail::kNoConstraints);
  plan.cs = pose.cs;
  plan.transforms = pose.transforms;
  const SessionBeta& session_beta = pose.beta;
  if (request.transforms_size() > 0) plan.transforms = from_proto(request.transforms(), *plan.cs);
  for (int i = 0; i < request.betas_size(); ++i) {
    try {
      plan.betas.push_back(beta_from(request.betas(i), request.units()));
    } catch (const InvalidInput& e) {
      throw InvalidInput("Sweep betas[" + std::to_string(i) + "]: " + e.what());
    }
  }
  // The session's local entries apply at every β (value = that β), in the sweep's units.
  if (session_beta.has_local()) {
    const BetaUnits from = session_beta.uniform.units, to = units_from(request.units());
    const PreparedMesh& pm = *pose.mesh->prepared;
    plan.local_max = session_beta.local_max->unaryExpr(
        [&](double v) { return convert_beta(pm, v, from, to); });
  }
  return plan;
}

void sweep_row(const SweepPlan& plan, const Beta& b, pb::SweepRow* row) {
  const UpdateOptions options{.energies = false, .normals = false};
  // Transient: a sweep's factorizations are freed after each β and never enter the cache
  // other sessions share (at most one extra factorization per running sweep).
  const hdeform::Frame f =
      plan.local_max.size() > 0
          ? plan.cs->update_local(plan.transforms, *detail::make_field(plan.local_max, b), options)
          : plan.cs->update_transient(plan.transforms, b, options);
  row->set_beta(b.value);
  to_proto(f.measures, row->mutable_measures());
}

}  // namespace hdeform::service
