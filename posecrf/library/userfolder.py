"""Load a user's folder of real CAD models into a `ModelLibrary`.

Each mesh file (``.obj``, ``.glb``, ``.gltf``, ``.ply``, ``.stl``) sits next to
a metadata file with the same stem: ``chair_eames.glb`` + ``chair_eames.json``
(or ``.yaml`` / ``.yml`` when PyYAML is installed). The metadata says what the
file's axes mean and how big the object is::

    {
      "class": "chair",          # required, lowercase word
      "front": "-y",             # required: file axis pointing to the object's front
      "up": "+z",                # required: file axis pointing up
      "units": "cm",             # exactly one of: units (m, cm, mm, in, ft),
                                 #   scale (file units -> metres), height (m),
                                 #   size [l, w, h] (m, canonical axes, per-axis)
      "id": "chair-eames",       # optional, default: the file stem
      "symmetry": "none",        # optional: none | two | full (default full for plant)
      "material": "plastic",     # optional default material of all parts
      "materials": {"legs": "metal"}   # optional per-part materials
    }

Each file's meshes are named parts (glTF nodes, OBJ objects; a PLY or STL is one
part called ``body``). The loader cleans the mesh with pymeshlab (merges close
vertices, removes duplicate and zero-area faces, decimates meshes above a face
budget with quadric edge collapse), rotates it so front -> +x and up -> +z,
scales it to metres and moves it into the canonical frame. A file that fails
yields a `ModelLoadIssue` naming it; the other models still load.

Convention:
    Output in the canonical model frame: metres, z up, bbox centre at
    x = y = 0, min z = 0, front facing +x; y = up x front (right-handed).
"""

from __future__ import annotations

import json
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .catalog import ModelLibrary
from .model import MATERIAL_NAMES, SYMMETRIES, Model3D
from .parts import canonicalize_vertices, drop_degenerate

MESH_SUFFIXES: tuple[str, ...] = (".obj", ".glb", ".gltf", ".ply", ".stl")
META_SUFFIXES: tuple[str, ...] = (".json", ".yaml", ".yml")
UNITS: dict[str, float] = {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254, "ft": 0.3048}
AXES: dict[str, tuple[float, float, float]] = {
    "+x": (1.0, 0.0, 0.0),
    "-x": (-1.0, 0.0, 0.0),
    "+y": (0.0, 1.0, 0.0),
    "-y": (0.0, -1.0, 0.0),
    "+z": (0.0, 0.0, 1.0),
    "-z": (0.0, 0.0, -1.0),
}
DEFAULT_FACE_BUDGET = 20_000
MAX_SIZE_M = 20.0
MIN_SIZE_M = 0.01
_META_KEYS = {"class", "front", "up", "units", "scale", "height", "size", "id", "symmetry", "material", "materials"}
_SCALE_KEYS = ("units", "scale", "height", "size")


class ModelFileError(ValueError):
    """A model file or its metadata could not be used; `file` names it."""

    def __init__(self, file: str | os.PathLike[str], message: str) -> None:
        self.file = Path(file)
        self.reason = message
        super().__init__(f"{self.file}: {message}")


@dataclass(frozen=True)
class ModelLoadIssue:
    """One file of a folder that did not load, and why."""

    file: Path
    message: str

    def __str__(self) -> str:
        return f"{self.file}: {self.message}"


@dataclass(frozen=True)
class ModelFolderResult:
    """What `load_model_folder` found.

    Attributes
    ----------
    folder : Path
    library : ModelLibrary
        The models that loaded, in file-name order.
    errors : tuple of ModelLoadIssue
        One entry per file that failed (mesh or metadata), naming it.
    """

    folder: Path
    library: ModelLibrary
    errors: tuple[ModelLoadIssue, ...]

    @property
    def ok(self) -> bool:
        """True when every file loaded."""
        return not self.errors

    def report(self) -> str:
        """A short human-readable summary: counts, then one line per error."""
        lines = [f"{self.folder}: {len(self.library)} models loaded, {len(self.errors)} failed"]
        lines += [f"  {e}" for e in self.errors]
        return "\n".join(lines)


