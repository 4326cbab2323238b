#!/usr/bin/env bash
# Installs every Debian 12 package hdeform needs to build, test and run.
# Idempotent: apt-get skips what is already installed. Run as root.
set -euo pipefail

packages=(
  # build
  build-essential cmake pkg-config
  # sanitizer builds (scripts/sanitize.sh): clang with its ASan/UBSan runtime and OpenMP
  clang libclang-rt-14-dev libomp-dev
  # engine
  libeigen3-dev libsuitesparse-dev libopenblas0-pthread libblas-dev liblapack-dev
  libtinygltf-dev libstb-dev
  # service and clients
  libgrpc++-dev protobuf-compiler-grpc libprotobuf-dev protobuf-compiler libssl-dev
  libspdlog-dev libcli11-dev libboost-dev nlohmann-json3-dev
  # compact frame encodings (FrameEncoding MESHOPT)
  libmeshoptimizer-dev
  # durable state: SQLite (embedded default), Redis (replicas)
  libsqlite3-dev libhiredis-dev redis-server
  # tests and benchmarks
  libgtest-dev libgmock-dev libbenchmark-dev
  # routing test (docker/ nginx config; curl plays the browser), browser tests
  nginx-light curl chromium python3
  # test certificates (TLS tests)
  openssl
  # the Python client (client-python/: stubs from grpc_python_plugin, tests with pytest)
  python3-grpcio python3-protobuf python3-numpy python3-pytest
)
# The machine image ships Node.js 20 (with npm); Debian's npm conflicts with it.
command -v npm >/dev/null 2>&1 || packages+=(nodejs npm)

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
  apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
echo "install-deps: all packages present"
