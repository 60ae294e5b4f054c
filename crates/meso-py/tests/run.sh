#!/usr/bin/env bash
# The Python package's tests: a venv in target/venv with maturin, numpy, pytest, mitsuba and
# dask[distributed] from PyPI (versions in requirements-test.txt), the extension built into it by
# `maturin develop --release`, the meso CLI built for the comparisons, then pytest on tests/.
# Last line: `e2e: N passed, M failed` (summed by scripts/test.sh).
set -uo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
crate="$(cd "$here/.." && pwd)"
root="$(cd "$crate/../.." && pwd)"
target="${CARGO_TARGET_DIR:-$root/target}"
case "$target" in /*) ;; *) target="$root/$target" ;; esac
venv="$root/target/venv"
mkdir -p "$root/target/python"

fail() {
  echo "python: setup failed: $*" >&2
  echo "e2e: 0 passed, 1 failed"
  exit 1
}

# shellcheck source=../../../scripts/lib/setup.sh
. "$root/scripts/lib/setup.sh"
ensure_venv "$venv" || fail "python3 -m venv (Debian: python3-venv)"
"$venv/bin/pip" install --quiet --disable-pip-version-check -r "$here/requirements-test.txt" \
  || fail "pip install -r crates/meso-py/tests/requirements-test.txt"
if [ -f "$here/setup-system.sh" ]; then
  bash "$here/setup-system.sh" || fail "crates/meso-py/tests/setup-system.sh"
fi

(cd "$root" && cargo build --release -p meso-cli) || fail "cargo build --release -p meso-cli"
export MESO_BIN="${MESO_BIN:-$target/release/meso}"
(cd "$crate" && VIRTUAL_ENV="$venv" PATH="$venv/bin:$PATH" maturin develop --release --quiet) \
  || fail "maturin develop --release"

export MESO_CACHE_DIR="${MESO_CACHE_DIR:-$root/target/test-cache}"
xml="$root/target/python/pytest.xml"
(cd "$crate" && "$venv/bin/python" -m pytest tests -q -rfE --durations=10 --junitxml="$xml")
status=$?
read -r passed failed < <("$venv/bin/python" - "$xml" <<'PY'
import sys, xml.etree.ElementTree as ET
try:
    root = ET.parse(sys.argv[1]).getroot()
except Exception:
    print(0, 1)
    raise SystemExit
suites = [root] if root.tag == "testsuite" else list(root)
t = sum(int(s.get("tests", 0)) for s in suites)
f = sum(int(s.get("failures", 0)) + int(s.get("errors", 0)) for s in suites)
sk = sum(int(s.get("skipped", 0)) for s in suites)
print(t - f - sk, f)
PY
)
if [ "$status" != "0" ] && [ "$failed" = "0" ]; then failed=1; fi
echo "e2e: ${passed} passed, ${failed} failed"
[ "$status" = "0" ] && [ "$failed" = "0" ]
