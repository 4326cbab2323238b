#!/usr/bin/env bash
# Regenerates docs/thesis-reproduction.md and its images (docs/reproduction/) from the
# bundled data: installs, builds the report tool, runs every experiment. Measured on the
# 2-core machine (loadavg ≈ 6): the experiments 17–19 s, the whole script 25 s with an
# up-to-date build; a first build of the engine adds minutes. Files whose content did not
# change are left alone (PNGs compared by their pixels), so a rerun leaves git clean.
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
install_deps
configure
build --target hdeform-reproduce
"$BUILD/bench/reproduce/hdeform-reproduce" --data "$ROOT/data" --out "$ROOT/docs"
