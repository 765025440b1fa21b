"""Export models (or placed models) to GLB / OBJ with colours, atomically.

Each model part becomes one named node (``<model id>/<part>``; placed models
get ``<k>:<model id>/<part>``) whose per-face colours are written as exact
vertex colours (vertices are split where faces of different colours meet).
Files are written to a temporary file in the target folder and moved into
place with ``os.replace``, so an interrupted export never leaves a
half-written file.

Convention:
    Geometry in metres, z up. A placement is a (4, 4) homogeneous transform
    from the model's canonical frame (front +x, base centred at the origin)
    into the world frame. glTF itself is y-up: by default GLB files hold the
    z-up coordinates unchanged (as trimesh writes and reads them); pass
    ``y_up=True`` for viewers that follow the glTF convention, which maps
    (x, y, z) -> (x, z, -y).
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Literal

import numpy as np
from numpy.typing import ArrayLike

from .model import Model3D

if TYPE_CHECKING:  # pragma: no cover - typing only
    import trimesh

ExportFormat = Literal["glb", "obj"]
_FORMATS: tuple[str, ...] = ("glb", "obj")


def _split_by_color(vertices: np.ndarray, faces: np.ndarray, colors: np.ndarray) -> "trimesh.Trimesh":
    """A mesh whose vertex colours reproduce the face colours exactly."""
    import trimesh

    _, color_id = np.unique(colors, axis=0, return_inverse=True)
    color_id = color_id.reshape(-1)
    corner_keys = np.stack([faces.reshape(-1), np.repeat(color_id, 3)], axis=1)
    uniq, inverse = np.unique(corner_keys, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    new_faces = inverse.reshape(-1, 3)
    vcol = np.empty((len(uniq), 4), dtype=np.uint8)
    vcol[inverse] = np.repeat(colors, 3, axis=0)
    return trimesh.Trimesh(
        vertices=vertices[uniq[:, 0]], faces=new_faces, vertex_colors=vcol, process=False
    )


def _check_transform(t: ArrayLike, what: str) -> np.ndarray:
    m = np.asarray(t, dtype=np.float64)
    if m.shape != (4, 4) or not np.all(np.isfinite(m)):
        raise ValueError(f"{what}: expected a finite (4, 4) transform, got shape {m.shape}")
    if not np.allclose(m[3], [0, 0, 0, 1]):
        raise ValueError(f"{what}: expected a homogeneous transform with last row [0, 0, 0, 1], got {m[3].tolist()}")
    if np.linalg.det(m[:3, :3]) <= 0:
        raise ValueError(f"{what}: expected a transform that keeps orientation (det > 0)")
    return m


def _pairs(placed: Sequence[tuple[Model3D, ArrayLike]]) -> list[tuple[Model3D, ArrayLike]]:
    if len(placed) == 0:
        raise ValueError("expected at least one (model, transform) pair, got none")
    for k, item in enumerate(placed):
        if not (isinstance(item, tuple) and len(item) == 2 and isinstance(item[0], Model3D)):
            raise ValueError(f"placed[{k}]: expected a (Model3D, (4, 4) transform) pair, got {type(item).__name__}")
    return list(placed)


def scene_of(placed: Sequence[tuple[Model3D, ArrayLike]]) -> "trimesh.Scene":
    """A ``trimesh.Scene`` of placed models, one colour-exact node per part.

    Parameters
    ----------
    placed : sequence of (Model3D, (4, 4) float)
        Models and their canonical-to-world transforms.

    Examples
    --------
    >>> from posecrf.library import builtin_library
    >>> lib = builtin_library()
    >>> sc = scene_of([(lib["tv-01"], np.eye(4))])
    >>> sorted(sc.geometry)[:2]
    ['0:tv-01/back_cover', '0:tv-01/foot']
    """
    import trimesh

    scene = trimesh.Scene()
    for k, (model, t) in enumerate(_pairs(placed)):
        m = _check_transform(t, f"placed[{k}] ({model.id})")
        v = model.vertices @ m[:3, :3].T + m[:3, 3]
        for pid, pname in enumerate(model.part_names):
            sel = model.face_parts == pid
            mesh = _split_by_color(v, model.faces[sel], model.face_colors[sel])
            name = f"{k}:{model.id}/{pname}"
            mesh.metadata["name"] = name
            scene.add_geometry(mesh, geom_name=name, node_name=name)
    return scene


def _write_atomic(data: bytes, path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    done = False
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
        done = True
    finally:
        if not done and os.path.exists(tmp):
            os.unlink(tmp)


def _format_of(path: Path, file_type: str | None) -> str:
    fmt = (file_type or path.suffix.lstrip(".")).lower()
    if fmt not in _FORMATS:
        raise ValueError(f"{path}: expected a .glb or .obj file (or file_type in {_FORMATS}), got {fmt!r}")
    return fmt


Z_UP_TO_Y_UP = np.array([[1.0, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 0], [0, 0, 0, 1]])
"""(4, 4) rotation by -90 deg about x: z-up world -> glTF's y-up frame."""


