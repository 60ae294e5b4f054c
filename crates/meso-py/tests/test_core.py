"""The meso Python package against independent truth: the CLI's numbers (to 1e-6 relative),
closed forms, numerical integration, and its own errors as Python exceptions."""

from __future__ import annotations

import math
import threading
import time
import warnings

import numpy as np
import pytest

import meso
from conftest import bumps, directions_deg, run_cli, write_gray16, write_rgb8

GLOSSY = """form = "microfacet"
[ndf]
kind = "ggx"
alpha = 0.05
[transfer]
kind = "mirror"
fresnel = "schlick"
f0 = [0.9, 0.6, 0.3]
"""

PEAKS = """[ndf]
kind = "phong-peaks"
lobes = [{ axis = [0.0, 0.0], weight = 1.0, exponent = 40.0 }, { axis = [30.0, 90.0], weight = 0.5, exponent = 300.0 }]
[transfer]
kind = "phong"
exponent = 50.0
[diffuse]
albedo = [0.2, 0.3, 0.4]
"""


def random_pairs(n: int, seed: int = 0, max_theta: float = 80.0):
    rng = np.random.default_rng(seed)
    deg = np.column_stack(
        [rng.uniform(0, max_theta, n), rng.uniform(0, 360, n), rng.uniform(0, max_theta, n), rng.uniform(0, 360, n)]
    ).round(3)
    return deg, directions_deg(deg[:, 0], deg[:, 1]), directions_deg(deg[:, 2], deg[:, 3])


def cli_brdf(tmp_path, material_path, deg):
    pairs = tmp_path / "pairs.csv"
    pairs.write_text("theta_i,phi_i,theta_o,phi_o\n" + "".join(f"{a},{b},{c},{d}\n" for a, b, c, d in deg))
    out = tmp_path / "out.csv"
    run_cli("brdf", material_path, "--pairs", pairs, "--out", out)
    return np.loadtxt(out, delimiter=",", skiprows=1)[:, 4:7]


@pytest.mark.parametrize("text", [GLOSSY, PEAKS], ids=["glossy-ggx", "phong-peaks"])
def test_brdf_equals_the_cli(tmp_path, text):
    path = tmp_path / "m.toml"
    path.write_text(text)
    deg, wi, wo = random_pairs(300)
    py = meso.Material.from_file(path).brdf(wi, wo)
    cli = cli_brdf(tmp_path, path, deg)
    assert py.shape == (300, 3)
    # The CLI prints 10 significant digits.
    np.testing.assert_allclose(py, cli, rtol=1e-6, atol=1e-300)
    # The same material from text and from keyword arguments.
    np.testing.assert_array_equal(meso.Material.from_toml(text).brdf(wi, wo), py)


def test_heightmap_material_equals_the_cli(tmp_path):
    write_gray16(tmp_path / "bumps.png", bumps(24))
    path = tmp_path / "hm.toml"
    path.write_text(
        '[ndf]\nkind = "heightmap"\nfile = "bumps.png"\ntexel_size = 1.0\nheight_scale = 3.0\n'
        'represent = "facets"\n[transfer]\nkind = "microfacet"\ndistribution = "beckmann"\nalpha = 0.1\n'
    )
    deg, wi, wo = random_pairs(60, seed=3, max_theta=60.0)
    py = meso.Material.from_file(path).brdf(wi, wo)
    np.testing.assert_allclose(py, cli_brdf(tmp_path, path, deg), rtol=1e-6, atol=1e-300)


def test_from_params_writes_the_material_format():
    m = meso.Material.from_params(
        form="microfacet",
        ndf={"kind": "ggx", "alpha": 0.05},
        transfer={"kind": "mirror", "fresnel": "schlick", "f0": [0.9, 0.6, 0.3]},
        name="glossy",
    )
    _, wi, wo = random_pairs(50)
    np.testing.assert_array_equal(m.brdf(wi, wo), meso.Material.from_toml(GLOSSY).brdf(wi, wo))
    assert m.name == "glossy" and m.form == "microfacet" and m.ndf.kind == "ggx"


