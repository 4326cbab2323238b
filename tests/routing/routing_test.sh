#!/usr/bin/env bash
# Session-affinity routing through nginx, for real (ctest -L routing):
#   routing_test.sh NGINX HDEFORM_SERVER ROUTING_PROBE SOURCE_DIR [HDEFORM_CLI]
#
# Starts two hdeform-server replicas on loopback and a non-daemon nginx in front of them,
# its config rendered from docker/nginx.conf.template (the same template as docker/nginx.conf)
# into a temp dir (pid, logs and temp files there too). Then shows:
#   1. each session created through nginx with an x-session-id header (and the same id as
#      CreateSessionHeader.session_id) is named sessions/{that id} and answers 20 GetSession
#      calls through nginx with that header: all OK (a session exists on one replica only, so
#      a wrong route would be NOT_FOUND);
#   2. different ids spread over both replicas (counted on each replica directly);
#   3. without the header calls are spread over the replicas and many are NOT_FOUND (the
#      header is what makes 1. work);
#   4. the hdeform CLI works through nginx (it sends the header on every call);
#   5. failover: a replica dies; a client re-imports its snapshot under the same id through
#      nginx, gets the same session name back, and the session answers again
#      (docs/deployment.md).
# Also checks that docker/nginx.conf is the template's current rendering.
set -uo pipefail

NGINX=$1
SERVER=$2
PROBE=$3
SRC=$4
CLI=${5:-}

TMP=$(mktemp -d "${TMPDIR:-/tmp}/hdeform-routing.XXXXXX")
PIDS=()
NGINX_PID=""
cleanup() {
  if [ -n "$NGINX_PID" ]; then
    kill -QUIT "$NGINX_PID" 2>/dev/null
    wait "$NGINX_PID" 2>/dev/null
  fi
  for p in "${PIDS[@]}"; do kill "$p" 2>/dev/null; done
  for p in "${PIDS[@]}"; do wait "$p" 2>/dev/null; done
  rm -rf "$TMP"
}
trap cleanup EXIT

fail() {
  echo "FAIL: $*" >&2
  if [ -f "$TMP/error.log" ]; then echo "--- nginx error.log" >&2; tail -20 "$TMP/error.log" >&2; fi
  exit 1
}

# docker/nginx.conf must be the template's rendering with the compose defaults.
diff <(bash "$SRC/docker/render-nginx-conf.sh") "$SRC/docker/nginx.conf" >/dev/null \
  || fail "docker/nginx.conf is stale: run docker/render-nginx-conf.sh > docker/nginx.conf"

# --- two replicas
start_replica() {  # INDEX → ADDR_INDEX
  local i=$1
  "$SERVER" --port 0 --bind 127.0.0.1 --workers 1 >"$TMP/server$i.out" 2>"$TMP/server$i.err" &
  PIDS+=($!)
  eval "SERVER${i}_PID=$!"
  for _ in $(seq 1 300); do
    local addr
    addr=$(sed -n 's/^hdeform-server listening on \([^ ]*\).*/\1/p' "$TMP/server$i.out")
    if [ -n "$addr" ]; then eval "ADDR$i=$addr"; return 0; fi
    sleep 0.1
  done
  cat "$TMP/server$i.err" >&2
  fail "replica $i did not start"
}
start_replica 1
start_replica 2
echo "replicas: $ADDR1 $ADDR2"

# --- nginx on a free loopback port
PORT=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])' 2>/dev/null \
       || echo $((20000 + RANDOM % 20000)))
LB=127.0.0.1:$PORT
mkdir -p "$TMP/temp/body" "$TMP/temp/proxy"
chmod -R 777 "$TMP/temp"
chmod 755 "$TMP"
NGINX_LISTEN=$LB NGINX_UPSTREAMS="$ADDR1 $ADDR2" NGINX_PID_FILE=$TMP/nginx.pid \
  NGINX_ERROR_LOG=$TMP/error.log NGINX_ACCESS_LOG=$TMP/access.log NGINX_TEMP_DIR=$TMP/temp \
  bash "$SRC/docker/render-nginx-conf.sh" >"$TMP/nginx.conf"
"$NGINX" -t -q -p "$TMP" -c "$TMP/nginx.conf" 2>"$TMP/nginx-t.err" \
  || { cat "$TMP/nginx-t.err" >&2; fail "nginx -t rejected the rendered config"; }
"$NGINX" -p "$TMP" -c "$TMP/nginx.conf" -g 'daemon off;' 2>"$TMP/nginx.stderr" &
NGINX_PID=$!
for _ in $(seq 1 100); do
  (exec 3<>"/dev/tcp/127.0.0.1/$PORT") 2>/dev/null && break
  kill -0 "$NGINX_PID" 2>/dev/null || { cat "$TMP/nginx.stderr" >&2; fail "nginx exited"; }
  sleep 0.1
done
echo "nginx: $LB"

