# Shared by the routing tests (source it after `set -uo pipefail`, with TEST_NAME set):
# a temp dir, every started process stopped on exit, failures that print the logs, ports.
#   TMP        the test's temp dir (removed on exit)
#   PIDS       processes to stop on exit (append with PIDS+=("$pid"))
#   NGINX_PID  a non-daemon nginx, stopped gracefully first
#   LOG_FILES  globs under $TMP whose tails `fail` prints

TMP=$(mktemp -d "${TMPDIR:-/tmp}/hdeform-$TEST_NAME.XXXXXX")
PIDS=()
NGINX_PID=""
LOG_FILES=()

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
  local pattern f
  for pattern in "${LOG_FILES[@]}"; do
    for f in "$TMP"/$pattern; do
      [ -f "$f" ] && { echo "--- $f" >&2; tail -20 "$f" >&2; }
    done
  done
  exit 1
}

# A port that was free a moment ago (the kernel's choice; a random one without python3).
free_port() {
  python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])' 2>/dev/null \
    || echo $((20000 + RANDOM % 20000))
}

# Waits up to 10 s until PORT accepts connections; fails if PID exits first.
wait_port() {  # PORT PID NAME
  for _ in $(seq 1 100); do
    (exec 3<>"/dev/tcp/127.0.0.1/$1") 2>/dev/null && return 0
    kill -0 "$2" 2>/dev/null || fail "$3 exited"
    sleep 0.1
  done
  fail "$3 does not listen on $1"
}