@dataclass(frozen=True)
class ModelMetadata:
    """Validated metadata of one model file (see the module docstring)."""

    cls: str
    front: str
    up: str
    scale_kind: str
    scale_value: float | tuple[float, float, float]
    id: str | None = None
    symmetry: str | None = None
    material: str = "plastic"
    materials: tuple[tuple[str, str], ...] = ()


# --------------------------------------------------------------------------- metadata


def axes_rotation(front: str, up: str) -> NDArray[np.float64]:
    """(3, 3) rotation taking the file's `front` axis to +x and `up` to +z.

    Convention:
        Canonical frame: front +x, up +z, y = up x front (right-handed).

    Examples
    --------
    >>> r = axes_rotation("-y", "+z")
    >>> (r @ [0.0, -1.0, 0.0]).round(6).tolist(), (r @ [0.0, 0.0, 1.0]).round(6).tolist()
    ([1.0, 0.0, 0.0], [0.0, 0.0, 1.0])
    """
    for name, val in (("front", front), ("up", up)):
        if val not in AXES:
            raise ValueError(f"expected {name} axis in {list(AXES)}, got {val!r}")
    f = np.array(AXES[front])
    u = np.array(AXES[up])
    if abs(float(f @ u)) > 0.5:
        raise ValueError(f"expected orthogonal front and up axes, got front {front!r} and up {up!r}")
    return np.stack([f, np.cross(u, f), u])


