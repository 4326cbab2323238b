#include "service/rpc/reactors.h"

#include "service/rpc/deform_service.h"
#include "service/infra/service_error.h"

#include <spdlog/spdlog.h>

namespace hdeform::service {

namespace {

// CreateSession: header, then upload chunks. Bounded: the byte limit per upload (as chunks
// arrive, and the declared total_bytes as an upper bound), the server-wide budget of bytes
// in flight, and a stall timeout (UploadBudget). A cancelled upload is never loaded.
class CreateSessionReactor final : public grpc::ServerReadReactor<v1::CreateSessionRequest> {
 public:
  CreateSessionReactor(DeformService* svc, grpc::CallbackServerContext* ctx,
                       v1::Session* response)
      : svc_(svc), ctx_(ctx), response_(response), ticket_(svc->uploads().open(ctx)) {
    StartRead(&request_);
  }

  void OnReadDone(bool ok) override {
    ticket_->touch();
    if (!ok) {
      if (ticket_->stalled()) {
        Finish({grpc::StatusCode::DEADLINE_EXCEEDED,
                "upload stalled: no data for " +
                    std::to_string(svc_->uploads().stall_timeout().count()) +
                    " ms (--upload-stall-timeout)"});
      } else if (ctx_->IsCancelled()) {
        Finish({grpc::StatusCode::CANCELLED, "upload cancelled by the client"});
      } else {
        ticket_->received_all();
        finish_upload();
      }
      return;
    }
    if (!have_header_) {
      if (!request_.has_header()) {
        Finish({grpc::StatusCode::INVALID_ARGUMENT,
                "the first CreateSessionRequest must carry the header"});
        return;
      }
      header_ = request_.header();
      have_header_ = true;
      const auto status = guarded([&] { check_header(); }, "CreateSession");
      if (!status.ok()) {
        Finish(status);
        return;
      }
    } else {
      if (!request_.has_chunk()) {
        Finish({grpc::StatusCode::INVALID_ARGUMENT,
                "only chunks may follow the CreateSession header"});
        return;
      }
      if (header_.has_library_mesh()) {
        Finish({grpc::StatusCode::INVALID_ARGUMENT,
                "a library mesh takes no upload chunks"});
        return;
      }
      const std::size_t n = request_.chunk().size();
      received_ += n;
      const auto limit = svc_->sessions().limits().max_upload_bytes;
      if (received_ > limit) {
        spdlog::warn("CreateSession: upload '{}' exceeds {} bytes; rejected", header_.filename(),
                     limit);
        Finish({grpc::StatusCode::RESOURCE_EXHAUSTED,
                "upload exceeds the limit of " + std::to_string(limit) +
                    " bytes (--max-upload-mb)"});
        return;
      }
      const auto declared = static_cast<std::size_t>(header_.total_bytes());
      if (declared > 0 && received_ > declared) {
        Finish({grpc::StatusCode::INVALID_ARGUMENT,
                "upload sent more than its declared total_bytes (" + std::to_string(declared) +
                    ")"});
        return;
      }
      // Declared uploads were charged in full at the header; others pay as they go.
      if (declared == 0 && !ticket_->charge(n)) {
        Finish(over_budget());
        return;
      }
      data_->append(request_.chunk());
    }
    request_.Clear();
    StartRead(&request_);
  }

  void OnDone() override {
    ticket_->detach();
    delete this;
  }

 private:
  grpc::Status over_budget() const { return svc_->uploads().exhausted(); }

  void check_header() {
    const auto& limits = svc_->sessions().limits();
    switch (header_.source_case()) {
      case v1::CreateSessionHeader::kLibraryMesh:
        if (header_.library_mesh().empty()) fail(grpc::StatusCode::INVALID_ARGUMENT,
                                                 "library_mesh is empty");
        break;
      case v1::CreateSessionHeader::kFilename:
        if (header_.filename().empty())
          fail(grpc::StatusCode::INVALID_ARGUMENT, "an upload needs a filename (its format)");
        break;
      default:
        fail(grpc::StatusCode::INVALID_ARGUMENT,
             "CreateSessionHeader needs library_mesh or filename");
    }
    if (header_.has_repair()) {
      if (header_.has_library_mesh())
        fail(grpc::StatusCode::INVALID_ARGUMENT,
             "repair applies to uploads; library meshes need none");
      repair_options(&header_.repair());  // fail fast, before an upload
    }
    if (header_.total_bytes() < 0)
      fail(grpc::StatusCode::INVALID_ARGUMENT, "total_bytes must not be negative");
    if (static_cast<std::uint64_t>(header_.total_bytes()) > limits.max_upload_bytes)
      fail(grpc::StatusCode::RESOURCE_EXHAUSTED,
           "upload of " + std::to_string(header_.total_bytes()) + " bytes exceeds the limit of " +
               std::to_string(limits.max_upload_bytes) + " bytes (--max-upload-mb)");
    svc_->sessions().check_id(header_.session_id());  // fail fast, before an upload
    svc_->sessions().check_capacity();
    if (header_.total_bytes() > 0) {
      const auto declared = static_cast<std::size_t>(header_.total_bytes());
      if (!ticket_->charge(declared)) throw ServiceError(over_budget().error_code(),
                                                         over_budget().error_message());
      data_->reserve(declared);  // accounted above: an upper bound, enforced per chunk
    }
  }

  void finish_upload() {
    if (!have_header_) {
      Finish({grpc::StatusCode::INVALID_ARGUMENT, "CreateSession needs a header"});
      return;
    }
    std::shared_ptr<const std::string> bytes = std::move(data_);
    svc_->pool().submit([this, bytes] {
      const auto status = guarded(
          [&] {
            svc_->sessions().check_capacity();
            std::shared_ptr<const MeshRef> mesh =
                header_.has_library_mesh()
                    ? svc_->load_library_mesh(header_.library_mesh(), svc_->open_order())
                    : svc_->load_upload(bytes, header_.filename(),
                                        header_.has_repair() ? &header_.repair() : nullptr,
                                        svc_->open_order());
            // The client left while its mesh was parsed: create nothing nobody will own.
            if (ctx_->IsCancelled())
              fail(grpc::StatusCode::CANCELLED, "upload cancelled by the client");
            IssuedTokens tokens;
            auto session =
                svc_->sessions().create(std::move(mesh), header_.session_id(),
                                        [this](Session& s) { s.name_upload(header_.filename()); },
                                        &tokens);
            *response_ = session->describe();
            response_->set_edit_token(tokens.edit);
            response_->set_view_token(tokens.view);
            if (session->mesh().repair) describe_repair(session->mesh(), response_->mutable_repair());
          },
          "CreateSession");
      Finish(status);
    });
  }

  DeformService* svc_;
  grpc::CallbackServerContext* ctx_;
  v1::Session* response_;
  std::shared_ptr<UploadBudget::Ticket> ticket_;
  v1::CreateSessionRequest request_;
  v1::CreateSessionHeader header_;
  bool have_header_ = false;
  std::size_t received_ = 0;
  std::shared_ptr<std::string> data_ = std::make_shared<std::string>();
};

}  // namespace

grpc::ServerReadReactor<v1::CreateSessionRequest>* new_create_session_reactor(
    DeformService* svc, grpc::CallbackServerContext* ctx, v1::Session* response) {
  return new CreateSessionReactor(svc, ctx, response);
}

}  // namespace hdeform::service
