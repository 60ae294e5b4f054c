"""Absurd but finite values through the Python API get the CLI's checks and messages (the CLI
audit's item 8): no NaN results, ValueError for a budget that is not one."""

from __future__ import annotations

import math

import numpy as np
import pytest

import meso


def test_extract_shares_the_cli_scale_range():
    h = np.zeros((8, 8))
    h[2:5, 3:6] = 1.0
    with pytest.raises(ValueError, match=r"height_scale = 1e300 must be between 1e-12 and 1e12"):
        meso.extract(h, texel_size=0.01, height_scale=1e300)
    with pytest.raises(ValueError, match=r"texel_size = 1e-20 must be between"):
        meso.extract(h, texel_size=1e-20, height_scale=1.0)
    with pytest.raises(ValueError, match=r"height_scale / texel_size = 1e8 must be at most 1e6"):
        meso.extract(h, texel_size=0.01, height_scale=1e6)
    meso.extract(h, texel_size=0.01, height_scale=0.05)


@pytest.mark.parametrize(
    "size, message",
    [
        (0, "a memory budget must be at least 1 byte"),
        ("0", "a memory budget must be at least 1 byte"),
        (-1, "not a size"),
        ("-1", "not a size"),
        (0.25, "a memory budget must be at least 1 byte"),
        (True, "not a size"),
    ],
)
def test_memory_budgets_that_are_not_sizes_are_value_errors(size, message):
    try:
        with pytest.raises(ValueError, match=message):
            meso.set_memory_budget(size)
    finally:
        meso.set_memory_budget("4G")


def test_memory_budget_of_another_type_is_a_type_error():
    with pytest.raises(TypeError, match="a memory budget is a number of bytes"):
        meso.set_memory_budget([1])
    meso.set_memory_budget(1 << 30)
    meso.set_memory_budget("4G")


def test_material_toml_writes_a_huge_vector_axis_as_its_direction():
    text = meso.material_toml(
        ndf={"kind": "phong-peaks", "lobes": [{"axis": [1e300, 1e300, 1e300], "weight": 1, "exponent": 10}]},
        transfer={"kind": "phong", "exponent": 10},
    )
    assert "nan" not in text.lower(), text
    m = meso.Material.from_toml(text)
    d = math.degrees(math.acos(1 / math.sqrt(3)))
    # The axis reads back as the diagonal: the lobe peaks there.
    wi = np.array([[math.sin(math.radians(d)) * math.cos(math.pi / 4),
                    math.sin(math.radians(d)) * math.sin(math.pi / 4),
                    math.cos(math.radians(d))]])
    v = m.brdf(wi, wi)
    assert np.all(np.isfinite(v)), v
