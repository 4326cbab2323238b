#!/usr/bin/env bash
# End-to-end tests of the hdeform CLI, run by ctest (LABELS cli):
#   cli_test.sh CASE HDEFORM DATA_DIR [HDEFORM_SERVER]
# Cases: deform, sweep, run, bad-inputs (in-process service) and remote (a real
# hdeform-server --port 0 started here: deform/sweep --server, and watch).
set -uo pipefail

case_name=$1
HDEFORM=$2
DATA=$3
SERVER_BIN=${4:-}
PY=${PYTHON3:-python3}
HERE=$(cd "$(dirname "$0")" && pwd)
CHECK="$PY $HERE/check_outputs.py"

TMP=$(mktemp -d "${TMPDIR:-/tmp}/hdeform-cli-test.XXXXXX")
SERVER_PID=""
WATCH_PID=""
cleanup() {
  [ -n "$WATCH_PID" ] && kill "$WATCH_PID" 2>/dev/null
  if [ -n "$SERVER_PID" ]; then
    kill "$SERVER_PID" 2>/dev/null
    wait "$SERVER_PID" 2>/dev/null
  fi
  rm -rf "$TMP"
}
trap cleanup EXIT

fail() {
  echo "FAIL: $*" >&2
  exit 1
}

# expect_fail DESCRIPTION PATTERN -- COMMAND…: non-zero exit, exactly one stderr line matching.
expect_fail() {
  local what=$1 pattern=$2
  shift 3
  "$@" >"$TMP/out" 2>"$TMP/err"
  local rc=$?
  [ $rc -ne 0 ] || fail "$what: exit 0, expected failure"
  local lines
  lines=$(wc -l <"$TMP/err")
  [ "$lines" -eq 1 ] || { cat "$TMP/err" >&2; fail "$what: $lines stderr lines, expected 1"; }
  grep -Eq -- "$pattern" "$TMP/err" || fail "$what: stderr '$(cat "$TMP/err")' does not match /$pattern/"
  echo "ok (exit $rc): $what: $(cat "$TMP/err")"
}

check_measures() {  # FILE: the deform report
  for m in '^E ' '^E_iso\^N ' '^E_conf\^N ' '^E_area % ' '^max e_iso ' '^max e_conf ' \
           '^max e_f\^2 ' '^flips +[0-9]+$'; do
    grep -Eq "$m" "$1" || { cat "$1" >&2; fail "deform output lacks /$m/"; }
  done
}

BS=$DATA/botsch-sorkine

start_server() {
  [ -x "$SERVER_BIN" ] || fail "no hdeform-server binary"
  "$SERVER_BIN" --port 0 --bind 127.0.0.1 --workers 1 >"$TMP/server.out" 2>"$TMP/server.err" &
  SERVER_PID=$!
  for _ in $(seq 1 300); do
    ADDR=$(sed -n 's/^hdeform-server listening on \([^ ]*\).*/\1/p' "$TMP/server.out")
    [ -n "$ADDR" ] && return 0
    kill -0 "$SERVER_PID" 2>/dev/null || { cat "$TMP/server.err" >&2; fail "hdeform-server exited"; }
    sleep 0.1
  done
  fail "hdeform-server did not report its address"
}

case "$case_name" in
deform)
  "$HDEFORM" deform cactus --sel "$BS/cactus.sel" --def "$BS/cactus.def" -o "$TMP/cactus.glb" \
    >"$TMP/out" || fail "deform exited $?"
  cat "$TMP/out"
  check_measures "$TMP/out"
  grep -q "^wrote $TMP/cactus.glb" "$TMP/out" || fail "no 'wrote' line"
  $CHECK glb "$TMP/cactus.glb" 5261 || fail "bad GLB"
  # an uploaded file, geometric selectors, β, OBJ output
  "$HDEFORM" deform "$BS/cactus.off" --fixed 'half:0,0,-1,-0.15' --handle 'half:0,0,1,0.8' \
    --rotate x,30 --translate 0,0.05,0 --beta 0.1 -o "$TMP/cactus.obj" >"$TMP/out2" \
    || fail "deform (upload) exited $?"
  check_measures "$TMP/out2"
  grep -c '^v ' "$TMP/cactus.obj" | grep -qx 5261 || fail "OBJ does not have 5261 vertices"
  ;;
