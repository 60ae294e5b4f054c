"""meso.batch on a LocalCluster of 3 worker processes: outputs byte-identical to the CLI's, bad
items reported, reruns skip, a killed worker and a killed client lose nothing and leave no partial
file. Needs dask[distributed] and the CLI binary (MESO_BIN, default target/release/meso)."""

from __future__ import annotations

import json
import os
import signal
import struct
import subprocess
import sys
import time
import zlib
from pathlib import Path

import numpy as np
import pytest

distributed = pytest.importorskip("distributed")
import meso  # noqa: E402
import meso.batch as batch  # noqa: E402

REPO = Path(__file__).resolve().parents[3]
MESO_BIN = Path(os.environ.get("MESO_BIN", REPO / "target" / "release" / "meso"))
TEXEL, SCALE = 0.5, 0.25
N_GOOD = 24
N = 32  # height-map side


def write_png(path: Path, a: np.ndarray) -> None:
    """A PNG of `a`: (h, w) uint16 → 16-bit grey, (h, w, 3) uint8 → RGB8."""
    if a.ndim == 2:
        color, raw_rows = 0, [r.astype(">u2").tobytes() for r in a]
        depth = 16
    else:
        color, raw_rows = 2, [r.astype(np.uint8).tobytes() for r in a]
        depth = 8
    h, w = a.shape[:2]

    def chunk(tag: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data))

    raw = b"".join(b"\0" + r for r in raw_rows)
    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, depth, color, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b"")
    path.write_bytes(png)


def height_map(seed: int, n: int = N) -> np.ndarray:
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:n, 0:n] / n
    z = np.zeros((n, n))
    for _ in range(4):
        fx, fy = rng.integers(1, 4, 2)
        z += rng.uniform(0.2, 1) * np.sin(2 * np.pi * (fx * x + fy * y) + rng.uniform(0, 6))
    z += 0.2 * rng.standard_normal((n, n))
    z = (z - z.min()) / (z.max() - z.min())
    return np.round(z * 65535).astype(np.uint16)


def normal_map(seed: int, n: int = N) -> np.ndarray:
    rng = np.random.default_rng(seed)
    v = np.dstack([rng.normal(0, 0.3, (n, n)), rng.normal(0, 0.3, (n, n)), np.ones((n, n))])
    v /= np.linalg.norm(v, axis=2, keepdims=True)
    return np.round((v * 0.5 + 0.5) * 255).astype(np.uint8)


def make_maps(folder: Path, count: int, seed0: int = 0) -> list:
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for i in range(count):
        p = folder / f"h{seed0 + i:03d}.png"
        write_png(p, height_map(seed0 + i))
        paths.append(p)
    return paths


