#include "openmp_wait.h"

#include <cstdlib>
#include <unistd.h>

namespace hdeform {

void ensure_openmp_waits_passively(char** argv) {
  if (std::getenv("OMP_WAIT_POLICY") != nullptr) return;
  if (::setenv("OMP_WAIT_POLICY", "PASSIVE", 0) != 0) return;
  ::execv("/proc/self/exe", argv);
  // Only reached if exec failed (no /proc): keep running with libgomp's default policy.
}

}  // namespace hdeform
