#!/usr/bin/env bash
# Long fuzzing runs of every libFuzzer target in tests/fuzz (issue 8), one after the other.
#   bash scripts/fuzz.sh [seconds-per-target] [target...]      (default 300 s, all targets)
# Builds a clang++ ASan+UBSan fuzz build in build-fuzz (override with BUILD_DIR=...), runs
# each target with -rss_limit_mb=2048 -timeout=10 over its committed seed corpus (read only)
# plus a work corpus kept in BUILD_DIR/fuzz/work/TARGET (grows from run to run), and prints
# executions, time and crashes / timeouts / OOMs / leaks per target. Inputs that failed are
# left in BUILD_DIR/fuzz/runs/DATE/TARGET/. Exit status 1 when any target failed.
# Runs niced; JOBS (default 2) is the build parallelism. EXTRA_ARGS are passed to libFuzzer.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
seconds="${1:-300}"
shift || true
build="${BUILD_DIR:-$here/build-fuzz}"
jobs="${JOBS:-2}"

if [[ ! -f "$build/CMakeCache.txt" ]]; then
  cmake -S "$here" -B "$build" -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DHDEFORM_FUZZ=ON -DHDEFORM_SANITIZE=ON -DHDEFORM_BUILD_TESTS=ON -DHDEFORM_BUILD_BENCH=OFF
fi
nice cmake --build "$build" -j"$jobs" --target fuzz_all

if [[ $# -gt 0 ]]; then
  targets=("$@")
else
  targets=()
  for d in "$here"/tests/fuzz/corpus/*/; do
    t="$(basename "$d")"
    [[ -x "$build/tests/fuzz/$t" ]] && targets+=("$t")
  done
fi

run_dir="$build/fuzz/runs/$(date +%Y%m%d-%H%M%S)"
mkdir -p "$run_dir"
summary="$run_dir/summary.txt"
printf '%-22s %12s %8s %8s %8s %6s %6s  %s\n' target executions seconds crashes timeouts ooms leaks result | tee "$summary"
failed=0
for t in "${targets[@]}"; do
  work="$build/fuzz/work/$t/corpus"
  art="$run_dir/$t"
  mkdir -p "$work" "$art"
  start=$(date +%s)
  set +e
  # shellcheck disable=SC2086
  nice "$build/tests/fuzz/$t" -max_total_time="$seconds" -rss_limit_mb=2048 -timeout=10 \
    -print_final_stats=1 -artifact_prefix="$art/" ${EXTRA_ARGS:-} "$work" "$here/tests/fuzz/corpus/$t" \
    >"$art/log.txt" 2>&1
  rc=$?
  set -e
  took=$(( $(date +%s) - start ))
  execs=$(grep -Eo 'stat::number_of_executed_units: [0-9]+' "$art/log.txt" | awk '{print $2}' | tail -1)
  if [[ -z "$execs" ]]; then  # no final stats after a crash: the last status line's #N
    execs=$(grep -Eo '^#[0-9]+' "$art/log.txt" | tr -d '#' | tail -1)
  fi
  crashes=$(find "$art" -name 'crash-*' | wc -l)
  timeouts=$(find "$art" -name 'timeout-*' | wc -l)
  ooms=$(find "$art" -name 'oom-*' | wc -l)
  leaks=$(find "$art" -name 'leak-*' | wc -l)
  result=ok
  if [[ $rc -ne 0 || $crashes -ne 0 || $timeouts -ne 0 || $ooms -ne 0 || $leaks -ne 0 ]]; then
    result="FAILED (exit $rc; see $art/log.txt)"
    failed=1
  fi
  printf '%-22s %12s %8s %8s %8s %6s %6s  %s\n' "$t" "${execs:-?}" "$took" "$crashes" "$timeouts" "$ooms" "$leaks" "$result" | tee -a "$summary"
done
echo "summary: $summary"
exit $failed
