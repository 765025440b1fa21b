"""Ray casting triangle scenes into equirectangular panoramas (depth, labels, instances).

A scene is plain data: one or more :class:`RenderMesh` (vertices in world
metres, triangles, and per-face surface label, instance id, material id and
base colour). :func:`room_meshes` builds the floor, ceiling and walls of a
Manhattan room from its floor polygon; :func:`transform_mesh` and
:func:`pose_matrix` place other meshes; :func:`merge_meshes` joins them.
:func:`raycast_equirect` casts one ray per panorama pixel with Open3D's
``RaycastingScene`` or libigl's Embree binding (both CPU) and returns a
:class:`RenderResult`; :func:`panogeom.texture.shade` turns that into an RGB
image.

Convention (CONVENTIONS.md):

- World frame: right-handed, metres, z up. The camera sits at
  ``camera_position``; with the default ``rotation=None`` its frame is the
  world frame, so the centre column of the panorama looks along +x and the
  column a quarter width left of centre along +y.
- ``rotation`` maps camera-frame directions into the world frame:
  ``world_dir = R @ cam_dir`` (scene.json's ``camera.rotation``).
- Pixel rays come from :func:`panogeom.coords.pixel_grid_rays` (pixel centres
  at integer + 0.5); nothing here re-derives them.
- Surface labels: 0 unknown / clutter, 1 floor, 2 ceiling, 3 wall facing +-x
  (normal parallel to x), 4 wall facing +-y, 5 object. Instance id 0 is the
  room, -1 marks pixels whose ray hits nothing.
- Depth is the distance along the (unit) ray from the camera centre to the
  first hit, in metres; ``inf`` where the ray hits nothing.

Both backends run Embree underneath and share all pre- and post-processing
here (normals, labels, hit points are computed from the face index and the
hit distance), so results agree up to rays that graze a triangle edge.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from typing import Literal, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._checks import float_array, pano_size
from .coords import pixel_grid_rays
from .rotation import check_rotation, rot_z
from .texture import Material

__all__ = [
    "LABEL_UNKNOWN",
    "LABEL_FLOOR",
    "LABEL_CEILING",
    "LABEL_WALL_X",
    "LABEL_WALL_Y",
    "LABEL_OBJECT",
    "RenderMesh",
    "RenderResult",
    "RayHits",
    "RayCaster",
    "room_meshes",
    "merge_meshes",
    "pose_matrix",
    "transform_mesh",
    "triangulate_polygon",
    "raycast_equirect",
]

#: Surface label ids (CONVENTIONS.md, "Surface labels").
LABEL_UNKNOWN, LABEL_FLOOR, LABEL_CEILING, LABEL_WALL_X, LABEL_WALL_Y, LABEL_OBJECT = 0, 1, 2, 3, 4, 5

Backend = Literal["auto", "open3d", "embree"]

_BACKENDS = ("auto", "open3d", "embree")
_ON_SURFACE_TOL = 1e-6  # metres: a camera closer than this to a triangle is "on" it


def _per_face(value: ArrayLike, n: int, name: str, dtype: type, lo: int | None = None,
              hi: int | None = None) -> np.ndarray:
    a = np.asarray(value)
    if a.ndim == 0:
        a = np.full(n, a)
    if a.shape != (n,):
        raise ValueError(f"{name}: expected a scalar or shape ({n},) (one per face), got {a.shape}")
    if a.dtype.kind not in "iu" and not (a.dtype.kind == "f" and np.all(np.isfinite(a)) and np.all(a == np.round(a))):
        raise ValueError(f"{name}: expected integers, got dtype {a.dtype}")
    if n and lo is not None and a.min() < lo:
        raise ValueError(f"{name}: expected values >= {lo}, got {a.min()}")
    if n and hi is not None and a.max() > hi:
        raise ValueError(f"{name}: expected values <= {hi}, got {a.max()}")
    out = a.astype(dtype)
    out.setflags(write=False)
    return out


def _colors(value: ArrayLike, n: int) -> NDArray[np.float32]:
    a = np.asarray(value)
    if a.dtype.kind not in "uif" or a.dtype == np.bool_:
        raise ValueError(f"colors: expected uint8 (0..255) or float (0..1) RGB, got dtype {a.dtype}")
    if a.shape == (3,):
        a = np.broadcast_to(a, (n, 3))
    if a.shape != (n, 3):
        raise ValueError(f"colors: expected shape (3,) or ({n}, 3), got {a.shape}")
    if a.dtype.kind in "ui":
        if n and (a.min() < 0 or a.max() > 255):
            raise ValueError(f"colors: expected integer colours in 0..255, got range [{a.min()}, {a.max()}]")
        out = a.astype(np.float32) / 255.0
    else:
        if n and not (np.all(np.isfinite(a)) and a.min() >= 0.0 and a.max() <= 1.0):
            raise ValueError("colors: expected float colours in [0, 1]")
        out = a.astype(np.float32)
    out = np.ascontiguousarray(out)
    out.setflags(write=False)
    return out


@dataclass(frozen=True, eq=False)
class RenderMesh:
    """A triangle mesh with per-face render attributes, in world metres.

    Attributes
    ----------
    vertices : (V, 3) float64
        Vertex positions (finite).
    faces : (F, 3) int64
        Triangles as indices into ``vertices``; F >= 1.
    labels : (F,) uint8
        Surface label of each face, 0..5 (CONVENTIONS.md, "Surface labels").
    instance_ids : (F,) int32
        Instance of each face, >= 0 (0 is the room).
    material_ids : (F,) int32
        Material of each face, >= 0 (:class:`panogeom.texture.Material` values
        or any id the ``materials`` mapping of the shader knows).
    colors : (F, 3) float32
        Base colour (albedo, sRGB) of each face in [0, 1].

    The per-face attributes may be given as scalars (broadcast to every face);
    ``colors`` may be uint8 0..255 or float 0..1, one colour or one per face.
    Defaults: label 5 (object), instance 1, material ``PLASTIC``, mid grey.
    All arrays are stored read-only.

    Examples
    --------
    >>> m = RenderMesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], labels=5,
    ...                instance_ids=3, material_ids=Material.WOOD, colors=(200, 150, 90))
    >>> m.n_faces, int(m.labels[0]), m.colors.dtype.name
    (1, 5, 'float32')
    """

    vertices: NDArray[np.float64]
    faces: NDArray[np.int64]
    labels: NDArray[np.uint8] = field(default=LABEL_OBJECT)  # type: ignore[assignment]
    instance_ids: NDArray[np.int32] = field(default=1)  # type: ignore[assignment]
    material_ids: NDArray[np.int32] = field(default=int(Material.PLASTIC))  # type: ignore[assignment]
    colors: NDArray[np.float32] = field(default=(0.6, 0.6, 0.6))  # type: ignore[assignment]

    def __post_init__(self) -> None:
        v = float_array(self.vertices, "vertices")
        if v.ndim != 2 or v.shape[1] != 3:
            raise ValueError(f"vertices: expected shape (V, 3), got {v.shape}")
        f = np.asarray(self.faces)
        if f.ndim != 2 or f.shape[1] != 3:
            raise ValueError(f"faces: expected shape (F, 3), got {f.shape}")
        if f.shape[0] == 0:
            raise ValueError("faces: expected at least one triangle, got an empty mesh")
        if f.dtype.kind not in "iu":
            raise ValueError(f"faces: expected integer vertex indices, got dtype {f.dtype}")
        if f.min() < 0 or f.max() >= len(v):
            raise ValueError(f"faces: expected indices in [0, {len(v)}), got range [{f.min()}, {f.max()}]")
        n = f.shape[0]
        v = np.ascontiguousarray(v)
        f = np.ascontiguousarray(f, dtype=np.int64)
        v.setflags(write=False)
        f.setflags(write=False)
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "faces", f)
        object.__setattr__(self, "labels", _per_face(self.labels, n, "labels", np.uint8, 0, LABEL_OBJECT))
        object.__setattr__(self, "instance_ids", _per_face(self.instance_ids, n, "instance_ids", np.int32, 0,
                                                           np.iinfo(np.int32).max))
        object.__setattr__(self, "material_ids", _per_face(self.material_ids, n, "material_ids", np.int32, 0,
                                                           np.iinfo(np.int32).max))
        object.__setattr__(self, "colors", _colors(self.colors, n))

    @property
    def n_faces(self) -> int:
        """Number of triangles F."""
        return int(self.faces.shape[0])

    def face_normals(self) -> NDArray[np.float64]:
        """Unit normals of the faces, ``(F, 3)``, right-hand rule on the vertex order.

        Degenerate (zero-area) faces get a zero normal.
        """
        tri = self.vertices[self.faces]
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        norm = np.linalg.norm(n, axis=1, keepdims=True)
        return np.divide(n, norm, out=np.zeros_like(n), where=norm > 0)


def merge_meshes(meshes: RenderMesh | Sequence[RenderMesh]) -> RenderMesh:
    """Concatenate meshes into one, keeping every per-face attribute.

    Face ``k`` of the result is face ``k - offset_i`` of mesh ``i`` where
    ``offset_i`` is the number of faces of the meshes before it, so face ids of
    a :class:`RenderResult` index the merge of the meshes in the order given.

    Examples
    --------
    >>> tri = RenderMesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    >>> m = merge_meshes([tri, tri])
    >>> m.faces.tolist()
    [[0, 1, 2], [3, 4, 5]]
    """
    if isinstance(meshes, RenderMesh):
        return meshes
    meshes = list(meshes)
    if not meshes:
        raise ValueError("meshes: expected at least one RenderMesh, got an empty sequence")
    for i, m in enumerate(meshes):
        if not isinstance(m, RenderMesh):
            raise ValueError(f"meshes[{i}]: expected a RenderMesh, got {type(m).__name__}")
    if len(meshes) == 1:
        return meshes[0]
    offsets = np.cumsum([0] + [len(m.vertices) for m in meshes[:-1]])
    return RenderMesh(
        vertices=np.concatenate([m.vertices for m in meshes]),
        faces=np.concatenate([m.faces + o for m, o in zip(meshes, offsets)]),
        labels=np.concatenate([m.labels for m in meshes]),
        instance_ids=np.concatenate([m.instance_ids for m in meshes]),
        material_ids=np.concatenate([m.material_ids for m in meshes]),
        colors=np.concatenate([m.colors for m in meshes]),
    )


def pose_matrix(yaw: float = 0.0, translation: ArrayLike = (0.0, 0.0, 0.0)) -> NDArray[np.float64]:
    """4x4 rigid transform: rotation by ``yaw`` about +z, then ``translation``.

    Convention: yaw in radians, counter-clockwise seen from above, from +x
    towards +y (an object's yaw, CONVENTIONS.md): a model whose front faces +x
    ends up facing ``(cos(yaw), sin(yaw), 0)``.

    Examples
    --------
    >>> T = pose_matrix(np.pi / 2, [1.0, 2.0, 0.0])
    >>> (T @ [1.0, 0.0, 0.0, 1.0]).round(12) + 0.0
    array([1., 3., 0., 1.])
    """
    if not np.isfinite(yaw):
        raise ValueError(f"yaw: expected a finite angle in radians, got {yaw!r}")
    t = float_array(translation, "translation")
    if t.shape != (3,):
        raise ValueError(f"translation: expected shape (3,), got {t.shape}")
    T = np.eye(4)
    T[:3, :3] = rot_z(float(yaw))
    T[:3, 3] = t
    return T


def transform_mesh(mesh: RenderMesh, matrix: ArrayLike) -> RenderMesh:
    """Apply a 4x4 affine transform (rotation, translation, scale) to a mesh.

    Parameters
    ----------
    mesh : RenderMesh
    matrix : (4, 4) float
        Acts on column vectors ``(x, y, z, 1)``; last row ``(0, 0, 0, 1)``; the
        3x3 part must be invertible. A mirroring transform (negative
        determinant) reverses the triangle winding so normals keep pointing the
        same way relative to the surface.

    Returns
    -------
    RenderMesh
        Same faces and attributes. Labels are kept as they are: rotating a
        wall-labelled face by other than a multiple of 90 degrees about z is the
        caller's business.
    """
    T = float_array(matrix, "matrix")
    if T.shape != (4, 4):
        raise ValueError(f"matrix: expected shape (4, 4), got {T.shape}")
    if not np.allclose(T[3], [0.0, 0.0, 0.0, 1.0]):
        raise ValueError(f"matrix: expected last row (0, 0, 0, 1), got {T[3].tolist()}")
    A = T[:3, :3]
    det = float(np.linalg.det(A))
    if abs(det) < 1e-12:
        raise ValueError(f"matrix: expected an invertible 3x3 part, got determinant {det:.3g}")
    faces = mesh.faces if det > 0 else mesh.faces[:, ::-1]
    return RenderMesh(mesh.vertices @ A.T + T[:3, 3], faces, mesh.labels, mesh.instance_ids,
                      mesh.material_ids, mesh.colors)


def _check_manhattan_polygon(polygon: ArrayLike, tol: float = 1e-9) -> NDArray[np.float64]:
    p = float_array(polygon, "floor_polygon")
    if p.ndim != 2 or p.shape[1] != 2:
        raise ValueError(f"floor_polygon: expected shape (N, 2), got {p.shape}")
    n = len(p)
    if n < 4 or n % 2:
        raise ValueError(f"floor_polygon: expected an even number >= 4 of vertices (Manhattan), got {n}")
    e = np.roll(p, -1, axis=0) - p
    length = np.abs(e).max(axis=1)
    if np.any(length <= tol):
        i = int(np.argmax(length <= tol))
        raise ValueError(f"floor_polygon: expected distinct consecutive vertices, edge {i} has zero length "
                         "(no repeated closing vertex)")
    along_x = np.abs(e[:, 1]) <= tol
    along_y = np.abs(e[:, 0]) <= tol
    if not np.all(along_x | along_y):
        i = int(np.argmin(along_x | along_y))
        raise ValueError(f"floor_polygon: expected axis-aligned (Manhattan) edges, edge {i} runs along "
                         f"{e[i].tolist()}")
    if np.any(along_x == np.roll(along_x, -1)):
        i = int(np.argmax(along_x == np.roll(along_x, -1)))
        raise ValueError(f"floor_polygon: expected consecutive edges to be orthogonal, edges {i} and {(i + 1) % n} "
                         "are parallel")
    area2 = float(np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1]))
    if area2 <= 0:
        raise ValueError(f"floor_polygon: expected counter-clockwise vertex order seen from above, got signed area "
                         f"{area2 / 2:.4g}")
    # Axis-aligned segments intersect exactly when their closed bounding boxes do.
    q = np.roll(p, -1, axis=0)
    lo, hi = np.minimum(p, q), np.maximum(p, q)
    overlap = np.all((lo[:, None, :] <= hi[None, :, :] + tol) & (lo[None, :, :] <= hi[:, None, :] + tol), axis=2)
    idx = np.arange(n)
    adjacent = (np.abs(idx[:, None] - idx[None, :]) <= 1) | (np.abs(idx[:, None] - idx[None, :]) == n - 1)
    bad = overlap & ~adjacent
    if np.any(bad):
        i, j = np.argwhere(bad)[0]
        raise ValueError(f"floor_polygon: expected a simple polygon, edges {i} and {j} intersect")
    return p


def triangulate_polygon(polygon: ArrayLike) -> NDArray[np.int64]:
    """Ear-clipping triangulation of a simple counter-clockwise polygon.

    Parameters
    ----------
    polygon : (N, 2) float
        Simple polygon, counter-clockwise, no repeated closing vertex.

    Returns
    -------
    triangles : (N - 2, 3) int
        Vertex indices, each triangle counter-clockwise.

    Examples
    --------
    >>> triangulate_polygon([[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]]).shape
    (4, 3)
    """
    p = float_array(polygon, "polygon")
    if p.ndim != 2 or p.shape[1] != 2 or len(p) < 3:
        raise ValueError(f"polygon: expected shape (N, 2) with N >= 3, got {p.shape}")
    scale = float(np.abs(p - p.mean(axis=0)).max()) or 1.0
    eps = 1e-12 * scale * scale

    def cross(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
        return (b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1]) - (b[..., 1] - a[..., 1]) * (c[..., 0] - a[..., 0])

    idx = list(range(len(p)))
    tris: list[tuple[int, int, int]] = []
    while len(idx) > 3:
        n = len(idx)
        for strict in (False, True):
            found = False
            for k in range(n):
                i0, i1, i2 = idx[k - 1], idx[k], idx[(k + 1) % n]
                a, b, c = p[i0], p[i1], p[i2]
                if cross(a, b, c) <= eps:
                    continue  # reflex or flat corner
                others = p[[j for j in idx if j not in (i0, i1, i2)]]
                c0, c1, c2 = cross(a, b, others), cross(b, c, others), cross(c, a, others)
                inside = (c0 > eps) & (c1 > eps) & (c2 > eps) if strict else \
                    (c0 >= -eps) & (c1 >= -eps) & (c2 >= -eps)
                if np.any(inside):
                    continue
                tris.append((i0, i1, i2))
                idx.pop(k)
                found = True
                break
            if found:
                break
        else:
            raise ValueError("polygon: expected a simple counter-clockwise polygon, found no ear to clip")
    if cross(p[idx[0]], p[idx[1]], p[idx[2]]) > eps:
        tris.append((idx[0], idx[1], idx[2]))
    return np.array(tris, dtype=np.int64).reshape(-1, 3)


def room_meshes(floor_polygon: ArrayLike, ceiling_z: float, floor_z: float = 0.0, *,
                floor_material: int = Material.WOOD, wall_material: int = Material.PLASTER,
                ceiling_material: int = Material.PLASTER,
                floor_color: ArrayLike = (0.55, 0.38, 0.24), wall_color: ArrayLike = (0.86, 0.84, 0.79),
                ceiling_color: ArrayLike = (0.93, 0.93, 0.91)) -> RenderMesh:
    """Floor, ceiling and walls of a Manhattan room as one mesh (instance id 0).

    Parameters
    ----------
    floor_polygon : (N, 2) float
        Floor corners in world x, y (metres), counter-clockwise seen from above,
        no repeated closing vertex, consecutive edges orthogonal and
        axis-aligned, simple (CONVENTIONS.md, ``room.floor``).
    ceiling_z, floor_z : float
        Heights of the ceiling and floor planes, ``ceiling_z > floor_z``.
    floor_material, wall_material, ceiling_material : int
        Material ids (:class:`panogeom.texture.Material`).
    floor_color, wall_color, ceiling_color : (3,) float in [0, 1] or uint8
        Base colours.

    Returns
    -------
    RenderMesh
        2N vertices; N - 2 floor triangles (label 1, normal +z), N - 2 ceiling
        triangles (label 2, normal -z) and one quad (2 triangles) per wall,
        wall ``i`` from corner ``i`` to ``i + 1``: label 3 when its normal is
        parallel to x, 4 when parallel to y; normals point into the room. The
        faces come in that order: floor, ceiling, walls.

    Examples
    --------
    >>> room = room_meshes([[-2, -1], [2, -1], [2, 1], [-2, 1]], ceiling_z=2.5)
    >>> room.n_faces, room.labels.tolist()
    (12, [1, 1, 2, 2, 4, 4, 3, 3, 4, 4, 3, 3])
    """
    p = _check_manhattan_polygon(floor_polygon)
    fz, cz = float(floor_z), float(ceiling_z)
    if not (np.isfinite(fz) and np.isfinite(cz) and cz > fz):
        raise ValueError(f"ceiling_z, floor_z: expected finite values with ceiling_z > floor_z, got {cz!r}, {fz!r}")
    n = len(p)
    verts = np.concatenate([np.column_stack([p, np.full(n, fz)]), np.column_stack([p, np.full(n, cz)])])
    floor = triangulate_polygon(p)
    ceiling = floor[:, ::-1] + n
    i = np.arange(n)
    j = (i + 1) % n
    walls = np.stack([np.column_stack([i, j + n, j]), np.column_stack([i, i + n, j + n])], axis=1).reshape(-1, 3)
    e = np.roll(p, -1, axis=0) - p
    wall_label = np.where(np.abs(e[:, 0]) >= np.abs(e[:, 1]), LABEL_WALL_Y, LABEL_WALL_X).repeat(2)
    nf, nc, nw = len(floor), len(ceiling), len(walls)
    labels = np.concatenate([np.full(nf, LABEL_FLOOR), np.full(nc, LABEL_CEILING), wall_label])
    materials = np.concatenate([np.full(nf, int(floor_material)), np.full(nc, int(ceiling_material)),
                                np.full(nw, int(wall_material))])
    colors = np.concatenate([_colors(floor_color, nf), _colors(ceiling_color, nc), _colors(wall_color, nw)])
    return RenderMesh(verts, np.concatenate([floor, ceiling, walls]), labels, 0, materials, colors)


@dataclass(frozen=True, eq=False)
class RayHits:
    """First hits of a batch of rays (see :meth:`RayCaster.cast`).

    Attributes
    ----------
    t : (N,) float32
        Hit distance in units of the direction's length; ``inf`` on a miss.
    face_ids : (N,) int32
        Index of the hit triangle in the merged mesh; -1 on a miss.
    barycentric : (N, 2) float32
        ``(b1, b2)`` of the hit point ``(1 - b1 - b2) v0 + b1 v1 + b2 v2``; 0 on a miss.
    """

    t: NDArray[np.float32]
    face_ids: NDArray[np.int32]
    barycentric: NDArray[np.float32]

    @property
    def hit(self) -> NDArray[np.bool_]:
        """``(N,)`` True where the ray hit a triangle."""
        return self.face_ids >= 0


def _import_open3d():
    try:
        import open3d as o3d
    except ImportError as exc:
        raise ImportError("the open3d ray-casting backend needs Open3D: pip install open3d-cpu") from exc
    return o3d


def _import_embree():
    try:
        from igl import embree
    except ImportError as exc:
        raise ImportError("the embree ray-casting backend needs libigl with Embree: pip install libigl") from exc
    return embree


def _resolve_backend(backend: str) -> str:
    if backend not in _BACKENDS:
        raise ValueError(f"backend: expected one of {_BACKENDS}, got {backend!r}")
    if backend != "auto":
        return backend
    for name, loader in (("open3d", _import_open3d), ("embree", _import_embree)):
        try:
            loader()
        except ImportError:
            continue
        return name
    raise ImportError("ray casting needs Open3D or libigl: pip install open3d-cpu (or pip install libigl)")


class RayCaster:
    """A scene built once for a backend, cast against many times.

    Parameters
    ----------
    meshes : RenderMesh or sequence of RenderMesh
        Merged in order (:func:`merge_meshes`); face ids refer to the merge.
    backend : {"auto", "open3d", "embree"}
        ``"auto"`` takes Open3D (batched, multi-threaded) when installed, else
        libigl's Embree (one Python call per ray, several times slower).

    Both backends find hits on either side of a triangle (no back-face culling).

    Examples
    --------
    >>> room = room_meshes([[-2, -2], [2, -2], [2, 2], [-2, 2]], ceiling_z=3.0)
    >>> hits = RayCaster(room).cast([[0.0, 0.0, 1.0]], [[0.0, 0.0, -1.0]])
    >>> round(float(hits.t[0]), 6), int(room.labels[hits.face_ids[0]])
    (1.0, 1)
    """

    def __init__(self, meshes: RenderMesh | Sequence[RenderMesh], backend: Backend = "auto") -> None:
        self.mesh = merge_meshes(meshes)
        self.backend = _resolve_backend(backend)
        v = self.mesh.vertices.astype(np.float32)
        if self.backend == "open3d":
            o3d = _import_open3d()
            scene = o3d.t.geometry.RaycastingScene()
            scene.add_triangles(o3d.core.Tensor(v), o3d.core.Tensor(self.mesh.faces.astype(np.uint32)))
            self._scene = scene
        else:
            embree = _import_embree()
            ei = embree.EmbreeIntersector()
            ei.init(np.asfortranarray(v), np.asfortranarray(self.mesh.faces.astype(np.int32)))
            self._scene = ei

    @staticmethod
    def _rays_arg(x: ArrayLike, name: str) -> NDArray[np.float32]:
        a = np.asarray(x)
        if a.dtype.kind not in "fiu" or a.dtype == np.bool_:
            raise ValueError(f"{name}: expected a numeric array, got dtype {a.dtype}")
        a = np.asarray(a, dtype=np.float32)
        if a.size and not np.isfinite(a).all():
            raise ValueError(f"{name}: expected finite values, got NaN or inf")
        return a

    def cast(self, origins: ArrayLike, directions: ArrayLike) -> RayHits:
        """First hit of each ray ``origin + t * direction``, ``t > 0``.

        Parameters
        ----------
        origins : (N, 3) or (3,) float
            Ray origins (one shared origin may be given as (3,)).
        directions : (N, 3) float
            Non-zero directions; ``t`` is in units of their length.

        Returns
        -------
        RayHits
        """
        d = self._rays_arg(directions, "directions")
        if d.ndim != 2 or d.shape[1] != 3:
            raise ValueError(f"directions: expected shape (N, 3), got {d.shape}")
        o = self._rays_arg(origins, "origins")
        if o.shape != (3,) and o.shape != d.shape:
            raise ValueError(f"origins: expected shape (3,) or {d.shape}, got {o.shape}")
        n = len(d)
        if n and not np.all(np.einsum("ij,ij->i", d, d) > 0):
            raise ValueError("directions: expected non-zero direction vectors, got a zero-length ray")
        if self.backend == "open3d":
            o3d = _import_open3d()
            rays = np.empty((n, 6), dtype=np.float32)
            rays[:, :3] = o
            rays[:, 3:] = d
            out = self._scene.cast_rays(o3d.core.Tensor(rays))
            prim = out["primitive_ids"].numpy()
            fid = np.where(prim == o3d.t.geometry.RaycastingScene.INVALID_ID, -1, prim).astype(np.int32)
            t = out["t_hit"].numpy().astype(np.float32)
            bary = out["primitive_uvs"].numpy().astype(np.float32)
        else:
            first = self._scene.intersectRay_first
            o32 = np.ascontiguousarray(o, dtype=np.float32)
            d32 = np.ascontiguousarray(d, dtype=np.float32)
            if o32.shape == (3,):
                res = [first(o32, di) for di in d32]
            else:
                res = [first(oi, di) for oi, di in zip(o32, d32)]
            arr = np.array(res, dtype=np.float64).reshape(n, 4)
            fid = arr[:, 0].astype(np.int32)
            t = arr[:, 1].astype(np.float32)
            bary = arr[:, 2:].astype(np.float32)
        miss = fid < 0
        t[miss] = np.inf
        bary[miss] = 0.0
        return RayHits(t=t, face_ids=fid, barycentric=bary)


@dataclass(frozen=True, eq=False)
class RenderResult:
    """Per-pixel geometry of a ray-cast panorama (H rows, W = 2H columns).

    Attributes
    ----------
    depth : (H, W) float32
        Distance in metres from the camera centre to the first hit along the
        pixel's unit ray; ``inf`` where nothing is hit.
    points : (H, W, 3) float32
        World coordinates of the hit points; NaN where nothing is hit.
    normals : (H, W, 3) float32
        Unit geometric normal of the hit face, turned to face the camera
        (``dot(normal, ray) <= 0``); NaN where nothing is hit.
    labels : (H, W) uint8
        Surface label of the hit face, 0 where nothing is hit.
    instance_ids : (H, W) int32
        Instance id of the hit face (0 room), -1 where nothing is hit.
    material_ids : (H, W) int32
        Material id of the hit face, -1 where nothing is hit.
    face_ids : (H, W) int32
        Index of the hit face in the merge of the meshes, -1 where nothing is hit.
    barycentric : (H, W, 2) float32
        ``(b1, b2)`` of the hit in its face (:class:`RayHits`).
    rays : (H, W, 3) float32
        Unit world-frame ray of each pixel (``R @`` camera ray).
    camera_position : (3,) float64
    rotation : (3, 3) float64
        Camera-to-world rotation used.
    n_faces : int
        Face count of the merged scene (lets the shader check it got the same meshes).
    backend : str
        ``"open3d"`` or ``"embree"``.
    """

    depth: NDArray[np.float32]
    points: NDArray[np.float32]
    normals: NDArray[np.float32]
    labels: NDArray[np.uint8]
    instance_ids: NDArray[np.int32]
    material_ids: NDArray[np.int32]
    face_ids: NDArray[np.int32]
    barycentric: NDArray[np.float32]
    rays: NDArray[np.float32]
    camera_position: NDArray[np.float64]
    rotation: NDArray[np.float64]
    n_faces: int
    backend: str

    @property
    def height(self) -> int:
        return int(self.depth.shape[0])

    @property
    def width(self) -> int:
        return int(self.depth.shape[1])

    @property
    def hit(self) -> NDArray[np.bool_]:
        """``(H, W)`` True where the pixel's ray hit a face."""
        return self.face_ids >= 0


@lru_cache(maxsize=2)
def _pixel_rays(width: int, height: int) -> NDArray[np.float64]:
    rays = pixel_grid_rays(width, height)
    rays.setflags(write=False)
    return rays


def _camera_on_surface(mesh: RenderMesh, c: NDArray[np.float64], tol: float) -> int:
    """Index of a face the point ``c`` lies on (within ``tol`` metres), or -1."""
    tri = mesh.vertices[mesh.faces]
    a, b, cc = tri[:, 0], tri[:, 1], tri[:, 2]
    n = np.cross(b - a, cc - a)
    nn = np.linalg.norm(n, axis=1)
    ok = nn > 0
    dist = np.full(len(tri), np.inf)
    dist[ok] = np.abs(np.einsum("ij,ij->i", n[ok], c - a[ok])) / nn[ok]
    cand = np.flatnonzero(dist <= tol)
    if cand.size == 0:
        return -1
    # Barycentric test of the projection of c on the candidate planes.
    a, b, cc, n, nn = a[cand], b[cand], cc[cand], n[cand], nn[cand]
    w0 = np.einsum("ij,ij->i", np.cross(b - a, c - a), n) / nn**2
    w1 = np.einsum("ij,ij->i", np.cross(cc - b, c - b), n) / nn**2
    w2 = np.einsum("ij,ij->i", np.cross(a - cc, c - cc), n) / nn**2
    edge = tol / np.sqrt(nn)  # relative slack of ~tol metres near the edges
    inside = (w0 >= -edge) & (w1 >= -edge) & (w2 >= -edge)
    return int(cand[np.argmax(inside)]) if np.any(inside) else -1


def raycast_equirect(meshes: RenderMesh | Sequence[RenderMesh], width: int, camera_position: ArrayLike,
                     rotation: ArrayLike | None = None, backend: Backend = "auto") -> RenderResult:
    """Cast one ray per pixel of a W x W/2 equirectangular panorama into a scene.

    Parameters
    ----------
    meshes : RenderMesh or sequence of RenderMesh
        The scene (room from :func:`room_meshes`, objects placed with
        :func:`transform_mesh`); merged in order, face ids refer to the merge.
    width : int
        Panorama width W (even); the height is W / 2.
    camera_position : (3,) float
        Camera centre in world metres. It may lie outside the room, but not on
        a surface (within 1e-6 m).
    rotation : (3, 3) float, optional
        Camera-to-world rotation: ``world_dir = R @ cam_dir``. Default identity.
    backend : {"auto", "open3d", "embree"}
        See :class:`RayCaster`; the result does not depend on it.

    Returns
    -------
    RenderResult

    Convention: pixel rays from :func:`panogeom.coords.pixel_grid_rays`; the
    centre column looks along ``R @ (1, 0, 0)``; depth is the Euclidean
    distance from the camera centre (not the z-buffer of a pinhole camera).

    Raises
    ------
    ValueError
        Bad width, camera position (NaN, on a surface), rotation, or meshes.

    Examples
    --------
    >>> room = room_meshes([[-2, -2], [2, -2], [2, 2], [-2, 2]], ceiling_z=2.5)
    >>> r = raycast_equirect(room, 64, camera_position=[0.0, 0.0, 1.6])
    >>> r.labels.shape, int(r.labels[0, 0]), int(r.labels[31, 5]), int(r.labels[16, 32]), int(r.labels[16, 16])
    ((32, 64), 2, 1, 3, 4)
    >>> round(float(r.depth[16, 32] * r.rays[16, 32, 0]), 4)    # hit on the wall x = 2
    2.0
    """
    try:
        w_int = int(width)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"width: expected an even positive integer, got {width!r}") from exc
    if w_int != width or w_int < 2 or w_int % 2:
        raise ValueError(f"width: expected an even positive integer (height = width / 2), got {width!r}")
    W, H = pano_size(w_int, w_int // 2)
    c = float_array(camera_position, "camera_position")
    if c.shape != (3,):
        raise ValueError(f"camera_position: expected shape (3,), got {c.shape}")
    R = np.eye(3) if rotation is None else check_rotation(rotation)
    caster = RayCaster(meshes, backend)
    mesh = caster.mesh
    on = _camera_on_surface(mesh, c, _ON_SURFACE_TOL)
    if on >= 0:
        raise ValueError(f"camera_position: expected a point off every surface, {c.tolist()} lies on face {on}")
    dirs = _pixel_rays(W, H).reshape(-1, 3)
    if rotation is not None:
        dirs = dirs @ R.T
    hits = caster.cast(c, dirs)
    fid = hits.face_ids
    hit = fid >= 0
    # One gather per attribute, with a sentinel row for misses.
    sel = np.where(hit, fid, mesh.n_faces)
    fn = mesh.face_normals()
    nrm = np.concatenate([fn, np.full((1, 3), np.nan)])[sel]
    flip = np.einsum("ij,ij->i", nrm, dirs) > 0
    nrm[flip] *= -1.0
    t = hits.t.astype(np.float64)
    pts = c + np.where(hit, t, np.nan)[:, None] * dirs

    def gather(a: np.ndarray, miss: float | int, dtype: type) -> np.ndarray:
        return np.concatenate([a.astype(dtype), np.array([miss], dtype=dtype)])[sel].reshape(H, W)

    return RenderResult(
        depth=hits.t.reshape(H, W),
        points=pts.astype(np.float32).reshape(H, W, 3),
        normals=nrm.astype(np.float32).reshape(H, W, 3),
        labels=gather(mesh.labels, LABEL_UNKNOWN, np.uint8),
        instance_ids=gather(mesh.instance_ids, -1, np.int32),
        material_ids=gather(mesh.material_ids, -1, np.int32),
        face_ids=fid.reshape(H, W),
        barycentric=hits.barycentric.reshape(H, W, 2),
        rays=dirs.astype(np.float32).reshape(H, W, 3),
        camera_position=c.copy(),
        rotation=R.copy(),
        n_faces=mesh.n_faces,
        backend=caster.backend,
    )
