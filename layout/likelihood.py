"""Likelihoods of a scene hypothesis: ``E_s`` (surface labels with object masks) and ``E_o`` (orientation).

``E_s`` (paper Sec. 3.1) compares the surface labels of a rendered
hypothesis with the observed label map:

    E_s = 1 - N_c / N_pix

* Observed side (:func:`observe_labels`): the label map at a working
  resolution; pixels inside the detection boxes and pixels labelled 0
  (unknown / clutter) or 5 (object) are masked. ``N_pix`` is the number of
  the remaining pixels - fixed for an observation, so a hypothesis cannot
  lower its energy by masking more.
* Predicted side: the room's labels (ceiling, one wall per column, floor;
  :func:`layout.labelmap.room_boundaries`, analytic per column) with the
  silhouettes of the objects' 3D boxes as masks (:func:`box_silhouettes`,
  analytic per column). ``N_c`` counts the observed pixels whose label the
  unmasked prediction reproduces; a silhouette that covers wall pixels
  outside the detection boxes loses them - the paper's "objects placed too
  close occlude larger wall regions, which is penalised". (Dropping the
  masked predicted pixels from ``N_pix`` instead would make hiding correct
  wall pixels free, and the scale cue would vanish.) Silhouettes are not
  occluded by walls: exact in a convex room; in an L-shaped one an object
  behind a reflex corner is drawn in front of the wall that hides it.

With ``object_pixels="matched"`` (an extension, not in the paper) the
object pixels inside the detection boxes count too: an observed 0 / 5 in box
k (object k itself, labelled clutter by the labeller) is reproduced only
where object k's predicted silhouette covers it (another object's
silhouette does not explain it). The energy is then two-sided: a
silhouette too small (object too far, camera too high) leaves object pixels
uncovered, one too large spills over walls outside the box. Room labels
seen inside a box (between the legs of a chair) stay masked, since the
predicted silhouette is a box, not the model's shape.

Everything is computed per panorama column, never per pixel of every
hypothesis: in column ``j`` the room is three row intervals (ceiling above
``ceil_v``, the wall seen, floor below ``floor_v``) and an oriented box seen
from outside covers one row interval ``[top_v, bottom_v]`` (the vertical
plane of a column cuts the box in a rectangle; its extreme elevation angles
are at the rectangle's corners). Per-column cumulative counts of the
observed labels then give ``N_c`` for any batch of hypotheses with a few
gathers per column and object; overlapping silhouettes are merged per
column first. ``coverage="area"`` counts the covered fraction of a pixel
(the energy is continuous in the parameters), ``coverage="centre"`` counts a
pixel when its centre is covered, exactly as :func:`render_scene_labels`
rasterises.

``E_o`` (:class:`OrientationLikelihood`) comes from the caller - the pose CRF
of :mod:`posecrf` computes it, and layout never imports posecrf: a callable
``E_o(cls, yaws)``, or one callable or one table over yaw bins per object.

Scale (the choice made throughout :mod:`layout.sampler`): a room known up to
scale is kept fixed in shape, and the absolute scale ``lambda`` multiplies
the floor polygon, the ceiling height AND the camera height. The room's
labels are then the same for every ``lambda``; only the objects, whose
metric sizes are known, change their silhouettes, through the camera height
``lambda * camera_height``. :class:`SurfaceLikelihood` exploits this.

Convention:
    Panorama pixels and world frame of shared/CONVENTIONS.md (W == 2*H,
    ``v`` down, pixel centres at integer + 0.5; metres, z up, camera at
    ``(0, 0, camera_height)``). Object boxes: ``center`` = box centre,
    ``size = (l, w, h)`` along the front / left / up, ``yaw`` CCW from +x to
    the front. Surface labels: 0 unknown, 1 floor, 2 ceiling, 3 wall +-x,
    4 wall +-y, 5 object.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Callable, Literal, Sequence, Union

import numpy as np
from numpy.typing import ArrayLike, NDArray

from panogeom.coords import lonlat_to_pixel, pixel_grid_rays, xy_to_lon

from .labelmap import (
    CEILING,
    FLOOR,
    OBJECT,
    UNKNOWN,
    RoomBoundaries,
    check_label_map,
    column_directions,
    labels_from_boundaries,
    room_boundaries,
)

__all__ = [
    "ObjectPixels",
    "Coverage",
    "SurfaceObservation",
    "observe_labels",
    "boxes_mask",
    "Silhouettes",
    "box_silhouettes",
    "render_scene_labels",
    "SurfaceEnergy",
    "surface_energy",
    "SurfaceLikelihood",
    "surface_likelihood",
    "OrientationLikelihood",
    "orientation_likelihood",
    "yaw_bin_energy",
]

FloatArray = NDArray[np.float64]
ObjectPixels = Literal["masked", "matched"]
Coverage = Literal["area", "centre"]

# weight tables of a SurfaceObservation: 0 zeros (a column without a wall agrees nowhere), 1..4 valid
# pixels observed with that label, 5 object pixels in any box, 6 all valid pixels, 7 + k those of box k
_EVIDENCE, _VALID, _N_TABLES = 5, 6, 7
_N_LABELS = 6


def _working_width(width: int) -> int:
    try:
        w = int(width)
    except (TypeError, ValueError):
        raise ValueError(f"width: expected a positive even integer, got {width!r}") from None
    if w != width or w < 4 or w % 2:
        raise ValueError(f"width: expected an even integer >= 4 (height = width / 2), got {width!r}")
    return w


def _resample_labels(labels: NDArray[np.uint8], width: int) -> NDArray[np.uint8]:
    """Labels at ``width``: majority vote in f x f blocks for an integer factor f (ties to the
    lower label id), nearest pixel centre otherwise."""
    h_in, w_in = labels.shape
    h = width // 2
    if w_in == width:
        return labels.copy()
    if w_in % width == 0:
        f = w_in // width
        counts = np.zeros((_N_LABELS, h, width), np.int32)
        blocks = labels.reshape(h, f, width, f)
        for k in range(_N_LABELS):
            counts[k] = np.count_nonzero(blocks == k, axis=(1, 3))
        return np.argmax(counts, axis=0).astype(np.uint8)
    rows = np.minimum(((np.arange(h) + 0.5) * h_in / h).astype(np.intp), h_in - 1)
    cols = np.minimum(((np.arange(width) + 0.5) * w_in / width).astype(np.intp), w_in - 1)
    return labels[np.ix_(rows, cols)].copy()


def _box_masks(boxes: ArrayLike | None, width: int, box_width: float | None,
               planes: Sequence[ArrayLike | None] | None = None) -> NDArray[np.bool_]:
    """(K, H, W) pixel-centre masks of K panorama boxes, checked; with ``planes[k]`` ((4, 3) inward unit normals of
    great circles through the camera, e.g. ``DetectedObject.edge_planes``; or (V, 4, 3), the boxes of V views)
    box k's mask keeps only the pixels on the inner side of all of them."""
    w = _working_width(width)
    h = w // 2
    if boxes is None:
        return np.zeros((0, h, w), bool)
    b = np.asarray(boxes, dtype=np.float64)
    if b.size == 0:
        return np.zeros((0, h, w), bool)
    if b.ndim != 2 or b.shape[1] != 4 or not np.all(np.isfinite(b)):
        raise ValueError(f"boxes: expected finite (K, 4) pixel boxes (u0, v0, u1, v1), got shape {b.shape}")
    bw = float(w if box_width is None else box_width)
    if not bw > 0:
        raise ValueError(f"box_width: expected a positive width in pixels, got {box_width!r}")
    b = b * (w / bw)
    u = np.arange(w) + 0.5
    v = np.arange(h) + 0.5
    out = np.zeros((len(b), h, w), bool)
    if planes is not None and len(planes) != len(b):
        raise ValueError(f"planes: expected one (4, 3) array or None per box ({len(b)}), got {len(planes)}")
    rays = None
    for k, (u0, v0, u1, v1) in enumerate(b):
        cols = (u >= u0) & (u <= u1) if u0 <= u1 else (u >= u0) | (u <= u1)
        rows = (v >= v0) & (v <= v1)
        out[k] = rows[:, None] & cols[None, :]
        if planes is not None and planes[k] is not None:
            n = np.asarray(planes[k], dtype=np.float64)
            if n.ndim not in (2, 3) or n.shape[-2:] != (4, 3) or n.size == 0 or not np.all(np.isfinite(n)):
                raise ValueError(f"planes[{k}]: expected a finite (4, 3) or (V, 4, 3) array of plane normals, got "
                                 f"shape {n.shape}")
            n = n.reshape(-1, 3)
            if rays is None:
                rays = pixel_grid_rays(w, h)
            inside = out[k]  # only the box's pixels can be in its region
            inside[inside] = np.all(rays[inside] @ n.T >= 0.0, axis=-1)
    return out


