#include "service/infra/service_error.h"

#include "engine/io/mesh_io.h"
#include "engine/mesh/mesh.h"

#include <spdlog/spdlog.h>

#include <new>

namespace hdeform::service {

grpc::Status guarded(const std::function<void()>& fn, const char* what) {
  const char* op = what ? what : "request";
  try {
    fn();
    return grpc::Status::OK;
  } catch (const ServiceError& e) {
    spdlog::debug("{}: {} ({})", op, e.what(), static_cast<int>(e.code()));
    return e.status();
  } catch (const LimitExceeded& e) {
    spdlog::debug("{}: limit: {}", op, e.what());
    return {grpc::StatusCode::RESOURCE_EXHAUSTED, e.what()};
  } catch (const ReadCancelled& e) {
    spdlog::debug("{}: {}", op, e.what());
    return {grpc::StatusCode::CANCELLED, e.what()};
  } catch (const Cancelled& e) {
    spdlog::debug("{}: {}", op, e.what());
    return {grpc::StatusCode::CANCELLED, e.what()};
  } catch (const InvalidInput& e) {
    spdlog::debug("{}: invalid input: {}", op, e.what());
    return {grpc::StatusCode::INVALID_ARGUMENT, e.what()};
  } catch (const std::bad_alloc&) {
    spdlog::warn("{}: out of memory", op);
    return {grpc::StatusCode::RESOURCE_EXHAUSTED, "out of memory"};
  } catch (const std::exception& e) {
    spdlog::error("{}: internal error: {}", op, e.what());
    return {grpc::StatusCode::INTERNAL, e.what()};
  } catch (...) {
    spdlog::error("{}: unknown internal error", op);
    return {grpc::StatusCode::INTERNAL, "unknown internal error"};
  }
}

}  // namespace hdeform::service
