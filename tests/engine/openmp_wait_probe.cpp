// Prints what the OpenMP runtime of this process was started with, after
// ensure_openmp_waits_passively (tests/CMakeLists.txt runs it with and without the variable,
// and with OMP_DISPLAY_ENV=true, so libgomp itself prints the policy it read at load).
#include "openmp_wait.h"

#include <omp.h>

#include <cstdio>
#include <cstdlib>

int main(int argc, char** argv) {
  hdeform::ensure_openmp_waits_passively(argv);
  const char* policy = std::getenv("OMP_WAIT_POLICY");
  std::printf("policy=%s argc=%d last=%s threads=%d\n", policy ? policy : "(unset)", argc,
              argv[argc - 1], omp_get_max_threads());
  return 0;
}