def boxes_mask(boxes: ArrayLike | None, width: int, *, box_width: float | None = None,
               planes: Sequence[ArrayLike | None] | None = None) -> NDArray[np.bool_]:
    """Pixels of a ``W/2 x W`` panorama whose centres lie inside panorama boxes.

    Parameters
    ----------
    boxes : (K, 4) float or None
        ``(u0, v0, u1, v1)`` in pixels of a panorama ``box_width`` wide;
        ``u0 > u1`` wraps the seam.
    width : int
        Width W of the mask (even).
    box_width : float, optional
        Width of the panorama the boxes refer to (default ``width``).
    planes : sequence of (4, 3) or (V, 4, 3) float or None, optional
        Per box, the inward normals of the great circles that bound the
        region inside it (as :func:`observe_labels`' ``box_planes``); with
        (V, 4, 3), the region inside all V boxes (an object seen whole in V
        tiles lies inside each of its tile boxes).

    Returns
    -------
    mask : (W / 2, W) bool

    Convention: continuous pixel coordinates, centres at integer + 0.5.

    Examples
    --------
    >>> m = boxes_mask([[6.0, 1.0, 2.0, 3.0]], 8)  # wraps the seam
    >>> m.astype(int)
    array([[0, 0, 0, 0, 0, 0, 0, 0],
           [1, 1, 0, 0, 0, 0, 1, 1],
           [1, 1, 0, 0, 0, 0, 1, 1],
           [0, 0, 0, 0, 0, 0, 0, 0]])
    """
    return np.any(_box_masks(boxes, width, box_width, planes), axis=0)


@dataclass(frozen=True, eq=False)
class SurfaceObservation:
    """An observed label map prepared for :func:`surface_energy` (result of :func:`observe_labels`).

    Attributes
    ----------
    labels : (H, W) uint8
        The observed labels at the working resolution.
    box_mask : (H, W) bool
        Pixels inside the detection boxes.
    valid : (H, W) bool
        Pixels counted in ``N_pix``.
    n_pix : int
        ``N_pix``: ``valid.sum()``, plus (``matched``) the object pixels
        of each box counted once per box they lie in.
    object_pixels : {"masked", "matched"}
    n_boxes : int
        Number of detection boxes K (``matched``: box k is object k's).
    box_evidence : (K,) float
        ``matched``: object pixels (observed 0 / 5) in each box; else zeros.
    width, height : int
        Working resolution.
    weights : (7 + K, H, W) float
        Per-pixel weight tables: index 1..4 = valid pixels observed with that
        label (agreement with a predicted room label), 5 = object pixels in
        any box (``matched`` only), 6 = all valid pixels, 7 + k = object
        pixels of box k (``matched`` only), 0 = zeros.
    cumulative : (7 + K, H + 1, W) float
        Column-wise cumulative sums of ``weights`` from the top row.
    """

    labels: NDArray[np.uint8]
    box_mask: NDArray[np.bool_]
    valid: NDArray[np.bool_]
    n_pix: int
    object_pixels: str
    n_boxes: int
    box_evidence: FloatArray
    width: int
    height: int
    weights: FloatArray
    cumulative: FloatArray


