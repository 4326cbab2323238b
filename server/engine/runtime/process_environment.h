// The process's runtime environment, set before main's first allocation or OpenMP loop
// (docs/architecture.md "Threads", docs/benchmarks.md "Huge pages").
//
// OMP_WAIT_POLICY=PASSIVE: libgomp's idle threads spin after every parallel loop (≈ 300,000
// polls when the variable is unset). On two cores a spinning thread holds the core that a
// frame's helper thread (two_threads.h) needs; passive waiting sleeps instead (a futex wake,
// microseconds, per loop).
//
// GLIBC_TUNABLES=glibc.malloc.hugetlb=1: glibc asks for transparent huge pages
// (madvise(MADV_HUGEPAGE)) on the large blocks it maps and on its heap. A first touch of a 4 KiB
// page costs ≈ 11 µs on these VMs, and a session open or a β change touches hundreds of MB
// of fresh memory (operators, CHOLMOD's factor and workspace): one 2 MiB fault replaces 512
// of them (docs/benchmarks.md "Huge pages" has the numbers).
#pragma once

namespace hdeform {

// libgomp and glibc's allocator read these variables once, when the process starts: so when
// either is unset this sets it and re-executes the program (same pid and arguments). It
// returns once both are set; a user's own setting of either is kept (an empty value opts
// out), and if the re-exec fails the program goes on with the defaults. Call it first thing
// in main. Precondition: argv is main's (null-terminated).
void ensure_process_environment(char** argv);

}  // namespace hdeform
