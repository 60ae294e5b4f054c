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
    # The engine parameters (glTF metallic-roughness of the best single GGX + Lambert): in the
    # report, and in both files as the same comment line. The truth's Schlick f0 is red > green >
    # blue, and so is the base colour.
    e = report["engine"]
    assert 0 < e["alpha"] <= 1.5 and 0 <= e["metallic"] <= 1, e
    assert e["base_color"][0] > e["base_color"][1] > e["base_color"][2], e
    line = next(s for s in (tmp_path / "py.toml").read_text().splitlines() if s.startswith("# engine (glTF"))
    assert line in (tmp_path / "cli.toml").read_text().splitlines()


def test_bad_inputs_raise(tmp_path):
    with pytest.raises(FileNotFoundError):
        meso.fit_nonparametric(tmp_path / "missing.binary")
    # A sample CSV takes the 2-D route: these samples hold no back-scattering pair.
    csv = tmp_path / "s.csv"
    csv.write_text("theta_i,phi_i,theta_o,phi_o,r,g,b\n" + "10,0,20,180,0.1,0.1,0.1\n" * 300)
    with pytest.raises(meso.MesoError, match=r"s\.csv.*back-scattering samples.*cover 0"):
        meso.fit_nonparametric(csv, grid=(64, 16))


def _deg(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return np.degrees(np.arccos(np.clip(w[:, 2], -1, 1))), np.degrees(np.arctan2(w[:, 1], w[:, 0]))


@pytest.fixture(scope="module")
def aniso_csv(tmp_path_factory: pytest.TempPathFactory):
    """A sample CSV of an anisotropic GGX material: two back-scattering pairs (i = o) at random
    points of every upper cell of a 64 × 16 equal-area grid (bands of equal height in cos θ,
    sectors in φ), and 6000 pairs over the hemisphere."""
    truth = meso.Material.from_params(
        form="microfacet",
        ndf={"kind": "ggx", "alpha_x": 0.25, "alpha_y": 0.5},
        transfer={"kind": "mirror", "fresnel": "schlick", "f0": [0.9, 0.6, 0.3], "specular": [0.8] * 3},
        diffuse=[0.05, 0.1, 0.2],
    )
    rng = np.random.default_rng(9)
    band, sector = np.meshgrid(np.arange(32), np.arange(16), indexing="ij")
    band, sector = np.repeat(band.ravel(), 2), np.repeat(sector.ravel(), 2)
    z = (band + rng.uniform(size=band.size)) / 32
    phi = (sector + rng.uniform(size=band.size)) * (2 * np.pi / 16)
    back = np.stack([np.sqrt(1 - z**2) * np.cos(phi), np.sqrt(1 - z**2) * np.sin(phi), z], 1)
    def hemi(n):
        z = np.maximum(rng.uniform(size=n), 0.02)
        p = rng.uniform(0, 2 * np.pi, n)
        return np.stack([np.sqrt(1 - z**2) * np.cos(p), np.sqrt(1 - z**2) * np.sin(p), z], 1)
    wi = np.concatenate([back, hemi(6000)])
    wo = np.concatenate([back, hemi(6000)])
    f = truth.brdf(wi, wo)
    (ti, pi), (to, po) = _deg(wi), _deg(wo)
    path = tmp_path_factory.mktemp("np2") / "aniso.csv"
    lines = ["theta_i,phi_i,theta_o,phi_o,r,g,b"]
    lines += [",".join(repr(float(x)) for x in row) for row in np.column_stack([ti, pi, to, po, f])]
    path.write_text("\n".join(lines) + "\n")
    return path, truth


def test_anisotropic_samples_give_a_2d_table_equal_to_the_cli(aniso_csv, tmp_path):
    path, truth = aniso_csv
    m, report = meso.fit_nonparametric(path, grid=(64, 16), out=tmp_path / "py.toml")
    assert m.ndf.kind == "tabulated" and report["kind"] == "tabulated"
    assert tuple(report["grid"]) == (64, 16)
    assert report["cells_covered"] >= 0.9 * report["cells_needed"] > 0
    # A 64 × 16 table is coarse (its polar cap is 14°): its held-out log error is that of the
    # table's steps (the CLI's test measures 0.01-0.03 on similar data).
    assert max(report["held_out"]["low_log"]) < 0.05, report["held_out"]
    # The anisotropy is in the table: the fitted BRDF is higher where the truth is, along y
    # (α 0.5) than along x (α 0.25), at 40° back-scattering.
    t = np.radians(40)
    wx = np.array([[np.sin(t), 0, np.cos(t)]])
    wy = np.array([[0, np.sin(t), np.cos(t)]])
    assert (m.brdf(wy, wy)[0, 0] > m.brdf(wx, wx)[0, 0]) == (truth.brdf(wy, wy)[0, 0] > truth.brdf(wx, wx)[0, 0])
    run_cli("fit", str(path), "--nonparametric", "--grid", "64,16", "--out", str(tmp_path / "cli.toml"))
    strip = lambda s: re.sub(r"^#.*\n", "", s, flags=re.M)  # noqa: E731
    assert strip((tmp_path / "cli.toml").read_text()) == strip((tmp_path / "py.toml").read_text())
    # A grid is for sample CSVs; an odd n_z cannot put the horizon on a band edge.
    with pytest.raises(meso.MesoError, match="even"):
        meso.fit_nonparametric(path, grid=(63, 16))


def test_a_grid_with_a_merl_table_is_refused(merl):
    path, _ = merl
    with pytest.raises(meso.MesoError, match="MERL table is isotropic"):
        meso.fit_nonparametric(path, grid=(64, 16))
