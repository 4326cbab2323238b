#!/usr/bin/env sh
# Installs the viewer's npm packages (npm ci, from package-lock.json; skipped when
# node_modules is already current) and builds web-viewer/dist (protoc stubs + vite), the
# production page, which has no test hook. With a second argument, also the browser tests'
# build (vite --mode test: the page with window.hdeform) into that folder.
set -eu
cd "$1"
if [ ! -f node_modules/.package-lock.json ] || [ package-lock.json -nt node_modules/.package-lock.json ]; then
  npm ci --no-audit --no-fund
fi
npm run build
if [ $# -ge 2 ]; then
  # Stubs and type check are done: vite only.
  npm exec --no -- vite build --mode test --outDir "$2" --emptyOutDir
fi