def read_metadata_file(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read a JSON or YAML metadata file into a dict (errors name the file)."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise ModelFileError(p, f"cannot read metadata: {exc.strerror or exc}") from exc
    if p.suffix.lower() == ".json":
        try:
            raw = json.loads(text)
        except json.JSONDecodeError as exc:
            raise ModelFileError(p, f"invalid JSON at line {exc.lineno} column {exc.colno}: {exc.msg}") from exc
    elif p.suffix.lower() in (".yaml", ".yml"):
        try:
            import yaml
        except ImportError:
            raise ModelFileError(p, "YAML metadata needs PyYAML: pip install pyyaml (or use a .json file)") from None
        try:
            raw = yaml.safe_load(text)
        except yaml.YAMLError as exc:
            raise ModelFileError(p, f"invalid YAML: {exc}") from exc
    else:
        raise ModelFileError(p, f"expected a metadata file ending in {META_SUFFIXES}, got {p.suffix!r}")
    if not isinstance(raw, dict):
        raise ModelFileError(p, f"expected a mapping of metadata fields, got {type(raw).__name__}")
    return raw


def _positive_number(value: Any, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value) or value <= 0:
        raise ValueError(f"expected {what} to be a positive number, got {value!r}")
    return float(value)


def parse_metadata(raw: dict[str, Any]) -> ModelMetadata:
    """Validate a metadata mapping (see the module docstring for the fields).

    Examples
    --------
    >>> parse_metadata({"class": "tv", "front": "+y", "up": "+z", "units": "cm"}).scale_value
    0.01
    """
    if not isinstance(raw, dict):
        raise ValueError(f"expected a mapping of metadata fields, got {type(raw).__name__}")
    unknown = sorted(set(raw) - _META_KEYS)
    if unknown:
        raise ValueError(f"unknown metadata field(s) {unknown}; expected some of {sorted(_META_KEYS)}")
    for key in ("class", "front", "up"):
        if key not in raw:
            raise ValueError(f"missing required metadata field {key!r}")
    cls = raw["class"]
    if not isinstance(cls, str) or not re.fullmatch(r"[a-z]+", cls):
        raise ValueError(f"expected 'class' to be a lowercase word such as 'chair', got {cls!r}")
    front, up = raw["front"], raw["up"]
    axes_rotation(front, up)
    given = [k for k in _SCALE_KEYS if k in raw]
    if len(given) != 1:
        raise ValueError(f"expected exactly one of {list(_SCALE_KEYS)} to give the metric size, got {given or 'none'}")
    kind = given[0]
    value: float | tuple[float, float, float]
    if kind == "units":
        if raw["units"] not in UNITS:
            raise ValueError(f"expected 'units' in {list(UNITS)}, got {raw['units']!r}")
        value = UNITS[raw["units"]]
    elif kind == "size":
        s = raw["size"]
        if not isinstance(s, (list, tuple)) or len(s) != 3:
            raise ValueError(f"expected 'size' to be [length, width, height] in metres, got {s!r}")
        value = tuple(_positive_number(x, "each 'size' entry") for x in s)  # type: ignore[assignment]
    else:
        value = _positive_number(raw[kind], repr(kind))
    model_id = raw.get("id")
    if model_id is not None and (not isinstance(model_id, str) or not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9_.\-]*", model_id)):
        raise ValueError(f"expected 'id' of letters, digits, '-', '_' or '.', got {model_id!r}")
    sym = raw.get("symmetry")
    if sym is not None and sym not in SYMMETRIES:
        raise ValueError(f"expected 'symmetry' in {list(SYMMETRIES)}, got {sym!r}")
    material = raw.get("material", "plastic")
    if material not in MATERIAL_NAMES:
        raise ValueError(f"expected 'material' in {list(MATERIAL_NAMES)}, got {material!r}")
    mats = raw.get("materials", {})
    if not isinstance(mats, dict) or any(not isinstance(k, str) or v not in MATERIAL_NAMES for k, v in mats.items()):
        raise ValueError(f"expected 'materials' to map part names to one of {list(MATERIAL_NAMES)}, got {mats!r}")
    return ModelMetadata(
        cls=cls,
        front=front,
        up=up,
        scale_kind=kind,
        scale_value=value,
        id=model_id,
        symmetry=sym,
        material=material,
        materials=tuple(sorted(mats.items())),
    )


# --------------------------------------------------------------------------- mesh reading


def _face_colors(mesh) -> NDArray[np.uint8]:
    """(F, 4) uint8 face colours of a trimesh mesh of any visual kind."""
    import trimesh

    vis = mesh.visual
    n = len(mesh.faces)
    try:
        if isinstance(vis, trimesh.visual.texture.TextureVisuals):
            vis = vis.to_color()
        cols = np.asarray(vis.face_colors, dtype=np.uint8)
        if cols.shape == (n, 4):
            return cols
    except (ValueError, AttributeError, IndexError, TypeError):
        pass
    return np.tile(np.array([160, 160, 160, 255], dtype=np.uint8), (n, 1))


def _read_parts(path: Path) -> list[tuple[str, NDArray[np.float64], NDArray[np.int64], NDArray[np.uint8]]]:
    """(part name, vertices, faces, face colours) of every triangle mesh in the file."""
    import trimesh

    try:
        # OBJ: one part per "o" object, not merged by material
        extra = {"split_objects": True, "group_material": False} if path.suffix.lower() == ".obj" else {}
        loaded = trimesh.load(str(path), process=False, **extra)
    except Exception as exc:  # trimesh raises many types on corrupt files
        raise ModelFileError(path, f"cannot read mesh ({type(exc).__name__}: {exc})") from exc
    geoms = loaded.dump(concatenate=False) if isinstance(loaded, trimesh.Scene) else [loaded]
    parts = []
    for g in geoms:
        if not isinstance(g, trimesh.Trimesh) or len(g.faces) == 0:
            continue
        name = str(g.metadata.get("node") or g.metadata.get("name") or "body")
        if isinstance(loaded, trimesh.Trimesh):
            name = "body"
        v = np.asarray(g.vertices, dtype=np.float64)
        f = np.asarray(g.faces, dtype=np.int64)
        if not np.all(np.isfinite(v)):
            raise ModelFileError(path, f"part {name!r} has NaN or infinite vertex coordinates")
        if f.min() < 0 or f.max() >= len(v):
            raise ModelFileError(path, f"part {name!r} has face indices outside its {len(v)} vertices")
        parts.append((name, v, f, _face_colors(g)))
    if not parts:
        raise ModelFileError(path, "contains no triangles (empty file, point cloud or lines only)")
    return parts


def _clean(
    v: NDArray[np.float64], f: NDArray[np.int64], key: NDArray[np.int64], face_budget: int, path: Path
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.int64]]:
    """pymeshlab clean-up; `key` (F,) is a per-face attribute carried through."""
    try:
        import pymeshlab
    except ImportError:  # pragma: no cover - core dependency
        raise ImportError("loading user models needs pymeshlab: pip install pymeshlab") from None
    ms = pymeshlab.MeshSet()
    ms.add_mesh(
        pymeshlab.Mesh(
            vertex_matrix=np.ascontiguousarray(v, dtype=np.float64),
            face_matrix=np.ascontiguousarray(f, dtype=np.int32),
            f_scalar_array=key.astype(np.float64),
        )
    )
    try:
        # 1e-5 of the bounding-box diagonal
        ms.meshing_merge_close_vertices(threshold=pymeshlab.PercentageValue(0.001))
        ms.meshing_remove_duplicate_faces()
        ms.meshing_remove_null_faces()
        ms.meshing_remove_unreferenced_vertices()
        if ms.current_mesh().face_number() > face_budget:
            ms.meshing_decimation_quadric_edge_collapse(
                targetfacenum=int(face_budget), preservenormal=True, preserveboundary=True, autoclean=True
            )
            ms.meshing_remove_unreferenced_vertices()
    except pymeshlab.PyMeshLabException as exc:
        raise ModelFileError(path, f"mesh clean-up failed: {exc}") from exc
    m = ms.current_mesh()
    return (
        np.asarray(m.vertex_matrix(), dtype=np.float64),
        np.asarray(m.face_matrix(), dtype=np.int64),
        np.rint(m.face_scalar_array()).astype(np.int64),
    )


