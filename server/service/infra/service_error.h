// Mapping of failures to gRPC statuses: the engine's InvalidInput → INVALID_ARGUMENT with
// its message, ServiceError → its own code, anything else → INTERNAL.
#pragma once

#include <grpcpp/support/status.h>

#include <functional>
#include <stdexcept>
#include <string>

namespace hdeform::service {

class ServiceError : public std::runtime_error {
 public:
  ServiceError(grpc::StatusCode code, const std::string& message)
      : std::runtime_error(message), code_(code) {}
  grpc::StatusCode code() const { return code_; }
  grpc::Status status() const { return {code_, what()}; }

 private:
  grpc::StatusCode code_;
};

[[noreturn]] inline void fail(grpc::StatusCode code, const std::string& message) {
  throw ServiceError(code, message);
}

// Runs fn and turns whatever it throws into a status (OK when it returns normally).
grpc::Status guarded(const std::function<void()>& fn, const char* what = nullptr);

}  // namespace hdeform::service
