#include "engine/runtime/one_blas_thread.h"

#include <dlfcn.h>

#include <cstdlib>
#include <mutex>

namespace hdeform {

void use_one_blas_thread() {
  static std::once_flag once;
  std::call_once(once, [] {
    if (std::getenv("OPENBLAS_NUM_THREADS") != nullptr) return;
    // Looked up, not linked: libblas.so.3 is whichever BLAS Debian's alternatives select.
    using SetThreads = void (*)(int);
    if (auto f = reinterpret_cast<SetThreads>(::dlsym(RTLD_DEFAULT, "openblas_set_num_threads")))
      f(1);
  });
}

}  // namespace hdeform
