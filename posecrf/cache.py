"""On-disk cache of the library's pose-render descriptors.

Every library model is rendered at every pose of a :class:`~posecrf.render.PoseGrid`
(360 by default) and the HOG descriptors of the crops are kept, one ``.npz``
file per model, in a cache folder. A file's name carries a key: the SHA-256 of
the model's content hash, the pose grid, the render settings and the code
version of the renderer and of the HOG descriptor, so a model is rendered
again exactly when one of those changed, and never otherwise.

- Folder: ``$PANO2CAD_CACHE`` if set, else ``~/.cache/pano2cad/renders``.
- Files are written to a temporary name in the same folder and moved into
  place with ``os.replace``: an interrupted build never leaves a half-written
  file, only the complete files of the models that were finished.
- A model that cannot be rendered (empty or degenerate mesh, NaN vertices,
  empty silhouette) is reported by name (a warning and
  ``LibraryRenders.failures``) and skipped; the others go on.

Convention: poses, labels and angles as in :mod:`posecrf.render` (labels in
C order over (n_yaw, n_pitch), radians).

Examples
--------
>>> import tempfile
>>> from posecrf.library import builtin_library
>>> from posecrf.render import PoseGrid, RenderSettings
>>> lib = builtin_library().subset(["tv"])
>>> small = dict(grid=PoseGrid(8, 2, np.deg2rad(30.0)), settings=RenderSettings(size=32, viewport=64), workers=1)
>>> with tempfile.TemporaryDirectory() as d:
...     first = library_renders(lib, cache_dir=d, **small)
...     second = library_renders(lib, cache_dir=d, **small)
>>> len(first.built), len(second.built), len(second.loaded), second["tv-01"].descriptors.shape[0]
(6, 0, 6, 16)
"""

from __future__ import annotations

import hashlib
import multiprocessing
import os
import sys
import tempfile
import time
import warnings
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from .render import PoseGrid, PoseRenderer, RenderError, RenderSettings, check_renderable

if TYPE_CHECKING:  # pragma: no cover - typing only
    from .library import Model3D, ModelLibrary

__all__ = [
    "CACHE_ENV",
    "default_cache_dir",
    "code_version",
    "cache_key",
    "ModelDescriptors",
    "RenderFailure",
    "LibraryRenders",
    "library_renders",
]

CACHE_ENV = "PANO2CAD_CACHE"
"""Environment variable naming the cache folder."""

_FORMAT = 1


def default_cache_dir() -> Path:
    """The cache folder: ``$PANO2CAD_CACHE`` if set and non-empty, else ``~/.cache/pano2cad/renders``."""
    env = os.environ.get(CACHE_ENV, "").strip()
    if env:
        return Path(env).expanduser()
    return Path.home() / ".cache" / "pano2cad" / "renders"


@lru_cache(maxsize=1)
def code_version() -> str:
    """SHA-256 (hex, 16 chars) of the source of the renderer and the HOG descriptor.

    Any edit of :mod:`posecrf.render` or :mod:`posecrf.hog` invalidates the cache.
    """
    from . import hog, render

    h = hashlib.sha256()
    for mod in (render, hog):
        h.update(Path(mod.__file__).read_bytes())
    return h.hexdigest()[:16]


def cache_key(model: "Model3D", grid: PoseGrid, settings: RenderSettings) -> str:
    """Cache key (64 hex chars) of one model's descriptors.

    SHA-256 of the model's content hash, its symmetry, the pose grid, the
    render settings, the file format and :func:`code_version`.
    """
    h = hashlib.sha256()
    for part in (model.content_hash(), model.symmetry, grid.key(), settings.key(), str(_FORMAT), code_version()):
        h.update(part.encode())
        h.update(b"\0")
    return h.hexdigest()


def _file_name(model_id: str, key: str) -> str:
    return f"{model_id}.{key[:24]}.npz"


@dataclass(frozen=True, eq=False)
class ModelDescriptors:
    """Descriptors of one model's renders at every pose of the grid.

    Attributes
    ----------
    model_id : str
    cls : str
    symmetry : {"none", "two", "full"}
    key : str
        The cache key it was stored under.
    descriptors : (L, D) float32
        HOG descriptor of the render at pose label ``l`` in row ``l``.
    aspect : (L,) float32
        Width / height of the silhouette box before the square resize.
    """

    model_id: str
    cls: str
    symmetry: str
    key: str
    descriptors: NDArray[np.float32] = field(repr=False)
    aspect: NDArray[np.float32] = field(repr=False)


@dataclass(frozen=True)
class RenderFailure:
    """A model that could not be rendered and was skipped."""

    model_id: str
    reason: str


