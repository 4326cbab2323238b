// What service_bench and load_bench both do to open a capsule session over gRPC: stream a
// mesh file to CreateSession in 1 MiB messages, and constrain the capsule's base (fixed)
// and cap (handle) by vertex ids. Header-only: load_bench links no benchmark library.
#pragma once

#include "fixtures/procedural.h"
#include "hdeform/v1/deform.grpc.pb.h"

#include <grpcpp/grpcpp.h>

#include <cstdint>
#include <string>

namespace hdeform::bench {

// CreateSession with `bytes` as file `filename`; `ctx` carries the caller's metadata.
inline grpc::Status upload_mesh(::hdeform::v1::Deformation::Stub& stub, grpc::ClientContext& ctx,
                                const std::string& filename, const std::string& bytes,
                                ::hdeform::v1::Session* out) {
  auto writer = stub.CreateSession(&ctx, out);
  ::hdeform::v1::CreateSessionRequest req;
  req.mutable_header()->set_filename(filename);
  req.mutable_header()->set_total_bytes(static_cast<std::int64_t>(bytes.size()));
  bool ok = writer->Write(req);
  constexpr std::size_t kChunk = 1u << 20;
  for (std::size_t at = 0; ok && at < bytes.size(); at += kChunk) {
    ::hdeform::v1::CreateSessionRequest chunk;
    chunk.set_chunk(bytes.substr(at, kChunk));
    ok = writer->Write(chunk);
  }
  writer->WritesDone();
  return writer->Finish();
}

// The capsule's constraints: `base` fixed, `cap` the one handle.
inline ::hdeform::v1::Constraints capsule_constraints(const procedural::CapsuleCase& c) {
  ::hdeform::v1::Constraints out;
  out.mutable_fixed()->add_selectors()->mutable_ids()->mutable_ids()->Add(c.base.begin(),
                                                                         c.base.end());
  out.add_handles()->add_selectors()->mutable_ids()->mutable_ids()->Add(c.cap.begin(),
                                                                       c.cap.end());
  return out;
}

}  // namespace hdeform::bench
