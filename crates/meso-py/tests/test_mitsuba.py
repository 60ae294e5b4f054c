"""The Mitsuba 3 plugin (meso.mitsuba): chi-square tests of its sampler with Mitsuba's own harness,
eval against Material.brdf (the frame mapping), and a sphere rendered by Mitsuba and by meso.

Run: ``python -m pytest tests/test_mitsuba.py -q -s`` (``-s`` prints the measured numbers).
The JIT tests need Dr.Jit's LLVM backend (Debian: ``libllvm19``); they are skipped without it.
"""

import functools
import os
import subprocess
import sys
import time

import numpy as np
import pytest

_LLVM19 = "/usr/lib/x86_64-linux-gnu/libLLVM-19.so"
if os.path.exists(_LLVM19):  # Debian 12's default libLLVM-15 crashes Dr.Jit; pick 19 if present
    os.environ.setdefault("DRJIT_LIBLLVM_PATH", _LLVM19)

mi = pytest.importorskip("mitsuba")
import drjit as dr  # noqa: E402

import meso  # noqa: E402
import meso.mitsuba as mm  # noqa: E402

# Fewer quadrature nodes than the default (32 × 48) keep Material.brdf at ~0.1 ms a row on this
# machine; the sampler and its pdf do not depend on them.
_FAST = "[quadrature]\nradial = 8\nazimuth = 16\n"

MATERIALS = {
    # glossy microfacet GGX (classic Cook–Torrance/Walter through the microfacet form)
    "ggx-glossy": 'form = "microfacet"\n' + _FAST + """
[ndf]
kind = "ggx"
alpha = 0.08
[transfer]
kind = "mirror"
fresnel = "schlick"
f0 = [0.95, 0.8, 0.5]
""",
    # rough Beckmann with a diffuse term
    "beckmann-rough-diffuse": 'form = "microfacet"\n' + _FAST + """
[ndf]
kind = "beckmann"
alpha = 0.4
[transfer]
kind = "mirror"
[diffuse]
albedo = [0.3, 0.2, 0.1]
""",
    # the multiple-surface form: phong peaks with a phong transfer (not reciprocal)
    "peaks-multiple-surface": _FAST + """
[ndf]
kind = "phong-peaks"
lobes = [
  { axis = [0.0, 0.0], weight = 0.6, exponent = 40.0 },
  { axis = [30.0, 90.0], weight = 0.4, exponent = 100.0 },
]
[transfer]
kind = "phong"
exponent = 50.0
specular = [1.0, 0.8, 0.6]
""",
}

# Viewer directions (Mitsuba's si.wi, meso's wo): near normal and at 60 degrees.
VIEWS = {
    "view-20deg": [np.sin(np.radians(20)) * np.cos(0.7), np.sin(np.radians(20)) * np.sin(0.7), np.cos(np.radians(20))],
    "view-60deg": [np.sin(np.radians(60)) * np.cos(2.0), np.sin(np.radians(60)) * np.sin(2.0), np.cos(np.radians(60))],
}

CHI2_SAMPLES = 100_000
CHI2_RES = 41  # 20 x 41 cells (SphericalDomain); ~100 samples a cell on average
CHI2_IRES = 16  # trapezoid nodes per cell side: the GGX alpha = 0.08 peak needs more than 4
# The chi-square tests only need f > 0 where the sampler goes (weight != 0), not an accurate f:
# an even coarser quadrature keeps 10^5 BRDF evaluations at ~2 s.
CHI2_QUADRATURE = "[quadrature]\nradial = 4\nazimuth = 8\n"
_N_CHI2 = len(MATERIALS) * len(VIEWS)


@functools.lru_cache(maxsize=None)
def _jit_runs(name):
    """Whether a JIT variant runs here, probed in a subprocess: a bad libLLVM (Debian 12's 15)
    crashes the process instead of raising."""
    code = ("import drjit as dr, mitsuba as mi; mi.set_variant(%r); "
            "dr.eval(dr.arange(mi.Float, 4) * 2)" % name)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    return r.returncode == 0, (r.stderr or r.stdout)[-500:]


def _variant(name):
    """Switch to a Mitsuba variant and register the plugin there; skip if it cannot run."""
    if name not in mi.variants():
        pytest.skip(f"Mitsuba variant {name} not available")
    if not name.startswith("scalar"):
        ok, why = _jit_runs(name)
        if not ok:
            pytest.skip(f"Mitsuba variant {name} does not run here (needs libllvm19?): {why}")
    try:
        mi.set_variant(name)
        if not name.startswith("scalar"):
            dr.eval(dr.arange(mi.Float, 4) * 2)  # fails here when the LLVM backend is missing
    except Exception as e:  # noqa: BLE001
        pytest.skip(f"Mitsuba variant {name} does not run here: {e}")
    mm.register()


