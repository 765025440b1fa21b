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

Convention: panoramas ``(H, W, 3) uint8`` RGB with W == 2*H; pixel and ray
conventions of CONVENTIONS.md through panogeom; a view at yaw ``a`` looks at
``lon = -a`` (panogeom.perspective).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from panogeom.coords import pixel_to_ray, ray_to_lonlat
from panogeom.perspective import PinholeView, equirect_to_perspective

from .detection import Detection, check_rgb_image
from .nms import region_boundary, region_contains

__all__ = ["ObjectCrop", "object_view", "grabcut_crop", "crop_mask_to_pano", "segment_detections"]

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
