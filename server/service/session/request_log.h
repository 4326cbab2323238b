// The answers of a session's recent changes by request id (docs/api.md "Retries"): a retry
// of a change whose answer was lost gets that answer again instead of applying the change a
// second time. Bounded: at most kMaxEntries answers, kMaxBytes of them, none older than
// kWindow; the oldest go first. Not thread-safe: used on the session's strand only.
#pragma once

#include <google/protobuf/message.h>
#include <grpcpp/support/status.h>

#include <chrono>
#include <cstddef>
#include <deque>
#include <map>
#include <string>

namespace hdeform::service {

class RequestLog {
 public:
  static constexpr std::size_t kMaxEntries = 256;
  static constexpr std::size_t kMaxBytes = 8u << 20;
  static constexpr std::chrono::minutes kWindow{10};
  static constexpr std::size_t kMaxIdBytes = 64;

  // INVALID_ARGUMENT naming `op` when `request_id` is longer than kMaxIdBytes.
  static void check_id(const std::string& request_id, const char* op);

  // The first answer to (op, request_id): its status, and its response parsed into
  // `response`. Nullopt-like false when there is none (or it expired).
  bool replay(const char* op, const std::string& request_id, google::protobuf::Message* response,
              grpc::Status* status);
  // Keeps the answer of an applied change (OK, or applied but not stored).
  void remember(const char* op, const std::string& request_id,
                const google::protobuf::Message& response, const grpc::Status& status);

 private:
  struct Entry {
    std::string key;
    std::string response;
    grpc::Status status;
    std::chrono::steady_clock::time_point at;
  };
  void expire(std::chrono::steady_clock::time_point now);

  std::deque<Entry> entries_;  // oldest first
  std::map<std::string, const Entry*> by_key_;
  std::size_t bytes_ = 0;
};

}  // namespace hdeform::service
