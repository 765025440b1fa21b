"""Many panoramas through the pipeline of ``pano2cad run``: inputs, output names, engines, results index.

Composition only (ARCHITECTURE.md): each item is :func:`apps.pipeline.run_pipeline`
plus :func:`apps.cmd_run.write_outputs`, exactly what ``pano2cad run`` writes,
into ``OUT/<name>/``. Distribution is left to a process pool (``local``) or
to Dask distributed (``dask``), which also handles retries and lost workers.

- Inputs: a folder (its image files, not recursive), a glob, a single image,
  or a CSV/JSON manifest (``path``, optional ``camera_height``, optional
  ``annotations`` per row; relative paths are relative to the manifest).
- Names: the file stem; stems found more than once get their parent folders
  prepended until they differ (``a/pano.png`` -> ``a-pano``), see
  :func:`unique_names`. Deterministic: a name depends only on the paths.
- Resumable: an item whose ``scene.json`` exists is skipped (``force``
  recomputes). An item is computed in a hidden ``.NAME.partial-*`` folder
  and renamed into place when complete, so a killed run leaves no half item;
  stale partial folders are removed when the next batch starts (one batch
  per output folder at a time).
- Failure isolation: an item that fails is recorded (file, error, exit
  code 2 for bad input as ``pano2cad run`` would exit, 1 for an internal
  error) and the batch goes on.
"""

from __future__ import annotations

import contextlib
import csv
import glob as globlib
import hashlib
import io
import json
import os
import re
import shutil
import tempfile
import time
from collections import Counter
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Literal

from .errors import EXIT_INTERNAL, EXIT_USAGE, UserError

EXIT_SOME_FAILED = 3
"""Exit code of ``pano2cad batch`` when at least one item failed."""

IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".webp", ".tif", ".tiff", ".bmp")
"""File types picked up when INPUTS is a folder."""

OBJECT_CLASSES = ("bed", "chair", "tv", "plant", "sofa", "table", "nightstand", "wardrobe")
"""Classes of CONVENTIONS.md; the index always has a count column for each (others are appended)."""

INDEX_COLUMNS = ("name", "file", "status", "exit_code", "seconds", "area_m2", "wall_height_m", "corners")

Engine = Literal["local", "dask"]
Status = Literal["ok", "skipped", "failed"]

_PARTIAL = ".partial-"
_GLOB_CHARS = re.compile(r"[*?\[]")
_UNSAFE = re.compile(r"[^A-Za-z0-9._-]+")


@dataclass(frozen=True)
class BatchItem:
    """One panorama of a batch.

    Attributes
    ----------
    name : str
        Output sub-folder (unique within the batch).
    path : Path
        The panorama.
    camera_height : float or None
        Metres; overrides the batch's ``--camera-height`` for this item.
    annotations : Path or None
        Boxes file; the item is run with the detector ``annotations:FILE``.
    """

    name: str
    path: Path
    camera_height: float | None = None
    annotations: Path | None = None


@dataclass(frozen=True)
class ItemResult:
    """One row of the results index.

    ``status`` is ``ok`` (computed now), ``skipped`` (complete outputs were
    there) or ``failed``; ``exit_code`` is what ``pano2cad run`` would have
    returned (0, 2 bad input, 1 internal). Room figures are ``None`` when unknown.
    """

    name: str
    file: str
    status: Status
    exit_code: int
    seconds: float
    area_m2: float | None = None
    wall_height_m: float | None = None
    corners: int | None = None
    objects: dict[str, int] = field(default_factory=dict)
    error: str | None = None

    @property
    def ok(self) -> bool:
        return self.status != "failed"


@dataclass(frozen=True)
class BatchResult:
    """What :func:`run_batch` did: one result per item in input order, and the index files written."""

    results: tuple[ItemResult, ...]
    index_csv: Path
    index_parquet: Path | None
    seconds: float

    @property
    def failed(self) -> tuple[ItemResult, ...]:
        return tuple(r for r in self.results if r.status == "failed")

    def count(self, status: Status) -> int:
        return sum(r.status == status for r in self.results)


# ----------------------------------------------------------------------------- inputs


def _safe(text: str) -> str:
    return _UNSAFE.sub("_", text).strip("._") or "pano"