@dataclass(frozen=True, eq=False)
class LibraryRenders:
    """Pose-render descriptors of a model library.

    Attributes
    ----------
    grid : PoseGrid
    settings : RenderSettings
    models : tuple of ModelDescriptors
        In library order, failed models left out.
    failures : tuple of RenderFailure
        Models skipped, with the reason.
    built, loaded : tuple of str
        Ids rendered by this call / read from the cache.
    cache_dir : Path or None
        None when the cache was not used.
    seconds : float
        Wall time of the call.
    """

    grid: PoseGrid
    settings: RenderSettings
    models: tuple[ModelDescriptors, ...]
    failures: tuple[RenderFailure, ...] = ()
    built: tuple[str, ...] = ()
    loaded: tuple[str, ...] = ()
    cache_dir: Path | None = None
    seconds: float = 0.0

    def __len__(self) -> int:
        return len(self.models)

    def __getitem__(self, model_id: str) -> ModelDescriptors:
        for m in self.models:
            if m.model_id == model_id:
                return m
        raise KeyError(f"no renders of model {model_id!r} (have {len(self.models)} models; failed: {[f.model_id for f in self.failures]})")

    @property
    def classes(self) -> tuple[str, ...]:
        """Classes with at least one rendered model, in order of first appearance."""
        return tuple(dict.fromkeys(m.cls for m in self.models))

    def by_class(self, cls: str) -> tuple[ModelDescriptors, ...]:
        """Rendered models of class `cls` (empty tuple if none)."""
        return tuple(m for m in self.models if m.cls == cls)


# --------------------------------------------------------------------------- building
_WORKER: dict[str, object] = {}


def _describe(model: "Model3D", grid: PoseGrid, renderer: PoseRenderer) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    from .retrieval import render_descriptors

    r = renderer.render_crops(model, grid.poses())
    return render_descriptors(r.images, r.masks), r.aspect.astype(np.float32)


def _worker_init(settings: RenderSettings) -> None:
    _WORKER["renderer"] = PoseRenderer(settings)


def _worker_job(model: "Model3D", grid: PoseGrid) -> tuple[str, object, object]:
    renderer = _WORKER["renderer"]
    assert isinstance(renderer, PoseRenderer)
    try:
        d, a = _describe(model, grid, renderer)
    except RenderError as exc:
        return model.id, None, exc.reason
    return model.id, d, a


def _start_method() -> str:
    """'fork' while this process holds no OpenGL context (fast, no ``__main__`` guard needed), else 'spawn'."""
    from . import render

    if not render._OFFSCREEN and "fork" in multiprocessing.get_all_start_methods():
        return "fork"
    return "spawn"


def _atomic_save(path: Path, **arrays: np.ndarray) -> None:
    fd, tmp = tempfile.mkstemp(prefix="." + path.name + ".", suffix=".tmp", dir=path.parent)
    done = False
    try:
        with os.fdopen(fd, "wb") as fh:
            np.savez(fh, **arrays)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
        done = True
    finally:
        if not done:  # interrupted or failed: drop the partial temporary file
            Path(tmp).unlink(missing_ok=True)


def _load(path: Path, model: "Model3D", key: str, grid: PoseGrid) -> ModelDescriptors | None:
    try:
        with np.load(path, allow_pickle=False) as z:
            if str(z["key"]) != key:
                return None
            d = np.asarray(z["descriptors"], dtype=np.float32)
            a = np.asarray(z["aspect"], dtype=np.float32)
    except (OSError, KeyError, ValueError, EOFError):
        return None
    if d.ndim != 2 or d.shape[0] != grid.size or a.shape != (grid.size,) or not np.all(np.isfinite(d)):
        return None
    return _entry(model, key, d, a)


def _entry(model: "Model3D", key: str, d: np.ndarray, a: np.ndarray) -> ModelDescriptors:
    d = np.ascontiguousarray(d, dtype=np.float32)
    a = np.ascontiguousarray(a, dtype=np.float32)
    d.setflags(write=False)
    a.setflags(write=False)
    return ModelDescriptors(model.id, model.cls, model.symmetry, key, d, a)