# --- 1. sessions through nginx, 20 calls each with the header
N=16
declare -A NAME
for i in $(seq 1 $N); do
  key=routing-$i-$RANDOM
  name=$("$PROBE" create "$LB" "$key" knight) || fail "CreateSession via nginx ($key)"
  [ "$name" = "sessions/$key" ] || fail "CreateSession with session_id $key named the session '$name'"
  NAME[$key]=$name
  got=$("$PROBE" get "$LB" "$name" "$key" 20)
  [ "$got" = "ok=20" ] || fail "$name (x-session-id $key): 20 GetSession calls via nginx gave '$got'"
done
echo "1. $N sessions x 20 GetSession calls through nginx: all OK"
honored=0
for key in "${!NAME[@]}"; do [ "${NAME[$key]}" = "sessions/$key" ] && honored=$((honored + 1)); done
echo "   the server used the client's session_id for $honored of $N sessions"
[ "$honored" -eq "$N" ] || fail "the server ignored session_id for $((N - honored)) of $N sessions"

# --- 2. spread over both replicas
c1=$("$PROBE" count "$ADDR1") || fail "ListSessions on $ADDR1"
c2=$("$PROBE" count "$ADDR2") || fail "ListSessions on $ADDR2"
echo "2. sessions per replica: $ADDR1=$c1 $ADDR2=$c2"
[ $((c1 + c2)) -eq $N ] || fail "expected $N sessions in all, found $((c1 + c2))"
[ "$c1" -gt 0 ] && [ "$c2" -gt 0 ] || fail "the sessions did not spread over both replicas"
for key in "${!NAME[@]}"; do
  a=0; b=0
  "$PROBE" has "$ADDR1" "${NAME[$key]}" && a=1
  "$PROBE" has "$ADDR2" "${NAME[$key]}" && b=1
  [ $((a + b)) -eq 1 ] || fail "${NAME[$key]} is on $((a + b)) replicas"
done

# --- 3. without the header nginx spreads calls (its hash falls back to round-robin for an
# empty key): some calls miss the session's replica
found=0; missed=0
for key in "${!NAME[@]}"; do
  got=$("$PROBE" get "$LB" "${NAME[$key]}" - 4)
  for kv in $got; do
    case "$kv" in
      ok=*) found=$((found + ${kv#ok=})) ;;
      code5=*) missed=$((missed + ${kv#code5=})) ;;   # 5 = NOT_FOUND
      *) fail "without the header, ${NAME[$key]} gave '$got'" ;;
    esac
  done
done
echo "3. without x-session-id: $found calls found their session, $missed were NOT_FOUND"
[ "$missed" -gt 0 ] || fail "without the header every call was found: routing proves nothing"

# --- 4. the CLI through nginx
if [ -n "$CLI" ]; then
  "$CLI" --server "$LB" deform cactus --sel "$SRC/data/botsch-sorkine/cactus.sel" \
    --def "$SRC/data/botsch-sorkine/cactus.def" -o "$TMP/via-nginx.glb" >"$TMP/cli.out" \
    || fail "hdeform deform through nginx"
  grep -q '^flips' "$TMP/cli.out" || fail "hdeform deform through nginx printed no measures"
  "$CLI" --server "$LB" sweep cactus --sel "$SRC/data/botsch-sorkine/cactus.sel" \
    --def "$SRC/data/botsch-sorkine/cactus.def" --betas 0,0.1 --csv - >"$TMP/cli.csv" \
    || fail "hdeform sweep through nginx"
  [ "$(wc -l <"$TMP/cli.csv")" -eq 3 ] || fail "hdeform sweep through nginx: expected 3 CSV lines"
  echo "4. hdeform deform/sweep through nginx: OK"
fi

# --- 5. failover: lose replica 2, re-import its session under the same id
victim=""
for key in "${!NAME[@]}"; do
  if "$PROBE" has "$ADDR2" "${NAME[$key]}"; then victim=$key; break; fi
done
[ -n "$victim" ] || fail "no session on replica 2"
vname=${NAME[$victim]}
"$PROBE" export "$LB" "$vname" "$victim" "$TMP/snapshot.pb" || fail "ExportSession via nginx"
kill "$SERVER2_PID"; wait "$SERVER2_PID" 2>/dev/null
got=$("$PROBE" get "$LB" "$vname" "$victim" 3)
[ "$got" != "ok=3" ] || fail "$vname still answers after its replica died"
echo "5. replica 2 stopped: $vname now gives '$got'"
newname=$("$PROBE" import "$LB" "$TMP/snapshot.pb" "$victim") || fail "ImportSession via nginx"
[ "$newname" = "$vname" ] || fail "re-imported under id $victim as '$newname', expected $vname"
got=$("$PROBE" get "$LB" "$newname" "$victim" 20)
[ "$got" = "ok=20" ] || fail "re-imported $newname: 20 GetSession calls via nginx gave '$got'"
echo "   re-imported as $newname under x-session-id $victim: 20 GetSession calls OK"

# the access log shows where each call went
grep -c 'upstream=' "$TMP/access.log" >/dev/null || fail "nginx access log is empty"
echo "PASS: routing"
