#!/usr/bin/env bash
# The whole test suite: installs, builds everything, checks that no suite vanished, runs
# ctest (the viewer's npm build and its browser tests run as ctest cases). The container
# suite (-L containers: builds the images, ~15 min) runs separately: scripts/container-test.sh
# through `ctest -L containers`, as .ci/run does.
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
install_deps
configure -DHDEFORM_BUILD_TESTS=ON -DHDEFORM_BUILD_BENCH=ON
build
bash "$ROOT/scripts/check-suites.sh" "$BUILD" engine service security cli docs gateway routing browser python bench-smoke containers
cd "$BUILD"
ctest --output-on-failure -j "$JOBS" --timeout 600 -LE '^containers$' "$@"
