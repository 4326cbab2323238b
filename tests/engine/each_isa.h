// Parameterized tests over the builds of the engine's hand-vectorized kernels
// (cpu_features.h): each test runs once per Isa, is skipped where the CPU lacks it, and
// restores the process's choice afterwards. Use:
//   class MySuite : public test::OnEachIsa {};
//   INSTANTIATE_TEST_SUITE_P(Isa, MySuite, test::kEachIsa, test::isa_param_name);
#pragma once

#include "engine/simd/cpu_features.h"

#include <gtest/gtest.h>

#include <string>

namespace hdeform::test {

class OnEachIsa : public ::testing::TestWithParam<Isa> {
 protected:
  void SetUp() override {
    if (!set_kernel_isa(GetParam())) GTEST_SKIP() << "this CPU does not run these kernels";
  }
  void TearDown() override { set_kernel_isa(best_); }
  const Isa best_ = kernel_isa();
};

inline const auto kEachIsa = ::testing::Values(Isa::generic, Isa::avx2);

inline std::string isa_param_name(const ::testing::TestParamInfo<Isa>& info) {
  return isa_name(info.param);
}

}  // namespace hdeform::test