def observe_labels(labels: ArrayLike, boxes: ArrayLike | None = None, *, box_width: float | None = None,
                   width: int = 256, object_pixels: ObjectPixels = "masked",
                   box_planes: Sequence[ArrayLike | None] | None = None) -> SurfaceObservation:
    """Prepare an observed label map and its detection boxes for ``E_s``.

    Parameters
    ----------
    labels : (H_in, W_in) uint8
        Observed surface labels (W_in == 2 * H_in, values 0..5), upright.
    boxes : (K, 4) float, optional
        Detection boxes ``(u0, v0, u1, v1)`` in pixels of a panorama
        ``box_width`` wide (default: that of ``labels``). With
        ``"matched"``, box k must be the detection of object k of the
        hypotheses.
    box_width : float, optional
    width : int
        Working width W (the map is resampled: majority vote in blocks for
        an integer factor, nearest pixel otherwise).
    object_pixels : {"masked", "matched"}
        ``"masked"`` (the paper): box pixels are excluded. ``"matched"``:
        the pixels of box k observed 0 / 5 are object k's evidence, counted
        as reproduced where object k's silhouette covers them; other box
        pixels stay excluded.
    box_planes : sequence of (4, 3) float or None, optional
        Per box, the inward normals of the four great circles that bound the
        detector's region (``detect.TileBox.edge_planes``; the panorama box
        of a turned or pitched tile's box is larger than that region): box
        k's pixels are only those inside them. None: the whole panorama box.

    Returns
    -------
    SurfaceObservation

    Examples
    --------
    >>> from layout.labelmap import render_room_labels
    >>> lab = render_room_labels([[-2, -1], [3, -1], [3, 2], [-2, 2]], 2.7, [0, 0], 1.6, 512)
    >>> obs = observe_labels(lab, [[200, 140, 260, 200]], width=128)
    >>> obs.labels.shape, bool(obs.n_pix == obs.valid.sum() == 64 * 128 - obs.box_mask.sum())
    ((64, 128), True)
    """
    lab = check_label_map(labels, "labels")
    if object_pixels not in ("masked", "matched"):
        raise ValueError(f"object_pixels: expected 'masked' or 'matched', got {object_pixels!r}")
    w = _working_width(width)
    h = w // 2
    work = _resample_labels(lab, w)
    per_box = _box_masks(boxes, w, lab.shape[1] if box_width is None else box_width, box_planes)
    in_box = np.any(per_box, axis=0)
    surface = (work >= FLOOR) & (work <= 4)
    clutter = (work == UNKNOWN) | (work == OBJECT)
    matched = object_pixels == "matched"
    k = len(per_box)
    weights = np.zeros((_N_TABLES + k, h, w))
    valid = surface & ~in_box
    if matched:
        weights[_N_TABLES:] = per_box & clutter
        weights[_EVIDENCE] = in_box & clutter
        valid = valid | (in_box & clutter)
    for lbl in range(1, 5):
        weights[lbl] = valid & (work == lbl)
    weights[_VALID] = valid
    n_pix = int(np.count_nonzero(surface & ~in_box)) + (int(weights[_N_TABLES:].sum()) if matched else 0)
    cumulative = np.zeros((_N_TABLES + k, h + 1, w))
    np.cumsum(weights, axis=1, out=cumulative[:, 1:])
    box_evidence = weights[_N_TABLES:].sum(axis=(1, 2))
    for a in (work, in_box, valid, weights, cumulative, box_evidence):
        a.setflags(write=False)
    return SurfaceObservation(labels=work, box_mask=in_box, valid=valid, n_pix=n_pix, object_pixels=object_pixels,
                              n_boxes=k, box_evidence=box_evidence, width=w, height=h, weights=weights,
                              cumulative=cumulative)


# --------------------------------------------------------------------------- silhouettes


def _lat_to_row(width: int, height: int) -> tuple[float, float]:
    """(v at lat = 0, dv / dlat) of the equirectangular map, from :func:`lonlat_to_pixel`."""
    v = lonlat_to_pixel(np.array([[0.0, 0.0], [0.0, 1.0]]), width, height)[:, 1]
    return float(v[0]), float(v[1] - v[0])


def _lon_to_col(width: int, height: int) -> tuple[float, float]:
    """(u at lon = 0, du / dlon) of the equirectangular map, from :func:`lonlat_to_pixel`."""
    u = lonlat_to_pixel(np.array([[0.0, 0.0], [1.0, 0.0]]), width, height)[:, 0]
    return float(u[0]), float(u[1] - u[0])


@lru_cache(maxsize=8)
def _column_geometry(width: int) -> tuple[FloatArray, float, float, float, float]:
    """Per working width: column directions (W, 2) and the affine lon -> u, lat -> v maps (cached)."""
    h = width // 2
    _, direction = column_directions(width)
    direction.setflags(write=False)
    u0, ku = _lon_to_col(width, h)
    v0, kv = _lat_to_row(width, h)
    return direction, u0, ku, v0, kv


@dataclass(frozen=True, eq=False)
class Silhouettes:
    """Per-column row intervals covered by oriented 3D boxes (result of :func:`box_silhouettes`).

    Sparse: one entry per (hypothesis, object, column) whose column meets
    the box - a box covers a small part of the columns, so this is far
    smaller than dense ``(..., N, W)`` arrays (see :meth:`dense`).

    Attributes (K = entries)
    ----------
    batch_shape : tuple of int
        Batch axes ``...`` of the hypotheses.
    n_objects : int
        N.
    hypothesis : (K,) int
        Flat (C-order) index into ``batch_shape``; entries are sorted by it.
    obj, col : (K,) int
        Object index and panorama column.
    top_v, bottom_v : (K,) float
        Continuous rows of the highest and lowest point of the box seen in
        the column (``top_v <= bottom_v``).
    inside : (..., N) bool
        The camera's vertical axis passes through the box footprint (the
        box then surrounds a pole; physically invalid).
    width, height : int

    Convention: rows ``v`` down, pixel centres at integer + 0.5; a pixel of
    row ``i`` in the column is covered when ``top_v <= i + 0.5 <= bottom_v``.
    """

    batch_shape: tuple[int, ...]
    n_objects: int
    hypothesis: NDArray[np.intp]
    obj: NDArray[np.intp]
    col: NDArray[np.intp]
    top_v: FloatArray
    bottom_v: FloatArray
    inside: NDArray[np.bool_]
    width: int
    height: int

    def dense(self) -> tuple[FloatArray, FloatArray, NDArray[np.bool_]]:
        """``(top_v, bottom_v, hit)``, each ``(..., N, W)``; rows are 0 where ``hit`` is False."""
        b = int(np.prod(self.batch_shape, dtype=np.int64))
        shape = (b, self.n_objects, self.width)
        top, bottom, hit = np.zeros(shape), np.zeros(shape), np.zeros(shape, bool)
        at = (self.hypothesis, self.obj, self.col)
        top[at], bottom[at], hit[at] = self.top_v, self.bottom_v, True
        full = self.batch_shape + (self.n_objects, self.width)
        return top.reshape(full), bottom.reshape(full), hit.reshape(full)


