#!/usr/bin/env bash
# The main job on the bundled data: installs, builds, deforms the cactus (Botsch–Sorkine
# benchmark constraints), prints the measures and writes cactus-deformed.glb.
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
install_deps
# A new build folder: the quick way, without tests and benches. An existing one keeps its
# options: forcing tests off would silently turn a test build into one without tests.
if [ -f "$BUILD/CMakeCache.txt" ]; then
  configure
else
  configure -DHDEFORM_BUILD_TESTS=OFF -DHDEFORM_BUILD_BENCH=OFF
fi
build --target hdeform
B="$ROOT/data/botsch-sorkine"
"$BUILD/client-cli/hdeform" deform "$B/cactus.off" --sel "$B/cactus.sel" --def "$B/cactus.def" \
  --beta "${BETA:-0.1}" -o "${OUT:-cactus-deformed.glb}"