def test_material_toml_is_written_by_meso_and_reads_back():
    """meso.material_toml writes through MaterialSpec::to_toml: written, parsed and written
    again gives the same text, and the text builds the material from_params builds."""
    tomllib = pytest.importorskip("tomllib")
    tables = dict(
        name="two lobes",
        ndf={"kind": "phong-peaks", "lobes": [
            {"axis": [0, 0], "weight": 3, "exponent": 40},
            {"axis": np.array([30.0, 90.0]), "weight": np.float64(1.0), "exponent": 100.0},
        ]},
        transfer={"kind": "phong", "exponent": 50, "specular": [1.0, 0.8, 0.6]},
        diffuse=np.array([0.1, 0.2, 0.3]),
    )
    text = meso.material_toml(**tables)
    # The writer's form: weights normalised as meso reads them, axes as degrees.
    assert "{ axis = [30.0, 90.0], weight = 0.25, exponent = 100.0 }" in text, text
    back = tomllib.loads(text)
    again = meso.material_toml(
        name=back["name"], ndf=back["ndf"], transfer=back["transfer"], diffuse=back["diffuse"]["albedo"]
    )
    assert again == text
    _, wi, wo = random_pairs(40, seed=9)
    np.testing.assert_array_equal(meso.Material.from_toml(text).brdf(wi, wo), meso.Material.from_params(**tables).brdf(wi, wo))
    with pytest.raises(meso.MesoError, match="transfer"):
        meso.material_toml(ndf={"kind": "sphere"})
    with pytest.raises(TypeError, match="ndf.kind"):
        meso.material_toml(ndf={"kind": object()}, transfer={"kind": "lambert"})
    # A misspelt width is named; the exception is meso's own, as tracebacks print it.
    with pytest.raises(meso.MesoError, match="`alhpa` is not a key here") as e:
        meso.Material.from_params(ndf={"kind": "ggx", "alhpa": 0.1}, transfer={"kind": "mirror"})
    assert type(e.value).__module__ == "meso"
    assert repr(meso.Material.from_params(transfer={"kind": "lambert"})).startswith("meso.Material(name=None")


def test_microfacet_form_is_reciprocal_and_loses_energy():
    m = meso.Material.from_params(
        form="microfacet", ndf={"kind": "beckmann", "alpha": 0.3}, transfer={"kind": "mirror"}
    )
    _, wi, wo = random_pairs(200, seed=5)
    np.testing.assert_allclose(m.brdf(wi, wo), m.brdf(wo, wi), rtol=1e-9)
    # White furnace: ∫ f cos dω_i ≤ 1 for every viewer direction (midpoint rule in cos θ, φ).
    nz, nphi = 100, 100
    z = (np.arange(nz) + 0.5) / nz
    phi = (np.arange(nphi) + 0.5) / nphi * 2 * np.pi
    zz, pp = np.meshgrid(z, phi, indexing="ij")
    s = np.sqrt(1 - zz**2)
    wi = np.column_stack([(s * np.cos(pp)).ravel(), (s * np.sin(pp)).ravel(), zz.ravel()])
    for theta_o in (0.0, 45.0, 75.0):
        wo = np.tile(directions_deg(np.array([theta_o]), np.array([0.0])), (len(wi), 1))
        albedo = (m.brdf(wi, wo)[:, 0] * wi[:, 2]).mean() * 2 * np.pi
        assert 0.85 < albedo <= 1.0 + 1e-3, (theta_o, albedo)


def sphere_grid(n: int = 400):
    """Midpoint cells in (cos θ, φ) over the whole sphere: directions and the solid angle each."""
    z = -1 + (np.arange(n) + 0.5) * 2 / n
    phi = (np.arange(2 * n) + 0.5) / (2 * n) * 2 * np.pi
    zz, pp = np.meshgrid(z, phi, indexing="ij")
    s = np.sqrt(1 - zz**2)
    d = np.column_stack([(s * np.cos(pp)).ravel(), (s * np.sin(pp)).ravel(), zz.ravel()])
    return d, (2 / n) * (2 * np.pi / (2 * n))


@pytest.mark.parametrize(
    "ndf",
    [{"kind": "beckmann", "alpha": 0.3}, {"kind": "vmf", "kappa": 20.0}, {"kind": "phong-peaks", "lobes": [{"axis": [20.0, 0.0], "weight": 1.0, "exponent": 30.0}]}],
    ids=["beckmann", "vmf", "phong-peaks"],
)
def test_ndf_integrates_to_one_and_samples_its_pdf(ndf):
    n = meso.Ndf.from_params(**ndf)
    d, dw = sphere_grid()
    assert abs(n.eval(d).sum() * dw - 1) < 2e-3  # Eq. 1
    # Draws against the pdf: counts in 12 bands of cos θ within 5 standard deviations.
    rng = np.random.default_rng(7)
    m = n.sample(rng.random((200_000, 2)))
    np.testing.assert_allclose(np.linalg.norm(m, axis=1), 1, atol=1e-9)
    edges = np.linspace(-1, 1, 13)
    observed = np.histogram(m[:, 2], edges)[0]
    p = n.pdf(d) * dw
    expected = np.histogram(d[:, 2], edges, weights=p)[0] * len(m)
    sd = np.sqrt(np.maximum(expected, 1))
    assert np.all(np.abs(observed - expected) < 5 * sd + 1e-3 * len(m)), (observed, expected)