def unique_names(paths: Sequence[str | os.PathLike[str]]) -> list[str]:
    """Output folder names for ``paths``: the stem, made unique deterministically.

    A stem used once is kept. Paths sharing a stem get as many of their
    parent folder names prepended as it takes to tell them apart; where that
    never works, an 8-hex-digit hash of the absolute path is appended.
    Characters other than letters, digits, ``.``, ``_`` and ``-`` become ``_``.

    Examples
    --------
    >>> unique_names(["rooms/a/pano.png", "rooms/b/pano.png", "x/kitchen.jpg"])
    ['a-pano', 'b-pano', 'kitchen']
    >>> unique_names(["one/pano.png", "two/pano.jpg", "two/pano.png"])  # doctest: +ELLIPSIS
    ['pano-...', 'pano-...', 'pano-...']
    """
    absolute = [Path(os.path.abspath(p)) for p in paths]
    if len(set(absolute)) != len(absolute):
        dup = sorted(str(p) for p, n in Counter(absolute).items() if n > 1)
        raise ValueError(f"paths: expected each file once, got {dup[0]} more than once")
    stems = [_safe(p.stem) for p in absolute]
    count = Counter(stems)
    names = list(stems)
    taken = {s for s in stems if count[s] == 1}
    for stem in sorted(s for s, n in count.items() if n > 1):
        idx = [i for i, s in enumerate(stems) if s == stem]
        parents = {i: absolute[i].parent.parts[1:] for i in idx}
        chosen: dict[int, str] | None = None
        for k in range(1, max(len(v) for v in parents.values()) + 1):
            cand = {i: "-".join(_safe(p) for p in (*parents[i][-k:], stem)) for i in idx}
            if len(set(cand.values())) == len(idx) and not taken & set(cand.values()):
                chosen = cand
                break
        if chosen is None:
            chosen = {i: f"{stem}-{hashlib.sha1(str(absolute[i]).encode()).hexdigest()[:8]}" for i in idx}
        for i, n in chosen.items():
            names[i] = n
        taken |= set(chosen.values())
    return names


def _height(value, where: str) -> float | None:
    if value is None or (isinstance(value, str) and not value.strip()):
        return None
    try:
        h = float(value)
    except (TypeError, ValueError):
        raise UserError(f"{where}: camera_height: expected metres, got {value!r}") from None
    if not 0.3 <= h <= 5.0:
        raise UserError(f"{where}: camera_height: expected metres in [0.3, 5], got {h}")
    return h


def _read_manifest(path: Path) -> list[tuple[Path, float | None, Path | None]]:
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"{path}: cannot read the manifest ({exc})") from None
    rows: list[dict]
    if path.suffix.lower() == ".csv":
        reader = csv.DictReader(io.StringIO(text))
        if reader.fieldnames is None or "path" not in [f.strip() for f in reader.fieldnames]:
            raise UserError(f"{path}: expected a CSV manifest with a 'path' column "
                            f"(optional 'camera_height', 'annotations'), got columns {reader.fieldnames}")
        rows = [{(k or "").strip(): v for k, v in r.items()} for r in reader]
    else:
        try:
            doc = json.loads(text)
        except json.JSONDecodeError as exc:
            raise UserError(f"{path}: not valid JSON ({exc})") from None
        if isinstance(doc, dict) and isinstance(doc.get("items"), list):
            doc = doc["items"]
        if not isinstance(doc, list):
            raise UserError(f"{path}: expected a JSON list of {{'path': ...}} objects (or {{'items': [...]}})")
        rows = [r if isinstance(r, dict) else {"path": r} for r in doc]
    base = path.parent
    out = []
    for n, r in enumerate(rows, start=1):
        where = f"{path} row {n}"
        p = r.get("path")
        if not isinstance(p, str) or not p.strip():
            raise UserError(f"{where}: expected a non-empty 'path', got {p!r}")
        ann = r.get("annotations")
        ann_p = base / ann.strip() if isinstance(ann, str) and ann.strip() else None
        out.append((base / p.strip(), _height(r.get("camera_height"), where), ann_p))
    return out