def _chi2(material, view, pdf_wrap=None):
    from mitsuba.chi2 import BSDFAdapter, ChiSquareTest, SphericalDomain

    text = MATERIALS[material].replace(_FAST, CHI2_QUADRATURE)
    sample_func, pdf_func = BSDFAdapter("meso", {"type": "meso", "toml": text},
                                          wi=mi.Vector3f(*(float(c) for c in view)))
    if pdf_wrap is not None:
        pdf_func = pdf_wrap(pdf_func)
    test = ChiSquareTest(
        domain=SphericalDomain(),
        sample_func=sample_func,
        pdf_func=pdf_func,
        sample_dim=3,
        sample_count=CHI2_SAMPLES,
        res=CHI2_RES,
        ires=CHI2_IRES,
    )
    return test


@pytest.mark.parametrize("view", list(VIEWS))
@pytest.mark.parametrize("material", list(MATERIALS))
def test_chi2_sampler(material, view):
    _variant("llvm_ad_rgb")
    t0 = time.time()
    test = _chi2(material, VIEWS[view])
    ok = test.run(significance_level=0.01, test_count=_N_CHI2, quiet=True)
    print(f"\nchi2 {material} {view}: p = {test.p_value:.4g} ({time.time() - t0:.1f} s)")
    assert ok, test.messages


def test_chi2_rejects_wrong_pdf():
    """The harness is not vacuous: a pdf skewed by (1 + 0.5 x) (still integrating to ~1) fails."""
    _variant("llvm_ad_rgb")

    def skew(pdf_func):
        return lambda wo, *a: pdf_func(wo, *a) * (1.0 + 0.5 * wo.x)

    test = _chi2("beckmann-rough-diffuse", VIEWS["view-20deg"], pdf_wrap=skew)
    ok = test.run(significance_level=0.01, test_count=1, quiet=True)
    print(f"\nchi2 with a wrong pdf: p = {test.p_value:.3g} (must be rejected)")
    assert not ok


def _random_pairs(n, seed):
    rng = np.random.default_rng(seed)

    def hemi(k):
        v = rng.normal(size=(k, 3))
        v[:, 2] = np.abs(v[:, 2]) + 0.05
        v /= np.linalg.norm(v, axis=1)[:, None]
        return v.astype(np.float32).astype(np.float64)  # what Mitsuba's float32 arrays hold

    return hemi(n), hemi(n)


def _check_eval(material, views, lights, values, pdfs):
    m = meso.Material.from_toml(MATERIALS[material])
    want = m.brdf(lights, views) * lights[:, 2:3] / np.linalg.norm(lights, axis=1)[:, None]
    np.testing.assert_allclose(values, want, rtol=1e-6, atol=0)
    np.testing.assert_allclose(pdfs, m.pdf(views, lights), rtol=1e-6, atol=0)


@pytest.mark.parametrize("material", list(MATERIALS))
def test_eval_matches_brdf_scalar(material):
    _variant("scalar_rgb")
    bsdf = mi.load_dict({"type": "meso", "toml": MATERIALS[material]})
    views, lights = _random_pairs(40, 1)
    ctx = mi.BSDFContext()
    si = dr.zeros(mi.SurfaceInteraction3f)
    vals, pdfs = [], []
    for v, l in zip(views, lights):
        si.wi = mi.Vector3f(*v)
        vals.append(np.array(bsdf.eval(ctx, si, mi.Vector3f(*l))))
        pdfs.append(float(bsdf.pdf(ctx, si, mi.Vector3f(*l))))
        f2, p2 = bsdf.eval_pdf(ctx, si, mi.Vector3f(*l))
        assert np.array_equal(np.array(f2), vals[-1]) and float(p2) == pdfs[-1]
    _check_eval(material, views, lights, np.array(vals), np.array(pdfs))
    # below the surface: nothing
    si.wi = mi.Vector3f(0.0, 0.6, -0.8)
    assert np.all(np.array(bsdf.eval(ctx, si, mi.Vector3f(0.0, 0.0, 1.0))) == 0)
    si.wi = mi.Vector3f(*views[0])
    assert np.all(np.array(bsdf.eval(ctx, si, mi.Vector3f(0.0, 0.6, -0.8))) == 0)
    assert float(bsdf.pdf(ctx, si, mi.Vector3f(0.0, 0.6, -0.8))) == 0


