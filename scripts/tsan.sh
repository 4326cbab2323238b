#!/usr/bin/env bash
# ThreadSanitizer pass over the concurrent suites: the service (sessions, strands, streams,
# the worker pool), the security suite (cancellation, deletes racing calls, uploads), the
# HTTP gateway, the two-thread factorization kernel and METIS calls at once (kernel_tests). clang++ (as scripts/sanitize.sh). Suppressions: tests/tsan.supp, each one justified
# there (only uninstrumented Debian libraries).
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
BUILD="${HDEFORM_TSAN_BUILD_DIR:-$ROOT/build-tsan}"
install_deps
cmake -S "$ROOT" -B "$BUILD" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=clang++ \
  -DHDEFORM_TSAN=ON -DHDEFORM_BUILD_BENCH=OFF
cmake --build "$BUILD" -j "$JOBS" --target service_tests security_tests gateway_tests kernel_tests
export TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1 suppressions=$ROOT/tests/tsan.supp"
# One OpenMP thread: libomp's runtime is not instrumented and its barriers read as races.
export OMP_NUM_THREADS=1
"$BUILD/tests/service/service_tests" --gtest_brief=1
"$BUILD/tests/security/security_tests" --gtest_brief=1
"$BUILD/tests/browser/gateway_tests" --gtest_brief=1
"$BUILD/tests/kernel_tests" --gtest_brief=1
echo "tsan: service, security, gateway and kernel suites clean under ThreadSanitizer"
