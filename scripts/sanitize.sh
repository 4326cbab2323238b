#!/usr/bin/env bash
# AddressSanitizer + UBSan pass over the engine (engine_tests, kernel_tests), service and security suites, and the
# libFuzzer smoke runs (tests/fuzz: every reader, .sel/.def, job files, gRPC-Web frames over
# their seed corpora) in the same build (clang++: g++ with sanitizers compiles the
# template-heavy code several times slower).
#   HDEFORM_FUZZ_SMOKE_SECONDS (default 10): seconds per fuzz target.
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
BUILD="${HDEFORM_ASAN_BUILD_DIR:-$ROOT/build-asan}"
install_deps
cmake -S "$ROOT" -B "$BUILD" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=clang++ \
  -DHDEFORM_SANITIZE=ON -DHDEFORM_FUZZ=ON -DHDEFORM_BUILD_BENCH=OFF \
  -DHDEFORM_FUZZ_SMOKE_SECONDS="${HDEFORM_FUZZ_SMOKE_SECONDS:-10}" >/dev/null
cmake --build "$BUILD" -j "$JOBS" --target engine_tests kernel_tests service_tests security_tests fuzz_all
bash "$ROOT/scripts/check-suites.sh" "$BUILD" fuzz
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
export LSAN_OPTIONS="suppressions=$ROOT/tests/lsan.supp"  # each entry justified there
"$BUILD/tests/engine_tests" --gtest_brief=1
"$BUILD/tests/kernel_tests" --gtest_brief=1
"$BUILD/tests/service/service_tests" --gtest_brief=1
"$BUILD/tests/security/security_tests" --gtest_brief=1
echo "sanitize: engine, service and security suites clean under ASan + UBSan"
ctest --test-dir "$BUILD" -L fuzz --output-on-failure
echo "sanitize: fuzz smoke clean"
