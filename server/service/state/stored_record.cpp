#include "service/state/stored_record.h"

#include "engine/solve/permutation.h"
#include "service/state/state_backend.h"

#include <cstring>

namespace hdeform::service {

hdeform::state::StoredSession parse_record(const std::string& id, const std::string& bytes) {
  hdeform::state::StoredSession r;
  if (!r.ParseFromString(bytes))
    throw StateError("stored session " + id + ": not a session record (" +
                     std::to_string(bytes.size()) + " bytes that do not parse)");
  if (r.format() != kRecordFormat)
    throw StateError("stored session " + id + ": record format " + std::to_string(r.format()) +
                     " is not one this server reads (" + std::to_string(kRecordFormat) + ")");
  if (r.id() != id)
    throw StateError("stored session " + id + ": the record is of session '" + r.id() + "'");
  if (r.edit_token_sha256().size() != 32 || r.view_token_sha256().size() != 32)
    throw StateError("stored session " + id + ": token hashes are not SHA-256 digests");
  if (!r.snapshot().mesh_bytes().empty())
    throw StateError("stored session " + id + ": a record never embeds mesh bytes");
  return r;
}

SessionTokens tokens_of(const hdeform::state::StoredSession& r) {
  SessionTokens t;
  std::memcpy(t.edit.data(), r.edit_token_sha256().data(), t.edit.size());
  std::memcpy(t.view.data(), r.view_token_sha256().data(), t.view.size());
  t.set = true;
  return t;
}

std::vector<std::string> index_hashes(const hdeform::state::StoredSession& r) {
  return {r.edit_token_sha256(), r.view_token_sha256()};
}

std::vector<std::string> index_hashes(const std::vector<TokenHash>& presented) {
  std::vector<std::string> out;
  out.reserve(presented.size());
  for (const auto& h : presented)
    out.emplace_back(reinterpret_cast<const char*>(h.data()), h.size());
  return out;
}

std::optional<StoredOrders> parse_orderings(std::string_view bytes, const std::string& hash,
                                            int vertices) {
  hdeform::state::StoredOrderings stored;
  if (!stored.ParseFromArray(bytes.data(), static_cast<int>(bytes.size())) ||
      stored.mesh_hash() != hash || stored.vertices() != vertices)
    return std::nullopt;
  StoredOrders out{{stored.order().begin(), stored.order().end()},
                   {stored.wide_order().begin(), stored.wide_order().end()}};
  for (const auto* p : {&out.order, &out.wide_order})
    if (!p->empty() && !is_permutation_of(*p, vertices)) return std::nullopt;
  return out;
}

}  // namespace hdeform::service
