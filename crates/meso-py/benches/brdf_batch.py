"""`python crates/meso-py/benches/brdf_batch.py [N]` — `Material.brdf` on N random direction
pairs (default 10⁶) from Python, best of 5 wall times: the Python side of the overhead benchmark in
docs/benchmarks.md (the Rust side: `cargo run --release -p meso-cli --example brdf_batch`, the
same material)."""

import sys
import time

import numpy as np

import meso

MATERIAL = """form = "microfacet"
[ndf]
kind = "ggx"
alpha = 0.1
[transfer]
kind = "mirror"
fresnel = "schlick"
f0 = [0.04, 0.04, 0.04]
[diffuse]
albedo = [0.5, 0.4, 0.3]
"""


def splitmix(n, seed=1):
    """The Rust example's SplitMix64 stream (crates/meso-cli/examples/brdf_batch.rs), so both sides
    evaluate the same pairs (their checksums agree)."""
    with np.errstate(over="ignore"):
        z = np.uint64(seed) + np.arange(1, n + 1, dtype=np.uint64) * np.uint64(0x9E3779B97F4A7C15)
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        z = z ^ (z >> np.uint64(31))
    return z.astype(np.float64) / 18446744073709551616.0


def hemisphere(u, v):
    z = u
    s = np.sqrt(np.maximum(0.0, 1 - z * z))
    phi = 2 * np.pi * v
    return np.column_stack([s * np.cos(phi), s * np.sin(phi), z])


def main():
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 1_000_000
    m = meso.Material.from_toml(MATERIAL)
    u = splitmix(4 * n).reshape(n, 4)
    wi, wo = hemisphere(u[:, 0], u[:, 1]), hemisphere(u[:, 2], u[:, 3])
    best = float("inf")
    for _ in range(5):
        t = time.perf_counter()
        f = m.brdf(wi, wo)
        best = min(best, time.perf_counter() - t)
    print(f"python: {n} pairs, best of 5: {best:.3f} s ({best / n * 1e9:.1f} ns/pair); checksum {f[:, 1].sum():.6e}")


if __name__ == "__main__":
    main()