@pytest.mark.parametrize("material", list(MATERIALS))
def test_eval_matches_brdf_llvm(material):
    _variant("llvm_ad_rgb")
    bsdf = mi.load_dict({"type": "meso", "toml": MATERIALS[material]})
    views, lights = _random_pairs(500, 2)
    si = dr.zeros(mi.SurfaceInteraction3f, len(views))
    si.wi = mi.Vector3f(views.T.astype(np.float32))
    wo = mi.Vector3f(lights.T.astype(np.float32))
    ctx = mi.BSDFContext()
    vals = _rows(bsdf.eval(ctx, si, wo))
    pdfs = np.array(bsdf.pdf(ctx, si, wo))
    _check_eval(material, views, lights, vals, pdfs)


def _rows(x):
    """A drjit Color3f/Vector3f of width n as an (n, 3) array."""
    a = np.array(x)
    return a.T if a.shape[0] == 3 else a


def test_frame_mapping_non_reciprocal():
    """On the multiple-surface material swapping the two directions changes the value; eval
    must be f(light = Mitsuba's wo, viewer = si.wi), not the swapped one."""
    _variant("scalar_rgb")
    m = meso.Material.from_toml(MATERIALS["peaks-multiple-surface"])
    bsdf = mi.load_dict({"type": "meso", "toml": MATERIALS["peaks-multiple-surface"]})
    view = np.array([0.5, 0.0, np.sqrt(0.75)], dtype=np.float32).astype(np.float64)
    light = np.array([-0.2, -0.5, np.sqrt(0.71)], dtype=np.float32).astype(np.float64)
    f_right = m.brdf(light[None], view[None])[0]
    f_swapped = m.brdf(view[None], light[None])[0]
    assert np.all(np.abs(f_right - f_swapped) > 0.02 * np.abs(f_right))  # not reciprocal here
    si = dr.zeros(mi.SurfaceInteraction3f)
    si.wi = mi.Vector3f(*view)
    got = np.array(bsdf.eval(mi.BSDFContext(), si, mi.Vector3f(*light)))
    np.testing.assert_allclose(got, f_right * light[2], rtol=1e-6)


@pytest.mark.parametrize("variant", ["scalar_rgb", "llvm_ad_rgb"])
def test_sample_consistent(variant):
    """sample: bs.pdf = pdf(bs.wo), weight = eval(bs.wo)/bs.pdf, eta 1, glossy reflection."""
    _variant(variant)
    text = MATERIALS["beckmann-rough-diffuse"]
    bsdf = mi.load_dict({"type": "meso", "toml": text})
    ctx = mi.BSDFContext()
    rng = np.random.default_rng(3)
    u = rng.random((200, 3)).astype(np.float32)
    view = np.array(VIEWS["view-60deg"], dtype=np.float32)
    if variant == "scalar_rgb":
        si = dr.zeros(mi.SurfaceInteraction3f)
        si.wi = mi.Vector3f(*view)
        rows = []
        for k in range(len(u)):
            bs, w = bsdf.sample(ctx, si, float(u[k, 0]), mi.Point2f(float(u[k, 1]), float(u[k, 2])))
            f = np.array(bsdf.eval(ctx, si, bs.wo))
            p = float(bsdf.pdf(ctx, si, bs.wo))
            rows.append((np.array(bs.wo), float(bs.pdf), np.array(w), f, p, float(bs.eta), int(bs.sampled_type)))
        wos = np.array([r[0] for r in rows])
        bpdf = np.array([r[1] for r in rows])
        weight = np.array([r[2] for r in rows])
        f = np.array([r[3] for r in rows])
        p = np.array([r[4] for r in rows])
        eta = np.array([r[5] for r in rows])
        stype = np.array([r[6] for r in rows])
    else:
        si = dr.zeros(mi.SurfaceInteraction3f, len(u))
        si.wi = mi.Vector3f(*[float(c) for c in view])
        bs, w = bsdf.sample(ctx, si, mi.Float(u[:, 0]), mi.Point2f(u[:, 1], u[:, 2]))
        wos = _rows(bs.wo)
        bpdf = np.array(bs.pdf)
        weight = _rows(w)
        f = _rows(bsdf.eval(ctx, si, bs.wo))
        p = np.array(bsdf.pdf(ctx, si, bs.wo))
        eta = np.broadcast_to(np.array(bs.eta), bpdf.shape)
        stype = np.broadcast_to(np.array(bs.sampled_type), bpdf.shape)
    ok = bpdf > 0
    assert ok.mean() > 0.7  # 13 % declined here (reflections below the horizon at 60 degrees)
    assert np.all(wos[ok, 2] > 0)
    np.testing.assert_allclose(bpdf[ok], p[ok], rtol=1e-5)
    np.testing.assert_allclose(weight[ok], f[ok] / bpdf[ok, None], rtol=1e-5)
    assert np.all(weight[~ok] == 0)
    assert np.all(eta == 1)
    assert np.all(stype == int(mi.BSDFFlags.GlossyReflection))


