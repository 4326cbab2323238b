// The process's OpenMP wait policy (docs/architecture.md "Threads").
//
// libgomp's idle threads spin after every parallel loop (≈ 300,000 polls when
// OMP_WAIT_POLICY is unset). On two cores that spinning thread holds the core the move's next
// step needs: the two-thread supernodal solve runs on its own helper thread
// (supernodal_solve.cpp), so guidance → solve → normals made three runnable threads fight for
// two cores. Passive waiting sleeps instead (a futex wake, microseconds, per loop).
// Measured with `bench/engine_bench`, see docs/benchmarks.md "Threads".
#pragma once

namespace hdeform {

// libgomp reads the policy from the environment once, when it loads, before main: so when
// OMP_WAIT_POLICY is unset this sets it to PASSIVE and re-executes the program (same pid and
// arguments). It returns once the variable is set; a user's own setting is kept, and if the
// re-exec fails the program goes on with libgomp's default. Call it first thing in main.
// Precondition: argv is main's (null-terminated).
void ensure_openmp_waits_passively(char** argv);

}  // namespace hdeform
