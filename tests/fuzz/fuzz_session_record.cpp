// libFuzzer target for what the service reads back from its state store
// (server/service/state/stored_record.h): a state database or a Redis that someone else can
// write to is input too. parse_record either returns a record it has checked or throws
// StateError; tokens_of never reads out of bounds; parse_orderings returns only permutations.
#include "service/state/state_backend.h"
#include "service/state/stored_record.h"

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace {
// The seeds' mesh (tests/fuzz/make_seeds.py stored_orderings): 8 vertices.
constexpr int kVertices = 8;
const std::string kHash(64, 'a');

void check_permutation(const std::vector<int>& p) {
  if (p.empty()) return;
  if (p.size() != kVertices) __builtin_trap();
  std::vector<bool> seen(kVertices, false);
  for (const int v : p) {
    if (v < 0 || v >= kVertices || seen[static_cast<std::size_t>(v)]) __builtin_trap();
    seen[static_cast<std::size_t>(v)] = true;
  }
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  try {
    const auto record = hdeform::service::parse_record("fuzz", bytes);
    if (record.id() != "fuzz" || record.edit_token_sha256().size() != 32) __builtin_trap();
    hdeform::service::tokens_of(record);
  } catch (const hdeform::service::StateError&) {
  }
  if (const auto orders = hdeform::service::parse_orderings(bytes, kHash, kVertices)) {
    check_permutation(orders->order);
    check_permutation(orders->wide_order);
  }
  return 0;
}
