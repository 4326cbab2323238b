#!/usr/bin/env sh
# Installs the viewer's npm packages (npm ci, from package-lock.json; skipped when
# node_modules is already current) and builds web-viewer/dist (protoc stubs + vite).
set -eu
cd "$1"
if [ ! -f node_modules/.package-lock.json ] || [ package-lock.json -nt node_modules/.package-lock.json ]; then
  npm ci --no-audit --no-fund
fi
npm run build
