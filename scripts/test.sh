#!/usr/bin/env bash
# The whole test suite: installs, builds everything (viewer included), runs ctest.
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
install_deps
if [ -f "$ROOT/web-viewer/package.json" ]; then
  (cd "$ROOT/web-viewer" && npm ci --no-audit --no-fund && npm run build)
fi
configure -DHDEFORM_BUILD_TESTS=ON -DHDEFORM_BUILD_BENCH=ON
build
cd "$BUILD"
ctest --output-on-failure -j "$JOBS" --timeout 600 "$@"