def load_model_file(
    mesh_path: str | os.PathLike[str],
    metadata: str | os.PathLike[str] | dict[str, Any] | None = None,
    *,
    face_budget: int = DEFAULT_FACE_BUDGET,
) -> Model3D:
    """Load one CAD file into a canonical `Model3D`.

    Convention:
        Output in the canonical model frame (metres, z up, front +x, bbox
        centre x = y = 0, min z = 0). The metadata's ``front``/``up`` name
        the file's axes; ``size`` is given along the canonical axes.

    Parameters
    ----------
    mesh_path : path
        ``.obj``, ``.glb``, ``.gltf``, ``.ply`` or ``.stl``.
    metadata : path or dict, optional
        Metadata file or an already parsed mapping; default: the ``.json``
        (or ``.yaml`` / ``.yml``) file next to the mesh with the same stem.
    face_budget : int
        Meshes with more faces are decimated to this many.

    Raises
    ------
    ModelFileError
        (a ValueError) naming the file, for unreadable meshes and missing
        or invalid metadata.

    Examples
    --------
    >>> import tempfile, json, trimesh
    >>> with tempfile.TemporaryDirectory() as d:
    ...     _ = trimesh.creation.box((40.0, 50.0, 90.0)).export(d + "/crate.ply")
    ...     _ = open(d + "/crate.json", "w").write(json.dumps({"class": "box", "front": "+y", "up": "+z", "units": "cm"}))
    ...     m = load_model_file(d + "/crate.ply")
    >>> m.id, m.size.round(3).tolist()
    ('crate', [0.5, 0.4, 0.9])
    """
    mp = Path(mesh_path)
    if int(face_budget) < 4:
        raise ValueError(f"expected face_budget >= 4, got {face_budget}")
    if mp.suffix.lower() not in MESH_SUFFIXES:
        raise ModelFileError(mp, f"expected a mesh file ending in {MESH_SUFFIXES}, got {mp.suffix!r}")
    if not mp.is_file():
        raise ModelFileError(mp, "mesh file does not exist")
    meta_where: Path = mp
    if metadata is None:
        found = [mp.with_suffix(s) for s in META_SUFFIXES if mp.with_suffix(s).is_file()]
        if not found:
            raise ModelFileError(mp, f"missing metadata: expected {mp.with_suffix('.json').name} next to it")
        if len(found) > 1:
            raise ModelFileError(mp, f"ambiguous metadata: {[p.name for p in found]}")
        meta_where = found[0]
        raw = read_metadata_file(meta_where)
    elif isinstance(metadata, dict):
        raw = metadata
    else:
        meta_where = Path(metadata)
        raw = read_metadata_file(meta_where)
    try:
        meta = parse_metadata(raw)
    except ValueError as exc:
        raise ModelFileError(meta_where, str(exc)) from exc

    parts = _read_parts(mp)
    names: list[str] = []
    verts, faces, cols, pids = [], [], [], []
    offset = 0
    for name, v, f, c in parts:
        if name not in names:
            names.append(name)
        verts.append(v)
        faces.append(f + offset)
        offset += len(v)
        cols.append(c)
        pids.append(np.full(len(f), names.index(name), dtype=np.int64))
    v_all = np.concatenate(verts)
    f_all = np.concatenate(faces)
    c_all = np.concatenate(cols)
    p_all = np.concatenate(pids)
    # one key per (part, colour) combination survives the clean-up exactly
    combo = np.concatenate([p_all[:, None], c_all.astype(np.int64)], axis=1)
    table, key = np.unique(combo, axis=0, return_inverse=True)
    v_all, f_all, keep, _ = drop_degenerate(v_all, f_all, min_area=0.0)
    if len(f_all) == 0:
        raise ModelFileError(mp, "all faces are degenerate")
    v_c, f_c, key_c = _clean(v_all, f_all, key.reshape(-1)[keep], int(face_budget), mp)
    if len(f_c) == 0:
        raise ModelFileError(mp, "no faces left after clean-up")

    v_c = v_c @ axes_rotation(meta.front, meta.up).T
    ext = v_c.max(axis=0) - v_c.min(axis=0)
    if meta.scale_kind == "size":
        if np.any(ext <= 0):
            raise ModelFileError(mp, f"flat mesh (extents {ext.tolist()}) cannot be scaled to a 3D 'size'")
        factor = np.asarray(meta.scale_value, dtype=np.float64) / ext
    elif meta.scale_kind == "height":
        if ext[2] <= 0:
            raise ModelFileError(mp, "mesh has zero height, cannot scale it to 'height'")
        factor = np.full(3, float(meta.scale_value) / ext[2])  # type: ignore[arg-type]
    else:
        factor = np.full(3, float(meta.scale_value))  # type: ignore[arg-type]
    v_c = v_c * factor
    size = ext * factor
    if size.max() > MAX_SIZE_M or size.max() < MIN_SIZE_M:
        raise ModelFileError(
            meta_where,
            f"implausible metric size {np.round(size, 4).tolist()} m after scaling; check 'units'/'scale'",
        )
    v_c = canonicalize_vertices(v_c)
    v_c, f_c, keep2, _ = drop_degenerate(v_c, f_c, min_area=1e-14)
    key_c = key_c[keep2]
    if len(f_c) == 0:
        raise ModelFileError(mp, "no faces left after removing degenerate ones")
    face_part = table[key_c, 0]
    face_col = table[key_c, 1:].astype(np.uint8)
    used = np.unique(face_part)
    remap = np.full(len(names), -1, dtype=np.int32)
    remap[used] = np.arange(len(used), dtype=np.int32)
    mat_of = dict(meta.materials)
    part_names = tuple(names[i] for i in used)
    unknown = sorted(set(mat_of) - set(names))
    if unknown:
        raise ModelFileError(meta_where, f"'materials' names parts {unknown} that the mesh lacks; it has {names}")
    symmetry = meta.symmetry or ("full" if meta.cls == "plant" else "none")
    try:
        return Model3D(
            id=meta.id or mp.stem,
            cls=meta.cls,
            symmetry=symmetry,  # type: ignore[arg-type]
            vertices=canonicalize_vertices(v_c),
            faces=f_c,
            face_colors=face_col,
            face_parts=remap[face_part],
            part_names=part_names,
            part_materials=tuple(mat_of.get(n, meta.material) for n in part_names),
            source=str(mp),
        )
    except ValueError as exc:
        raise ModelFileError(mp, str(exc)) from exc


