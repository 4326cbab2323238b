#include "engine/runtime/process_environment.h"

#include <cstdlib>
#include <utility>
#include <unistd.h>

namespace hdeform {

void ensure_process_environment(char** argv) {
  bool changed = false;
  // setenv(…, 0) never overwrites: a user's own value (even an empty one) stays.
  for (auto [name, value] : {std::pair{"OMP_WAIT_POLICY", "PASSIVE"},
                             std::pair{"GLIBC_TUNABLES", "glibc.malloc.hugetlb=1"}})
    if (std::getenv(name) == nullptr && ::setenv(name, value, 0) == 0) changed = true;
  if (!changed) return;
  ::execv("/proc/self/exe", argv);
  // Only reached if exec failed (no /proc): keep running with the defaults.
}

}  // namespace hdeform