@pytest.mark.parametrize("text", [GLOSSY, PEAKS], ids=["glossy-ggx", "phong-peaks"])
def test_material_sampler_averages_to_the_albedo(text):
    m = meso.Material.from_toml(text)
    wo1 = directions_deg(np.array([35.0]), np.array([50.0]))
    rng = np.random.default_rng(3)
    n = 20_000
    wo = np.tile(wo1, (n, 1))
    wi, pdf = m.sample(wo, rng.random((n, 3)))
    ok = pdf > 0
    np.testing.assert_allclose(m.pdf(wo[ok], wi[ok]), pdf[ok], rtol=1e-12)
    w = np.zeros(n)
    w[ok] = m.brdf(wi[ok], wo[ok])[:, 1] * wi[ok, 2] / pdf[ok]
    mc, se = w.mean(), w.std() / math.sqrt(n)
    # Independent: a fine midpoint rule over the hemisphere of incident directions.
    d, dw = sphere_grid(200)
    up = d[d[:, 2] > 0]
    quad = (m.brdf(up, np.tile(wo1, (len(up), 1)))[:, 1] * up[:, 2]).sum() * dw
    assert abs(mc - quad) < 5 * se + 0.01 * quad, (mc, se, quad)


def test_extract_of_a_tilted_plane_has_its_normal():
    # A plane of slope 0.25 along x (clamped border: no wrap-around step): every lobe's axis is the
    # plane's normal (−0.25, 0, 1)/|…|, in every level.
    y, x = np.mgrid[0:16, 0:16].astype(float)
    pyr = meso.extract(0.25 * x, texel_size=1.0, border="clamp")
    normal = np.array([-0.25, 0, 1]) / math.hypot(0.25, 1)
    for level in pyr.levels:
        # One normal everywhere: the lobes shade as the footprint does.
        assert level.shading_error is not None and 0 <= level.shading_error <= level.shading_error_max * (1 + 1e-12) < 1e-3
        counts, axes, weights = level.counts, level.axes, level.weights
        assert counts.shape == (level.rows, level.cols) and counts.min() >= 1
        np.testing.assert_allclose(weights.sum(axis=2), 1, atol=1e-9)
        main = axes[:, :, 0, :].reshape(-1, 3)
        np.testing.assert_allclose(main, np.tile(normal, (len(main), 1)), atol=1e-3)
    assert pyr.top.rows == pyr.top.cols == 1


def test_extract_file_equals_the_cli_and_the_array_path(tmp_path):
    codes = bumps(32, seed=4)
    write_gray16(tmp_path / "h.png", codes)
    pyr, warnings = meso.extract_file(tmp_path / "h.png", tmp_path / "py.map", texel_size=1.0, height_scale=4.0, max_lobes=3)
    run_cli("extract", tmp_path / "h.png", "--texel-size", 1.0, "--height-scale", 4.0, "--max-lobes", 3, "--out", tmp_path / "cli.map")
    assert (tmp_path / "py.map").read_bytes() == (tmp_path / "cli.map").read_bytes()
    assert warnings == []
    again = meso.extract(codes / 65535.0, texel_size=1.0, height_scale=4.0, max_lobes=3)
    read = meso.Pyramid.read(tmp_path / "cli.map")
    assert len(read) == len(pyr) == len(again)
    for a, b, c in zip(pyr.levels, read.levels, again.levels):
        np.testing.assert_array_equal(a.counts, b.counts)
        np.testing.assert_allclose(a.axes, c.axes, atol=1e-12)
        # Map format 3 stores log2(1 + η) in 16 bits: |Δη| ≤ 1.06e-4 · (1 + η) (docs/map-format.md).
        assert np.all(np.abs(a.exponents - b.exponents) <= 1.07e-4 * (1 + a.exponents))
        assert a.shading_error == pytest.approx(b.shading_error, rel=1e-6)
        assert a.shading_error_max == pytest.approx(b.shading_error_max, rel=1e-6)
        assert a.residual_max >= a.residual >= 0
    # The same shading errors as `meso map info` prints (in % of the peak, 2 decimals).
    info = run_cli("map", "info", tmp_path / "cli.map").stdout
    rows = [l.split() for l in info.splitlines() if l[:1].isdigit()]
    assert len(rows) == len(read)
    for row, level in zip(rows, read.levels):
        mean, peak = (float(x) for x in row[-1].split("/"))
        assert mean == pytest.approx(100 * level.shading_error, abs=0.006)
        assert peak == pytest.approx(100 * level.shading_error_max, abs=0.006)
    assert max(l.shading_error for l in read.levels) > 0


