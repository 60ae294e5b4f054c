#!/usr/bin/env bash
# meso export checked in a real engine: three.js (npm) in headless Debian chromium (playwright-core)
# renders the exported normal + roughness mip chains and the original normal map with standard mips,
# against meso's supersampled bump-mapped render (docs/engine.md). Installs what is missing, builds the
# meso binary (release: the reference renders take 1024 spp), runs engine.test.mjs with node's test
# runner, and lobes.test.mjs (meso-export's GLSL lobe function run in WebGL 2 and its WGSL in
# WebGPU, against the CPU reference), and aniso.test.mjs (`meso export --anisotropic` through GLTFLoader's
# KHR_materials_anisotropy on grooves). Inputs, renders and results.json land in tests/engine/artifacts/; ENGINE_FIGURES=DIR also
# writes the pictures. Last line: `e2e: N passed, M failed` (summed by scripts/test.sh).
set -uo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/../.." && pwd)"
cd "$here"
mkdir -p artifacts

fail() {
  echo "engine: setup failed: $*" >&2
  echo "e2e: 0 passed, 1 failed"
  exit 1
}
# shellcheck source=../../scripts/lib/setup.sh
. "$root/scripts/lib/setup.sh"
ensure_node || fail "Node.js ≥ 20.10 and npm"

ensure_chromium || fail "cannot install chromium"

if [ ! -d node_modules/playwright-core ] || [ ! -d node_modules/three ]; then
  npm ci --no-audit --no-fund || npm install --no-audit --no-fund || fail "npm install"
fi

(cd "$root" && cargo build --release -p meso-cli) || fail "cargo build --release -p meso-cli"
target="${CARGO_TARGET_DIR:-$root/target}"
case "$target" in /*) ;; *) target="$root/$target" ;; esac
export MESO_BIN="${MESO_BIN:-$target/release/meso}"

node --test --test-concurrency=1 --test-reporter=tap engine.test.mjs lobes.test.mjs aniso.test.mjs 2>&1 | tee artifacts/tap.txt
status=${PIPESTATUS[0]}
passed=$(grep -E '^# pass ' artifacts/tap.txt | tail -1 | awk '{print $3}')
failed=$(grep -E '^# fail ' artifacts/tap.txt | tail -1 | awk '{print $3}')
passed=${passed:-0}
failed=${failed:-0}
if [ "$status" != "0" ] && [ "$failed" = "0" ]; then failed=1; fi
echo "e2e: ${passed} passed, ${failed} failed"
[ "$status" = "0" ] && [ "$failed" = "0" ]
