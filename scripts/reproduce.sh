#!/usr/bin/env bash
# Regenerates docs/thesis-reproduction.md and its images (docs/reproduction/) from the
# bundled data: installs, builds the report tool, runs every experiment (≈ 30 s).
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
install_deps
configure
build --target hdeform-reproduce
"$BUILD/bench/reproduce/hdeform-reproduce" --data "$ROOT/data" --out "$ROOT/docs"