sweep)
  "$HDEFORM" sweep cactus --sel "$BS/cactus.sel" --def "$BS/cactus.def" --betas 0,0.1,0.25 \
    --csv "$TMP/sweep.csv" --svg "$TMP/sweep.svg" >"$TMP/out" || fail "sweep exited $?"
  cat "$TMP/out"
  [ "$(wc -l <"$TMP/out")" -eq 4 ] || fail "table: expected a header and 3 rows"
  head -1 "$TMP/out" | grep -q 'beta.*E_iso^N.*flips' || fail "table header"
  $CHECK sweep-csv "$TMP/sweep.csv" 0,0.1,0.25 || fail "bad CSV"
  $CHECK svg "$TMP/sweep.svg" 8 3 || fail "bad SVG"
  # CSV on stdout
  "$HDEFORM" sweep cactus --sel "$BS/cactus.sel" --def "$BS/cactus.def" --betas 0.5 --csv - \
    >"$TMP/stdout.csv" || fail "sweep --csv - exited $?"
  $CHECK sweep-csv "$TMP/stdout.csv" 0.5 || fail "bad stdout CSV"
  ;;
run)
  "$HDEFORM" run "$DATA/jobs/small.json" -o "$TMP/out-small" >"$TMP/out" 2>"$TMP/progress" \
    || { cat "$TMP/progress" >&2; fail "run exited $?"; }
  cat "$TMP/progress" "$TMP/out"
  [ "$(grep -Ec '^\[[0-9]/8\] cactus .* ok [0-9]* ms( .*)?$' "$TMP/progress")" -eq 8 ] \
    || fail "expected 8 progress lines ending in 'ok N ms'"
  $CHECK summary "$TMP/out-small/summary.csv" 8 || fail "bad summary"
  [ "$(ls "$TMP"/out-small/*.glb | wc -l)" -eq 8 ] || fail "expected 8 GLB files"
  ;;
bad-inputs)
  cd "$TMP" || exit 1
  expect_fail "unknown option" 'hdeform: .*--bogus' -- "$HDEFORM" deform cactus --bogus
  expect_fail "no command" 'hdeform: ' -- "$HDEFORM"
  expect_fail "missing mesh file" 'hdeform: nope\.obj: no such file' -- \
    "$HDEFORM" deform nope.obj --handle ids:1
  expect_fail "unknown library mesh" 'hdeform: CreateSession: NOT_FOUND: ' -- \
    "$HDEFORM" deform nosuchmesh --handle ids:1
  expect_fail "bad selector" "hdeform: --handle 'box:1,2,3': expected 6" -- \
    "$HDEFORM" deform cactus --handle box:1,2,3
  expect_fail "bad output extension" 'hdeform: x\.txt: unsupported output format' -- \
    "$HDEFORM" deform cactus --sel "$BS/cactus.sel" -o x.txt
  expect_fail "beta out of range" 'hdeform: SetBeta: INVALID_ARGUMENT: ' -- \
    "$HDEFORM" deform cactus --sel "$BS/cactus.sel" --beta 1.5
  expect_fail "vertex id out of range" 'hdeform: SetConstraints: INVALID_ARGUMENT: ' -- \
    "$HDEFORM" deform cactus --fixed ids:0 --handle ids:99999999
  printf '# m\n1 0 0 0\n0 1 0 x\n' >bad.def
  expect_fail "bad .def" '^bad\.def:3: ' -- "$HDEFORM" deform cactus --sel "$BS/cactus.sel" --def bad.def
  printf '{\n  "meshes": ["cactus"],\n  "constraints": [ {"name": "a" "sel": "x"} ]\n}\n' >bad1.json
  expect_fail "JSON syntax" '^bad1\.json:3: ' -- "$HDEFORM" run bad1.json
  printf '{"meshes": ["cactus"], "constraints": [{"nme": "a"}]}\n' >bad2.json
  expect_fail "JSON schema" "^bad2\.json: constraints\[0\]: unknown key 'nme'" -- "$HDEFORM" run bad2.json
  expect_fail "sweep beta list" 'hdeform: --betas: ' -- \
    "$HDEFORM" sweep cactus --sel "$BS/cactus.sel" --betas 0,x
  expect_fail "no server" 'hdeform: cannot connect to hdeform-server at 127\.0\.0\.1:1$' -- \
    "$HDEFORM" --server 127.0.0.1:1 --timeout 5 deform cactus --sel "$BS/cactus.sel"
  ;;