def discover_inputs(spec: str | os.PathLike[str]) -> list[BatchItem]:
    """The items of INPUTS: a folder, a glob, an image file, or a ``.csv``/``.json`` manifest.

    Missing or unreadable panoramas named by a manifest or glob are kept: they
    fail as items, recorded in the index. Raises :class:`UserError` when INPUTS
    names nothing, or a manifest is malformed or lists a file twice.
    """
    s = os.fspath(spec)
    p = Path(s)
    if p.is_dir():
        rows = [(f, None, None) for f in sorted(p.iterdir()) if f.is_file() and f.suffix.lower() in IMAGE_SUFFIXES]
        if not rows:
            raise UserError(f"{p}: the folder holds no image files ({', '.join(IMAGE_SUFFIXES)})")
    elif p.is_file() and p.suffix.lower() in (".csv", ".json"):
        rows = _read_manifest(p)
        if not rows:
            raise UserError(f"{p}: the manifest lists no panoramas")
    elif p.is_file():
        rows = [(p, None, None)]
    elif _GLOB_CHARS.search(s):
        rows = [(Path(f), None, None) for f in sorted(globlib.glob(s, recursive=True)) if Path(f).is_file()]
        if not rows:
            raise UserError(f"{s}: the glob matches no files")
    else:
        raise UserError(f"{s}: expected a folder, a glob, an image or a .csv/.json manifest; nothing is there")
    try:
        names = unique_names([r[0] for r in rows])
    except ValueError as exc:
        raise UserError(f"{s}: {str(exc).removeprefix('paths: ')}") from None
    return [BatchItem(n, path, h, a) for n, (path, h, a) in zip(names, rows)]


# ----------------------------------------------------------------------------- one item


def summarize_outputs(item: BatchItem, folder: Path, status: Status, seconds: float) -> ItemResult:
    """An index row from a complete output folder (its scene.json)."""
    import numpy as np

    from layout.polygon import signed_area

    doc = json.loads((folder / "scene.json").read_text(encoding="utf-8"))
    room = doc.get("room") or {}
    floor = room.get("floor") or []
    area = round(abs(float(signed_area(np.asarray(floor, float)))), 4) if len(floor) >= 3 else None
    cz, fz = room.get("ceiling_z"), room.get("floor_z")
    wall = round(float(cz) - float(fz or 0.0), 4) if cz is not None else None
    counts = Counter(str(o.get("class")) for o in doc.get("objects") or [])
    return ItemResult(item.name, str(item.path), status, 0, round(seconds, 3), area, wall, len(floor),
                      dict(sorted(counts.items())))


def _clean_partials(out: Path) -> None:
    for d in out.glob(f".*{_PARTIAL}*"):
        if d.is_dir():
            shutil.rmtree(d, ignore_errors=True)


def _commit(tmp: Path, dest: Path) -> None:
    """Move a complete item folder into place, replacing an older one."""
    old = None
    if dest.exists():
        old = Path(tempfile.mkdtemp(prefix=f".{dest.name}{_PARTIAL}old-", dir=dest.parent))
        os.replace(dest, old / "item")
    os.replace(tmp, dest)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def process_item(item: BatchItem, out: str | os.PathLike[str], options, size: int, force: bool = False) -> ItemResult:
    """Run ``pano2cad run`` on one item into ``out/<name>/``; never raises for a failed panorama.

    Parameters
    ----------
    item : BatchItem
    out : path of the batch's output folder (shared by every worker)
    options : apps.pipeline.RunOptions
        The batch's options; the item's camera height and annotations override them.
    size : int
        Working width in pixels.
    force : bool
        Recompute an item whose scene.json exists.
    """
    from .cmd_run import write_outputs
    from .imageio import read_panorama
    from .pipeline import run_pipeline
    from .progress import Progress

    t0 = time.perf_counter()
    out_p = Path(out)
    dest = out_p / item.name
    if not force and (dest / "scene.json").is_file():
        return summarize_outputs(item, dest, "skipped", time.perf_counter() - t0)
    opts = options
    if item.camera_height is not None:
        opts = replace(opts, camera_height=item.camera_height)
    if item.annotations is not None:
        opts = replace(opts, detector=f"annotations:{item.annotations}")
    tmp: Path | None = None
    try:
        pano = read_panorama(item.path, max_width=size)
        result = run_pipeline(pano.image, opts, Progress(quiet=True))
        tmp = Path(tempfile.mkdtemp(prefix=f".{item.name}{_PARTIAL}", dir=out_p))
        write_outputs(result, tmp, item.path.name)
        _commit(tmp, dest)
        tmp = None
    except UserError as exc:
        return ItemResult(item.name, str(item.path), "failed", EXIT_USAGE, round(time.perf_counter() - t0, 3),
                          error=str(exc))
    except Exception as exc:  # an internal error of one item is recorded; the batch goes on
        return ItemResult(item.name, str(item.path), "failed", EXIT_INTERNAL, round(time.perf_counter() - t0, 3),
                          error=f"{type(exc).__name__}: {exc}")
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
    return summarize_outputs(item, dest, "ok", time.perf_counter() - t0)


