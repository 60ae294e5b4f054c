"""Level.lobe_shares and Level.lobe_visibility (of one direction, or of a light and a viewer
together): what each lobe of a pyramid stands for (issue #11 item 1, meso_maps::lobe_stats), on touching half-cylinders and their negative (grooves: the same
normals, so the same NDF), where which normals are shadowed differs."""

from __future__ import annotations

import numpy as np
import pytest

import meso
from conftest import write_rgb8

PERIOD = 16


def cylinders(n: int = 64, sign: float = 1.0) -> np.ndarray:
    """Touching half-cylinders of radius PERIOD/2 along the image's columns (heights vary in x),
    or their negative (`sign = -1`: grooves)."""
    x = np.arange(n) % PERIOD + 0.5 - PERIOD / 2
    h = np.sqrt(np.maximum((PERIOD / 2) ** 2 - x**2, 0.0))
    return sign * np.tile(h, (n, 1))


def light(deg: float) -> list[float]:
    t = np.radians(deg)
    return [float(np.sin(t)), 0.0, float(np.cos(t))]


def flat_and_steep(level: meso.Level, w: list[float]) -> tuple[float, float]:
    """Share-weighted mean visibility towards `w` of the near-flat lobes (axis z > 0.95) and the
    steep ones (axis z < 0.7) over the level's texels."""
    shares, vis, z = level.lobe_shares, level.lobe_visibility(w), level.axes[..., 2]
    flat, steep = shares * (z > 0.95), shares * (z < 0.7)
    return float((flat * vis).sum() / flat.sum()), float((steep * vis).sum() / steep.sum())


@pytest.fixture(scope="module")
def pyramids():
    return {s: meso.extract(cylinders(sign=s), texel_size=1.0) for s in (1.0, -1.0)}


def test_shares_sum_to_one_and_pad_with_zeros(pyramids):
    for pyr in pyramids.values():
        for level in pyr.levels:
            s = level.lobe_shares
            assert s.shape == level.weights.shape and s.min() >= 0
            np.testing.assert_allclose(s.sum(axis=2), 1, atol=1e-9)
            k = np.arange(s.shape[2])
            assert not s[k[None, None, :] >= level.counts[:, :, None]].any()


def test_bumps_and_grooves_shadow_different_lobes(pyramids):
    # Light at 70° across the cylinders. On the bumps the steep normals lie in the creases
    # (shadowed) and the flat ones on the tops (lit); in the grooves the flat ones lie at the
    # bottoms (shadowed) and the steep ones at the rims (lit). At half a period and a period per
    # texel, with the same NDF, the lobes must say which are hidden (one visibility per texel
    # would give every lobe the same value).
    w = light(70)
    for level_index in (3, 4):
        bumps = flat_and_steep(pyramids[1.0].levels[level_index], w)
        grooves = flat_and_steep(pyramids[-1.0].levels[level_index], w)
        # Measured (flat, steep; each lobe's horizon distribution since 2026-12-07): bumps
        # (0.75, 0.17) and (0.81, 0.39), grooves (0.19, 0.56) and (0.19, 0.53) at levels 3 and 4
        # (with the ramp of pooled means and variances before: (0.73, 0.15), (0.68, 0.36),
        # (0.13, 0.56), (0.35, 0.55)).
        assert bumps[0] > bumps[1] + 0.25, (level_index, bumps)
        assert grooves[1] > grooves[0] + 0.15, (level_index, grooves)
        # The same normals, lit on the tops of the bumps and shadowed at the grooves' bottoms.
        assert bumps[0] > grooves[0] + 0.3, (level_index, bumps, grooves)


