# %% [markdown]
# # meso from Python: a tour
#
# A notebook-style script (cells marked `# %%`; run it whole with
# `target/venv/bin/python docs/examples/python_tour.py OUTDIR`, or cell by cell in an editor that
# knows the markers). The test suite runs it (crates/meso-py/tests/test_docs_example.py).

# %%
import pathlib
import sys

import numpy as np

import meso

out = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else "out/python-tour")
out.mkdir(parents=True, exist_ok=True)

# %% [markdown]
# ## A material and its BRDF
# Directions are unit vectors in the local frame (normal +z); `wi` points towards the light, `wo`
# towards the viewer; values are RGB in 1/sr without the cosine — the numbers of `meso brdf`.

# %%
glossy = meso.Material.from_params(
    form="microfacet",
    ndf={"kind": "ggx", "alpha": 0.08},
    transfer={"kind": "mirror", "fresnel": "schlick", "f0": [0.95, 0.64, 0.54]},
)
theta = np.radians(np.linspace(0, 80, 9))
wi = np.column_stack([np.sin(theta), np.zeros_like(theta), np.cos(theta)])
wo = wi * np.array([-1.0, 1.0, 1.0])  # the mirror directions
print("BRDF along the mirror direction (1/sr):")
for t, f in zip(np.degrees(theta), glossy.brdf(wi, wo)):
    print(f"  θ = {t:4.0f}°  f = {f[0]:9.3f} {f[1]:9.3f} {f[2]:9.3f}")

# %% [markdown]
# ## Its NDF (Eq. 1: it integrates to 1 over the sphere) and its sampler

# %%
ndf = glossy.ndf
print(ndf, ndf.stats())
rng = np.random.default_rng(0)
m = ndf.sample(rng.random((5, 2)))
print("sampled normals:\n", m.round(4), "\ndensities (1/sr):", ndf.pdf(m).round(2))

# Importance sampling the material for a viewer at 30°: f·cos/pdf averages to the albedo.
n = 50_000
view = np.tile([np.sin(0.5), 0.0, np.cos(0.5)], (n, 1))
light, pdf = glossy.sample(view, rng.random((n, 3)))
ok = pdf > 0
weights = glossy.brdf(light[ok], view[ok]) * light[ok, 2:3] / pdf[ok, None]
print("directional albedo (RGB):", (weights.sum(axis=0) / n).round(4))

# %% [markdown]
# ## A height map filtered into an NDF pyramid (TR-92-41)
# Arrays are in image order (row 0 at the top); lobe axes in meso's frame (+y up in the image).

# %%
y, x = np.mgrid[0:64, 0:64] / 64
heights = 0.5 * np.sin(2 * np.pi * 3 * x) * np.sin(2 * np.pi * 2 * y)
pyramid = meso.extract(heights, texel_size=1 / 64, height_scale=0.05, max_lobes=3)
print(pyramid)
for level in pyramid.levels[::2]:
    print(f"  level {level.rows}×{level.cols}: lobes per texel ≤ {level.counts.max()}, NDF residual {level.residual:.4f}")
# The whole map: a broad lobe about +z and two narrow ones at the steepest slopes of the waves
# (the slopes of a sine pile up at its extremes).
top = pyramid.top
for axis, weight, eta in zip(top.axes[0, 0], top.weights[0, 0], top.exponents[0, 0]):
    print(f"  top lobe: axis {axis.round(3).tolist()}, weight {weight:.3f}, exponent {eta:.4g}")
pyramid.write(out / "waves.map")

# %% [markdown]
# ## Rendering a scene file to a float image

# %%
(out / "gold.toml").write_text(glossy.toml)
(out / "scene.toml").write_text(
    '[camera]\nkind = "orthographic"\nposition = [0.0, 0.0, 5.0]\nlook_at = [0.0, 0.0, 0.0]\nwidth = 2.5\n'
    "[image]\nwidth = 64\nheight = 64\nspp = 4\n"
    '[[object]]\nkind = "sphere"\ncenter = [0.0, 0.0, 0.0]\nradius = 1.0\nmaterial = "gold.toml"\n'
    '[[light]]\nkind = "directional"\ndirection = [0.3, 0.4, 0.866]\nirradiance = [3.0, 3.0, 3.0]\n'
)
image = meso.render(out / "scene.toml")
print("rendered", image.shape, image.dtype, "mean radiance", image.mean(axis=(0, 1)).round(4))

# %% [markdown]
# ## Errors are Python exceptions with meso's message

# %%
try:
    meso.Material.from_params(ndf={"kind": "ggx", "alpha": -1}, transfer={"kind": "mirror"})
except meso.MesoError as e:
    print("MesoError:", e)
try:
    glossy.brdf(np.zeros((2, 2)), np.zeros((2, 2)))
except ValueError as e:
    print("ValueError:", e)
