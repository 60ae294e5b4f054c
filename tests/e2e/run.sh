#!/usr/bin/env bash
# Browser tests of `meso serve`: installs what is missing (Debian's chromium, playwright-core),
# builds the meso binary, runs editor.test.mjs with node's test runner. Screenshots and the
# saved TOML land in tests/e2e/artifacts/. Last line: `e2e: N passed, M failed`.
set -uo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/../.." && pwd)"
cd "$here"
mkdir -p artifacts

fail() {
  echo "e2e: setup failed: $*" >&2
  echo "e2e: 0 passed, 1 failed"
  exit 1
}

if [ ! -x /usr/bin/chromium ]; then
  sudo_cmd=""
  if [ "$(id -u)" != "0" ] && command -v sudo >/dev/null 2>&1; then sudo_cmd="sudo"; fi
  echo "e2e: installing chromium (apt-get)" >&2
  $sudo_cmd apt-get update && DEBIAN_FRONTEND=noninteractive $sudo_cmd apt-get install -y chromium \
    || fail "cannot install chromium"
fi

if [ ! -d node_modules/playwright-core ]; then
  npm ci --no-audit --no-fund || npm install --no-audit --no-fund || fail "npm install"
fi

(cd "$root" && cargo build -p meso-cli) || fail "cargo build -p meso-cli"
target="${CARGO_TARGET_DIR:-$root/target}"
case "$target" in /*) ;; *) target="$root/$target" ;; esac
export MESO_BIN="${MESO_BIN:-$target/debug/meso}"

node --test --test-concurrency=1 --test-reporter=tap editor.test.mjs 2>&1 | tee artifacts/tap.txt
status=${PIPESTATUS[0]}
passed=$(grep -E '^# pass ' artifacts/tap.txt | tail -1 | awk '{print $3}')
failed=$(grep -E '^# fail ' artifacts/tap.txt | tail -1 | awk '{print $3}')
passed=${passed:-0}
failed=${failed:-0}
if [ "$status" != "0" ] && [ "$failed" = "0" ]; then failed=1; fi
echo "e2e: ${passed} passed, ${failed} failed"
[ "$status" = "0" ] && [ "$failed" = "0" ]
