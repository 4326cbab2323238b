// What the HTTP door checks on a gRPC-Web call's body before the service sees it: the method
// must exist, the body must split into frames, and a method that takes one request message
// must get exactly one (else the service would wait for a half-close that never comes).
// Pure functions of the path and the parsed body, so the fuzzer drives them on whole request
// streams (tests/fuzz/fuzz_http_request.cpp).
#pragma once

#include "gateway/grpc_web.h"

#include <google/protobuf/descriptor.h>
#include <grpcpp/grpcpp.h>

#include <cstddef>
#include <optional>
#include <string_view>

namespace hdeform::gateway {

inline constexpr std::string_view kServicePrefix = "/hdeform.v1.Deformation/";

// A gRPC-Web body is read whole; one sent chunked (its size unknown until it is in) may hold
// at most this many bytes (one with a Content-Length: up to GatewayOptions::max_body_bytes).
inline constexpr std::size_t kChunkedBodyLimit = 4u << 20;

// The Deformation method a decoded URL path names; null if none. `path` starts with
// kServicePrefix.
const google::protobuf::MethodDescriptor* find_method(std::string_view path);

// A call the backend would never answer, refused at once (as the call's trailers): a
// malformed body (INVALID_ARGUMENT), an unknown method (UNIMPLEMENTED), or a method that is
// not client-streaming given other than one message (INVALID_ARGUMENT). nullopt: relay it.
// `path` starts with kServicePrefix.
std::optional<grpc::Status> body_refusal(std::string_view path, const grpc_web::ParsedBody& body);

}  // namespace hdeform::gateway