def cli(*args) -> None:
    r = subprocess.run([str(MESO_BIN), *map(str, args)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr


def cli_extract(img: Path, out: Path) -> bytes:
    cli("extract", img, "--texel-size", TEXEL, "--height-scale", SCALE, "--out", out)
    return out.read_bytes()


def leftovers(out: Path) -> list:
    return [p.name for p in out.iterdir()
            if p.name.startswith(batch.TMP_PREFIX) or (p.name.startswith(".") and p.name.endswith(".tmp"))]


def outputs_by_input(summary) -> dict:
    return {r["input"]: r["output"] for r in summary.items if r["status"] in ("done", "skipped")}


@pytest.fixture(scope="module")
def client():
    from distributed import Client, LocalCluster

    cluster = LocalCluster(n_workers=3, threads_per_worker=1, processes=True,
                           dashboard_address=None, env={"RAYON_NUM_THREADS": "1"})
    c = Client(cluster)
    yield c
    c.close()
    cluster.close()


@pytest.fixture(scope="module")
def cli_bin():
    if not MESO_BIN.is_file():
        pytest.skip(f"{MESO_BIN}: no CLI binary (cargo build --release -p meso-cli, or set MESO_BIN)")
    return MESO_BIN


@pytest.fixture(scope="module")
def first_batch(tmp_path_factory, client, cli_bin):
    """(a) ~30 items, good and bad, through the batch; returns what the checks need."""
    d = tmp_path_factory.mktemp("a")
    good = make_maps(d / "in", N_GOOD)
    nm = d / "in" / "normals.png"
    write_png(nm, normal_map(7))
    corrupt = d / "in" / "corrupt.png"
    corrupt.write_bytes(b"\x89PNG\r\n\x1a\nthis is not a png")
    items = [{"input": f"in/{p.name}"} for p in good]
    items += [
        {"input": "in/normals.png", "params": {"normal_map": True, "texel_size": None,
                                                "height_scale": None}},
        {"input": "in/normals.png", "op": "export", "params": {"texel_size": None,
                                                               "height_scale": None}},
        {"input": f"in/{good[0].name}", "op": "export"},
        {"input": "in/missing.png"},
        {"input": "in/corrupt.png"},
        {"input": f"in/{good[1].name}", "max_lobes": 99},
        {"input": f"in/{good[2].name}", "op": "bake"},
    ]
    manifest = d / "manifest.json"
    manifest.write_text(json.dumps({"defaults": {"texel_size": TEXEL, "height_scale": SCALE},
                                    "items": items}))
    out = d / "out"
    s = batch.run(manifest, out, client=client, progress=False)
    return {"dir": d, "good": good, "normals": nm, "out": out, "summary": s, "manifest": manifest}


def test_batch_outputs_match_cli_and_bad_items_reported(first_batch):
    s, out, d = first_batch["summary"], first_batch["out"], first_batch["dir"]
    assert (s.total, s.done, s.skipped, s.failed) == (N_GOOD + 7, N_GOOD + 3, 0, 4), s.text()
    by_input = {r["input"]: r for r in s.items}
    ref = d / "ref"
    ref.mkdir()
    for p in first_batch["good"]:
        rec = [r for r in s.items if r["input"] == str(p) and r["op"] == "extract"
               and r["status"] == "done"]
        assert len(rec) == 1
        assert (out / rec[0]["output"]).read_bytes() == cli_extract(p, ref / (p.stem + ".map"))
    # normal-map extraction, and both exports, against the CLI
    nm = first_batch["normals"]
    recs = [r for r in s.items if r["input"] == str(nm)]
    ext = [r for r in recs if r["op"] == "extract"][0]
    cli("extract", nm, "--normal-map", "--out", ref / "nm.map")
    assert (out / ext["output"]).read_bytes() == (ref / "nm.map").read_bytes()
    exp = [r for r in recs if r["op"] == "export"][0]
    cli("export", nm, "--out", ref / "nm-export")
    assert_same_dir(out / exp["output"], ref / "nm-export")
    h0 = first_batch["good"][0]
    exp = [r for r in s.items if r["input"] == str(h0) and r["op"] == "export"][0]
    cli("export", h0, "--texel-size", TEXEL, "--height-scale", SCALE, "--out", ref / "h-export")
    assert_same_dir(out / exp["output"], ref / "h-export")
    # bad items: reported with their file named, nothing written for them
    fails = {f["input"]: f["error"] for f in s.failures}
    assert "missing.png" in fails[str(d / "in" / "missing.png")]
    assert "corrupt.png" in fails[str(d / "in" / "corrupt.png")]
    assert any("max_lobes" in e for e in fails.values())
    assert any("unknown operation 'bake'" in e for e in fails.values())
    assert all(by_input[k]["status"] == "failed" for k in fails)
    assert "missing.png" in s.text() and "corrupt.png" in s.text()
    report = json.loads((out / batch.REPORT_NAME).read_text())
    assert report["failed"] == 4 and len(report["items"]) == s.total
    assert leftovers(out) == []
    names = sorted(p.name for p in out.iterdir())
    assert len([n for n in names if n.endswith(".map")]) == N_GOOD + 1
    # the output name is content-hashed: the same bytes under another name hash the same
    assert all(len(r["hash"]) == 64 for r in s.items if r["status"] == "done")


def assert_same_dir(a: Path, b: Path) -> None:
    fa, fb = sorted(p.name for p in a.iterdir()), sorted(p.name for p in b.iterdir())
    assert fa == fb and fa
    for n in fa:
        assert (a / n).read_bytes() == (b / n).read_bytes(), n


def test_rerun_skips_everything(first_batch, client):
    out = first_batch["out"]
    before = {p.name: p.stat().st_mtime_ns for p in out.iterdir() if p.name != batch.REPORT_NAME}
    s = batch.run(first_batch["manifest"], out, client=client, progress=False)
    assert (s.done, s.skipped, s.failed) == (0, N_GOOD + 3, 4), s.text()
    after = {p.name: p.stat().st_mtime_ns for p in out.iterdir() if p.name != batch.REPORT_NAME}
    assert after == before
    # a directory of the same images with the same parameters maps to the same outputs
    s2 = batch.run(first_batch["dir"] / "in", out, address=client.scheduler.address, progress=False,
                   params={"texel_size": TEXEL, "height_scale": SCALE}, glob="h*.png")
    assert (s2.done, s2.skipped, s2.failed) == (0, N_GOOD, 0), s2.text()


def test_killed_worker_loses_nothing(tmp_path, client, cli_bin):
    import threading

    maps = make_maps(tmp_path / "in", 12, seed0=100)
    out = tmp_path / "out"
    pids = list(client.run(os.getpid).values())
    assert len(pids) == 3
    res = {}
    t = threading.Thread(target=lambda: res.update(s=batch.run(
        tmp_path / "in", out, client=client, progress=False, _delay=0.4,
        params={"texel_size": TEXEL, "height_scale": SCALE})))
    t.start()
    deadline = time.time() + 30
    while time.time() < deadline and not (out.exists() and any(out.glob("*.map"))):
        time.sleep(0.02)
    os.kill(pids[0], signal.SIGKILL)
    t.join(60)
    assert not t.is_alive()
    s = res["s"]
    # an item whose output was in place when its worker died is skipped by the retry
    assert (s.done + s.skipped, s.failed) == (12, 0), s.text()
    assert pids[0] not in client.run(os.getpid).values()
    outs = outputs_by_input(s)
    for p in maps:
        assert (out / outs[str(p)]).read_bytes() == cli_extract(p, tmp_path / "ref.map")
    assert leftovers(out) == []


def test_killed_client_then_rerun_finishes(tmp_path, client, cli_bin):
    import psutil

    maps = make_maps(tmp_path / "in", 16, seed0=200)
    out = tmp_path / "out"
    code = (
        "import meso.batch as b\n"
        f"b.run({str(tmp_path / 'in')!r}, {str(out)!r}, workers=2, progress=False, _delay=0.5,"
        f" params={{'texel_size': {TEXEL}, 'height_scale': {SCALE}}})\n"
    )
    proc = subprocess.Popen([sys.executable, "-c", code])
    try:
        deadline = time.time() + 60
        while time.time() < deadline and not (out.exists() and len(list(out.glob("*.map"))) >= 3):
            time.sleep(0.05)
        children = psutil.Process(proc.pid).children(recursive=True)
        proc.send_signal(signal.SIGKILL)
        for c in children:
            try:
                c.send_signal(signal.SIGKILL)
            except psutil.NoSuchProcess:
                pass
        proc.wait(10)
    finally:
        if proc.poll() is None:
            proc.kill()
    present = len(list(out.glob("*.map")))
    assert 3 <= present < len(maps)
    s = batch.run(tmp_path / "in", out, client=client, progress=False,
                  params={"texel_size": TEXEL, "height_scale": SCALE})
    assert s.failed == 0 and s.skipped >= present and s.done + s.skipped == len(maps), s.text()
    outs = outputs_by_input(s)
    for p in maps:
        assert (out / outs[str(p)]).read_bytes() == cli_extract(p, tmp_path / "ref.map")
    assert leftovers(out) == []
    assert len(list(out.glob("*.map"))) == len(maps)


def test_cli_entry_and_exit_status(tmp_path, cli_bin):
    """`python -m meso.batch` on a CSV manifest with a bad row: exit status 1, summary printed."""
    make_maps(tmp_path, 2, seed0=300)
    (tmp_path / "m.csv").write_text(
        "input,op,texel_size,height_scale,max_lobes\n"
        f"h300.png,extract,{TEXEL},{SCALE},\n"
        f"h301.png,extract,{TEXEL},{SCALE},2\n"
        f"nope.png,extract,{TEXEL},{SCALE},\n"
    )
    r = subprocess.run([sys.executable, "-m", "meso.batch", str(tmp_path / "m.csv"), "--out",
                        str(tmp_path / "o"), "--workers", "1", "--quiet"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 1, r.stdout + r.stderr
    assert "2 done" in r.stdout and "1 failed" in r.stdout and "nope.png" in r.stdout


def test_item_key_is_content_and_parameter_hash(tmp_path):
    (p,) = make_maps(tmp_path, 1)
    it = batch.Item(0, str(p), "extract", {"texel_size": TEXEL, "height_scale": SCALE}, str(tmp_path))
    k1 = batch.item_key(it)[2]
    it2 = batch.Item(0, str(p), "extract", {"texel_size": str(TEXEL), "height_scale": SCALE,
                                             "border": "wrap"}, str(tmp_path))
    assert batch.item_key(it2)[2] == k1  # defaults and spelling do not change the key
    it3 = batch.Item(0, str(p), "extract", {"texel_size": TEXEL, "height_scale": SCALE * 2},
                     str(tmp_path))
    assert batch.item_key(it3)[2] != k1
    assert batch.item_key(it, version="0.0.0-other")[2] != k1


def test_one_run_per_out_dir_and_leftovers_removed(tmp_path):
    import fcntl

    out = tmp_path / "out"
    out.mkdir()
    (out / ".h000-0123456789abcdef.map.AbC123.tmp").write_bytes(b"partial")
    (out / f"{batch.TMP_PREFIX}0123456789abcdef-1234abcd").mkdir()
    with open(out / batch.LOCK_NAME, "a+") as lock:
        fcntl.flock(lock.fileno(), fcntl.LOCK_EX)
        with pytest.raises(RuntimeError, match="another meso batch"):
            batch.run([], out, progress=False)
    assert len(leftovers(out)) == 2  # a running batch's temporaries are not touched
    assert batch.clean_temps(out) == 2 and leftovers(out) == []


def test_fit_items_equal_meso_fit(tmp_path, client):
    """`op = "fit"`: measured data (sample CSVs) fitted on the cluster; each output is the material
    `meso.fit` writes for the same file (the fit is deterministic; only the time in its header
    comment differs), and a rerun skips them."""
    import re

    import meso

    truth = meso.Material.from_params(
        form="microfacet", ndf={"kind": "ggx", "alpha": 0.25}, transfer={"kind": "mirror"},
        diffuse=[0.2, 0.2, 0.2],
    )
    rng = np.random.default_rng(5)
    (tmp_path / "in").mkdir()
    for k in range(3):
        t = rng.uniform(2, 75, (600, 2))
        p = rng.uniform(0, 360, (600, 2))
        rad = np.radians
        wi = np.column_stack([np.sin(rad(t[:, 0])) * np.cos(rad(p[:, 0])), np.sin(rad(t[:, 0])) * np.sin(rad(p[:, 0])), np.cos(rad(t[:, 0]))])
        wo = np.column_stack([np.sin(rad(t[:, 1])) * np.cos(rad(p[:, 1])), np.sin(rad(t[:, 1])) * np.sin(rad(p[:, 1])), np.cos(rad(t[:, 1]))])
        f = truth.brdf(wi, wo) * (1 + 0.1 * k)
        rows = np.column_stack([t[:, 0], p[:, 0], t[:, 1], p[:, 1], f])
        (tmp_path / "in" / f"m{k}.csv").write_text(
            "theta_i,phi_i,theta_o,phi_o,r,g,b\n" + "".join(",".join(repr(float(x)) for x in r) + "\n" for r in rows)
        )
    out = tmp_path / "out"
    s = batch.run(tmp_path / "in", out, client=client, op="fit", params={"lobes": 1}, glob="*.csv", progress=False)
    assert (s.done, s.failed) == (3, 0), s.text()
    strip = lambda text: re.sub(r" in [0-9.]+ s, ", " in <t> s, ", text)  # noqa: E731
    for r in s.items:
        written = (out / r["output"]).read_text()
        _, report = meso.fit(r["input"], lobes=1)
        assert strip(written) == strip(report["toml"]), r["input"]
    again = batch.run(tmp_path / "in", out, client=client, op="fit", params={"lobes": 1}, glob="*.csv", progress=False)
    assert (again.done, again.skipped) == (0, 3), again.text()
    # `lobes = "auto"` (a manifest or --lobes auto) is a parameter set of its own.
    auto = batch.run(tmp_path / "in", out, client=client, op="fit", params={"lobes": "auto", "transfer": "microfacet"},
                     glob="*.csv", progress=False)
    assert (auto.done, auto.failed) == (3, 0), auto.text()
    for r in auto.items:
        _, report = meso.fit(r["input"], lobes="auto", transfer="microfacet")
        assert strip((out / r["output"]).read_text()) == strip(report["toml"]), r["input"]
