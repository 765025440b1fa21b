"""Detection records and protocols: validation, seam-aware helpers, JSON form."""

from __future__ import annotations

import numpy as np
import pytest

from detect.detection import (BatchDetector, Detection, Detector, ImageDetection, PanoramaDetector, TileBox,
                              check_label)
from panogeom.perspective import PinholeView


def test_image_detection_validates_and_freezes():
    d = ImageDetection("chair", 0.5, [1, 2, 3, 4])
    assert d.box.dtype == np.float64 and not d.box.flags.writeable
    with pytest.raises(ValueError, match=r"u0 < u1 and v0 < v1, got \[3.0, 2.0, 1.0, 4.0\]"):
        ImageDetection("chair", 0.5, [3, 2, 1, 4])
    with pytest.raises(ValueError, match=r"score: expected a number in \[0, 1\], got 1.5"):
        ImageDetection("chair", 1.5, [1, 2, 3, 4])
    with pytest.raises(ValueError, match="lowercase word"):
        ImageDetection("Chair", 0.5, [1, 2, 3, 4])
    with pytest.raises(ValueError, match=r"box: expected shape \(4,\), got \(3,\)"):
        ImageDetection("chair", 0.5, [1, 2, 3])


def test_image_detection_clipped():
    d = ImageDetection("tv", 0.9, [-5, 10, 50, 120])
    assert d.clipped(40, 100).box.tolist() == [0.0, 10.0, 40.0, 100.0]
    assert d.clipped(40, 5) is None


def test_detection_box_rules_and_seam_helpers():
    d = Detection("table", 0.8, [2000, 600, 40, 700], 2048, 1024)
    assert d.wraps and d.width_px == 88.0
    assert d.center_px.tolist() == [(2000 + 44) % 2048, 650.0]
    plain = Detection("table", 0.8, [100, 600, 140, 700], 2048, 1024)
    assert not plain.wraps and plain.width_px == 40.0
    full = Detection("bed", 0.8, [0, 900, 2048, 1024], 2048, 1024)
    assert full.width_px == 2048.0
    with pytest.raises(ValueError, match=r"in a 2048x1024 panorama .* got \[2048.0, 600.0, 40.0, 700.0\]"):
        Detection("table", 0.8, [2048, 600, 40, 700], 2048, 1024)
    with pytest.raises(ValueError, match="u0 != u1"):
        Detection("table", 0.8, [40, 600, 40, 700], 2048, 1024)
    with pytest.raises(ValueError, match="W == 2\\*H, got W=2048, H=1000"):
        Detection("table", 0.8, [0, 600, 40, 700], 2048, 1000)


def test_detection_mask_and_json():
    m = np.zeros((8, 16), bool)
    m[2, 3] = True
    d = Detection("chair", 0.25, [1, 1, 5, 4], 16, 8).with_mask(m)
    m[2, 3] = False  # the record keeps its own read-only copy
    assert d.mask[2, 3] and not d.mask.flags.writeable
    assert d.to_json() == {"class": "chair", "score": 0.25, "bbox_pano": [1.0, 1.0, 5.0, 4.0]}
    with pytest.raises(ValueError, match=r"mask: expected a \(8, 16\) bool array, got shape \(8, 8\)"):
        d.with_mask(np.zeros((8, 8), bool))


def test_tilebox_and_support():
    v = PinholeView(0.0, 0.0, 0.0, np.pi / 2, 10, 10)
    t = TileBox(v, [1, 1, 4, 4], index=3, truncated=False)
    d = Detection("tv", 1.0, [1, 1, 5, 4], 16, 8, tile=t, support=2)
    assert d.tile.index == 3 and d.support == 2
    with pytest.raises(ValueError, match="support: expected a positive integer, got 0"):
        Detection("tv", 1.0, [1, 1, 5, 4], 16, 8, support=0)


def test_check_label():
    assert check_label("computer_mouse") == "computer_mouse"
    for bad in ("", "two words", "Chair", 3, "9lives"):
        with pytest.raises(ValueError, match="lowercase word"):
            check_label(bad)


def test_protocols_are_structural():
    class One:
        def detect(self, image):
            return []

    class Many(One):
        def detect_batch(self, images):
            return [[] for _ in images]

    class Pano:
        def detect_panorama(self, pano):
            return []

    assert isinstance(One(), Detector) and not isinstance(One(), BatchDetector)
    assert isinstance(Many(), BatchDetector)
    assert isinstance(Pano(), PanoramaDetector) and not isinstance(Pano(), Detector)


def test_tile_box_edge_planes_bound_the_box_on_the_sphere():
    """The four planes hold the box's edges (its corner rays lie on two of them), every ray through a pixel inside
    the box is on their inner side, and one outside is not; also for a turned, pitched and rolled tile."""
    from detect.detection import TileBox
    from panogeom.perspective import PinholeView

    view = PinholeView(yaw=0.7, pitch=-0.4, roll=0.1, fov=np.pi / 2, width=320, height=240)
    tb = TileBox(view, [40.0, 30.0, 200.0, 180.0])
    n = tb.edge_planes()
    assert n.shape == (4, 3) and np.allclose(np.linalg.norm(n, axis=1), 1.0)
    corners = view.pixel_to_ray(np.array([[40.0, 30.0], [200.0, 30.0], [200.0, 180.0], [40.0, 180.0]]))
    d = corners @ n.T  # (corner, plane): TL on left and top, TR on top and right, ...
    on = np.array([[1, 1, 0, 0], [0, 1, 1, 0], [0, 0, 1, 1], [1, 0, 0, 1]], bool)
    assert np.allclose(d[on], 0.0, atol=1e-9) and np.all(d[~on] > 0)
    rng = np.random.default_rng(0)
    inside = view.pixel_to_ray(rng.uniform([41, 31], [199, 179], size=(200, 2)))
    assert np.all(inside @ n.T > 0)
    outside = view.pixel_to_ray(np.array([[20.0, 100.0], [120.0, 200.0], [250.0, 100.0], [120.0, 10.0]]))
    assert np.all(np.any(outside @ n.T < 0, axis=1))
    assert tb.border_edges().tolist() == [False] * 4
    assert TileBox(view, [0.5, 30.0, 200.0, 239.0]).border_edges().tolist() == [True, False, False, True]


def test_a_tile_boxs_region_boundary_lies_on_its_edge_planes_around_its_centre_ray():
    from detect.detection import Detection, TileBox
    from detect.nms import region_boundary
    from panogeom.perspective import PinholeView

    view = PinholeView(yaw=-2.0, pitch=-0.5, roll=0.0, fov=np.pi / 2, width=320, height=240)
    tb = TileBox(view, [40.0, 30.0, 200.0, 180.0])
    np.testing.assert_allclose(tb.centre_ray(), view.pixel_to_ray(np.array([120.0, 105.0])), atol=1e-12)
    rays = region_boundary(Detection("bed", 0.9, [100.0, 300.0, 300.0, 400.0], 1024, 512, tile=tb), 5)
    assert rays.shape == (20, 3) and np.allclose(np.linalg.norm(rays, axis=1), 1.0)
    d = rays @ tb.edge_planes().T
    assert np.allclose(d.min(axis=1), 0.0, atol=1e-9) and np.all(d > -1e-9)  # each on one plane, inside the rest
    assert np.all(tb.centre_ray() @ tb.edge_planes().T > 0.05)
