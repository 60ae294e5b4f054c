"""meso.batch — many height maps or normal maps through meso on a Dask cluster.

``meso.batch.run(manifest_or_dir, out_dir, address=None, workers=None, ...)`` runs one meso
operation per item on a Dask (``distributed``) cluster: the scheduler at ``address``
(``tcp://host:8786``), or a :class:`distributed.LocalCluster` of worker processes started for the
run. The command line is ``python -m meso.batch MANIFEST_OR_DIR --out DIR`` (or ``meso-batch``);
docs/batch.md is the guide.

Items
    A **manifest** (``.json`` or ``.csv``) lists items: an input path (relative paths are relative to
    the manifest's folder), an operation (``op``: ``extract`` or ``export``, see
    :data:`OPERATIONS`) and that operation's parameters (the keyword arguments of
    :func:`meso.extract_file` / :func:`meso.export`). JSON is a list of items or
    ``{"defaults": {...}, "items": [...]}``; an item is ``{"input": ..., "op": ..., "params":
    {...}}`` (parameters may also be written beside ``input``). CSV has a header with ``input``,
    optionally ``op``, and one column per parameter (an empty cell leaves the default). A
    **directory** gives every image in it (``glob``) with the parameters given to :func:`run`.

Guarantees
    * idempotent — an output is named ``STEM-HASH.map`` (``extract``) or ``STEM-HASH/``
      (``export``), HASH the SHA-256 of the input bytes (and of the other input files an item
      names), the operation, its parameters with defaults filled in, and the meso version. An
      output already present is complete (see atomic) and its item is *skipped*;
    * atomic — ``extract`` writes through meso's own atomic write (a ``.NAME.XXXXXX.tmp`` file in
      ``out_dir`` renamed over the name); ``export`` writes into a temporary directory
      ``.meso-batch-tmp-…`` in ``out_dir`` that is renamed to its name once complete. Temporary
      files and directories left by killed runs are removed when the next run starts (a lock file
      keeps two runs off one ``out_dir``);
    * resumable — a task whose worker dies is rescheduled by Dask on another worker, exceptions other
      than the item's own errors are retried (``retries``), and a rerun after a dead client only
      computes the outputs that are missing;
    * per-item errors — a missing file, an unreadable image or a bad parameter fails that item only
      (``MesoError`` / ``ValueError`` / ``FileNotFoundError`` with meso's message, which names the
      file); the summary lists them, the exit status of the command is 1 when any item failed.

:func:`run` returns a :class:`Summary` and writes it, with one record per item, to
``out_dir/meso-batch-report.json``.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import fcntl
import hashlib
import json
import os
import shutil
import sys
import time
import uuid
from pathlib import Path
from typing import Any, Callable, Dict, Iterable, List, Optional, Sequence, Union

__all__ = ["OPERATIONS", "Item", "Operation", "Summary", "load_items", "main", "run"]

REPORT_NAME = "meso-batch-report.json"
LOCK_NAME = ".meso-batch.lock"
TMP_PREFIX = ".meso-batch-tmp-"
IMAGE_SUFFIXES = (".png", ".tif", ".tiff", ".exr", ".pfm", ".hdr", ".jpg", ".jpeg", ".bmp", ".tga")

# --------------------------------------------------------------------------------------------
# Operations: what a manifest's `op` may name. Adding one = one `Operation` in OPERATIONS.
# --------------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Operation:
    """One operation a manifest may name.

    ``params``: name → (type, default) (type one of ``float``, ``int``, ``bool``, ``str``,
    ``"lobes"`` — an int or ``"auto"``, ``"path"`` — a further input file whose bytes go into
    the hash); ``output``: ``"file"``
    (``call(input, out_path, **params)`` writes one file atomically) or ``"dir"`` (``call`` writes
    the files of a new directory ``out_path``, made atomic here); ``suffix`` ends a file output's
    name.
    """

    name: str
    params: Dict[str, tuple]
    output: str
    suffix: str
    call: Callable[..., Any]


def _extract(path: str, out: str, **p: Any) -> dict:
    import meso

    pyr, warnings = meso.extract_file(path, out, **p)
    return {"warnings": list(warnings), "levels": len(pyr), "size": [pyr.width, pyr.height]}


def _export(path: str, out: str, **p: Any) -> dict:
    import meso

    files, _levels, warnings = meso.export(path, out, **p)
    return {"warnings": list(warnings), "files": [os.path.basename(f) for f in files]}


def _fit(path: str, out: str, **p: Any) -> dict:
    import meso

    _material, report = meso.fit(path, out=out, **p)
    return {"lobes": report["lobes"], "held_out": report["held_out"], "description": report["description"]}


OPERATIONS: Dict[str, Operation] = {
    "extract": Operation(
        "extract",
        {
            "texel_size": (float, None),
            "height_scale": (float, None),
            "max_lobes": (int, None),
            "normal_map": (bool, False),
            "convention": (str, "gl"),
            "border": (str, "wrap"),
            "normals": (str, "triangles"),
            "method": (str, "lobes"),
        },
        "file",
        ".map",
        _extract,
    ),
    "export": Operation(
        "export",
        {
            "texel_size": (float, None),
            "height_scale": (float, None),
            "convention": (str, None),
            "alpha": (float, None),
            "roughness_map": ("path", None),
            "metallic": (float, None),
            "base_color": ("path", None),
            "anisotropic": (bool, False),
            "lobes": ("path", None),
        },
        "dir",
        "",
        _export,
    ),
    "fit": Operation(
        "fit",
        {
            "lobes": ("lobes", "auto"),
            "transfer": (str, "auto"),
            "metric": (str, "both"),
            "axes": (str, "auto"),
            "samples": (int, 30000),
        },
        "file",
        ".toml",
        _fit,
    ),
}


class ItemError(Exception):
    """A problem of one item (reported, the batch goes on)."""


def _convert(op: Operation, name: str, value: Any, base: Path) -> Any:
    if name not in op.params:
        raise ItemError(
            f"{op.name}: unknown parameter {name!r} (known: {', '.join(sorted(op.params))})"
        )
    kind, _ = op.params[name]
    if value is None or (isinstance(value, str) and value.strip() == ""):
        return None
    try:
        if kind is bool:
            if isinstance(value, str):
                v = value.strip().lower()
                if v in ("1", "true", "yes", "on"):
                    return True
                if v in ("0", "false", "no", "off"):
                    return False
                raise ValueError(value)
            if isinstance(value, (bool, int)) and value in (0, 1):
                return bool(value)
            raise ValueError(value)
        if kind == "lobes":  # a count, or "auto"
            if isinstance(value, str) and value.strip().lower() == "auto":
                return "auto"
            kind = int
        if kind is int:
            if isinstance(value, bool) or (isinstance(value, float) and not value.is_integer()):
                raise ValueError(value)
            return int(value)
        if kind is float:
            if isinstance(value, bool):
                raise ValueError(value)
            return float(value)
        if kind == "path":
            p = Path(os.path.expanduser(str(value)))
            return str(p if p.is_absolute() else (base / p).resolve())
        return str(value)
    except (TypeError, ValueError):
        tname = kind if isinstance(kind, str) else kind.__name__
        raise ItemError(f"{op.name}: parameter {name} = {value!r} is not a {tname}") from None


@dataclasses.dataclass
class Item:
    """One unit of work: ``op`` applied to ``input`` with ``params`` (raw, as written), or an
    ``error`` found while reading the manifest."""

    index: int
    input: str
    op: str
    params: Dict[str, Any]
    base: str  # folder relative paths in params resolve against
    error: Optional[str] = None


def _normalise(item: Item) -> tuple:
    """``(Operation, params with defaults filled in and types fixed)``, or raise ItemError."""
    if item.error:
        raise ItemError(item.error)
    op = OPERATIONS.get(item.op)
    if op is None:
        raise ItemError(f"unknown operation {item.op!r} (known: {', '.join(sorted(OPERATIONS))})")
    params = {k: d for k, (_, d) in op.params.items()}
    for k, v in item.params.items():
        params[k] = _convert(op, k, v, Path(item.base))
    return op, params


# --------------------------------------------------------------------------------------------
# Reading manifests and directories.
# --------------------------------------------------------------------------------------------


def _resolve(path: str, base: Path) -> str:
    p = Path(os.path.expanduser(str(path)))
    return str(p if p.is_absolute() else (base / p).absolute())


def load_items(
    source: Union[str, os.PathLike],
    op: Optional[str] = None,
    params: Optional[Dict[str, Any]] = None,
    glob: str = "*",
) -> List[Item]:
    """The items of a manifest (``.json``/``.csv``) or of a directory of images. ``op`` and
    ``params`` are the defaults an item does not override (for a directory: the one set of
    parameters)."""
    src = Path(source)
    default_op = op or "extract"
    defaults = dict(params or {})
    items: List[Item] = []
    if src.is_dir():
        base = src.absolute()
        paths = sorted(
            p
            for p in src.glob(glob)
            if p.is_file()
            and not p.name.startswith(".")
            and (glob != "*" or p.suffix.lower() in IMAGE_SUFFIXES)
        )
        for i, p in enumerate(paths):
            items.append(Item(i, str(p.absolute()), default_op, dict(defaults), str(base)))
        return items
    if not src.exists():
        raise FileNotFoundError(f"{src}: no such manifest or directory")
    base = src.absolute().parent
    suffix = src.suffix.lower()
    if suffix == ".json":
        with open(src, encoding="utf-8") as f:
            try:
                doc = json.load(f)
            except json.JSONDecodeError as e:
                raise ValueError(f"{src}: not valid JSON: {e}") from None
        if isinstance(doc, dict):
            defaults.update(doc.get("defaults", {}) or {})
            default_op = doc.get("op", defaults.pop("op", default_op))
            rows = doc.get("items")
        else:
            rows = doc
        if not isinstance(rows, list):
            raise ValueError(f"{src}: expected a list of items or {{\"items\": [...]}}")
        raw: Iterable[Any] = rows
    elif suffix == ".csv":
        with open(src, encoding="utf-8", newline="") as f:
            reader = csv.DictReader(f)
            if not reader.fieldnames or "input" not in reader.fieldnames:
                raise ValueError(f"{src}: the CSV header needs an 'input' column")
            raw = [
                {k.strip(): v for k, v in row.items() if k and v is not None and v.strip() != ""}
                for row in reader
            ]
    else:
        raise ValueError(f"{src}: a manifest is a .json or .csv file, or a directory of images")
    for i, row in enumerate(raw):
        if isinstance(row, str):
            row = {"input": row}
        if not isinstance(row, dict) or "input" not in row:
            items.append(Item(i, f"<item {i}>", default_op, {}, str(base),
                              error=f"{src}: item {i} has no 'input'"))
            continue
        row = dict(row)
        inp = _resolve(row.pop("input"), base)
        item_op = row.pop("op", None) or default_op
        p = dict(defaults)
        extra = row.pop("params", None) or {}
        p.update(row)
        p.update(extra)
        p.pop("op", None)
        items.append(Item(i, inp, item_op, p, str(base)))
    return items


# --------------------------------------------------------------------------------------------
# The task: runs on a worker.
# --------------------------------------------------------------------------------------------


def _sha256_file(path: str, h: "hashlib._Hash") -> None:
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)


def item_key(item: Item, version: Optional[str] = None) -> tuple:
    """``(Operation, params, hex digest)`` of an item: SHA-256 of the input bytes, the operation,
    its normalised parameters, the bytes of further input files and the meso version."""
    import meso

    op, params = _normalise(item)
    h = hashlib.sha256()
    h.update(b"meso-batch 1\0")
    h.update((version or meso.__version__).encode() + b"\0")
    h.update(op.name.encode() + b"\0")
    h.update(json.dumps(params, sort_keys=True, separators=(",", ":")).encode() + b"\0")
    _sha256_file(item.input, h)
    for name, (kind, _) in sorted(op.params.items()):
        if kind == "path" and params[name] is not None:
            h.update(name.encode() + b"\0")
            _sha256_file(params[name], h)
    return op, params, h.hexdigest()


def output_name(item: Item, op: Operation, digest: str) -> str:
    stem = Path(item.input).stem or "item"
    return f"{stem}-{digest[:16]}{op.suffix}"


def _process(item: Item, out_dir: str, delay: float = 0.0) -> dict:
    """Run one item; every problem of the item itself comes back as a ``failed`` record."""
    t0 = time.perf_counter()
    rec: Dict[str, Any] = {"index": item.index, "input": item.input, "op": item.op}
    try:
        import meso

        try:
            op, params, digest = item_key(item)
        except FileNotFoundError as e:
            raise ItemError(f"{e.filename or item.input}: no such file") from None
        except IsADirectoryError:
            raise ItemError(f"{item.input}: is a directory, not an image") from None
        name = output_name(item, op, digest)
        final = os.path.join(out_dir, name)
        rec.update(params={k: v for k, v in params.items() if v is not None},
                   hash=digest, output=name)
        if os.path.exists(final):
            rec["status"] = "skipped"
            return rec
        if delay:
            time.sleep(delay)  # for tests: widen the window in which a worker can be killed
        call = {k: v for k, v in params.items() if v is not None}
        if op.output == "file":
            info = op.call(item.input, final, **call)
        else:
            tmp = os.path.join(out_dir, f"{TMP_PREFIX}{digest[:16]}-{uuid.uuid4().hex[:8]}")
            try:
                info = op.call(item.input, tmp, **call)
                try:
                    os.rename(tmp, final)
                except OSError:
                    if not os.path.isdir(final):
                        raise
                    shutil.rmtree(tmp, ignore_errors=True)  # another attempt finished it first
            except BaseException:
                shutil.rmtree(tmp, ignore_errors=True)
                raise
        rec["status"] = "done"
        rec.update(info)
    except (ItemError,) + meso_errors() as e:
        rec.pop("output", None)  # nothing was written
        rec["status"] = "failed"
        rec["error"] = f"{type(e).__name__}: {e}"
    rec["seconds"] = round(time.perf_counter() - t0, 4)
    return rec


def meso_errors() -> tuple:
    """The exceptions that are an item's own problem (not retried)."""
    import meso

    return (meso.MesoError, ValueError, TypeError, FileNotFoundError, IsADirectoryError,
            PermissionError)


