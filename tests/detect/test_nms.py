"""Overlap and NMS on the sphere: exact forms against brute force, seam and poles, merging across tiles."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from detect.detection import Detection, ImageDetection
from detect.nms import (box_iou, box_nms, merge_sphere, nms_sphere, pano_box_iou, pano_box_solid_angle, region_contains,
                        solid_angle, spherical_overlaps, suppress_across_classes)
from detect.tiles import box_in_view, tile_consensus, to_panorama
from panogeom.coords import pixel_grid_rays
from panogeom.perspective import PinholeView, detection_views

W, H = 512, 256


def _brute_iou(a_mask: np.ndarray, b_mask: np.ndarray) -> float:
    """IoU by summing cos(lat)-weighted pixels of a fine equirectangular grid."""
    h = a_mask.shape[0]
    lat = np.pi / 2 - np.pi * (np.arange(h) + 0.5) / h
    w = np.cos(lat)[:, None]
    return float((w * (a_mask & b_mask)).sum() / (w * (a_mask | b_mask)).sum())


def _brute_rect_iou(a, b, n: int = 400000) -> float:
    """IoU of two lon/lat rectangles by fine 1-D quadrature (the regions are products of intervals)."""
    u = (np.arange(n) + 0.5) * W / n
    v = (np.arange(n) + 0.5) * H / n
    wv = np.cos(np.pi / 2 - np.pi * v / H)

    def in_u(x):
        return (u >= x[0]) & (u <= x[2]) if x[2] > x[0] else (u >= x[0]) | (u <= x[2])

    def in_v(x):
        return (v >= x[1]) & (v <= x[3])

    def area(mu, mv):
        return mu.sum() * (wv * mv).sum()

    inter = area(in_u(a) & in_u(b), in_v(a) & in_v(b))
    return float(inter / (area(in_u(a), in_v(a)) + area(in_u(b), in_v(b)) - inter))


boxes = st.tuples(st.floats(0, W - 1), st.floats(0, H - 10), st.floats(4, W / 2), st.floats(8, H / 2)).map(
    lambda t: [t[0], t[1], (t[0] + t[2]) % W or W, min(H, t[1] + t[3])])


@settings(max_examples=30, deadline=None)
@given(boxes, boxes)
def test_pano_box_iou_matches_brute_force(a, b):
    exact = pano_box_iou([a], [b], W, H)[0, 0]
    assert exact == pytest.approx(_brute_rect_iou(a, b), abs=2e-3)


@settings(max_examples=30, deadline=None)
@given(boxes, boxes, st.floats(0, W))
def test_pano_box_iou_is_invariant_to_turning_around_the_seam(a, b, shift):
    def turn(x):
        u0, u1 = (x[0] + shift) % W, (x[2] + shift) % W or W
        return [u0 if u0 < W else 0.0, x[1], u1, x[3]]
    assert pano_box_iou([a], [b], W, H)[0, 0] == pytest.approx(pano_box_iou([turn(a)], [turn(b)], W, H)[0, 0],
                                                               abs=1e-9)


def test_solid_angles_are_exact():
    assert pano_box_solid_angle([[0, 0, W, H]], W, H)[0] == pytest.approx(4 * np.pi)
    # a 90 degree square tile box covers 1/6 of the sphere
    v = detection_views(100)[0]
    whole = to_panorama(ImageDetection("tv", 1.0, [0, 0, 100, 100]), v, W, H)
    assert solid_angle(whole) == pytest.approx(4 * np.pi / 6)


def test_polar_boxes_count_less_than_equatorial_ones():
    eq = pano_box_solid_angle([[0, 118, 50, 138]], W, H)[0]
    polar = pano_box_solid_angle([[0, 0, 50, 20]], W, H)[0]
    assert polar < 0.2 * eq


def test_sampled_overlap_of_tile_boxes_matches_brute_force():
    views = detection_views(200)
    a = to_panorama(ImageDetection("chair", 1.0, [60, 80, 190, 170]), views[0], W, H)   # yaw 0
    b = to_panorama(ImageDetection("chair", 1.0, [10, 70, 120, 160]), views[1], W, H)   # yaw 30 deg
    c = to_panorama(ImageDetection("chair", 1.0, [40, 20, 160, 120]), views[12], W, H)  # low ring, pitch -50
    rays = pixel_grid_rays(2 * W, 2 * H).reshape(-1, 3)
    masks = region_contains([a, b, c], rays).reshape(3, 2 * H, 2 * W)
    iou, inside = spherical_overlaps([a, b, c], samples=24)
    for i, j in [(0, 1), (0, 2), (1, 2)]:
        assert iou[i, j] == pytest.approx(_brute_iou(masks[i], masks[j]), abs=0.03)
    assert np.allclose(iou, iou.T) and np.allclose(np.diag(iou), 1.0)
    assert 0.0 <= inside.min() and inside.max() <= 1.0 + 1e-9


def _same_object_in(view_a, view_b, box_a, label="chair"):
    """The same object seen in two tiles: box_a in view_a, and its box as seen in view_b."""
    da = to_panorama(ImageDetection(label, 0.9, box_a), view_a, W, H, index=0)
    bb = box_in_view(da, view_b)
    db = to_panorama(ImageDetection(label, 0.7, bb).clipped(view_b.width, view_b.height), view_b, W, H, index=1)
    return da, db


def test_nms_merges_one_object_seen_in_two_tiles_across_the_seam():
    views = detection_views(200)
    # views 5 and 6 look at yaw 150 and 180 degrees: the seam (lon = -pi) is in the middle of view 6
    # (yaw grows to the left in the panorama, so view 5 is right of view 6)
    da, db = _same_object_in(views[6], views[5], [120, 90, 170, 150])
    merged = nms_sphere([da, db])
    assert len(merged) == 1
    assert merged[0].support == 2 and merged[0].score == 0.9
    # an object straddling the seam
    dc, dd = _same_object_in(views[6], views[5], [80, 90, 120, 150])
    assert dc.wraps
    assert len(nms_sphere([dc, dd])) == 1


def _object_at(yaw_deg, pitch_deg, half=20, label="chair", score=1.0):
    """An object region: the footprint of a centred box in a virtual view pointing at (yaw, pitch)."""
    virt = PinholeView(np.deg2rad(yaw_deg), np.deg2rad(pitch_deg), 0.0, np.pi / 2, 200, 200)
    return to_panorama(ImageDetection(label, score, [100 - half, 100 - half, 100 + half, 100 + half]), virt, W, H)


def test_nms_merges_one_object_near_the_nadir_seen_by_two_low_tiles():
    views = detection_views(200)
    obj = _object_at(45, -75)  # between views 12 and 13 (pitch -50, yaw 15 and 75 degrees), close to the nadir
    da = to_panorama(ImageDetection("chair", 0.9, box_in_view(obj, views[12])), views[12], W, H)
    db = to_panorama(ImageDetection("chair", 0.8, box_in_view(obj, views[13])), views[13], W, H)
    for d in (da, db):  # both extents span the full width and reach the bottom row
        assert (d.box[0], d.box[2], d.box[3]) == (0.0, W, H)
    assert spherical_overlaps([da, db])[0][0, 1] > 0.6
    assert len(nms_sphere([da, db])) == 1
    # two different objects on opposite sides of the nadir have full-width extents too, but are not merged
    far = _object_at(225, -75)
    other = to_panorama(ImageDetection("chair", 0.7, box_in_view(far, views[15])), views[15], W, H)
    assert other.box[0] == 0.0 and other.box[2] == W
    assert pano_box_iou([da.box], [other.box], W, H)[0, 0] > 0.5  # what a lon/lat-box NMS would see
    assert spherical_overlaps([da, other])[0][0, 1] < 0.05
    assert len(nms_sphere([da, other])) == 2


def test_nms_is_class_aware_and_keeps_separate_objects():
    views = detection_views(200)
    da, db = _same_object_in(views[0], views[1], [40, 80, 100, 150])
    other = to_panorama(ImageDetection("table", 0.95, [40, 80, 100, 150]), views[0], W, H)
    far = to_panorama(ImageDetection("chair", 0.5, [140, 80, 195, 150]), views[0], W, H)
    merged = nms_sphere([da, db, other, far])
    assert sorted((d.label, d.support) for d in merged) == [("chair", 1), ("chair", 2), ("table", 1)]
    assert len(nms_sphere([da, db, other], class_aware=False)) == 1


def test_nms_prefers_a_whole_view_over_a_truncated_one():
    views = detection_views(200)
    whole = to_panorama(ImageDetection("sofa", 0.6, [60, 80, 140, 150]), views[0], W, H, index=0)
    bb = box_in_view(whole, views[2])  # yaw 60 degrees: the object is cut by the tile's left border
    cut = ImageDetection("sofa", 0.9, bb).clipped(200, 200)
    part = to_panorama(cut, views[2], W, H, index=2)
    assert part.tile.truncated and not whole.tile.truncated
    merged = nms_sphere([part, whole])
    assert len(merged) == 1
    assert merged[0].tile.index == 0 and merged[0].score == 0.9


def test_the_representative_is_the_box_most_tiles_agree_on():
    """Three tiles box one object tightly, a fourth (best score) loosely: the merged box is a tight one."""
    views = detection_views(200)
    obj = _object_at(15, -25, half=25)  # seen whole by views 0, 1 (pitch 0) and 12 (pitch -50)
    tight = [to_panorama(ImageDetection("chair", s, box_in_view(obj, views[k])), views[k], W, H, index=k)
             for k, s in ((0, 0.7), (1, 0.65), (12, 0.6))]
    b = box_in_view(obj, views[0])
    loose = to_panorama(ImageDetection("chair", 0.9, b + np.array([-8.0, -8.0, 8.0, 8.0])), views[0], W, H,
                        index=0)
    (merged, members), = merge_sphere([loose, *tight])
    assert len(members) == 4 and merged.score == 0.9 and merged.support == 4
    assert any(merged.tile == t.tile for t in tight)
    assert spherical_overlaps([merged, obj])[0][0, 1] > spherical_overlaps([loose, obj])[0][0, 1] + 0.15
    assert [d.box.tolist() for d in nms_sphere([loose, *tight])] == [merged.box.tolist()]


def test_merged_views_are_the_whole_views_that_score_enough_representative_first():
    views = detection_views(200)
    obj = _object_at(15, -25, half=25)  # seen whole by views 0, 1 and 12
    whole = [to_panorama(ImageDetection("chair", s, box_in_view(obj, views[k])), views[k], W, H, index=k)
             for k, s in ((0, 0.7), (1, 0.65), (12, 0.1))]
    cut = to_panorama(ImageDetection("chair", 0.9, box_in_view(obj, views[2])).clipped(200, 200), views[2], W, H,
                      index=2)
    assert cut.tile.truncated
    (merged, members), = merge_sphere([*whole, cut])
    assert len(members) == 4
    # the truncated view and the one scoring under view_score (0.2) are left out; the representative comes first
    assert len(merged.views) == 2 and merged.views[0] == merged.tile
    assert {t.index for t in merged.views} == {0, 1}
    (low, _), = merge_sphere([*whole, cut], view_score=0.05)
    assert {t.index for t in low.views} == {0, 1, 12}
    (one, _), = merge_sphere(whole, max_views=2)
    assert len(one.views) == 2
    # a single whole view: no views
    (alone, _), = merge_sphere([whole[0], cut])
    assert alone.views == ()
    with pytest.raises(ValueError, match="max_views"):
        merge_sphere(whole, max_views=0)
    with pytest.raises(ValueError, match="view_score"):
        merge_sphere(whole, view_score=1.5)


def test_one_object_called_two_classes_keeps_its_best_class_only():
    views = detection_views(200)
    obj = _object_at(15, -25, half=25)
    bed = to_panorama(ImageDetection("bed", 0.63, box_in_view(obj, views[0])), views[0], W, H, index=0)
    sofa = to_panorama(ImageDetection("sofa", 0.57, box_in_view(obj, views[1]) + 1.0), views[1], W, H, index=1)
    near = _object_at(15, -25, half=12, label="chair", score=0.9)  # a smaller object inside: IoU about 0.2
    other_bed = _object_at(120, -25, half=25, label="bed", score=0.5)
    assert spherical_overlaps([bed, sofa])[0][0, 1] > 0.8
    kept = suppress_across_classes([sofa, other_bed, bed, near])
    assert [d.label for d in kept] == ["chair", "bed", "bed"] and kept[1] is bed
    # the same class is the merge's business, not this one's
    twin = to_panorama(ImageDetection("bed", 0.6, box_in_view(obj, views[1])), views[1], W, H, index=1)
    assert len(suppress_across_classes([bed, twin])) == 2
    assert suppress_across_classes([sofa, bed], iou_threshold=1.0) == [bed, sofa]
    assert suppress_across_classes([]) == []
    with pytest.raises(ValueError, match="iou_threshold"):
        suppress_across_classes([bed], iou_threshold=2.0)


def test_tile_consensus_ranks_what_most_tiles_find_above_what_one_tile_finds():
    views = detection_views(200)
    obj = _object_at(15, -25, half=25)
    seen = []
    for k, v in enumerate(views):  # the tiles that see the object whole (inside by 2 % of the width)
        try:
            b = box_in_view(obj, v)
        except ValueError:  # partly behind the view
            continue
        if b[0] >= 4 and b[1] >= 4 and b[2] <= 196 and b[3] <= 196:
            seen.append(k)
    assert len(seen) >= 2
    found = [to_panorama(ImageDetection("tv", 0.8, box_in_view(obj, views[k])), views[k], W, H, index=k)
             for k in seen]
    # the same score from one tile only: a false box
    lone = to_panorama(ImageDetection("plant", 0.85, box_in_view(obj, views[seen[0]])), views[seen[0]], W, H,
                       index=seen[0])
    out = tile_consensus(merge_sphere([*found, lone]), views)
    assert [d.label for d in out] == ["tv", "plant"]
    assert out[0].score == pytest.approx(0.8)
    assert out[1].score == pytest.approx(0.5 * 0.85 + 0.5 * 0.85 / len(seen))
    # weight 0: the best member's score
    assert [d.score for d in tile_consensus(merge_sphere([*found, lone]), views, 0.0)] == [0.85, 0.8]
    with pytest.raises(ValueError, match=r"weight: expected a number in \[0, 1\]"):
        tile_consensus([], views, 1.5)


def test_nms_checks_its_thresholds():
    with pytest.raises(ValueError, match=r"iou_threshold: expected a number in \[0, 1\], got 2"):
        nms_sphere([], iou_threshold=2)
    assert nms_sphere([]) == []


def test_planar_box_nms_per_class():
    b = [[0, 0, 10, 10], [1, 1, 10, 10], [0, 0, 10, 10]]
    assert box_nms(b, [0.9, 0.8, 0.7], 0.5).tolist() == [0]
    assert box_nms(b, [0.9, 0.8, 0.7], 0.5, labels=["a", "a", "b"]).tolist() == [0, 2]
    assert box_iou([[0, 0, 1, 1]], [[2, 2, 3, 3]])[0, 0] == 0.0
    with pytest.raises(ValueError, match=r"scores: expected shape \(3,\), got \(2,\)"):
        box_nms(b, [0.9, 0.8])


def test_region_of_a_rect_detection_contains_its_pixels():
    d = Detection("bed", 1.0, [500, 100, 20, 140], W, H)
    rays = pixel_grid_rays(W, H)
    inside = region_contains([d], rays.reshape(-1, 3))[0].reshape(H, W)
    assert inside[120, 505] and inside[120, 10] and not inside[120, 30] and not inside[90, 505]
