#!/usr/bin/env bash
# The committed browser HMI is what its sources and the proto give (issue #30): installs the
# locked npm packages, regenerates the TypeScript of proto/proto/cnc/v1/cnc.proto, type-checks,
# rebuilds dist/ and fails when anything under hmi/ differs from the commit. Needs node and npm
# (building cncd does not: dist/ is committed and embedded by cargo).
set -euo pipefail
cd "$(dirname "$0")"
if ! command -v npm >/dev/null; then
  echo "hmi/check.sh: npm is missing (apt-get install nodejs npm)" >&2
  exit 1
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