remote)
  start_server
  echo "server at $ADDR"
  "$HDEFORM" --server "$ADDR" deform cactus --sel "$BS/cactus.sel" --def "$BS/cactus.def" \
    -o "$TMP/remote.glb" >"$TMP/out" || fail "remote deform exited $?"
  check_measures "$TMP/out"
  $CHECK glb "$TMP/remote.glb" 5261 || fail "bad GLB"
  # the same numbers in-process and remote (when this build has the in-process service)
  if "$HDEFORM" deform cactus --sel "$BS/cactus.sel" --def "$BS/cactus.def" >"$TMP/local" 2>/dev/null; then
    diff <(sed -n '/^E /,/^flips/p' "$TMP/local") <(sed -n '/^E /,/^flips/p' "$TMP/out") \
      || fail "in-process and remote measures differ"
  fi
  "$HDEFORM" sweep cactus --server "$ADDR" --sel "$BS/cactus.sel" --def "$BS/cactus.def" \
    --betas 0,0.1 --csv "$TMP/remote.csv" >/dev/null || fail "remote sweep exited $?"
  $CHECK sweep-csv "$TMP/remote.csv" 0,0.1 || fail "bad CSV"

  # watch: keep a session, watch it, move its handle from another client
  "$HDEFORM" --server "$ADDR" deform cactus --sel "$BS/cactus.sel" --def "$BS/cactus.def" --keep \
    >"$TMP/kept" || fail "deform --keep exited $?"
  SESSION=$(sed -n 's/^session \(sessions\/.*\)$/\1/p' "$TMP/kept")
  [ -n "$SESSION" ] || fail "deform --keep printed no session name"
  echo "kept $SESSION"
  "$HDEFORM" --server "$ADDR" watch "$SESSION" --for 60 >"$TMP/watch" 2>"$TMP/watch.err" &
  WATCH_PID=$!
  sleep 1
  "$HDEFORM" --server "$ADDR" deform --session "$SESSION" --beta 0.1 --translate 0,0.01,0 \
    >"$TMP/out3" || fail "deform --session exited $?"
  check_measures "$TMP/out3"
  for _ in $(seq 1 100); do
    grep -q '^frame seq=1 ' "$TMP/watch" && break
    sleep 0.1
  done
  cat "$TMP/watch"
  grep -Eq '^frame seq=1 version=[0-9]+ beta=0.1 E=[^ ]+ .* flips=[0-9]+ solve_ms=' "$TMP/watch" \
    || fail "watch printed no frame line"
  grep -q "^state $SESSION " "$TMP/watch" || fail "watch printed no state line"
  kill "$WATCH_PID" 2>/dev/null; wait "$WATCH_PID" 2>/dev/null; WATCH_PID=""
  expect_fail "watch unknown session" 'hdeform: WatchSession: NOT_FOUND: ' -- \
    "$HDEFORM" --server "$ADDR" watch sessions/doesnotexist --for 10
  ;;
*)
  fail "unknown case $case_name"
  ;;
esac
echo "PASS: $case_name"
