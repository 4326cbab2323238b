#!/usr/bin/env bash
# Failover on shared state, for real (ctest -L routing):
#   failover_test.sh NGINX HDEFORM_SERVER ROUTING_PROBE SOURCE_DIR REDIS_SERVER
#
# redis-server, two hdeform-server replicas with --state-redis, and nginx in front of them
# (config rendered from docker/nginx.conf.template, as in routing_test.sh), all on loopback in
# a temp dir. A client (routing_probe drag) creates a session through nginx and drags its
# handle continuously with the session's own tokens; meanwhile the replica that holds the
# session is killed with SIGKILL. The drag must go on through the other replica with the same
# session id, tokens and pose, retrying at most once per failed call (docs/deployment.md);
# the probe checks the final pose and version against its last acknowledged move and reports
# the longest gap between two answered moves (the failover gap).
set -uo pipefail

NGINX=$1
SERVER=$2
PROBE=$3
SRC=$4
REDIS=$5

TEST_NAME=failover
source "$(dirname "$0")/lib.sh"
LOG_FILES=("server*.out" error.log drag.err)

# --- Redis (no persistence: the test is about replicas, not Redis restarts)
REDIS_PORT=$(free_port)
"$REDIS" --port "$REDIS_PORT" --bind 127.0.0.1 --save '' --appendonly no --dir "$TMP" \
  >"$TMP/redis.out" 2>&1 &
REDIS_PID=$!
PIDS+=("$REDIS_PID")
wait_port "$REDIS_PORT" "$REDIS_PID" redis-server

# --- two replicas on the shared state, each on fixed ports (nginx needs them up front)
G1=$(free_port); G2=$(free_port); H1=$(free_port); H2=$(free_port)
start_replica() {  # INDEX GRPC_PORT HTTP_PORT
  "$SERVER" --port "$2" --http-port "$3" --bind 127.0.0.1 --workers 1 \
    --state-redis "redis://127.0.0.1:$REDIS_PORT" >"$TMP/server$1.out" 2>&1 &
  local pid=$!
  PIDS+=("$pid")
  eval "SERVER$1_PID=$pid"
  wait_port "$2" "$pid" "replica $1"
}
start_replica 1 "$G1" "$H1"
start_replica 2 "$G2" "$H2"

# --- nginx
PORT=$(free_port)
HTTP_PORT=$(free_port)
LB=127.0.0.1:$PORT
mkdir -p "$TMP/temp/body" "$TMP/temp/proxy"
chmod -R 777 "$TMP/temp"
chmod 755 "$TMP"
NGINX_LISTEN=$LB NGINX_UPSTREAMS="127.0.0.1:$G1 127.0.0.1:$G2" \
  NGINX_HTTP_LISTEN=127.0.0.1:$HTTP_PORT NGINX_HTTP_UPSTREAMS="127.0.0.1:$H1 127.0.0.1:$H2" \
  NGINX_PID_FILE=$TMP/nginx.pid NGINX_ERROR_LOG=$TMP/error.log \
  NGINX_ACCESS_LOG=$TMP/access.log NGINX_TEMP_DIR=$TMP/temp \
  bash "$SRC/docker/render-nginx-conf.sh" >"$TMP/nginx.conf"
"$NGINX" -t -q -p "$TMP" -c "$TMP/nginx.conf" 2>"$TMP/nginx-t.err" \
  || { cat "$TMP/nginx-t.err" >&2; fail "nginx -t rejected the rendered config"; }
"$NGINX" -p "$TMP" -c "$TMP/nginx.conf" -g 'daemon off;' 2>"$TMP/nginx.stderr" &
NGINX_PID=$!
wait_port "$PORT" "$NGINX_PID" nginx
echo "redis :$REDIS_PORT, replicas :$G1 :$G2, nginx $LB"

# --- the drag, and the kill of the replica that holds its session
ID=failover-$RANDOM$RANDOM
"$PROBE" drag "$LB" "$ID" cactus 7 >"$TMP/drag.out" 2>"$TMP/drag.err" &
DRAG_PID=$!
holder=""
for _ in $(seq 1 100); do
  sleep 0.1
  grep -q "sessions/$ID: created" "$TMP/server1.out" && holder=1
  grep -q "sessions/$ID: created" "$TMP/server2.out" && holder=2
  [ -n "$holder" ] && break
done
[ -n "$holder" ] || fail "no replica logged the creation of sessions/$ID"
survivor=$((3 - holder))
sleep 2.5  # dragging on the holder
eval "victim=\$SERVER${holder}_PID"
kill -9 "$victim"
echo "killed replica $holder (pid $victim) holding sessions/$ID mid-drag"
wait "$DRAG_PID"
rc=$?
cat "$TMP/drag.out"
[ "$rc" = 0 ] || fail "the drag did not survive the failover (exit $rc)"
grep -q "sessions/$ID: restored from redis" "$TMP/server$survivor.out" \
  || fail "replica $survivor did not restore sessions/$ID from Redis"
grep -q "failures=[1-9]" "$TMP/drag.out" \
  || echo "note: no call failed (the kill fell between two calls)"
gap=$(sed -n 's/.*gap_ms=\([0-9]*\).*/\1/p' "$TMP/drag.out")
[ -n "$gap" ] && [ "$gap" -lt 5000 ] || fail "failover gap ${gap:-?} ms (limit 5000)"
echo "PASS: the drag went on on replica $survivor with the same id, tokens and pose; failover gap $gap ms"
