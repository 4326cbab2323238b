#!/usr/bin/env bash
# Durable sessions across kill -9, for real (ctest -L routing):
#   restart_test.sh HDEFORM_SERVER ROUTING_PROBE
#
# 1. kill -9 mid-drag: a server with --state-dir; routing_probe crash drags a session, kills
#    the server itself with SIGKILL, and polls; this script restarts the server on the same
#    port and state folder at once. The session must answer with the same id and tokens, its
#    pose at most 250 ms of the drag behind (docs/api.md "Durable state"), and take further
#    moves with the same edit token.
# 2. restart time with 100 stored sessions: 100 sessions, kill -9, start again; prints the
#    time until the server listens and the time of the first call on a stored session (it is
#    restored on that call).
set -uo pipefail

SERVER=$1
PROBE=$2

TEST_NAME=restart
source "$(dirname "$0")/lib.sh"
LOG_FILES=("server*.out" probe.err)
now_ms() { date +%s%3N; }

PORT=$(free_port)
export HDEFORM_ADMIN_TOKEN=$(od -An -N16 -tx1 /dev/urandom | tr -d " \n")
RUN=0
start_server() {  # → SERVER_PID; waits until it listens
  RUN=$((RUN + 1))
  "$SERVER" --port "$PORT" --bind 127.0.0.1 --workers 2 --state-dir "$TMP/state" --max-sessions 200 \
    >"$TMP/server$RUN.out" 2>&1 &
  SERVER_PID=$!
  PIDS+=("$SERVER_PID")
  for _ in $(seq 1 300); do
    grep -q "^hdeform-server listening on" "$TMP/server$RUN.out" && return 0
    kill -0 "$SERVER_PID" 2>/dev/null || fail "hdeform-server run $RUN exited"
    sleep 0.02
  done
  fail "hdeform-server run $RUN did not start"
}

# --- 1. kill -9 mid-drag, restart at once
start_server
ID=durable-$RANDOM$RANDOM
"$PROBE" crash "127.0.0.1:$PORT" "$ID" cactus "$SERVER_PID" 3 >"$TMP/probe.out" 2>"$TMP/probe.err" &
PROBE_PID=$!
victim=$SERVER_PID
# The probe kills the server itself; restart as soon as it is gone.
for _ in $(seq 1 600); do
  kill -0 "$victim" 2>/dev/null || break
  sleep 0.01
done
wait "$victim" 2>/dev/null
start_server
wait "$PROBE_PID"
rc=$?
cat "$TMP/probe.out"
[ "$rc" = 0 ] || fail "the session did not come back as it was (probe exit $rc)"
grep -q "sessions/$ID: restored from sqlite" "$TMP/server$RUN.out" \
  || fail "the restarted server did not restore sessions/$ID"
echo "1. kill -9 mid-drag: sessions/$ID came back with its tokens; $(grep -o 'lost_ms=[0-9]*' "$TMP/probe.out") of the drag lost (limit 250)"

# --- 2. 100 stored sessions: restart time
export HDEFORM_TOKEN=$HDEFORM_ADMIN_TOKEN
for i in $(seq 1 100); do
  "$PROBE" create "127.0.0.1:$PORT" "stored-$i" bar >/dev/null || fail "CreateSession stored-$i"
done
kill -9 "$SERVER_PID"
wait "$SERVER_PID" 2>/dev/null
t0=$(now_ms)
start_server
t1=$(now_ms)
got=$("$PROBE" get "127.0.0.1:$PORT" "sessions/stored-57" stored-57 1)
t2=$(now_ms)
[ "$got" = "ok=1" ] || fail "a stored session after the restart: $got"
got=$("$PROBE" get "127.0.0.1:$PORT" "sessions/stored-57" stored-57 1)
t3=$(now_ms)
grep -q "101 stored sessions" "$TMP/server$RUN.out" || fail "the server did not see its 101 stored sessions"
echo "2. restart with 101 stored sessions: listening after $((t1 - t0)) ms; first call on a stored session $((t2 - t1)) ms (restores it), the next $((t3 - t2)) ms (each including the probe's process start)"
echo "PASS"
