"""Tests of panogeom.lines: LSD segments lifted to great-circle arcs, merged, drawn."""

from __future__ import annotations

import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st

from panogeom.coords import pixel_to_ray, ray_to_pixel
from panogeom.lines import (
    VP_COLORS,
    LineSegments,
    detect_line_segments,
    draw_segments,
    line_views,
    lsd_segments,
    merge_collinear,
)
from panogeom.perspective import equirect_to_perspective
from panogeom.rotation import rot_x, rot_z
from panogeom.transform import pano_from_directions

sys.path.insert(0, str(Path(__file__).resolve().parent))
from synthetic_rooms import make_room, render_room  # noqa: E402


def unit(v):
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def step_pano(normals, height=256, ss=3):
    """Anti-aliased panorama whose only edges lie on the great circles of ``normals``."""
    normals = unit(normals)

    def f(d):
        parity = np.prod(np.sign(d @ normals.T), axis=1)
        return np.where(parity > 0, 200.0, 60.0)

    big = pano_from_directions(f, height * ss)
    return cv2.resize(big.astype(np.float32), (2 * height, height), interpolation=cv2.INTER_AREA).round().astype(
        np.uint8)


def angle_deg(n, m):
    """Angle between the lines (unsigned directions) n and m, degrees."""
    return np.rad2deg(np.arccos(np.clip(np.abs(np.sum(n * m, axis=-1)), 0.0, 1.0)))


# --- lsd_segments -------------------------------------------------------------------------------------------


def test_lsd_segments_subpixel_in_continuous_coordinates():
    ss, n = 8, 200
    yy, xx = np.mgrid[0:n * ss, 0:n * ss] / ss + 0.5 / ss  # continuous coordinates of sub-samples
    inside = (xx - 100.3) - 0.25 * (yy - 100.0) > 0
    img = (inside.reshape(n, ss, n, ss).mean(axis=(1, 3)) * 180 + 30).round().astype(np.uint8)
    seg, widths = lsd_segments(img)
    long = np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1]) > 100
    assert long.sum() == 1 and widths.shape == (len(seg),)
    s = seg[long][0]
    for u, v in (s[:2], s[2:]):
        assert abs(u - (100.3 + 0.25 * (v - 100.0))) < 0.1


@pytest.mark.parametrize("shape", [(-1, 4), (-1, 1, 4)])
def test_lsd_segments_accepts_opencv_4_and_5_layouts(monkeypatch, shape):
    lines = np.array([[10.0, 20.0, 30.0, 40.0], [1.0, 2.0, 3.0, 4.0]], np.float32).reshape(shape)

    class FakeLSD:
        def detect(self, img):
            return lines, np.array([[2.0], [3.0]], np.float32), None, None

    monkeypatch.setattr(cv2, "createLineSegmentDetector", lambda *a: FakeLSD())
    seg, w = lsd_segments(np.zeros((50, 50), np.uint8), scale=1.0)
    assert seg.shape == (2, 4) and np.allclose(seg[0], [10.5, 20.5, 30.5, 40.5]) and np.allclose(w, [2, 3])


def test_lsd_segments_blank_and_bad_input():
    seg, w = lsd_segments(np.full((40, 60), 90, np.uint8))
    assert seg.shape == (0, 4) and w.shape == (0,)
    with pytest.raises(ValueError, match=r"expected a \(h, w\) uint8 grey image, got shape \(4, 4, 3\)"):
        lsd_segments(np.zeros((4, 4, 3), np.uint8))
    with pytest.raises(ValueError, match="scale: expected a value in"):
        lsd_segments(np.zeros((4, 4), np.uint8), scale=2.0)


# --- LineSegments ---------------------------------------------------------------------------------------------

vec = st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3).filter(lambda v: np.linalg.norm(v) > 0.1)