def test_read_heights_reads_what_extract_file_reads(tmp_path):
    codes = bumps(32, seed=4)
    write_gray16(tmp_path / "h.png", codes)
    heights, warnings = meso.read_heights(tmp_path / "h.png")
    # 16-bit codes over 65535, in image order (row 0 at the top), nothing corrected.
    assert heights.shape == (32, 32) and heights.dtype == np.float64
    np.testing.assert_array_equal(heights, codes / 65535.0)
    assert warnings == []
    from_file, _ = meso.extract_file(tmp_path / "h.png", tmp_path / "h.map", texel_size=1.0, height_scale=4.0, max_lobes=3)
    from_array = meso.extract(heights, texel_size=1.0, height_scale=4.0, max_lobes=3)
    for a, b in zip(from_file.levels, from_array.levels):
        np.testing.assert_array_equal(a.counts, b.counts)
        np.testing.assert_allclose(a.axes, b.axes, atol=1e-12)
    # An 8-bit map of gentle slopes, terraces one code high: dequantised as meso extract does,
    # and said so.
    from conftest import _png

    y, x = np.mgrid[0:32, 0:32] / 32
    steps = np.round(20 + 6 * np.sin(2 * np.pi * x) * np.cos(2 * np.pi * y)).astype(np.uint8)
    _png(tmp_path / "t.png", 32, 32, 8, 0, b"".join(b"\x00" + steps[r].tobytes() for r in range(32)))
    heights, warnings = meso.read_heights(tmp_path / "t.png")
    assert any("dequantised" in w and "t.png" in w for w in warnings), warnings
    assert not np.array_equal(heights, steps / 255.0)
    assert np.abs(heights - steps / 255.0).max() <= 0.5 / 255 + 1e-12
    with pytest.raises(FileNotFoundError, match="nope.png"):
        meso.read_heights(tmp_path / "nope.png")
    with pytest.raises(ValueError, match="border"):
        meso.read_heights(tmp_path / "h.png", border="mirror")


