"""meso.fit_nonparametric: the non-parametric NDF of a MERL table written from a known material,
the same file as `meso fit --nonparametric`, clean errors."""

from __future__ import annotations

import re

import numpy as np
import pytest

import meso
from conftest import run_cli

SCALES = np.array([1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0])


def _rot_y(v: np.ndarray, a: np.ndarray) -> np.ndarray:
    s, c = np.sin(a), np.cos(a)
    return np.stack([v[..., 0] * c + v[..., 2] * s, v[..., 1], -v[..., 0] * s + v[..., 2] * c], -1)


def write_merl(path, material: meso.Material) -> None:
    """A MERL binary of `material`: cells at their lower bin edges (φh = 0), as meso reads them
    (meso_measured::rusinkiewicz::dirs_from_half_diff), cells below the horizon marked -1."""
    ih, id_, ip = np.meshgrid(np.arange(90), np.arange(90), np.arange(180), indexing="ij")
    th = (ih / 90.0) ** 2 * (np.pi / 2)
    td = id_ / 90.0 * (np.pi / 2)
    pd = ip / 180.0 * np.pi
    d = np.stack([np.sin(td) * np.cos(pd), np.sin(td) * np.sin(pd), np.cos(td)], -1)
    dm = d * np.array([-1.0, -1.0, 1.0])
    wi = _rot_y(d, th).reshape(-1, 3)
    wo = _rot_y(dm, th).reshape(-1, 3)
    f = material.brdf(wi, wo)
    below = (wi[:, 2] <= 0) | (wo[:, 2] <= 0)
    vals = f / SCALES
    vals[below] = -1.0
    with open(path, "wb") as fh:
        fh.write(np.array([90, 90, 180], dtype="<i4").tobytes())
        fh.write(np.ascontiguousarray(vals.T).astype("<f8").tobytes())


@pytest.fixture(scope="module")
def merl(tmp_path_factory: pytest.TempPathFactory):
    truth = meso.Material.from_params(
        form="microfacet",
        ndf={"kind": "ggx", "alpha": 0.15},
        transfer={"kind": "mirror", "fresnel": "schlick", "f0": [0.9, 0.6, 0.3]},
        diffuse=[0.05, 0.1, 0.2],
    )
    path = tmp_path_factory.mktemp("np") / "ggx.binary"
    write_merl(path, truth)
    return path, truth


def test_recovers_the_material_and_equals_the_cli(merl, tmp_path):
    path, truth = merl
    m, report = meso.fit_nonparametric(path, out=tmp_path / "py.toml")
    assert m.ndf.kind == "radial"
    assert np.allclose(report["f0"], [0.9, 0.6, 0.3], rtol=0.03)
    assert np.allclose(report["albedo"], [0.05, 0.1, 0.2], rtol=0.02)
    assert max(report["held_out"]["low_log"]) < 1e-3
    # The fitted material reproduces the truth at random pairs (θ ≤ 70°).
    rng = np.random.default_rng(3)
    t = np.radians(rng.uniform(0, 70, (2, 500)))
    p = rng.uniform(0, 2 * np.pi, (2, 500))
    wi = np.stack([np.sin(t[0]) * np.cos(p[0]), np.sin(t[0]) * np.sin(p[0]), np.cos(t[0])], 1)
    wo = np.stack([np.sin(t[1]) * np.cos(p[1]), np.sin(t[1]) * np.sin(p[1]), np.cos(t[1])], 1)
    a, b = m.brdf(wi, wo), truth.brdf(wi, wo)
    rel = np.sqrt(np.mean((np.log1p(a * wi[:, 2:]) - np.log1p(b * wi[:, 2:])) ** 2))
    assert rel < 2e-3, rel
    # The CLI writes the same file (up to the data path in its comment).
    run_cli("fit", str(path), "--nonparametric", "--out", str(tmp_path / "cli.toml"))
    strip = lambda s: re.sub(r"^#.*\n", "", s, flags=re.M)  # noqa: E731
    assert strip((tmp_path / "cli.toml").read_text()) == strip((tmp_path / "py.toml").read_text())


def test_bad_inputs_raise(tmp_path):
    with pytest.raises(FileNotFoundError):
        meso.fit_nonparametric(tmp_path / "missing.binary")
    csv = tmp_path / "s.csv"
    csv.write_text("theta_i,phi_i,theta_o,phi_o,r,g,b\n" + "10,0,20,180,0.1,0.1,0.1\n" * 300)
    with pytest.raises(meso.MesoError, match="needs a MERL table"):
        meso.fit_nonparametric(csv)
