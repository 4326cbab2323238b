// libFuzzer target for stored session records (server/service/state/stored_record.h): a state
// database or a Redis that someone else can write to is input too. parse_record either
// returns a record it has checked or throws StateError; tokens_of never reads out of bounds.
#include "service/state/state_backend.h"
#include "service/state/stored_record.h"

#include <cstddef>
#include <cstdint>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  try {
    const auto record = hdeform::service::parse_record("fuzz", bytes);
    if (record.id() != "fuzz" || record.edit_token_sha256().size() != 32) __builtin_trap();
    hdeform::service::tokens_of(record);
  } catch (const hdeform::service::StateError&) {
  }
  return 0;
}
