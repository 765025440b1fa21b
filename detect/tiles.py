"""Panorama driver: perspective tiles -> detector -> boxes in the panorama -> NMS on the sphere.

Paper, Sec. 3.1 and 4: detection runs "in each perspective image", "the
coordinates of object locations are reprojected to the panorama image, and
non-maximum suppression is applied". The default view set is panogeom's
:func:`~panogeom.perspective.detection_views` (18 tiles, 90 degree FOV).

Steps of :func:`detect_panorama`:

1. render every tile with one resampling call (:class:`PanoramaTiler` caches
   the sampling maps per view set and panorama size);
2. run the detector on the tiles, in batches when it is a
   :class:`~detect.detection.BatchDetector`;
3. back-project each tile box into the panorama with panogeom's
   :func:`~panogeom.perspective.box_to_pano` (seam- and pole-aware extent),
   keeping the tile and box so the object's region on the sphere is exact;
   boxes around the nadir, where the camera stands, are dropped
   (:func:`~panogeom.perspective.poles_in_box`);
4. merge the same object seen from several tiles with
   :func:`~detect.nms.merge_sphere`, class-aware; each merged detection
   keeps the boxes of the tiles that see it whole (``Detection.views``),
   whose edges the box fits of :mod:`layout` take the median of;
5. score each merged object by the *tile consensus*
   (:func:`tile_consensus`): its best score blended with the mean, over the
   tiles that see the object whole, of each tile's best score for it (0 where
   a tile that sees it whole did not find it). An object most tiles find
   outranks a false or wrong-class box that one or two tiles produce;
6. optionally segment each object by grab-cut (:mod:`detect.grabcut`).

Convention: panoramas are ``(H, W, 3) uint8`` RGB with W == 2*H; pixel
coordinates, boxes and rays as in CONVENTIONS.md (``u0 > u1`` wraps the seam).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

from panogeom.coords import ray_to_pixel
from panogeom.perspective import PinholeView, box_to_pano, detection_views, poles_in_box
from panogeom.sampling import sample_equirect

from .detection import (BatchDetector, Detection, Detector, ImageDetection, PanoramaDetector, TileBox,
                        check_rgb_image)
from .nms import merge_sphere, region_boundary

__all__ = [
    "PanoramaTiler",
    "render_tiles",
    "to_panorama",
    "tile_detections",
    "detect_panorama",
    "tile_consensus",
    "box_in_view",
    "rays_box_in_view",
]

Array = NDArray[np.float64]


def _check_pano(pano: ArrayLike) -> NDArray[np.uint8]:
    img = check_rgb_image(pano, "pano")
    h, w = img.shape[:2]
    if w != 2 * h:
        raise ValueError(f"pano: expected an equirectangular panorama with W == 2*H, got {w}x{h} (shape {img.shape})")
    return img


class PanoramaTiler:
    """Renders the perspective tiles of a view set from panoramas of one size.

    The sampling coordinates of all tiles are computed once (panogeom rays) and
    reused for every panorama; tiles of equal size are sampled in one call.

    Parameters
    ----------
    views : sequence of PinholeView
    pano_width, pano_height : int
        Panorama size (W == 2*H).

    Examples
    --------
    >>> tiler = PanoramaTiler(detection_views(64), 256, 128)
    >>> tiles = tiler.render(np.zeros((128, 256, 3), np.uint8))
    >>> len(tiles), tiles[0].shape
    (18, (64, 64, 3))
    """

    def __init__(self, views: Sequence[PinholeView], pano_width: int, pano_height: int) -> None:
        self.views: tuple[PinholeView, ...] = tuple(views)
        if not self.views or not all(isinstance(v, PinholeView) for v in self.views):
            raise ValueError(f"views: expected a non-empty sequence of PinholeView, got {views!r}")
        if int(pano_width) != 2 * int(pano_height) or int(pano_height) <= 0:
            raise ValueError(f"panorama size: expected W == 2*H > 0, got W={pano_width}, H={pano_height}")
        self.pano_width, self.pano_height = int(pano_width), int(pano_height)
        groups: dict[tuple[int, int], list[int]] = {}
        for i, v in enumerate(self.views):
            groups.setdefault((v.height, v.width), []).append(i)
        self._groups = [(idx, np.concatenate([ray_to_pixel(self.views[i].grid_rays(), self.pano_width,
                                                           self.pano_height) for i in idx], axis=0))
                        for idx in groups.values()]

    def render(self, pano: ArrayLike) -> list[NDArray[np.uint8]]:
        """One ``(h, w, 3) uint8`` tile per view, in view order."""
        img = _check_pano(pano)
        if img.shape[:2] != (self.pano_height, self.pano_width):
            raise ValueError(f"pano: expected size {self.pano_width}x{self.pano_height} for this tiler, "
                             f"got {img.shape[1]}x{img.shape[0]}")
        out: list[NDArray[np.uint8] | None] = [None] * len(self.views)
        for idx, uv in self._groups:
            stacked = sample_equirect(img, uv, "linear")
            h = self.views[idx[0]].height
            for k, i in enumerate(idx):
                out[i] = stacked[k * h:(k + 1) * h]
        return out  # type: ignore[return-value]


@lru_cache(maxsize=4)
def _tiler(views: tuple[PinholeView, ...], width: int, height: int) -> PanoramaTiler:
    return PanoramaTiler(views, width, height)


def render_tiles(pano: ArrayLike, views: Sequence[PinholeView] | None = None,
                 tile_size: int = 416) -> tuple[tuple[PinholeView, ...], list[NDArray[np.uint8]]]:
    """Render perspective tiles of a panorama.

    Parameters
    ----------
    pano : (H, W, 3) uint8, W == 2*H
    views : sequence of PinholeView, optional
        Defaults to ``detection_views(tile_size)`` (the paper's 18 views).
    tile_size : int
        Tile side in pixels for the default views.

    Returns
    -------
    views : tuple of PinholeView
    tiles : list of (h, w, 3) uint8, one per view
    """
    img = _check_pano(pano)
    vs = tuple(detection_views(int(tile_size)) if views is None else views)
    return vs, _tiler(vs, img.shape[1], img.shape[0]).render(img)


def to_panorama(det: ImageDetection, view: PinholeView, pano_width: int, pano_height: int, index: int = -1,
                truncation_margin: float = 2.0) -> Detection:
    """Back-project a tile detection into the panorama.

    Parameters
    ----------
    det : ImageDetection
        Box in the pixels of ``view`` (inside the tile).
    view : PinholeView
    pano_width, pano_height : int
    index : int
        Index of the view in its view set, stored in ``tile.index``.
    truncation_margin : float
        A box closer than this many pixels to the tile border is marked truncated.

    Returns
    -------
    Detection
        ``box`` is the seam-aware lon/lat extent of the box's footprint
        (panogeom's ``box_to_pano``); ``tile`` keeps the view and box.

    Examples
    --------
    >>> view = PinholeView(yaw=0.0, pitch=0.0, roll=0.0, fov=np.pi / 2, width=100, height=100)
    >>> d = to_panorama(ImageDetection("tv", 0.9, [25, 25, 75, 75]), view, 2048, 1024)
    >>> np.round(d.box, 1).tolist(), d.tile.truncated
    ([872.9, 360.9, 1175.1, 663.1], False)
    """
    b = det.box
    ext = box_to_pano(b, view, pano_width, pano_height).extent
    ext = np.clip(ext, [0.0, 0.0, 0.0, 0.0], [pano_width, pano_height, pano_width, pano_height])
    if ext[0] >= pano_width:
        ext[0] = 0.0
    if ext[2] <= 0.0:
        ext[2] = float(pano_width)
    m = float(truncation_margin)
    trunc = bool(b[0] <= m or b[1] <= m or b[2] >= view.width - m or b[3] >= view.height - m)
    return Detection(det.label, det.score, ext, pano_width, pano_height,
                     tile=TileBox(view=view, box=b, index=int(index), truncated=trunc))


def _run_detector(detector: Detector, tiles: list[NDArray[np.uint8]],
                  batch_size: int | None) -> list[list[ImageDetection]]:
    if isinstance(detector, BatchDetector):
        bs = len(tiles) if batch_size is None else int(batch_size)
        if bs < 1:
            raise ValueError(f"batch_size: expected a positive integer or None, got {batch_size!r}")
        res: list[list[ImageDetection]] = []
        for s in range(0, len(tiles), bs):
            chunk = tiles[s:s + bs]
            got = list(detector.detect_batch(chunk))
            if len(got) != len(chunk):
                raise ValueError(f"detector.detect_batch: expected {len(chunk)} result lists, got {len(got)}")
            res.extend(list(g) for g in got)
    else:
        res = [list(detector.detect(t)) for t in tiles]
    for dl in res:
        for d in dl:
            if not isinstance(d, ImageDetection):
                raise TypeError(f"detector: expected ImageDetection records, got {type(d).__name__}")
    return res


def tile_detections(pano: ArrayLike, detector: Detector, views: Sequence[PinholeView] | None = None, *,
                    tile_size: int = 416, batch_size: int | None = None, score_threshold: float = 0.0,
                    truncation_margin: float = 2.0, keep_nadir: bool = False) -> list[Detection]:
    """Raw detections of every tile in panorama pixels, before NMS.

    Parameters
    ----------
    pano : (H, W, 3) uint8 RGB, W == 2*H
    detector : Detector
    views : sequence of PinholeView, optional
        Defaults to ``detection_views(tile_size)``.
    tile_size : int
    batch_size : int, optional
        Tiles per ``detect_batch`` call for batch detectors (default: all).
    score_threshold : float
        Detections scoring below are dropped.
    truncation_margin : float
        See :func:`to_panorama`.
    keep_nadir : bool
        Keep tile boxes that contain the nadir
        (:func:`~panogeom.perspective.poles_in_box`). By
        default they are dropped: the camera stands there, so no object on
        the floor surrounds that point, and such a box (a near object cut by
        a downward tile's border, or the tripod) would span the panorama's
        whole width.

    Returns
    -------
    list of Detection, each with its ``tile``
    """
    if not isinstance(detector, Detector):
        raise TypeError(f"detector: expected an object with detect(image), got {type(detector).__name__}")
    img = _check_pano(pano)
    H, W = img.shape[:2]
    vs, tiles = render_tiles(img, views, tile_size)
    results = _run_detector(detector, tiles, batch_size)
    out = []
    for k, (view, dl) in enumerate(zip(vs, results)):
        for d in dl:
            if d.score < score_threshold:
                continue
            c = d.clipped(view.width, view.height)
            if c is not None and (keep_nadir or not poles_in_box(c.box, view)[1]):
                out.append(to_panorama(c, view, W, H, index=k, truncation_margin=truncation_margin))
    return out


def detect_panorama(pano: ArrayLike, detector: Detector | PanoramaDetector,
                    views: Sequence[PinholeView] | None = None, *, tile_size: int = 416,
                    score_threshold: float = 0.0, iou_threshold: float = 0.5, containment: float = 0.5,
                    truncated_weight: float = 0.5, consensus: float = 0.5, batch_size: int | None = None,
                    masks: bool = False, grabcut_iterations: int = 5,
                    keep_nadir: bool = False) -> list[Detection]:
    """Detect objects in a panorama through perspective tiles, merged by NMS on the sphere.

    Parameters
    ----------
    pano : (H, W, 3) uint8 RGB, W == 2*H
    detector : Detector or PanoramaDetector
        A tile detector (see :mod:`detect.backends`), or a source of panorama
        boxes such as an annotation file, which is used as is (no tiles, no NMS).
    views : sequence of PinholeView, optional
        Defaults to the paper's 18 views, ``detection_views(tile_size)``.
    tile_size : int
    score_threshold : float
        Drop tile detections scoring below (before the merge), and merged
        detections whose consensus score is below.
    iou_threshold, containment, truncated_weight : float
        See :func:`detect.nms.merge_sphere`.
    consensus : float
        Weight of the tiles' mean in the merged score (:func:`tile_consensus`);
        0 keeps the group's best score.
    batch_size : int, optional
        Tiles per batch for batch detectors (default: all in one batch).
    masks : bool
        Also segment each detection by grab-cut (``Detection.mask``).
    grabcut_iterations : int
    keep_nadir : bool
        Keep tile boxes around the nadir (see :func:`tile_detections`).

    Returns
    -------
    list of Detection, by decreasing score

    Examples
    --------
    A detector that boxes the bright pixels of a tile; five tiles see the
    bright patch and their boxes merge into one:

    >>> class Bright:
    ...     def detect(self, image):
    ...         ys, xs = np.nonzero(image[..., 0] > 127)
    ...         box = [xs.min(), ys.min(), xs.max() + 1, ys.max() + 1] if len(xs) else None
    ...         return [ImageDetection("tv", 1.0, box)] if box else []
    >>> pano = np.zeros((256, 512, 3), np.uint8); pano[140:160, 240:272] = 255
    >>> [(d.label, d.support, d.box.round().tolist()) for d in detect_panorama(pano, Bright(), tile_size=64)]
    [('tv', 5, [238.0, 137.0, 274.0, 167.0])]
    """
    img = _check_pano(pano)
    if isinstance(detector, Detector):
        raw = tile_detections(img, detector, views, tile_size=tile_size, batch_size=batch_size,
                              score_threshold=score_threshold, keep_nadir=keep_nadir)
        vs = tuple(detection_views(int(tile_size)) if views is None else views)
        groups = merge_sphere(raw, iou_threshold, containment=containment, truncated_weight=truncated_weight)
        dets = [d for d in tile_consensus(groups, vs, consensus) if d.score >= score_threshold]
    elif isinstance(detector, PanoramaDetector):
        dets = [d for d in detector.detect_panorama(img) if d.score >= score_threshold]
        dets.sort(key=lambda d: -d.score)
    else:
        raise TypeError(f"detector: expected an object with detect(image) or detect_panorama(pano), "
                        f"got {type(detector).__name__}")
    if masks:
        from .grabcut import segment_detections

        dets = segment_detections(img, dets, iterations=grabcut_iterations)
    return dets


def tile_consensus(groups: Sequence[tuple[Detection, Sequence[Detection]]], views: Sequence[PinholeView],
                   weight: float = 0.5, margin: float = 0.02) -> list[Detection]:
    """Score merged detections by how many of the tiles that see them whole found them.

    For a merged detection with members (:func:`detect.nms.merge_sphere`):
    the tiles that see its region whole are the views in which its box
    (:func:`box_in_view`) lies in front of the camera and inside the image by
    ``margin`` of the view's width. Each such tile contributes the best score
    of the members it produced, or 0. The new score is
    ``(1 - weight) * best + weight * mean``; with no such tile, ``best``.

    Measured on 90 synthetic rooms of the tuning seeds 7000 and 8000 (the
    builtin detector, panorama AP@0.5 of bed, chair, TV and plant;
    ``benchmarks/eval_detect_merge.py``): 0.869 with the best score alone,
    0.895 with ``weight=0.5`` (session-4 weights); 0.889 and 0.914 with the
    retrained weights of session 5. False and wrong-class boxes are mostly found by
    one or two of the tiles that see them.

    Parameters
    ----------
    groups : sequence of (Detection, sequence of Detection)
        Merged detections and their members, as :func:`~detect.nms.merge_sphere`
        returns them.
    views : sequence of PinholeView
        The tile set the members came from (``tile.view``).
    weight : float in [0, 1]
    margin : float
        Fraction of a view's width by which the box must stay inside it.

    Returns
    -------
    list of Detection, by decreasing new score (``score`` replaced)

    Examples
    --------
    Two of the three tiles that see a box whole found it (0.9 and 0.6), the
    third did not: ``0.5 * 0.9 + 0.5 * (0.9 + 0.6 + 0) / 3 = 0.7``.

    >>> vs = [PinholeView(yaw=y, pitch=0.0, roll=0.0, fov=np.pi / 2, width=100, height=100)
    ...       for y in (-0.2, 0.0, 0.2)]
    >>> a, b = (to_panorama(ImageDetection("tv", s, [40, 40, 60, 60]), vs[k], 2048, 1024, k)
    ...         for s, k in ((0.9, 1), (0.6, 0)))
    >>> [round(d.score, 3) for d in tile_consensus([(a, (a, b))], vs)]
    [0.7]
    """
    if not 0.0 <= float(weight) <= 1.0:
        raise ValueError(f"weight: expected a number in [0, 1], got {weight!r}")
    if not 0.0 <= float(margin) < 0.5:
        raise ValueError(f"margin: expected a fraction in [0, 0.5), got {margin!r}")
    vs = list(views)
    out = []
    for det, members in groups:
        best_of: dict[PinholeView, float] = {}
        for m in members:
            if m.tile is not None:
                best_of[m.tile.view] = max(best_of.get(m.tile.view, 0.0), float(m.score))
        seen = []
        if weight > 0.0:
            rays = region_boundary(det, 16)
            for v in vs:
                b = rays_box_in_view(rays, v)
                e = float(margin) * v.width
                if b is not None and b[0] >= e and b[1] >= e and b[2] <= v.width - e and b[3] <= v.height - e:
                    seen.append(best_of.get(v, 0.0))
        score = det.score if not seen else (1.0 - weight) * det.score + weight * float(np.mean(seen))
        out.append(replace(det, score=float(score)))
    out.sort(key=lambda d: -d.score)
    return out


def box_in_view(det: Detection, view: PinholeView, samples: int = 64) -> Array:
    """Bounding box of a detection's region seen in a perspective view (panorama -> tile).

    Parameters
    ----------
    det : Detection
    view : PinholeView
    samples : int
        Points per edge of the region's boundary.

    Returns
    -------
    box : (4,) float
        ``(u0, v0, u1, v1)`` in the view's pixels (may extend beyond the image).

    Raises
    ------
    ValueError
        If part of the region lies behind the view (no finite box).

    Examples
    --------
    >>> view = PinholeView(yaw=0.0, pitch=0.0, roll=0.0, fov=np.pi / 2, width=100, height=100)
    >>> d = to_panorama(ImageDetection("tv", 0.9, [25, 25, 75, 75]), view, 2048, 1024)
    >>> np.round(box_in_view(d, view), 6).tolist()
    [25.0, 25.0, 75.0, 75.0]
    """
    box = rays_box_in_view(region_boundary(det, samples), view)
    if box is None:
        raise ValueError(f"det: expected a region in front of the view (yaw={view.yaw:.3f}, "
                         f"pitch={view.pitch:.3f}), got one that reaches behind it")
    return box


def rays_box_in_view(rays: ArrayLike, view: PinholeView) -> Array | None:
    """Pixel bounding box ``(u0, v0, u1, v1)`` of rays ``(K, 3)`` seen in a view; None if any lies behind it.

    Examples
    --------
    >>> view = PinholeView(yaw=0.0, pitch=0.0, roll=0.0, fov=np.pi / 2, width=100, height=100)
    >>> rays = view.pixel_to_ray(np.array([[10.0, 20.0], [60.0, 70.0]]))
    >>> np.round(rays_box_in_view(rays, view), 6).tolist()
    [10.0, 20.0, 60.0, 70.0]
    """
    uv, front = view.ray_to_pixel(rays)
    if not np.all(front):
        return None
    return np.array([uv[:, 0].min(), uv[:, 1].min(), uv[:, 0].max(), uv[:, 1].max()])
