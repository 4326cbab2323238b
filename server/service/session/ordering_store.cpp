#include "service/session/ordering_store.h"

#include "service/state/stored_record.h"
#include "stored_session.pb.h"

#include <spdlog/spdlog.h>

#include <optional>
#include <set>

namespace hdeform::service {

namespace {
unsigned computed(const PreparedMesh& pm) {
  return (pm.has_order() ? 1u : 0u) | (pm.has_wide_order() ? 2u : 0u);
}
}  // namespace

std::optional<std::string> OrderingStore::read(const std::string& mesh_hash) {
  if (mesh_hash.empty()) return std::nullopt;
  try {
    return backend_.get_derived(mesh_hash);
  } catch (const StateError& e) {
    spdlog::warn("mesh {}: its orderings could not be read ({}); computing them", mesh_hash,
                 e.what());
    return std::nullopt;
  }
}

void OrderingStore::prime(const MeshRef& mesh) {
  if (computed(*mesh.prepared) == (kOrder | kWide)) return;
  prime(mesh, read(mesh.hash));
}

void OrderingStore::prime(const MeshRef& mesh, const std::optional<std::string>& bytes) {
  const PreparedMesh& pm = *mesh.prepared;
  if (computed(pm) == (kOrder | kWide)) return;
  if (!bytes) return;
  const auto stored = parse_orderings(*bytes, mesh.hash, pm.n());
  if (!stored) {
    spdlog::warn("mesh {}: the stored orderings are unreadable, of another mesh or not "
                 "permutations of its vertices; computing them",
                 mesh.hash);
    return;
  }
  unsigned taken = 0;
  if (!stored->order.empty() && pm.adopt_order(stored->order, false)) taken |= kOrder;
  if (!stored->wide_order.empty() && pm.adopt_order(stored->wide_order, true)) taken |= kWide;
  if (taken == 0) return;
  {
    std::lock_guard lock(mutex_);
    kept_[mesh.hash] |= taken;
  }
  spdlog::info("mesh {}: {} taken from the state store (no METIS call)", mesh.hash,
               taken == (kOrder | kWide) ? "both orderings"
               : taken == kOrder         ? "the β = 0 ordering"
                                         : "the β > 0 ordering");
}

std::string OrderingStore::encode(const MeshRef& mesh) {
  const PreparedMesh& pm = *mesh.prepared;
  hdeform::state::StoredOrderings out;
  out.set_mesh_hash(mesh.hash);
  out.set_vertices(pm.n());
  if (pm.has_order()) out.mutable_order()->Add(pm.order().begin(), pm.order().end());
  if (pm.has_wide_order())
    out.mutable_wide_order()->Add(pm.wide_order().begin(), pm.wide_order().end());
  return out.SerializeAsString();
}

void OrderingStore::keep(const std::vector<std::shared_ptr<const MeshRef>>& in_use) {
  std::map<std::string, std::shared_ptr<const MeshRef>> todo;  // one per mesh
  {
    std::lock_guard lock(mutex_);
    std::set<std::string> used;
    for (const auto& m : in_use) {
      used.insert(m->hash);
      const unsigned have = computed(*m->prepared);
      if ((have & ~kept_[m->hash]) != 0) todo.emplace(m->hash, m);
    }
    std::erase_if(kept_, [&](const auto& e) { return !used.count(e.first); });
  }
  for (const auto& [hash, mesh] : todo) {
    const unsigned have = computed(*mesh->prepared);
    try {
      backend_.put_derived(hash, encode(*mesh));
    } catch (const StateError& e) {
      spdlog::error("mesh {}: its orderings could not be kept: {}", hash, e.what());
      continue;
    }
    std::lock_guard lock(mutex_);
    kept_[hash] |= have;
  }
}

}  // namespace hdeform::service
