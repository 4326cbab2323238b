#include "service/infra/upload_budget.h"
#include "engine/runtime/elapsed_ms.h"

#include <spdlog/spdlog.h>

#include <algorithm>

namespace hdeform::service {

UploadBudget::Ticket::Ticket(UploadBudget& budget, grpc::CallbackServerContext* ctx)
    : budget_(budget), ctx_(ctx), last_ns_(steady_ns()) {}

UploadBudget::Ticket::~Ticket() { detach(); }

void UploadBudget::Ticket::touch() { last_ns_.store(steady_ns()); }

bool UploadBudget::Ticket::charge(std::size_t bytes) {
  std::size_t current = budget_.bytes_.load();
  do {
    if (current + bytes > budget_.max_bytes_ || current + bytes < current) return false;
  } while (!budget_.bytes_.compare_exchange_weak(current, current + bytes));
  charged_ += bytes;
  return true;
}

grpc::Status UploadBudget::exhausted() const {
  return {grpc::StatusCode::RESOURCE_EXHAUSTED,
          "the server is receiving too many uploads at once (" + std::to_string(max_bytes_) +
              " bytes in flight, --max-upload-inflight-mb); retry later"};
}

void UploadBudget::Ticket::detach() {
  std::lock_guard lock(mutex_);
  ctx_ = nullptr;
  budget_.bytes_ -= charged_;
  charged_ = 0;
}

UploadBudget::UploadBudget(std::size_t max_bytes, std::chrono::milliseconds stall_timeout)
    : max_bytes_(max_bytes), stall_timeout_(stall_timeout) {
  watchdog_ = std::thread([this] { watch(); });
}

UploadBudget::~UploadBudget() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  cv_.notify_all();
  if (watchdog_.joinable()) watchdog_.join();
}

std::shared_ptr<UploadBudget::Ticket> UploadBudget::open(grpc::CallbackServerContext* ctx) {
  std::shared_ptr<Ticket> t(new Ticket(*this, ctx));
  std::lock_guard lock(mutex_);
  std::erase_if(tickets_, [](const std::weak_ptr<Ticket>& w) { return w.expired(); });
  tickets_.push_back(t);
  return t;
}

void UploadBudget::watch() {
  const auto period = std::clamp(stall_timeout_ / 4, std::chrono::milliseconds(10),
                                 std::chrono::milliseconds(1000));
  std::unique_lock lock(mutex_);
  while (!cv_.wait_for(lock, period, [this] { return stopping_; })) {
    std::vector<std::shared_ptr<Ticket>> live;
    for (auto& w : tickets_)
      if (auto t = w.lock()) live.push_back(std::move(t));
    lock.unlock();
    const std::int64_t limit = steady_ns() - std::chrono::nanoseconds(stall_timeout_).count();
    for (auto& t : live) {
      if (t->last_ns_.load() > limit || t->stalled_ || t->received_all_) continue;
      std::lock_guard ticket_lock(t->mutex_);
      if (!t->ctx_) continue;
      // TryCancel never runs OnDone inline, so holding the ticket lock here is safe; OnDone
      // takes it (detach) before the context dies.
      t->stalled_ = true;
      spdlog::warn("CreateSession: upload stalled for {} ms; cancelled", stall_timeout_.count());
      t->ctx_->TryCancel();
    }
    live.clear();
    lock.lock();
  }
}

}  // namespace hdeform::service