def warm_model_library() -> int:
    """Build the on-disk model-library cache (posecrf.cache) once; returns the number of models ready."""
    from posecrf.cache import library_renders
    from posecrf.library import builtin_library

    return len(library_renders(builtin_library(), workers=1).models)


# ----------------------------------------------------------------------------- engines


def _limit_threads(n: int) -> None:
    """Process-pool initializer: n math threads per worker, so workers x threads <= cores.

    Set before the worker imports torch, numba or BLAS (they read these at import).
    """
    for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS"):
        os.environ[var] = str(n)


def _failed(item: BatchItem, exc: BaseException) -> ItemResult:
    return ItemResult(item.name, str(item.path), "failed", EXIT_INTERNAL, 0.0, error=f"{type(exc).__name__}: {exc}")


def _local(todo: list[BatchItem], out: Path, options, size: int, force: bool, jobs: int) -> Iterator[ItemResult]:
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor, as_completed

    cores = os.cpu_count() or 1
    with ProcessPoolExecutor(jobs, mp_context=mp.get_context("spawn"), initializer=_limit_threads,
                             initargs=(max(1, cores // jobs),)) as ex:
        if options.objects:
            ex.submit(warm_model_library).result()
        futs = {ex.submit(process_item, it, str(out), options, size, force): it for it in todo}
        for f in as_completed(futs):
            exc = f.exception()
            yield _failed(futs[f], exc) if exc is not None else f.result()


def _dask(todo: list[BatchItem], out: Path, options, size: int, force: bool, jobs: int,
          scheduler: str | None) -> Iterator[ItemResult]:
    try:
        from distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise UserError("--engine dask needs Dask distributed: pip install 'dask[distributed]'") from None
    with contextlib.ExitStack() as stack:
        if scheduler:
            try:
                client = stack.enter_context(Client(scheduler, timeout="20s"))
            except (OSError, TimeoutError) as exc:
                raise UserError(f"--scheduler {scheduler}: cannot connect to a Dask scheduler ({exc})") from None
        else:
            cluster = stack.enter_context(LocalCluster(n_workers=jobs, threads_per_worker=1, processes=True,
                                                       host="127.0.0.1", dashboard_address="127.0.0.1:0"))
            client = stack.enter_context(Client(cluster))
        if options.objects:
            client.submit(warm_model_library, pure=False).result()
        token = hashlib.sha1(f"{out}{time.time_ns()}".encode()).hexdigest()[:10]
        futs = client.map(process_item, todo, out=str(out), options=options, size=size, force=force,
                          key=[f"pano2cad-batch-{token}-{i}" for i in range(len(todo))], pure=False)
        by_key = {f.key: it for f, it in zip(futs, todo)}
        for f in as_completed(futs):
            if f.status == "finished":
                r = f.result()
            else:  # lost more often than Dask's allowed-failures, or an unexpected error
                r = _failed(by_key[f.key], f.exception())
            f.release()  # a worker lost later must not recompute a finished item
            yield r


# ----------------------------------------------------------------------------- index


def _classes(results: Sequence[ItemResult]) -> list[str]:
    extra = sorted({c for r in results for c in r.objects} - set(OBJECT_CLASSES))
    return [*OBJECT_CLASSES, *extra]


def index_rows(results: Sequence[ItemResult]) -> list[dict]:
    """Rows of the index: :data:`INDEX_COLUMNS`, ``n_<class>`` per class, ``error``."""
    classes = _classes(results)
    rows = []
    for r in results:
        row = {c: getattr(r, c) for c in INDEX_COLUMNS}
        for c in classes:
            row[f"n_{c}"] = r.objects.get(c, 0) if r.ok else None
        row["error"] = r.error
        rows.append(row)
    return rows


def write_index(results: Sequence[ItemResult], out: Path) -> tuple[Path, Path | None]:
    """Write ``out/index.csv`` (and ``out/index.parquet`` when pyarrow is installed), atomically."""
    from .atomic import atomic_path, write_text

    rows = index_rows(results)
    cols = [*INDEX_COLUMNS, *(f"n_{c}" for c in _classes(results)), "error"]
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=cols, lineterminator="\n")
    w.writeheader()
    for row in rows:
        w.writerow({k: "" if v is None else v for k, v in row.items()})
    csv_path = write_text(out / "index.csv", buf.getvalue())
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        return csv_path, None
    with atomic_path(out / "index.parquet") as tmp:
        pq.write_table(pa.Table.from_pylist(rows), tmp)
    return csv_path, out / "index.parquet"


# ----------------------------------------------------------------------------- batch


def run_batch(items: Sequence[BatchItem], out: str | os.PathLike[str], options, *, size: int = 1024,
              force: bool = False, engine: Engine = "local", scheduler: str | None = None, jobs: int = 0,
              progress=None, on_result: Callable[[ItemResult], None] | None = None) -> BatchResult:
    """Run the pipeline on every item into ``out/<name>/`` and write the results index.

    Parameters
    ----------
    items : sequence of BatchItem (unique names; see :func:`discover_inputs`)
    out : output folder (must exist and be writable; on a Dask cluster, visible to every worker)
    options : apps.pipeline.RunOptions
    size : int
        Working width in pixels.
    force : bool
        Recompute items whose scene.json exists.
    engine : ``"local"`` (process pool) or ``"dask"`` (Dask distributed)
    scheduler : str, optional
        Address of an existing Dask scheduler; None with ``"dask"`` starts a LocalCluster on 127.0.0.1.
    jobs : int
        Worker processes of the pool or LocalCluster; 0: one per core.
    progress : apps.progress.Progress, optional
        Its bar shows items done, rate and ETA.
    on_result : callable, optional
        Called in this process with each item's result as it arrives.

    Returns
    -------
    BatchResult
        Results in the order of ``items``; the index is written even when items failed.
    """
    from .progress import Progress

    if engine not in ("local", "dask"):
        raise ValueError(f"engine: expected 'local' or 'dask', got {engine!r}")
    if scheduler and engine != "dask":
        raise ValueError(f"scheduler: only with engine='dask', got engine={engine!r}")
    if jobs < 0:
        raise ValueError(f"jobs: expected 0 (one per core) or more, got {jobs}")
    names = [it.name for it in items]
    if len(set(names)) != len(names):
        raise ValueError(f"items: expected unique names, got {sorted(n for n, c in Counter(names).items() if c > 1)}")
    t0 = time.perf_counter()
    prog = progress or Progress(quiet=True)
    out_p = Path(os.path.abspath(out))
    _clean_partials(out_p)
    done: dict[str, ItemResult] = {}
    todo: list[BatchItem] = []
    for it in items:  # complete items are skipped here, without starting any worker
        if not force and (out_p / it.name / "scene.json").is_file():
            done[it.name] = summarize_outputs(it, out_p / it.name, "skipped", 0.0)
        else:
            todo.append(it)
    if done:
        prog.say(f"batch: {len(done)} of {len(items)} items already complete, skipped (--force recomputes)")
    if todo:
        n = max(1, min(jobs or os.cpu_count() or 1, len(todo)))
        where = (f"{n} processes" if engine == "local" else
                 f"scheduler {scheduler}" if scheduler else f"a LocalCluster of {n} workers on 127.0.0.1")
        prog.say(f"batch: {len(todo)} panoramas -> {out_p} ({engine} engine, {where})")
        stream = (_local(todo, out_p, options, size, force, n) if engine == "local"
                  else _dask(todo, out_p, options, size, force, n, scheduler))
        for r in prog.bar(stream, total=len(todo), desc="panoramas"):
            done[r.name] = r
            if on_result is not None:
                on_result(r)
            if r.status == "failed":
                prog.say(f"failed: {r.name} (exit {r.exit_code}): {r.error}")
    results = tuple(done[it.name] for it in items)
    csv_path, pq_path = write_index(results, out_p)
    from .report import write_batch_index

    write_batch_index(out_p)
    return BatchResult(results, csv_path, pq_path, round(time.perf_counter() - t0, 3))
