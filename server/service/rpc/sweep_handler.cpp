#include "service/rpc/deform_service.h"

#include "service/infra/release_memory.h"
#include "service/infra/service_error.h"
#include "service/session/convert.h"
#include "service/session/sweep_plan.h"

#include <spdlog/spdlog.h>

namespace hdeform::service {

// Sweep: one pool task per β, each queued behind whatever else waits, so a long sweep
// never holds the session's strand (edits go on) nor a worker for its whole length.
// Stops at the next β when the client leaves or its deadline passes, the session is
// deleted or the server stops. At most --max-sweeps run at once.
namespace {
struct SweepJob {
  DeformService* svc;
  grpc::CallbackServerContext* ctx;
  grpc::ServerUnaryReactor* reactor;
  v1::SweepResponse* response;
  std::shared_ptr<Session> session;
  SweepPlan plan;
  std::size_t next = 0;
};

void sweep_step(const std::shared_ptr<SweepJob>& job) {
  auto finish = [&](const grpc::Status& status) {
    --job->svc->running_sweeps();
    release_freed_memory();  // a finished sweep must not leave its peak resident
    job->reactor->Finish(status);
  };
  const auto status = guarded(
      [&] {
        if (job->ctx->IsCancelled()) throw Cancelled("Sweep cancelled by the client");
        if (std::chrono::system_clock::now() > job->ctx->deadline())
          fail(grpc::StatusCode::DEADLINE_EXCEEDED,
               "Sweep deadline exceeded after " + std::to_string(job->next) + " of " +
                   std::to_string(job->plan.betas.size()) + " betas");
        if (job->svc->stopping()) fail(grpc::StatusCode::UNAVAILABLE, "the server is stopping");
        if (job->session->closed())
          fail(grpc::StatusCode::NOT_FOUND, job->session->name() + " was deleted");
        sweep_row(job->plan, job->plan.betas[job->next], job->response->add_rows());
        ++job->next;
      },
      "Sweep");
  if (!status.ok()) return finish(status);
  if (job->next == job->plan.betas.size()) return finish(grpc::Status::OK);
  job->svc->pool().submit([job] { sweep_step(job); });
}
}  // namespace

grpc::ServerUnaryReactor* DeformService::Sweep(grpc::CallbackServerContext* ctx,
                                               const v1::SweepRequest* request,
                                               v1::SweepResponse* response) {
  auto* reactor = ctx->DefaultReactor();
  auto job = std::make_shared<SweepJob>();
  job->svc = this;
  job->ctx = ctx;
  job->reactor = reactor;
  job->response = response;
  // Looks the session up, plans and admits; here when the lookup does no work, else from the
  // pool (a restore parses and factorizes).
  auto enter = [this, ctx, request, reactor, job] {
    const auto status = guarded(
        [&] {
          job->session = session_for(*ctx, request->name(), Access::kEdit, "Sweep");
          job->plan = plan_sweep(job->session->pose(), job->session->limits(), *request);
          if (++running_sweeps_ > options_.request.max_concurrent_sweeps) {
            --running_sweeps_;
            fail(grpc::StatusCode::RESOURCE_EXHAUSTED,
                 "too many sweeps running (" +
                     std::to_string(options_.request.max_concurrent_sweeps) +
                     ", --max-sweeps); retry later");
          }
        },
        "Sweep");
    if (!status.ok()) {
      reactor->Finish(status);
      return;
    }
    pool_->submit([job] { sweep_step(job); });
  };
  if (store_.resident(request->name())) {
    enter();
    return reactor;
  }
  const auto admitted = guarded([this] { admit_to_pool(); }, "Sweep");
  if (!admitted.ok()) {
    reactor->Finish(admitted);
    return reactor;
  }
  pool_->submit(std::move(enter));
  return reactor;
}

}  // namespace hdeform::service
