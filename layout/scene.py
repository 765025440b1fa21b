"""The scene model: walls, objects and the room, and their JSON form (scene@1, gt@1).

A :class:`Scene` is what the MAP sampler (:mod:`layout.sampler`) returns and
what ``pano2cad run`` writes as ``scene.json``: the Manhattan floor polygon,
the ceiling height, the camera (height and the rotation of the input
panorama), the furniture as :class:`SceneObject` records (class, model,
oriented 3D box) and the absolute scale. :meth:`Scene.to_json_dict` and
:meth:`Scene.from_json_dict` implement the schema ``"pano2cad/scene@1"`` of
shared/CONVENTIONS.md exactly (degrees only at this edge, as ``yaw_deg`` in
[0, 360); unknown values are ``null``); :meth:`Scene.to_gt_json_dict` and
:meth:`Scene.from_gt_json_dict` the ground-truth schema ``"pano2cad/gt@1"``.

Scale: the room geometry estimated from the labels is metric only if the
assumed camera height is right. ``Scene.scale`` is the factor ``lambda``
that the sampler applied to that room (floor polygon, ceiling and camera
height all multiplied by it); the stored floor, ceiling and camera height
are already metric. ``None`` when no scale was estimated.

Convention:
    World frame of shared/CONVENTIONS.md: metres, z up, origin on the floor
    below the camera, camera at ``(0, 0, camera_height)``. Floor polygon
    counter-clockwise seen from above, no repeated closing vertex,
    consecutive edges orthogonal. Object ``center`` = centre of its 3D box,
    ``size = (l, w, h)`` along its front, its left and up, ``yaw`` in radians
    in [0, 2 pi), counter-clockwise about +z from +x to the object's front.
    ``bbox_pano = (u0, v0, u1, v1)`` in pixels of the input panorama,
    ``u0 > u1`` wraps the seam.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Mapping

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .polygon import as_polygon, oriented_rectangles, polygon_problems, wall_segments

__all__ = [
    "SCENE_SCHEMA",
    "GT_SCHEMA",
    "Wall",
    "SceneObject",
    "Scene",
    "scene_walls",
]

SCENE_SCHEMA = "pano2cad/scene@1"
GT_SCHEMA = "pano2cad/gt@1"

FloatArray = NDArray[np.float64]

#: Largest |cos| between consecutive floor edges still accepted as orthogonal
#: (JSON written by other tools may round coordinates to the millimetre).
_MANHATTAN_TOL = 1e-3


def _ro(a: ArrayLike) -> FloatArray:
    out = np.array(a, dtype=np.float64)
    out.setflags(write=False)
    return out


def _vector(value: ArrayLike, n: int, name: str, *, positive: bool = False) -> FloatArray:
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected {n} numbers, got {value!r}") from None
    if a.shape != (n,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: expected {n} finite numbers, got {value!r}")
    if positive and np.any(a <= 0):
        raise ValueError(f"{name}: expected {n} numbers > 0, got {a.tolist()}")
    return _ro(a)


def _finite(value: Any, name: str, *, positive: bool = False, optional: bool = False) -> float | None:
    if value is None and optional:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name}: expected a number{' or null' if optional else ''}, got {value!r}")
    v = float(value)
    if not math.isfinite(v) or (positive and v <= 0):
        raise ValueError(f"{name}: expected a finite number{' > 0' if positive else ''}, got {value!r}")
    return v


def _wrap_yaw(yaw: float) -> float:
    """yaw in [0, 2 pi) (a tiny negative value would round up to 2 pi)."""
    w = math.fmod(float(yaw), 2.0 * math.pi)
    if w < 0:
        w += 2.0 * math.pi
    return 0.0 if w >= 2.0 * math.pi else w


def _yaw_deg(yaw: float) -> float:
    d = math.degrees(yaw) % 360.0
    return 0.0 if d >= 360.0 else d


def _require(d: Mapping[str, Any], key: str, where: str) -> Any:
    if not isinstance(d, Mapping):
        raise ValueError(f"{where}: expected a JSON object, got {type(d).__name__}")
    if key not in d:
        raise ValueError(f"{where}: expected a key {key!r}, got keys {sorted(d)}")
    return d[key]


@dataclass(frozen=True, eq=False)
class Wall:
    """One wall of the room: the floor-polygon edge from vertex ``index`` to ``index + 1``.

    Attributes
    ----------
    index : int
    start, end : (2,) float
        Floor points of the wall, metres.
    normal : (2,) float
        Unit normal pointing into the room.
    label : int
        Surface label of the wall (shared/CONVENTIONS.md): 3 when its normal
        is parallel to x, 4 when parallel to y.
    height : float or None
        ``ceiling_z - floor_z`` in metres (None when the ceiling is unknown).

    Convention: world x, y in metres seen from above; inward normals.
    """

    index: int
    start: FloatArray
    end: FloatArray
    normal: FloatArray
    label: int
    height: float | None

    @property
    def length(self) -> float:
        """Length in metres."""
        return float(np.linalg.norm(self.end - self.start))

    @property
    def midpoint(self) -> FloatArray:
        """(2,) centre of the wall on the floor (the paper's ``p^w_i``)."""
        return 0.5 * (self.start + self.end)


def scene_walls(floor: ArrayLike, height: float | None = None) -> tuple[Wall, ...]:
    """The walls of a floor polygon as :class:`Wall` records.

    Parameters
    ----------
    floor : (N, 2) float
        Floor polygon, metres.
    height : float, optional
        Wall height in metres.

    Returns
    -------
    tuple of N Wall

    Examples
    --------
    >>> ws = scene_walls([[0, 0], [4, 0], [4, 3], [0, 3]], 2.5)
    >>> [(w.label, w.length) for w in ws]
    [(4, 4.0), (3, 3.0), (4, 4.0), (3, 3.0)]
    >>> ws[1].normal.tolist()
    [-1.0, 0.0]
    """
    poly = as_polygon(floor, name="floor")
    if poly.ndim != 2:
        raise ValueError(f"floor: expected a single polygon (N, 2), got {poly.shape}")
    w = wall_segments(poly)
    out = []
    for i in range(len(poly)):
        n = w.normal[i]
        out.append(Wall(index=i, start=_ro(w.start[i]), end=_ro(w.end[i]), normal=_ro(n),
                        label=3 if abs(n[0]) >= abs(n[1]) else 4,
                        height=None if height is None else float(height)))
    return tuple(out)


@dataclass(frozen=True, eq=False)
class SceneObject:
    """One piece of furniture: class, retrieved model and oriented 3D box.

    Attributes
    ----------
    id : str
        Unique within the scene, e.g. ``"bed-0"``.
    cls : str
        Lowercase class name (``bed``, ``chair``, ``tv``, ``plant``, ...).
    center : (3,) float
        Centre of the 3D box, world frame, metres.
    size : (3,) float
        ``(l, w, h)``: length along the front, width, height; metres, > 0.
    yaw : float
        Radians in [0, 2 pi) (wrapped on construction), counter-clockwise
        about +z from +x to the object's front.
    model_id : str or None
        Retrieved 3D model.
    score : float or None
        Detection score.
    bbox_pano : (4,) float or None
        ``(u0, v0, u1, v1)`` pixel box in the input panorama; ``u0 > u1``
        wraps the seam.

    Examples
    --------
    >>> o = SceneObject("bed-0", "bed", [1.0, 2.0, 0.3], [2.0, 1.6, 0.6], -np.pi / 2, "bed-03", 0.9)
    >>> round(o.yaw_deg, 6), o.footprint.shape
    (270.0, (4, 2))
    >>> SceneObject.from_json_dict(o.to_json_dict()).to_json_dict() == o.to_json_dict()
    True
    """

    id: str
    cls: str
    center: FloatArray
    size: FloatArray
    yaw: float
    model_id: str | None = None
    score: float | None = None
    bbox_pano: FloatArray | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.id, str) or not self.id:
            raise ValueError(f"id: expected a non-empty string, got {self.id!r}")
        if not isinstance(self.cls, str) or not self.cls or self.cls != self.cls.lower():
            raise ValueError(f"cls: expected a lowercase class name, got {self.cls!r}")
        object.__setattr__(self, "center", _vector(self.center, 3, f"{self.id}.center"))
        object.__setattr__(self, "size", _vector(self.size, 3, f"{self.id}.size", positive=True))
        yaw = _finite(self.yaw, f"{self.id}.yaw")
        object.__setattr__(self, "yaw", _wrap_yaw(float(yaw)))  # type: ignore[arg-type]
        if self.model_id is not None and not isinstance(self.model_id, str):
            raise ValueError(f"{self.id}.model_id: expected a string or None, got {self.model_id!r}")
        object.__setattr__(self, "score", _finite(self.score, f"{self.id}.score", optional=True))
        if self.bbox_pano is not None:
            object.__setattr__(self, "bbox_pano", _vector(self.bbox_pano, 4, f"{self.id}.bbox_pano"))

    @property
    def yaw_deg(self) -> float:
        """Yaw in degrees, [0, 360)."""
        return _yaw_deg(self.yaw)

    @property
    def footprint(self) -> FloatArray:
        """(4, 2) floor footprint corners, counter-clockwise (front-right first)."""
        return oriented_rectangles(self.center[:2], self.yaw, self.size[:2])

    @property
    def corners(self) -> FloatArray:
        """(8, 3) box corners (bottom face, then top face), as :func:`panogeom.project.world_box_corners`."""
        from panogeom.project import world_box_corners

        return world_box_corners(self.center, self.size, self.yaw)

    def to_json_dict(self) -> dict[str, Any]:
        """The object as in scene.json's ``objects`` list (degrees at this edge)."""
        return {
            "id": self.id,
            "class": self.cls,
            "center": [float(v) for v in self.center],
            "size": [float(v) for v in self.size],
            "yaw_deg": self.yaw_deg,
            "model": self.model_id,
            "score": self.score,
            "bbox_pano": None if self.bbox_pano is None else [float(v) for v in self.bbox_pano],
        }

    @classmethod
    def from_json_dict(cls, d: Mapping[str, Any], where: str = "object") -> "SceneObject":
        """Inverse of :meth:`to_json_dict`; ``where`` names the object in error messages."""
        yaw_deg = _finite(_require(d, "yaw_deg", where), f"{where}.yaw_deg")
        if not 0.0 <= float(yaw_deg) < 360.0:  # type: ignore[arg-type]
            raise ValueError(f"{where}.yaw_deg: expected a value in [0, 360), got {yaw_deg}")
        model = d.get("model")
        if model is not None and not isinstance(model, str):
            raise ValueError(f"{where}.model: expected a string or null, got {model!r}")
        return cls(
            id=str(_require(d, "id", where)),
            cls=_require(d, "class", where),
            center=_require(d, "center", where),
            size=_require(d, "size", where),
            yaw=math.radians(float(yaw_deg)),  # type: ignore[arg-type]
            model_id=model,
            score=d.get("score"),
            bbox_pano=d.get("bbox_pano"),
        )