def test_light_and_viewer_together(pyramids):
    # A light 70° from the normal across the cylinders (+x) and a viewer 70° from it on the
    # other side (-x). A texel's lobes partition its cells, so the share-weighted fraction of a
    # level that sees both is the same at every level when pooled exactly: level 0's, whose
    # lobes stand for one cell each. The product of each lobe's two visibilities loses it from
    # level 3 on (the tops of the bumps see both ways, the bottoms of the grooves neither: they
    # go together); each lobe's joint distribution keeps it. Every lobe stays within the
    # Frechet bounds, and one direction twice is its visibility.
    w, o = light(70), [-light(70)[0], 0.0, light(70)[2]]

    def mean(level, v):
        return float((level.lobe_shares * v).sum() / level.lobe_shares.sum())

    for sign, pyr in pyramids.items():
        for level in pyr.levels:
            vw, vo = level.lobe_visibility(w), level.lobe_visibility(o)
            both = level.lobe_visibility(w, view=o)
            assert (both <= np.minimum(vw, vo) + 1e-12).all()
            assert (both >= np.maximum(vw + vo - 1, 0) - 1e-12).all()
            np.testing.assert_allclose(level.lobe_visibility(w, view=w), vw, atol=1e-12)
        want = mean(pyr.levels[0], pyr.levels[0].lobe_visibility(w, view=o))
        for level in pyr.levels[3:6]:
            joint = mean(level, level.lobe_visibility(w, view=o))
            product = mean(level, level.lobe_visibility(w) * level.lobe_visibility(o))
            # Measured (2026-12-07, level 0 reading its cells point by point, as the renderer
            # does, since the eleventh session; its cells' distributions multiplied gave 0.396
            # and 0.094 before): bumps 0.403 at level 0, the joint 0.390-0.396, the product
            # 0.347-0.365; grooves 0.103, 0.082-0.094, 0.041-0.055.
            assert abs(joint - want) < 0.025, (sign, level, joint, want)
            assert abs(product - want) > 2 * abs(joint - want), (sign, level, product, joint)
    # Directions are normalised, as Material.brdf's are; a zero one is refused.
    top = pyramids[1.0].top
    np.testing.assert_array_equal(top.lobe_visibility(w, view=[0.0, 0.0, 2.0]), top.lobe_visibility(w, view=[0.0, 0.0, 1.0]))
    with pytest.raises(ValueError, match="not a direction"):
        top.lobe_visibility(w, view=[0.0, 0.0, 0.0])


def test_a_plane_sees_everything():
    y, x = np.mgrid[0:32, 0:32].astype(float)
    pyr = meso.extract(0.1 * x, texel_size=1.0, border="clamp")
    for level in pyr.levels:
        np.testing.assert_allclose(level.lobe_visibility(light(60)), (level.weights > 0) * 1.0, atol=1e-9)
    np.testing.assert_array_equal(pyr.top.lobe_visibility([0.0, 0.0, 2.0]), pyr.top.lobe_visibility([0.0, 0.0, 1.0]))
    with pytest.raises(ValueError, match="not a direction"):
        pyr.top.lobe_visibility([0.0, np.nan, 1.0])
    # Below the horizon nothing sees, whatever the lobe.
    np.testing.assert_array_equal(pyr.top.lobe_visibility([0.0, 0.0, -1.0]), 0.0)


def test_a_normal_map_pyramid_has_shares_but_no_visibility(tmp_path):
    # A normal map (8-bit RGB, OpenGL convention) of gentle random slopes: no heights, so no
    # horizon statistics.
    rng = np.random.default_rng(2)
    n = np.dstack([rng.normal(0, 0.2, (32, 32, 2)), np.ones((32, 32))])
    n /= np.linalg.norm(n, axis=2, keepdims=True)
    write_rgb8(tmp_path / "n.png", np.round((n * 0.5 + 0.5) * 255).astype(np.uint8))
    pyr, _ = meso.extract_file(tmp_path / "n.png", tmp_path / "n.map", normal_map=True)
    for level in pyr.levels:
        np.testing.assert_allclose(level.lobe_shares.sum(axis=2), 1, atol=1e-9)
        assert level.lobe_visibility(light(45)) is None
