"""Automatic grab-cut segmentation of detected objects (paper, Sec. 4).

"We extract the object in the input image by automatic grab-cut
segmentation, assuming that the image center contains the object and image
corners are part of the background." For each detection:

1. a perspective crop is rendered from the panorama, centred on the
   detection's region on the sphere and a ``margin`` wider than it, so the
   object is undistorted and the crop corners are background
   (:func:`object_view`);
2. OpenCV's ``grabCut`` is initialised from a mask: outside the detection's
   region = background, inside = probable foreground, a small ellipse at the
   region's centre = foreground (:func:`grabcut_crop`);
3. the foreground is mapped back into panorama pixels, seam-aware
   (:func:`crop_mask_to_pano`).

The crop (image and mask) is what a pose estimator wants: an undistorted view
of the object with its background removed.

Not in the paper: :func:`silhouette_box` moves a tile detection's box edges
onto the silhouette's where the two agree, for the box fits that fix the
room's scale (the pipeline's default, ``--box-edges silhouette``).

Convention: panoramas ``(H, W, 3) uint8`` RGB with W == 2*H; pixel and ray
conventions of CONVENTIONS.md through panogeom; a view at yaw ``a`` looks at
``lon = -a`` (panogeom.perspective).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from panogeom.coords import pixel_to_ray, ray_to_lonlat
from panogeom.perspective import PinholeView, equirect_to_perspective

from .detection import Detection, TileBox, check_rgb_image, tile_edge_planes
from .nms import region_boundary, region_contains
from .tiles import rays_box_in_view

__all__ = ["ObjectCrop", "object_view", "grabcut_crop", "crop_mask_to_pano", "segment_detections", "SilhouetteBox",
           "silhouette_box"]

_MAX_HALF_TAN = float(np.tan(np.deg2rad(80.0)))


def _cv2():
    try:
        import cv2
    except ImportError as exc:  # pragma: no cover - dependency of the package
        raise ImportError("detect.grabcut needs OpenCV: pip install opencv-contrib-python-headless") from exc
    return cv2


@dataclass(frozen=True, eq=False)
class ObjectCrop:
    """A perspective crop of one detected object and its grab-cut segmentation.

    Attributes
    ----------
    view : PinholeView
        Camera of the crop, pointed at the centre of the detection's region.
    image : (h, w, 3) uint8
        The crop, RGB.
    region : (h, w) bool
        The detection's region (its box footprint) in the crop.
    mask : (h, w) bool
        Grab-cut foreground.
    """

    view: PinholeView
    image: NDArray[np.uint8]
    region: NDArray[np.bool_]
    mask: NDArray[np.bool_]


def _center_ray(det: Detection) -> NDArray[np.float64]:
    if det.tile is not None:
        b = det.tile.box
        return det.tile.view.pixel_to_ray(np.array([0.5 * (b[0] + b[2]), 0.5 * (b[1] + b[3])]))
    return pixel_to_ray(det.center_px, det.pano_width, det.pano_height)


def object_view(det: Detection, max_size: int = 256, margin: float = 0.25) -> PinholeView:
    """A pinhole view centred on a detection's region, ``margin`` wider than it on each side.

    Parameters
    ----------
    det : Detection
    max_size : int
        Longest side of the crop in pixels; the crop is never sampled finer
        than the panorama (``W / (2*pi)`` pixels per radian at its centre).
    margin : float
        Extra border, as a fraction of the region's half-extent.

    Returns
    -------
    PinholeView

    Raises
    ------
    ValueError
        When the region is too wide for one pinhole view (over about 160 degrees).

    Examples
    --------
    >>> d = Detection("chair", 0.9, [1000, 600, 1100, 700], 2048, 1024)
    >>> v = object_view(d)
    >>> (v.width, v.height), round(float(np.rad2deg(v.yaw)), 3)
    ((123, 131), -4.57)
    """
    if int(max_size) < 16:
        raise ValueError(f"max_size: expected at least 16 pixels, got {max_size!r}")
    if not 0.0 <= float(margin) <= 2.0:
        raise ValueError(f"margin: expected a fraction in [0, 2], got {margin!r}")
    lon, lat = ray_to_lonlat(_center_ray(det))
    probe = PinholeView(yaw=float(-lon), pitch=float(lat), roll=0.0, fov=np.pi / 2, width=2, height=2)
    c = region_boundary(det, 32) @ probe.R
    if np.any(c[:, 2] <= 1e-6):
        raise ValueError(f"det: expected a region narrower than 180 degrees for a crop, got box {det.box.tolist()}")
    x, y = c[:, 0] / c[:, 2], c[:, 1] / c[:, 2]
    hx = float(np.abs(x).max()) * (1.0 + margin)
    hy = float(np.abs(y).max()) * (1.0 + margin)
    if max(hx, hy) > _MAX_HALF_TAN:
        raise ValueError(f"det: expected a region narrower than 160 degrees for a crop, got box {det.box.tolist()}")
    f = min(det.pano_width / (2.0 * np.pi), max_size / (2.0 * max(hx, hy)))
    w, h = max(8, int(np.ceil(2.0 * f * hx))), max(8, int(np.ceil(2.0 * f * hy)))
    return PinholeView(yaw=float(-lon), pitch=float(lat), roll=0.0, fov=float(2.0 * np.arctan(0.5 * w / f)),
                       width=w, height=h)


def grabcut_crop(pano: ArrayLike, det: Detection, *, iterations: int = 5, max_size: int = 256,
                 margin: float = 0.25, core: float = 0.15) -> ObjectCrop:
    """Render a crop around a detection and segment the object by grab-cut.

    Parameters
    ----------
    pano : (H, W, 3) uint8 RGB, W == 2*H
    det : Detection
        Must refer to a panorama of this size.
    iterations : int
        Grab-cut iterations.
    max_size, margin : see :func:`object_view`
    core : float
        Semi-axes of the central ellipse marked as sure foreground, as a
        fraction of the region's width and height in the crop.

    Returns
    -------
    ObjectCrop
    """
    cv2 = _cv2()
    img = check_rgb_image(pano, "pano")
    if img.shape[:2] != (det.pano_height, det.pano_width):
        raise ValueError(f"pano: expected size {det.pano_width}x{det.pano_height} (the detection's panorama), "
                         f"got {img.shape[1]}x{img.shape[0]}")
    if int(iterations) < 1:
        raise ValueError(f"iterations: expected a positive integer, got {iterations!r}")
    view = object_view(det, max_size, margin)
    crop = np.ascontiguousarray(equirect_to_perspective(img, view, "linear"))
    region = region_contains([det], view.grid_rays().reshape(-1, 3))[0].reshape(view.height, view.width)
    init = np.full(region.shape, cv2.GC_BGD, np.uint8)
    init[region] = cv2.GC_PR_FGD
    ys, xs = np.nonzero(region)
    if len(xs) == 0:
        raise ValueError(f"det: expected a region visible in its crop, got box {det.box.tolist()}")
    cx, cy = 0.5 * (xs.min() + xs.max() + 1), 0.5 * (ys.min() + ys.max() + 1)
    ax = max(1.0, core * 0.5 * (xs.max() + 1 - xs.min()))
    ay = max(1.0, core * 0.5 * (ys.max() + 1 - ys.min()))
    yy, xx = np.mgrid[0:view.height, 0:view.width] + 0.5
    init[(((xx - cx) / ax) ** 2 + ((yy - cy) / ay) ** 2 <= 1.0) & region] = cv2.GC_FGD
    mask = init.copy()
    cv2.setRNGSeed(0)
    bgd, fgd = np.zeros((1, 65), np.float64), np.zeros((1, 65), np.float64)
    cv2.grabCut(crop, mask, None, bgd, fgd, int(iterations), cv2.GC_INIT_WITH_MASK)
    fg = (mask == cv2.GC_FGD) | (mask == cv2.GC_PR_FGD)
    return ObjectCrop(view=view, image=crop, region=region, mask=fg)


def crop_mask_to_pano(crop: ObjectCrop, det: Detection) -> NDArray[np.bool_]:
    """Map a crop's foreground back into panorama pixels.

    Parameters
    ----------
    crop : ObjectCrop
    det : Detection
        The detection the crop was made for; only pixels inside its box are
        looked up (seam-aware).

    Returns
    -------
    mask : (H, W) bool
        A panorama pixel is set when its centre projects onto a foreground
        pixel of the crop.
    """
    W, H = det.pano_width, det.pano_height
    out = np.zeros((H, W), dtype=bool)
    u0, v0, u1, v1 = det.box
    r0, r1 = int(np.floor(v0)), min(H, int(np.ceil(v1)))
    if u1 > u0:
        cols = np.arange(int(np.floor(u0)), min(W, int(np.ceil(u1))))
    else:
        cols = np.concatenate([np.arange(int(np.floor(u0)), W), np.arange(0, min(W, int(np.ceil(u1))))])
    rows = np.arange(r0, r1)
    if len(cols) == 0 or len(rows) == 0:
        return out
    uu, vv = np.meshgrid(cols + 0.5, rows + 0.5)
    uv, front = crop.view.ray_to_pixel(pixel_to_ray(np.stack([uu, vv], -1), W, H))
    iu, iv = np.floor(uv[..., 0]).astype(np.int64), np.floor(uv[..., 1]).astype(np.int64)
    ok = front & (iu >= 0) & (iu < crop.view.width) & (iv >= 0) & (iv < crop.view.height)
    val = np.zeros(ok.shape, dtype=bool)
    val[ok] = crop.mask[iv[ok], iu[ok]]
    out[np.ix_(rows, cols)] = val
    return out


def segment_detections(pano: ArrayLike, detections: Sequence[Detection], *, iterations: int = 5,
                       max_size: int = 256, margin: float = 0.25) -> list[Detection]:
    """Grab-cut mask for every detection, in panorama pixels.

    Parameters
    ----------
    pano : (H, W, 3) uint8 RGB
    detections : sequence of Detection
    iterations, max_size, margin : see :func:`grabcut_crop`

    Returns
    -------
    list of Detection
        The same detections, in order, with ``mask`` set.
    """
    out = []
    for d in detections:
        crop = grabcut_crop(pano, d, iterations=iterations, max_size=max_size, margin=margin)
        out.append(d.with_mask(crop_mask_to_pano(crop, d)))
    return out


@dataclass(frozen=True, eq=False)
class SilhouetteBox:
    """A detection's tile boxes with their edges moved onto its grab-cut silhouette (:func:`silhouette_box`).

    Attributes
    ----------
    views : tuple of TileBox
        One per tile box of the detection (``det.views``, or ``(det.tile,)``
        when no other tile sees it whole), in the same views: each edge the
        silhouette's tight box in that view where ``snapped``, else the
        detector's.
    snapped : (V, 4) bool
        Left, top, right, bottom of each view: the edge is the silhouette's.
    """

    views: tuple[TileBox, ...]
    snapped: NDArray[np.bool_]

    def edge_planes(self) -> NDArray[np.float64]:
        """The edges as planes through the camera, as :meth:`Detection.edge_planes`: (4, 3) for one view,
        else (V, 4, 3) (:func:`~detect.detection.tile_edge_planes`)."""
        return tile_edge_planes(self.views)


def _mask_corner_rays(crop: ObjectCrop) -> NDArray[np.float64]:
    """Rays through the four corners of every boundary pixel of a crop's foreground: (K, 3)."""
    cv2 = _cv2()
    m = crop.mask.astype(np.uint8)
    cross = cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3))
    inner = cv2.erode(m, cross, borderType=cv2.BORDER_CONSTANT, borderValue=0)
    ys, xs = np.nonzero(m > inner)
    corners = np.stack([np.stack([xs + dx, ys + dy], -1) for dx in (0.0, 1.0) for dy in (0.0, 1.0)])
    return crop.view.pixel_to_ray(corners.reshape(-1, 2).astype(np.float64))


