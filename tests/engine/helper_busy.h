// Runs a test body with the process's helper thread (two_threads.h) taken, so every
// two_halves and two-thread solve inside it runs on the calling thread alone: the path a
// caller takes while another session's kernel holds the helper. Results must not change.
#pragma once

#include "engine/runtime/two_threads.h"

#include <gtest/gtest.h>

namespace hdeform::test {

template <class Fn>
void run_with_helper_busy(Fn&& fn) {
  // The outer call holds the helper; its part 0 (this thread) runs fn, part 1 does nothing.
  auto part = [](void* ctx, int p) {
    if (p == 0) (*static_cast<std::remove_reference_t<Fn>*>(ctx))();
  };
  ASSERT_TRUE(Helper::instance().run(part, &fn)) << "the helper is busy with another test";
}

}  // namespace hdeform::test
