"""Panorama driver: reprojection round trips (acceptance: within 1 px), tiling, batching, end to end."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from detect.detection import Detection, ImageDetection
from detect.nms import pano_box_iou
from detect.tiles import (PanoramaTiler, box_in_view, detect_panorama, render_tiles, tile_detections,
                          to_panorama)
from panogeom.coords import pixel_grid_rays
from panogeom.perspective import PinholeView, detection_views, equirect_to_perspective, poles_in_box

W, H = 1024, 512
VIEWS = detection_views(256)


def _paint_tile_box(view, box, scale: int = 1) -> np.ndarray:
    """Panorama pixels whose centres project inside ``box`` of ``view`` (the box drawn into the panorama)."""
    uv, front = view.ray_to_pixel(pixel_grid_rays(scale * W, scale * H))
    return front & (uv[..., 0] >= box[0]) & (uv[..., 0] <= box[2]) & (uv[..., 1] >= box[1]) & (uv[..., 1] <= box[3])


def _circular_extent(mask: np.ndarray) -> tuple[float, float, float, float]:
    """Seam-aware pixel extent (u0, v0, u1, v1) of a mask, pixel edges, u0 > u1 when it wraps."""
    rows = np.flatnonzero(mask.any(axis=1))
    cols = mask.any(axis=0)
    if cols.all():
        return 0.0, float(rows[0]), float(W), float(rows[-1] + 1)
    empty = np.flatnonzero(~cols)
    # the longest run of empty columns (circularly) is outside the box
    gaps = np.diff(np.concatenate([empty, [empty[0] + W]]))
    k = int(np.argmax(gaps))
    u0 = (empty[k] + 1) % W
    u1 = (empty[(k + 1) % len(empty)])
    return float(u0), float(rows[0]), float(u1 if u1 > 0 else W), float(rows[-1] + 1)


def _udist(a: float, b: float) -> float:
    d = abs(a - b) % W
    return min(d, W - d)


CASES = [  # (view index, box in the 256 px tile): horizon, across the seam, low ring, around the nadir
    (3, [40.0, 60.0, 200.0, 230.0]),
    (6, [70.0, 100.0, 190.0, 200.0]),
    (6, [150.0, 30.0, 250.0, 120.0]),
    (14, [30.0, 20.0, 120.0, 90.0]),
    (12, [90.0, 180.0, 170.0, 250.0]),
]


@pytest.mark.parametrize("index,box", CASES)
def test_tile_box_to_panorama_and_back_within_one_pixel(index, box):
    view = VIEWS[index]
    det = to_panorama(ImageDetection("chair", 0.9, box), view, W, H, index=index)
    painted = _paint_tile_box(view, box)
    u0, v0, u1, v1 = _circular_extent(painted)
    # panorama: the box's extent is the painted region's pixel extent within 1 px (seam-aware)
    assert _udist(det.box[0], u0) <= 1.0 and _udist(det.box[2], u1) <= 1.0
    assert abs(det.box[1] - v0) <= 1.0 and abs(det.box[3] - v1) <= 1.0
    assert det.wraps == (u0 > u1)
    # and back: the stored region seen in its tile is the box (exactly) ...
    assert np.allclose(box_in_view(det, view), box, atol=1e-6)
    # ... and the painted panorama re-rendered into the tile gives the box within 1 px
    tile = equirect_to_perspective(painted.astype(np.float32), view) > 0.5
    ys, xs = np.nonzero(tile)
    assert np.allclose([xs.min(), ys.min(), xs.max() + 1, ys.max() + 1], box, atol=1.0)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 17), st.floats(0, 200), st.floats(0, 200), st.floats(8, 56), st.floats(8, 56))
def test_round_trip_through_panorama_is_exact(index, u, v, bw, bh):
    view = VIEWS[index]
    box = [u, v, u + bw, v + bh]
    det = to_panorama(ImageDetection("tv", 0.5, box), view, W, H)
    assert np.allclose(box_in_view(det, view), box, atol=1e-6)
    assert 0 <= det.box[0] < W and 0 < det.box[2] <= W and det.box[1] < det.box[3]


def test_the_same_region_seen_from_a_neighbouring_tile_matches_a_drawn_box():
    # a box drawn in tile 0, seen by tile 1 (30 degrees left): box_in_view agrees with re-rendering within 1 px
    box = [20.0, 70.0, 110.0, 180.0]
    det = to_panorama(ImageDetection("chair", 0.9, box), VIEWS[0], W, H)
    painted = _paint_tile_box(VIEWS[0], box, scale=2)  # drawn finer than the tile's pixels
    seen = equirect_to_perspective(painted.astype(np.float32), VIEWS[1]) > 0.5
    ys, xs = np.nonzero(seen)
    assert np.allclose(box_in_view(det, VIEWS[1]), [xs.min(), ys.min(), xs.max() + 1, ys.max() + 1], atol=1.0)


def test_box_in_view_refuses_regions_behind_the_view():
    det = to_panorama(ImageDetection("chair", 0.9, [20, 20, 60, 60]), VIEWS[0], W, H)
    with pytest.raises(ValueError, match="reaches behind it"):
        box_in_view(det, VIEWS[6])


def test_tiler_matches_panogeom_perspective_rendering(synth):
    pano = synth.grey_pano(128, seed=3)
    pano[40:60, 240:256] = (255, 0, 0)
    views, tiles = render_tiles(pano, tile_size=48)
    assert len(tiles) == 18 and tiles[0].shape == (48, 48, 3)
    for k in (0, 6, 13):
        assert np.array_equal(tiles[k], equirect_to_perspective(pano, views[k]))
    with pytest.raises(ValueError, match="expected size 512x256 for this tiler, got 256x128"):
        PanoramaTiler(views, 512, 256).render(pano)
    with pytest.raises(ValueError, match=r"W == 2\*H, got 100x100"):
        render_tiles(np.zeros((100, 100, 3), np.uint8))


class ColourBlobs:
    """A cheap detector: boxes of connected saturated-red pixels (counts its calls)."""

    def __init__(self):
        self.calls = 0

    def detect(self, image):
        import cv2

        self.calls += 1
        red = (image[..., 0] > 200) & (image[..., 1] < 60)
        n, _, stats, _ = cv2.connectedComponentsWithStats(red.astype(np.uint8))
        return [ImageDetection("chair", 0.9, [x, y, x + w, y + h]) for x, y, w, h, a in stats[1:] if a >= 4]


class BatchedBlobs(ColourBlobs):
    def __init__(self):
        super().__init__()
        self.batches = []

    def detect_batch(self, images):
        self.batches.append(len(images))
        return [ColourBlobs.detect(self, im) for im in images]


def test_detect_panorama_finds_an_object_across_the_seam(synth):
    pano = synth.grey_pano(256)
    lon0, lon1 = np.deg2rad(170), np.deg2rad(-168)  # wraps the seam
    mask = synth.paint_lonlat(pano, lon0, lon1, np.deg2rad(-25), np.deg2rad(-5), (255, 20, 20))
    det = BatchedBlobs()
    raw = tile_detections(pano, det, tile_size=128)
    assert len({d.tile.index for d in raw}) >= 3  # seen by several tiles
    found = detect_panorama(pano, det, tile_size=128)
    assert len(found) == 1
    d = found[0]
    assert d.label == "chair" and d.wraps and d.support >= 3
    cols = np.flatnonzero(mask.any(axis=0))
    rows = np.flatnonzero(mask.any(axis=1))
    truth = [cols[cols > 256][0], rows[0], cols[cols < 256][-1] + 1, rows[-1] + 1]
    assert d.tile.index == 6  # the tile that sees it in its centre represents it
    assert pano_box_iou([d.box], [truth], 512, 256)[0, 0] > 0.85


def test_driver_batches_tiles_for_batch_detectors(synth):
    pano = synth.grey_pano(64)
    b = BatchedBlobs()
    detect_panorama(pano, b, tile_size=32)
    assert b.batches == [18] and b.calls == 18
    b2 = BatchedBlobs()
    detect_panorama(pano, b2, tile_size=32, batch_size=5)
    assert b2.batches == [5, 5, 5, 3]
    one = ColourBlobs()
    detect_panorama(pano, one, tile_size=32)
    assert one.calls == 18
    with pytest.raises(ValueError, match="batch_size: expected a positive integer or None, got 0"):
        detect_panorama(pano, BatchedBlobs(), tile_size=32, batch_size=0)


def test_driver_uses_panorama_detectors_as_they_are(synth):
    class Known:
        def detect_panorama(self, pano):
            h, w = pano.shape[:2]
            return [Detection("bed", 0.4, [10, 10, 20, 20], w, h), Detection("tv", 0.9, [w - 5, 10, 5, 20], w, h)]

    got = detect_panorama(synth.grey_pano(64), Known(), score_threshold=0.5)
    assert [d.label for d in got] == ["tv"]


def test_driver_rejects_what_is_not_a_detector(synth):
    with pytest.raises(TypeError, match="expected an object with detect"):
        detect_panorama(synth.grey_pano(64), object())

    class Wrong:
        def detect(self, image):
            return [(0, 0, 1, 1)]

    with pytest.raises(TypeError, match="expected ImageDetection records, got tuple"):
        detect_panorama(synth.grey_pano(64), Wrong(), tile_size=32)


class LowerHalf:
    """Boxes the lower half of every tile: around the nadir in a tile that looks straight down."""

    def detect(self, image):
        h, w = image.shape[:2]
        return [ImageDetection("bed", 0.9, [1.0, h / 2, w - 1.0, h - 1.0])]


def test_tile_boxes_around_the_nadir_are_dropped_unless_kept(synth):
    pano = synth.grey_pano(128)
    views = [PinholeView(yaw=0.0, pitch=0.0, roll=0.0, fov=np.pi / 2, width=64, height=64),
             PinholeView(yaw=0.3, pitch=-np.deg2rad(60), roll=0.0, fov=np.pi / 2, width=64, height=64)]
    assert [poles_in_box([1.0, 32.0, 63.0, 63.0], v) for v in views] == [(False, False), (False, True)]
    kept = tile_detections(pano, LowerHalf(), views, keep_nadir=True)
    assert [d.tile.index for d in kept] == [0, 1]
    assert kept[1].box[0] == 0.0 and kept[1].box[2] == pano.shape[1]  # the whole width: no object is that
    dropped = tile_detections(pano, LowerHalf(), views)
    assert [d.tile.index for d in dropped] == [0]
    assert [d.tile.index for d in detect_panorama(pano, LowerHalf(), views)] == [0]