def silhouette_box(pano: ArrayLike, det: Detection, *, grow: float = 0.1, gate_deg: float = 3.0,
                   iterations: int = 5, max_size: int = 256, margin: float = 0.3) -> SilhouetteBox | None:
    """Move a tile detection's box edges onto the object's grab-cut silhouette where the two agree.

    Not in the paper (it uses grab-cut for the pose step's crops). The
    builtin detector's box edges are off by most of a degree (median absolute
    deviation 0.6-0.8 deg per edge on the synthetic tuning rooms, even as the
    median over the tiles that see the object), and the box fits that fix
    the room's scale (:mod:`layout.modelfit`) read those edges. Grab-cut
    follows the object's outline to a fraction of that, but now and then it
    bleeds into the background or loses a part; so:

    1. the detection's tile box is grown by ``grow`` of its width and height
       on each side (grab-cut cannot reach beyond its initial region, and
       the detector's box is as often too tight as too loose) and segmented
       (:func:`grabcut_crop` with ``margin``);
    2. in each view the detection has a tile box in (``det.views``, or
       ``det.tile``), the silhouette's tight box (the corners of its
       boundary pixels projected into the view) is compared with the
       detector's box, edge by edge;
    3. an edge within ``gate_deg`` of the detector's becomes the
       silhouette's, unless the silhouette reaches the grown region's
       border there (grab-cut was stopped; the outline may go on); the
       others stay the detector's.

    With the defaults the per-edge median absolute deviation falls to
    0.23-0.57 deg and the share of edges within 0.5 deg of the true outline
    rises from 0.33-0.42 to 0.40-0.70 (``benchmarks/eval_box_edges.py`` on
    the 30 rooms of seed 7000, detector run 7; docs/EVALUATION.md, "Detector
    box edges"); 10-20 % of the edges stay more than 2 deg off.
    Beds gain least (on seed 7000 their top and right edges get no better).

    ``grow`` and ``gate_deg`` were chosen on the synthetic tuning seeds 7000
    and 8000 (docs/EVALUATION.md, "Session 18"; partly with session
    scripts): a grown region of 0.1 (0 and 0.2 fitted the true outlines
    worse) and a gate of 3 degrees (1 and 2 degrees left the camera height
    of the model choice further off, 5 degrees was not better on both sets).

    Parameters
    ----------
    pano : (H, W, 3) uint8 RGB
        The panorama ``det`` refers to.
    det : Detection
        With a ``tile`` (boxes read from a file have none: None is returned).
    grow : float
        Fraction of the tile box's width / height added on each side.
    gate_deg : float
        Largest move of an edge, degrees (at the view's focal length).
    iterations, max_size, margin : see :func:`grabcut_crop`

    Returns
    -------
    SilhouetteBox or None
        None when the detection has no tile, its region is too wide for a
        crop, or the silhouette is (nearly) empty.
    """
    if det.tile is None:
        return None
    if not (0.0 <= float(grow) <= 1.0):
        raise ValueError(f"grow: expected a fraction in [0, 1], got {grow!r}")
    if not (float(gate_deg) > 0.0):
        raise ValueError(f"gate_deg: expected degrees > 0, got {gate_deg!r}")
    b = det.tile.box
    g = float(grow) * np.array([-(b[2] - b[0]), -(b[3] - b[1]), b[2] - b[0], b[3] - b[1]])
    grown = TileBox(det.tile.view, b + g, index=det.tile.index)
    try:
        crop = grabcut_crop(pano, replace(det, tile=grown), iterations=iterations, max_size=max_size,
                            margin=margin)
    except ValueError:
        return None
    if int(crop.mask.sum()) < 16:
        return None
    rays = _mask_corner_rays(crop)
    own = rays_box_in_view(rays, det.tile.view)
    if own is None:
        return None
    # a silhouette edge on the grown region's own border is where grab-cut was stopped, not the outline
    reach = np.abs(own - grown.box) <= max(1.0, det.tile.view.focal / crop.view.focal)
    views, snapped = [], []
    for t in det.views or (det.tile,):
        sil = own if t.view == det.tile.view else rays_box_in_view(rays, t.view)
        if sil is None:
            return None
        ok = (np.abs(sil - t.box) <= t.view.focal * np.deg2rad(float(gate_deg))) & ~reach
        box = np.where(ok, sil, t.box)
        if not (box[0] < box[2] and box[1] < box[3]):
            ok, box = np.zeros(4, bool), t.box
        views.append(TileBox(t.view, box, index=t.index, truncated=t.truncated))
        snapped.append(ok)
    return SilhouetteBox(tuple(views), np.array(snapped))
