#!/usr/bin/env bash
# Independent checks of `meso export`: installs ktx-parse and gltf-validator (npm), builds the
# meso binary (debug; a binary given in $MESO_BIN is used as it is), runs export.test.mjs with
# node's test runner. Inputs and outputs land in tests/export/artifacts/. Last line: `e2e: N
# passed, M failed` (summed by scripts/test.sh).
set -uo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/../.." && pwd)"
cd "$here"
mkdir -p artifacts

fail() {
  echo "export: setup failed: $*" >&2
  echo "e2e: 0 passed, 1 failed"
  exit 1
}
# shellcheck source=../../scripts/lib/setup.sh
. "$root/scripts/lib/setup.sh"
ensure_node || fail "Node.js ≥ 20.10 and npm"

if [ ! -d node_modules/ktx-parse ] || [ ! -d node_modules/gltf-validator ]; then
  npm ci --no-audit --no-fund || npm install --no-audit --no-fund || fail "npm install"
fi

# MESO_BIN set by the caller (e.g. a release build): use that binary, build nothing.
if [ -z "${MESO_BIN:-}" ]; then
  (cd "$root" && cargo build -p meso-cli) || fail "cargo build -p meso-cli"
  target="${CARGO_TARGET_DIR:-$root/target}"
  case "$target" in /*) ;; *) target="$root/$target" ;; esac
  export MESO_BIN="$target/debug/meso"
fi

node --test --test-concurrency=1 --test-reporter=tap export.test.mjs 2>&1 | tee artifacts/tap.txt
status=${PIPESTATUS[0]}
passed=$(grep -E '^# pass ' artifacts/tap.txt | tail -1 | awk '{print $3}')
failed=$(grep -E '^# fail ' artifacts/tap.txt | tail -1 | awk '{print $3}')
passed=${passed:-0}
failed=${failed:-0}
if [ "$status" != "0" ] && [ "$failed" = "0" ]; then failed=1; fi
echo "e2e: ${passed} passed, ${failed} failed"
[ "$status" = "0" ] && [ "$failed" = "0" ]
