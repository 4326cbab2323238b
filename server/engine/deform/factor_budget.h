// A byte budget for cached factorizations, shared by every ConstraintSet charged to it (a
// server's sessions): each per-β, per-field or transient system is charged when it is
// built, and when the charged bytes plus other_bytes() (what else shares the budget, e.g.
// the cache of prepared meshes) exceed the limit, the least recently used evictable systems
// of any set are dropped from their caches, to be rebuilt on demand. Memory a solve still
// holds is freed when that solve ends.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <vector>

namespace hdeform {

class FactorBudget {
 public:
  // What the budget charges: one cached system. last_use orders evictions (touch()).
  struct Item {
    mutable std::atomic<std::uint64_t> last_use{0};
    virtual ~Item() = default;
  };
  // The cache an Item lives in; evict() drops the item from it (thread-safe; called with no
  // lock of the budget's held).
  class Owner {
   public:
    virtual void evict(const Item& item) const = 0;

   protected:
    ~Owner() = default;
  };

  // limit_bytes: the bound on charged bytes + other_bytes() (empty: 0). after_eviction runs
  // once the evicted items are released (e.g. to hand freed heap pages back to the system).
  explicit FactorBudget(std::size_t limit_bytes, std::function<std::size_t()> other_bytes = {},
                        std::function<void()> after_eviction = {});

  // A use of item: it becomes the most recently used. Lock-free.
  static void touch(const Item& item);
  // Charges item's bytes. Pinned items count but are never evicted (a set's β = 0 system,
  // which its harmonic basis came from; a transient system while its call runs). Then
  // evicts unpinned items, least recently used first and never `item` itself, until the
  // bound holds or nothing is left to evict. Evictions run on the calling thread after the
  // budget's lock is released: the caller must hold no lock that Owner::evict takes.
  // An item stops being charged when it is destroyed (the budget holds weak references).
  void charge(std::weak_ptr<const Owner> owner, std::weak_ptr<const Item> item,
              std::size_t bytes, bool pinned);
  // Charges item's bytes, pinned, only if the bound then still holds; evicts nothing. For
  // work that can wait or be skipped (a background order): it never costs a cached system.
  // False: nothing was charged.
  bool charge_if_room(std::weak_ptr<const Item> item, std::size_t bytes);

  struct Stats {
    std::size_t limit = 0, charged = 0, pinned = 0, items = 0;
    std::uint64_t evictions = 0;
  };
  Stats stats() const;

 private:
  struct Entry {
    std::weak_ptr<const Owner> owner;
    std::weak_ptr<const Item> item;
    std::size_t bytes = 0;
    bool pinned = false;
  };
  void prune_locked() const;  // drops entries whose item is gone
  std::size_t charged_locked() const;  // bytes of every entry

  const std::size_t limit_;
  const std::function<std::size_t()> other_bytes_;
  const std::function<void()> after_eviction_;
  mutable std::mutex mutex_;
  mutable std::vector<Entry> entries_;
  std::uint64_t evictions_ = 0;
};

}  // namespace hdeform
