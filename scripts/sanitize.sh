#!/usr/bin/env bash
# AddressSanitizer + UBSan pass over the engine and service suites (clang++: g++ with
# sanitizers compiles the template-heavy code several times slower, TOOLCHAIN.md).
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
BUILD="${HDEFORM_ASAN_BUILD_DIR:-$ROOT/build-asan}"
install_deps
cmake -S "$ROOT" -B "$BUILD" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=clang++ \
  -DHDEFORM_SANITIZE=ON -DHDEFORM_BUILD_BENCH=OFF >/dev/null
cmake --build "$BUILD" -j "$JOBS" --target engine_tests service_tests
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
"$BUILD/tests/engine_tests" --gtest_brief=1
"$BUILD/tests/service/service_tests" --gtest_brief=1
echo "sanitize: engine and service suites clean under ASan + UBSan"