@settings(max_examples=60, deadline=None)
@given(a=vec, b=vec)
def test_from_endpoints_properties(a, b):
    a, b = unit(a), unit(b)
    assume(np.linalg.norm(np.cross(a, b)) > 1e-6)
    s = LineSegments.from_endpoints([a], [b])
    assert np.isclose(np.linalg.norm(s.normals[0]), 1.0)
    assert abs(s.normals[0] @ s.a[0]) < 1e-12 and abs(s.normals[0] @ s.b[0]) < 1e-12
    assert np.isclose(s.lengths[0], np.arccos(np.clip(a @ b, -1, 1)), atol=1e-7)
    assert 0 < s.lengths[0] < np.pi and np.allclose(s.midpoints[0] @ s.normals[0], 0.0, atol=1e-12)


def test_degenerate_arcs_are_rejected():
    for b in ([0.0, 2.0, 0.0], [0.0, -1.0, 0.0]):  # same direction, antipodal
        with pytest.raises(ValueError, match="distinct, non-antipodal endpoints, got a degenerate arc"):
            LineSegments.from_endpoints([[0.0, 1.0, 0.0]], [b])
    with pytest.raises(ValueError, match="non-zero directions"):
        LineSegments.from_endpoints([[0.0, 0.0, 0.0]], [[1.0, 0.0, 0.0]])


def test_linesegments_checks_shapes_and_subsets():
    with pytest.raises(ValueError, match=r"LineSegments.normals: expected shape \(1, 3\), got \(2, 3\)"):
        LineSegments(np.zeros((1, 3)), np.zeros((1, 3)), np.zeros((2, 3)), np.zeros(1), np.zeros(1))
    with pytest.raises(ValueError, match=r"strength: expected shape \(2,\)"):
        LineSegments.from_endpoints(np.eye(3)[:2], np.eye(3)[1:], strength=[1.0])
    s = LineSegments.from_endpoints(np.eye(3), np.roll(np.eye(3), 1, axis=0), strength=[1.0, 2.0, 3.0])
    assert len(s) == 3 and len(LineSegments.empty()) == 0
    sub = s.subset(np.array([False, True, True]))
    assert len(sub) == 2 and np.allclose(sub.strength, [2.0, 3.0])


def test_rotated_moves_arcs_with_the_frame():
    rng = np.random.default_rng(3)
    a, b = unit(rng.normal(size=(20, 3))), unit(rng.normal(size=(20, 3)))
    s = LineSegments.from_endpoints(a, b)
    R = rot_z(0.7) @ rot_x(-0.3)
    r = s.rotated(R)
    ref = LineSegments.from_endpoints(a @ R.T, b @ R.T)
    assert np.allclose(r.normals, ref.normals) and np.allclose(r.lengths, s.lengths)


def test_polylines_split_at_the_seam():
    lon = np.deg2rad([170.0, -170.0])  # 20 degrees across the seam at lon = +-pi
    a = [np.cos(lon[0]), -np.sin(lon[0]), 0.1]
    b = [np.cos(lon[1]), -np.sin(lon[1]), 0.1]
    polys = LineSegments.from_endpoints([a], [b]).polylines(512, 256)
    assert len(polys) == 2
    for p in polys:
        assert np.ptp(p[:, 0]) < 20  # no piece jumps across the image


# --- merge_collinear ------------------------------------------------------------------------------------------


def on_circle(normal, t0, t1):
    """Endpoints at angles t0, t1 along the great circle of ``normal``."""
    n = unit(normal)
    e1 = unit(np.cross(n, [0.3, 0.2, 0.9]))
    e2 = np.cross(n, e1)
    return np.cos(t0) * e1 + np.sin(t0) * e2, np.cos(t1) * e1 + np.sin(t1) * e2


