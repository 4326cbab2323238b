// Byte-bounded LRU shared by all sessions: prepared meshes keyed by content hash and
// constraint sets (with their factorizations) keyed by (mesh hash, constraint ids).
// Eviction only drops the cache's own reference: objects still held by sessions stay alive
// and are found again (a weak reference) until the last session lets go.
#pragma once

#include "engine/deform/deformer.h"

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <list>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <unordered_map>

namespace hdeform::service {

// SHA-256 (OpenSSL) over a sequence of byte ranges: cache identities come from uploads,
// so they must not be forgeable (a 64-bit FNV-1a collision would poison a shared entry).
class Sha256 {
 public:
  Sha256();
  ~Sha256();
  Sha256(const Sha256&) = delete;
  Sha256& operator=(const Sha256&) = delete;
  Sha256& add(const void* data, std::size_t size);
  Sha256& add(std::string_view bytes) { return add(bytes.data(), bytes.size()); }
  std::string hex();  // 64 lower-case hex digits; ends the hash

 private:
  void* ctx_;  // EVP_MD_CTX
};

// Content hash of the engine mesh (SHA-256 of the counts, then the V double and F int bytes).
std::string mesh_hash(const TriMesh& mesh);
// Digest of constraint ids (fixed set and each handle region, in order), SHA-256.
std::string constraints_digest(const Constraints& constraints);
// 16 random hex digits from the OS CSPRNG (session ids).
std::string random_hex64();

class Cache {
 public:
  struct Stats {
    std::size_t bytes = 0, budget = 0, entries = 0;
    std::uint64_t hits = 0, misses = 0, evictions = 0;
  };

  // budget_bytes bounds the cache's own entries and, together with them, every
  // factorization charged to factor_budget() (those are evicted first).
  explicit Cache(std::size_t budget_bytes);

  // The object for `key`, built by `make` on a miss (outside the cache lock; concurrent
  // callers for one key wait for a single build). Exceptions from `make` propagate and
  // nothing is cached.
  template <class T>
  std::shared_ptr<const T> get_or_create(const std::string& key,
                                         const std::function<std::shared_ptr<const T>()>& make,
                                         const std::function<std::size_t(const T&)>& size_of) {
    auto erased = get_or_create_erased(
        key, [&]() -> std::shared_ptr<const void> { return make(); },
        [&](const void* p) { return size_of(*static_cast<const T*>(p)); });
    return std::static_pointer_cast<const T>(erased);
  }

  template <class T>
  std::shared_ptr<const T> find(const std::string& key) {
    return std::static_pointer_cast<const T>(find_erased(key));
  }

  // Re-account an entry whose size changed (a constraint set that built its β > 0 blocks).
  void update_size(const std::string& key, std::size_t bytes);
  Stats stats() const;
  // The budget the constraint sets' factorizations are charged to (ConstraintSet::charge_to).
  const std::shared_ptr<FactorBudget>& factor_budget() const { return factors_; }

 private:
  struct Slot {
    std::mutex build;
    std::shared_ptr<const void> strong;  // set while in the LRU
    std::weak_ptr<const void> weak;      // alive while anyone holds it
    std::size_t bytes = 0;
    std::list<std::string>::iterator lru;
  };

  std::shared_ptr<const void> get_or_create_erased(
      const std::string& key, const std::function<std::shared_ptr<const void>()>& make,
      const std::function<std::size_t(const void*)>& size_of);
  std::shared_ptr<const void> find_erased(const std::string& key);
  // With mutex_ held: returns the live object and (re)inserts it at the LRU front.
  std::shared_ptr<const void> lookup_locked(const std::string& key, Slot& slot);
  void insert_locked(const std::string& key, Slot& slot, std::shared_ptr<const void> obj,
                     std::size_t bytes);
  void evict_locked(const std::string& keep);

  mutable std::mutex mutex_;
  std::size_t budget_;
  std::size_t bytes_ = 0;
  std::list<std::string> lru_;  // front = most recent
  std::unordered_map<std::string, std::shared_ptr<Slot>> slots_;
  Stats counters_;
  std::shared_ptr<std::atomic<std::size_t>> bytes_now_;  // bytes_, for the factor budget
  std::shared_ptr<FactorBudget> factors_;
};

}  // namespace hdeform::service
