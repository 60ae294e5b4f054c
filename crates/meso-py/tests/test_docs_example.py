"""The tour in docs/examples/python_tour.py runs as published."""

import subprocess
import sys

from conftest import REPO


def test_the_python_tour_runs(tmp_path):
    r = subprocess.run(
        [sys.executable, str(REPO / "docs/examples/python_tour.py"), str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stderr
    assert "MesoError:" in r.stdout and "ValueError:" in r.stdout
    assert (tmp_path / "waves.map").stat().st_size > 0
