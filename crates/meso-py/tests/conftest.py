"""Shared fixtures of the meso Python tests: the CLI binary to compare with, and image writers
(16-bit grey and 8-bit RGB PNG with the standard library's zlib, so the tests need no imaging
package)."""

from __future__ import annotations

import os
import pathlib
import struct
import subprocess
import zlib

import numpy as np
import pytest

REPO = pathlib.Path(__file__).resolve().parents[3]


def meso_bin() -> pathlib.Path:
    """The `meso` CLI: $MESO_BIN, else the release build, else the test-profile build."""
    env = os.environ.get("MESO_BIN")
    if env:
        return pathlib.Path(env)
    for p in (REPO / "target/release/meso", REPO / "target/debug/meso"):
        if p.exists():
            return p
    pytest.skip("the meso CLI is not built (cargo build --release -p meso-cli)")


def run_cli(*args: object) -> subprocess.CompletedProcess:
    """Run the CLI; a failure shows its stderr."""
    r = subprocess.run(
        [str(meso_bin()), *map(str, args)], capture_output=True, text=True, timeout=600
    )
    assert r.returncode == 0, f"meso {' '.join(map(str, args))} failed:\n{r.stderr}"
    return r


def _png(path: pathlib.Path, width: int, height: int, bit_depth: int, colour: int, rows: bytes) -> None:
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    header = struct.pack(">IIBBBBB", width, height, bit_depth, colour, 0, 0, 0)
    path.write_bytes(
        b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b"")
    )


def write_gray16(path: pathlib.Path, codes: np.ndarray) -> None:
    """A 16-bit grey PNG of integer codes (rows, cols), row 0 at the top."""
    codes = np.asarray(codes, dtype=">u2")
    h, w = codes.shape
    rows = b"".join(b"\x00" + codes[r].tobytes() for r in range(h))
    _png(path, w, h, 16, 0, rows)


def write_rgb8(path: pathlib.Path, rgb: np.ndarray) -> None:
    """An 8-bit RGB PNG of (rows, cols, 3) codes, row 0 at the top."""
    rgb = np.asarray(rgb, dtype=np.uint8)
    h, w, _ = rgb.shape
    rows = b"".join(b"\x00" + rgb[r].tobytes() for r in range(h))
    _png(path, w, h, 8, 2, rows)


def bumps(n: int = 32, seed: int = 1) -> np.ndarray:
    """A periodic random bump field, 16-bit codes: a sum of a few sines with random phases."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:n, 0:n] / n
    h = np.zeros((n, n))
    for _ in range(6):
        kx, ky = rng.integers(1, 4, size=2)
        h += np.sin(2 * np.pi * (kx * x + ky * y) + rng.uniform(0, 2 * np.pi))
    h = (h - h.min()) / (h.max() - h.min())
    return np.round(h * 65535).astype(np.uint16)


def directions_deg(theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Unit vectors from polar angle θ (from +z) and azimuth φ (from +x towards +y), degrees —
    meso_core::frame::spherical_direction_deg."""
    t, p = np.radians(theta), np.radians(phi)
    return np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=1)
