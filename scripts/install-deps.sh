#!/usr/bin/env bash
# Installs the Debian 12 packages hdeform needs. Idempotent: apt-get skips what is already
# installed. Run as root.
#   install-deps.sh          everything: build, tests, benchmarks, viewer, containers (CI)
#   install-deps.sh build    only what `cmake --build` of hdeform-server and hdeform needs
#                            (docker/Dockerfile's build stage)
#   install-deps.sh web      only what the viewer's `npm ci && npm run build` needs
#                            (docker/Dockerfile's web stage)
set -euo pipefail

build=(
  build-essential cmake pkg-config
  # a compile cache (CMakeLists.txt; the container suite lends the host's to the image build)
  ccache
  # engine
  libeigen3-dev libsuitesparse-dev libmetis-dev libopenblas0-pthread libblas-dev liblapack-dev
  libtinygltf-dev libstb-dev
  # service and clients
  libgrpc++-dev protobuf-compiler-grpc libprotobuf-dev protobuf-compiler libssl-dev
  libspdlog-dev libcli11-dev libboost-dev nlohmann-json3-dev
  # compact frame encodings (FrameEncoding MESHOPT)
  libmeshoptimizer-dev
  # durable state: SQLite (embedded default), Redis (replicas)
  libsqlite3-dev libhiredis-dev
)
# The viewer: protoc for its generated stubs; Node.js and npm unless the machine has its own
# (this machine image ships Node.js 20 with npm, which Debian's npm conflicts with).
web=(protobuf-compiler)
command -v npm >/dev/null 2>&1 || web+=(nodejs npm)
tests=(
  # sanitizer builds (scripts/sanitize.sh, scripts/tsan.sh): clang with its runtimes, OpenMP
  clang libclang-rt-14-dev libomp-dev
  # tests and benchmarks
  libgtest-dev libgmock-dev libbenchmark-dev
  # real peers: Redis (state), nginx (routing), curl (plays the browser), Chromium (viewer)
  redis-server nginx-light curl chromium python3
  # test certificates (TLS tests)
  openssl
  # the Python client (client-python/: stubs from grpc_python_plugin, tests with pytest)
  python3-grpcio python3-protobuf python3-numpy python3-pytest
  # its documented pip install (CTest python_pip_install): venv with pip and setuptools, and
  # wheel for pip's bdist_wheel (without it: "invalid command 'bdist_wheel'")
  python3-venv python3-wheel
  # its type check (CTest python_mypy: mypy --strict), and its optional extras the tests
  # exercise: SweepResult.plot / Frame.plot_measures (matplotlib), from_meshio / to_meshio
  mypy python3-matplotlib python3-meshio
  # the container suite (scripts/container-test.sh): podman with runc, a base image made by
  # debootstrap, the compose file run by podman-compose; netavark and aardvark-dns so the
  # containers find each other by name (podman's CNI fallback has no DNS: "redis" and
  # "hdeform-1" did not resolve on a machine without them); iptables, which netavark runs to
  # set up a network (without it every container stays "Created": "netavark: No such file
  # or directory")
  podman buildah runc debootstrap podman-compose netavark aardvark-dns iptables
)

case "${1:-all}" in
  build) packages=("${build[@]}") ;;
  web) packages=("${web[@]}") ;;
  all) packages=("${build[@]}" "${web[@]}" "${tests[@]}") ;;
  *) echo "usage: install-deps.sh [build|web|all]" >&2; exit 2 ;;
esac

# The kernel's userspace headers come with the machine, often older than the mirror's, which
# the image's build stage gets: one differing <linux/version.h> made all 46 service, gateway and
# CLI objects miss the host's ccache in the image build (measured). When apt runs, take the mirror's.
track_mirror=()
[ "${1:-all}" = web ] || track_mirror=(linux-libc-dev)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

if [ ${#missing[@]} -gt 0 ]; then
  if [ "$(id -u)" != 0 ]; then
    echo "install-deps: missing packages (${missing[*]}); run as root" >&2
    exit 1
  fi
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends "${missing[@]}" "${track_mirror[@]}"
fi
echo "install-deps: all packages present (${1:-all})"
