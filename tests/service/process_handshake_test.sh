#!/bin/bash
# hdeform-server's handshake with the process that starts it: --ready-file holds the bound
# addresses (JSON, written atomically once serving), an unwritable one fails the start naming
# it, and --exit-with-parent shuts the server down cleanly when its parent is killed.
#   usage: process_handshake_test.sh HDEFORM_SERVER
set -u
server=$1
tmp=$(mktemp -d)
trap 'kill -9 $(cat "$tmp/server.pid" 2>/dev/null) 2>/dev/null; rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; cat "$tmp"/*.log 2>/dev/null; exit 1; }

# An unwritable ready file: exit 1 and the path in the message, no server left behind.
"$server" --no-state --port 0 --ready-file "$tmp/no/such/dir/ready.json" >"$tmp/bad.log" 2>&1
[ $? -eq 1 ] || fail "an unwritable --ready-file did not fail the start with exit 1"
grep -q -- "--ready-file: cannot .*$tmp/no/such/dir" "$tmp/bad.log" || fail "no message naming the ready file"

# The parent: a shell that starts the server and sleeps; the server must die with it.
bash -c '"$@" & echo $! >"'"$tmp"'/server.pid"; sleep 600' _ \
  "$server" --no-state --port 0 --http-port 0 --exit-with-parent \
  --ready-file "$tmp/ready.json" >"$tmp/server.log" 2>&1 &
parent=$!
for _ in $(seq 100); do [ -s "$tmp/ready.json" ] && break; sleep 0.1; done
[ -s "$tmp/ready.json" ] || fail "no ready file after 10 s"
ls -a "$tmp" | grep -q '\.tmp' && fail "the ready file's temporary copy was left behind"
read -r grpc http < <(python3 -c 'import json,sys; d=json.load(open(sys.argv[1])); print(d["grpc"], d["http"])' "$tmp/ready.json") \
  || fail "the ready file is not JSON with grpc and http: $(cat "$tmp/ready.json")"
grep -q "listening on $grpc\$" "$tmp/server.log" || fail "ready file's grpc $grpc is not the address the server logs"
grep -q "http on $http " "$tmp/server.log" || fail "ready file's http $http is not the address the server logs"
(exec 3<>"/dev/tcp/${grpc%:*}/${grpc##*:}") 2>/dev/null || fail "nothing accepts on $grpc"
(exec 3<>"/dev/tcp/${http%:*}/${http##*:}") 2>/dev/null || fail "nothing accepts on $http"

pid=$(cat "$tmp/server.pid")
kill -0 "$pid" || fail "the server is not running"
kill -9 "$parent"
for _ in $(seq 100); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
kill -0 "$pid" 2>/dev/null && fail "the server outlived its killed parent by 10 s"
grep -q "signal 15: shutting down" "$tmp/server.log" || fail "the server did not shut down as on SIGTERM"
grep -q "bye" "$tmp/server.log" || fail "the server did not finish its shutdown"
echo "process handshake: ok (ready file $grpc / $http; exit with parent)"
