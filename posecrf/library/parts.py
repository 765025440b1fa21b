"""Coloured primitive parts and their assembly into a canonical `Model3D`.

Every procedural model is a list of `Part` objects (a trimesh primitive with a
name, a material and a colour) put together by `assemble_model`, which moves
the result into the canonical frame and drops degenerate triangles.

Convention:
    Parts are built in any frame with z up and the object's front at +x;
    `assemble_model` only translates (never rotates) into the canonical frame
    (bounding-box centre at x = y = 0, min z = 0). Lengths in metres,
    angles in radians.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from panogeom.rotation import rot_x, rot_y, rot_z  # noqa: F401  (re-exported for the builders)

from .model import Model3D, Symmetry, material_index

if TYPE_CHECKING:  # pragma: no cover - typing only
    import trimesh

RGB = tuple[int, int, int]

MIN_FACE_AREA = 1e-10
"""Triangles below this area (m^2) are dropped as degenerate."""


def _trimesh():
    try:
        import trimesh
    except ImportError as exc:  # pragma: no cover - trimesh is a core dependency
        raise ImportError("posecrf.library needs trimesh: pip install trimesh") from exc
    return trimesh


@dataclass(frozen=True, eq=False)
class Part:
    """One named, coloured piece of a model.

    Attributes
    ----------
    name : str
        Part name; parts with the same name are merged into one part of the
        model and must share the material.
    material : str
        Material name from `MATERIALS`.
    color : tuple of 3 int
        RGB 0..255.
    mesh : trimesh.Trimesh
        The geometry (owned by the part; do not edit after creating it).
    """

    name: str
    material: str
    color: RGB
    mesh: "trimesh.Trimesh"

    def __post_init__(self) -> None:
        material_index(self.material)
        c = tuple(int(x) for x in self.color)
        if len(c) != 3 or min(c) < 0 or max(c) > 255:
            raise ValueError(f"part {self.name!r}: expected an RGB colour of 3 ints in 0..255, got {self.color!r}")
        object.__setattr__(self, "color", c)

    def transformed(self, matrix: ArrayLike) -> "Part":
        """A copy moved by a (4, 4) homogeneous transform."""
        m = np.asarray(matrix, dtype=np.float64)
        if m.shape != (4, 4):
            raise ValueError(f"expected a (4, 4) transform, got {m.shape}")
        mesh = self.mesh.copy()
        mesh.apply_transform(m)
        return Part(self.name, self.material, self.color, mesh)


# --------------------------------------------------------------------------- rotations


def _pose(rotation: ArrayLike | None, center: ArrayLike) -> NDArray[np.float64]:
    t = np.eye(4)
    if rotation is not None:
        r = np.asarray(rotation, dtype=np.float64)
        if r.shape != (3, 3):
            raise ValueError(f"expected a (3, 3) rotation, got {r.shape}")
        t[:3, :3] = r
    c = np.asarray(center, dtype=np.float64)
    if c.shape != (3,):
        raise ValueError(f"expected a centre (3,), got {c.shape}")
    t[:3, 3] = c
    return t


def _positive(name: str, **values: float) -> None:
    for key, val in values.items():
        if not np.isfinite(val) or val <= 0:
            raise ValueError(f"part {name!r}: expected {key} > 0, got {val}")


# --------------------------------------------------------------------------- primitives


def box(
    name: str,
    material: str,
    color: RGB,
    extents: ArrayLike,
    center: ArrayLike = (0.0, 0.0, 0.0),
    rotation: ArrayLike | None = None,
) -> Part:
    """A box with `extents` (x, y, z) centred at `center`, optionally rotated about its centre."""
    e = np.asarray(extents, dtype=np.float64)
    if e.shape != (3,) or np.any(~np.isfinite(e)) or np.any(e <= 0):
        raise ValueError(f"part {name!r}: expected 3 positive extents, got {extents!r}")
    mesh = _trimesh().creation.box(extents=e, transform=_pose(rotation, center))
    return Part(name, material, color, mesh)


def box_between(name: str, material: str, color: RGB, lo: ArrayLike, hi: ArrayLike) -> Part:
    """An axis-aligned box from corner `lo` to corner `hi` (each (3,))."""
    lo_, hi_ = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    return box(name, material, color, hi_ - lo_, (lo_ + hi_) / 2)


def cylinder(
    name: str, material: str, color: RGB, p0: ArrayLike, p1: ArrayLike, radius: float, sections: int = 16
) -> Part:
    """A capped cylinder of `radius` whose axis runs from `p0` to `p1` (each (3,))."""
    a, b = np.asarray(p0, dtype=np.float64), np.asarray(p1, dtype=np.float64)
    _positive(name, radius=radius, length=float(np.linalg.norm(b - a)))
    mesh = _trimesh().creation.cylinder(radius=radius, segment=np.stack([a, b]), sections=sections)
    return Part(name, material, color, mesh)


def capsule(
    name: str, material: str, color: RGB, p0: ArrayLike, p1: ArrayLike, radius: float, count: int = 8
) -> Part:
    """A capsule (cylinder with hemispherical ends) from `p0` to `p1` (end-sphere centres)."""
    a, b = np.asarray(p0, dtype=np.float64), np.asarray(p1, dtype=np.float64)
    d = b - a
    length = float(np.linalg.norm(d))
    _positive(name, radius=radius, length=length)
    tm = _trimesh()
    mesh = tm.creation.capsule(height=length, radius=radius, count=[count, count])
    # trimesh's capsule is centred at the origin, its sphere centres at z = -+height/2
    t = np.eye(4)
    t[:3, :3] = _align_z_to(d / length)
    t[:3, 3] = (a + b) / 2
    mesh.apply_transform(t)
    return Part(name, material, color, mesh)


def cone(
    name: str,
    material: str,
    color: RGB,
    base_center: ArrayLike,
    radius: float,
    height: float,
    sections: int = 16,
) -> Part:
    """An upright cone standing on `base_center` (apex at +`height` along z)."""
    _positive(name, radius=radius, height=height)
    mesh = _trimesh().creation.cone(radius=radius, height=height, sections=sections)
    mesh.apply_translation(np.asarray(base_center, dtype=np.float64))
    return Part(name, material, color, mesh)


def ellipsoid(
    name: str,
    material: str,
    color: RGB,
    center: ArrayLike,
    radii: ArrayLike,
    rotation: ArrayLike | None = None,
    subdivisions: int = 1,
) -> Part:
    """An ellipsoid with semi-axes `radii` (x, y, z), optionally rotated about its centre."""
    r = np.asarray(radii, dtype=np.float64)
    if r.shape != (3,) or np.any(~np.isfinite(r)) or np.any(r <= 0):
        raise ValueError(f"part {name!r}: expected 3 positive radii, got {radii!r}")
    mesh = _trimesh().creation.icosphere(subdivisions=subdivisions, radius=1.0)
    mesh.apply_scale(r)
    mesh.apply_transform(_pose(rotation, center))
    return Part(name, material, color, mesh)


def sphere(name: str, material: str, color: RGB, center: ArrayLike, radius: float, subdivisions: int = 1) -> Part:
    """A sphere (icosphere) of `radius` at `center`."""
    return ellipsoid(name, material, color, center, (radius, radius, radius), subdivisions=subdivisions)


def revolved(
    name: str,
    material: str,
    color: RGB,
    profile_rz: ArrayLike,
    base_center: ArrayLike = (0.0, 0.0, 0.0),
    sections: int = 24,
) -> Part:
    """A surface of revolution about the vertical axis through `base_center`.

    Parameters
    ----------
    profile_rz : (N, 2) float
        (radius, height) points, from the bottom on the axis round to the top
        on the axis for a closed solid (e.g. a pot).
    """
    p = np.asarray(profile_rz, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2 or len(p) < 3 or np.any(p[:, 0] < 0):
        raise ValueError(f"part {name!r}: expected a profile (N >= 3, 2) of (r >= 0, z), got {p.shape}")
    mesh = _trimesh().creation.revolve(p, sections=sections)
    mesh.apply_translation(np.asarray(base_center, dtype=np.float64))
    return Part(name, material, color, mesh)


def quad(name: str, material: str, color: RGB, corners: ArrayLike) -> Part:
    """A single-sided planar quad (two triangles).

    Parameters
    ----------
    corners : (4, 3) float
        Corners counter-clockwise seen from the side the quad faces.
    """
    c = np.asarray(corners, dtype=np.float64)
    if c.shape != (4, 3):
        raise ValueError(f"part {name!r}: expected 4 corners (4, 3), got {c.shape}")
    mesh = _trimesh().Trimesh(vertices=c, faces=[[0, 1, 2], [0, 2, 3]], process=False)
    return Part(name, material, color, mesh)


def _align_z_to(direction: NDArray[np.float64]) -> NDArray[np.float64]:
    """(3, 3) rotation taking +z to the unit vector `direction`."""
    z = np.array([0.0, 0.0, 1.0])
    v = np.cross(z, direction)
    c = float(np.dot(z, direction))
    if np.linalg.norm(v) < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + vx + vx @ vx / (1.0 + c)


def rotated_about(parts: Sequence[Part], rotation: ArrayLike, pivot: ArrayLike) -> list[Part]:
    """Copies of `parts` rotated by a (3, 3) `rotation` about the point `pivot` (3,)."""
    r = np.asarray(rotation, dtype=np.float64)
    p = np.asarray(pivot, dtype=np.float64)
    t = _pose(r, p) @ _pose(None, -p)
    return [part.transformed(t) for part in parts]


# --------------------------------------------------------------------------- assembly


def canonicalize_vertices(vertices: ArrayLike) -> NDArray[np.float64]:
    """Translate vertices so the bbox centre is at x = y = 0 and min z = 0.

    Convention:
        Canonical model frame (shared/CONVENTIONS.md); only a translation,
        the axes must already be z up and front +x.

    Parameters
    ----------
    vertices : (V, 3) float

    Returns
    -------
    (V, 3) float64

    Examples
    --------
    >>> canonicalize_vertices([[1.0, 2.0, 3.0], [3.0, 4.0, 5.0]]).tolist()
    [[-1.0, -1.0, 0.0], [1.0, 1.0, 2.0]]
    """
    v = np.asarray(vertices, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != 3 or len(v) == 0:
        raise ValueError(f"expected vertices (V, 3) with V >= 1, got {v.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError("expected finite vertices, got NaN or inf")
    lo, hi = v.min(axis=0), v.max(axis=0)
    shift = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
    return v - shift


def drop_degenerate(
    vertices: NDArray[np.float64], faces: NDArray[np.int64], min_area: float = MIN_FACE_AREA
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.bool_], NDArray[np.int64]]:
    """Remove faces below `min_area` and vertices no face uses.

    Returns
    -------
    vertices : (V', 3) float64
    faces : (F', 3) int64
        Re-indexed.
    kept_faces : (F,) bool
        Which input faces survive.
    kept_vertices : (V',) int64
        Input index of each output vertex.
    """
    tri = vertices[faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    distinct = (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])
    keep = (area > min_area) & distinct & np.all(np.isfinite(tri), axis=(1, 2))
    f = faces[keep]
    used = np.unique(f)
    remap = np.full(len(vertices), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    return vertices[used], remap[f], keep, used


def assemble_model(
    model_id: str,
    cls: str,
    parts: Sequence[Part],
    *,
    symmetry: Symmetry = "none",
    source: str = "",
) -> Model3D:
    """Concatenate parts into one canonical `Model3D`.

    Parts sharing a name become one model part (their materials must agree).
    The result is translated into the canonical frame and degenerate faces
    are dropped; vertices of different parts are never merged, so per-face
    colours stay exact when converted to vertex colours.

    Convention:
        Parts are given with z up and the front at +x; the output has its
        bbox centre at x = y = 0 and min z = 0 (metres).

    Examples
    --------
    >>> seat = box("seat", "wood", (150, 100, 60), (0.4, 0.4, 0.05), (0.0, 0.0, 0.45))
    >>> m = assemble_model("stool-01", "stool", [seat])
    >>> m.size.round(2).tolist(), m.part_names, m.n_faces
    ([0.4, 0.4, 0.05], ('seat',), 12)
    """
    if len(parts) == 0:
        raise ValueError(f"{model_id}: expected at least one part, got none")
    names: list[str] = []
    materials: list[str] = []
    verts, faces, colors, pids = [], [], [], []
    offset = 0
    for part in parts:
        if not isinstance(part, Part):
            raise ValueError(f"{model_id}: expected Part objects, got {type(part).__name__}")
        if part.name in names:
            k = names.index(part.name)
            if materials[k] != part.material:
                raise ValueError(
                    f"{model_id}: part {part.name!r} has materials {materials[k]!r} and {part.material!r}"
                )
        else:
            k = len(names)
            names.append(part.name)
            materials.append(part.material)
        v = np.asarray(part.mesh.vertices, dtype=np.float64)
        f = np.asarray(part.mesh.faces, dtype=np.int64)
        verts.append(v)
        faces.append(f + offset)
        offset += len(v)
        colors.append(np.tile(np.array([*part.color, 255], dtype=np.uint8), (len(f), 1)))
        pids.append(np.full(len(f), k, dtype=np.int32))
    v_all = np.concatenate(verts)
    f_all = np.concatenate(faces)
    v_all, f_all, keep, _ = drop_degenerate(v_all, f_all)
    if len(f_all) == 0:
        raise ValueError(f"{model_id}: all faces are degenerate")
    c_all = np.concatenate(colors)[keep]
    p_all = np.concatenate(pids)[keep]
    # parts whose faces all vanished are removed from the table
    present = np.unique(p_all)
    remap = np.full(len(names), -1, dtype=np.int32)
    remap[present] = np.arange(len(present), dtype=np.int32)
    return Model3D(
        id=model_id,
        cls=cls,
        symmetry=symmetry,
        vertices=canonicalize_vertices(v_all),
        faces=f_all,
        face_colors=c_all,
        face_parts=remap[p_all],
        part_names=tuple(names[i] for i in present),
        part_materials=tuple(materials[i] for i in present),
        source=source,
    )
