#!/usr/bin/env bash
# End-to-end tests of the hdeform CLI, run by ctest (LABELS cli):
#   cli_test.sh CASE HDEFORM DATA_DIR [HDEFORM_SERVER]
# Cases: deform, sweep, run, beta (automatic and local β), bad-inputs, run-names (hostile
# names in a job write only inside -o), non-finite (huge transforms: no file with NaN/Inf)
# (in-process service); remote (a real hdeform-server --port 0 started here: deform/sweep
# --server, and watch), run-sessions (a job with 3 meshes on a --max-sessions 1 server),
# tokens (a kept session's edit/view tokens used by later runs), tls (--tls-ca against a
# server with a certificate made here with openssl) and restart (a session survives kill -9
# of a server with --state-dir; watch and an in-flight call retry), sessions (sessions
# list/get/delete/export/import and meshes against a real server, sweep --session at a moved
# pose, their bad inputs) and progress (the status line only when stderr is a terminal).
# Every server started here gets --no-state (or a --state-dir in $TMP): never the user's
# ~/.local/share/hdeform.
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
SWEEP_PID=""
SERVER_PORT=""  # set by start_server; a restart reuses it
cleanup() {
  [ -n "$WATCH_PID" ] && kill "$WATCH_PID" 2>/dev/null
  [ -n "$SWEEP_PID" ] && kill "$SWEEP_PID" 2>/dev/null
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
# The cactus with its base fixed and the single topmost vertex (z = 0.89169…) as the handle,
# pulled sideways: the naive result has a spike there (thesis Figure 7.8).
SINGLE=(--fixed "sel:$BS/cactus.sel:0" --handle 'half:0,0,1,0.8916' --translate 0.08,0,0)
TOP='half:0,0,1,0.8916'

max_e_iso() { sed -n 's/^max e_iso  *//p' "$1"; }

start_server() {  # [extra hdeform-server options]; --no-state unless a --state-dir is given
  [ -x "$SERVER_BIN" ] || fail "no hdeform-server binary"
  local state=--no-state port=0 a
  for a in "$@"; do [ "$a" = --state-dir ] && state=; done
  [ -n "$SERVER_PORT" ] && port=$SERVER_PORT  # restart: the same port
  "$SERVER_BIN" --port "$port" --bind 127.0.0.1 --workers 1 $state "$@" \
    >"$TMP/server.out" 2>"$TMP/server.err" &
  SERVER_PID=$!
  for _ in $(seq 1 300); do
    ADDR=$(sed -n 's/^hdeform-server listening on \([^ ]*\).*/\1/p' "$TMP/server.out")
    [ -n "$ADDR" ] && { SERVER_PORT=${ADDR##*:}; return 0; }
    kill -0 "$SERVER_PID" 2>/dev/null || { cat "$TMP/server.err" >&2; fail "hdeform-server exited"; }
    sleep 0.1
  done
  fail "hdeform-server did not report its address"
}

# keep_session FILE: the session name and tokens a `--keep` run printed into FILE.
keep_session() {
  SESSION=$(sed -n 's/^session \(sessions\/.*\)$/\1/p' "$1")
  EDIT=$(sed -n 's/^edit token: \(.*\)$/\1/p' "$1")
  VIEW=$(sed -n 's/^view token: \(.*\)$/\1/p' "$1")
  [ -n "$SESSION" ] || { cat "$1" >&2; fail "--keep printed no session name"; }
  [ -n "$EDIT" ] && [ -n "$VIEW" ] && [ "$EDIT" != "$VIEW" ] \
    || { cat "$1" >&2; fail "--keep did not print two tokens"; }
}

# wait_for PATTERN FILE: up to 10 s for a line matching PATTERN in FILE.
wait_for() {
  for _ in $(seq 1 100); do
    grep -Eq -- "$1" "$2" && return 0
    sleep 0.1
  done
  cat "$2" >&2
  fail "no line /$1/ in $2"
}

# make_pki DIR: a CA and a server certificate for 127.0.0.1 / localhost signed by it, a
# client certificate signed by it, and an unrelated second CA.
make_pki() {
  local d=$1 ssl=${OPENSSL:-openssl}
  mkdir -p "$d"
  printf 'subjectAltName = IP:127.0.0.1,DNS:localhost\n' >"$d/server.ext"
  printf 'extendedKeyUsage = clientAuth\n' >"$d/client.ext"
  for ca in ca other-ca; do
    "$ssl" req -x509 -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -days 2 \
      -subj "/CN=hdeform test $ca" -keyout "$d/$ca.key" -out "$d/$ca.pem" 2>>"$d/log" \
      || { cat "$d/log" >&2; fail "openssl: $ca"; }
  done
  for who in server client; do
    "$ssl" req -new -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -subj "/CN=$who" \
      -keyout "$d/$who.key" -out "$d/$who.csr" 2>>"$d/log" || { cat "$d/log" >&2; fail "openssl: $who key"; }
    "$ssl" x509 -req -in "$d/$who.csr" -CA "$d/ca.pem" -CAkey "$d/ca.key" -CAcreateserial \
      -days 2 -extfile "$d/$who.ext" -out "$d/$who.pem" 2>>"$d/log" \
      || { cat "$d/log" >&2; fail "openssl: sign $who"; }
  done
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
  # outputs that keep what the user gave: the z-up cactus as an upright GLB, binary PLY in,
  # binary PLY out (and ASCII on request), bad values refused
  "$HDEFORM" deform cactus --sel "$BS/cactus.sel" --def "$BS/cactus.def" --up z \
    -o "$TMP/up.glb" >/dev/null || fail "deform --up z exited $?"
  grep -aq 'z-up to y-up' "$TMP/up.glb" || fail "--up z: no root rotation node in the GLB"
  $CHECK glb "$TMP/up.glb" 5261 || fail "bad --up z GLB"
  "$HDEFORM" deform cactus --sel "$BS/cactus.sel" --def "$BS/cactus.def" --ply binary \
    -o "$TMP/bin.ply" >/dev/null || fail "deform --ply binary exited $?"
  head -c 40 "$TMP/bin.ply" | grep -aq 'format binary_little_endian' || fail "--ply binary: ASCII"
  "$HDEFORM" deform "$TMP/bin.ply" --sel "$BS/cactus.sel" -o "$TMP/again.ply" >/dev/null \
    || fail "deform of a binary PLY exited $?"
  head -c 40 "$TMP/again.ply" | grep -aq 'format binary_little_endian' \
    || fail "a binary PLY input did not give a binary PLY output"
  "$HDEFORM" deform "$TMP/bin.ply" --sel "$BS/cactus.sel" --ply ascii -o "$TMP/ascii.ply" \
    >/dev/null || fail "deform --ply ascii exited $?"
  head -c 40 "$TMP/ascii.ply" | grep -aq 'format ascii' || fail "--ply ascii: not ASCII"
  expect_fail "--up x" "--up: Check x value in" -- \
    "$HDEFORM" deform cactus --sel "$BS/cactus.sel" --up x -o "$TMP/x.glb"
  # --repair: a bowtie (two triangles touching at vertex 0) is refused with the hint, and
  # opens repaired with what changed on stderr (vertex 0 split: 6 vertices written)
  printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nv -1 0 0\nv 0 -1 0\nf 1 2 3\nf 1 4 5\n' >"$TMP/bowtie.obj"
  expect_fail "bowtie without --repair" "non-manifold vertex.*\(--repair may fix it\)" -- \
    "$HDEFORM" deform "$TMP/bowtie.obj" --fixed ids:1,2,4,5 --handle ids:3 --translate 0,0,0.1 \
    -o "$TMP/bowtie-out.obj"
  "$HDEFORM" deform "$TMP/bowtie.obj" --repair --fixed ids:1,2,4,5 --handle ids:3 \
    --translate 0,0,0.1 -o "$TMP/bowtie-out.obj" >"$TMP/out" 2>"$TMP/err" \
    || { cat "$TMP/err" >&2; fail "deform --repair exited $?"; }
  grep -q '^hdeform: repair of bowtie.obj: split 1 non-manifold vertex' "$TMP/err" \
    || fail "no repair report on stderr: $(cat "$TMP/err")"
  [ "$(grep -c '^v ' "$TMP/bowtie-out.obj")" = 6 ] || fail "repaired bowtie: not 6 vertices"
  expect_fail "--merge-tolerance without --repair" "needs --repair|requires --repair|Needs: --repair" -- \
    "$HDEFORM" deform "$TMP/bowtie.obj" --merge-tolerance 0.001 --fixed ids:1 --handle ids:3
  expect_fail "--merge-tolerance 0.5" "merge-tolerance" -- \
    "$HDEFORM" deform "$TMP/bowtie.obj" --repair --merge-tolerance 0.5 --fixed ids:1 --handle ids:3
  ;;
sweep)
  "$HDEFORM" sweep cactus --sel "$BS/cactus.sel" --def "$BS/cactus.def" --betas 0,0.1,0.25 \
    --csv "$TMP/sweep.csv" --svg "$TMP/sweep.svg" >"$TMP/out" 2>"$TMP/err" || fail "sweep exited $?"
  cat "$TMP/out" "$TMP/err"
  # every output file is announced (on stderr: stdout is the table)
  grep -qx "wrote $TMP/sweep.csv ([0-9]* bytes)" "$TMP/err" || fail "no 'wrote …sweep.csv'"
  grep -qx "wrote $TMP/sweep.svg ([0-9]* bytes)" "$TMP/err" || fail "no 'wrote …sweep.svg'"
  # β without float noise: 0.1 is "0.1" in the CSV and the table, never 0.10000000000000001
  [ "$(cut -d, -f1 "$TMP/sweep.csv" | tr '\n' ' ')" = "beta 0 0.1 0.25 " ] \
    || fail "CSV beta column: $(cut -d, -f1 "$TMP/sweep.csv" | tr '\n' ' ')"
  [ "$(awk 'NR > 1 { print $1 }' "$TMP/out" | tr '\n' ' ')" = "0 0.1 0.25 " ] || fail "table beta column"
  "$HDEFORM" sweep cactus --sel "$BS/cactus.sel" --betas 0.3,0.7,0.123456789 --csv - >"$TMP/b.csv" \
    || fail "sweep exited $?"
  [ "$(cut -d, -f1 "$TMP/b.csv" | tr '\n' ' ')" = "beta 0.3 0.7 0.123456789 " ] \
    || fail "CSV beta column: $(cut -d, -f1 "$TMP/b.csv" | tr '\n' ' ')"
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
  # every file written is announced on stderr; β in the summary without float noise
  for f in "$TMP"/out-small/*.glb "$TMP/out-small/summary.csv"; do
    grep -qx "wrote $f ([0-9]* bytes)" "$TMP/progress" || fail "no 'wrote $f'"
  done
  [ "$(cut -d, -f4 "$TMP/out-small/summary.csv" | sort -u | tr '\n' ' ')" = "0 0.1 beta " ] \
    || fail "summary beta column: $(cut -d, -f4 "$TMP/out-small/summary.csv" | sort -u | tr '\n' ' ')"
  # More meshes than the in-process service's 64 sessions: each session is deleted when its
  # items are done.
  "$PY" -c 'import json, sys; json.dump({"format": "none", "meshes": [{"name": "m%d" % i, "library": "cactus"} for i in range(65)], "constraints": [{"fixed": "half:0,0,-1,-0.15", "handles": ["half:0,0,1,0.8"]}], "transforms": [{"translate": [0, 0, 0.01]}]}, sys.stdout)' \
    >"$TMP/m65.json"
  "$HDEFORM" run "$TMP/m65.json" -o "$TMP/out-65" >/dev/null 2>"$TMP/progress" \
    || { grep -v ' ok ' "$TMP/progress" | head -5 >&2; fail "run of 65 meshes in-process exited $?"; }
  [ "$(grep -c ' ok [0-9]* ms' "$TMP/progress")" -eq 65 ] || fail "expected 65 ok items"
  ;;
beta)
  "$HDEFORM" deform cactus "${SINGLE[@]}" >"$TMP/naive" || fail "naive deform exited $?"
  naive=$(max_e_iso "$TMP/naive")
  # --beta auto: the server picks β at the transforms; the pick is printed.
  "$HDEFORM" deform cactus "${SINGLE[@]}" --beta auto --beta-units raw -o "$TMP/auto.glb" \
    >"$TMP/auto" || fail "deform --beta auto exited $?"
  cat "$TMP/auto"
  check_measures "$TMP/auto"
  grep -q '; beta [0-9.]* (raw, automatic);' "$TMP/auto" || fail "no '(raw, automatic)' in the summary"
  pick=$(sed -n 's/^automatic beta: picked \([0-9.e-]*\) (raw units)$/\1/p' "$TMP/auto")
  [ -n "$pick" ] || fail "deform --beta auto printed no 'automatic beta: picked' line"
  awk -v b="$pick" 'BEGIN { exit !(b >= 0.1 && b <= 0.25) }' || fail "picked beta $pick not in [0.1, 0.25]"
  auto=$(max_e_iso "$TMP/auto")
  awk -v a="$auto" -v n="$naive" 'BEGIN { exit !(a * 10 <= n) }' \
    || fail "auto max e_iso $auto is not 10x below the naive $naive"
  $CHECK glb "$TMP/auto.glb" 5261 || fail "bad GLB"
  # --local-beta: a falloff around the handle vertex removes the spike as well.
  "$HDEFORM" deform cactus "${SINGLE[@]}" --local-beta "$TOP@0.3@0.03" >"$TMP/local" \
    || fail "deform --local-beta exited $?"
  cat "$TMP/local"
  grep -q '+ 1 local beta region(s)' "$TMP/local" || fail "no local beta in the summary"
  local_=$(max_e_iso "$TMP/local")
  awk -v a="$local_" -v n="$naive" 'BEGIN { exit !(a * 10 <= n) }' \
    || fail "local max e_iso $local_ is not 10x below the naive $naive"
  # two entries (one a plain region, radius 0), '|' in a selector
  "$HDEFORM" deform cactus "${SINGLE[@]}" --local-beta "$TOP|ids:0@0.3@0.03" \
    --local-beta 'ids:1,2@0.2' >"$TMP/local2" || fail "deform with two --local-beta exited $?"
  grep -q '+ 2 local beta region(s)' "$TMP/local2" || fail "two local entries not reported"
  # sweep: the local entries apply at every β
  "$HDEFORM" sweep cactus "${SINGLE[@]}" --local-beta "$TOP@0.3@0.03" --betas 0,0.1 \
    --csv "$TMP/local.csv" >/dev/null || fail "sweep --local-beta exited $?"
  $CHECK sweep-csv "$TMP/local.csv" 0,0.1 || fail "bad CSV"
  first=$(sed -n '2p' "$TMP/local.csv" | cut -d, -f6)
  awk -v a="$first" -v n="$naive" 'BEGIN { exit !(a * 10 <= n) }' \
    || fail "sweep --local-beta at beta 0: max e_iso $first is not 10x below the naive $naive"
  # run: "auto" in betas, local_beta in a constraint set (string and object forms)
  cat >"$TMP/job.json" <<JSON
{
  "format": "none",
  "beta_units": "raw",
  "betas": [0, "auto"],
  "meshes": ["cactus"],
  "constraints": [
    { "name": "top", "sel": "$BS/{mesh}.sel", "handles": ["$TOP"] },
    { "name": "toplocal", "sel": "$BS/{mesh}.sel", "handles": ["$TOP"],
      "local_beta": ["$TOP@0.2@0.03", { "region": ["ids:1"], "beta": 0.1 }] }
  ],
  "transforms": [ { "name": "side", "translate": [0.08, 0, 0] } ]
}
JSON
  "$HDEFORM" run "$TMP/job.json" -o "$TMP/out-job" >"$TMP/out" 2>"$TMP/progress" \
    || { cat "$TMP/progress" "$TMP/out" >&2; fail "run exited $?"; }
  cat "$TMP/progress" "$TMP/out"
  $CHECK summary "$TMP/out-job/summary.csv" 4 || fail "bad summary"
  grep -Eq '^\[2/4\] cactus top side β=auto … ok [0-9]+ ms \(picked β=0\.(1|15|2|25)\)' "$TMP/progress" \
    || fail "run: no 'picked' β in the auto item's progress line"
  grep -Eq '^cactus +top +side +auto=0\.(1|15|2|25) ' "$TMP/out" || fail "run table: no auto=PICK"
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
  expect_fail "--beta not a number" "hdeform: --beta \\(a number or 'auto'\\): 'x' is not a number" -- \
    "$HDEFORM" deform cactus --sel "$BS/cactus.sel" --beta x
  expect_fail "--local-beta without @" "hdeform: --local-beta 'ids:1': expected SEL@BETA or SEL@BETA@RADIUS" -- \
    "$HDEFORM" deform cactus --sel "$BS/cactus.sel" --local-beta ids:1
  expect_fail "--local-beta bad beta" "hdeform: --local-beta 'ids:1@x': BETA: 'x' is not a number" -- \
    "$HDEFORM" deform cactus --sel "$BS/cactus.sel" --local-beta 'ids:1@x'
  expect_fail "--local-beta beta out of range" "hdeform: --local-beta 'ids:1@1.5@0.1': beta 1\\.5 is outside \\[0, 1\\)" -- \
    "$HDEFORM" sweep cactus --sel "$BS/cactus.sel" --betas 0 --local-beta 'ids:1@1.5@0.1'
  expect_fail "--local-beta bad selector" "hdeform: --local-beta 'sphere:0,0,1': expected 4" -- \
    "$HDEFORM" deform cactus --sel "$BS/cactus.sel" --local-beta 'sphere:0,0,1@0.3'
  expect_fail "--local-beta negative radius" "hdeform: --local-beta 'ids:1@0.3@-1': radius must be >= 0" -- \
    "$HDEFORM" deform cactus --sel "$BS/cactus.sel" --local-beta 'ids:1@0.3@-1'
  expect_fail "--local-beta empty region" 'hdeform: SetBeta: INVALID_ARGUMENT: beta.local\[0\]:? region selects no vertices' -- \
    "$HDEFORM" deform cactus --sel "$BS/cactus.sel" --local-beta 'sphere:100,0,0,0.01@0.3'
  printf '{"meshes": ["cactus"], "betas": ["autp"], "constraints": [{"handles": ["ids:1"]}]}\n' >bad3.json
  expect_fail "job betas" '^bad3\.json: betas\[0\]: expected a number or "auto"' -- "$HDEFORM" run bad3.json
  printf '{"meshes": ["cactus"], "constraints": [{"handles": ["ids:1"], "local_beta": ["ids:2@0.5@x"]}]}\n' >bad4.json
  expect_fail "job local_beta" "^bad4\.json: constraints\[0\]\.local_beta\[0\] 'ids:2@0\.5@x': BETA: 'x' is not a number" -- \
    "$HDEFORM" run bad4.json
  expect_fail "sweep beta list" 'hdeform: --betas: ' -- \
    "$HDEFORM" sweep cactus --sel "$BS/cactus.sel" --betas 0,x
  expect_fail "no server" 'hdeform: cannot connect to hdeform-server at 127\.0\.0\.1:1$' -- \
    "$HDEFORM" --server 127.0.0.1:1 --timeout 5 deform cactus --sel "$BS/cactus.sel"
  ;;
remote)
  # The warm-cores window: a bad value refused at start, the default named in the log.
  "$SERVER_BIN" --warm-cores-ms 20000 >"$TMP/out" 2>"$TMP/err" && fail "--warm-cores-ms 20000 accepted"
  grep -q -- '--warm-cores-ms: Value 20000 not in range -1 to 10000' "$TMP/err" ||
    fail "--warm-cores-ms 20000: '$(cat "$TMP/err")'"
  # The budget of threads beside the workers: the same, and its limit named in the log.
  "$SERVER_BIN" --beside-threads 300 >"$TMP/out" 2>"$TMP/err" && fail "--beside-threads 300 accepted"
  grep -q -- '--beside-threads: Value 300 not in range -1 to 256' "$TMP/err" ||
    fail "--beside-threads 300: '$(cat "$TMP/err")'"
  start_server
  echo "server at $ADDR"
  grep -Eq "at most [1-9][0-9]* threads beside the workers" "$TMP/server.out" ||
    fail "no beside-threads line in the server log: $(head -5 "$TMP/server.out")"
  grep -Eq 'cores kept warm for 250 ms after each drag move|cores not kept warm between drag moves \(the cgroup has a CPU quota\)' \
    "$TMP/server.out" || fail "no warm-cores line in the server log: $(head -5 "$TMP/server.out")"
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
  # --beta auto and --local-beta over TCP
  "$HDEFORM" --server "$ADDR" deform cactus "${SINGLE[@]}" --beta auto --beta-units raw \
    --local-beta "$TOP@0.3@0.03" >"$TMP/auto" || fail "remote deform --beta auto exited $?"
  grep -Eq '^automatic beta: picked 0\.(1|15|2|25) \(raw units\)$' "$TMP/auto" \
    || { cat "$TMP/auto" >&2; fail "remote deform --beta auto: no pick in [0.1, 0.25]"; }

  # watch: keep a session, watch it, move its handle from another client
  "$HDEFORM" --server "$ADDR" deform cactus --sel "$BS/cactus.sel" --def "$BS/cactus.def" --keep \
    >"$TMP/kept" || fail "deform --keep exited $?"
  keep_session "$TMP/kept"
  echo "kept $SESSION"
  "$HDEFORM" --server "$ADDR" --token "$VIEW" watch "$SESSION" --for 60 >"$TMP/watch" 2>"$TMP/watch.err" &
  WATCH_PID=$!
  # A second watcher takes its frames meshopt-compressed (watch decodes and checks each one).
  "$HDEFORM" --server "$ADDR" --token "$VIEW" watch "$SESSION" --encoding meshopt --for 60 \
    >"$TMP/watch-meshopt" 2>"$TMP/watch-meshopt.err" &
  WATCH_MESHOPT_PID=$!
  # A third as meshopt-delta: its first frame is a key frame (delta=0).
  "$HDEFORM" --server "$ADDR" --token "$VIEW" watch "$SESSION" --encoding meshopt-delta --for 60 \
    >"$TMP/watch-delta" 2>"$TMP/watch-delta.err" &
  WATCH_DELTA_PID=$!
  sleep 1
  "$HDEFORM" --server "$ADDR" --token "$EDIT" deform --session "$SESSION" --beta 0.1 --translate 0,0.01,0 \
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
  grep -Eq ' encoding=float32 bytes=[0-9]+$' "$TMP/watch" || fail "watch: no float32 frame"
  # On joining: the state once, then who is here; the move shows as a history step.
  [ "$(sed -n 2p "$TMP/watch" | cut -d' ' -f1)" = presence ] \
    || fail "watch: the second line is not the presence line (the join state twice?)"
  grep -Eq '^step id=[0-9]+ kind=move version=[0-9]+ author=[^ ]+ summary="' "$TMP/watch" \
    || fail "watch printed no step line for the move"
  for _ in $(seq 1 100); do
    grep -q '^frame seq=1 ' "$TMP/watch-meshopt" && break
    kill -0 "$WATCH_MESHOPT_PID" 2>/dev/null || break  # exited: a frame did not decode
    sleep 0.1
  done
  kill "$WATCH_MESHOPT_PID" 2>/dev/null; wait "$WATCH_MESHOPT_PID" 2>/dev/null
  cat "$TMP/watch-meshopt" "$TMP/watch-meshopt.err"
  grep -Eq '^frame seq=1 .* encoding=meshopt bytes=[0-9]+$' "$TMP/watch-meshopt" \
    || fail "watch --encoding meshopt printed no meshopt frame"
  for _ in $(seq 1 100); do
    grep -q '^frame seq=1 ' "$TMP/watch-delta" && break
    kill -0 "$WATCH_DELTA_PID" 2>/dev/null || break
    sleep 0.1
  done
  kill "$WATCH_DELTA_PID" 2>/dev/null; wait "$WATCH_DELTA_PID" 2>/dev/null
  cat "$TMP/watch-delta" "$TMP/watch-delta.err"
  grep -Eq '^frame seq=1 .* encoding=meshopt-delta bytes=[0-9]+ delta=0$' "$TMP/watch-delta" \
    || fail "watch --encoding meshopt-delta printed no key frame"
  kill "$WATCH_PID" 2>/dev/null; wait "$WATCH_PID" 2>/dev/null; WATCH_PID=""
  expect_fail "watch unknown session" 'hdeform: WatchSession: PERMISSION_DENIED: .*opens no session of that name' -- \
    "$HDEFORM" --server "$ADDR" --token "$VIEW" watch sessions/doesnotexist --for 10
  ;;
tokens)
  start_server
  # deform --keep prints the name and both tokens on stdout; sweep --keep on stderr (its
  # stdout may be the CSV).
  "$HDEFORM" --server "$ADDR" deform cactus --sel "$BS/cactus.sel" --def "$BS/cactus.def" --keep \
    >"$TMP/kept" || fail "deform --keep exited $?"
  cat "$TMP/kept"
  keep_session "$TMP/kept"
  "$HDEFORM" --server "$ADDR" sweep cactus --sel "$BS/cactus.sel" --betas 0 --csv - --keep \
    >"$TMP/sweep.csv" 2>"$TMP/sweep.err" || fail "sweep --keep exited $?"
  grep -q '^edit token: ' "$TMP/sweep.err" && grep -q '^view token: ' "$TMP/sweep.err" \
    || fail "sweep --keep printed no tokens on stderr"
  grep -q 'token' "$TMP/sweep.csv" && fail "sweep --keep printed a token into the CSV"
  # The edit token, by --token and by HDEFORM_TOKEN, opens the session in another run.
  "$HDEFORM" --server "$ADDR" --token "$EDIT" deform --session "$SESSION" --translate 0,0.01,0 \
    >"$TMP/out" 2>"$TMP/err" || { cat "$TMP/err" >&2; fail "--token EDIT: exited $?"; }
  check_measures "$TMP/out"
  HDEFORM_TOKEN=$EDIT "$HDEFORM" --server "$ADDR" deform --session "$SESSION" --rotate z,5 \
    -o "$TMP/env.glb" >"$TMP/out" || fail "HDEFORM_TOKEN=EDIT: exited $?"
  $CHECK glb "$TMP/env.glb" 5261 || fail "bad GLB"
  "$HDEFORM" --server "$ADDR" deform --session "$SESSION" --translate 0,0.02,0 --token "$EDIT" \
    --log-level debug >/dev/null 2>"$TMP/debug.err" || fail "--token after the command: exited $?"
  # The view token reads (watch) but does not edit; no token, a wrong one: clear errors.
  "$HDEFORM" --server "$ADDR" --token "$VIEW" watch "$SESSION" --count 1 >"$TMP/watch" \
    || fail "watch with the view token exited $?"
  grep -q "^state $SESSION " "$TMP/watch" || fail "watch with the view token: no state line"
  expect_fail "view token for an edit" \
    "hdeform: UpdateHandles: PERMISSION_DENIED: .*edit token.*view token" -- \
    "$HDEFORM" --server "$ADDR" --token "$VIEW" deform --session "$SESSION" --translate 0,0.01,0
  expect_fail "view token for an edit (environment)" "hdeform: SetBeta: PERMISSION_DENIED: " -- \
    env HDEFORM_TOKEN="$VIEW" "$HDEFORM" --server "$ADDR" deform --session "$SESSION" --beta 0.2
  expect_fail "no token" "hdeform: GetSession: UNAUTHENTICATED: .*authorization: Bearer" -- \
    "$HDEFORM" --server "$ADDR" deform --session "$SESSION" --translate 0,0.01,0
  expect_fail "no token (watch)" "hdeform: WatchSession: UNAUTHENTICATED: " -- \
    "$HDEFORM" --server "$ADDR" watch "$SESSION" --for 10
  expect_fail "wrong token" "hdeform: GetSession: PERMISSION_DENIED: .*opens no session of that name" -- \
    "$HDEFORM" --server "$ADDR" --token 0123456789abcdef0123456789abcdef deform --session "$SESSION" --rotate x,1
  expect_fail "a token with a space" "hdeform: --token: not a token" -- \
    "$HDEFORM" --server "$ADDR" --token "Bearer $EDIT" deform --session "$SESSION" --rotate x,1
  # list: the sessions the token opens; none without one.
  "$HDEFORM" --server "$ADDR" --token "$VIEW" list >"$TMP/list" || fail "list exited $?"
  cat "$TMP/list"
  [ "$(grep -c "^$SESSION mesh=cactus vertices=5261 " "$TMP/list")" -eq 1 ] || fail "list: not the session"
  [ "$(wc -l <"$TMP/list")" -eq 1 ] || fail "list: sessions of other tokens listed"
  "$HDEFORM" --server "$ADDR" list >"$TMP/list0" || fail "list without a token exited $?"
  [ ! -s "$TMP/list0" ] || fail "list without a token listed sessions"
  # A token is never printed except by --keep: not in logs, not in errors.
  for f in "$TMP/debug.err" "$TMP/err" "$TMP/watch"; do
    if grep -qF -- "$EDIT" "$f" || grep -qF -- "$VIEW" "$f"; then fail "a token was printed in $f"; fi
  done
  # In-process runs use the tokens of the sessions they create (every deform above did).
  "$HDEFORM" deform cactus --sel "$BS/cactus.sel" --def "$BS/cactus.def" --keep >"$TMP/inproc" \
    || fail "in-process deform exited $?"
  grep -q '^session \|token' "$TMP/inproc" && fail "in-process --keep printed a session (it ends with the run)"
  ;;
tls)
  make_pki "$TMP/pki"
  P=$TMP/pki
  start_server --tls-cert "$P/server.pem" --tls-key "$P/server.key"
  "$HDEFORM" --server "$ADDR" --tls-ca "$P/ca.pem" deform cactus --sel "$BS/cactus.sel" \
    --def "$BS/cactus.def" -o "$TMP/tls.glb" >"$TMP/out" || fail "deform --tls-ca exited $?"
  check_measures "$TMP/out"
  $CHECK glb "$TMP/tls.glb" 5261 || fail "bad GLB over TLS"
  HDEFORM_TLS_CA=$P/ca.pem "$HDEFORM" --server "localhost:$SERVER_PORT" sweep cactus --sel "$BS/cactus.sel" \
    --betas 0,0.1 --csv - >"$TMP/tls.csv" || fail "HDEFORM_TLS_CA + localhost: exited $?"
  $CHECK sweep-csv "$TMP/tls.csv" 0,0.1 || fail "bad CSV over TLS"
  # kept over TLS, then used with its token over TLS
  "$HDEFORM" --server "$ADDR" --tls-ca "$P/ca.pem" deform cactus --sel "$BS/cactus.sel" --keep \
    >"$TMP/kept" || fail "deform --keep over TLS exited $?"
  keep_session "$TMP/kept"
  "$HDEFORM" --server "$ADDR" --tls-ca "$P/ca.pem" --token "$EDIT" deform --session "$SESSION" \
    --rotate x,10 >/dev/null || fail "deform --session over TLS exited $?"
  expect_fail "plain text to a TLS server" \
    "hdeform: cannot connect to hdeform-server at $ADDR \\(.*pass --tls-ca\\)" -- \
    "$HDEFORM" --server "$ADDR" --timeout 5 deform cactus --sel "$BS/cactus.sel"
  expect_fail "a CA that did not sign the server's certificate" \
    "hdeform: cannot connect to hdeform-server at $ADDR over TLS \\(the TLS handshake failed" -- \
    "$HDEFORM" --server "$ADDR" --tls-ca "$P/other-ca.pem" deform cactus --sel "$BS/cactus.sel"
  expect_fail "--tls-cert without --tls-key" "hdeform: .*--tls-cert requires --tls-key" -- \
    "$HDEFORM" --server "$ADDR" --tls-ca "$P/ca.pem" --tls-cert "$P/client.pem" deform cactus --sel "$BS/cactus.sel"
  expect_fail "--tls-ca not a file" "hdeform: .*--tls-ca.*$TMP/nope.pem" -- \
    "$HDEFORM" --server "$ADDR" --tls-ca "$TMP/nope.pem" deform cactus --sel "$BS/cactus.sel"
  # mutual TLS: a server that requires client certificates signed by the CA
  kill "$SERVER_PID" 2>/dev/null; wait "$SERVER_PID" 2>/dev/null; SERVER_PID=""; SERVER_PORT=""
  start_server --tls-cert "$P/server.pem" --tls-key "$P/server.key" --tls-client-ca "$P/ca.pem"
  "$HDEFORM" --server "$ADDR" --tls-ca "$P/ca.pem" --tls-cert "$P/client.pem" --tls-key "$P/client.key" \
    deform cactus --sel "$BS/cactus.sel" --def "$BS/cactus.def" >"$TMP/out" || fail "mutual TLS: exited $?"
  check_measures "$TMP/out"
  HDEFORM_TLS_CA=$P/ca.pem HDEFORM_TLS_CLIENT_CERT=$P/client.pem HDEFORM_TLS_CLIENT_KEY=$P/client.key \
    "$HDEFORM" --server "$ADDR" deform cactus --sel "$BS/cactus.sel" >/dev/null \
    || fail "mutual TLS from the environment: exited $?"
  expect_fail "mutual TLS without a client certificate" \
    "hdeform: (cannot connect to hdeform-server at $ADDR over TLS|CreateSession: UNAVAILABLE: )" -- \
    "$HDEFORM" --server "$ADDR" --tls-ca "$P/ca.pem" deform cactus --sel "$BS/cactus.sel"
  ;;
restart)
  # Durable state: a kept session survives kill -9 of its server. The watcher's stream and an
  # in-flight Sweep are cut; each is retried once, when the server is back on the same port.
  STATE=$TMP/state
  start_server --state-dir "$STATE"
  "$HDEFORM" --server "$ADDR" deform cactus --sel "$BS/cactus.sel" --def "$BS/cactus.def" --keep \
    >"$TMP/kept" || fail "deform --keep exited $?"
  keep_session "$TMP/kept"
  "$HDEFORM" --server "$ADDR" --token "$VIEW" --log-level info watch "$SESSION" --for 120 \
    >"$TMP/watch" 2>"$TMP/watch.err" &
  WATCH_PID=$!
  wait_for "^state $SESSION " "$TMP/watch"
  v1=$(sed -n "s|^state $SESSION version=\([0-9]*\) .*|\1|p" "$TMP/watch" | head -1)
  # 1. kill -9 with no call in flight; restart; a later run finds the session restored
  sleep 0.3  # the opening stream's state lines (its state, then the observer count)
  n0=$(grep -c "^state $SESSION " "$TMP/watch")
  kill -9 "$SERVER_PID"; wait "$SERVER_PID" 2>/dev/null; SERVER_PID=""
  start_server --state-dir "$STATE"
  echo "restarted on $ADDR"
  # The watcher reopens its stream (one retry after 200 ms): a new state line. The move below
  # must come after it, or its frame goes out while nobody watches.
  for _ in $(seq 1 100); do
    [ "$(grep -c "^state $SESSION " "$TMP/watch")" -gt "$n0" ] && break
    sleep 0.1
  done
  "$HDEFORM" --server "$ADDR" --token "$EDIT" deform --session "$SESSION" --translate 0,0.01,0 \
    >"$TMP/out" 2>"$TMP/err" || { cat "$TMP/err" "$TMP/server.err" >&2; fail "deform --session after the restart: exited $?"; }
  cat "$TMP/out"
  grep -q '^cactus: 5261 vertices, 10518 triangles, 446 fixed, 1 handle(s)' "$TMP/out" \
    || fail "the restored session lost its constraints"
  check_measures "$TMP/out"
  # the watcher reopened its stream: a second state line (same version as before the kill,
  # or later), then the new frame
  wait_for "^frame seq=1 " "$TMP/watch" || true; cat "$TMP/watch.err" >&2; cat "$TMP/watch" >&2
  [ "$(grep -c "^state $SESSION " "$TMP/watch")" -gt "$n0" ] || { cat "$TMP/watch" >&2; fail "watch did not reopen"; }
  grep -q 'WatchSession: the server is unavailable; retrying once' "$TMP/watch.err" \
    || { cat "$TMP/watch.err" >&2; fail "watch: no retry logged"; }
  v2=$(sed -n "s|^state $SESSION version=\([0-9]*\) .*|\1|p" "$TMP/watch" | sed -n 2p)
  [ "$v2" -ge "$v1" ] || fail "the restored session is at version $v2, before the kill at $v1"
  kill -0 "$WATCH_PID" 2>/dev/null || fail "watch ended after the restart"
  # 2. kill -9 while a Sweep runs (64 β, each a factorization: seconds); the CLI retries it
  # once the server is back and prints every row.
  betas=$(seq -s, 0.01 0.01 0.64)
  "$HDEFORM" --server "$ADDR" --token "$EDIT" --log-level debug sweep --session "$SESSION" \
    --betas "$betas" --csv - >"$TMP/sweep.csv" 2>"$TMP/sweep.err" &
  SWEEP_PID=$!
  # The kill must land mid-sweep: 64 transient factorizations of the cactus take ≈ 0.5 s on
  # a quiet machine. Not before the CLI connected: a refused first connection fails at once
  # by design (a loaded machine can take longer than a fixed pause to start the CLI).
  wait_for "connected to " "$TMP/sweep.err"
  kill -0 "$SWEEP_PID" 2>/dev/null || { cat "$TMP/sweep.err" >&2; fail "the sweep ended before the kill (too fast for this test)"; }
  kill -9 "$SERVER_PID"; wait "$SERVER_PID" 2>/dev/null; SERVER_PID=""
  sleep 0.5
  start_server --state-dir "$STATE"
  wait "$SWEEP_PID" || { cat "$TMP/sweep.err" >&2; fail "the sweep across a restart exited $?"; }
  SWEEP_PID=""
  grep -q 'Sweep: the server is unavailable; retrying once' "$TMP/sweep.err" \
    || { cat "$TMP/sweep.err" >&2; fail "sweep: no retry logged"; }
  $CHECK sweep-csv "$TMP/sweep.csv" "$betas" || fail "bad CSV after the retry"
  kill "$WATCH_PID" 2>/dev/null; wait "$WATCH_PID" 2>/dev/null; WATCH_PID=""
  # the tokens were never printed by the CLI's logs
  if grep -qF -- "$EDIT" "$TMP/watch.err" "$TMP/sweep.err" "$TMP/err"; then fail "a token in a log"; fi
  ;;
sessions)
  start_server
  cd "$TMP" || exit 1
  R=(--server "$ADDR")
  "$HDEFORM" "${R[@]}" deform cactus --sel "$BS/cactus.sel" --keep >kept || fail "deform --keep exited $?"
  keep_session kept
  # Move the kept session away from its rest pose.
  MOVE=(--translate 0,0.05,0.02 --rotate x,25)
  "$HDEFORM" "${R[@]}" --token "$EDIT" deform --session "$SESSION" "${MOVE[@]}" >/dev/null \
    || fail "deform --session exited $?"
  # sweep --session without transform options: at the session's current (moved) pose. It
  # equals a sweep with the same transforms given explicitly, and differs from the rest pose.
  "$HDEFORM" "${R[@]}" --token "$EDIT" sweep --session "$SESSION" --betas 0,0.1 --csv current.csv \
    >/dev/null 2>err || { cat err >&2; fail "sweep --session exited $?"; }
  grep -qx "wrote current.csv ([0-9]* bytes)" err || fail "sweep: no 'wrote current.csv'"
  "$HDEFORM" "${R[@]}" --token "$EDIT" sweep --session "$SESSION" --betas 0,0.1 "${MOVE[@]}" \
    --csv explicit.csv >/dev/null 2>&1 || fail "sweep --session with transforms exited $?"
  "$HDEFORM" "${R[@]}" --token "$EDIT" sweep --session "$SESSION" --betas 0,0.1 --translate 0,0,0 \
    --csv rest.csv >/dev/null 2>&1 || fail "sweep --session at identity exited $?"
  cat current.csv rest.csv
  $CHECK sweep-csv current.csv 0,0.1 || fail "bad CSV"
  diff current.csv explicit.csv >/dev/null || fail "sweep at the current pose != sweep with its transforms given"
  [ "$(sed -n 2p current.csv)" != "$(sed -n 2p rest.csv)" ] || fail "sweep --session swept at the rest pose"
  # the sweeps left the session's pose as it was (transform options replace, for the sweep only)
  "$HDEFORM" "${R[@]}" --token "$EDIT" sweep --session "$SESSION" --betas 0,0.1 --csv again.csv \
    >/dev/null 2>&1 || fail "sweep exited $?"
  diff current.csv again.csv >/dev/null || fail "a sweep with transform options moved the session"

  # sessions list / get (the view token is enough), text and JSON
  "$HDEFORM" "${R[@]}" --token "$VIEW" sessions list >list || fail "sessions list exited $?"
  cat list
  head -1 list | grep -Eq '^name +mesh +vertices +version +observers +updated$' || fail "sessions list header"
  [ "$(wc -l <list)" -eq 2 ] || fail "sessions list: expected one row"
  grep -Eq "^$SESSION +cactus +5261 +[0-9]+ +0 +20[0-9]{2}-[0-9]{2}-[0-9]{2}T[0-9:]{8}Z$" list \
    || fail "sessions list row"
  "$HDEFORM" "${R[@]}" --token "$VIEW" sessions list --json >list.json || fail "sessions list --json exited $?"
  "$PY" - "$SESSION" <<'PY' || fail "sessions list --json"
import json, sys
a = json.load(open("list.json"))
assert len(a) == 1 and a[0]["name"] == sys.argv[1], a
assert a[0]["vertices"] == 5261 and a[0]["handles"] == 1 and a[0]["mesh"] == "cactus", a
assert "edit_token" not in json.dumps(a) and len(a[0]["transforms"]) == 1, a
PY
  "$HDEFORM" "${R[@]}" --token "$VIEW" sessions list --json | grep -qF -- "$EDIT" && fail "a token in list --json"
  "$HDEFORM" "${R[@]}" --token "$VIEW" sessions get "$SESSION" >get || fail "sessions get exited $?"
  cat get
  grep -qx "name: *$SESSION" get || fail "sessions get: name"
  grep -qx "constraints: 446 fixed, 1 handle(s)" get || fail "sessions get: constraints"
  # the move (--translate 0,0.05,0.02 --rotate x,25) as the command line takes it: no JSON,
  # no 17-digit noise
  grep -Eq '^handle 0: +translate 0 0.05 0.02, rotate 25° about 1 0 0, scale 1, pivot centroid$' get \
    || fail "sessions get: the handle's transform"
  "$HDEFORM" "${R[@]}" --token "$VIEW" sessions get "${SESSION#sessions/}" --json >get.json \
    || fail "sessions get ID --json exited $?"
  "$PY" -c 'import json,sys; s=json.load(open("get.json")); assert s["name"]==sys.argv[1] and s["beta"]["units"]=="area" and s["triangles"]==10518, s' \
    "$SESSION" || fail "sessions get --json"

  # export: JSON and binary, from the moved session; --include-mesh of an upload
  "$HDEFORM" "${R[@]}" --token "$EDIT" sessions export "$SESSION" -o snap.json >out \
    || fail "sessions export (JSON) exited $?"
  grep -qx "wrote snap.json ([0-9]* bytes, JSON Snapshot)" out || { cat out >&2; fail "export: wrote line"; }
  "$PY" -c 'import json; s=json.load(open("snap.json")); assert s["library_mesh"]=="cactus" and len(s["transforms"])==1 and "constraints" in s, s' \
    || fail "snap.json is not the session's snapshot"
  "$HDEFORM" "${R[@]}" --token "$EDIT" sessions export "$SESSION" -o snap.pb >out \
    || fail "sessions export (binary) exited $?"
  grep -qx "wrote snap.pb ([0-9]* bytes, binary Snapshot)" out || fail "export: binary wrote line"
  # delete: gone afterwards
  "$HDEFORM" "${R[@]}" --token "$EDIT" sessions delete "$SESSION" >out || fail "sessions delete exited $?"
  grep -qx "deleted $SESSION" out || fail "delete: no 'deleted' line"
  expect_fail "get a deleted session" "hdeform: GetSession: PERMISSION_DENIED: .*opens no session of that name" -- \
    "$HDEFORM" "${R[@]}" --token "$EDIT" sessions get "$SESSION"
  # import (JSON, then binary): new sessions with new tokens, at the exported pose
  for f in snap.json snap.pb; do
    "$HDEFORM" "${R[@]}" sessions import "$f" >imported || fail "sessions import $f exited $?"
    cat imported
    OLD_EDIT=$EDIT
    keep_session imported
    [ "$EDIT" != "$OLD_EDIT" ] || fail "import: the old token again"
    "$HDEFORM" "${R[@]}" --token "$EDIT" sweep --session "$SESSION" --betas 0,0.1 --csv imported.csv \
      >/dev/null 2>&1 || fail "sweep of the imported session exited $?"
    diff current.csv imported.csv >/dev/null || fail "the session imported from $f is not at the exported pose"
  done
  "$HDEFORM" "${R[@]}" sessions import snap.pb --session-id chosen-id-1 >imported \
    || fail "import --session-id exited $?"
  grep -qx "session sessions/chosen-id-1" imported || fail "import --session-id: name"
  # --include-mesh: an uploaded mesh travels in the snapshot
  "$HDEFORM" "${R[@]}" deform "$BS/bar.off" --sel "$BS/bar.sel" --keep >kept2 || fail "upload --keep exited $?"
  keep_session kept2
  "$HDEFORM" "${R[@]}" --token "$EDIT" sessions export "$SESSION" -o bar.json --include-mesh >out \
    || fail "export --include-mesh exited $?"
  grep -q ", with the mesh)$" out || fail "export --include-mesh: no mesh"
  "$HDEFORM" "${R[@]}" --token "$EDIT" sessions export "$SESSION" -o bar-hash.pb >/dev/null \
    || fail "export exited $?"
  "$HDEFORM" "${R[@]}" --token "$EDIT" sessions delete "$SESSION" >/dev/null || fail "delete exited $?"
  "$HDEFORM" "${R[@]}" sessions import bar.json >imported || fail "import --include-mesh snapshot exited $?"
  grep -q "^session sessions/" imported || fail "import of bar.json"

  # meshes, remote and in-process
  "$HDEFORM" "${R[@]}" meshes >meshes || fail "meshes exited $?"
  cat meshes
  grep -Eq '^cactus +botsch-sorkine/cactus\.off +yes$' meshes || fail "meshes: cactus row"
  grep -Eq '^bunny +models/bunny\.off +no$' meshes || fail "meshes: bunny row"
  "$HDEFORM" meshes --json >meshes.json || fail "meshes --json (in-process) exited $?"
  "$PY" -c 'import json; a=json.load(open("meshes.json")); assert {"name":"cactus","path":"botsch-sorkine/cactus.off","benchmark":True} in a, a' \
    || fail "meshes --json"

  # bad inputs: one stderr line each, exit 1
  # an unknown id answers like a session the token does not open (ids cannot be probed)
  expect_fail "unknown session" "hdeform: GetSession: PERMISSION_DENIED: .*opens no session of that name" -- \
    "$HDEFORM" "${R[@]}" --token "$VIEW" sessions get sessions/doesnotexist
  expect_fail "delete an unknown session" "hdeform: DeleteSession: PERMISSION_DENIED: .*opens no session" -- \
    "$HDEFORM" "${R[@]}" --token "$VIEW" sessions delete sessions/doesnotexist
  "$HDEFORM" "${R[@]}" deform cactus --sel "$BS/cactus.sel" --keep >kept3 || fail "deform --keep exited $?"
  keep_session kept3
  expect_fail "get without a token" "hdeform: GetSession: UNAUTHENTICATED: " -- \
    "$HDEFORM" "${R[@]}" sessions get "$SESSION"
  expect_fail "delete without a token" "hdeform: DeleteSession: UNAUTHENTICATED: " -- \
    "$HDEFORM" "${R[@]}" sessions delete "$SESSION"
  expect_fail "export without a token" "hdeform: ExportSession: UNAUTHENTICATED: " -- \
    "$HDEFORM" "${R[@]}" sessions export "$SESSION" -o x.json
  expect_fail "export with the view token" "hdeform: ExportSession: PERMISSION_DENIED: " -- \
    "$HDEFORM" "${R[@]}" --token "$VIEW" sessions export "$SESSION" -o x.json
  expect_fail "delete with the view token" "hdeform: DeleteSession: PERMISSION_DENIED: " -- \
    "$HDEFORM" "${R[@]}" --token "$VIEW" sessions delete "$SESSION"
  [ ! -e x.json ] || fail "a failed export wrote x.json"
  printf 'hello, not a snapshot\n' >bad.pb
  expect_fail "bad snapshot (binary)" "hdeform: bad\.pb: not a session snapshot \(neither a binary Snapshot nor JSON" -- \
    "$HDEFORM" "${R[@]}" sessions import bad.pb
  printf '{"library_mesh": "cactus", "bogus": 1}\n' >bad.json
  expect_fail "bad snapshot (JSON)" "hdeform: bad\.json: not a session snapshot \(JSON: .*bogus" -- \
    "$HDEFORM" "${R[@]}" sessions import bad.json
  : >empty.pb
  expect_fail "empty snapshot" "hdeform: empty\.pb: not a session snapshot \(it names no mesh\)" -- \
    "$HDEFORM" "${R[@]}" sessions import empty.pb
  expect_fail "missing snapshot file" "hdeform: .*nope\.json" -- "$HDEFORM" "${R[@]}" sessions import nope.json
  # a snapshot naming an upload by its hash alone opens it only with a live session's token
  expect_fail "hash-only snapshot without a token" "hdeform: ImportSession: [A-Z_]+: " -- \
    "$HDEFORM" "${R[@]}" sessions import bar-hash.pb
  expect_fail "sessions without --server" "hdeform: sessions list needs --server" -- \
    "$HDEFORM" sessions list
  expect_fail "sessions without a subcommand" "hdeform: " -- "$HDEFORM" "${R[@]}" sessions
  ;;
progress)
  # The status line (progress.h) is drawn only when stderr is a terminal.
  PLANE=(sweep plane --sel "$BS/plane.sel" --def "$BS/plane.def" --betas 0,0.1,0.25)
  "$HDEFORM" "${PLANE[@]}" --csv "$TMP/p.csv" >/dev/null 2>"$TMP/err" || fail "sweep exited $?"
  if grep -q "$(printf '\r')" "$TMP/err" || grep -q 'Sweep: ' "$TMP/err"; then
    cat -A "$TMP/err" >&2; fail "a status line although stderr is a file"
  fi
  grep -qx "wrote $TMP/p.csv ([0-9]* bytes)" "$TMP/err" || fail "no 'wrote' line"
  if command -v script >/dev/null; then
    # script(1) gives the command a terminal; no delay before the first draw (a quiet machine
    # sweeps the plane's 3 βs in well under the default 0.5 s).
    HDEFORM_PROGRESS_DELAY_MS=0 \
      script -qec "$(printf '%q ' "$HDEFORM" "${PLANE[@]}" --csv "$TMP/q.csv")" /dev/null \
      >"$TMP/tty" 2>&1 || { cat "$TMP/tty" >&2; fail "sweep on a terminal exited $?"; }
    grep -q 'hdeform: Sweep: 3 beta value(s), a factorization each … [0-9.]* s' "$TMP/tty" \
      || { cat -A "$TMP/tty" | head -20 >&2; fail "no status line on a terminal"; }
    grep -q "$(printf '\r\033\\[K')" "$TMP/tty" || fail "the status line is not erased"
  else
    echo "progress: no script(1); the terminal half is skipped"
  fi
  ;;
run-names)
  # Hostile names (path components, absolute paths, NUL and control characters, Windows
  # separators, leading dots and dashes, a very long name) write only inside -o.
  mkdir -p "$TMP/work/sub" && cd "$TMP/work/sub" || exit 1
  long=$(printf 'L%.0s' $(seq 1 300))
  cat >job.json <<JSON
{
  "name": "../../jobname",
  "format": "off",
  "meshes": [ { "name": "../../escaped", "library": "cactus" },
              { "name": "$TMP/absolute", "library": "cactus" } ],
  "constraints": [
    { "name": "/etc/cron.d/x", "fixed": "half:0,0,-1,-0.15", "handles": ["half:0,0,1,0.8"] }
  ],
  "transforms": [
    { "name": "..", "translate": [0, 0.01, 0] },
    { "name": "a/b\\\\c\u0000d\u001b[31m", "rotate": "x,10" },
    { "name": ".hidden", "scale": 1.1 },
    { "name": "-rf", "translate": "0,0,0.01" },
    { "name": "$long", "translate": [0.01, 0, 0] }
  ]
}
JSON
  find "$TMP" -mindepth 1 | sort >"$TMP/before"
  "$HDEFORM" run job.json -o "$TMP/jobout" >"$TMP/stdout" 2>"$TMP/progress"
  rc=$?
  cat "$TMP/progress"
  [ $rc -eq 0 ] || fail "run with hostile names exited $rc"
  # names are shown with control characters escaped
  grep -q 'a/b\\c\\x00d\\x1b\[31m' "$TMP/progress" || fail "control characters not escaped"
  if grep -q "$(printf '\033')" "$TMP/progress" "$TMP/stdout" "$TMP/jobout/summary.csv"; then
    fail "an escape character was printed"
  fi
  # Only the output folder and its files are new, each a plain name.
  find "$TMP" -mindepth 1 | sort >"$TMP/after"
  new=$(comm -13 "$TMP/before" "$TMP/after" | grep -v "^$TMP/\(jobout\|stdout\|progress\|before\|after\)$" \
        | grep -v "^$TMP/jobout/[A-Za-z0-9_][A-Za-z0-9._-]*$")
  [ -z "$new" ] || fail "files outside -o or with unsafe names: $new"
  [ "$(find "$TMP/jobout" -type f -name '*.off' | wc -l)" -eq 10 ] || { ls -la "$TMP/jobout" >&2; fail "expected 10 OFF files"; }
  [ -f "$TMP/jobout/summary.csv" ] || fail "no summary.csv"
  [ ! -e "$TMP/absolute" ] && [ ! -e "$TMP/escaped" ] && [ ! -e "$TMP/work/escaped" ] || fail "escaped"
  ls "$TMP/jobout" | awk 'length($0) > 255 { exit 1 }' || fail "a file name longer than 255"
  ls "$TMP/jobout" | grep -qxF '___.._escaped-_etc_cron.d_x-__-b0.off' || { ls "$TMP/jobout" >&2; fail "sanitized name"; }
  # names that collide once sanitized, summaries and output folders that leave -o
  printf '{"meshes": ["cactus"], "constraints": [{"name": "a/b", "handles": ["ids:1"]}, {"name": "a_b", "handles": ["ids:2"]}]}\n' >c.json
  expect_fail "colliding names" "^c\.json: constraints\[1\]: name 'a_b' and constraints\[0\] name 'a/b' give the same output file name part 'a_b'" -- \
    "$HDEFORM" run c.json -o "$TMP/jobout2"
  printf '{"summary": "../../s.csv", "meshes": ["cactus"], "constraints": [{"handles": ["ids:1"]}]}\n' >s.json
  expect_fail "summary outside -o" "^s\.json: summary: '\.\./\.\./s\.csv' is not a plain file name" -- \
    "$HDEFORM" run s.json -o "$TMP/jobout2"
  printf '{"output_dir": "%s/elsewhere", "meshes": ["cactus"], "constraints": [{"handles": ["ids:1"]}]}\n' "$TMP" >o.json
  expect_fail "absolute output_dir" "^o\.json: output_dir: '.*/elsewhere' is absolute" -- "$HDEFORM" run o.json
  [ ! -e "$TMP/jobout2" ] && [ ! -e "$TMP/elsewhere" ] || fail "a rejected job created its output folder"
  ;;
non-finite)
  cd "$TMP" || exit 1
  # Command line and job: numbers that are not finite are rejected before any call.
  expect_fail "--translate overflow" "hdeform: transform translate: '1e400' is not a finite number" -- \
    "$HDEFORM" deform cactus --sel "$BS/cactus.sel" --translate 1e400,0,0 -o x.glb
  expect_fail "--scale inf" "hdeform: transform scale: 'inf' is not a finite number" -- \
    "$HDEFORM" deform cactus --sel "$BS/cactus.sel" --scale inf -o x.glb
  printf '{"meshes": ["cactus"], "constraints": [{"handles": ["ids:1"]}], "transforms": [{"translate": [1e400, 0, 0]}]}\n' >j1.json
  expect_fail "job number overflow" "^j1\.json: number overflow parsing '1e400'" -- "$HDEFORM" run j1.json -o out1
  printf '{"meshes": ["cactus"], "constraints": [{"handles": ["ids:1"]}], "transforms": [{"scale": "nan"}]}\n' >j2.json
  expect_fail "job scale nan" "^j2\.json: transforms\[0\] scale: 'nan' is not a finite number" -- "$HDEFORM" run j2.json -o out2
  # Finite but huge: the result must not be written with NaN/Inf coordinates (the server
  # rejects the transform, or the CLI finds non-finite positions); exit non-zero.
  for fmt in glb obj; do
    "$HDEFORM" deform cactus --sel "$BS/cactus.sel" --translate 1e300,0,0 -o "huge.$fmt" \
      >"$TMP/out" 2>"$TMP/err" && fail "deform --translate 1e300 exited 0"
    cat "$TMP/err"
    [ "$(wc -l <"$TMP/err")" -eq 1 ] || fail "deform --translate 1e300: expected one stderr line"
    grep -Eq 'non-finite|INVALID_ARGUMENT' "$TMP/err" || fail "deform --translate 1e300: unclear message"
    [ ! -e "huge.$fmt" ] || fail "deform --translate 1e300 wrote huge.$fmt"
  done
  "$HDEFORM" deform cactus --sel "$BS/cactus.sel" --scale 1e300 -o scale.glb >/dev/null 2>"$TMP/err" \
    && fail "deform --scale 1e300 exited 0"
  [ ! -e scale.glb ] || fail "deform --scale 1e300 wrote scale.glb"
  cat >huge.json <<JSON
{ "format": "obj", "meshes": ["cactus"],
  "constraints": [ { "name": "bench", "sel": "$BS/{mesh}.sel" } ],
  "transforms": [ { "name": "ok", "translate": [0, 0.01, 0] },
                  { "name": "huge", "translate": [1e300, 0, 0] },
                  { "name": "big", "scale": 1e300 } ] }
JSON
  "$HDEFORM" run huge.json -o out3 >"$TMP/out" 2>"$TMP/progress" && fail "run with huge transforms exited 0"
  cat "$TMP/progress"
  grep -Eq '^\[1/3\] cactus bench ok .* ok [0-9]+ ms' "$TMP/progress" || fail "the finite item failed"
  grep -Eq '^\[2/3\] cactus bench huge .* FAILED: .*(non-finite|INVALID_ARGUMENT)' "$TMP/progress" \
    || fail "the huge item did not fail clearly"
  grep -Eq '^\[3/3\] cactus bench big .* FAILED: ' "$TMP/progress" || fail "the scale 1e300 item did not fail"
  grep -q '^hdeform: 2 of 3 items failed' "$TMP/progress" || fail "no failure count"
  [ -f out3/cactus-bench-ok-b0.obj ] || fail "the finite item's file is missing"
  [ "$(ls out3/*.obj | wc -l)" -eq 1 ] || { ls out3 >&2; fail "a non-finite mesh was written"; }
  if grep -qiE '(^| )-?(nan|inf)( |$)' out3/*.obj; then fail "NaN/Inf in a written OBJ"; fi
  ;;
run-sessions)
  # A job with more meshes than the server's --max-sessions: each session is deleted as
  # soon as its items are done, so all items run and the server is left with no session.
  start_server --max-sessions 1
  cat >"$TMP/three.json" <<JSON
{ "format": "none", "meshes": [ { "name": "m1", "library": "cactus" },
    { "name": "m2", "library": "cactus" }, { "name": "m3", "library": "cactus" } ],
  "constraints": [ { "name": "bench", "sel": "$BS/{mesh}.sel" } ],
  "transforms": [ { "name": "bend", "def": "$BS/cactus.def" } ] }
JSON
  sed -i 's/{mesh}/cactus/' "$TMP/three.json"
  "$HDEFORM" --server "$ADDR" run "$TMP/three.json" -o "$TMP/out" >"$TMP/stdout" 2>"$TMP/progress" \
    || { cat "$TMP/progress" >&2; fail "run of 3 meshes on --max-sessions 1 exited $?"; }
  cat "$TMP/progress"
  [ "$(grep -Ec '^\[[1-3]/3\] m[1-3] bench bend .* ok [0-9]+ ms' "$TMP/progress")" -eq 3 ] \
    || fail "expected 3 ok items"
  $CHECK summary "$TMP/out/summary.csv" 3 || fail "bad summary"
  # the slot is free again: another client can create a session
  "$HDEFORM" --server "$ADDR" deform cactus --sel "$BS/cactus.sel" --def "$BS/cactus.def" \
    >"$TMP/after" || fail "the server's only session slot is still taken after the job"
  # a failing item (a bad .sel label) still closes its session
  printf '{"format": "none", "meshes": ["cactus", {"name": "c2", "library": "cactus"}], "constraints": [{"handles": ["ids:99999999"]}]}\n' \
    >"$TMP/bad.json"
  "$HDEFORM" --server "$ADDR" run "$TMP/bad.json" -o "$TMP/out-bad" >/dev/null 2>"$TMP/progress" \
    && fail "a job with a bad vertex id exited 0"
  grep -q 'RESOURCE_EXHAUSTED' "$TMP/progress" && { cat "$TMP/progress" >&2; fail "a session was left open"; }
  "$HDEFORM" --server "$ADDR" deform cactus --sel "$BS/cactus.sel" >/dev/null \
    || fail "a failed job left its session open"
  ;;
*)
  fail "unknown case $case_name"
  ;;
esac
echo "PASS: $case_name"
