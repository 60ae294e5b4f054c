#!/usr/bin/env bash
# Build meso (release) and render the paper's figures from built-in data into out/figures.
# (`cargo run` so that a CARGO_TARGET_DIR set by the user is honoured.)
set -euo pipefail
cd "$(dirname "$0")/.."
cargo run --release -p meso-cli --bin meso -- figures --out "${1:-out/figures}"
