#!/usr/bin/env bash
# WAN bench (issue 11): hdeform-server and a headless drag client (bench/wan/drag.ts, the
# viewer's gRPC-Web transport and frame decoders) in a private network namespace whose
# loopback is rate-limited with tbf, one run per (rate, encoding); prints one table.
# Results and method: docs/benchmarks.md "WAN bench (issue 11)".
#
#   sudo bench/wan/run.sh [--server PATH] [--vertices N] [--seconds S] [--hz H]
#                         [--rate 50mbit,none] [--encodings float32,quantized,meshopt,meshopt-delta]
#
# Needs root (ip netns, tc), node 20 and web-viewer's node_modules (npm ci) with the
# generated stubs (npm run generate; done here when missing). netem is not assumed: only the
# bandwidth is shaped (tbf), so the round trip is loopback's plus queueing behind the frames.
set -euo pipefail

here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
server="$root/build/server/hdeform-server"
vertices=100000
seconds=10
hz=60
rates="50mbit,none"
encodings="float32,quantized,meshopt,meshopt-delta"
while [[ $# -gt 0 ]]; do
  case "$1" in
    --server) server=$2; shift 2 ;;
    --vertices) vertices=$2; shift 2 ;;
    --seconds) seconds=$2; shift 2 ;;
    --hz) hz=$2; shift 2 ;;
    --rate) rates=$2; shift 2 ;;
    --encodings) encodings=$2; shift 2 ;;
    -h|--help) sed -n '2,13p' "$0"; exit 0 ;;
    *) echo "run.sh: unknown option $1" >&2; exit 2 ;;
  esac
done
[[ $EUID -eq 0 ]] || { echo "run.sh: needs root (ip netns, tc)" >&2; exit 1; }
[[ -x "$server" ]] || { echo "run.sh: no server at $server (--server PATH)" >&2; exit 1; }
tsx="$root/web-viewer/node_modules/.bin/tsx"
[[ -x "$tsx" ]] || { echo "run.sh: $tsx missing: (cd web-viewer && npm ci)" >&2; exit 1; }
[[ -f "$root/web-viewer/src/gen/hdeform/v1/deform_pb.ts" ]] || (cd "$root/web-viewer" && npm run -s generate)

ns="hdeform-wan-$$"
work=$(mktemp -d)
server_pid=""
cleanup() {
  [[ -n "$server_pid" ]] && kill "$server_pid" 2>/dev/null && wait "$server_pid" 2>/dev/null
  ip netns del "$ns" 2>/dev/null
  rm -rf "$work"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

ip netns add "$ns"
# Ethernet's MTU rather than loopback's 64 KiB: tbf drops any packet larger than its burst,
# and a WAN path carries 1500-byte packets anyway.
ip -n "$ns" link set lo mtu 1500 up
# The token goes through the environment (not argv, which `ps` shows); ≥ 16 characters.
export HDEFORM_ADMIN_TOKEN="wan-bench-$(head -c 12 /dev/urandom | od -An -tx1 | tr -d ' \n')"
# --no-state: nothing written to the state folder; nice: the machine is shared.
ip netns exec "$ns" nice -n 10 "$server" --port 50051 --http-port 8080 --no-state \
  --log-level warn >"$work/server.log" 2>&1 &
server_pid=$!
for _ in $(seq 100); do
  ip netns exec "$ns" curl -sf http://127.0.0.1:8080/healthz >/dev/null 2>&1 && break
  kill -0 "$server_pid" 2>/dev/null || { cat "$work/server.log" >&2; exit 1; }
  sleep 0.1
done

results="$work/results.jsonl"
IFS=, read -ra rate_list <<<"$rates"
IFS=, read -ra enc_list <<<"$encodings"
for rate in "${rate_list[@]}"; do
  # Shape the namespace's loopback: every byte between client and server crosses it (both
  # directions share the one qdisc, as on a half-duplex-ish uplink; the frames dominate).
  ip netns exec "$ns" tc qdisc del dev lo root 2>/dev/null || true
  if [[ "$rate" != none ]]; then
    ip netns exec "$ns" tc qdisc add dev lo root tbf rate "$rate" burst 64kb latency 200ms
  fi
  for enc in "${enc_list[@]}"; do
    echo "== $enc @ $rate, $vertices vertices, ${seconds}s at ${hz} Hz" >&2
    ip netns exec "$ns" nice -n 10 "$tsx" "$here/drag.ts" --url http://127.0.0.1:8080 \
      --vertices "$vertices" --seconds "$seconds" --hz "$hz" --encoding "$enc" --rate "$rate" \
      | tee "$work/run.out" >&2 || echo "   (run failed)" >&2
    grep '^{' "$work/run.out" >>"$results" || true
  done
done

# One table from the JSON lines (node: already required).
node -e '
const rows = require("fs").readFileSync(process.argv[1], "utf8").trim().split("\n").filter(Boolean).map(JSON.parse);
const cols = [["encoding","encoding"],["rate","rate"],["vertices","N"],["fps_delivered","fps deliv"],["fps_decoded","fps dec"],
  ["latency_p50_ms","lat p50 ms"],["latency_p99_ms","lat p99 ms"],["frame_buffer_bytes_p50","buffer B"],["wire_bytes_per_frame","wire B/frame"],
  ["watch_mbit_s","Mbit/s"],["decode_p50_ms","decode ms"],["solve_p50_ms","solve ms"],["superseded","superseded"],["skipped_full_window","skipped"],
  ["key_frames","key frames"],["final_ok","final ok"],["decoder","decoder"]];
console.log("| " + cols.map(c => c[1]).join(" | ") + " |");
console.log("|" + cols.map(() => "---").join("|") + "|");
for (const r of rows) console.log("| " + cols.map(([k]) => k === "decoder" && r[k] !== "ok" ? "missing" : (r[k] === null ? "—" : String(r[k]))).join(" | ") + " |");
' "$results"
