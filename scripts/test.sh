#!/usr/bin/env bash
# The whole test suite, as CI runs it: formatting, lints, every crate's tests, and the browser
# end-to-end tests of the editor (installs Debian's chromium and npm's playwright-core when missing).
set -euo pipefail
cd "$(dirname "$0")/.."

echo "== cargo fmt --check"
cargo fmt --all -- --check

echo "== cargo clippy (all targets, -D warnings)"
cargo clippy --workspace --all-targets -- -D warnings

echo "== cargo test (workspace)"
cargo test --workspace --no-fail-fast 2>&1 | tee target/test-output.txt

if [ -f tests/e2e/package.json ]; then
  echo "== browser end-to-end tests"
  bash tests/e2e/run.sh
fi

# One closing line for humans and CI: the sum of cargo's per-binary results.
awk '/^test result:/ { for (i = 1; i <= NF; i++) { if ($i ~ /^passed;?$/) p += $(i-1); if ($i ~ /^failed;?$/) f += $(i-1) } }
     END { printf "cargo tests: %d passed, %d failed\n", p, f; exit (f > 0) }' target/test-output.txt