def load_model_folder(
    path: str | os.PathLike[str],
    *,
    face_budget: int = DEFAULT_FACE_BUDGET,
    recursive: bool = False,
) -> ModelFolderResult:
    """Load every model file of a folder; failures are collected, not raised.

    Convention:
        Models come out in the canonical model frame (metres, z up, front +x,
        bbox centre x = y = 0, min z = 0).

    Parameters
    ----------
    path : path
        The folder.
    face_budget : int
        Per-model face limit (quadric decimation above it).
    recursive : bool
        Also look into sub-folders.

    Returns
    -------
    ModelFolderResult
        ``.library`` with the models that loaded, ``.errors`` with one
        `ModelLoadIssue` per failed file (mesh without metadata, metadata
        without mesh, unreadable mesh, invalid metadata, duplicate id).

    Examples
    --------
    >>> import tempfile, json, trimesh
    >>> with tempfile.TemporaryDirectory() as d:
    ...     _ = trimesh.creation.box((0.5, 0.5, 0.5)).export(d + "/a.obj")
    ...     _ = open(d + "/a.json", "w").write(json.dumps({"class": "box", "front": "+x", "up": "+z", "units": "m"}))
    ...     _ = open(d + "/b.obj", "w").write("v 0 0 0\\n")
    ...     res = load_model_folder(d)
    >>> res.library.ids, [e.file.name for e in res.errors]
    (('a',), ['b.obj'])
    """
    folder = Path(path)
    if not folder.is_dir():
        raise ValueError(f"expected a folder of model files, got {str(folder)!r} (not a directory)")
    files = sorted(folder.rglob("*") if recursive else folder.iterdir())
    meshes = [p for p in files if p.is_file() and p.suffix.lower() in MESH_SUFFIXES]
    metas = [p for p in files if p.is_file() and p.suffix.lower() in META_SUFFIXES]
    errors: list[ModelLoadIssue] = []
    models: list[Model3D] = []
    seen: dict[str, Path] = {}
    mesh_stems = {p.with_suffix("") for p in meshes}
    for meta in metas:
        if meta.with_suffix("") not in mesh_stems:
            errors.append(ModelLoadIssue(meta, f"metadata without a mesh: expected {meta.stem}{{.obj,.glb,.ply,...}} next to it"))
    for mesh_path in meshes:
        try:
            model = load_model_file(mesh_path, face_budget=face_budget)
        except ModelFileError as exc:
            errors.append(ModelLoadIssue(exc.file, exc.reason))
            continue
        if model.id in seen:
            errors.append(ModelLoadIssue(mesh_path, f"duplicate model id {model.id!r} (already used by {seen[model.id].name})"))
            continue
        seen[model.id] = mesh_path
        models.append(model)
    errors.sort(key=lambda e: str(e.file))
    return ModelFolderResult(folder=folder, library=ModelLibrary(models), errors=tuple(errors))
