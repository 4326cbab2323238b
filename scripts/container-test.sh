#!/usr/bin/env bash
# The images of docker/Dockerfile and the cluster of docker/docker-compose.yml, built and run
# for real with Debian's podman (ctest -L containers; docs/deployment.md "Containers"):
#   container-test.sh HDEFORM_CLI PYTHON PYTHONPATH
#
#  1. a debian:bookworm base image made by debootstrap (no outside registry; kept as a cache);
#  2. the server, lb and redis images built from docker/Dockerfile;
#  3. the compose file (three replicas, Redis, nginx with TLS from docker/compose.tls.yml and a
#     CA made here) run unchanged by podman-compose on its own podman network (netavark, with
#     names resolved by aardvark-dns), nginx's doors published on free loopback ports
#     (HDEFORM_LB_GRPC_PORT, HDEFORM_LB_HTTP_PORT). Not host networking: podman-compose 1.0.3
#     adds its project network to every container even with `network_mode: host`, which
#     podman refuses ("cannot set multiple networks without bridge network mode");
#  4. from the host, through nginx: the viewer page and /healthz over HTTPS, a CLI job over
#     gRPC+TLS, a Python drag; `podman kill` of the replica holding the session, and the drag
#     goes on with the same id, pose and version; `podman-compose down` + `up`, and the
#     session is still there (Redis's volume).
# Every step asserts; a missing tool fails (install-deps.sh installs them). Prints sizes and
# times (docs/deployment.md quotes them).
set -uo pipefail
CLI=${1:?usage: container-test.sh HDEFORM_CLI PYTHON PYTHONPATH}
PY=${2:?}
PYPATH=${3:?}
ROOT=$(cd "$(dirname "$0")/.." && pwd)
PROJECT=hdeform-ct

fail() {
  echo "FAIL: $*" >&2
  if [ -n "${COMPOSE_UP:-}" ]; then
    for c in $(podman ps -a --filter "label=io.podman.compose.project=$PROJECT" --format '{{.Names}}'); do
      echo "--- podman logs $c (last 20 lines)" >&2
      podman logs --tail 20 "$c" >&2 2>&1
    done
  fi
  exit 1
}
for tool in podman runc debootstrap podman-compose curl openssl "$CLI" "$PY"; do
  command -v "$tool" >/dev/null 2>&1 || [ -x "$tool" ] \
    || fail "$tool is missing (scripts/install-deps.sh installs podman, runc, debootstrap, podman-compose)"
done
[ "$(id -u)" = 0 ] || fail "podman runs here as root (rootful storage, host networking): run as root"

WORK=$(mktemp -d "${TMPDIR:-/tmp}/hdeform-containers.XXXXXX")
# podman's own settings for this run: runc (crun cannot use this kernel's hybrid cgroups) and
# ulimits the kernel grants (podman's defaults are refused); netavark, whose aardvark-dns
# resolves the compose services' names (a podman that first ran without netavark would
# otherwise stay on CNI, which resolves none).
cat >"$WORK/containers.conf" <<'CONF'
[containers]
default_ulimits = ["nofile=1024:1024", "nproc=1024:1024"]
[engine]
runtime = "runc"
[network]
network_backend = "netavark"
CONF
export CONTAINERS_CONF=$WORK/containers.conf

compose() {
  (cd "$ROOT/docker" && HDEFORM_TLS_DIR=$WORK/tls podman-compose -p "$PROJECT" \
     -f docker-compose.yml -f compose.tls.yml "$@") \
    >>"$WORK/compose.log" 2>&1
}
cleanup() {
  if [ -n "${COMPOSE_UP:-}" ]; then
    compose down -v || true
    podman volume rm -f "${PROJECT}_redis-data" >/dev/null 2>&1 || true
  fi
  rm -rf "$WORK"
}
trap cleanup EXIT
now() { date +%s.%N; }
since() { awk -v a="$1" -v b="$(now)" 'BEGIN { printf "%.1f", b - a }'; }

# --- 1. the base image: Debian 12 from Debian's archive (what `FROM debian:bookworm` names)
if podman image exists docker.io/library/debian:bookworm \
   && podman image exists docker.io/library/debian:bookworm-slim; then
  echo "base: debian:bookworm present (made by an earlier run: debootstrap + podman import)"
else
  t=$(now)
  debootstrap --variant=minbase bookworm "$WORK/rootfs" http://deb.debian.org/debian \
    >"$WORK/debootstrap.log" 2>&1 || { tail -20 "$WORK/debootstrap.log"; fail "debootstrap"; }
  # the official image's sources: the release, its updates and security
  cat >"$WORK/rootfs/etc/apt/sources.list" <<'SRC'
deb http://deb.debian.org/debian bookworm main
deb http://deb.debian.org/debian bookworm-updates main
deb http://deb.debian.org/debian-security bookworm-security main
SRC
  rm -rf "$WORK/rootfs/var/cache/apt/archives/"*.deb "$WORK/rootfs/var/lib/apt/lists/"*
  tar -C "$WORK/rootfs" -c . | podman import - docker.io/library/debian:bookworm >/dev/null \
    || fail "podman import of the base image"
  # -slim as Debian's own: no documentation, manual pages or translations, now or later
  cat >"$WORK/rootfs/etc/dpkg/dpkg.cfg.d/docker-slim" <<'SLIM'
