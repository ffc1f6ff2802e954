#!/usr/bin/env bash
# The committed browser HMI is what its sources and the proto give (issue #30): installs the
# locked npm packages, regenerates the TypeScript of proto/proto/cnc/v1/cnc.proto, type-checks,
# rebuilds dist/ and fails when anything under hmi/ differs from the commit. Installs node and
# npm with apt when missing (building cncd needs neither: dist/ is committed, cargo embeds it).
set -euo pipefail
cd "$(dirname "$0")"
if ! command -v npm >/dev/null; then
  echo "installing nodejs npm"
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq nodejs npm >/dev/null
fi
npm ci --no-audit --no-fund --loglevel=error
npm run --silent generate
npm run --silent typecheck
npm run --silent build
if ! git diff --exit-code --stat -- . || [ -n "$(git status --porcelain --untracked-files=all -- .)" ]; then
  echo "hmi/: the committed files differ from what the sources and cnc.proto give;" >&2
  echo "run hmi/check.sh and commit hmi/ (src/gen and dist/)" >&2
  git status --short -- . >&2
  exit 1
fi
echo "hmi/: generated code and dist/ match their sources"
