"""The `Model3D` record: one furniture model in the canonical model frame.

Convention:
    Model canonical frame (shared/CONVENTIONS.md): metres, z up, the base
    centred at the origin (x, y centre of the bounding box at 0, min z = 0),
    the object's front (bed foot end, TV screen, chair seat opening, sofa
    seat, doors and drawers) facing +x. ``size`` = (extent along x, along y,
    along z) = (length, width, height).
"""

from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING, Literal

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:  # pragma: no cover - typing only
    import trimesh

Symmetry = Literal["none", "two", "full"]
SYMMETRIES: tuple[str, ...] = ("none", "two", "full")


@dataclass(frozen=True)
class Material:
    """One entry of the material table a renderer uses to texture parts.

    Attributes
    ----------
    index : int
        Position in `MATERIALS`; the value stored in ``Model3D.face_materials``.
    name : str
        Lowercase material name (``"wood"``, ``"fabric"``, ...).
    rgb : tuple of 3 int
        A typical colour in 0..255, used where a model brings no colour.
    """

    index: int
    name: str
    rgb: tuple[int, int, int]


MATERIALS: tuple[Material, ...] = (
    Material(0, "wood", (160, 120, 80)),
    Material(1, "fabric", (150, 150, 155)),
    Material(2, "metal", (170, 172, 178)),
    Material(3, "plastic", (40, 40, 44)),
    Material(4, "leaf", (70, 130, 60)),
    Material(5, "screen", (15, 20, 35)),
    Material(6, "ceramic", (225, 222, 215)),
    Material(7, "soil", (70, 50, 35)),
    Material(8, "glass", (190, 205, 215)),
)
"""The material table: ``MATERIALS[i].name`` is material index ``i``."""

MATERIAL_NAMES: tuple[str, ...] = tuple(m.name for m in MATERIALS)


def material_index(name: str) -> int:
    """Index of a material name in `MATERIALS`.

    Examples
    --------
    >>> material_index("screen")
    5
    """
    try:
        return MATERIAL_NAMES.index(name)
    except ValueError:
        raise ValueError(
            f"expected a material name out of {list(MATERIAL_NAMES)}, got {name!r}"
        ) from None


_CLASS_RE = re.compile(r"^[a-z]+$")
_ID_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.\-]*$")
_CANON_TOL = 1e-6


def _readonly(a: NDArray) -> NDArray:
    a = np.array(a, copy=True)
    a.flags.writeable = False
    return a


