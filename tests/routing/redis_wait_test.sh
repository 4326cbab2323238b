#!/usr/bin/env bash
# A replica that starts before its Redis (ctest -L routing):
#   redis_wait_test.sh HDEFORM_SERVER REDIS_SERVER
#
# (a) with HDEFORM_STATE_REDIS and --state-redis-wait 20 the server waits for a Redis started
#     2 s after it, logs that it is not reachable yet, and opens its port once it is;
# (b) with no Redis and --state-redis-wait 1 it exits non-zero within seconds, naming it;
# (c) HDEFORM_PORT is read (an empty HDEFORM_STATE_REDIS is no Redis), and --port wins over it.
set -uo pipefail

SERVER=$1
REDIS=$2

TEST_NAME=redis_wait
source "$(dirname "$0")/lib.sh"
LOG_FILES=("server-*.out" redis.out)

port_open() { (exec 3<>"/dev/tcp/127.0.0.1/$1") 2>/dev/null; }

# --- (a) the server first, Redis 2 s later
REDIS_PORT=$(free_port)
G=$(free_port)
HDEFORM_STATE_REDIS="redis://127.0.0.1:$REDIS_PORT" \
  "$SERVER" --port "$G" --bind 127.0.0.1 --workers 1 --state-redis-wait 20 \
  >"$TMP/server-a.out" 2>&1 &
A_PID=$!
PIDS+=("$A_PID")
sleep 2
kill -0 "$A_PID" 2>/dev/null || fail "(a) the server did not wait for Redis"
port_open "$G" && fail "(a) the server listens before its Redis is reachable"
"$REDIS" --port "$REDIS_PORT" --bind 127.0.0.1 --save '' --appendonly no --dir "$TMP" \
  >"$TMP/redis.out" 2>&1 &
PIDS+=("$!")
wait_port "$G" "$A_PID" "(a) the server"
grep -q "state: redis 127.0.0.1:$REDIS_PORT not reachable yet (connection refused); retrying for up to" \
  "$TMP/server-a.out" || fail "(a) no 'not reachable yet' line in the log"
grep -q "session state: redis 127.0.0.1:$REDIS_PORT" "$TMP/server-a.out" \
  || fail "(a) the server does not use the Redis"
echo "(a) waited for redis :$REDIS_PORT and listens on :$G"

# --- (b) no Redis at all: a bounded wait, then a non-zero exit naming it
NO_REDIS=$(free_port)
start=$SECONDS
"$SERVER" --port 0 --bind 127.0.0.1 --workers 1 --state-redis "redis://127.0.0.1:$NO_REDIS" \
  --state-redis-wait 1 >"$TMP/server-b.out" 2>&1 &
B_PID=$!
PIDS+=("$B_PID")
for _ in $(seq 1 50); do
  kill -0 "$B_PID" 2>/dev/null || break
  sleep 0.1
done
kill -0 "$B_PID" 2>/dev/null && fail "(b) the server still runs 5 s after a 1 s wait"
wait "$B_PID"
rc=$?
[ "$rc" -ne 0 ] || fail "(b) the server exited 0 without its Redis"
grep -q "critical.*redis 127.0.0.1:$NO_REDIS: cannot connect" "$TMP/server-b.out" \
  || fail "(b) the exit message does not name 127.0.0.1:$NO_REDIS"
echo "(b) exited $rc after $((SECONDS - start)) s: $(grep critical "$TMP/server-b.out")"

# --- (c) the port from the environment; the command line wins over it
C_PORT=$(free_port)
HDEFORM_PORT=$C_PORT HDEFORM_STATE_REDIS= HDEFORM_BIND=127.0.0.1 \
  "$SERVER" --workers 1 --no-state >"$TMP/server-c.out" 2>&1 &
C_PID=$!
PIDS+=("$C_PID")
wait_port "$C_PORT" "$C_PID" "(c) the server on HDEFORM_PORT"
D_PORT=$(free_port)
HDEFORM_PORT=$C_PORT "$SERVER" --port "$D_PORT" --bind 127.0.0.1 --workers 1 --no-state \
  >"$TMP/server-d.out" 2>&1 &
D_PID=$!
PIDS+=("$D_PID")
wait_port "$D_PORT" "$D_PID" "(c) the server on --port over HDEFORM_PORT"
echo "(c) HDEFORM_PORT=$C_PORT listened on; --port $D_PORT won over it"

echo PASS