def _timing(t: Mapping[str, Any] | None) -> Mapping[str, float]:
    out: dict[str, float] = {}
    for k, v in dict(t or {}).items():
        if not isinstance(k, str):
            raise ValueError(f"timing: expected string keys, got {k!r}")
        out[k] = float(_finite(v, f"timing[{k!r}]"))  # type: ignore[arg-type]
        if out[k] < 0:
            raise ValueError(f"timing[{k!r}]: expected seconds >= 0, got {v}")
    return MappingProxyType(out)


@dataclass(frozen=True, eq=False)
class Scene:
    """A room with furniture seen from a panorama camera.

    Attributes
    ----------
    floor : (N, 2) float
        Floor polygon, metres, counter-clockwise, Manhattan, no repeated
        closing vertex.
    ceiling_z : float or None
        Ceiling height (z of the ceiling plane), metres; None if unknown.
    camera_height : float
        Camera centre above the floor, metres.
    objects : tuple of SceneObject
    floor_z : float
        z of the floor plane (0 in the world frame of the conventions).
    rotation : (3, 3) float or None
        Maps input-camera-frame directions into the world frame; None if
        unknown.
    scale : float or None
        The absolute scale ``lambda`` applied to the room estimated with the
        assumed camera height (see the module docstring); None if not
        estimated.
    image_file : str or None
    image_width, image_height : int or None
        The input panorama.
    timing : mapping str -> float
        Seconds per stage (``"total"`` at least when known).

    Examples
    --------
    >>> s = Scene([[-2, -1.5], [2, -1.5], [2, 1.5], [-2, 1.5]], 2.6, 1.6,
    ...           (SceneObject("tv-0", "tv", [1.8, 0, 0.4], [0.2, 1.0, 0.6], np.pi),), scale=1.02)
    >>> d = s.to_json_dict()
    >>> d["schema"], d["room"]["ceiling_z"], d["objects"][0]["yaw_deg"]
    ('pano2cad/scene@1', 2.6, 180.0)
    >>> Scene.from_json_dict(d).to_json_dict() == d
    True
    >>> round(s.wall_height, 3), [w.label for w in s.walls]
    (2.6, [4, 3, 4, 3])
    """

    floor: FloatArray
    ceiling_z: float | None
    camera_height: float
    objects: tuple[SceneObject, ...] = ()
    floor_z: float = 0.0
    rotation: FloatArray | None = field(default_factory=lambda: np.eye(3))
    scale: float | None = None
    image_file: str | None = None
    image_width: int | None = None
    image_height: int | None = None
    timing: Mapping[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        poly = as_polygon(self.floor, name="floor")
        if poly.ndim != 2:
            raise ValueError(f"floor: expected a single polygon (N, 2), got {poly.shape}")
        problems = polygon_problems(poly, manhattan=True, tol=_MANHATTAN_TOL)
        if problems:
            raise ValueError("floor: expected a simple counter-clockwise Manhattan polygon, got one that is "
                             + "; ".join(problems))
        object.__setattr__(self, "floor", _ro(poly))
        floor_z = float(_finite(self.floor_z, "floor_z"))  # type: ignore[arg-type]
        object.__setattr__(self, "floor_z", floor_z)
        cam_h = float(_finite(self.camera_height, "camera_height", positive=True))  # type: ignore[arg-type]
        object.__setattr__(self, "camera_height", cam_h)
        ceil = _finite(self.ceiling_z, "ceiling_z", optional=True)
        if ceil is not None and ceil <= floor_z:
            raise ValueError(f"ceiling_z: expected a value above floor_z = {floor_z}, got {ceil}")
        object.__setattr__(self, "ceiling_z", ceil)
        if self.rotation is not None:
            from panogeom.rotation import check_rotation

            object.__setattr__(self, "rotation", _ro(check_rotation(self.rotation, "rotation", atol=1e-4)))
        object.__setattr__(self, "scale", _finite(self.scale, "scale", positive=True, optional=True))
        objs = tuple(self.objects)
        for o in objs:
            if not isinstance(o, SceneObject):
                raise ValueError(f"objects: expected SceneObject items, got {type(o).__name__}")
        ids = [o.id for o in objs]
        dup = sorted({i for i in ids if ids.count(i) > 1})
        if dup:
            raise ValueError(f"objects: expected unique ids, got duplicates {dup}")
        object.__setattr__(self, "objects", objs)
        if self.image_file is not None and not isinstance(self.image_file, str):
            raise ValueError(f"image_file: expected a string or None, got {self.image_file!r}")
        for name in ("image_width", "image_height"):
            v = getattr(self, name)
            if v is not None:
                if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v <= 0:
                    raise ValueError(f"{name}: expected a positive integer or None, got {v!r}")
                object.__setattr__(self, name, int(v))
        object.__setattr__(self, "timing", _timing(self.timing))

    # ------------------------------------------------------------------ derived

    @property
    def wall_height(self) -> float | None:
        """``ceiling_z - floor_z`` in metres (None if the ceiling is unknown)."""
        return None if self.ceiling_z is None else self.ceiling_z - self.floor_z

    @property
    def walls(self) -> tuple[Wall, ...]:
        """The walls, one per floor-polygon edge."""
        return scene_walls(self.floor, self.wall_height)

    # ------------------------------------------------------------------ scene@1

    def to_json_dict(self) -> dict[str, Any]:
        """The scene as a ``"pano2cad/scene@1"`` JSON object (shared/CONVENTIONS.md)."""
        return {
            "schema": SCENE_SCHEMA,
            "image": {"file": self.image_file, "width": self.image_width, "height": self.image_height},
            "camera": {
                "height_m": self.camera_height,
                "rotation": None if self.rotation is None else self.rotation.tolist(),
            },
            "room": {
                "floor": self.floor.tolist(),
                "floor_z": self.floor_z,
                "ceiling_z": self.ceiling_z,
            },
            "objects": [o.to_json_dict() for o in self.objects],
            "scale": self.scale,
            "timing_s": dict(self.timing),
        }

    @classmethod
    def from_json_dict(cls, d: Mapping[str, Any]) -> "Scene":
        """Read a ``"pano2cad/scene@1"`` (or ``"pano2cad/gt@1"``) JSON object.

        Raises
        ------
        ValueError
            Naming the first missing or malformed field.

        Examples
        --------
        >>> Scene.from_json_dict({"schema": "pano2cad/scene@0"})
        Traceback (most recent call last):
        ...
        ValueError: schema: expected 'pano2cad/scene@1' or 'pano2cad/gt@1', got 'pano2cad/scene@0'
        """
        schema = _require(d, "schema", "scene")
        if schema == GT_SCHEMA:
            return cls.from_gt_json_dict(d)
        if schema != SCENE_SCHEMA:
            raise ValueError(f"schema: expected {SCENE_SCHEMA!r} or {GT_SCHEMA!r}, got {schema!r}")
        image = d.get("image") or {}
        camera = _require(d, "camera", "scene")
        room = _require(d, "room", "scene")
        objs = _require(d, "objects", "scene")
        if not isinstance(objs, list):
            raise ValueError(f"objects: expected a JSON list, got {type(objs).__name__}")
        return cls(
            floor=_require(room, "floor", "room"),
            floor_z=room.get("floor_z", 0.0),
            ceiling_z=_require(room, "ceiling_z", "room"),
            camera_height=_require(camera, "height_m", "camera"),
            rotation=camera.get("rotation"),
            objects=tuple(SceneObject.from_json_dict(o, f"objects[{i}]") for i, o in enumerate(objs)),
            scale=d.get("scale"),
            image_file=image.get("file"),
            image_width=image.get("width"),
            image_height=image.get("height"),
            timing=d.get("timing_s") or {},
        )

    # ------------------------------------------------------------------ gt@1

    def corners_px(self, width: int, height: int) -> FloatArray:
        """``(N, 4)`` pixels ``[u_ceiling, v_ceiling, u_floor, v_floor]`` of the room corners.

        In the upright panorama of size ``width x height`` (the gt@1 field
        ``corners_px``), in the order of the floor polygon.
        """
        from panogeom.coords import world_to_pixel

        if self.ceiling_z is None:
            raise ValueError("expected a scene with a known ceiling_z for corner pixels, got ceiling_z None")
        n = len(self.floor)
        fl = np.column_stack([self.floor, np.full(n, self.floor_z)])
        ce = np.column_stack([self.floor, np.full(n, self.ceiling_z)])
        cam_h = self.floor_z + self.camera_height
        return np.column_stack([world_to_pixel(ce, width, height, cam_h), world_to_pixel(fl, width, height, cam_h)])

    def to_gt_json_dict(self) -> dict[str, Any]:
        """The scene as a ``"pano2cad/gt@1"`` JSON object (ground truth of a synthetic panorama).

        ``corners_px`` needs the image size and the ceiling; it is ``null``
        when either is unknown.
        """
        known = self.image_width is not None and self.image_height is not None and self.ceiling_z is not None
        return {
            "schema": GT_SCHEMA,
            "image": {"file": self.image_file, "width": self.image_width, "height": self.image_height},
            "room": {"floor": self.floor.tolist(), "floor_z": self.floor_z, "ceiling_z": self.ceiling_z},
            "camera_height_m": self.camera_height,
            "objects": [o.to_json_dict() for o in self.objects],
            "corners_px": (self.corners_px(self.image_width, self.image_height).tolist()  # type: ignore[arg-type]
                           if known else None),
        }

    @classmethod
    def from_gt_json_dict(cls, d: Mapping[str, Any]) -> "Scene":
        """Read a ``"pano2cad/gt@1"`` JSON object (``corners_px`` is derived data and only shape-checked).

        Examples
        --------
        >>> s = Scene([[-2, -1.5], [2, -1.5], [2, 1.5], [-2, 1.5]], 2.6, 1.5, image_width=512, image_height=256)
        >>> g = s.to_gt_json_dict()
        >>> g["schema"], len(g["corners_px"]), Scene.from_json_dict(g).camera_height
        ('pano2cad/gt@1', 4, 1.5)
        """
        schema = _require(d, "schema", "gt")
        if schema != GT_SCHEMA:
            raise ValueError(f"schema: expected {GT_SCHEMA!r}, got {schema!r}")
        room = _require(d, "room", "gt")
        objs = _require(d, "objects", "gt")
        if not isinstance(objs, list):
            raise ValueError(f"objects: expected a JSON list, got {type(objs).__name__}")
        image = d.get("image") or {}
        scene = cls(
            floor=_require(room, "floor", "room"),
            floor_z=room.get("floor_z", 0.0),
            ceiling_z=_require(room, "ceiling_z", "room"),
            camera_height=_require(d, "camera_height_m", "gt"),
            rotation=None,
            objects=tuple(SceneObject.from_json_dict(o, f"objects[{i}]") for i, o in enumerate(objs)),
            image_file=image.get("file"),
            image_width=image.get("width"),
            image_height=image.get("height"),
        )
        corners = d.get("corners_px")
        if corners is not None:
            c = np.asarray(corners, dtype=np.float64)
            if c.shape != (len(scene.floor), 4):
                raise ValueError(f"corners_px: expected shape ({len(scene.floor)}, 4) (one row per floor corner), "
                                 f"got {c.shape}")
        return scene
