#!/usr/bin/env bash
# Build meso (release) and render the paper's figures from built-in data into out/figures.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release -p meso-cli
./target/release/meso figures --out "${1:-out/figures}"