def _box_arrays(centers: ArrayLike, sizes: ArrayLike, yaws: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
    c = np.asarray(centers, dtype=np.float64)
    s = np.asarray(sizes, dtype=np.float64)
    y = np.asarray(yaws, dtype=np.float64)
    if c.ndim < 2 or c.shape[-1] != 3:
        raise ValueError(f"centers: expected shape (..., N, 3), got {c.shape}")
    n = c.shape[-2]
    if s.ndim < 2 or s.shape[-2:] != (n, 3):
        raise ValueError(f"sizes: expected shape ({n}, 3) or (..., {n}, 3), got {s.shape}")
    if y.ndim < 1 or y.shape[-1] != n:
        raise ValueError(f"yaws: expected shape (..., {n}), got {y.shape}")
    for name, a in (("centers", c), ("sizes", s), ("yaws", y)):
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{name}: expected finite values, got NaN or inf")
    if np.any(s <= 0):
        raise ValueError(f"sizes: expected (l, w, h) > 0, got min {float(s.min())}")
    return c, s, y


def _ranges(start: NDArray[np.intp], count: NDArray[np.intp]) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Concatenated ``arange(start[i], start[i] + count[i])``: (owner i, value) per element."""
    owner = np.repeat(np.arange(len(count)), count)
    first = np.cumsum(count) - count
    return owner, start[owner] + (np.arange(len(owner)) - first[owner])


def box_silhouettes(centers: ArrayLike, sizes: ArrayLike, yaws: ArrayLike, camera_height: ArrayLike,
                    width: int) -> Silhouettes:
    """Analytic per-column silhouettes of oriented 3D boxes seen from the camera, batched.

    The columns a box can cover lie between the longitudes of its footprint
    corners. For such a column ``j`` (horizontal direction ``d_j``) the ray
    ``t * d_j`` from the camera axis enters the footprint at ``t = r_near``
    and leaves at ``r_far`` (slab test in the box's frame); the vertical
    plane of the column cuts the box in ``[r_near, r_far] x [z0, z1]``,
    whose elevation angles seen from ``(0, camera_height)`` are extreme at
    its corners.

    Parameters
    ----------
    centers : (..., N, 3) float
        Box centres, world metres.
    sizes : (N, 3) or (..., N, 3) float
        ``(l, w, h)``, metres.
    yaws : (..., N) float
        Radians, CCW from +x to each box's front.
    camera_height : (...) float
        Camera centre above the floor per hypothesis, metres.
    width : int
        Panorama width W (even).

    Returns
    -------
    Silhouettes

    Convention: see the module docstring (camera at ``(0, 0, camera_height)``).

    Examples
    --------
    >>> sil = box_silhouettes([[2.0, 0.0, 0.5]], [[1.0, 1.0, 1.0]], [0.0], 1.0, 64)
    >>> top, bottom, hit = sil.dense()
    >>> j = 32  # the centre column looks along +x; the box top is at camera height: row H / 2
    >>> bool(hit[0, j]), round(float(top[0, j]), 3), round(float(bottom[0, j]), 2)
    (True, 16.0, 21.98)
    >>> round(16 + float(np.arctan(1 / 1.5)) * 32 / np.pi, 2)  # the near bottom edge, 1.5 m away and 1 m down
    21.99
    >>> int(hit[0].sum())  # column centres within +-atan(0.5 / 1.5) = 18.4 deg of +x, 5.625 deg apart
    6
    """
    w = _working_width(width)
    h = w // 2
    c, s, y = _box_arrays(centers, sizes, yaws)
    cam_h = np.asarray(camera_height, dtype=np.float64)
    if not np.all(np.isfinite(cam_h)) or np.any(cam_h <= 0):
        raise ValueError(f"camera_height: expected finite values > 0, got {camera_height!r}")
    n = c.shape[-2]
    lead = np.broadcast_shapes(c.shape[:-2], s.shape[:-2], y.shape[:-1], cam_h.shape)
    nb = int(np.prod(lead, dtype=np.int64))
    c = np.broadcast_to(c, lead + (n, 3)).reshape(nb * n, 3)
    s = np.broadcast_to(s, lead + (n, 3)).reshape(nb * n, 3)
    y = np.broadcast_to(y, lead + (n,)).reshape(nb * n)
    ch = np.repeat(np.broadcast_to(cam_h, lead).reshape(nb), n)
    cos, sin = np.cos(y), np.sin(y)
    hl, hw = 0.5 * s[:, 0], 0.5 * s[:, 1]
    # camera axis in each box's frame; inside the footprint = the box surrounds a pole
    ox = -(c[:, 0] * cos + c[:, 1] * sin)
    oy = c[:, 0] * sin - c[:, 1] * cos
    inside = (np.abs(ox) < hl) & (np.abs(oy) < hw)
    # candidate columns: between the extreme corner longitudes (plus one column of slack)
    lx_c = np.array([1.0, 1.0, -1.0, -1.0])[None, :] * hl[:, None]
    ly_c = np.array([-1.0, 1.0, 1.0, -1.0])[None, :] * hw[:, None]
    px = c[:, 0, None] + cos[:, None] * lx_c - sin[:, None] * ly_c
    py = c[:, 1, None] + sin[:, None] * lx_c + cos[:, None] * ly_c
    lon_c = xy_to_lon(c[:, :2])
    rel = np.angle(np.exp(1j * (xy_to_lon(np.stack([px, py], axis=-1)) - lon_c[:, None])))
    direction, u0, ku, v0, kv = _column_geometry(w)
    first = np.floor(u0 + ku * (lon_c + rel.min(axis=1)) - 0.5).astype(np.intp) - 1
    last = np.ceil(u0 + ku * (lon_c + rel.max(axis=1)) - 0.5).astype(np.intp) + 1
    count = np.where(inside, w, np.minimum(last - first + 1, w))
    first = np.where(inside, 0, first)
    owner, col = _ranges(first, count)
    col %= w
    # slab test of the column rays against each footprint
    dx, dy = direction[col, 0], direction[col, 1]
    co, si = cos[owner], sin[owner]
    lx = dx * co + dy * si
    ly = dy * co - dx * si
    tiny = 1e-12
    lx = np.where(np.abs(lx) < tiny, np.where(lx < 0, -tiny, tiny), lx)
    ly = np.where(np.abs(ly) < tiny, np.where(ly < 0, -tiny, tiny), ly)
    oxo, oyo, hlo, hwo = ox[owner], oy[owner], hl[owner], hw[owner]
    ax, bx = (-hlo - oxo) / lx, (hlo - oxo) / lx
    ay, by = (-hwo - oyo) / ly, (hwo - oyo) / ly
    t_near = np.maximum(np.minimum(ax, bx), np.minimum(ay, by))
    t_far = np.minimum(np.maximum(ax, bx), np.maximum(ay, by))
    hit = (t_far > t_near) & (t_far > 0)
    owner, col, t_near, t_far = owner[hit], col[hit], np.maximum(t_near[hit], 0.0), t_far[hit]
    a1 = c[owner, 2] + 0.5 * s[owner, 2] - ch[owner]  # box top relative to the camera
    a0 = c[owner, 2] - 0.5 * s[owner, 2] - ch[owner]
    lat_top = np.arctan2(a1, np.where(a1 > 0, t_near, t_far))
    lat_bot = np.arctan2(a0, np.where(a0 < 0, t_near, t_far))
    return Silhouettes(batch_shape=tuple(lead), n_objects=n, hypothesis=owner // n, obj=owner % n, col=col,
                       top_v=v0 + kv * lat_top, bottom_v=v0 + kv * lat_bot,
                       inside=inside.reshape(lead + (n,)), width=w, height=h)


def render_scene_labels(floor: ArrayLike, ceiling_z: float, camera_height: float, centers: ArrayLike | None = None,
                        sizes: ArrayLike | None = None, yaws: ArrayLike | None = None, *, width: int = 256,
                        object_label: int = OBJECT) -> NDArray[np.uint8]:
    """Surface labels of a room with boxes: what ``E_s`` compares with the observation.

    Parameters
    ----------
    floor : (M, 2) float
        Floor polygon, metres, around the camera at the origin.
    ceiling_z, camera_height : float
        Metres.
    centers, sizes, yaws : (N, 3), (N, 3), (N,) float, optional
        Object boxes; their pixels (centre rule) get ``object_label``.
    width : int
    object_label : int
        0..5 (5 = object; 0 renders objects as clutter).

    Returns
    -------
    labels : (W / 2, W) uint8

    Examples
    --------
    >>> lab = render_scene_labels([[-2, -2], [2, -2], [2, 2], [-2, 2]], 2.5, 1.5,
    ...                           [[1.5, 0.0, 0.4]], [[0.4, 1.0, 0.8]], [0.0], width=64)
    >>> int(lab[20, 32]), int(lab[20, 0]), sorted(np.unique(lab).tolist())
    (5, 3, [1, 2, 3, 4, 5])
    """
    w = _working_width(width)
    if not 0 <= int(object_label) <= 5:
        raise ValueError(f"object_label: expected a label id 0..5, got {object_label!r}")
    b = room_boundaries(floor, ceiling_z, [0.0, 0.0], camera_height, w)
    if not bool(b.valid):
        raise ValueError("floor: expected a polygon around the camera at the origin, got one that some columns miss")
    lab = labels_from_boundaries(b)
    if centers is None:
        return lab
    c, s, y = _box_arrays(centers, sizes, yaws)  # type: ignore[arg-type]
    if c.ndim != 2:
        raise ValueError(f"centers: expected a single hypothesis (N, 3), got {c.shape}")
    sil = box_silhouettes(c, s, y, camera_height, w)
    rows = np.arange(w // 2) + 0.5
    for j, t, bt in zip(sil.col, sil.top_v, sil.bottom_v):
        lab[(rows >= t) & (rows <= bt), j] = np.uint8(object_label)
    return lab


# --------------------------------------------------------------------------- E_s


@dataclass(frozen=True)
class SurfaceEnergy:
    """``E_s`` of a batch of hypotheses (result of :func:`surface_energy`).

    Attributes (``...`` = batch axes)
    ----------
    energy : (...) float
        ``1 - n_correct / n_pix`` in [0, 1].
    n_correct : (...) float
        ``N_c``: observed pixels reproduced by the masked prediction
        (fractional with ``coverage="area"``).
    n_pix : int
        ``N_pix`` of the observation.
    covered : (...) float
        Counted pixels under the predicted silhouettes.
    object_coverage : (..., N) float or None
        ``object_pixels="matched"`` only: the fraction of box k's object
        pixels that object k's silhouette covers (1 for a box without
        object pixels).
    """

    energy: FloatArray
    n_correct: FloatArray
    n_pix: int
    covered: FloatArray
    object_coverage: FloatArray | None = None


def _cum_eval(obs: SurfaceObservation, table: NDArray[np.intp] | int, v: FloatArray, col: NDArray[np.intp],
              coverage: str) -> FloatArray:
    """Cumulative weight of table ``table`` in column ``col`` from the top down to row ``v``.

    ``coverage="area"``: pixel fractions (linear inside a pixel);
    ``"centre"``: pixels whose centre is above ``v``.
    """
    h, w = obs.height, obs.width
    if coverage == "area":
        vc = np.clip(v, 0.0, float(h))
        i = np.minimum(vc.astype(np.intp), h - 1)
        base = obs.cumulative.ravel()[(table * (h + 1) + i) * w + col]
        return base + (vc - i) * obs.weights.ravel()[(table * h + i) * w + col]
    i = np.clip(np.ceil(v - 0.5), 0, h).astype(np.intp)
    return obs.cumulative.ravel()[(table * (h + 1) + i) * w + col]


def _room_correct(obs: SurfaceObservation, ceil_v: FloatArray, floor_v: FloatArray,
                  wall: NDArray[np.intp], coverage: str) -> FloatArray:
    """Agreeing pixels per column of the unmasked room prediction, (..., W)."""
    col = np.broadcast_to(np.arange(obs.width), ceil_v.shape)
    h = np.full(ceil_v.shape, float(obs.height))
    zero = np.zeros(ceil_v.shape)

    def span(table: NDArray[np.intp] | int, a: FloatArray, b: FloatArray) -> FloatArray:
        return _cum_eval(obs, table, b, col, coverage) - _cum_eval(obs, table, a, col, coverage)

    return span(CEILING, zero, ceil_v) + span(wall, ceil_v, floor_v) + span(FLOOR, floor_v, h)


def _merge_intervals(key: NDArray[np.intp], s: FloatArray, e: FloatArray, span: float) -> tuple[FloatArray, FloatArray]:
    """Make the row intervals that share a key (hypothesis, column) disjoint; their union keeps its measure.

    Intervals of a key are sorted by top row and each is cut to start after
    the running maximum of the previous bottoms. Rows lie in [0, span]; the
    running maximum is taken over ``row + key * 4 * span`` so that it never
    crosses from one key into the next. Only keys with two or more intervals
    are touched.
    """
    counts = np.bincount(key)
    multi = counts[key] >= 2
    if not np.any(multi):
        return s, e
    idx = np.flatnonzero(multi)
    off = key[idx].astype(np.float64) * (4.0 * span)
    ss, ee = s[idx] + off, e[idx] + off  # one float sort key: by key, then by top row
    order = np.argsort(ss)
    idx, off, ss, ee = idx[order], off[order], ss[order], ee[order]
    run = np.maximum.accumulate(ee)
    prev = np.concatenate([[-np.inf], run[:-1]])
    ss, ee = ss - off, ee - off
    prev = prev - off
    eff_s = np.maximum(ss, prev)
    eff_e = np.maximum(ee, eff_s)
    s, e = s.copy(), e.copy()
    s[idx], e[idx] = eff_s, eff_e
    return s, e


def _lead_index(shape: tuple[int, ...], lead: tuple[int, ...]) -> NDArray[np.intp]:
    """For every flat position of ``lead``, the flat index into ``shape`` broadcast to it."""
    n = int(np.prod(shape, dtype=np.int64))
    return np.broadcast_to(np.arange(n).reshape(shape), lead).ravel()


def surface_energy(observation: SurfaceObservation, boundaries: RoomBoundaries,
                   silhouettes: Silhouettes | None = None, *, coverage: Coverage = "area") -> SurfaceEnergy:
    """``E_s = 1 - N_c / N_pix`` for a batch of scene hypotheses.

    Parameters
    ----------
    observation : SurfaceObservation
        From :func:`observe_labels`.
    boundaries : RoomBoundaries
        Predicted room per column (:func:`layout.labelmap.room_boundaries`
        at the observation's width), batch axes ``...R``.
    silhouettes : Silhouettes, optional
        Predicted object masks (:func:`box_silhouettes`), batch axes
        ``...S`` broadcast against ``...R``.
    coverage : {"area", "centre"}
        Count covered pixel fractions (continuous energy) or pixel centres
        (equal to counting on :func:`render_scene_labels`).

    Returns
    -------
    SurfaceEnergy
        Batch axes ``broadcast(...R, ...S)``.

    Examples
    --------
    >>> from layout.labelmap import render_room_labels
    >>> room = [[-2, -1], [3, -1], [3, 2], [-2, 2]]
    >>> obs = observe_labels(render_room_labels(room, 2.7, [0, 0], 1.6, 128), width=128)
    >>> b = room_boundaries(room, 2.7, [0, 0], 1.6, 128, scale=[1.0, 1.2])  # right room, and 20 % too large
    >>> e = surface_energy(obs, b, coverage="centre")
    >>> float(e.energy[0]), bool(e.energy[1] > 0.01)
    (0.0, True)
    """
    if coverage not in ("area", "centre"):
        raise ValueError(f"coverage: expected 'area' or 'centre', got {coverage!r}")
    return _surface_energy(observation, boundaries, silhouettes, coverage, None)


def _surface_energy(obs: SurfaceObservation, boundaries: RoomBoundaries, silhouettes: Silhouettes | None,
                    coverage: str, room_total: FloatArray | float | None) -> SurfaceEnergy:
    """:func:`surface_energy`, with the room's ``N_c`` given when it is known (a fixed room)."""
    w = obs.width
    if boundaries.width != w:
        raise ValueError(f"boundaries: expected width {w} (the observation's), got {boundaries.width}")
    room_lead = tuple(boundaries.floor_v.shape[:-1])
    lead = room_lead
    if silhouettes is not None:
        if silhouettes.width != w:
            raise ValueError(f"silhouettes: expected width {w} (the observation's), got {silhouettes.width}")
        lead = tuple(np.broadcast_shapes(room_lead, silhouettes.batch_shape))
    n_lead = int(np.prod(lead, dtype=np.int64))
    wall = boundaries.wall_label.astype(np.intp)
    if room_total is None:
        room_total = _room_correct(obs, boundaries.ceil_v, boundaries.floor_v, wall, coverage).sum(axis=-1)
    n_correct = np.broadcast_to(room_total, lead).astype(np.float64)
    covered = np.zeros(lead)
    object_coverage = None
    if obs.object_pixels == "matched" and silhouettes is not None:
        if silhouettes.n_objects != obs.n_boxes:
            raise ValueError(f"silhouettes: expected one object per detection box ({obs.n_boxes}) with "
                             f"object_pixels='matched', got {silhouettes.n_objects} objects")
        object_coverage = np.where(obs.box_evidence > 0, 0.0, 1.0) * np.ones(lead + (silhouettes.n_objects,))
    if silhouettes is not None and len(silhouettes.col):
        sil = silhouettes
        # the entries of every lead position (replicated where the silhouettes broadcast)
        if tuple(sil.batch_shape) == lead:
            pos, ent = sil.hypothesis, np.arange(len(sil.col))
        else:
            n_sil = int(np.prod(sil.batch_shape, dtype=np.int64))
            per = np.bincount(sil.hypothesis, minlength=n_sil)
            start = np.cumsum(per) - per
            of_lead = _lead_index(tuple(sil.batch_shape), lead)
            pos, ent = _ranges(start[of_lead], per[of_lead])
        col = sil.col[ent]
        if obs.object_pixels == "matched":  # each object's own evidence, before merging the intervals
            obj = sil.obj[ent]
            ev = _N_TABLES + obj
            gained = _cum_eval(obs, ev, sil.bottom_v[ent], col, coverage) - _cum_eval(obs, ev, sil.top_v[ent], col,
                                                                                       coverage)
            n_correct = n_correct + np.bincount(pos, weights=gained, minlength=n_lead).reshape(lead)
            n_obj = sil.n_objects
            per_obj = np.bincount(pos * n_obj + obj, weights=gained, minlength=n_lead * n_obj)
            object_coverage = np.where(obs.box_evidence > 0, per_obj.reshape(lead + (n_obj,))
                                       / np.maximum(obs.box_evidence, 1e-12), 1.0)
        s, e = _merge_intervals(pos * w + col, sil.top_v[ent], sil.bottom_v[ent], float(obs.height))
        keep = e > s
        pos, col, s, e = pos[keep], col[keep], s[keep], e[keep]
        room_pos = _lead_index(room_lead, lead)[pos] * w + col
        cv = boundaries.ceil_v.reshape(-1)[room_pos]
        fv = boundaries.floor_v.reshape(-1)[room_pos]
        wl = wall.reshape(-1)[room_pos]

        def span(table: NDArray[np.intp] | int, a: FloatArray, b: FloatArray) -> FloatArray:
            return _cum_eval(obs, table, b, col, coverage) - _cum_eval(obs, table, a, col, coverage)

        lost = (span(CEILING, np.minimum(s, cv), np.minimum(e, cv))
                + span(wl, np.clip(s, cv, fv), np.clip(e, cv, fv))
                + span(FLOOR, np.maximum(s, fv), np.maximum(e, fv)))
        counted = span(_VALID, s, e)
        n_correct = n_correct - np.bincount(pos, weights=lost, minlength=n_lead).reshape(lead)
        covered = np.bincount(pos, weights=counted, minlength=n_lead).reshape(lead)
    n_pix = obs.n_pix
    energy = 1.0 - n_correct / n_pix if n_pix > 0 else np.ones(lead)
    return SurfaceEnergy(energy=np.asarray(energy, dtype=np.float64), n_correct=np.asarray(n_correct),
                         n_pix=n_pix, covered=np.asarray(covered), object_coverage=object_coverage)


@dataclass(frozen=True, eq=False)
class SurfaceLikelihood:
    """``E_s`` for a room known up to scale, evaluated for object and scale hypotheses.

    Built by :func:`surface_likelihood`. The room (floor, ceiling, camera
    height at scale 1) is fixed; a hypothesis is a set of metric object
    boxes and a scale ``lambda`` that multiplies the room AND the camera
    height (so the room's labels do not change, see the module docstring).

    Attributes
    ----------
    observation : SurfaceObservation
    floor : (M, 2) float
        Floor polygon at scale 1, metres, around the camera at the origin.
    ceiling_z, camera_height : float
        Ceiling and camera height at scale 1, metres.
    boundaries : RoomBoundaries
        The room's per-column boundaries at the working width.
    coverage : {"area", "centre"}
    room_correct : float
        ``N_c`` of the room without objects (cached).
    """

    observation: SurfaceObservation
    floor: FloatArray
    ceiling_z: float
    camera_height: float
    boundaries: RoomBoundaries
    coverage: str
    room_correct: float

    def __call__(self, centers: ArrayLike, sizes: ArrayLike, yaws: ArrayLike,
                 scale: ArrayLike = 1.0) -> SurfaceEnergy:
        """``E_s`` of boxes ``centers (..., N, 3)``, ``sizes (N, 3)``, ``yaws (..., N)`` at ``scale (...)``."""
        lam = np.asarray(scale, dtype=np.float64)
        if not np.all(np.isfinite(lam)) or np.any(lam <= 0):
            raise ValueError(f"scale: expected finite values > 0, got {scale!r}")
        sil = box_silhouettes(centers, sizes, yaws, lam * self.camera_height, self.observation.width)
        return _surface_energy(self.observation, self.boundaries, sil, self.coverage, self.room_correct)


def surface_likelihood(observation: SurfaceObservation, floor: ArrayLike, ceiling_z: float, camera_height: float,
                       *, coverage: Coverage = "area") -> SurfaceLikelihood:
    """Prepare ``E_s`` for a room up to scale (floor, ceiling, camera height at scale 1).

    Parameters
    ----------
    observation : SurfaceObservation
    floor : (M, 2) float
        Floor polygon around the camera at the origin, metres at scale 1.
    ceiling_z, camera_height : float
        Metres at scale 1.
    coverage : {"area", "centre"}

    Returns
    -------
    SurfaceLikelihood

    Examples
    --------
    >>> from layout.labelmap import render_room_labels
    >>> room = [[-2, -1], [3, -1], [3, 2], [-2, 2]]
    >>> obs = observe_labels(render_room_labels(room, 2.7, [0, 0], 1.6, 128), width=128)
    >>> es = surface_likelihood(obs, room, 2.7, 1.6)
    >>> e = es([[[2.5, 0.0, 0.4]], [[1.5, 0.0, 0.4]]], [[0.4, 1.0, 0.8]], [[0.0], [0.0]])
    >>> bool(0 < e.energy[0] < e.energy[1])  # the closer box hides more of the wall
    True
    """
    if not float(ceiling_z) > float(camera_height) > 0:
        raise ValueError(f"expected 0 < camera_height < ceiling_z, got camera_height={camera_height}, "
                         f"ceiling_z={ceiling_z}")
    b = room_boundaries(floor, ceiling_z, [0.0, 0.0], camera_height, observation.width)
    if not bool(b.valid):
        raise ValueError("floor: expected a polygon around the camera at the origin, got one that some columns miss")
    if coverage not in ("area", "centre"):
        raise ValueError(f"coverage: expected 'area' or 'centre', got {coverage!r}")
    room = _room_correct(observation, b.ceil_v, b.floor_v, b.wall_label.astype(np.intp), coverage)
    poly = np.array(floor, dtype=np.float64)
    poly.setflags(write=False)
    return SurfaceLikelihood(observation=observation, floor=poly, ceiling_z=float(ceiling_z),
                             camera_height=float(camera_height), boundaries=b, coverage=coverage,
                             room_correct=float(room.sum()))


# --------------------------------------------------------------------------- E_o


YawEnergy = Callable[[FloatArray], ArrayLike]
OrientationSpec = Union[None, Callable[[str, FloatArray], ArrayLike], Sequence[Union[YawEnergy, ArrayLike, None]]]


def yaw_bin_energy(energies: ArrayLike) -> YawEnergy:
    """A yaw -> energy function from a table over uniform yaw bins (linear, wrapping).

    Parameters
    ----------
    energies : (K,) float
        Energy of bin k, centred at yaw ``2 pi k / K``; K >= 2.

    Returns
    -------
    callable
        ``f(yaws (...)) -> (...)``.

    Examples
    --------
    >>> f = yaw_bin_energy([0.0, 1.0, 2.0, 1.0])  # bins at 0, 90, 180, 270 degrees
    >>> f(np.radians([0.0, 45.0, 180.0, 315.0, 360.0])).tolist()
    [0.0, 0.5, 2.0, 0.5, 0.0]
    """
    table = np.asarray(energies, dtype=np.float64)
    if table.ndim != 1 or len(table) < 2 or not np.all(np.isfinite(table)):
        raise ValueError(f"energies: expected a finite (K,) table with K >= 2, got shape {table.shape}")
    table = table.copy()
    table.setflags(write=False)
    k = len(table)

    def energy(yaws: FloatArray) -> FloatArray:
        x = np.mod(np.asarray(yaws, dtype=np.float64), 2 * np.pi) * (k / (2 * np.pi))
        i = np.floor(x).astype(np.intp) % k
        f = x - np.floor(x)
        return (1.0 - f) * table[i] + f * table[(i + 1) % k]

    return energy


@dataclass(frozen=True, eq=False)
class OrientationLikelihood:
    """``E_o``: orientation energy of each object, from the caller (built by :func:`orientation_likelihood`).

    Attributes
    ----------
    terms : tuple of callables or None
        Per object, ``f(yaws (B,)) -> (B,)`` energies; None: no term.
    """

    terms: tuple[YawEnergy | None, ...]

    def per_object(self, yaws: ArrayLike) -> FloatArray:
        """``(..., N)`` energies of yaws ``(..., N)``."""
        y = np.asarray(yaws, dtype=np.float64)
        n = len(self.terms)
        if y.ndim < 1 or y.shape[-1] != n:
            raise ValueError(f"yaws: expected shape (..., {n}), got {y.shape}")
        out = np.zeros(y.shape)
        for j, f in enumerate(self.terms):
            if f is None:
                continue
            col = y[..., j]
            e = np.asarray(f(col), dtype=np.float64)
            if e.shape != col.shape or not np.all(np.isfinite(e)):
                raise ValueError(f"E_o of object {j}: expected finite energies of shape {col.shape}, "
                                 f"got shape {e.shape}")
            out[..., j] = e
        return out

    def __call__(self, yaws: ArrayLike) -> FloatArray:
        """``(...)`` total ``E_o`` of yaws ``(..., N)``."""
        return self.per_object(yaws).sum(axis=-1)


def orientation_likelihood(spec: OrientationSpec, classes: Sequence[str]) -> OrientationLikelihood:
    """Normalise the caller's ``E_o`` into an :class:`OrientationLikelihood`.

    Parameters
    ----------
    spec : None, callable or sequence
        None: ``E_o = 0``. A callable ``E_o(cls, yaws) -> energies`` applied
        to each object with its class. A sequence of one item per object:
        a callable ``f(yaws) -> energies``, a ``(K,)`` table over yaw bins
        (:func:`yaw_bin_energy`), or None.
    classes : sequence of str
        Class of each object.

    Returns
    -------
    OrientationLikelihood

    Examples
    --------
    >>> eo = orientation_likelihood([[0.0, 1.0, 2.0, 1.0], None], ["bed", "plant"])
    >>> eo([[np.pi, 1.0], [0.0, 2.0]]).tolist()
    [2.0, 0.0]
    >>> eo2 = orientation_likelihood(lambda cls, y: 1.0 - np.cos(y), ["tv"])
    >>> eo2([[np.pi]]).tolist()
    [2.0]
    """
    names = [str(c) for c in classes]
    if spec is None:
        return OrientationLikelihood(terms=tuple(None for _ in names))
    if callable(spec):
        fn = spec
        return OrientationLikelihood(terms=tuple((lambda y, c=c: fn(c, y)) for c in names))
    items = list(spec)
    if len(items) != len(names):
        raise ValueError(f"E_o: expected one term per object ({len(names)}), got {len(items)}")
    terms: list[YawEnergy | None] = []
    for it in items:
        if it is None or callable(it):
            terms.append(it)  # type: ignore[arg-type]
        else:
            terms.append(yaw_bin_energy(it))
    return OrientationLikelihood(terms=tuple(terms))
