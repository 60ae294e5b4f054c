"""meso.export against the CLI: the same bytes for an anisotropic export, a material-file export
and an export with a lobe pyramid (``--lobes``); map options refused for a material file; and
meso.batch's ``export`` passing ``anisotropic`` and ``lobes`` through (its item normalisation and
call, without a cluster)."""

from __future__ import annotations

import pathlib

import pytest

import meso
import meso.batch as batch
from conftest import bumps, run_cli, write_gray16

GGX = (
    'form = "microfacet"\n[ndf]\nkind = "ggx"\nalpha = 0.09\n[transfer]\nkind = "mirror"\n'
    'fresnel = "schlick"\nf0 = [0.04, 0.04, 0.04]\n[shadowing]\nkind = "smith"\n'
    "[diffuse]\nalbedo = [0.5, 0.3, 0.2]\n"
)


def same_folders(a: pathlib.Path, b: pathlib.Path) -> list[str]:
    names = sorted(p.name for p in a.iterdir())
    assert names == sorted(p.name for p in b.iterdir())
    for name in names:
        assert (a / name).read_bytes() == (b / name).read_bytes(), name
    return names


def test_anisotropic_export_equals_the_cli(tmp_path):
    write_gray16(tmp_path / "h.png", bumps(32, seed=4))
    files, levels, _ = meso.export(tmp_path / "h.png", tmp_path / "py", texel_size=1.0,
                                   height_scale=3.0, alpha=0.05, anisotropic=True)
    run_cli("export", tmp_path / "h.png", "--out", tmp_path / "cli", "--texel-size", 1.0,
            "--height-scale", 3.0, "--alpha", 0.05, "--anisotropic")
    names = same_folders(tmp_path / "py", tmp_path / "cli")
    assert "anisotropy.ktx2" in names and len(files) == len(names)
    # The level dicts carry the anisotropic columns of errors.csv; no width below the base α.
    assert all("mean_alpha_t" in l and l["mean_alpha"] >= 0.05 - 1e-9 for l in levels)


def test_material_file_export_equals_the_cli(tmp_path):
    (tmp_path / "ggx.toml").write_text(GGX)
    files, levels, warnings = meso.export(tmp_path / "ggx.toml", tmp_path / "py")
    r = run_cli("export", tmp_path / "ggx.toml", "--out", tmp_path / "cli")
    same_folders(tmp_path / "py", tmp_path / "cli")
    assert levels[0]["width"] == 4 and "engine" in warnings[0]
    assert warnings[0] in r.stderr
    # Map options are refused by name, even at a map export's default values.
    for kw, name in [({"alpha": 0.1}, "alpha"), ({"convention": "gl"}, "convention"),
                     ({"metallic": 0.0}, "metallic"), ({"anisotropic": True}, "anisotropic")]:
        with pytest.raises(meso.MesoError, match=name) as e:
            meso.export(tmp_path / "ggx.toml", tmp_path / "refused", **kw)
        assert "ggx.toml" in str(e.value)
        assert not (tmp_path / "refused").exists()


def lobes_setup(tmp_path: pathlib.Path) -> tuple[pathlib.Path, pathlib.Path]:
    write_gray16(tmp_path / "h.png", bumps(16, seed=2))
    meso.extract_file(tmp_path / "h.png", tmp_path / "h.map", texel_size=1.0, height_scale=2.0,
                      max_lobes=2)
    return tmp_path / "h.png", tmp_path / "h.map"


def test_lobes_export_equals_the_cli(tmp_path):
    h, m = lobes_setup(tmp_path)
    meso.export(h, tmp_path / "py", texel_size=1.0, height_scale=2.0, lobes=m)
    run_cli("export", h, "--out", tmp_path / "cli", "--texel-size", 1.0, "--height-scale", 2.0,
            "--lobes", m)
    names = same_folders(tmp_path / "py", tmp_path / "cli")
    assert "lobes0_mip4.png" in names and "meso_lobes.wgsl" in names
    # The map file given as the image: what to do instead.
    with pytest.raises(meso.MesoError, match="is a meso map file"):
        meso.export(m, tmp_path / "bad")


def test_batch_export_passes_anisotropic_and_lobes_through(tmp_path):
    h, m = lobes_setup(tmp_path)
    item = batch.Item(0, str(h), "export", {"texel_size": 1, "height_scale": 2,
                                            "anisotropic": "true", "lobes": "h.map"},
                      str(tmp_path))
    op, params = batch._normalise(item)
    assert params["anisotropic"] is True and params["lobes"] == str(m.resolve())
    op.call(str(h), str(tmp_path / "batch"), **params)
    run_cli("export", h, "--out", tmp_path / "cli", "--texel-size", 1.0, "--height-scale", 2.0,
            "--anisotropic", "--lobes", m)
    names = same_folders(tmp_path / "batch", tmp_path / "cli")
    assert "anisotropy.ktx2" in names and "lobes0_mip0.png" in names
    # A material-file item exports with the batch's defaults (none of the map options given).
    (tmp_path / "ggx.toml").write_text(GGX)
    item = batch.Item(1, str(tmp_path / "ggx.toml"), "export", {}, str(tmp_path))
    op, params = batch._normalise(item)
    op.call(str(tmp_path / "ggx.toml"), str(tmp_path / "batch-mat"), **params)
    run_cli("export", tmp_path / "ggx.toml", "--out", tmp_path / "cli-mat")
    same_folders(tmp_path / "batch-mat", tmp_path / "cli-mat")


def test_outputs_never_replace_their_inputs(tmp_path):
    """As the CLI: extract_file refuses to write its map over the image it reads, and export
    refuses an output folder where one of its files would replace the input (ValueError / the
    meso error, naming the clash), leaving the input byte for byte."""
    h = tmp_path / "h.png"
    write_gray16(h, bumps(16, seed=7))
    before = h.read_bytes()
    with pytest.raises(ValueError, match="same file as the input"):
        meso.extract_file(h, h, texel_size=1.0, height_scale=1.0)
    assert h.read_bytes() == before
    out = tmp_path / "out"
    out.mkdir()
    inside = out / "normal_mip0.png"  # a height map, under a name the export writes
    inside.write_bytes(before)
    names_before = sorted(p.name for p in out.iterdir())
    with pytest.raises(Exception, match="same file as the input"):
        meso.export(inside, out, texel_size=1.0, height_scale=1.0)
    assert inside.read_bytes() == before
    assert sorted(p.name for p in out.iterdir()) == names_before


def test_a_second_export_warns_of_the_earlier_ones_files(tmp_path):
    # A 64² height map exported, then a 16² one into the same folder: the first one's extra mip
    # levels stay (nothing removed) and the warnings name them, as the CLI's warning line does.
    write_gray16(tmp_path / "big.png", bumps(64, seed=5))
    write_gray16(tmp_path / "small.png", bumps(16, seed=6))
    out = tmp_path / "out"
    _, _, warnings = meso.export(tmp_path / "big.png", out, texel_size=1.0, height_scale=2.0)
    assert not any("earlier export" in w for w in warnings)
    _, _, warnings = meso.export(tmp_path / "small.png", out, texel_size=1.0, height_scale=2.0)
    stale = [w for w in warnings if "earlier export" in w]
    assert len(stale) == 1 and "normal_mip6.png" in stale[0] and "normal_mip4.png" not in stale[0]
    assert (out / "normal_mip6.png").exists()
