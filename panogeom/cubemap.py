"""Equirectangular panorama <-> cubemap (six 90-degree pinhole faces).

Convention (our frame of CONVENTIONS.md: x at lon = 0, y at lon = -pi/2, z up):

- Faces in the order ``F R B L U D``. Each face is the pinhole view
  ``PinholeView(yaw, pitch, 0, fov=pi/2, S, S)`` of :mod:`panogeom.perspective`:

  ====  ===============  ==============  ================  ===============
  face  looks at         (yaw, pitch)    image right (+u)  image down (+v)
  ====  ===============  ==============  ================  ===============
  F     +x (lon = 0)     (0, 0)          -y                -z
  R     -y (lon = pi/2)  (-pi/2, 0)      -x                -z
  B     -x (lon = pi)    (pi, 0)         +y                -z
  L     +y (lon = -pi/2) (pi/2, 0)       +x                -z
  U     +z (up)          (0, pi/2)       -y                +x
  D     -z (down)        (0, -pi/2)      -y                -x
  ====  ===============  ==============  ================  ===============

  So the four side faces are seen upright from the centre, U is what the F
  view sees when it tilts up (its top row borders B, its bottom row F) and D
  what it sees when it tilts down (top row borders F).
- Face pixels follow the panorama's pixel convention: continuous ``(u, v)``
  in ``[0, S] x [0, S]``, centres at integer + 0.5, so pixel centre ``j``
  lies at ``tan = (2*(j + 0.5) / S - 1)`` on the unit-distance face plane.
- Layouts: ``"list"`` (6 faces, each ``(S, S[, C])``), ``"dict"`` (keys ``F R B L U D``),
  ``"horizon"`` (``(S, 6S)`` strip in list order) and ``"dice"`` (``(3S, 4S)``
  cross: U above F; L F R B in the middle row; D below F; other cells zero).

Relation to py360convert (1.0.x): its cube frame is ``(x right, y up, z
forward) = (-y, z, x)`` of ours; it uses the same face order, the same
in-face orientation and the same ``dice`` layout, so faces correspond one to
one. It differs in the pixel grids, and its two directions disagree with
each other: its ``e2c`` face pixel ``j`` samples ``tan = 2*j/(S - 1) - 1``
(corner pixels centred on the cube edges, a field of view slightly above 90
degrees; the panorama is read with our centre convention), while its ``c2e``
reads face pixel ``j`` at ``tan = 2*j/S - 1`` (half a pixel off ours) and
writes output pixel ``(i, j)`` at ``lon = -pi + 2*pi*j/(W - 1)``,
``lat = pi/2 - pi*i/(H - 1)``. The tests check all of this empirically.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Literal, Mapping, Sequence, Union, overload

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._checks import float_array, pano_image
from .coords import pixel_grid_rays, ray_to_pixel
from .perspective import PinholeView
from .sampling import _MAX_REMAP_SIZE, EquirectSampler, Interp, _cv2, _flags, _pad_width

__all__ = [
    "FACE_NAMES",
    "CubeFormat",
    "cube_face_views",
    "cube_face_axes",
    "cube_to_ray",
    "ray_to_cube",
    "equirect_to_cubemap",
    "cubemap_to_equirect",
    "cubemap_faces",
    "faces_to_cubemap",
]

#: Face order of every cubemap layout.
FACE_NAMES: tuple[str, ...] = ("F", "R", "B", "L", "U", "D")

CubeFormat = Literal["list", "dict", "horizon", "dice"]
_FORMATS = ("list", "dict", "horizon", "dice")

# (yaw, pitch) of each face, radians, in FACE_NAMES order.
_FACE_YAW_PITCH = ((0.0, 0.0), (-0.5 * np.pi, 0.0), (np.pi, 0.0), (0.5 * np.pi, 0.0),
                   (0.0, 0.5 * np.pi), (0.0, -0.5 * np.pi))
# (column, row) of each face in the dice cross, in face-size units.
_DICE_CELLS = ((1, 1), (2, 1), (3, 1), (0, 1), (1, 0), (1, 2))

Array = NDArray[np.float64]
Cubemap = Union[list[np.ndarray], dict[str, np.ndarray], np.ndarray]


def _face_size(face_size: int, name: str = "face_size") -> int:
    try:
        s = int(face_size)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: expected a positive integer, got {face_size!r}") from exc
    if s <= 0 or s != face_size:
        raise ValueError(f"{name}: expected a positive integer, got {face_size!r}")
    return s


def cube_face_views(face_size: int) -> list[PinholeView]:
    """The six faces as 90-degree square pinhole views, order ``F R B L U D``.

    Parameters
    ----------
    face_size : int
        Face width and height S in pixels.

    Returns
    -------
    views : list of 6 PinholeView

    Examples
    --------
    >>> [round(float(np.rad2deg(v.yaw))) for v in cube_face_views(8)]
    [0, -90, 180, 90, 0, 0]
    """
    s = _face_size(face_size)
    return [PinholeView(yaw=float(y), pitch=float(p), roll=0.0, fov=0.5 * np.pi, width=s, height=s)
            for y, p in _FACE_YAW_PITCH]


@lru_cache(maxsize=1)
def _axes() -> Array:
    axes = np.stack([v.R for v in cube_face_views(1)])
    # The face frames are exact signed permutations; remove trigonometric round-off.
    axes = np.round(axes)
    axes.setflags(write=False)
    return axes


@lru_cache(maxsize=1)
def _to_world() -> tuple[NDArray[np.intp], Array]:
    """The face frames as signed permutations, for a gather instead of per-pixel matrix products.

    World component k of face-camera coordinates c on face f is
    ``c[index[f, k]] * sign[f, k]`` (that is ``cube_face_axes()[f] @ c``).
    """
    ax = _axes()
    index = np.argmax(np.abs(ax), axis=2)  # (6, 3)
    sign = ax[np.arange(6)[:, None], np.arange(3)[None, :], index]
    return index, sign


def cube_face_axes() -> Array:
    """Face frames: ``axes[f]`` maps face camera coordinates into the panorama frame.

    Returns
    -------
    axes : (6, 3, 3) float
        Columns of ``axes[f]`` are the face's image-right, image-down and
        viewing directions (OpenCV camera axes), exact signed unit vectors.

    Examples
    --------
    >>> cube_face_axes()[0] + 0.0   # F: right = -y, down = -z, forward = +x
    array([[ 0.,  0.,  1.],
           [-1.,  0.,  0.],
           [ 0., -1.,  0.]])
    """
    return _axes().copy()


def cube_to_ray(face: ArrayLike, uv: ArrayLike, face_size: int) -> Array:
    """Face pixel coordinates to unit rays in the panorama frame.

    Parameters
    ----------
    face : (...,) int
        Face index 0..5 in ``F R B L U D`` order.
    uv : (..., 2) float
        Continuous face pixel coordinates (centres at integer + 0.5); values
        outside [0, S] extend the face plane.
    face_size : int

    Returns
    -------
    rays : (..., 3) float, unit norm

    Examples
    --------
    >>> cube_to_ray(4, [4.0, 4.0], 8) + 0.0   # centre of U
    array([0., 0., 1.])
    """
    s = _face_size(face_size)
    f = np.asarray(face)
    if f.dtype.kind not in "iu" or (f.size and (f.min() < 0 or f.max() > 5)):
        raise ValueError(f"face: expected integer face indices in 0..5, got {np.unique(f)[:6].tolist()}")
    uv = float_array(uv, "uv", last=2)
    t = 2.0 * uv / s - 1.0
    f, tu, tv = np.broadcast_arrays(f, t[..., 0], t[..., 1])
    cam = np.stack([tu, tv, np.ones_like(tu)], axis=-1)
    index, sign = _to_world()
    d = np.take_along_axis(cam, index[f], axis=-1) * sign[f]  # cube_face_axes()[f] @ cam
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def ray_to_cube(rays: ArrayLike, face_size: int) -> tuple[NDArray[np.intp], Array]:
    """Rays to the face they hit and continuous pixel coordinates on it.

    Parameters
    ----------
    rays : (..., 3) float
        Non-zero directions in the panorama frame.
    face_size : int

    Returns
    -------
    face : (...,) int
        Index 0..5 (``F R B L U D``) of the face whose viewing direction is
        closest to the ray; ties on cube edges go to the x faces, then the y faces.
    uv : (..., 2) float
        Face pixel coordinates in [0, S] x [0, S].

    Convention: face frames and pixel centres as in the module docstring;
    inverse of :func:`cube_to_ray`.

    Examples
    --------
    >>> face, uv = ray_to_cube([0.0, -1.0, 0.0], 8)   # -y: centre of R
    >>> int(face), uv.tolist()
    (1, [4.0, 4.0])
    """
    s = _face_size(face_size)
    r = float_array(rays, "rays", last=3)
    # The face is picked by the dominant component of r and its sign; its camera
    # coordinates are signed components of r (the table of the module docstring,
    # i.e. cube_face_axes()[face].T @ r, written out: gathers are slow on large grids).
    x, y, z = r[..., 0], r[..., 1], r[..., 2]
    ax, ay, az = np.abs(x), np.abs(y), np.abs(z)
    k = np.where((ax >= ay) & (ax >= az), 0, np.where(ay >= az, 1, 2))
    den = np.where(k == 0, ax, np.where(k == 1, ay, az))
    if r.size and not np.all(den > 0):
        raise ValueError("rays: expected non-zero direction vectors, got a zero-length ray")
    face = np.where(k == 0, np.where(x > 0, 0, 2), np.where(k == 1, np.where(y < 0, 1, 3), np.where(z > 0, 4, 5)))
    cu = np.where(k == 0, -y * np.sign(x), np.where(k == 1, x * np.sign(y), -y))
    cv = np.where(k == 2, x * np.sign(z), -z)
    half = 0.5 * s
    uv = np.stack([half * (cu / den + 1.0), half * (cv / den + 1.0)], axis=-1)
    return face, np.clip(uv, 0.0, float(s), out=uv)


# ----------------------------------------------------------------------------------------------
# layouts

def _check_face(face: ArrayLike, name: str) -> np.ndarray:
    a = np.asarray(face)
    if a.ndim not in (2, 3) or (a.ndim == 3 and a.shape[2] not in (1, 3, 4)):
        raise ValueError(f"{name}: expected (S, S) or (S, S, C) with C in (1, 3, 4), got shape {a.shape}")
    if a.dtype.kind not in "uif" or a.dtype == np.bool_:
        raise ValueError(f"{name}: expected an integer or float dtype, got {a.dtype}")
    if a.shape[0] == 0 or a.shape[0] != a.shape[1]:
        raise ValueError(f"{name}: expected a non-empty square face, got shape {a.shape}")
    return a


def _infer_format(cubemap: object) -> str:
    if isinstance(cubemap, Mapping):
        return "dict"
    if isinstance(cubemap, (list, tuple)):
        return "list"
    a = np.asarray(cubemap)
    if a.ndim == 4 and a.shape[0] == 6:
        return "list"
    if a.ndim in (2, 3) and a.shape[0] > 0 and a.shape[1] == 6 * a.shape[0]:
        return "horizon"
    if a.ndim in (2, 3) and a.shape[0] > 0 and 3 * a.shape[1] == 4 * a.shape[0]:
        return "dice"
    raise ValueError(f"cubemap: expected a list or dict of 6 faces, a (S, 6S) strip or a (3S, 4S) dice, "
                     f"got {type(cubemap).__name__} of shape {getattr(a, 'shape', None)}")


def cubemap_faces(cubemap: Cubemap, cube_format: CubeFormat | None = None) -> list[np.ndarray]:
    """Split a cubemap in any layout into its 6 faces (``F R B L U D``).

    Parameters
    ----------
    cubemap : list, dict or array
        See the module docstring for the layouts; a ``(6, S, S[, C])`` array
        counts as a list.
    cube_format : {"list", "dict", "horizon", "dice"}, optional
        Inferred from the type and shape when omitted.

    Returns
    -------
    faces : list of 6 (S, S[, C]) arrays, all of one shape and dtype
        Views into ``cubemap`` where possible.
    """
    fmt = _infer_format(cubemap) if cube_format is None else cube_format
    if fmt not in _FORMATS:
        raise ValueError(f"cube_format: expected one of {list(_FORMATS)}, got {fmt!r}")
    if fmt == "dict":
        if not isinstance(cubemap, Mapping) or sorted(cubemap) != sorted(FACE_NAMES):
            got = sorted(cubemap) if isinstance(cubemap, Mapping) else type(cubemap).__name__
            raise ValueError(f"cubemap: expected a dict with keys {list(FACE_NAMES)}, got {got}")
        faces = [np.asarray(cubemap[k]) for k in FACE_NAMES]
    elif fmt == "list":
        if isinstance(cubemap, np.ndarray) and cubemap.ndim in (3, 4):
            cubemap = list(cubemap)
        if not isinstance(cubemap, (list, tuple)) or len(cubemap) != 6:
            got = f"{len(cubemap)} items" if isinstance(cubemap, (list, tuple)) else type(cubemap).__name__
            raise ValueError(f"cubemap: expected a list of 6 faces (F R B L U D), got {got}")
        faces = [np.asarray(f) for f in cubemap]
    else:
        a = np.asarray(cubemap)
        if a.ndim not in (2, 3) or a.shape[0] == 0:
            raise ValueError(f"cubemap: expected a 2D or 3D {fmt} image, got shape {a.shape}")
        h, w = a.shape[:2]
        if fmt == "horizon":
            if w != 6 * h:
                raise ValueError(f"cubemap: expected a horizon strip of shape (S, 6S), got {a.shape}")
            faces = [a[:, k * h:(k + 1) * h] for k in range(6)]
        else:
            if h % 3 or 3 * w != 4 * h:
                raise ValueError(f"cubemap: expected a dice of shape (3S, 4S), got {a.shape}")
            s = h // 3
            faces = [a[r * s:(r + 1) * s, c * s:(c + 1) * s] for c, r in _DICE_CELLS]
    faces = [_check_face(f, f"face {n}") for f, n in zip(faces, FACE_NAMES)]
    first = faces[0]
    for f, n in zip(faces, FACE_NAMES):
        if f.shape != first.shape or f.dtype != first.dtype:
            raise ValueError(f"face {n}: expected shape {first.shape} and dtype {first.dtype} like face F, "
                             f"got {f.shape} {f.dtype}")
    return faces


@overload
def faces_to_cubemap(faces: Sequence[np.ndarray], cube_format: Literal["list"]) -> list[np.ndarray]: ...
@overload
def faces_to_cubemap(faces: Sequence[np.ndarray], cube_format: Literal["dict"]) -> dict[str, np.ndarray]: ...
@overload
def faces_to_cubemap(faces: Sequence[np.ndarray], cube_format: Literal["horizon", "dice"]) -> np.ndarray: ...


def faces_to_cubemap(faces: Sequence[np.ndarray], cube_format: CubeFormat = "list") -> Cubemap:
    """Arrange 6 faces (``F R B L U D``) in a layout.

    Parameters
    ----------
    faces : sequence of 6 (S, S[, C]) arrays
    cube_format : {"list", "dict", "horizon", "dice"}

    Returns
    -------
    list, dict, (S, 6S[, C]) array or (3S, 4S[, C]) array
    """
    fs = cubemap_faces(list(faces), "list")
    if cube_format == "list":
        return fs
    if cube_format == "dict":
        return dict(zip(FACE_NAMES, fs))
    if cube_format == "horizon":
        return np.concatenate(fs, axis=1)
    if cube_format == "dice":
        s = fs[0].shape[0]
        out = np.zeros((3 * s, 4 * s) + fs[0].shape[2:], dtype=fs[0].dtype)
        for f, (c, r) in zip(fs, _DICE_CELLS):
            out[r * s:(r + 1) * s, c * s:(c + 1) * s] = f
        return out
    raise ValueError(f"cube_format: expected one of {list(_FORMATS)}, got {cube_format!r}")


# ----------------------------------------------------------------------------------------------
# equirect -> cubemap

@lru_cache(maxsize=8)
def _face_stack_rays(face_size: int) -> Array:
    """(6*S, S, 3) rays of the face pixel centres, faces stacked vertically."""
    s = face_size
    j = np.arange(s, dtype=np.float64) + 0.5
    uu, vv = np.meshgrid(j, j)
    # cube_to_ray for every face: one grid of face-camera rays, rotated by each face frame.
    cam = cube_to_ray(np.zeros(uu.shape, dtype=int), np.stack([uu, vv], axis=-1), s) @ _axes()[0]
    rays = np.concatenate([cam @ R.T for R in _axes()], axis=0)
    rays.setflags(write=False)
    return rays


@lru_cache(maxsize=8)
def _e2c_sampler(face_size: int, width: int, height: int, interpolation: Interp) -> EquirectSampler:
    uv = ray_to_pixel(_face_stack_rays(face_size), width, height)
    return EquirectSampler.from_uv(uv, width, height, interpolation)


@overload
def equirect_to_cubemap(pano: ArrayLike, face_size: int, cube_format: Literal["list"] = ...,
                        interpolation: Interp = ...) -> list[np.ndarray]: ...
@overload
def equirect_to_cubemap(pano: ArrayLike, face_size: int, cube_format: Literal["dict"],
                        interpolation: Interp = ...) -> dict[str, np.ndarray]: ...
@overload
def equirect_to_cubemap(pano: ArrayLike, face_size: int, cube_format: Literal["horizon", "dice"],
                        interpolation: Interp = ...) -> np.ndarray: ...


def equirect_to_cubemap(pano: ArrayLike, face_size: int, cube_format: CubeFormat = "list",
                        interpolation: Interp = "linear") -> Cubemap:
    """Resample a panorama into a cubemap.

    Parameters
    ----------
    pano : (H, W[, C]) array, W == 2*H
    face_size : int
        Face width and height S.
    cube_format : {"list", "dict", "horizon", "dice"}
    interpolation : {"linear", "nearest", "cubic"}

    Returns
    -------
    Faces ``F R B L U D`` in the requested layout, dtype of ``pano``. The
    sampling maps are cached per (S, W, H, interpolation).

    Convention: face orientation and pixel centres as in the module docstring;
    sampling is seam- and pole-correct (:class:`panogeom.sampling.EquirectSampler`).

    Examples
    --------
    >>> pano = np.zeros((64, 128, 3), np.uint8)
    >>> [f.shape for f in equirect_to_cubemap(pano, 16)][:2]
    [(16, 16, 3), (16, 16, 3)]
    >>> equirect_to_cubemap(pano, 16, "dice").shape
    (48, 64, 3)
    """
    img = pano_image(pano, "pano")
    s = _face_size(face_size)
    if cube_format not in _FORMATS:
        raise ValueError(f"cube_format: expected one of {list(_FORMATS)}, got {cube_format!r}")
    h, w = img.shape[:2]
    stack = _e2c_sampler(s, w, h, interpolation)(img)
    return faces_to_cubemap(list(stack.reshape((6, s, s) + stack.shape[2:])), cube_format)


# ----------------------------------------------------------------------------------------------
# cubemap -> equirect

@lru_cache(maxsize=8)
def _border_maps(face_size: int, pad: int) -> tuple[NDArray[np.intp], NDArray[np.intp], np.ndarray, np.ndarray]:
    """Where the ``pad``-pixel border of each padded face samples the unpadded face strip.

    Returns (rows, cols) of the border pixels in the padded atlas and float32
    remap coordinates into the (S, 6S) horizon strip, clamped inside the
    neighbouring face so bilinear weights never mix two faces.
    """
    s, b = face_size, pad
    p = s + 2 * b
    kk = np.arange(p)
    rr, cc = np.meshgrid(kk, kk, indexing="ij")
    ring = (rr < b) | (rr >= s + b) | (cc < b) | (cc >= s + b)
    rows1, cols1 = rr[ring], cc[ring]
    face = np.repeat(np.arange(6), len(rows1))
    # Padded index k is face pixel k - b, whose centre is at k - b + 0.5.
    uv = np.stack([np.tile(cols1, 6), np.tile(rows1, 6)], axis=1) - b + 0.5
    nface, nuv = ray_to_cube(cube_to_ray(face, uv, s), s)
    nuv = np.clip(nuv, 0.5, s - 0.5)
    map_x = (nface * s + nuv[:, 0] - 0.5).astype(np.float32)[None]
    map_y = (nuv[:, 1] - 0.5).astype(np.float32)[None]
    return np.tile(rows1, 6), face * p + np.tile(cols1, 6), map_x, map_y


@lru_cache(maxsize=8)
def _c2e_maps(face_size: int, height: int, pad: int, interpolation: Interp) -> tuple[np.ndarray, np.ndarray]:
    """float32 remap maps from every panorama pixel into the padded face atlas."""
    s = face_size
    face, uv = ray_to_cube(pixel_grid_rays(2 * height, height), s)
    if interpolation == "nearest":
        uv = np.minimum(np.floor(uv), s - 1) + 0.5
    map_x = (face * (s + 2 * pad) + pad + uv[..., 0] - 0.5).astype(np.float32)
    map_y = (pad + uv[..., 1] - 0.5).astype(np.float32)
    map_x.setflags(write=False)
    map_y.setflags(write=False)
    return map_x, map_y


def cubemap_to_equirect(cubemap: Cubemap, height: int, cube_format: CubeFormat | None = None,
                        interpolation: Interp = "linear") -> np.ndarray:
    """Resample a cubemap into an equirectangular panorama.

    Parameters
    ----------
    cubemap : list, dict or array
        Any layout of :func:`equirect_to_cubemap`.
    height : int
        Output height H; the width is 2*H.
    cube_format : {"list", "dict", "horizon", "dice"}, optional
        Inferred from the type and shape when omitted.
    interpolation : {"linear", "nearest", "cubic"}

    Returns
    -------
    pano : (H, 2H[, C]) array, dtype of the faces

    Convention: each face is padded by one pixel sampled (bilinearly, at the
    exact geometric position) from its neighbouring faces, then one
    ``cv2.remap`` over the atlas of padded faces gives seamless interpolation
    across face edges. Maps are cached per (S, H, interpolation).

    Examples
    --------
    >>> faces = [np.full((8, 8), k, np.uint8) for k in range(6)]
    >>> pano = cubemap_to_equirect(faces, 16)
    >>> pano.shape, int(pano[8, 16]), int(pano[0, 0]), int(pano[15, 0])   # F at the centre, U top, D bottom
    ((16, 32), 0, 4, 5)
    """
    cv2 = _cv2()
    faces = cubemap_faces(cubemap, cube_format)
    if isinstance(height, (bool, np.bool_)) or not isinstance(height, (int, np.integer)) or height <= 0:
        raise ValueError(f"height: expected a positive integer (the output is (H, 2H)), got {height!r}")
    h = int(height)
    flags = _flags()
    if interpolation not in flags:
        raise ValueError(f"interpolation: expected one of {sorted(flags)}, got {interpolation!r}")
    s = faces[0].shape[0]
    b = _pad_width(interpolation)
    if 6 * (s + 2 * b) > _MAX_REMAP_SIZE or 2 * h > _MAX_REMAP_SIZE:
        raise ValueError(f"cubemap: expected 6*(S+2) and 2*H below OpenCV's remap limit {_MAX_REMAP_SIZE}, "
                         f"got S={s}, H={h}")
    dtype = faces[0].dtype
    work = [f[..., 0] if f.ndim == 3 and f.shape[2] == 1 else f for f in faces]
    if dtype not in (np.uint8, np.uint16, np.int16, np.float32, np.float64):
        work = [f.astype(np.float32) for f in work]
    strip = np.concatenate(work, axis=1)
    p = s + 2 * b
    atlas = np.empty((p, 6 * p) + strip.shape[2:], dtype=strip.dtype)
    for k in range(6):
        atlas[b:b + s, k * p + b:k * p + b + s] = strip[:, k * s:(k + 1) * s]
    if interpolation != "nearest":  # nearest never reads the border
        rows, cols, bx, by = _border_maps(s, b)
        atlas[rows, cols] = cv2.remap(strip, bx, by, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)[0]
    map_x, map_y = _c2e_maps(s, h, b, interpolation)
    out = cv2.remap(atlas, map_x, map_y, flags[interpolation], borderMode=cv2.BORDER_REPLICATE)
    if out.dtype != dtype:
        out = out.astype(dtype)
    if faces[0].ndim == 3 and faces[0].shape[2] == 1:
        out = out[..., None]
    return out
