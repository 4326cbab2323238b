#include "service/infra/cache.h"

#include "service/infra/release_memory.h"

#include <openssl/evp.h>
#include <openssl/rand.h>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <stdexcept>
#include <vector>

namespace hdeform::service {

Sha256::Sha256() : ctx_(EVP_MD_CTX_new()) {
  if (!ctx_ || EVP_DigestInit_ex(static_cast<EVP_MD_CTX*>(ctx_), EVP_sha256(), nullptr) != 1)
    throw std::runtime_error("OpenSSL: SHA-256 unavailable");
}

Sha256::~Sha256() { EVP_MD_CTX_free(static_cast<EVP_MD_CTX*>(ctx_)); }

Sha256& Sha256::add(const void* data, std::size_t size) {
  if (size > 0) EVP_DigestUpdate(static_cast<EVP_MD_CTX*>(ctx_), data, size);
  return *this;
}

std::string Sha256::hex() {
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int length = 0;
  EVP_DigestFinal_ex(static_cast<EVP_MD_CTX*>(ctx_), digest, &length);
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out;
  out.reserve(2 * length);
  for (unsigned int i = 0; i < length; ++i) {
    out += kHex[digest[i] >> 4];
    out += kHex[digest[i] & 15];
  }
  return out;
}

std::string mesh_hash(const TriMesh& mesh) {
  const std::int64_t counts[2] = {mesh.V.rows(), mesh.F.rows()};
  return Sha256()
      .add(counts, sizeof counts)
      .add(mesh.V.data(), sizeof(double) * static_cast<std::size_t>(mesh.V.size()))
      .add(mesh.F.data(), sizeof(int) * static_cast<std::size_t>(mesh.F.size()))
      .hex();
}

std::string constraints_digest(const Constraints& c) {
  Sha256 h;
  auto add = [&h](const std::vector<int>& ids) {
    const std::int64_t n = static_cast<std::int64_t>(ids.size());
    h.add(&n, sizeof n).add(ids.data(), sizeof(int) * ids.size());
  };
  add(c.fixed);
  for (const auto& handle : c.handles) add(handle);
  return h.hex();
}

std::string random_hex64() {
  std::uint64_t value = 0;
  if (RAND_bytes(reinterpret_cast<unsigned char*>(&value), sizeof value) != 1)
    throw std::runtime_error("OpenSSL: RAND_bytes failed");
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(value));
  return buf;
}

std::shared_ptr<const void> Cache::lookup_locked(const std::string& key, Slot& slot) {
  if (slot.strong) {
    lru_.splice(lru_.begin(), lru_, slot.lru);
    return slot.strong;
  }
  if (auto alive = slot.weak.lock()) {  // evicted but still used by a session: reinstate
    insert_locked(key, slot, alive, slot.bytes);
    return alive;
  }
  return nullptr;
}

void Cache::insert_locked(const std::string& key, Slot& slot, std::shared_ptr<const void> obj,
                          std::size_t bytes) {
  slot.strong = obj;
  slot.weak = obj;
  slot.bytes = bytes;
  lru_.push_front(key);
  slot.lru = lru_.begin();
  bytes_ += bytes;
  evict_locked(key);
  bytes_now_->store(bytes_, std::memory_order_relaxed);
}

void Cache::evict_locked(const std::string& keep) {
  while (bytes_ > budget_ && !lru_.empty()) {
    const std::string victim = lru_.back();
    if (victim == keep) break;  // the newest entry stays even when it alone is too big
    auto it = slots_.find(victim);
    lru_.pop_back();
    if (it == slots_.end()) continue;
    Slot& s = *it->second;
    bytes_ -= s.bytes;
    s.strong.reset();
    ++counters_.evictions;
    spdlog::debug("cache: evicted {} ({} bytes)", victim, s.bytes);
    if (s.weak.expired()) slots_.erase(it);
  }
  // Forget slots whose objects died after eviction.
  for (auto it = slots_.begin(); it != slots_.end();) {
    if (!it->second->strong && it->second->weak.expired() && it->second.use_count() == 1)
      it = slots_.erase(it);
    else
      ++it;
  }
}

std::shared_ptr<const void> Cache::find_erased(const std::string& key) {
  std::lock_guard lock(mutex_);
  auto it = slots_.find(key);
  if (it == slots_.end()) return nullptr;
  return lookup_locked(key, *it->second);
}

std::shared_ptr<const void> Cache::get_or_create_erased(
    const std::string& key, const std::function<std::shared_ptr<const void>()>& make,
    const std::function<std::size_t(const void*)>& size_of) {
  std::shared_ptr<Slot> slot;
  {
    std::lock_guard lock(mutex_);
    auto& s = slots_[key];
    if (!s) s = std::make_shared<Slot>();
    if (auto hit = lookup_locked(key, *s)) {
      ++counters_.hits;
      return hit;
    }
    slot = s;
  }
  std::lock_guard build(slot->build);
  {
    std::lock_guard lock(mutex_);
    if (auto hit = lookup_locked(key, *slot)) {  // built while we waited
      ++counters_.hits;
      return hit;
    }
    ++counters_.misses;
  }
  std::shared_ptr<const void> obj = make();
  const std::size_t bytes = size_of(obj.get());
  std::lock_guard lock(mutex_);
  auto& s = slots_[key];
  if (s != slot) s = slot;  // the slot was pruned meanwhile: put ours back
  if (slot->strong) {       // defensive: should not happen under the build lock
    return slot->strong;
  }
  insert_locked(key, *slot, obj, bytes);
  return obj;
}

void Cache::update_size(const std::string& key, std::size_t bytes) {
  std::lock_guard lock(mutex_);
  auto it = slots_.find(key);
  if (it == slots_.end()) return;
  Slot& s = *it->second;
  if (s.strong) {
    bytes_ = bytes_ - s.bytes + bytes;
    s.bytes = bytes;
    evict_locked(key);
    bytes_now_->store(bytes_, std::memory_order_relaxed);
  } else {
    s.bytes = bytes;
  }
}

Cache::Cache(std::size_t budget_bytes)
    : budget_(budget_bytes),
      bytes_now_(std::make_shared<std::atomic<std::size_t>>(0)),
      // The budget may outlive the cache (a session holds its sets): it reads the mirror.
      factors_(std::make_shared<FactorBudget>(
          budget_bytes, [now = bytes_now_] { return now->load(std::memory_order_relaxed); },
          release_freed_memory)) {}

Cache::Stats Cache::stats() const {
  std::lock_guard lock(mutex_);
  Stats s = counters_;
  s.bytes = bytes_;
  s.budget = budget_;
  s.entries = lru_.size();
  return s;
}

}  // namespace hdeform::service