def test_merge_collinear_joins_overlaps_and_keeps_distinct_lines():
    d = np.deg2rad
    n = [0.2, -0.5, 0.8]
    pieces = [on_circle(n, d(0), d(30)), on_circle(n, d(25), d(60)), on_circle(n, d(60.5), d(70)),
              on_circle(n, d(90), d(100))]  # last one: 20 deg gap
    other = unit(np.array(n) + [0.0, 0.0, 0.05])  # about 1.5 deg away: a different line
    pieces.append(on_circle(other, d(10), d(40)))
    a, b = np.array([p[0] for p in pieces]), np.array([p[1] for p in pieces])
    m = merge_collinear(LineSegments.from_endpoints(a, b), angle=d(0.5), gap=d(1.0))
    assert sorted(np.rad2deg(m.lengths).round(6).tolist()) == [10.0, 30.0, 70.0]


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000))
@example(seed=1773)
def test_merge_collinear_covers_its_input_and_is_idempotent(seed):
    rng = np.random.default_rng(seed)
    normals = unit(rng.normal(size=(4, 3)))
    a, b = [], []
    for n in normals:
        for _ in range(rng.integers(1, 5)):
            t0 = rng.uniform(0, 2 * np.pi)
            p, q = on_circle(n + rng.normal(scale=1e-4, size=3), t0, t0 + rng.uniform(0.05, 0.8))
            a.append(p)
            b.append(q)
    s = LineSegments.from_endpoints(a, b)
    m = merge_collinear(s)
    assert len(m) <= len(s)
    # every input endpoint lies on (within the tolerance of) some merged arc's circle and span; a point off the
    # circle by delta next to an arc's end is up to about delta longer a way round its ends (two random circles
    # may lie within the merge angle of each other: seed 1773 has two 0.28 deg apart, merged into one arc)
    for p in np.concatenate([s.a, s.b]):
        off = np.abs(m.normals @ p)
        near = off < np.sin(np.deg2rad(0.6))
        span = np.arccos(np.clip(np.sum(m.a * p, 1), -1, 1)) + np.arccos(np.clip(np.sum(m.b * p, 1), -1, 1))
        assert np.any(near & (span <= m.lengths + np.arcsin(np.clip(off, 0, 1)) + 1e-3))
    again = merge_collinear(m)
    assert len(again) == len(m)


# --- line_views / detect_line_segments ------------------------------------------------------------------------


def test_line_views_cover_the_sphere_below_the_poles():
    views = line_views(1024)
    assert len(views) == 8 and all(v.width == v.height == 285 for v in views)
    uv = np.stack(np.meshgrid(np.linspace(0.5, 1023.5, 96), np.linspace(256 - 213, 256 + 213, 40)), -1)
    rays = pixel_to_ray(uv.reshape(-1, 2), 1024, 512)  # |lat| <= 75 deg
    seen = np.zeros(len(rays), bool)
    for v in views:
        p, front = v.ray_to_pixel(rays)
        seen |= front & (p[:, 0] >= 0) & (p[:, 0] <= v.width) & (p[:, 1] >= 0) & (p[:, 1] <= v.height)
    assert seen.all()
    with pytest.raises(ValueError, match="n: expected a positive integer, got 0"):
        line_views(1024, n=0)


def test_detect_segments_on_known_great_circles():
    circles = unit(np.array([[0.1, 0.2, 1.0], [1.0, -0.3, 0.15], [-0.2, 1.0, 0.4]]))
    pano = step_pano(circles)
    segs = detect_line_segments(pano)
    err = np.min([angle_deg(segs.normals, c) for c in circles], axis=0)
    # pieces bending round the X-junctions where circles cross are the only outliers
    assert segs.lengths[err < 0.1].sum() > 0.9 * segs.lengths.sum()
    assert segs.lengths[err < 0.03].sum() > 0.5 * segs.lengths.sum()
    # duplicates from overlapping views are merged: per circle, no more than 2*pi in total
    for c in circles:
        mine = angle_deg(segs.normals, c) < 0.3
        assert 1.2 * np.pi < segs.lengths[mine].sum() <= 2.0 * np.pi * 1.01
    assert np.all(segs.lengths >= np.deg2rad(2.5))


def test_detect_segments_grey_float_and_rgb_agree():
    pano = step_pano([[0.3, 0.1, 1.0]], height=128)
    a = detect_line_segments(pano)
    b = detect_line_segments(pano.astype(np.float32) / 255.0)
    c = detect_line_segments(np.repeat(pano[..., None], 3, axis=2))
    assert len(a) == len(b) == len(c) > 0
    assert np.allclose(a.normals, c.normals)


