#include "service/session/request_log.h"

#include "service/infra/service_error.h"

namespace hdeform::service {

namespace {
std::string key_of(const char* op, const std::string& request_id) {
  return std::string(op) + '\n' + request_id;  // ids are per method: a retry is the same call
}
}  // namespace

void RequestLog::check_id(const std::string& request_id, const char* op) {
  if (request_id.size() > kMaxIdBytes)
    fail(grpc::StatusCode::INVALID_ARGUMENT,
         std::string(op) + ": request_id has " + std::to_string(request_id.size()) +
             " bytes, at most " + std::to_string(kMaxIdBytes));
}

void RequestLog::expire(std::chrono::steady_clock::time_point now) {
  while (!entries_.empty() && (entries_.size() > kMaxEntries || bytes_ > kMaxBytes ||
                               now - entries_.front().at > kWindow)) {
    if (const auto it = by_key_.find(entries_.front().key);
        it != by_key_.end() && it->second == &entries_.front())
      by_key_.erase(it);
    bytes_ -= entries_.front().response.size() + entries_.front().key.size();
    entries_.pop_front();
  }
}

bool RequestLog::replay(const char* op, const std::string& request_id,
                        google::protobuf::Message* response, grpc::Status* status) {
  if (request_id.empty()) return false;
  expire(std::chrono::steady_clock::now());
  const auto it = by_key_.find(key_of(op, request_id));
  if (it == by_key_.end()) return false;
  response->ParseFromString(it->second->response);
  *status = it->second->status;
  return true;
}

void RequestLog::remember(const char* op, const std::string& request_id,
                          const google::protobuf::Message& response, const grpc::Status& status) {
  if (request_id.empty()) return;
  const auto now = std::chrono::steady_clock::now();
  Entry e{key_of(op, request_id), response.SerializeAsString(), status, now};
  bytes_ += e.response.size() + e.key.size();
  if (const auto old = by_key_.find(e.key); old != by_key_.end()) by_key_.erase(old);
  entries_.push_back(std::move(e));
  by_key_[entries_.back().key] = &entries_.back();
  expire(now);
}

}  // namespace hdeform::service
