# Shared by the README's commands: install packages (as root), configure and build.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD="${HDEFORM_BUILD_DIR:-$ROOT/build}"
JOBS="${HDEFORM_JOBS:-$(nproc)}"

install_deps() {
  if [ "$(id -u)" = 0 ]; then
    bash "$ROOT/scripts/install-deps.sh"
  elif command -v sudo >/dev/null 2>&1; then
    sudo bash "$ROOT/scripts/install-deps.sh"
  else
    bash "$ROOT/scripts/install-deps.sh"  # reports what is missing
  fi
}

configure() {
  cmake -S "$ROOT" -B "$BUILD" -DCMAKE_BUILD_TYPE=Release "$@" >/dev/null
}

build() {
  cmake --build "$BUILD" -j "$JOBS" "$@"
}