def test_detect_segments_blank_is_empty_and_checks_input():
    assert len(detect_line_segments(np.full((128, 256, 3), 77, np.uint8))) == 0
    with pytest.raises(ValueError, match=r"W == 2\*H, got 300x128"):
        detect_line_segments(np.zeros((128, 300), np.uint8))
    with pytest.raises(ValueError, match="min_contrast: expected a finite value >= 0, got -1"):
        detect_line_segments(np.zeros((128, 256), np.uint8), min_contrast=-1)


def test_detect_segments_on_a_room_lie_on_its_edges():
    room = make_room(7)
    R = rot_z(0.4)  # upright: every structural line is vertical or horizontal along x/y of rot_z(0.4)
    pano = render_room(room, R, 512)
    segs = detect_line_segments(pano)
    axes = R  # rows: world axes in the camera frame (R maps camera to world)
    err = np.rad2deg(np.arcsin(np.min(np.abs(segs.normals @ axes.T), axis=1)))
    w = segs.lengths
    assert len(segs) > 100
    assert np.sum(w[err < 1.0]) / w.sum() > 0.65  # most of the length is Manhattan (rest: clutter, junctions)


# --- draw_segments --------------------------------------------------------------------------------------------


def test_draw_segments_colours_arcs_and_respects_the_seam():
    h, w = 128, 256
    img = np.zeros((h, w, 3), np.uint8)
    lon = np.deg2rad([150.0, -150.0, 0.0])
    lat = np.deg2rad(10.0)
    a = [np.cos(lat) * np.cos(lon[0]), -np.cos(lat) * np.sin(lon[0]), np.sin(lat)]
    b = [np.cos(lat) * np.cos(lon[1]), -np.cos(lat) * np.sin(lon[1]), np.sin(lat)]
    v0, v1 = [1.0, 0.0, 0.5], [1.0, 0.0, -0.5]  # vertical segment through the centre column
    s = LineSegments.from_endpoints([a, v0], [b, v1])
    out = draw_segments(img, s, labels=[-1, 2], thickness=3)
    assert out.shape == (h, w, 3) and out.dtype == np.uint8 and not np.shares_memory(out, img)
    u, v = ray_to_pixel(np.array([1.0, 0.0, 0.0]), w, h).astype(int)
    assert np.abs(out[v, u].astype(int) - VP_COLORS[2]).max() <= 2
    row = int(ray_to_pixel(np.array(a), w, h)[1])
    drawn = out[row - 1:row + 2].max(axis=(0, 2)) > 0
    assert drawn[:10].any() and drawn[-10:].any() and not drawn[60:100].any()  # two pieces, not across the image
    assert np.all(out[row - 1:row + 2][out[row - 1:row + 2].max(axis=2) > 0][:, 0] <= 150)  # grey, unlabelled
    with pytest.raises(ValueError, match=r"labels: expected shape \(2,\), got \(3,\)"):
        draw_segments(img, s, labels=[0, 1, 2])


def test_views_of_a_room_show_the_segments_where_lsd_found_them():
    # the arcs lifted from one view project back onto that view's LSD segments
    room = make_room(2)
    pano = render_room(room, np.eye(3), 512)
    view = line_views(512)[0]
    tile = equirect_to_perspective(cv2.cvtColor(pano, cv2.COLOR_RGB2GRAY), view)
    seg, _ = lsd_segments(tile)
    long = seg[np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1]) > 30]
    segs = detect_line_segments(pano, [view], merge_angle=0.0, merge_gap=0.0)
    ua, _ = view.ray_to_pixel(segs.a)
    ub, _ = view.ray_to_pixel(segs.b)
    back = np.concatenate([ua, ub], axis=1)
    for s in long:
        d = np.minimum(np.abs(back - s).max(axis=1), np.abs(back - np.r_[s[2:], s[:2]]).max(axis=1))
        assert d.min() < 1e-3
