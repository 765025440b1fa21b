"""The pose grid and pyrender renders of library models at every pose.

The paper renders each 3D model "in 360 poses" (yaw in [0, 360) degrees x
pitch in [0, 45] degrees, roll fixed; Sec. 3.2 and 4) and compares HOG
descriptors of the renders with those of the detected object crops. This
module defines that pose grid (:class:`PoseGrid`), the render settings
(:class:`RenderSettings`) and an off-screen renderer (:class:`PoseRenderer`,
pyrender on EGL, headless) that draws one model from any pose and cuts the
square crop the descriptors are computed on (:func:`crop_square`).

Convention:
    A *pose* (yaw, pitch) is where the camera stands as seen from the object,
    in the object's canonical frame (metres, z up, front facing +x):

    - yaw: azimuth of the direction object -> camera, counter-clockwise seen
      from above, measured from the object's front (+x). yaw 0 = the camera
      is on the +x side of the model, looking towards -x at the front face;
      yaw pi/2 = the camera is on the model's +y side (its left, seen from
      the front).
    - pitch: elevation of the camera above the horizontal plane through the
      model centre, positive = camera above, looking down.

    The camera always looks at the model's bounding-box centre
    ``(0, 0, height / 2)`` with no roll (image up = the world's z projected),
    from a room-like distance (``RenderSettings.distance``, or farther when
    the model's bounding sphere would not fit the field of view), with the
    field of view narrowed so that the sphere fills it
    (:func:`camera_setup`). Angles are radians; ``_deg`` names carry degrees.

    Pose labels follow :class:`posecrf.mrf.LabelGrid`: C order over
    ``(n_yaw, n_pitch)``, so ``label = i_yaw * n_pitch + i_pitch``.

Examples
--------
>>> grid = PoseGrid()
>>> grid.size, grid.shape
(360, (72, 5))
>>> [round(float(np.rad2deg(p)), 2) for p in grid.pitches]
[0.0, 11.25, 22.5, 33.75, 45.0]
>>> float(np.rad2deg(grid.poses()[7, 0])), float(np.rad2deg(grid.poses()[7, 1]))
(5.0, 22.5)
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .mrf import LabelGrid

if TYPE_CHECKING:  # pragma: no cover - typing only
    from .library import Model3D

__all__ = [
    "PoseGrid",
    "RenderSettings",
    "RenderError",
    "PoseRenders",
    "PoseRenderer",
    "camera_setup",
    "camera_pose_matrix",
    "look_at",
    "crop_square",
    "mask_bbox",
    "render_poses",
    "shared_offscreen_renderer",
    "check_renderable",
    "RENDER_VERSION",
]

RENDER_VERSION = "3"
"""Bumped whenever the renders change for the same settings (part of the cache key)."""

_TWO_PI = 2.0 * math.pi


def _pyrender():
    """Import pyrender headless (EGL unless PYOPENGL_PLATFORM says otherwise)."""
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    try:
        import pyrender
    except ImportError as exc:  # pragma: no cover - pyrender is a core dependency
        raise ImportError("posecrf.render needs pyrender: pip install pyrender==0.1.45 (and Mesa EGL for headless use)") from exc
    return pyrender


_OFFSCREEN: dict[tuple[int, int], Any] = {}


def shared_offscreen_renderer(width: int, height: int) -> Any:
    """The process's ``pyrender.OffscreenRenderer`` of this size, created on first use and kept.

    pyrender's EGL back end terminates the EGL display when any renderer is
    deleted, which kills every other live context of the process. So
    renderers are shared per size and never deleted before the process
    exits; everything in posecrf (and the benchmarks) that renders off
    screen takes its renderer from here. Rendering different scenes in turn
    with one renderer is fine.
    """
    if int(width) != width or int(height) != height or width < 1 or height < 1:
        raise ValueError(f"width, height: expected positive integer pixels, got {width!r}, {height!r}")
    key = (int(width), int(height))
    r = _OFFSCREEN.get(key)
    if r is None:
        r = _pyrender().OffscreenRenderer(*key)
        _OFFSCREEN[key] = r
    return r


def _cv2():
    try:
        import cv2
    except ImportError as exc:  # pragma: no cover - opencv is a core dependency
        raise ImportError("posecrf.render needs OpenCV: pip install opencv-contrib-python-headless") from exc
    return cv2


# --------------------------------------------------------------------------- pose grid
@dataclass(frozen=True)
class PoseGrid:
    """The quantised pose space: ``n_yaw`` yaws x ``n_pitch`` pitches.

    Parameters
    ----------
    n_yaw : int
        Yaw bins over [0, 2*pi): yaw ``i`` is ``2*pi*i/n_yaw`` (default 72,
        a 5 degree step).
    n_pitch : int
        Pitch values from 0 to `pitch_max` inclusive (default 5).
    pitch_max : float
        Largest pitch, radians, in [0, pi/2) (default pi/4 = 45 degrees).
        Must be 0 when ``n_pitch == 1``.

    Convention: see the module docstring (pose = camera position seen from
    the object; labels in C order, ``label = i_yaw * n_pitch + i_pitch``).
    """

    n_yaw: int = 72
    n_pitch: int = 5
    pitch_max: float = math.pi / 4

    def __post_init__(self) -> None:
        if int(self.n_yaw) != self.n_yaw or self.n_yaw < 1:
            raise ValueError(f"n_yaw: expected a positive integer, got {self.n_yaw!r}")
        if int(self.n_pitch) != self.n_pitch or self.n_pitch < 1:
            raise ValueError(f"n_pitch: expected a positive integer, got {self.n_pitch!r}")
        pm = float(self.pitch_max)
        if not (math.isfinite(pm) and 0.0 <= pm < math.pi / 2):
            raise ValueError(f"pitch_max: expected radians in [0, pi/2), got {self.pitch_max!r}")
        if self.n_pitch == 1 and pm != 0.0:
            raise ValueError(f"pitch_max: expected 0 with n_pitch == 1, got {pm}")
        if self.n_pitch > 1 and pm == 0.0:
            raise ValueError(f"pitch_max: expected > 0 with n_pitch = {self.n_pitch}, got 0")
        object.__setattr__(self, "n_yaw", int(self.n_yaw))
        object.__setattr__(self, "n_pitch", int(self.n_pitch))
        object.__setattr__(self, "pitch_max", pm)

    @property
    def shape(self) -> tuple[int, int]:
        """``(n_yaw, n_pitch)``."""
        return (self.n_yaw, self.n_pitch)

    @property
    def size(self) -> int:
        """Number of poses L = n_yaw * n_pitch."""
        return self.n_yaw * self.n_pitch

    @property
    def yaw_step(self) -> float:
        """Yaw bin width, radians."""
        return _TWO_PI / self.n_yaw

    @property
    def pitch_step(self) -> float:
        """Pitch spacing, radians (1.0 when there is a single pitch, as a metric placeholder)."""
        return self.pitch_max / (self.n_pitch - 1) if self.n_pitch > 1 else 1.0

    @property
    def yaws(self) -> NDArray[np.float64]:
        """(n_yaw,) float: yaw of each bin, radians in [0, 2*pi)."""
        return np.arange(self.n_yaw, dtype=np.float64) * self.yaw_step

    @property
    def pitches(self) -> NDArray[np.float64]:
        """(n_pitch,) float: pitch values, radians in [0, pitch_max]."""
        if self.n_pitch == 1:
            return np.zeros(1)
        return np.linspace(0.0, self.pitch_max, self.n_pitch)

    def poses(self) -> NDArray[np.float64]:
        """(L, 2) float: ``(yaw, pitch)`` of every label, in label order."""
        y, p = np.meshgrid(self.yaws, self.pitches, indexing="ij")
        return np.stack([y.ravel(), p.ravel()], axis=1)

    def label_grid(self) -> LabelGrid:
        """The :class:`~posecrf.mrf.LabelGrid` of this pose space (yaw cyclic, radian steps)."""
        return LabelGrid(self.shape, steps=(self.yaw_step, self.pitch_step), cyclic=(True, False))

    def nearest_label(self, yaw: ArrayLike, pitch: ArrayLike) -> NDArray[np.int64]:
        """Label of the grid pose nearest to ``(yaw, pitch)`` (broadcast), radians.

        Yaw wraps; pitch is clipped to the grid's range.

        Examples
        --------
        >>> PoseGrid().nearest_label(np.deg2rad(358.0), np.deg2rad(10.0)).tolist()
        1
        """
        y = np.asarray(yaw, dtype=np.float64)
        p = np.asarray(pitch, dtype=np.float64)
        if not (np.all(np.isfinite(y)) and np.all(np.isfinite(p))):
            raise ValueError("yaw, pitch: expected finite angles in radians, got NaN or inf")
        iy = np.mod(np.rint(y / self.yaw_step).astype(np.int64), self.n_yaw)
        if self.n_pitch == 1:
            ip = np.zeros(np.broadcast(y, p).shape, dtype=np.int64)
        else:
            ip = np.clip(np.rint(p / self.pitch_step), 0, self.n_pitch - 1).astype(np.int64)
        return iy * self.n_pitch + ip

    def key(self) -> str:
        """A stable text key of the grid (for cache keys)."""
        return f"yaw{self.n_yaw}-pitch{self.n_pitch}-max{self.pitch_max:.12g}"


# --------------------------------------------------------------------------- settings
@dataclass(frozen=True)
class RenderSettings:
    """How library models are rendered for the descriptor database.

    Parameters
    ----------
    size : int
        Side of the square crop the descriptors are computed on, pixels.
    viewport : int
        Side of the square off-screen image rendered before cropping.
    fov : float
        Largest vertical (= horizontal) field of view of the render camera,
        radians: a model whose bounding sphere does not fit at `distance`
        is moved back until it fills this field of view (a 2 m bed at
        40 degrees: about 3.8 m).
    margin : float
        Fraction of the silhouette box added on every side before the crop
        is resized square (0 = tight crop). The default 0.08 is about what a
        detection box enlarged by 10 % leaves around the object.
    background : tuple of 3 int
        Neutral background colour, RGB 0..255.
    ambient : float
        Ambient light level in [0, 1].
    light : float
        Intensity of the directional key light.
    light_elevation : float
        The key light shines from the camera's azimuth, raised by this angle
        above the camera direction (radians, in [0, pi/2)); 0 = a headlight.
    distance : float or None
        Camera distance from the model centre in metres (at least the
        distance that fits the bounding sphere into `fov`; the field of view
        then shrinks to fit the sphere), so that the renders show the
        perspective of furniture seen across a room. The default 2.75 m is
        the middle of the 1.5-4 m range of benchmarks/eval_pose.py; it was
        chosen on that script's tuning split. None = always the fitting
        distance.
    """

    size: int = 64
    viewport: int = 128
    fov: float = math.radians(40.0)
    margin: float = 0.08
    background: tuple[int, int, int] = (128, 128, 128)
    ambient: float = 0.45
    light: float = 3.0
    light_elevation: float = 0.0
    distance: float | None = 2.75

    def __post_init__(self) -> None:
        for name in ("size", "viewport"):
            v = getattr(self, name)
            if int(v) != v or not (8 <= v <= 4096):
                raise ValueError(f"{name}: expected an integer in [8, 4096] pixels, got {v!r}")
            object.__setattr__(self, name, int(v))
        if not (math.isfinite(self.fov) and 0.05 < self.fov < 2.5):
            raise ValueError(f"fov: expected radians in (0.05, 2.5), got {self.fov!r}")
        if not (math.isfinite(self.margin) and 0.0 <= self.margin <= 1.0):
            raise ValueError(f"margin: expected a fraction in [0, 1], got {self.margin!r}")
        bg = tuple(int(c) for c in self.background)
        if len(bg) != 3 or min(bg) < 0 or max(bg) > 255:
            raise ValueError(f"background: expected an RGB triple in 0..255, got {self.background!r}")
        object.__setattr__(self, "background", bg)
        if not (0.0 <= self.ambient <= 1.0):
            raise ValueError(f"ambient: expected a level in [0, 1], got {self.ambient!r}")
        if not (math.isfinite(self.light) and self.light >= 0.0):
            raise ValueError(f"light: expected a finite intensity >= 0, got {self.light!r}")
        if not (math.isfinite(self.light_elevation) and 0.0 <= self.light_elevation < math.pi / 2):
            raise ValueError(f"light_elevation: expected radians in [0, pi/2), got {self.light_elevation!r}")
        if self.distance is not None and not (math.isfinite(self.distance) and self.distance > 0):
            raise ValueError(f"distance: expected None or a positive distance in metres, got {self.distance!r}")
        object.__setattr__(self, "light_elevation", float(self.light_elevation))
        if self.distance is not None:
            object.__setattr__(self, "distance", float(self.distance))
        object.__setattr__(self, "fov", float(self.fov))
        object.__setattr__(self, "margin", float(self.margin))
        object.__setattr__(self, "ambient", float(self.ambient))
        object.__setattr__(self, "light", float(self.light))

    def key(self) -> str:
        """Canonical JSON of the settings plus `RENDER_VERSION` (for cache keys)."""
        d: dict[str, Any] = asdict(self)
        for name in ("fov", "margin", "ambient", "light", "light_elevation"):
            d[name] = f"{getattr(self, name):.12g}"
        d["distance"] = None if self.distance is None else f"{self.distance:.12g}"
        d["render_version"] = RENDER_VERSION
        return json.dumps(d, sort_keys=True)


class RenderError(ValueError):
    """A model that cannot be rendered (empty or degenerate mesh, NaN vertices, empty silhouette)."""

    def __init__(self, model_id: str, reason: str) -> None:
        super().__init__(f"{model_id}: {reason}")
        self.model_id = model_id
        self.reason = reason


# --------------------------------------------------------------------------- geometry
def look_at(eye: ArrayLike, target: ArrayLike, up: ArrayLike = (0.0, 0.0, 1.0)) -> NDArray[np.float64]:
    """OpenGL camera-to-world matrix of a camera at `eye` looking at `target`.

    Convention: pyrender/OpenGL camera axes: x right, y up, the camera looks
    along its -z. The returned (4, 4) matrix has columns (right, up, -forward,
    eye). `up` is the world direction that appears upwards (no roll).

    Examples
    --------
    >>> m = look_at([3.0, 0.0, 0.0], [0.0, 0.0, 0.0])
    >>> (-m[:3, 2] + 0.0).tolist(), (m[:3, 1] + 0.0).tolist()   # forward, up
    ([-1.0, 0.0, 0.0], [0.0, 0.0, 1.0])
    """
    e = np.asarray(eye, dtype=np.float64)
    t = np.asarray(target, dtype=np.float64)
    u = np.asarray(up, dtype=np.float64)
    if e.shape != (3,) or t.shape != (3,) or u.shape != (3,):
        raise ValueError(f"eye, target, up: expected (3,) vectors, got {e.shape}, {t.shape}, {u.shape}")
    f = t - e
    n = np.linalg.norm(f)
    if not np.isfinite(n) or n < 1e-12:
        raise ValueError(f"eye, target: expected two distinct finite points, got {e.tolist()} and {t.tolist()}")
    f = f / n
    r = np.cross(f, u)
    rn = np.linalg.norm(r)
    if rn < 1e-9:
        raise ValueError("up: expected a direction not parallel to the viewing direction")
    r = r / rn
    up2 = np.cross(r, f)
    m = np.eye(4)
    m[:3, 0] = r
    m[:3, 1] = up2
    m[:3, 2] = -f
    m[:3, 3] = e
    return m


def camera_setup(model_size: ArrayLike, settings: RenderSettings) -> tuple[float, float]:
    """Camera distance (metres) and field of view (radians) for a model of this size.

    The fitting distance puts the model's bounding sphere (radius ``|size| / 2``)
    just inside ``settings.fov``: ``r / sin(fov / 2)``. With
    ``settings.distance`` set, the camera stays at least that far and the
    field of view shrinks to ``2 asin(r / distance)`` so the sphere still fills it.

    Examples
    --------
    >>> d, f = camera_setup([0.0, 0.0, 1.0], RenderSettings(fov=np.pi / 3, distance=None))
    >>> round(d, 6), round(float(np.rad2deg(f)), 6)
    (1.0, 60.0)
    >>> d, f = camera_setup([0.0, 0.0, 1.0], RenderSettings(fov=np.pi / 3, distance=2.0))
    >>> round(d, 6), round(float(np.rad2deg(f)), 6)
    (2.0, 28.955024)
    """
    s = np.asarray(model_size, dtype=np.float64)
    if s.shape != (3,) or not np.all(np.isfinite(s)) or np.any(s < 0) or float(np.linalg.norm(s)) <= 0:
        raise ValueError(f"model_size: expected (3,) finite extents >= 0 (not all 0), got {s.tolist()}")
    radius = 0.5 * float(np.linalg.norm(s))
    fit = radius / math.sin(0.5 * settings.fov)
    if settings.distance is None or settings.distance <= fit:
        return fit, settings.fov
    return settings.distance, 2.0 * math.asin(radius / settings.distance)


def camera_pose_matrix(model_size: ArrayLike, yaw: float, pitch: float, distance: float) -> NDArray[np.float64]:
    """Camera-to-model matrix (OpenGL axes) of the render camera at pose (yaw, pitch).

    Parameters
    ----------
    model_size : (3,) float
        Model extents (x, y, z), metres; the camera aims at ``(0, 0, z/2)``.
    yaw, pitch : float
        Pose, radians (module docstring: camera direction seen from the model).
    distance : float
        Camera distance from that centre, metres (see :func:`camera_setup`).

    Returns
    -------
    (4, 4) float

    Examples
    --------
    >>> m = camera_pose_matrix([2.0, 1.0, 1.0], 0.0, 0.0, 3.0)
    >>> float(m[0, 3]), float(m[1, 3]), float(m[2, 3])   # in front (+x), level with the centre
    (3.0, 0.0, 0.5)
    >>> m = camera_pose_matrix([2.0, 1.0, 1.0], np.pi / 2, np.pi / 4, 2.0)
    >>> (m[:3, 3].round(6) + 0.0).tolist()   # on the model's +y side, above
    [0.0, 1.414214, 1.914214]
    """
    s = np.asarray(model_size, dtype=np.float64)
    if s.shape != (3,) or not np.all(np.isfinite(s)):
        raise ValueError(f"model_size: expected (3,) finite extents, got {s.tolist()}")
    if not (math.isfinite(yaw) and math.isfinite(pitch) and abs(pitch) < math.pi / 2):
        raise ValueError(f"yaw, pitch: expected finite radians with |pitch| < pi/2, got {yaw!r}, {pitch!r}")
    if not (math.isfinite(distance) and distance > 0):
        raise ValueError(f"distance: expected a positive distance in metres, got {distance!r}")
    centre = np.array([0.0, 0.0, 0.5 * s[2]])
    d = np.array([math.cos(pitch) * math.cos(yaw), math.cos(pitch) * math.sin(yaw), math.sin(pitch)])
    return look_at(centre + distance * d, centre)


def mask_bbox(mask: ArrayLike) -> tuple[int, int, int, int] | None:
    """Bounding box ``(x0, y0, x1, y1)`` (exclusive ends, pixels) of a mask's True pixels, or None if empty.

    Examples
    --------
    >>> m = np.zeros((5, 6), bool); m[1:3, 2:5] = True
    >>> mask_bbox(m)
    (2, 1, 5, 3)
    """
    m = np.asarray(mask, dtype=bool)
    if m.ndim != 2:
        raise ValueError(f"mask: expected an (H, W) array, got shape {m.shape}")
    rows = np.flatnonzero(m.any(axis=1))
    if rows.size == 0:
        return None
    cols = np.flatnonzero(m.any(axis=0))
    return int(cols[0]), int(rows[0]), int(cols[-1]) + 1, int(rows[-1]) + 1


def crop_square(
    image: ArrayLike,
    mask: ArrayLike | None = None,
    size: int = 64,
    margin: float = 0.0,
    box: ArrayLike | None = None,
    background: tuple[int, int, int] | None = None,
) -> tuple[NDArray[np.uint8], NDArray[np.bool_]]:
    """Cut the object's box out of an image and resize it to ``size x size``.

    The box is `box` if given, else the bounding box of `mask`, else the
    whole image; it is enlarged by `margin` (a fraction of its width and
    height) on every side, pixels outside the image count as background,
    and the result is resized (anisotropically) to a square, as the library
    renders are.

    Parameters
    ----------
    image : (H, W, 3) uint8
    mask : (H, W) bool, optional
        Object pixels. Without it the whole crop counts as object.
    size : int
        Output side, pixels.
    margin : float
        Fraction added on every side, >= 0.
    box : (4,) float, optional
        ``(x0, y0, x1, y1)`` in pixels (exclusive ends), x0 < x1, y0 < y1.
    background : tuple of 3 int, optional
        When given (and a mask is given), pixels outside the mask are painted
        this colour before resizing.

    Returns
    -------
    crop : (size, size, 3) uint8
    crop_mask : (size, size) bool

    Examples
    --------
    >>> img = np.zeros((40, 80, 3), np.uint8); m = np.zeros((40, 80), bool); m[10:20, 20:60] = True
    >>> c, cm = crop_square(img, m, size=16)
    >>> c.shape, bool(cm.all())
    ((16, 16, 3), True)
    """
    img = np.asarray(image)
    if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8 or img.shape[0] < 1 or img.shape[1] < 1:
        raise ValueError(f"image: expected an (H, W, 3) uint8 array, got shape {img.shape} dtype {img.dtype}")
    h, w = img.shape[:2]
    if mask is None:
        m = np.ones((h, w), dtype=bool)
    else:
        m = np.asarray(mask)
        if m.shape != (h, w):
            raise ValueError(f"mask: expected shape (H, W) = ({h}, {w}), got {m.shape}")
        m = m.astype(bool)
    if int(size) != size or size < 4:
        raise ValueError(f"size: expected an integer >= 4, got {size!r}")
    if not (math.isfinite(margin) and margin >= 0):
        raise ValueError(f"margin: expected a fraction >= 0, got {margin!r}")
    if box is not None:
        b = np.asarray(box, dtype=np.float64)
        if b.shape != (4,) or not np.all(np.isfinite(b)) or b[2] <= b[0] or b[3] <= b[1]:
            raise ValueError(f"box: expected (x0, y0, x1, y1) with x0 < x1 and y0 < y1, got {np.asarray(box).tolist()}")
        x0, y0, x1, y1 = (float(v) for v in b)
    else:
        bb = mask_bbox(m) if mask is not None else (0, 0, w, h)
        if bb is None:
            raise ValueError("mask: expected at least one object pixel, got an empty mask")
        x0, y0, x1, y1 = (float(v) for v in bb)
    if background is not None and mask is not None:
        img = img.copy()
        img[~m] = np.asarray(background, dtype=np.uint8)
    bw, bh = x1 - x0, y1 - y0
    x0, x1 = x0 - margin * bw, x1 + margin * bw
    y0, y1 = y0 - margin * bh, y1 + margin * bh
    cv2 = _cv2()
    # affine map of the box onto the square, sampled with area-like smoothing
    sx, sy = size / (x1 - x0), size / (y1 - y0)
    a = np.array([[sx, 0.0, -x0 * sx], [0.0, sy, -y0 * sy]])
    bg = tuple(float(c) for c in (background if background is not None else (0, 0, 0)))
    src = img
    if sx < 1.0 or sy < 1.0:
        # pre-blur against aliasing when shrinking
        kx = max(1, int(round(1.0 / sx)) | 1)
        ky = max(1, int(round(1.0 / sy)) | 1)
        src = cv2.GaussianBlur(img, (kx, ky), 0)
    crop = cv2.warpAffine(src, a, (size, size), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=bg)
    cm = cv2.warpAffine(m.astype(np.float32), a, (size, size), flags=cv2.INTER_LINEAR,
                        borderMode=cv2.BORDER_CONSTANT, borderValue=0.0) >= 0.5
    return np.ascontiguousarray(crop, dtype=np.uint8), cm


# --------------------------------------------------------------------------- renderer
@dataclass(frozen=True, eq=False)
class PoseRenders:
    """Square crops of one model rendered at a list of poses.

    Attributes
    ----------
    model_id : str
    poses : (P, 2) float
        ``(yaw, pitch)`` per render, radians.
    images : (P, S, S, 3) uint8
        Crops of the silhouette box resized square, on the neutral background.
    masks : (P, S, S) bool
        Silhouettes in the crops.
    aspect : (P,) float
        Width / height of the silhouette box before resizing.
    """

    model_id: str
    poses: NDArray[np.float64]
    images: NDArray[np.uint8]
    masks: NDArray[np.bool_]
    aspect: NDArray[np.float64]


def check_renderable(model: "Model3D") -> None:
    """Raise :class:`RenderError` naming the model if its mesh cannot be rendered.

    Checks: (V, 3) finite vertices, at least one face, face indices in
    range, total face area > 0.
    """
    v = np.asarray(model.vertices, dtype=np.float64)
    f = np.asarray(model.faces)
    if v.ndim != 2 or v.shape[1] != 3 or len(v) == 0:
        raise RenderError(model.id, f"expected (V, 3) vertices, got shape {v.shape}")
    if not np.all(np.isfinite(v)):
        raise RenderError(model.id, "vertices contain NaN or inf")
    if f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
        raise RenderError(model.id, f"empty mesh: expected (F, 3) faces with F >= 1, got shape {f.shape}")
    if f.min() < 0 or f.max() >= len(v):
        raise RenderError(model.id, f"face indices must lie in [0, {len(v)}), got [{f.min()}, {f.max()}]")
    tri = v[f]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    if not float(area.sum()) > 1e-12:
        raise RenderError(model.id, "degenerate mesh: total face area is 0")


class PoseRenderer:
    """Off-screen pyrender renderer of library models (EGL, headless).

    Uses the process's shared OpenGL context of its viewport size
    (:func:`shared_offscreen_renderer`); use it as a context manager or call
    `close`. A model's GPU mesh is kept until another model is rendered.

    Parameters
    ----------
    settings : RenderSettings, optional

    Convention: see the module docstring (pose = camera seen from the model).

    Examples
    --------
    >>> from posecrf.library import builtin_library
    >>> with PoseRenderer(RenderSettings(size=32, viewport=64)) as r:
    ...     rgb, mask = r.render(builtin_library()["tv-01"], yaw=0.0, pitch=0.0)
    >>> rgb.shape, bool(mask.any())
    ((64, 64, 3), True)
    """

    def __init__(self, settings: RenderSettings | None = None) -> None:
        self.settings = settings if settings is not None else RenderSettings()
        if not isinstance(self.settings, RenderSettings):
            raise ValueError(f"settings: expected RenderSettings, got {type(self.settings).__name__}")
        pr = _pyrender()
        self._pr = pr
        s = self.settings
        self._renderer = shared_offscreen_renderer(s.viewport, s.viewport)
        bg = [c / 255.0 for c in s.background] + [1.0]
        self._scene = pr.Scene(bg_color=bg, ambient_light=[s.ambient] * 3)
        self._camera = self._scene.add(pr.PerspectiveCamera(yfov=s.fov, aspectRatio=1.0, znear=0.05, zfar=100.0))
        self._light = self._scene.add(pr.DirectionalLight(color=[1.0, 1.0, 1.0], intensity=s.light))
        self._mesh_node = None
        self._model: "Model3D | None" = None
        self._size = np.zeros(3)
        self._distance = 1.0

    def __enter__(self) -> "PoseRenderer":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Drop the model and stop rendering (idempotent); the shared context stays for reuse."""
        if self._mesh_node is not None:
            self._scene.remove_node(self._mesh_node)
            self._mesh_node = None
            self._model = None
        self._renderer = None

    def _set_model(self, model: "Model3D") -> None:
        if model is self._model:
            return
        check_renderable(model)
        if self._mesh_node is not None:
            self._scene.remove_node(self._mesh_node)
            self._mesh_node = None
            self._model = None
        try:
            mesh = self._pr.Mesh.from_trimesh(model.mesh, smooth=False)
        except (ValueError, IndexError, TypeError) as exc:
            raise RenderError(model.id, f"pyrender refused the mesh: {exc}") from exc
        self._mesh_node = self._scene.add(mesh)
        self._model = model
        self._size = np.asarray(model.size, dtype=np.float64)
        self._distance, self._camera.camera.yfov = camera_setup(self._size, self.settings)

    def render(self, model: "Model3D", yaw: float, pitch: float) -> tuple[NDArray[np.uint8], NDArray[np.bool_]]:
        """Full viewport render of `model` at pose (yaw, pitch), radians.

        Returns
        -------
        rgb : (viewport, viewport, 3) uint8
        mask : (viewport, viewport) bool
            The model's silhouette.
        """
        if self._renderer is None:
            raise ValueError("renderer: expected an open PoseRenderer, got one that was closed")
        self._set_model(model)
        pose = camera_pose_matrix(self._size, float(yaw), float(pitch), self._distance)
        self._scene.set_pose(self._camera, pose)
        le = self.settings.light_elevation
        if le > 0.0:
            # key light from the camera's azimuth, raised by light_elevation
            up = min(float(pitch) + le, math.radians(89.0))
            pose = camera_pose_matrix(self._size, float(yaw), up, self._distance)
        self._scene.set_pose(self._light, pose)
        color, depth = self._renderer.render(self._scene)
        return np.ascontiguousarray(color[..., :3]), depth > 0

    def render_crops(self, model: "Model3D", poses: ArrayLike) -> PoseRenders:
        """Render `model` at every pose and cut the square crops.

        Parameters
        ----------
        model : Model3D
        poses : (P, 2) float
            ``(yaw, pitch)`` radians, |pitch| < pi/2.

        Returns
        -------
        PoseRenders

        Raises
        ------
        RenderError
            The mesh is empty, degenerate or not finite, or a view shows nothing.
        """
        p = np.asarray(poses, dtype=np.float64)
        if p.ndim != 2 or p.shape[1] != 2 or not np.all(np.isfinite(p)):
            raise ValueError(f"poses: expected a finite (P, 2) array of (yaw, pitch), got shape {p.shape}")
        s = self.settings
        images = np.empty((len(p), s.size, s.size, 3), dtype=np.uint8)
        masks = np.empty((len(p), s.size, s.size), dtype=bool)
        aspect = np.empty(len(p))
        for k, (yaw, pitch) in enumerate(p):
            rgb, mask = self.render(model, yaw, pitch)
            bb = mask_bbox(mask)
            if bb is None:
                raise RenderError(model.id, f"empty silhouette at yaw {math.degrees(yaw):.1f} deg, pitch {math.degrees(pitch):.1f} deg")
            aspect[k] = (bb[2] - bb[0]) / (bb[3] - bb[1])
            images[k], masks[k] = crop_square(rgb, mask, s.size, s.margin, background=s.background)
        return PoseRenders(model.id, p, images, masks, aspect)


def render_poses(model: "Model3D", grid: PoseGrid | None = None, settings: RenderSettings | None = None) -> PoseRenders:
    """Render one model at every pose of a grid (opens and closes a renderer).

    Examples
    --------
    >>> from posecrf.library import builtin_library
    >>> r = render_poses(builtin_library()["chair-01"], PoseGrid(4, 1, 0.0), RenderSettings(size=32, viewport=64))
    >>> r.images.shape, r.masks.shape
    ((4, 32, 32, 3), (4, 32, 32))
    """
    g = grid if grid is not None else PoseGrid()
    with PoseRenderer(settings) as r:
        return r.render_crops(model, g.poses())
