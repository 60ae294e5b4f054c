#!/usr/bin/env bash
# The whole test suite, as CI runs it: formatting, lints, the API docs, every crate's tests, and the browser
# end-to-end tests of the editor (installs Debian's chromium and npm's playwright-core when missing), and the
# independent checks of `meso export` (npm ktx-parse and gltf-validator, tests/export), and the Python
# package's pytest suite (a venv in target/venv with maturin, numpy, pytest, mitsuba, dask).
set -euo pipefail
cd "$(dirname "$0")/.."
# No incremental-compilation state: a clean checkout gains nothing from it, and it doubled the
# disk that the debug build takes (CI's disk ran out). Opt back in with CARGO_INCREMENTAL=1.
export CARGO_INCREMENTAL="${CARGO_INCREMENTAL:-0}"

echo "== cargo fmt --check"
cargo fmt --all -- --check

echo "== cargo clippy (all targets, -D warnings)"
cargo clippy --workspace --all-targets -- -D warnings

echo "== cargo doc (public docs build without warnings: no broken or private links)"
RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps --quiet

echo "== cargo test (workspace)"
mkdir -p target   # the logs below live here even when CARGO_TARGET_DIR points elsewhere
# Height-map facet caches (crates/meso-maps/src/facet_cache.rs) of the tests live here, fresh each
# run, not in the user's ~/.cache.
export MESO_CACHE_DIR="$PWD/target/test-cache"
rm -rf "$MESO_CACHE_DIR"
# A failing crate does not stop the script: the other suites still run and the closing line counts
# every failure (the script's status is non-zero all the same).
cargo_status=0
cargo test --workspace --no-fail-fast 2>&1 | tee target/test-output.txt || cargo_status=1

e2e_status=0
: > target/e2e-output.txt
if [ -f tests/e2e/package.json ]; then
  echo "== browser end-to-end tests"
  bash tests/e2e/run.sh 2>&1 | tee target/e2e-output.txt || e2e_status=1
fi

export_status=0
: > target/export-output.txt
if [ -f tests/export/package.json ]; then
  echo "== export checks (ktx-parse, gltf-validator)"
  bash tests/export/run.sh 2>&1 | tee target/export-output.txt || export_status=1
fi

engine_status=0
: > target/engine-output.txt
if [ -f tests/engine/package.json ]; then
  echo "== export in a real engine (three.js in headless Chromium vs meso's reference)"
  bash tests/engine/run.sh 2>&1 | tee target/engine-output.txt || engine_status=1
fi

python_status=0
: > target/python-output.txt
if [ -f crates/meso-py/tests/run.sh ]; then
  echo "== Python package (maturin, pytest, Mitsuba 3, Dask)"
  bash crates/meso-py/tests/run.sh 2>&1 | tee target/python-output.txt || python_status=1
fi

# One closing line for humans and CI: cargo's per-binary results plus the browser tests.
awk '/^test result:/ { for (i = 1; i <= NF; i++) { if ($i ~ /^passed;?$/) p += $(i-1); if ($i ~ /^failed;?$/) f += $(i-1) } }
     /^e2e: [0-9]+ passed, [0-9]+ failed/ { p += $2; f += $4 }
     END { printf "tests: %d passed, %d failed\n", p, f; exit (f > 0) }' target/test-output.txt target/e2e-output.txt target/export-output.txt target/engine-output.txt target/python-output.txt
[ $cargo_status = 0 ] && [ $e2e_status = 0 ] && [ $export_status = 0 ] && [ $engine_status = 0 ] && [ $python_status = 0 ]
