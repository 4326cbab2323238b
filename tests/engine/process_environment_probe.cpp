// Prints what this process was started with, after ensure_process_environment
// (tests/CMakeLists.txt runs it with and without the variables, and with
// OMP_DISPLAY_ENV=verbose, so libgomp itself prints the policy it read at load), and whether
// a large malloc'd block got transparent huge pages ("thp=yes"; "thp=n/a" where the kernel
// has THP off or a sanitizer's allocator replaces glibc's, which ignores the tunable).
#include "engine/runtime/process_environment.h"

#include <omp.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <string>

namespace {

bool thp_possible() {
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  return false;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
  return false;
#endif
#endif
  std::ifstream mode("/sys/kernel/mm/transparent_hugepage/enabled");
  std::string s((std::istreambuf_iterator<char>(mode)), std::istreambuf_iterator<char>());
  return !s.empty() && s.find("[never]") == std::string::npos;
}

long anon_huge_kb() {
  std::ifstream f("/proc/self/smaps_rollup");
  for (std::string line; std::getline(f, line);)
    if (line.rfind("AnonHugePages:", 0) == 0) return std::atol(line.c_str() + 14);
  return -1;
}

}  // namespace

int main(int argc, char** argv) {
  hdeform::ensure_process_environment(argv);
  const char* policy = std::getenv("OMP_WAIT_POLICY");
  const char* tunables = std::getenv("GLIBC_TUNABLES");
  const std::size_t bytes = 64u << 20;
  auto* block = static_cast<char*>(std::malloc(bytes));
  std::memset(block, 1, bytes);
  const long huge_kb = anon_huge_kb();
  const char* thp = !thp_possible() ? "n/a" : huge_kb > 0 ? "yes" : "no";
  std::printf("policy=%s tunables=%s argc=%d last=%s threads=%d thp=%s (%ld kB) %d\n",
              policy ? policy : "(unset)", tunables ? tunables : "(unset)", argc, argv[argc - 1],
              omp_get_max_threads(), thp, huge_kb, block[bytes / 2]);
  std::free(block);
  return 0;
}