@dataclass(frozen=True, eq=False)
class Model3D:
    """A furniture model: a coloured triangle mesh in the canonical frame.

    The arrays are read-only copies: a `Model3D` (and with it a cached
    library) cannot be changed by accident. `mesh` builds a fresh
    ``trimesh.Trimesh`` on every access, so editing it leaves the model
    untouched. Equality is identity; compare contents with `content_hash`.

    Convention:
        Canonical model frame: metres, z up, bounding-box centre at x = y = 0,
        min z = 0, front facing +x. ``size`` = extents along (x, y, z).
        The constructor refuses vertices that are not in this frame.

    Attributes
    ----------
    id : str
        Model id, e.g. ``"bed-03"``.
    cls : str
        Lowercase class name (``bed``, ``chair``, ``tv``, ``plant``, ...).
    symmetry : {"none", "two", "full"}
        Rotational symmetry about z: none, 2-fold (180 deg), or full
        (orientation carries no information, e.g. plants).
    vertices : (V, 3) float64
    faces : (F, 3) int64
        Vertex indices, counter-clockwise seen from outside.
    face_colors : (F, 4) uint8
        RGBA per face.
    face_parts : (F,) int32
        Index into `part_names` / `part_materials` per face.
    part_names : tuple of str
        One name per part (``"mattress"``, ``"leg"``, ...).
    part_materials : tuple of str
        Material name (see `MATERIALS`) per part.
    source : str
        Where the model came from: ``"procedural:<builder>"`` or a file path.
    size : (3,) float64
        Derived: extents along x, y, z in metres.
    """

    id: str
    cls: str
    symmetry: Symmetry
    vertices: NDArray[np.float64] = field(repr=False)
    faces: NDArray[np.int64] = field(repr=False)
    face_colors: NDArray[np.uint8] = field(repr=False)
    face_parts: NDArray[np.int32] = field(repr=False)
    part_names: tuple[str, ...] = field(repr=False)
    part_materials: tuple[str, ...] = field(repr=False)
    source: str = ""
    size: NDArray[np.float64] = field(init=False)

    def __post_init__(self) -> None:
        if not isinstance(self.id, str) or not _ID_RE.match(self.id):
            raise ValueError(
                f"expected a model id of letters, digits, '-', '_' or '.', got {self.id!r}"
            )
        if not isinstance(self.cls, str) or not _CLASS_RE.match(self.cls):
            raise ValueError(f"expected a lowercase class name such as 'bed', got {self.cls!r}")
        if self.symmetry not in SYMMETRIES:
            raise ValueError(f"expected symmetry in {SYMMETRIES}, got {self.symmetry!r}")
        v = np.asarray(self.vertices, dtype=np.float64)
        f = np.asarray(self.faces)
        if v.ndim != 2 or v.shape[1] != 3 or len(v) < 3:
            raise ValueError(f"{self.id}: expected vertices (V, 3) with V >= 3, got {v.shape}")
        if not np.all(np.isfinite(v)):
            raise ValueError(f"{self.id}: vertices contain NaN or inf")
        if f.ndim != 2 or f.shape[1] != 3 or len(f) == 0 or not np.issubdtype(f.dtype, np.integer):
            raise ValueError(f"{self.id}: expected integer faces (F, 3) with F >= 1, got {f.shape} {f.dtype}")
        if f.min() < 0 or f.max() >= len(v):
            raise ValueError(f"{self.id}: face indices must lie in [0, {len(v)}), got [{f.min()}, {f.max()}]")
        c = np.asarray(self.face_colors)
        if c.shape != (len(f), 4) or c.dtype != np.uint8:
            raise ValueError(f"{self.id}: expected face_colors ({len(f)}, 4) uint8, got {c.shape} {c.dtype}")
        p = np.asarray(self.face_parts)
        names = tuple(self.part_names)
        mats = tuple(self.part_materials)
        if len(names) == 0 or len(names) != len(mats):
            raise ValueError(
                f"{self.id}: expected as many part_materials as part_names (>= 1), got {len(mats)} and {len(names)}"
            )
        if len(set(names)) != len(names):
            raise ValueError(f"{self.id}: part names must be unique, got {names}")
        for m in mats:
            material_index(m)
        if p.shape != (len(f),) or not np.issubdtype(p.dtype, np.integer):
            raise ValueError(f"{self.id}: expected integer face_parts ({len(f)},), got {p.shape} {p.dtype}")
        if p.min() < 0 or p.max() >= len(names):
            raise ValueError(f"{self.id}: face_parts must lie in [0, {len(names)}), got [{p.min()}, {p.max()}]")
        lo, hi = v.min(axis=0), v.max(axis=0)
        tol = _CANON_TOL * max(1.0, float(np.max(hi - lo)))
        centre = (lo + hi) / 2
        if abs(centre[0]) > tol or abs(centre[1]) > tol or abs(lo[2]) > tol:
            raise ValueError(
                f"{self.id}: expected vertices in the canonical frame (bbox centre x, y = 0, min z = 0), "
                f"got bbox centre ({centre[0]:.4g}, {centre[1]:.4g}) and min z {lo[2]:.4g}; "
                "use posecrf.library.canonicalize_vertices first"
            )
        set_ = object.__setattr__
        set_(self, "vertices", _readonly(v))
        set_(self, "faces", _readonly(f.astype(np.int64)))
        set_(self, "face_colors", _readonly(c))
        set_(self, "face_parts", _readonly(p.astype(np.int32)))
        set_(self, "part_names", names)
        set_(self, "part_materials", mats)
        set_(self, "size", _readonly(hi - lo))

    def __setstate__(self, state: dict) -> None:
        # unpickled arrays come back writeable; keep the read-only guarantee
        for key, value in state.items():
            object.__setattr__(self, key, _readonly(value) if isinstance(value, np.ndarray) else value)

    @property
    def n_faces(self) -> int:
        """Number of triangles."""
        return int(len(self.faces))

    @property
    def bounds(self) -> NDArray[np.float64]:
        """(2, 3) float: min and max corner of the bounding box."""
        return np.stack([self.vertices.min(axis=0), self.vertices.max(axis=0)])

    @cached_property
    def face_materials(self) -> NDArray[np.uint8]:
        """(F,) uint8: material index (into `MATERIALS`) per face."""
        per_part = np.array([material_index(m) for m in self.part_materials], dtype=np.uint8)
        return _readonly(per_part[self.face_parts])

    @property
    def mesh(self) -> "trimesh.Trimesh":
        """A fresh ``trimesh.Trimesh`` copy with per-face colours.

        ``mesh.metadata`` holds ``model_id``, ``class``, ``face_parts``,
        ``face_materials`` and ``part_names``. Editing the returned mesh does
        not change the model.
        """
        import trimesh

        m = trimesh.Trimesh(
            vertices=self.vertices.copy(),
            faces=self.faces.copy(),
            face_colors=self.face_colors.copy(),
            process=False,
        )
        m.metadata.update(
            {
                "model_id": self.id,
                "class": self.cls,
                "face_parts": self.face_parts.copy(),
                "face_materials": np.array(self.face_materials),
                "part_names": list(self.part_names),
            }
        )
        return m

    def part_mask(self, name: str) -> NDArray[np.bool_]:
        """(F,) bool: faces of the part called `name`."""
        if name not in self.part_names:
            raise ValueError(f"{self.id}: expected a part name out of {list(self.part_names)}, got {name!r}")
        return self.face_parts == self.part_names.index(name)

    def material_mask(self, material: str) -> NDArray[np.bool_]:
        """(F,) bool: faces whose material is `material`."""
        return self.face_materials == material_index(material)

    @cached_property
    def _hash(self) -> str:
        h = hashlib.sha256()
        q = np.round(self.vertices * 1e6).astype(np.int64)
        for arr in (q, self.faces, self.face_colors, self.face_parts):
            h.update(str(arr.shape).encode())
            h.update(np.ascontiguousarray(arr).tobytes())
        h.update("|".join(self.part_materials).encode())
        return h.hexdigest()

    def content_hash(self) -> str:
        """SHA-256 hex digest of geometry, colours and part materials.

        Vertices are quantised to 1 micrometre first. The id, class and
        source are not part of it, so identical geometry hashes the same.
        Computed once per model.
        """
        return self._hash
