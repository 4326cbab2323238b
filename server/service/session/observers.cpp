#include "service/session/observers.h"

#include <algorithm>

namespace hdeform::service {

bool Observers::add_watcher(std::shared_ptr<EventSink> sink) {
  std::lock_guard lock(mutex_);
  if (closed_) return false;
  watchers_.push_back(std::move(sink));
  return true;
}

bool Observers::remove_watcher(const EventSink* sink) {
  std::lock_guard lock(mutex_);
  const auto it = std::find_if(watchers_.begin(), watchers_.end(),
                               [&](const auto& w) { return w.get() == sink; });
  if (it == watchers_.end()) return false;
  watchers_.erase(it);
  return true;
}

void Observers::add_stream(std::weak_ptr<AuthorizedStream> stream) {
  std::lock_guard lock(mutex_);
  std::erase_if(deform_, [](const auto& w) { return w.expired(); });
  deform_.push_back(std::move(stream));
}

int Observers::watchers() const {
  std::lock_guard lock(mutex_);
  return static_cast<int>(watchers_.size());
}

void Observers::broadcast(const std::shared_ptr<const pb::SessionEvent>& event,
                          const EventSink* except) const {
  std::vector<std::shared_ptr<EventSink>> sinks;
  {
    std::lock_guard lock(mutex_);
    sinks = watchers_;
  }
  for (auto& s : sinks)
    if (s.get() != except) s->push(event);
}

std::vector<std::shared_ptr<AuthorizedStream>> Observers::take_if(
    const std::function<bool(const AuthorizedStream&)>& lost) {
  std::vector<std::shared_ptr<AuthorizedStream>> out;
  std::lock_guard lock(mutex_);
  for (auto it = watchers_.begin(); it != watchers_.end();)
    if (lost(**it)) {
      out.push_back(std::move(*it));
      it = watchers_.erase(it);
    } else {
      ++it;
    }
  for (auto it = deform_.begin(); it != deform_.end();) {
    auto live = it->lock();
    if (!live || lost(*live)) {
      if (live) out.push_back(std::move(live));
      it = deform_.erase(it);
    } else {
      ++it;
    }
  }
  return out;
}

Observers::Open Observers::close() {
  Open out;
  std::lock_guard lock(mutex_);
  closed_ = true;
  out.watchers.swap(watchers_);
  for (auto& w : deform_)
    if (auto s = w.lock()) out.deform.push_back(std::move(s));
  deform_.clear();
  return out;
}

void Observers::end_all(const grpc::Status& why) {
  for (const auto& s : take_if([](const AuthorizedStream&) { return true; })) s->revoke(why);
}

bool Observers::acquire_delta_watcher(std::size_t limit) {
  int n = delta_watchers_.load();
  do {
    if (static_cast<std::size_t>(n) >= limit) return false;
  } while (!delta_watchers_.compare_exchange_weak(n, n + 1));
  return true;
}

}  // namespace hdeform::service
