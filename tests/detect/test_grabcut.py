"""Grab-cut masks: synthetic objects on textured backgrounds, across the seam, near a pole."""

from __future__ import annotations

import numpy as np
import pytest

from detect.detection import Detection, ImageDetection
from detect.grabcut import crop_mask_to_pano, grabcut_crop, object_view, segment_detections
from detect.tiles import detect_panorama, to_panorama
from panogeom.coords import pixel_grid, pixel_to_lonlat
from panogeom.perspective import PinholeView

W, H = 1024, 512


def _textured(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    base = rng.integers(0, 50, (H, W, 3)) + np.array([60, 90, 120])
    return base.astype(np.uint8)


def _ellipse(centre_lonlat_deg, radii_deg) -> np.ndarray:
    ll = np.rad2deg(pixel_to_lonlat(pixel_grid(W, H), W, H))
    dlon = (ll[..., 0] - centre_lonlat_deg[0] + 180) % 360 - 180
    return (dlon / radii_deg[0]) ** 2 + ((ll[..., 1] - centre_lonlat_deg[1]) / radii_deg[1]) ** 2 <= 1


def _iou(a, b):
    return (a & b).sum() / (a | b).sum()


def test_grabcut_segments_an_object_across_the_seam():
    pano = _textured(0)
    obj = _ellipse((178, -20), (12, 15))  # crosses lon = +-180
    pano[obj] = (200, 60, 50)
    det = Detection("chair", 0.9, [W - 40, 280, 30, 360], W, H)
    assert det.wraps
    crop = grabcut_crop(pano, det)
    assert crop.mask.shape == crop.image.shape[:2] == crop.region.shape
    assert crop.region.any() and not crop.region.all()
    mask = crop_mask_to_pano(crop, det)
    assert _iou(mask, obj) > 0.9
    assert mask[:, :W // 2].any() and mask[:, W // 2:].any()  # on both sides of the seam


def test_grabcut_of_a_tile_detection_near_the_nadir():
    pano = _textured(1)
    obj = _ellipse((40, -62), (14, 8))
    pano[obj] = (40, 200, 60)
    view = PinholeView(np.deg2rad(-40), np.deg2rad(-60), 0.0, np.pi / 2, 200, 200)
    det = to_panorama(ImageDetection("table", 0.8, [55, 60, 145, 140]), view, W, H)
    (out,) = segment_detections(pano, [det])
    assert out.mask is not None and out.mask.shape == (H, W)
    assert _iou(out.mask, obj) > 0.85


def test_object_view_is_centred_and_bounded():
    det = Detection("tv", 0.9, [500, 200, 540, 240], W, H)
    v = object_view(det, max_size=64)
    assert max(v.width, v.height) <= 65
    # the crop is never finer than the panorama
    v2 = object_view(det, max_size=4096)
    assert v2.focal <= W / (2 * np.pi) + 1e-9
    with pytest.raises(ValueError, match="max_size: expected at least 16 pixels, got 4"):
        object_view(det, max_size=4)
    wide = Detection("bed", 0.9, [0, 100, W, 300], W, H)
    with pytest.raises(ValueError, match="narrower than 180 degrees"):
        object_view(wide)


def test_grabcut_checks_the_panorama_size():
    det = Detection("tv", 0.9, [500, 200, 540, 240], W, H)
    with pytest.raises(ValueError, match="expected size 1024x512 \\(the detection's panorama\\), got 512x256"):
        grabcut_crop(np.zeros((256, 512, 3), np.uint8), det)


def test_detect_panorama_can_return_masks():
    pano = _textured(2)
    obj = _ellipse((0, -15), (10, 10))
    pano[obj] = (250, 10, 10)

    class Red:
        def detect(self, image):
            ys, xs = np.nonzero((image[..., 0] > 200) & (image[..., 1] < 60))
            if len(xs) < 10:
                return []
            return [ImageDetection("chair", 0.9, [xs.min(), ys.min(), xs.max() + 1, ys.max() + 1])]

    (d,) = detect_panorama(pano, Red(), tile_size=96, masks=True)
    assert _iou(d.mask, obj) > 0.85


def _object_in_view(view: PinholeView, rect, colour) -> tuple[np.ndarray, np.ndarray]:
    """A panorama whose object is the set of rays inside ``rect`` (pixels of ``view``): its tile box is exact."""
    from panogeom.coords import pixel_to_ray

    pano = _textured(5)
    uv, front = view.ray_to_pixel(pixel_to_ray(pixel_grid(W, H), W, H))
    obj = front & (uv[..., 0] >= rect[0]) & (uv[..., 0] <= rect[2]) & (uv[..., 1] >= rect[1]) & (uv[..., 1] <= rect[3])
    pano[obj] = colour
    return pano, obj


def _edge_angles_deg(a, b) -> np.ndarray:
    """Angle between corresponding edge planes of two TileBoxes, degrees: (4,)."""
    na, nb = a.edge_planes(), b.edge_planes()
    return np.rad2deg(np.arccos(np.clip((na * nb).sum(axis=1), -1.0, 1.0)))


def test_silhouette_box_moves_loose_edges_onto_the_outline():
    from detect.detection import TileBox
    from detect.grabcut import silhouette_box

    view = PinholeView(np.deg2rad(30), np.deg2rad(-20), 0.0, np.pi / 2, 200, 200)
    rect = [80.0, 90.0, 130.0, 150.0]
    pano, _ = _object_in_view(view, rect, (210, 70, 40))
    true = TileBox(view, rect)
    # the detector's box: left and right 2 px loose, top and bottom 2 px tight (1 px ~ 0.57 deg)
    det = to_panorama(ImageDetection("chair", 0.9, [78.0, 92.0, 132.0, 148.0]), view, W, H)
    assert np.all(_edge_angles_deg(det.tile, true) > 0.9)
    sb = silhouette_box(pano, det)
    assert sb is not None and sb.snapped.tolist() == [[True, True, True, True]]
    assert len(sb.views) == 1 and sb.views[0].view == view
    assert np.all(_edge_angles_deg(sb.views[0], true) < 0.5)  # a pixel of the crop: 0.35 deg
    assert sb.edge_planes().shape == (4, 3)


def test_silhouette_box_keeps_the_detector_edges_it_cannot_confirm():
    from detect.detection import Detection as D
    from detect.grabcut import silhouette_box

    view = PinholeView(np.deg2rad(-60), np.deg2rad(-15), 0.0, np.pi / 2, 200, 200)
    rect = [70.0, 80.0, 120.0, 140.0]
    pano, _ = _object_in_view(view, rect, (40, 200, 90))
    # right edge 14 px (about 8 deg) outside the object: the silhouette's right edge is beyond the 3 deg gate;
    # bottom edge 14 px inside: grab-cut stops at the grown region, which is no outline either
    det = to_panorama(ImageDetection("chair", 0.9, [70.0, 80.0, 134.0, 126.0]), view, W, H)
    sb = silhouette_box(pano, det)
    assert sb is not None and sb.snapped.tolist() == [[True, True, False, False]]
    assert sb.views[0].box[2:].tolist() == [134.0, 126.0]
    # boxes read from a file have no tile: nothing to refine
    assert silhouette_box(pano, D("chair", 0.9, [600.0, 300.0, 650.0, 360.0], W, H)) is None
    with pytest.raises(ValueError, match="gate_deg: expected degrees > 0"):
        silhouette_box(pano, det, gate_deg=0.0)