def export_scene(
    placed: Sequence[tuple[Model3D, ArrayLike]],
    path: str | os.PathLike[str],
    *,
    file_type: ExportFormat | None = None,
    y_up: bool = False,
) -> Path:
    """Write placed models to one GLB or OBJ file, atomically.

    OBJ files carry the colours as per-vertex RGB after each ``v`` line (read
    by trimesh, MeshLab and Blender) and one ``o`` object per part; no MTL
    file is written.

    Convention:
        Metres, z up; each transform maps the model's canonical frame into
        the world frame.

    Parameters
    ----------
    placed : sequence of (Model3D, (4, 4) float)
    path : str or PathLike
        Target file; its suffix picks the format unless `file_type` is given.
    file_type : {"glb", "obj"}, optional
    y_up : bool
        Rotate the output into a y-up frame (`Z_UP_TO_Y_UP`), the glTF
        convention; default False keeps z up.

    Returns
    -------
    Path
        The written file.

    Examples
    --------
    >>> import tempfile, trimesh
    >>> from posecrf.library import builtin_library
    >>> lib = builtin_library()
    >>> t = np.eye(4); t[:3, 3] = (2.0, 0.0, 0.0)
    >>> with tempfile.TemporaryDirectory() as d:
    ...     p = export_scene([(lib["bed-01"], np.eye(4)), (lib["chair-01"], t)], d + "/room.glb")
    ...     back = trimesh.load(p, force="mesh")
    >>> bool(back.bounds[1, 0] > 2.0)
    True
    """
    p = Path(path)
    fmt = _format_of(p, file_type)
    if y_up:
        placed = [(m, Z_UP_TO_Y_UP @ _check_transform(t, f"placed[{k}]")) for k, (m, t) in enumerate(_pairs(placed))]
    scene = scene_of(placed)
    data = scene.export(file_type=fmt)
    if isinstance(data, str):
        data = data.encode("utf-8")
    _write_atomic(data, p)
    return p


def export_model(
    model: Model3D,
    path: str | os.PathLike[str],
    *,
    transform: ArrayLike | None = None,
    file_type: ExportFormat | None = None,
    y_up: bool = False,
) -> Path:
    """Write one model to GLB or OBJ with its colours, atomically.

    Convention:
        Metres, z up; `transform` (default identity) maps the canonical
        model frame into the output frame.

    Examples
    --------
    >>> import tempfile, trimesh
    >>> from posecrf.library import builtin_library
    >>> m = builtin_library()["plant-01"]
    >>> with tempfile.TemporaryDirectory() as d:
    ...     back = trimesh.load(export_model(m, d + "/plant.obj"), force="mesh")
    >>> bool(np.allclose(back.bounds, m.bounds, atol=1e-6))
    True
    """
    if not isinstance(model, Model3D):
        raise ValueError(f"expected a Model3D, got {type(model).__name__}")
    t = np.eye(4) if transform is None else transform
    return export_scene([(model, t)], path, file_type=file_type, y_up=y_up)
