// Reading a stored session record (stored_session.proto) back: the checks that make a
// record from a state store (input like any other) safe to restore. session_record.h makes
// records; this part needs no Session and is fuzzed on its own (tests/fuzz).
#pragma once

#include "service/access/access.h"
#include "stored_session.pb.h"

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace hdeform::service {

inline constexpr std::uint32_t kRecordFormat = 1;

// Parses and checks a stored record (StateError naming the id and the problem: not a record,
// an unknown format, another id, token hashes of the wrong size, embedded mesh bytes).
hdeform::state::StoredSession parse_record(const std::string& id, const std::string& bytes);

SessionTokens tokens_of(const hdeform::state::StoredSession& record);
// The record's token hashes as the state's token index keeps them (StateBackend).
std::vector<std::string> index_hashes(const hdeform::state::StoredSession& record);
// The hashes a caller presented, in the same form.
std::vector<std::string> index_hashes(const std::vector<TokenHash>& presented);

// The solver's orderings kept for a mesh (StoredOrderings, ordering_store.h), read back: each
// a permutation of 0..vertices−1, or empty when it was not kept. nullopt when the bytes are
// not a StoredOrderings of mesh `hash` with `vertices` vertices, or an order is not such a
// permutation. Never throws.
struct StoredOrders {
  std::vector<int> order, wide_order;
};
std::optional<StoredOrders> parse_orderings(std::string_view bytes, const std::string& hash,
                                            int vertices);

}  // namespace hdeform::service