def _process_chunk(items: List[Item], out_dir: str, delay: float = 0.0) -> List[dict]:
    return [_process(it, out_dir, delay) for it in items]


# --------------------------------------------------------------------------------------------
# The client side.
# --------------------------------------------------------------------------------------------


@dataclasses.dataclass
class Summary:
    """What a run did: counts, the failures (input and message), wall time, the report path."""

    total: int
    done: int
    skipped: int
    failed: int
    failures: List[dict]
    seconds: float
    report: str
    removed_temps: int
    items: List[dict] = dataclasses.field(repr=False, default_factory=list)

    @property
    def ok(self) -> bool:
        return self.failed == 0

    def text(self) -> str:
        lines = [
            f"meso batch: {self.total} items: {self.done} done, {self.skipped} skipped, "
            f"{self.failed} failed in {self.seconds:.1f} s"
            + (f" ({self.removed_temps} leftover temporary files removed)"
               if self.removed_temps else "")
        ]
        for f in self.failures:
            lines.append(f"  failed: {f['input']}: {f['error']}")
        lines.append(f"  report: {self.report}")
        return "\n".join(lines)


def clean_temps(out_dir: Union[str, os.PathLike]) -> int:
    """Remove temporary files and directories left in ``out_dir`` by killed runs: meso's atomic
    writes (``.NAME.XXXXXX.tmp``) and export directories (``.meso-batch-tmp-…``)."""
    n = 0
    for e in os.scandir(out_dir):
        if e.name.startswith(TMP_PREFIX) or (e.name.startswith(".") and e.name.endswith(".tmp")):
            if e.is_dir(follow_symlinks=False):
                shutil.rmtree(e.path, ignore_errors=True)
            else:
                try:
                    os.unlink(e.path)
                except FileNotFoundError:
                    pass
            n += 1
    return n


