#!/usr/bin/env bash
# Session-affinity routing through nginx, for real (ctest -L routing):
#   routing_test.sh NGINX HDEFORM_SERVER ROUTING_PROBE SOURCE_DIR CURL [HDEFORM_CLI]
#
# Starts two hdeform-server replicas on loopback (each with its gRPC port and its HTTP
# gateway, --http-port) and a non-daemon nginx in front of them, its config rendered from
# docker/nginx.conf.template (the same template as docker/nginx.conf) into a temp dir (pid,
# logs and temp files there too): a gRPC door and a browser (HTTP/1.1) door. Then shows:
#   1. each session created through nginx with an x-session-id header (and the same id as
#      CreateSessionHeader.session_id) is named sessions/{that id} and answers 20 GetSession
#      calls through nginx with that header: all OK (a session exists on one replica only, so
#      a wrong route would be NOT_FOUND);
#   2. different ids spread over both replicas (counted on each replica directly);
#   3. without the header calls are spread over the replicas and many are NOT_FOUND (the
#      header is what makes 1. work);
#   4. the hdeform CLI works through nginx (it sends the header on every call);
#   5. the browser door (what the web viewer does, with curl): static files; gRPC-Web
#      GetSession with the header reaches the session of every id from 1. (both doors map an
#      id to the same replica); POST /upload?…&session_id=ID with the header creates sessions
#      that the gRPC door then finds under that header, spread over both replicas; without the
#      header gRPC-Web calls miss; a WatchSession stream delivers a state event while it is
#      still open (nginx does not buffer it);
#   6. failover: a replica dies; a client re-imports its snapshot under the same id through
#      nginx, gets the same session name back, and the session answers again — through both
#      doors (docs/deployment.md).
# Also checks that docker/nginx.conf is the template's current rendering.
set -uo pipefail

NGINX=$1
SERVER=$2
PROBE=$3
SRC=$4
CURL=$5
CLI=${6:-}

TEST_NAME=routing
source "$(dirname "$0")/lib.sh"
LOG_FILES=(error.log nginx.stderr)

# docker/nginx.conf must be the template's rendering with the compose defaults.
diff <(bash "$SRC/docker/render-nginx-conf.sh") "$SRC/docker/nginx.conf" >/dev/null \
  || fail "docker/nginx.conf is stale: run docker/render-nginx-conf.sh > docker/nginx.conf"

# The replicas' operator token: every session call below presents it (routing_probe and the
# CLI read HDEFORM_TOKEN; curl sends it as the gRPC-Web authorization header). Access control
# itself is tested in tests/security; here it must simply not get in the way of routing.
export HDEFORM_ADMIN_TOKEN=$(od -An -N16 -tx1 /dev/urandom | tr -d " \n")
export HDEFORM_TOKEN=$HDEFORM_ADMIN_TOKEN
AUTH=(-H "authorization: Bearer $HDEFORM_TOKEN")

# --- two replicas, each with its HTTP gateway serving a tiny web root
mkdir -p "$TMP/web"
echo "hdeform routing test page" >"$TMP/web/index.html"
start_replica() {  # INDEX → ADDR_INDEX, HTTP_INDEX
  local i=$1
  "$SERVER" --port 0 --http-port 0 --web-root "$TMP/web" --bind 127.0.0.1 --workers 1 --no-state \
    >"$TMP/server$i.out" 2>"$TMP/server$i.err" &
  PIDS+=($!)
  eval "SERVER${i}_PID=$!"
  for _ in $(seq 1 300); do
    local addr http
    addr=$(sed -n 's/^hdeform-server listening on \([^ ]*\).*/\1/p' "$TMP/server$i.out")
    http=$(sed -n 's/^hdeform-server http on \([^ ]*\).*/\1/p' "$TMP/server$i.out")
    if [ -n "$addr" ] && [ -n "$http" ]; then
      eval "ADDR$i=$addr"
      eval "HTTP$i=$http"
      return 0
    fi
    sleep 0.1
  done
  cat "$TMP/server$i.err" >&2
  fail "replica $i did not start (gRPC and http lines expected)"
}
start_replica 1
start_replica 2
echo "replicas: gRPC $ADDR1 $ADDR2, http $HTTP1 $HTTP2"

# --- nginx on two free loopback ports
PORT=$(free_port)
HTTP_PORT=$(free_port)
while [ "$HTTP_PORT" = "$PORT" ]; do HTTP_PORT=$(free_port); done
LB=127.0.0.1:$PORT
WEB=127.0.0.1:$HTTP_PORT
mkdir -p "$TMP/temp/body" "$TMP/temp/proxy"
chmod -R 777 "$TMP/temp"
chmod 755 "$TMP"
NGINX_LISTEN=$LB NGINX_UPSTREAMS="$ADDR1 $ADDR2" \
  NGINX_HTTP_LISTEN=$WEB NGINX_HTTP_UPSTREAMS="$HTTP1 $HTTP2" NGINX_PID_FILE=$TMP/nginx.pid \
  NGINX_ERROR_LOG=$TMP/error.log NGINX_ACCESS_LOG=$TMP/access.log NGINX_TEMP_DIR=$TMP/temp \
  bash "$SRC/docker/render-nginx-conf.sh" >"$TMP/nginx.conf"
