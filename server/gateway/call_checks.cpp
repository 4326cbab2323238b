#include "gateway/call_checks.h"

#include <string>

#include "hdeform/v1/deform.pb.h"

namespace hdeform::gateway {

const google::protobuf::MethodDescriptor* find_method(std::string_view path) {
  const auto* service =
      hdeform::v1::CreateSessionRequest::descriptor()->file()->FindServiceByName("Deformation");
  return service->FindMethodByName(std::string(path.substr(kServicePrefix.size())));
}

std::optional<grpc::Status> body_refusal(std::string_view path, const grpc_web::ParsedBody& body) {
  if (!body.error.empty()) {
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "gateway: " + body.error);
  }
  const auto name = path.substr(kServicePrefix.size());
  const auto* service =
      hdeform::v1::CreateSessionRequest::descriptor()->file()->FindServiceByName("Deformation");
  const auto* method = find_method(path);
  if (!method) {
    return grpc::Status(grpc::StatusCode::UNIMPLEMENTED,
                        "gateway: " + std::string(service->full_name()) + " has no method '" +
                            std::string(name.substr(0, 100)) + "'");
  }
  if (!method->client_streaming() && body.messages.size() != 1) {
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                        "gateway: " + std::string(name) + " takes exactly one request message; " +
                            "the body holds " + std::to_string(body.messages.size()));
  }
  return std::nullopt;
}

}  // namespace hdeform::gateway