def library_renders(
    library: "ModelLibrary | Iterable[Model3D]",
    *,
    grid: PoseGrid | None = None,
    settings: RenderSettings | None = None,
    cache_dir: str | os.PathLike[str] | None = None,
    use_cache: bool = True,
    workers: int | None = None,
    progress: bool | Callable[[str], None] = False,
) -> LibraryRenders:
    """Descriptors of every model rendered at every pose, from the cache or rendered now.

    Parameters
    ----------
    library : ModelLibrary or iterable of Model3D
    grid : PoseGrid, optional
        Default ``PoseGrid()`` (72 yaws x 5 pitches).
    settings : RenderSettings, optional
    cache_dir : path, optional
        Default :func:`default_cache_dir`. Created if missing.
    use_cache : bool
        False renders everything and writes nothing.
    workers : int, optional
        Render processes for the models not in the cache (each has its own
        EGL context). Default: the number of CPUs, at most the number of
        models to render; 1 renders in this process. Processes are forked
        while this process has no OpenGL context yet, else started with
        'spawn' (a script calling this after rendering something itself
        needs the usual ``if __name__ == "__main__":`` guard).
    progress : bool or callable
        True prints one line per model to stderr; a callable receives the lines.

    Returns
    -------
    LibraryRenders

    Warns
    -----
    UserWarning
        Once per model that failed to render, naming it and the reason.
    """
    t0 = time.perf_counter()
    g = grid if grid is not None else PoseGrid()
    s = settings if settings is not None else RenderSettings()
    if not isinstance(g, PoseGrid):
        raise ValueError(f"grid: expected a PoseGrid, got {type(g).__name__}")
    if not isinstance(s, RenderSettings):
        raise ValueError(f"settings: expected RenderSettings, got {type(s).__name__}")
    models = list(library)
    ids = [m.id for m in models]
    if len(set(ids)) != len(ids):
        raise ValueError(f"library: expected unique model ids, got duplicates {sorted({i for i in ids if ids.count(i) > 1})}")
    if workers is not None and (int(workers) != workers or workers < 1):
        raise ValueError(f"workers: expected a positive integer or None, got {workers!r}")
    say: Callable[[str], None]
    if callable(progress):
        say = progress
    elif progress:
        def say(line: str) -> None:
            print(line, file=sys.stderr, flush=True)
    else:
        def say(line: str) -> None:
            return None

    folder: Path | None = None
    if use_cache:
        folder = Path(cache_dir).expanduser() if cache_dir is not None else default_cache_dir()
        folder.mkdir(parents=True, exist_ok=True)

    entries: dict[str, ModelDescriptors] = {}
    failures: dict[str, str] = {}
    keys: dict[str, str] = {}
    todo: list["Model3D"] = []
    loaded: list[str] = []
    for m in models:
        try:
            check_renderable(m)
        except RenderError as exc:
            failures[m.id] = exc.reason
            continue
        key = cache_key(m, g, s)
        keys[m.id] = key
        if folder is not None:
            e = _load(folder / _file_name(m.id, key), m, key, g)
            if e is not None:
                entries[m.id] = e
                loaded.append(m.id)
                continue
        todo.append(m)

    def finish(model: "Model3D", d: object, a: object) -> None:
        if d is None:
            failures[model.id] = str(a)
            say(f"posecrf: {model.id}: failed ({a})")
            return
        assert isinstance(d, np.ndarray) and isinstance(a, np.ndarray)
        key = keys[model.id]
        if folder is not None:
            _atomic_save(folder / _file_name(model.id, key), key=np.array(key), model_id=np.array(model.id),
                         descriptors=d.astype(np.float32), aspect=a.astype(np.float32))
        entries[model.id] = _entry(model, key, d, a)
        say(f"posecrf: rendered {model.id} ({len(entries)}/{len(models)})")

    n_workers = min(os.cpu_count() or 1, len(todo)) if workers is None else min(int(workers), max(len(todo), 1))
    if todo and n_workers <= 1:
        with PoseRenderer(s) as renderer:
            for m in todo:
                try:
                    d, a = _describe(m, g, renderer)
                except RenderError as exc:
                    finish(m, None, exc.reason)
                    continue
                finish(m, d, a)
    elif todo:
        from concurrent.futures import ProcessPoolExecutor

        by_id = {m.id: m for m in todo}
        # big models first so that the two queues end together
        order = sorted(todo, key=lambda m: -m.n_faces)
        ctx = multiprocessing.get_context(_start_method())
        with ProcessPoolExecutor(max_workers=n_workers, mp_context=ctx, initializer=_worker_init, initargs=(s,)) as pool:
            for mid, d, a in pool.map(_worker_job, order, [g] * len(order)):
                finish(by_id[mid], d, a)

    for mid, reason in failures.items():
        warnings.warn(f"posecrf: model {mid!r} skipped, it could not be rendered: {reason}", stacklevel=2)
    return LibraryRenders(
        grid=g,
        settings=s,
        models=tuple(entries[m.id] for m in models if m.id in entries),
        failures=tuple(RenderFailure(mid, failures[mid]) for mid in ids if mid in failures),
        built=tuple(m.id for m in todo if m.id in entries),
        loaded=tuple(loaded),
        cache_dir=folder,
        seconds=time.perf_counter() - t0,
    )