# --- the same sphere rendered by Mitsuba and by meso ---

RENDER_MATERIAL = 'form = "microfacet"\n' + _FAST + """
[ndf]
kind = "ggx"
alpha = 0.3
[transfer]
kind = "mirror"
fresnel = "schlick"
f0 = [0.9, 0.7, 0.4]
[diffuse]
albedo = [0.2, 0.3, 0.4]
"""
RENDER_PX = 64
RENDER_WIDTH = 2.5  # world units across the image (meso camera.width)
LIGHT = np.array([0.3, 0.4, 0.866]) / np.linalg.norm([0.3, 0.4, 0.866])  # towards the light


def _scenes(tmp_path, spp):
    (tmp_path / "sphere.toml").write_text(RENDER_MATERIAL)
    d = [float(c) for c in LIGHT]
    (tmp_path / "scene.toml").write_text(f"""[camera]
kind = "orthographic"
position = [0.0, 0.0, 5.0]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
width = {RENDER_WIDTH}
[image]
width = {RENDER_PX}
height = {RENDER_PX}
spp = {spp}
[[object]]
kind = "sphere"
center = [0.0, 0.0, 0.0]
radius = 1.0
material = "sphere.toml"
[[light]]
kind = "directional"
direction = [{d[0]!r}, {d[1]!r}, {d[2]!r}]
irradiance = [1.0, 1.0, 1.0]
""")
    T = mi.ScalarTransform4f
    # Mitsuba's orthographic sensor spans [-1, 1] across the film width in camera space, scaled by
    # to_world: a scale of width/2 gives meso's `width` (square pixels, image y down in both).
    mitsuba_scene = {
        "type": "scene",
        "integrator": {"type": "direct"},
        "sensor": {
            "type": "orthographic",
            "to_world": T().look_at(origin=[0, 0, 5], target=[0, 0, 0], up=[0, 1, 0])
            .scale([RENDER_WIDTH / 2, RENDER_WIDTH / 2, 1]),
            "film": {
                "type": "hdrfilm",
                "width": RENDER_PX,
                "height": RENDER_PX,
                "rfilter": {"type": "box"},
                "pixel_format": "rgb",
            },
            "sampler": {"type": "independent", "sample_count": spp},
        },
        "sphere": {
            "type": "sphere",
            "center": [0, 0, 0],
            "radius": 1.0,
            "bsdf": {"type": "meso", "material": str(tmp_path / "sphere.toml")},
        },
        # Mitsuba's `direction` is the direction the light travels: minus meso's
        "light": {"type": "directional", "direction": [-c for c in d],
                  "irradiance": {"type": "rgb", "value": [1.0, 1.0, 1.0]}},
    }
    return tmp_path / "scene.toml", mitsuba_scene


def _compare(img, ref, label, seconds):
    lum = ref.mean(axis=2)
    lit = lum > 1e-3 * lum.max()
    mean_rel = abs(img.mean() - ref.mean()) / ref.mean()
    pix = np.abs(img - ref).mean(axis=2)[lit] / lum[lit]
    print(f"\nrender {label}: mean mitsuba {img.mean():.6f} meso {ref.mean():.6f} "
          f"(rel diff {mean_rel:.2e}); mean relative pixel error {pix.mean():.4f} "
          f"(median {np.median(pix):.4f}, {lit.sum()} lit pixels); mitsuba {seconds:.1f} s")
    return mean_rel, pix.mean()


@pytest.mark.parametrize("variant,spp,pixel_bound", [("llvm_ad_rgb", 16, 0.05), ("scalar_rgb", 4, 0.08)])
def test_render_matches_meso(tmp_path, variant, spp, pixel_bound):
    """Measured here: llvm 16 spp, means within 6.9e-4, mean relative pixel error 0.027; scalar
    4 spp, means within 3e-5, pixel error 0.046. A directional light and a box filter leave only
    the pixel jitter as noise, mostly at the silhouette: the pixel error halves when spp
    quadruples (0.050 / 0.027 / 0.014 at 4 / 16 / 64 spp in llvm), so it is noise, not a bias."""
    _variant(variant)
    scene_path, scene_dict = _scenes(tmp_path, spp)
    scene = mi.load_dict(scene_dict)
    t0 = time.time()
    img = np.array(mi.render(scene, spp=spp))
    seconds = time.time() - t0
    ref = np.asarray(meso.render(str(scene_path), spp=spp, width=RENDER_PX, height=RENDER_PX, seed=0))
    assert img.shape == ref.shape == (RENDER_PX, RENDER_PX, 3)
    mean_rel, pixel_err = _compare(img, ref, f"{variant} {spp} spp", seconds)
    assert mean_rel < 0.01
    assert pixel_err < pixel_bound