path-exclude /usr/share/doc/*
path-include /usr/share/doc/*/copyright
path-exclude /usr/share/man/*
path-exclude /usr/share/info/*
path-exclude /usr/share/locale/*
path-exclude /usr/share/groff/*
path-exclude /usr/share/linda/*
path-exclude /usr/share/lintian/*
SLIM
  find "$WORK/rootfs/usr/share/doc" -mindepth 2 ! -name copyright ! -type d -delete
  rm -rf "$WORK/rootfs/usr/share/"{man,info,locale,groff,linda,lintian}/*
  tar -C "$WORK/rootfs" -c . | podman import - docker.io/library/debian:bookworm-slim >/dev/null \
    || fail "podman import of the slim base image"
  rm -rf "$WORK/rootfs"
  echo "base: debian:bookworm made by debootstrap in $(since "$t") s"
fi

# --- 2. the images, from docker/Dockerfile
build_args=(--pull=never --format docker --network host --build-arg BUILD_JOBS="$(nproc)")
# Behind a TLS-inspecting proxy npm needs the host's CA bundle (the web stage names it).
if [ -f /etc/ssl/certs/ca-certificates.crt ]; then
  build_args+=(-v /etc/ssl/certs/ca-certificates.crt:/run/extra-ca.crt:ro
               --build-arg NODE_EXTRA_CA_CERTS=/run/extra-ca.crt)
fi
# The host's compile cache (CMakeLists.txt, HDEFORM_CCACHE), lent to the build stage: the
# objects this checkout's build/ compiled are reused, not compiled again. A miss only costs time.
ccache_hits() { ccache --print-stats | awk '$1 ~ /^(direct|preprocessed)_cache_hit$/ { h += $2 } $1 == "cache_miss" { m = $2 } END { print h + 0, m + 0 }'; }
cache_dir=
if command -v ccache >/dev/null 2>&1 && cache_dir=$(ccache -k cache_dir) && mkdir -p "$cache_dir"; then
  build_args+=(-v "$cache_dir:/ccache" --build-arg CCACHE_DIR=/ccache)
  read -r hits0 misses0 < <(ccache_hits)
fi
for target in server lb redis; do
  t=$(now)
  podman build "${build_args[@]}" -f "$ROOT/docker/Dockerfile" --target "$target" \
    -t "hdeform-$target:latest" "$ROOT" >"$WORK/build-$target.log" 2>&1 \
    || { tail -40 "$WORK/build-$target.log"; fail "podman build --target $target"; }
  size=$(podman image inspect --format '{{.Size}}' "hdeform-$target:latest")
  echo "image hdeform-$target: built in $(since "$t") s, $((size / 1000000)) MB"
done
if [ -n "$cache_dir" ]; then
  read -r hits misses < <(ccache_hits)
  echo "images: the C++ build took $((hits - hits0)) objects from the host's ccache, compiled $((misses - misses0))"
fi

# --- 3. the cluster: the compose file as it is, plus the TLS override, on a podman network
# of its own; only nginx's two doors are published, on free loopback ports.
free_port() {
  "$PY" -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}
LBG=$(free_port); LBH=$(free_port)
export HDEFORM_LB_GRPC_PORT=$LBG HDEFORM_LB_HTTP_PORT=$LBH

# A CA of this run and the lb's certificate for 127.0.0.1 and localhost (compose.tls.yml).
mkdir -p "$WORK/tls"
openssl req -x509 -newkey rsa:2048 -nodes -days 1 -subj "/CN=hdeform test CA" \
  -keyout "$WORK/ca.key" -out "$WORK/ca.pem" 2>/dev/null || fail "openssl: CA"
openssl req -newkey rsa:2048 -nodes -subj "/CN=localhost" -keyout "$WORK/tls/key.pem" \
  -out "$WORK/lb.csr" 2>/dev/null || fail "openssl: request"
printf 'subjectAltName=DNS:localhost,IP:127.0.0.1\n' >"$WORK/san.ext"
openssl x509 -req -in "$WORK/lb.csr" -CA "$WORK/ca.pem" -CAkey "$WORK/ca.key" \
  -CAcreateserial -days 1 -extfile "$WORK/san.ext" -out "$WORK/tls/cert.pem" 2>/dev/null \
  || fail "openssl: certificate"
chmod 644 "$WORK/tls/"*.pem
CA=$WORK/ca.pem

# Up, and ready when the viewer's door answers /healthz through nginx.
up() {
  local t
  t=$(now)
  COMPOSE_UP=1
  compose up -d || { tail -30 "$WORK/compose.log"; fail "podman-compose up"; }
  for _ in $(seq 1 120); do
    if curl -sf --cacert "$CA" "https://127.0.0.1:$LBH/healthz" >/dev/null 2>&1 \
       && "$CLI" --server "127.0.0.1:$LBG" --tls-ca "$CA" meshes >/dev/null 2>&1; then
      echo "cluster up: ready through nginx in $(since "$t") s"
      return 0
    fi
    sleep 0.5
  done
  fail "the cluster did not become ready through nginx within 60 s"
}
podman ps -a --filter "label=io.podman.compose.project=$PROJECT" -q | xargs -r podman rm -f >/dev/null
podman volume rm -f "${PROJECT}_redis-data" >/dev/null 2>&1
up

# --- 4. through nginx, from the host
page=$(curl -sf --cacert "$CA" "https://127.0.0.1:$LBH/") || fail "GET / through nginx"
grep -q "<title>hdeform" <<<"$page" || fail "GET / is not the viewer page"
[ "$(curl -sf --cacert "$CA" "https://127.0.0.1:$LBH/healthz")" = ok ] || fail "/healthz"
# nginx answers plain HTTP on its TLS port with 400 only
curl -sf -o /dev/null "http://127.0.0.1:$LBH/healthz" \
  && fail "the browser door served plain HTTP (TLS only expected)"
echo "ok: the viewer page and /healthz through nginx over HTTPS (plain HTTP refused)"

"$CLI" --server "127.0.0.1:$LBG" --tls-ca "$CA" deform cactus \
  --sel "$ROOT/data/botsch-sorkine/cactus.sel" --def "$ROOT/data/botsch-sorkine/cactus.def" \
  -o "$WORK/cactus.glb" >"$WORK/cli.log" 2>&1 || { cat "$WORK/cli.log"; fail "CLI job"; }
[ "$(head -c 4 "$WORK/cactus.glb")" = glTF ] || fail "the CLI job wrote no GLB"
echo "ok: CLI job (deform cactus) through nginx over gRPC+TLS: $(stat -c %s "$WORK/cactus.glb") bytes"

drag() { PYTHONPATH=$PYPATH "$PY" "$ROOT/tests/containers/drag_session.py" "$@"; }
drag start "127.0.0.1:$LBG" "$CA" "$WORK/drag.json" "$ROOT/data" || fail "Python drag (start)"
ID=$("$PY" -c 'import json,sys; print(json.load(open(sys.argv[1]))["name"].split("/")[1])' "$WORK/drag.json")
holder=""
# podman's log of a container lags its output: look again for up to 10 s.
for _ in $(seq 1 20); do
  for i in 1 2 3; do
    podman logs "${PROJECT}_hdeform-${i}_1" 2>&1 | grep -q "sessions/$ID: created" && holder=$i
  done
  [ -n "$holder" ] && break
  sleep 0.5
done
[ -n "$holder" ] || fail "no replica logged the creation of sessions/$ID"
podman kill "${PROJECT}_hdeform-${holder}_1" >/dev/null || fail "podman kill"
echo "killed replica hdeform-$holder, which held sessions/$ID"
drag resume "127.0.0.1:$LBG" "$CA" "$WORK/drag.json" || fail "Python drag (resume after the kill)"
# (podman may have restarted the killed replica meanwhile: restart: unless-stopped)
grep -q "sessions/$ID: restored from redis" \
  <(for i in 1 2 3; do podman logs "${PROJECT}_hdeform-${i}_1" 2>&1; done) \
  || fail "no replica restored sessions/$ID from Redis after the kill"

t=$(now)
compose down || fail "podman-compose down"
echo "cluster down in $(since "$t") s (volumes kept)"
up
drag check "127.0.0.1:$LBG" "$CA" "$WORK/drag.json" || fail "the session did not survive down + up"
# --- 5. the server image alone: SQLite state in its volume outlives the container
compose down -v >/dev/null 2>&1; COMPOSE_UP=""
SOLO=$(free_port)
solo() {
  podman run -d --name hdeform-ct-solo -p "127.0.0.1:$SOLO:50051" \
    -v hdeform-ct-state:/var/lib/hdeform/data hdeform-server:latest >/dev/null \
    || fail "podman run of the server image"
  for _ in $(seq 1 60); do
    "$CLI" --server "127.0.0.1:$SOLO" meshes >/dev/null 2>&1 && return 0
    sleep 0.5
  done
  podman logs hdeform-ct-solo >&2; fail "the server image alone did not answer"
}
solo_cleanup() { podman rm -f hdeform-ct-solo >/dev/null 2>&1; podman volume rm -f hdeform-ct-state >/dev/null 2>&1; }
solo_cleanup
solo
drag start "127.0.0.1:$SOLO" - "$WORK/solo.json" "$ROOT/data" || { solo_cleanup; fail "drag on the server image alone"; }
podman rm -f hdeform-ct-solo >/dev/null
solo
drag check "127.0.0.1:$SOLO" - "$WORK/solo.json" \
  || { solo_cleanup; fail "the session did not survive podman rm + run on the same volume"; }
solo_cleanup
echo "ok: the server image alone keeps its sessions in its volume across podman rm + run"
echo "PASS: images built; cluster served the viewer, a CLI job and a Python drag through nginx with TLS; the drag survived the kill of its replica; the session survived down + up"
