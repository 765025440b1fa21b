"""Tests of layout.metrics (IoU, corner, pixel, height errors) and layout.corners (corners_px round trips)."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from layout.corners import (
    corners_from_horizonnet,
    corners_px_to_polygon,
    corners_to_horizonnet,
    polygon_to_corners_px,
)
from layout.metrics import (
    corner_error,
    corner_error_px,
    intersection_area,
    iou_2d,
    iou_3d,
    pixel_error,
    polygon_area,
    score_layout,
    wall_height_error,
)
from layout.polygon import points_in_polygon
from layout.rooms import generate_room

SHARED = Path(__file__).resolve().parents[2].parent / "shared"
SCORE_SCENE = SHARED / "tools" / "score_scene.py"
REAL = SHARED / "data" / "real"

SQ = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]])
L_ROOM = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 1.0], [1.0, 1.0], [1.0, 4.0], [0.0, 4.0]])


def _raster_intersection(a, b, n=600):
    lo = np.minimum(a.min(0), b.min(0))
    hi = np.maximum(a.max(0), b.max(0))
    step = float(np.max(hi - lo)) / n
    xs = np.arange(lo[0] + step / 2, hi[0], step)
    ys = np.arange(lo[1] + step / 2, hi[1], step)
    g = np.stack(np.meshgrid(xs, ys), -1).reshape(-1, 2)
    return float(np.sum(points_in_polygon(g, a) & points_in_polygon(g, b)) * step * step)


def test_intersection_of_shifted_squares_and_iou():
    assert intersection_area(SQ, SQ + [1.0, 1.0]) == pytest.approx(1.0)
    assert iou_2d(SQ, SQ + [1.0, 1.0]) == pytest.approx(1.0 / 7.0)
    assert iou_2d(SQ, SQ + [5.0, 0.0]) == 0.0
    assert iou_2d(SQ, SQ[::-1]) == pytest.approx(1.0)  # orientation does not matter


def test_intersection_of_non_convex_and_skew_polygons_matches_fine_raster():
    skew = np.array([[0.3, -0.5], [3.5, 0.2], [2.8, 3.1], [-0.4, 2.2]])
    got = intersection_area(L_ROOM, skew)
    assert got == pytest.approx(_raster_intersection(L_ROOM, skew, 1200), rel=5e-3)
    tri = np.array([[0.0, 0.0], [4.0, 4.0], [0.0, 4.0]])
    # y >= x inside the L: a triangle of 0.5 in the lower arm plus the whole 1 x 3 upper arm
    assert intersection_area(L_ROOM, tri) == pytest.approx(3.5, abs=1e-12)


@settings(max_examples=25, deadline=None)
@given(seed_a=st.integers(0, 10_000), seed_b=st.integers(0, 10_000),
       shift=st.tuples(st.floats(-1.5, 1.5), st.floats(-1.5, 1.5)))
def test_iou_properties_on_generated_rooms(seed_a, seed_b, shift):
    a = generate_room(seed_a).floor
    b = generate_room(seed_b).floor + np.asarray(shift)
    inter = intersection_area(a, b)
    assert inter == pytest.approx(intersection_area(b, a), abs=1e-9)
    assert -1e-12 <= inter <= min(polygon_area(a), polygon_area(b)) + 1e-9
    assert iou_2d(a, a) == pytest.approx(1.0)
    assert 0.0 <= iou_2d(a, b) <= 1.0
    assert 0.0 <= iou_3d(a, 2.5, b, 2.7) <= 1.0
    assert inter == pytest.approx(_raster_intersection(a, b, 400), abs=0.02 * max(polygon_area(a), polygon_area(b)))


def test_iou_3d_extrusion():
    assert iou_3d(SQ, 2.0, SQ, 2.0) == pytest.approx(1.0)
    assert iou_3d(SQ, 3.0, SQ, 1.5) == pytest.approx(0.5)
    assert iou_3d(SQ, 2.0, SQ + [1.0, 0.0], 2.0) == pytest.approx(iou_2d(SQ, SQ + [1.0, 0.0]))
    assert iou_3d(SQ, 3.0, SQ, 3.0, a_floor_z=1.0) == pytest.approx(2.0 / 3.0)
    with pytest.raises(ValueError, match="ceilings above floors"):
        iou_3d(SQ, 0.0, SQ, 2.0)


@pytest.mark.skipif(not SCORE_SCENE.is_file(), reason="shared/tools/score_scene.py is absent")
@pytest.mark.parametrize("seed", range(6))
def test_iou_agrees_with_the_projects_rasterised_scorer(seed):
    spec = importlib.util.spec_from_file_location("score_scene", SCORE_SCENE)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    rng = np.random.default_rng(seed)
    a = generate_room(rng)
    b = generate_room(rng)
    shift = rng.uniform(-1, 1, 2)
    gt = {"room": {"floor": a.floor.tolist(), "ceiling_z": a.ceiling_z}}
    scene = {"room": {"floor": (b.floor * 0.8 + shift).tolist(), "ceiling_z": b.ceiling_z, "floor_z": 0.0}}
    ref = mod.score_room(scene, gt)
    assert iou_2d(b.floor * 0.8 + shift, a.floor) == pytest.approx(ref["iou2d"], abs=0.01)
    assert iou_3d(b.floor * 0.8 + shift, b.ceiling_z, a.floor, a.ceiling_z) == pytest.approx(ref["iou3d"], abs=0.01)
    assert wall_height_error(b.ceiling_z, a.ceiling_z) == pytest.approx(ref["height_err"])


def test_corner_error_matches_regardless_of_order():
    pred = np.roll(SQ + [0.1, 0.0], 2, axis=0)
    e = corner_error(pred, SQ)
    assert e.mean == pytest.approx(0.1) and e.max == pytest.approx(0.1) and e.same_count
    e2 = corner_error(L_ROOM, SQ)
    assert e2.n_matched == 4 and not e2.same_count


def test_corner_error_px_is_seam_aware_and_zero_for_identity():
    c = polygon_to_corners_px(SQ - 1.0, 2.7, 1.6, 1024)
    assert corner_error_px(c, c, 1024) == 0.0
    assert corner_error_px([[1023.0, 100, 1023.0, 400]], [[1.0, 100, 1.0, 400]], 1024) == pytest.approx(
        100 * 2 / np.hypot(1024, 512))


def test_pixel_error_is_zero_for_the_same_room_and_symmetric():
    a = L_ROOM - [0.5, 0.5]
    b = a * 1.1
    assert pixel_error(a, 2.7, a, 2.7, 1.6, 256) == 0.0
    e_ab = pixel_error(a, 2.7, b, 2.9, 1.6, 256)
    assert e_ab > 0 and e_ab == pytest.approx(pixel_error(b, 2.9, a, 2.7, 1.6, 256))
    assert pixel_error(a, 2.7, b, 2.9, 1.6, 256, classes="labels") >= e_ab


def test_score_layout_bundles_the_scores():
    a = L_ROOM - [0.5, 0.5]
    s = score_layout(a, 2.7, a * 1.05, 2.8, 1.6, 512)
    assert 0.8 < s.iou_3d < s.iou_2d < 1.0
    assert s.corners_ok and s.height_error == pytest.approx(0.1)
    assert s.corner_error.mean > 0 and s.corner_error_px > 0 and s.pixel_error > 0


# ---------------------------------------------------------------- corners_px


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), cam_h=st.floats(0.8, 2.0))
def test_corners_round_trip(seed, cam_h):
    from layout.labelmap import sample_camera_xy

    room = generate_room(seed)
    cam = sample_camera_xy(room.floor, seed, margin=0.5)
    floor = room.floor - cam
    ceil = max(room.ceiling_z, cam_h + 0.3)
    c = polygon_to_corners_px(floor, ceil, cam_h, 1024)
    assert c.shape == (len(floor), 4)
    np.testing.assert_allclose(c[:, 0], c[:, 2])  # vertical wall corners share their column
    assert np.all(c[:, 1] < 256) and np.all(c[:, 3] > 256)
    back = corners_px_to_polygon(c, 1024, camera_height=cam_h)
    np.testing.assert_allclose(back.floor, floor, atol=1e-9)
    assert back.ceiling_z == pytest.approx(ceil) and not back.reversed


def test_clockwise_corners_come_back_counter_clockwise():
    c = polygon_to_corners_px(SQ - 1.0, 2.7, 1.6, 1024)
    back = corners_px_to_polygon(c[::-1], 1024, camera_height=1.6)
    assert back.reversed
    np.testing.assert_allclose(back.floor[0], (SQ - 1.0)[-1], atol=1e-9)


def test_horizonnet_text_round_trip():
    c = polygon_to_corners_px(L_ROOM - 0.5, 2.7, 1.6, 1024)
    text = corners_to_horizonnet(c)
    assert len(text.splitlines()) == 2 * len(c)
    np.testing.assert_allclose(corners_from_horizonnet(text), c, atol=1e-3)
    with pytest.raises(ValueError, match="even number"):
        corners_from_horizonnet("1 2\n3 4\n5 6")


def test_corners_above_the_horizon_are_refused():
    with pytest.raises(ValueError, match="below the horizon"):
        corners_px_to_polygon([[10, 100, 10, 200], [300, 100, 300, 400], [600, 100, 600, 400]], 1024,
                              camera_height=1.6)


@pytest.mark.skipif(not REAL.is_dir(), reason="shared/data/real is absent")
@pytest.mark.parametrize("name", sorted(p.name for p in REAL.iterdir() if (p / "gt.json").is_file())
                         if REAL.is_dir() else [])
def test_real_gt_corners_px_match_their_polygon(name):
    gt = json.loads((REAL / name / "gt.json").read_text())
    w, h = gt["image"]["width"], gt["image"]["height"]
    back = corners_px_to_polygon(gt["corners_px"], w, h, camera_height=gt["camera_height_m"])
    np.testing.assert_allclose(back.floor, gt["room"]["floor"], atol=2e-3)
    assert back.ceiling_z == pytest.approx(gt["room"]["ceiling_z"], abs=5e-3)
    again = polygon_to_corners_px(gt["room"]["floor"], gt["room"]["ceiling_z"], gt["camera_height_m"], w, h)
    assert corner_error_px(again, gt["corners_px"], w, h) < 0.1