"$NGINX" -t -q -p "$TMP" -c "$TMP/nginx.conf" 2>"$TMP/nginx-t.err" \
  || { cat "$TMP/nginx-t.err" >&2; fail "nginx -t rejected the rendered config"; }
"$NGINX" -p "$TMP" -c "$TMP/nginx.conf" -g 'daemon off;' 2>"$TMP/nginx.stderr" &
NGINX_PID=$!
wait_port "$PORT" "$NGINX_PID" nginx
wait_port "$HTTP_PORT" "$NGINX_PID" nginx
echo "nginx: gRPC $LB, http $WEB"

# --- gRPC-Web over curl, as the viewer's transport does it (binary protobuf frames)
hex2() { printf '\\x%02x' "$1"; }
# A gRPC-Web data frame around a request whose field 1 is NAME (< 100 bytes) and whose
# optional EXTRA is printf-escaped bytes of further fields.
web_request() {  # NAME FILE [EXTRA EXTRA_LEN]
  local name=$1 n=${#1} extra=${3:-} extra_len=${4:-0}
  local len=$((n + 2 + extra_len))
  printf "\\x00\\x00\\x00\\x00$(hex2 $len)\\x0a$(hex2 "$n")%s$extra" "$name" >"$2"
}
# One gRPC-Web call through the browser door; prints its grpc-status ("" if none).
web_call() {  # METHOD REQUEST_FILE KEY|-
  local method=$1 req=$2 key=$3 hdr=()
  [ "$key" != "-" ] && hdr=(-H "x-session-id: $key")
  "$CURL" -sS -o "$TMP/web.body" -D "$TMP/web.headers" --max-time 30 "${hdr[@]}" "${AUTH[@]}" \
    -H 'content-type: application/grpc-web+proto' -H 'x-grpc-web: 1' \
    --data-binary @"$req" "http://$WEB/hdeform.v1.Deformation/$method" 2>"$TMP/web.err" || return 0
  cat "$TMP/web.headers" "$TMP/web.body" | tr -d '\r' | grep -aoiE 'grpc-status: ?[0-9]+' \
    | head -1 | grep -oE '[0-9]+$'
}
web_get() {  # NAME KEY|- N → "ok=K codeC=n …" like routing_probe get
  local name=$1 key=$2 n=$3 i code
  declare -A seen=()
  web_request "$name" "$TMP/get.req"
  for i in $(seq 1 "$n"); do
    code=$(web_call GetSession "$TMP/get.req" "$key")
    if [ "$code" = 0 ]; then seen[ok]=$((${seen[ok]:-0} + 1)); else seen[code${code:-?}]=$((${seen[code${code:-?}]:-0} + 1)); fi
  done
  local out=""
  for k in $(printf '%s\n' "${!seen[@]}" | sort); do out+="$k=${seen[$k]} "; done
  echo "${out% }"
}

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

# --- 5. the browser door
page=$("$CURL" -sS --max-time 10 "http://$WEB/") || fail "GET / through nginx's http door"
[ "$page" = "hdeform routing test page" ] || fail "GET / through nginx's http door gave '$page'"
for key in "${!NAME[@]}"; do
  got=$(web_get "${NAME[$key]}" "$key" 5)
  [ "$got" = "ok=5" ] \
    || fail "${NAME[$key]} (made through the gRPC door): 5 gRPC-Web GetSession via the http door gave '$got'"
done
echo "5. http door: static page OK; the $N gRPC-door sessions x 5 gRPC-Web GetSession with the header: all OK"
M=8
declare -A WNAME
for i in $(seq 1 $M); do
  key=web-$i-$RANDOM
  if [ $((i % 2)) = 1 ]; then
    args=(--data-binary @"$SRC/data/models/knight.off" -H 'content-type: application/octet-stream')
    q="filename=knight.off"
  else
    args=(-X POST)
    q="library=knight"
  fi
  status=$("$CURL" -sS -o "$TMP/upload.out" -w '%{http_code}' --max-time 60 "${args[@]}" "${AUTH[@]}" \
           -H "x-session-id: $key" "http://$WEB/upload?$q&session_id=$key") \
    || fail "POST /upload?$q through the http door"
  [ "$status" = 200 ] || fail "POST /upload?$q&session_id=$key: HTTP $status: $(head -c 300 "$TMP/upload.out")"
  grep -aq "sessions/$key" "$TMP/upload.out" || fail "POST /upload for $key: the reply names no sessions/$key"
  WNAME[$key]=sessions/$key
  got=$("$PROBE" get "$LB" "sessions/$key" "$key" 5)
  [ "$got" = "ok=5" ] || fail "sessions/$key (uploaded through the http door): 5 GetSession via the gRPC door gave '$got'"
done
w1=0; w2=0
for key in "${!WNAME[@]}"; do
  a=0; b=0
  "$PROBE" has "$ADDR1" "${WNAME[$key]}" && a=1
  "$PROBE" has "$ADDR2" "${WNAME[$key]}" && b=1
  [ $((a + b)) -eq 1 ] || fail "${WNAME[$key]} is on $((a + b)) replicas"
  w1=$((w1 + a)); w2=$((w2 + b))
done
echo "   $M sessions made by POST /upload (uploads and library) with the header: found through the gRPC door; per replica $w1 + $w2"
[ "$w1" -gt 0 ] && [ "$w2" -gt 0 ] || fail "the uploaded sessions did not spread over both replicas"
found=0; missed=0
for key in "${!NAME[@]}"; do
  got=$(web_get "${NAME[$key]}" - 4)
  for kv in $got; do
    case "$kv" in
      ok=*) found=$((found + ${kv#ok=})) ;;
      code5=*) missed=$((missed + ${kv#code5=})) ;;
      *) fail "gRPC-Web without the header, ${NAME[$key]} gave '$got'" ;;
    esac
  done
done
echo "   gRPC-Web without x-session-id: $found calls found their session, $missed were NOT_FOUND"
[ "$missed" -gt 0 ] || fail "gRPC-Web without the header: every call was found, routing proves nothing"
# A live WatchSession stream: its first event (the state) and one after a SetBeta must come
# through while the stream is still open.
wkey=$(printf '%s\n' "${!WNAME[@]}" | head -1)
wname=${WNAME[$wkey]}
web_request "$wname" "$TMP/watch.req"
"$CURL" -sS -N --max-time 30 -o "$TMP/watch.out" -H "x-session-id: $wkey" "${AUTH[@]}" \
  -H 'content-type: application/grpc-web+proto' -H 'x-grpc-web: 1' \
  --data-binary @"$TMP/watch.req" "http://$WEB/hdeform.v1.Deformation/WatchSession" 2>/dev/null &
WATCH_PID=$!
events() { grep -ao "$wname" "$TMP/watch.out" 2>/dev/null | wc -l; }
for _ in $(seq 1 100); do [ "$(events)" -ge 1 ] && break; sleep 0.1; done
[ "$(events)" -ge 1 ] || { kill "$WATCH_PID" 2>/dev/null; fail "WatchSession through the http door: no first event within 10 s"; }
# SetBeta {name, beta {value 0.25}}: field 2 = 0x12, 9 bytes: 0x09 + 0.25 as LE double.
web_request "$wname" "$TMP/beta.req" '\x12\x09\x09\x00\x00\x00\x00\x00\x00\xd0\x3f' 11
code=$(web_call SetBeta "$TMP/beta.req" "$wkey")
[ "$code" = 0 ] || { kill "$WATCH_PID" 2>/dev/null; fail "SetBeta via gRPC-Web for $wname: grpc-status '$code'"; }
for _ in $(seq 1 100); do [ "$(events)" -ge 2 ] && break; sleep 0.1; done
n_events=$(events)
kill -0 "$WATCH_PID" 2>/dev/null || fail "the WatchSession stream ended early"
kill "$WATCH_PID" 2>/dev/null; wait "$WATCH_PID" 2>/dev/null
[ "$n_events" -ge 2 ] || fail "WatchSession through the http door: the SetBeta state event did not arrive while the stream was open (buffered?)"
echo "   WatchSession through the http door: state events arrive live ($n_events while open)"

# --- 6. failover: lose replica 2, re-import its session under the same id
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
echo "6. replica 2 stopped: $vname now gives '$got'"
newname=$("$PROBE" import "$LB" "$TMP/snapshot.pb" "$victim") || fail "ImportSession via nginx"
[ "$newname" = "$vname" ] || fail "re-imported under id $victim as '$newname', expected $vname"
got=$("$PROBE" get "$LB" "$newname" "$victim" 20)
[ "$got" = "ok=20" ] || fail "re-imported $newname: 20 GetSession calls via nginx gave '$got'"
echo "   re-imported as $newname under x-session-id $victim: 20 GetSession calls OK"
got=$(web_get "$newname" "$victim" 5)
[ "$got" = "ok=5" ] || fail "re-imported $newname: 5 gRPC-Web GetSession via the http door gave '$got'"
echo "   and 5 gRPC-Web GetSession calls through the http door: OK (both doors rehash alike)"

# the access log shows where each call went
grep -c 'upstream=' "$TMP/access.log" >/dev/null || fail "nginx access log is empty"
echo "PASS: routing"
