// SerialOpenMP: a per-thread hold on OpenMP regions, for CHOLMOD's num_threads(4) loops.
#include "engine/runtime/serial_openmp.h"

#include <gtest/gtest.h>
#include <omp.h>

#include <thread>

using hdeform::SerialOpenMP;

namespace {

// The team size a region asking for four threads gets on the calling thread.
int team_of_four() {
  int team = 0;
#pragma omp parallel num_threads(4)
  {
#pragma omp single
    team = omp_get_num_threads();
  }
  return team;
}

TEST(SerialOpenMP, HoldsThisThreadsRegionsToOneThreadAndRestores) {
  const int levels = omp_get_max_active_levels();
  ASSERT_EQ(team_of_four(), 4);  // num_threads wins over omp_set_num_threads: why the guard
  {
    SerialOpenMP serial;
    EXPECT_EQ(team_of_four(), 1);
    {
      SerialOpenMP nested;
      EXPECT_EQ(team_of_four(), 1);
    }
    EXPECT_EQ(team_of_four(), 1);  // the inner guard restored the outer one's setting
  }
  EXPECT_EQ(omp_get_max_active_levels(), levels);
  EXPECT_EQ(team_of_four(), 4);
}

TEST(SerialOpenMP, OtherThreadsKeepTheirTeams) {
  SerialOpenMP serial;
  int other = 0;
  std::thread t([&] { other = team_of_four(); });
  t.join();
  EXPECT_EQ(other, 4);  // another session's move keeps both cores
  EXPECT_EQ(team_of_four(), 1);
}

}  // namespace
