#include "engine/deform/factor_budget.h"

#include <algorithm>
#include <utility>

namespace hdeform {

namespace {
std::atomic<std::uint64_t> g_clock{0};  // the LRU's time: one tick per use
}  // namespace

FactorBudget::FactorBudget(std::size_t limit_bytes, std::function<std::size_t()> other_bytes,
                           std::function<void()> after_eviction)
    : limit_(limit_bytes),
      other_bytes_(std::move(other_bytes)),
      after_eviction_(std::move(after_eviction)) {}

void FactorBudget::touch(const Item& item) {
  item.last_use.store(g_clock.fetch_add(1, std::memory_order_relaxed) + 1,
                      std::memory_order_relaxed);
}

void FactorBudget::prune_locked() const {
  std::erase_if(entries_, [](const Entry& e) { return e.item.expired(); });
}

void FactorBudget::charge(std::weak_ptr<const Owner> owner, std::weak_ptr<const Item> item,
                          std::size_t bytes, bool pinned) {
  // Held for the whole call: the item charged now is never its own victim.
  const std::shared_ptr<const Item> charged_now = item.lock();
  if (charged_now) touch(*charged_now);
  // Read before the lock: other_bytes_ may take another object's lock.
  const std::size_t other = other_bytes_ ? other_bytes_() : 0;
  struct Victim {
    std::shared_ptr<const Owner> owner;
    std::shared_ptr<const Item> item;
  };
  std::vector<Victim> victims;
  {
    std::lock_guard lock(mutex_);
    entries_.push_back({std::move(owner), std::move(item), bytes, pinned});
    prune_locked();
    std::size_t total = other + charged_locked();
    if (total <= limit_) return;
    struct Candidate {
      std::uint64_t last_use;
      std::size_t index;
    };
    std::vector<Candidate> order;
    for (std::size_t i = 0; i < entries_.size(); ++i) {
      const Entry& e = entries_[i];
      if (e.pinned) continue;
      const auto live = e.item.lock();
      if (!live || live == charged_now) continue;
      order.push_back({live->last_use.load(std::memory_order_relaxed), i});
    }
    std::sort(order.begin(), order.end(),
              [](const Candidate& a, const Candidate& b) { return a.last_use < b.last_use; });
    std::vector<bool> evicted(entries_.size(), false);
    for (const Candidate& c : order) {
      if (total <= limit_) break;
      Entry& e = entries_[c.index];
      auto o = e.owner.lock();
      auto it = e.item.lock();
      if (!o || !it) continue;
      victims.push_back({std::move(o), std::move(it)});
      evicted[c.index] = true;
      total -= e.bytes;
      ++evictions_;
    }
    std::size_t i = 0;
    std::erase_if(entries_, [&](const Entry&) { return evicted[i++]; });
  }
  for (const Victim& v : victims) v.owner->evict(*v.item);
  if (victims.empty()) return;
  victims.clear();  // an item no solve holds is freed here
  if (after_eviction_) after_eviction_();
}

bool FactorBudget::charge_if_room(std::weak_ptr<const Item> item, std::size_t bytes) {
  const std::size_t other = other_bytes_ ? other_bytes_() : 0;  // before the lock, as above
  std::lock_guard lock(mutex_);
  prune_locked();
  const std::size_t total = other + charged_locked();
  if (total > limit_ || bytes > limit_ - total) return false;
  entries_.push_back({{}, std::move(item), bytes, /*pinned=*/true});
  return true;
}

std::size_t FactorBudget::charged_locked() const {
  std::size_t total = 0;
  for (const Entry& e : entries_) total += e.bytes;
  return total;
}

FactorBudget::Stats FactorBudget::stats() const {
  std::lock_guard lock(mutex_);
  prune_locked();
  Stats s;
  s.limit = limit_;
  s.items = entries_.size();
  s.evictions = evictions_;
  for (const Entry& e : entries_) {
    s.charged += e.bytes;
    if (e.pinned) s.pinned += e.bytes;
  }
  return s;
}

}  // namespace hdeform
