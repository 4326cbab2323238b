#!/usr/bin/env bash
# Fails when an expected test suite has no tests in a configured build dir: a missing tool
# must never make a whole suite vanish while CI stays green.
# usage: check-suites.sh BUILD_DIR LABEL...
set -euo pipefail
build="$1"; shift
status=0
for label in "$@"; do
  count=$(ctest --test-dir "$build" -N -L "^${label}\$" | sed -n 's/^Total Tests: //p')
  if [ -z "$count" ] || [ "$count" -eq 0 ]; then
    echo "check-suites: suite '$label' has no tests in $build" >&2
    status=1
  else
    echo "check-suites: $label: $count tests"
  fi
done
exit $status
