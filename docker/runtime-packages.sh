#!/usr/bin/env bash
# Prints the Debian packages that provide the shared libraries the given binaries load
# (one per line, sorted) — the runtime stage of docker/Dockerfile installs exactly these.
# Usage: docker/runtime-packages.sh BINARY…
set -euo pipefail
mapfile -t libs < <(for bin in "$@"; do
  ldd "$bin" | awk '/=> \// { print $3 } /^\t\/lib/ { print $1 }'
done | sort -u)

# Each library under its spellings: as loaded, resolved (alternatives, symlinks), and with
# the /lib ↔ /usr/lib prefix swapped (merged /usr).
candidates() {
  local f=$1 r
  r=$(readlink -f "$f")
  printf '%s\n' "$f" "$r" "/usr$f" "${f#/usr}" "/usr$r" "${r#/usr}"
}
declare -A owner
while IFS= read -r line; do
  owner["${line#*: }"]=${line%%:*}
done < <(for f in "${libs[@]}"; do candidates "$f"; done | sort -u | xargs dpkg -S 2>/dev/null || true)

for f in "${libs[@]}"; do
  pkg=""
  while IFS= read -r c; do
    if [ -n "${owner[$c]:-}" ]; then pkg=${owner[$c]}; break; fi
  done < <(candidates "$f")
  if [ -z "$pkg" ]; then
    echo "runtime-packages: no package owns $f" >&2
    exit 1
  else
    echo "$pkg"
  fi
done | sort -u  # pipefail: a library without a package fails the script
