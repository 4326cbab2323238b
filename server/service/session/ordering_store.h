// The solver's orderings of the meshes sessions use (PreparedMesh::order, wide_order: METIS,
// 4.7 s of a 1M mesh's 7.7 s open), kept in the state store beside the mesh by its hash, so
// that a restore after a restart, another replica and a later session on the same mesh take
// them instead of computing them (docs/architecture.md "Durable state"). A cache: one that is
// missing, unreadable or of another mesh is computed again, and written again.
#pragma once

#include "service/session/mesh_library.h"
#include "service/state/state_backend.h"

#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace hdeform::service {

class OrderingStore {
 public:
  explicit OrderingStore(StateBackend& backend) : backend_(backend) {}

  // Before a new or restored session's first factorization (on the pool: it reads the
  // store): adopts the orderings kept for `mesh`, if any. Never throws; a failure is logged.
  void prime(const MeshRef& mesh);
  // The same in two steps, for a restore that asks before its mesh is prepared (whether
  // create() should order it: PrepareOrder): the stored bytes for a mesh hash (nullopt:
  // none, or unreadable, logged), then their orderings adopted by the mesh.
  std::optional<std::string> read(const std::string& mesh_hash);
  void prime(const MeshRef& mesh, const std::optional<std::string>& bytes);
  // Writes the orderings computed since they were last kept, for the meshes in use (the
  // flusher's job; the others are forgotten here, not in the store). Never throws: a failed
  // write is logged and tried again at the next call.
  void keep(const std::vector<std::shared_ptr<const MeshRef>>& in_use);
  // Bytes of a StoredOrderings for `mesh` with what it has computed.
  static std::string encode(const MeshRef& mesh);

 private:
  enum : unsigned { kOrder = 1, kWide = 2 };
  StateBackend& backend_;
  std::mutex mutex_;
  std::map<std::string, unsigned> kept_;  // mesh hash → what the store holds (kOrder | kWide)
};

}  // namespace hdeform::service