def test_extract_gives_maps_of_faces_and_walls_six_lobes():
    """max_lobes=None (the default) is the CLI's rule: terraces (flat steps 4 cells wide, 3
    high) get up to six lobes a texel, a gentle map four; a K asked for applies to any map."""
    j = np.arange(64)
    terraces = 3.0 * ((j[None, :] // 4 + j[:, None] // 8) % 2)
    assert meso.extract(terraces, texel_size=1.0).max_lobes == 6
    assert meso.extract(terraces, texel_size=1.0, max_lobes=4).max_lobes == 4
    assert meso.extract(bumps(32, seed=4) / 65535.0, texel_size=1.0, height_scale=0.5).max_lobes == 4


def test_extract_merge_levels_equals_the_cli(tmp_path):
    # 128² cells: level 1 (64²) is merged from its cells by default, kept its own fit with
    # merge_levels="none"; each equals `meso extract --merge-levels` byte for byte.
    codes = bumps(128, seed=9)
    write_gray16(tmp_path / "h.png", codes)
    maps = {}
    for m in ["plain", "none", "all"]:
        meso.extract_file(tmp_path / "h.png", tmp_path / f"py-{m}.map", texel_size=1.0, height_scale=4.0, merge_levels=m)
        run_cli("extract", tmp_path / "h.png", "--texel-size", 1.0, "--height-scale", 4.0, "--merge-levels", m, "--out", tmp_path / f"cli-{m}.map")
        maps[m] = (tmp_path / f"py-{m}.map").read_bytes()
        assert maps[m] == (tmp_path / f"cli-{m}.map").read_bytes()
    assert maps["plain"] != maps["none"] and maps["plain"] != maps["all"]
    default = meso.extract(codes / 65535.0, texel_size=1.0, height_scale=4.0)
    plain = meso.extract(codes / 65535.0, texel_size=1.0, height_scale=4.0, merge_levels="plain")
    for a, b in zip(default.levels, plain.levels):
        np.testing.assert_array_equal(a.axes, b.axes)
    with pytest.raises(ValueError, match="merge_levels"):
        meso.extract(codes / 65535.0, texel_size=1.0, merge_levels="some")


def test_render_of_a_lambert_sphere_is_albedo_over_pi_times_irradiance(tmp_path):
    (tmp_path / "white.toml").write_text('[ndf]\nkind = "sphere"\n[transfer]\nkind = "lambert"\nalbedo = [0.5, 0.5, 0.5]\n')
    (tmp_path / "white.toml").write_text("[diffuse]\nalbedo = [0.5, 0.5, 0.5]\n[transfer]\nkind = \"phong\"\nexponent = 1.0\nspecular = [0.0, 0.0, 0.0]\n")
    (tmp_path / "scene.toml").write_text(
        '[camera]\nkind = "orthographic"\nposition = [0.0, 0.0, 5.0]\nlook_at = [0.0, 0.0, 0.0]\nwidth = 2.5\n'
        "[image]\nwidth = 33\nheight = 33\nspp = 4\n"
        '[[object]]\nkind = "sphere"\ncenter = [0.0, 0.0, 0.0]\nradius = 1.0\nmaterial = "white.toml"\n'
        '[[light]]\nkind = "directional"\ndirection = [0.0, 0.0, 1.0]\nirradiance = [2.0, 2.0, 2.0]\n'
    )
    img = meso.render(tmp_path / "scene.toml", spp=1)
    assert img.shape == (33, 33, 3) and img.dtype == np.float32
    # The centre pixel sees the sphere's pole, lit head-on: L = (0.5/π)·2.
    np.testing.assert_allclose(img[16, 16], 1 / math.pi, rtol=1e-3)
    assert np.all(img[0, 0] == 0)  # background


def test_export_equals_the_cli(tmp_path):
    write_gray16(tmp_path / "h.png", bumps(32, seed=9))
    files, levels, _ = meso.export(tmp_path / "h.png", tmp_path / "py", texel_size=1.0, height_scale=2.0, alpha=0.08)
    run_cli("export", tmp_path / "h.png", "--out", tmp_path / "cli", "--texel-size", 1.0, "--height-scale", 2.0, "--alpha", 0.08)
    names = sorted(p.name for p in (tmp_path / "py").iterdir())
    assert names == sorted(p.name for p in (tmp_path / "cli").iterdir())
    assert len(files) == len(names)
    for name in names:
        assert (tmp_path / "py" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes(), name
    assert levels[0]["width"] == 32 and levels[-1]["width"] == 1


# ---- errors: Python exceptions, never a crash ----------------------------------------------


def test_bad_arrays_raise_python_exceptions():
    m = meso.Material.from_toml(GLOSSY)
    good = np.array([[0.0, 0.0, 1.0]])
    with pytest.raises(ValueError, match=r"shape \(N, 3\)"):
        m.brdf(np.zeros((2, 2)), good)
    with pytest.raises(ValueError, match=r"wi\[0, 0\] = NaN: not a finite number"):
        m.brdf(np.array([[np.nan, 0.0, 1.0]]), good)
    with pytest.raises(ValueError, match="not a direction"):
        m.brdf(np.zeros((1, 3)), good)
    with pytest.raises(ValueError, match="rows"):
        m.brdf(np.tile(good, (3, 1)), np.tile(good, (2, 1)))
    with pytest.raises(TypeError, match=r"got an ndarray of shape \(1, 3\) and dtype <U1"):
        m.brdf(np.array([["a", "b", "c"]]), good)
    # The wrong dimension or no numbers at all: a TypeError saying what was expected and what
    # came, the argument named in the exception's notes (Python ≥ 3.11 prints them).
    expected = r"expected a 2-D array of numbers, a list of rows \(one direction: \[\[x, y, z\]\]"
    for bad, came in [
        (np.zeros(3), r"got an ndarray of shape \(3,\)"),
        ([0, 0, 1], r"got a list of shape \(3,\)"),
        ("abc", "got a str"),
        (None, "got None"),
    ]:
        with pytest.raises(TypeError, match=expected + ".*" + came) as e:
            m.brdf(bad, good)
        assert "while processing 'wi'" in getattr(e.value, "__notes__", ["while processing 'wi'"])
    with pytest.raises(TypeError, match=r"got an ndarray of shape \(8, 8, 3\)"):
        meso.extract(np.zeros((8, 8, 3)), texel_size=1.0)
    # A sampler's random numbers lie in [0, 1].
    with pytest.raises(ValueError, match=r"u\[0, 0\] = 1.5: random numbers must lie in \[0, 1\]"):
        m.sample(good, np.array([[1.5, 0.5, 0.2]]))
    with pytest.raises(ValueError, match=r"u\[0, 1\] = -0.1"):
        meso.Ndf.from_params(kind="ggx", alpha=0.3).sample(np.array([[0.5, -0.1]]))
    assert np.isfinite(m.sample(good, np.array([[1.0, 0.0, 1.0]]))[1]).all()
    # Other dtypes and lists are converted.
    np.testing.assert_array_equal(m.brdf([[0, 0, 1]], good.astype(np.float32)), m.brdf(good, good))
    with pytest.raises(ValueError, match="not a finite number"):
        m.sample(good, np.array([[0.5, np.inf, 0.5]]))
    with pytest.raises(ValueError, match=r"heights\[0, 1\] = NaN: not a finite number"):
        meso.extract(np.array([[0.0, np.nan], [1.0, 2.0]]), texel_size=1.0)


def test_bad_files_and_materials_raise_with_the_name(tmp_path):
    with pytest.raises(FileNotFoundError, match="nope.toml"):
        meso.Material.from_file(tmp_path / "nope.toml")
    with pytest.raises(meso.MesoError, match=r"alpha"):
        meso.Material.from_toml('[ndf]\nkind = "ggx"\nalpha = -1.0\n')
    (tmp_path / "bad.png").write_bytes(b"\x89PNG\r\n\x1a\n garbage")
    with pytest.raises(meso.MesoError, match="bad.png"):
        meso.extract_file(tmp_path / "bad.png", tmp_path / "o.map", texel_size=1.0, height_scale=1.0)
    assert not (tmp_path / "o.map").exists()
    with pytest.raises(FileNotFoundError, match="missing.toml"):
        meso.render(tmp_path / "missing.toml")
    with pytest.raises(ValueError, match="max_lobes"):
        meso.extract(np.zeros((4, 4)), texel_size=1.0, max_lobes=0)


def test_memory_budget_refuses_before_allocating():
    meso.set_memory_budget("1M")
    try:
        with pytest.raises(meso.MesoError, match="budget"):
            meso.extract(np.zeros((512, 512)), texel_size=1.0)
    finally:
        meso.set_memory_budget("4G")


def test_brdf_releases_the_gil():
    # While one thread evaluates a large batch, another Python thread keeps running.
    m = meso.Material.from_toml(PEAKS)
    _, wi, wo = random_pairs(3_000, seed=2)
    ticks = []
    done = threading.Event()

    def count():
        while not done.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.001)

    t = threading.Thread(target=count)
    t.start()
    start = time.perf_counter()
    m.brdf(wi, wo)
    end = time.perf_counter()
    done.set()
    t.join()
    during = [x for x in ticks if start < x < end]
    assert end - start > 0.05 and len(during) >= 3, (end - start, len(during))


def test_loading_a_height_map_says_what_it_found(tmp_path, monkeypatch):
    """A colour image given as heights is converted and said so, as the CLI prints it: a Python
    UserWarning naming the file (not a silent conversion)."""
    monkeypatch.setenv("MESO_CACHE_DIR", str(tmp_path / "cache"))
    y, x = np.mgrid[0:16, 0:16]
    write_rgb8(tmp_path / "colour.png", np.stack([x * 15, y * 15, np.full_like(x, 40)], axis=-1))
    text = (
        '[ndf]\nkind = "heightmap"\nfile = "colour.png"\ntexel_size = 1.0\nheight_scale = 1.0\n'
        '[transfer]\nkind = "lambert"\n'
    )
    (tmp_path / "m.toml").write_text(text)
    with pytest.warns(UserWarning, match=r"colour\.png: colour image used as a height map"):
        meso.Material.from_file(tmp_path / "m.toml")
    # A grey map says nothing.
    write_gray16(tmp_path / "grey.png", bumps(16))
    (tmp_path / "g.toml").write_text(text.replace("colour.png", "grey.png"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        meso.Material.from_file(tmp_path / "g.toml")