def _write_json_atomic(path: str, doc: Any) -> None:
    tmp = os.path.join(os.path.dirname(path), f"{TMP_PREFIX}{uuid.uuid4().hex[:8]}.json")
    with open(tmp, "w", encoding="utf-8") as f:
        json.dump(doc, f, indent=1)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def run(
    manifest_or_dir: Union[str, os.PathLike, Sequence[Item]],
    out_dir: Union[str, os.PathLike],
    address: Optional[str] = None,
    workers: Optional[int] = None,
    op: Optional[str] = None,
    params: Optional[Dict[str, Any]] = None,
    glob: str = "*",
    retries: int = 2,
    chunk_size: int = 1,
    progress: bool = True,
    client: Any = None,
    worker_threads: int = 1,
    rayon_threads: Optional[int] = 1,
    _delay: float = 0.0,
) -> Summary:
    """Run the items of ``manifest_or_dir`` (a manifest, a directory, or a list of :class:`Item`)
    into ``out_dir`` on the Dask cluster at ``address`` (or an existing ``client``, or a
    ``LocalCluster`` of ``workers`` processes with ``worker_threads`` threads each, meso's own
    thread pool set to ``rayon_threads`` per worker). ``op``/``params``: the operation and
    parameters of a directory's images, defaults for a manifest's items. ``retries``: how many
    times Dask retries a task that raised something other than the item's own error;
    ``chunk_size``: items per Dask task (fewer, longer tasks for very many small items). Returns
    the :class:`Summary` (also written to ``out_dir/meso-batch-report.json``)."""
    from distributed import Client, LocalCluster, as_completed

    t0 = time.perf_counter()
    if isinstance(manifest_or_dir, (str, os.PathLike)):
        items = load_items(manifest_or_dir, op=op, params=params, glob=glob)
        source = str(manifest_or_dir)
    else:
        items = list(manifest_or_dir)
        source = "<items>"
    out = os.path.abspath(out_dir)
    os.makedirs(out, exist_ok=True)
    lock = open(os.path.join(out, LOCK_NAME), "a+")
    try:
        try:
            fcntl.flock(lock.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise RuntimeError(f"{out}: another meso batch is running into this directory") from None
        removed = clean_temps(out)
        cluster = None
        own_client = client is None
        if own_client:
            if address is None:
                n = workers or max(1, min(4, os.cpu_count() or 1))
                env = {"RAYON_NUM_THREADS": str(rayon_threads)} if rayon_threads else {}
                cluster = LocalCluster(
                    n_workers=n, threads_per_worker=worker_threads, processes=True,
                    dashboard_address=None, env=env,
                )
                client = Client(cluster)
            else:
                client = Client(address)
        records: Dict[int, dict] = {}
        try:
            chunks = [items[i:i + max(1, chunk_size)] for i in range(0, len(items), max(1, chunk_size))]
            futures = {}
            for chunk in chunks:
                fut = client.submit(_process_chunk, chunk, out, _delay, retries=retries,
                                    pure=False, key=f"meso-batch-{chunk[0].index}-{uuid.uuid4().hex[:8]}")
                futures[fut] = chunk
            counts = {"done": 0, "skipped": 0, "failed": 0}
            finished = 0
            last = 0.0
            for fut in as_completed(futures):
                chunk = futures[fut]
                try:
                    recs = fut.result()
                except Exception as e:  # KilledWorker, or an error left after the retries
                    recs = [{"index": it.index, "input": it.input, "op": it.op, "status": "failed",
                             "error": f"{type(e).__name__}: {e}"} for it in chunk]
                for r in recs:
                    records[r["index"]] = r
                    counts[r["status"]] += 1
                finished += len(recs)
                now = time.perf_counter()
                if progress and (now - last > 0.5 or finished == len(items)):
                    last = now
                    print(f"\r[{finished}/{len(items)}] done {counts['done']}, skipped "
                          f"{counts['skipped']}, failed {counts['failed']}", end="",
                          file=sys.stderr, flush=True)
            if progress and items:
                print(file=sys.stderr, flush=True)
        finally:
            if own_client:
                client.close()
                if cluster is not None:
                    cluster.close()
        removed += clean_temps(out)  # what workers killed during this run left behind
        recs = [records[it.index] for it in items]
        failures = [{"input": r["input"], "error": r["error"]} for r in recs if r["status"] == "failed"]
        summary = Summary(
            total=len(recs),
            done=sum(r["status"] == "done" for r in recs),
            skipped=sum(r["status"] == "skipped" for r in recs),
            failed=len(failures),
            failures=failures,
            seconds=time.perf_counter() - t0,
            report=os.path.join(out, REPORT_NAME),
            removed_temps=removed,
            items=recs,
        )
        doc = dataclasses.asdict(summary)
        doc.update(source=source, out_dir=out, finished=time.strftime("%Y-%m-%dT%H:%M:%S%z"))
        _write_json_atomic(summary.report, doc)
        return summary
    finally:
        lock.close()


# --------------------------------------------------------------------------------------------
# Command line.
# --------------------------------------------------------------------------------------------


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(
        prog="meso-batch",
        description="Run meso extract/export/fit over a manifest (.json/.csv) or a directory of "
                    "images on a Dask cluster (docs/batch.md).",
    )
    ap.add_argument("source", help="manifest (.json or .csv) or directory of images")
    ap.add_argument("--out", required=True, help="output directory")
    ap.add_argument("--address", help="Dask scheduler (tcp://host:8786); default: a LocalCluster")
    ap.add_argument("--workers", type=int, help="LocalCluster worker processes (default min(4, cores))")
    ap.add_argument("--op", choices=sorted(OPERATIONS), help="operation (default extract)")
    ap.add_argument("--glob", default="*", help="file pattern for a directory (default: images)")
    ap.add_argument("--retries", type=int, default=2)
    ap.add_argument("--chunk-size", type=int, default=1, help="items per Dask task")
    ap.add_argument("--quiet", action="store_true", help="no progress line")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                    help="any other parameter of the operation")
    names = sorted({k for o in OPERATIONS.values() for k in o.params})
    bools = {k for o in OPERATIONS.values() for k, (t, _) in o.params.items() if t is bool}
    for k in names:
        if k in bools:  # --normal-map, or --normal-map false
            ap.add_argument("--" + k.replace("_", "-"), dest="p_" + k, metavar="BOOL",
                            nargs="?", const="true")
        else:
            ap.add_argument("--" + k.replace("_", "-"), dest="p_" + k, metavar="VALUE")
    a = ap.parse_args(argv)
    params: Dict[str, Any] = {k: getattr(a, "p_" + k) for k in names
                              if getattr(a, "p_" + k) is not None}
    for s in a.set:
        k, sep, v = s.partition("=")
        if not sep:
            ap.error(f"--set {s!r}: expected NAME=VALUE")
        params[k.strip().replace("-", "_")] = v
    try:
        summary = run(a.source, a.out, address=a.address, workers=a.workers, op=a.op,
                      params=params, glob=a.glob, retries=a.retries, chunk_size=a.chunk_size,
                      progress=not a.quiet)
    except (OSError, ValueError, RuntimeError) as e:
        print(f"meso-batch: {e}", file=sys.stderr)
        return 2
    print(summary.text())
    return 0 if summary.ok else 1


if __name__ == "__main__":
    sys.exit(main())
