"""The pose CRF's crop of a detection (apps.pipeline.object_crop): tile box region vs panorama box."""

from __future__ import annotations

import math

import numpy as np
import pytest

from detect.detection import Detection, TileBox
from detect.nms import region_boundary
from panogeom.coords import ray_to_pixel
from panogeom.perspective import PinholeView
from apps.pipeline import RunOptions, object_crop


def _detection(W: int = 1024, H: int = 512) -> Detection:
    tile = PinholeView(yaw=0.9, pitch=-0.7, roll=0.0, fov=math.radians(90.0), width=416, height=416)
    tb = TileBox(tile, [140.0, 190.0, 290.0, 320.0])
    pp = ray_to_pixel(region_boundary(Detection("chair", 0.9, [0.0, 1.0, 10.0, 2.0], W, H, tile=tb), 16), W, H)
    box = [pp[:, 0].min(), pp[:, 1].min(), pp[:, 0].max(), pp[:, 1].max()]
    return Detection("chair", 0.9, box, W, H, tile=tb)


def test_the_tile_crop_holds_the_tile_box_and_is_tighter_than_the_panorama_box():
    pano = np.random.default_rng(0).integers(0, 255, (512, 1024, 3), dtype=np.uint8)
    det = _detection()
    crop, view = object_crop(pano, det, "tile")
    crop_b, view_b = object_crop(pano, det, "box")
    assert crop.shape[1] == crop_b.shape[1] == 128 and crop.dtype == np.uint8
    uv, front = view.ray_to_pixel(region_boundary(det, 16))
    assert front.all() and uv.min() >= -1e-6 and uv[:, 0].max() <= view.width + 1e-6
    assert view.fov < view_b.fov - math.radians(3.0)
    # without a tile both modes crop the panorama box
    plain = Detection("chair", 0.9, det.box, 1024, 512)
    assert object_crop(pano, plain, "tile")[1].fov == pytest.approx(view_b.fov)
    with pytest.raises(ValueError, match="crop"):
        object_crop(pano, det, "mask")



def test_the_other_tiles_crops_are_those_of_the_detection_with_that_tile():
    from apps.pipeline import other_tile_crops

    pano = np.random.default_rng(1).integers(0, 255, (512, 1024, 3), dtype=np.uint8)
    det = _detection()
    other = TileBox(PinholeView(yaw=0.7, pitch=-0.5, roll=0.0, fov=math.radians(90.0), width=416, height=416),
                    [160.0, 130.0, 330.0, 290.0])
    assert other_tile_crops(pano, det) == []  # no other view
    seen_twice = Detection("chair", 0.9, det.box, 1024, 512, tile=det.tile, views=(det.tile, other))
    (crop, ray), = other_tile_crops(pano, seen_twice)
    want, view = object_crop(pano, Detection("chair", 0.9, det.box, 1024, 512, tile=other), "tile")
    np.testing.assert_array_equal(crop, want)
    np.testing.assert_allclose(ray, view.direction)
    assert np.degrees(np.arccos(np.clip(ray @ object_crop(pano, det, "tile")[1].direction, -1, 1))) > 5.0


def test_run_options_refuse_an_unknown_crop_mode():
    assert RunOptions().crop == "tile" and RunOptions(crop="box").crop == "box"
    with pytest.raises(ValueError, match="crop"):
        RunOptions(crop="mask")


def test_the_object_mask_is_the_intersection_of_the_tile_regions_inside_the_panorama_box():
    from layout.likelihood import boxes_mask
    from apps.pipeline import object_mask

    det = _detection()
    # a second view of the same object, from a tile turned the other way: its box region differs from the first's
    other = TileBox(PinholeView(yaw=0.7, pitch=-0.5, roll=0.0, fov=math.radians(90.0), width=416, height=416),
                    [160.0, 130.0, 330.0, 290.0])
    seen_twice = Detection("chair", 0.9, det.box, 1024, 512, tile=det.tile, views=(det.tile, other))
    plain = Detection("table", 0.5, [700.0, 300.0, 760.0, 340.0], 1024, 512)  # from a file: no tile
    box = object_mask([det, plain], (512, 1024), "box")
    np.testing.assert_array_equal(box, boxes_mask(np.array([det.box, plain.box]), 1024))
    one = object_mask([det], (512, 1024))
    two = object_mask([seen_twice], (512, 1024))
    # the tile region is inside the panorama box and clearly smaller (the tile is pitched)
    own = boxes_mask(np.array([det.box]), 1024)
    assert one.any() and not (one & ~own).any() and one.sum() < 0.9 * own.sum()
    # with two views: the pixels inside both tile boxes
    np.testing.assert_array_equal(two, one & boxes_mask(np.array([det.box]), 1024, planes=[other.edge_planes()]))
    assert 0 < two.sum() < one.sum()
    # a detection without a tile masks its panorama box in either mode
    np.testing.assert_array_equal(object_mask([plain], (512, 1024)), boxes_mask(np.array([plain.box]), 1024))
    assert not object_mask([], (512, 1024)).any()
    with pytest.raises(ValueError, match="mode: expected one of"):
        object_mask([det], (512, 1024), "silhouette")
    assert RunOptions().object_mask == "tiles"
    with pytest.raises(ValueError, match="object_mask: expected one of"):
        RunOptions(object_mask="silhouette")
