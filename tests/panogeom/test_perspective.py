"""Tests of panogeom.perspective: pinhole views of a panorama and back-projection."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from panogeom.coords import pixel_to_ray, ray_to_lonlat, ray_to_pixel
from panogeom.perspective import (
    PinholeView,
    arc_points,
    box_to_pano,
    detection_views,
    equirect_to_perspective,
    layout_views,
    pano_box_union,
    pano_to_perspective,
    perspective_to_pano,
    ring_views,
    segment_to_arc,
)
from panogeom.sampling import sample_equirect
from panogeom.transform import pano_from_directions, procedural_pano

W, H = 2048, 1024


def in_extent(uv, ext, width, tol=1e-6):
    """Seam-aware containment of pixel points in an extent (u0 > u1 wraps)."""
    u, v = uv[..., 0], uv[..., 1]
    ok_v = (v >= ext[1] - tol) & (v <= ext[3] + tol)
    if ext[0] <= ext[2]:
        ok_u = (u >= ext[0] - tol) & (u <= ext[2] + tol)
    else:
        ok_u = (u >= ext[0] - tol) | (u <= ext[2] + tol)
    return ok_u & ok_v


def test_intrinsics():
    v = PinholeView(0.0, 0.0, 0.0, np.pi / 2, 640, 480)
    assert np.isclose(v.focal, 320.0)
    assert np.allclose(v.K, [[320, 0, 320], [0, 320, 240], [0, 0, 1]])
    # the principal point looks along the optical axis, which is +x for yaw 0
    assert np.allclose(v.pixel_to_ray([320.0, 240.0]), [1, 0, 0])
    assert np.allclose(v.direction, [1, 0, 0])
    # the left and right image edges are 45 degrees off axis
    assert np.isclose(np.degrees(np.arccos(v.pixel_to_ray([0.0, 240.0])[0])), 45.0)


@settings(max_examples=150, deadline=None)
@given(yaw=st.floats(-4, 4), pitch=st.floats(-1.57, 1.57), roll=st.floats(-3, 3),
       fov=st.floats(0.05, 3.0), u=st.floats(0, 300), v=st.floats(0, 200))
def test_view_pixel_ray_round_trip(yaw, pitch, roll, fov, u, v):
    view = PinholeView(yaw, pitch, roll, fov, 300, 200)
    ray = view.pixel_to_ray([u, v])
    assert np.isclose(np.linalg.norm(ray), 1.0)
    back, front = view.ray_to_pixel(ray)
    assert front
    assert np.abs(back - [u, v]).max() < 1e-6 * max(1.0, view.focal / 100)
    # and through the panorama
    pano_uv = perspective_to_pano([u, v], view, W, H)
    back2, front2 = pano_to_perspective(pano_uv, view, W, H)
    assert front2 and np.abs(back2 - [u, v]).max() < 1e-5 * max(1.0, view.focal / 100)


def test_view_orientation_in_the_panorama():
    for yaw in np.radians([0.0, 50.0, -120.0, 180.0]):
        view = PinholeView(float(yaw), 0.0, 0.0, np.pi / 2, 64, 48)
        c = perspective_to_pano([32.0, 24.0], view, W, H)
        # a view at yaw a is centred on lon = -a
        assert np.isclose(np.mod(ray_to_lonlat(pixel_to_ray(c, W, H))[0] + yaw + np.pi, 2 * np.pi), np.pi)
        right = perspective_to_pano([40.0, 24.0], view, W, H)
        up = perspective_to_pano([32.0, 10.0], view, W, H)
        assert 0 < (right[0] - c[0]) % W < W / 2          # image right is panorama right
        assert up[1] < c[1]                                 # image up is panorama up
    # positive roll turns the scene counter-clockwise in the view: world up appears upper left
    view = PinholeView(0.0, 0.0, 0.3, np.pi / 2, 64, 48)
    uv, _ = view.ray_to_pixel([1.0, 0.0, 0.2])
    assert uv[0] < 32 and uv[1] < 24


def test_points_behind_the_view_are_flagged():
    view = PinholeView(0.0, 0.0, 0.0, np.pi / 2, 64, 48)
    _, front = view.ray_to_pixel([[-1.0, 0.0, 0.0], [1.0, 0.2, 0.0], [0.0, 1.0, 0.0]])
    assert front.tolist() == [False, True, False]


def render_dots(points, sigma, height):
    """Analytic panorama (float32) with a Gaussian spot at the direction of each point."""
    dirs = points / np.linalg.norm(points, axis=1, keepdims=True)

    def spots(d):
        return np.exp(-np.maximum(1.0 - d @ dirs.T, 0.0).min(axis=1) / sigma ** 2)

    return pano_from_directions(spots, height).astype(np.float32)


@pytest.mark.parametrize("yaw_deg, pitch_deg, roll_deg, fov_deg", [
    (0.0, 0.0, 0.0, 90.0),
    (180.0, 0.0, 0.0, 90.0),      # across the seam
    (-65.0, 20.0, 10.0, 75.0),
    (130.0, 78.0, 0.0, 90.0),     # the zenith inside the view
    (30.0, -85.0, -20.0, 100.0),  # the nadir inside the view
])
def test_dots_land_where_the_pinhole_model_says(yaw_deg, pitch_deg, roll_deg, fov_deg):
    view = PinholeView(*np.radians([yaw_deg, pitch_deg, roll_deg, fov_deg]), 400, 300)
    rng = np.random.default_rng(int(abs(yaw_deg) + pitch_deg + 100))
    # a jittered 4 x 3 grid keeps the spots apart; the corner cells reach 15 px from the border
    gu, gv = np.meshgrid(np.arange(4) * 100 + 50.0, np.arange(3) * 100 + 50.0)
    target = np.stack([gu.ravel(), gv.ravel()], axis=1) + rng.uniform(-35, 35, (12, 2))
    points = view.pixel_to_ray(target) * rng.uniform(1.0, 8.0, (12, 1))   # camera-centred 3D points
    img = equirect_to_perspective(render_dots(points, np.radians(0.6), 512), view)
    expected, front = view.ray_to_pixel(points)
    assert front.all()
    yy, xx = np.mgrid[0:300, 0:400] + 0.5
    for (eu, ev) in expected:
        wgt = img * ((np.abs(xx - eu) < 8) & (np.abs(yy - ev) < 8))
        cu, cv = (wgt * xx).sum() / wgt.sum(), (wgt * yy).sum() / wgt.sum()
        assert np.hypot(cu - eu, cv - ev) < 0.5
    # the analytic chain agrees exactly
    assert np.allclose(perspective_to_pano(expected, view, W, H), ray_to_pixel(points, W, H), atol=1e-8)


def test_perspective_matches_py360convert():
    p3 = pytest.importorskip("py360convert")
    pano = procedural_pano(256)
    w, h = 160, 120
    for yaw_deg, pitch_deg in [(0, 0), (100, 30), (-170, -60), (180, 10)]:
        view = PinholeView(np.radians(yaw_deg), np.radians(pitch_deg), 0.0, np.radians(90.0), w, h)
        vfov_deg = np.degrees(2 * np.arctan(np.tan(np.radians(45.0)) * h / w))
        ref = p3.e2p(pano, (90.0, vfov_deg), -yaw_deg, pitch_deg, (h, w)).astype(float)
        # py360convert puts its outer pixel centres on the image border: its pixel j is our u = w*j/(w-1)
        jj, ii = np.meshgrid(np.arange(w) * w / (w - 1), np.arange(h) * h / (h - 1))
        at_its_pixels = sample_equirect(pano, perspective_to_pano(np.stack([jj, ii], -1), view, 512, 256))
        assert np.abs(at_its_pixels - ref).mean() < 0.5
        assert np.abs(equirect_to_perspective(pano, view).astype(float) - ref).mean() < 1.5


def test_view_sets():
    lv = layout_views(128)
    assert len(lv) == 6
    assert all(v.width == v.height == 128 and np.isclose(v.fov, np.pi / 2) and v.pitch == 0 for v in lv)
    yaws = np.degrees([v.yaw for v in lv])
    assert np.allclose(np.diff(yaws), 60.0)      # 90 degree FOV every 60 degrees: 30 degrees overlap
    dv = detection_views(64)
    assert len(dv) == 18
    assert sorted({round(np.degrees(v.pitch)) for v in dv}) == [-50, -10]
    rv = ring_views(4, 1.0, (30, 40), pitch=0.2, yaw0=0.1)
    assert [(v.height, v.width) for v in rv] == [(30, 40)] * 4
    assert np.allclose([v.yaw for v in rv], 0.1 + np.arange(4) * np.pi / 2)


def test_segment_to_arc_and_arc_points():
    view = PinholeView(0.7, -0.2, 0.1, 1.4, 320, 240)
    segs = np.array([[10.0, 20.0, 300.0, 200.0], [160.0, 5.0, 160.0, 230.0]])
    a, b, n = segment_to_arc(segs, view)
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0)
    assert np.allclose(np.sum(n * a, axis=1), 0.0) and np.allclose(np.sum(n * b, axis=1), 0.0)
    # every pixel of a straight segment lies on its great circle
    t = np.linspace(0, 1, 50)[:, None]
    for k, s in enumerate(segs):
        rays = view.pixel_to_ray(s[:2] + t * (s[2:] - s[:2]))
        assert np.abs(rays @ n[k]).max() < 1e-12
    pts = arc_points(a, b, 17)
    assert pts.shape == (2, 17, 3)
    assert np.allclose(np.linalg.norm(pts, axis=-1), 1.0)
    assert np.allclose(pts[:, 0], a) and np.allclose(pts[:, -1], b)
    steps = np.arccos(np.clip(np.sum(pts[:, 1:] * pts[:, :-1], axis=-1), -1, 1))
    assert np.allclose(steps, steps[:, :1], atol=1e-9)                 # equal angular steps
    assert np.abs(np.einsum("kij,kj->ki", pts, n)).max() < 1e-12     # on the great circle


def test_box_to_pano_contains_the_whole_box():
    rng = np.random.default_rng(11)
    n_wrap = n_pole = 0
    for _ in range(120):
        pitch = rng.choice([rng.uniform(-1.2, 1.2), rng.choice([-1.0, 1.0]) * rng.uniform(1.2, np.pi / 2)])
        view = PinholeView(rng.uniform(-np.pi, np.pi), float(pitch), rng.uniform(-0.5, 0.5),
                           rng.uniform(0.5, 2.5), 320, 240)
        u0, u1 = np.sort(rng.uniform(0, 320, 2))
        v0, v1 = np.sort(rng.uniform(0, 240, 2))
        res = box_to_pano([u0, v0, u1, v1], view, W, H)
        grid = np.stack(np.meshgrid(np.linspace(u0, u1, 30), np.linspace(v0, v1, 30)), axis=-1)
        assert in_extent(perspective_to_pano(grid, view, W, H), res.extent, W).all()
        assert in_extent(res.outline, res.extent, W).all()
        n_wrap += res.wraps
        n_pole += res.extent[0] == 0 and res.extent[2] == W
    assert n_wrap > 5 and n_pole > 5     # the cases of interest were exercised


def test_box_to_pano_seam_and_pole_cases():
    view = PinholeView(np.pi, 0.0, 0.0, np.pi / 2, 200, 200)      # looks at the seam
    res = box_to_pano([50.0, 50.0, 150.0, 150.0], view, W, H)
    assert res.wraps and res.extent[0] > W / 2 > res.extent[2]
    up = PinholeView(0.3, np.pi / 2 - 0.05, 0.0, np.pi / 2, 200, 200)  # zenith near the image centre
    res = box_to_pano([60.0, 60.0, 140.0, 140.0], up, W, H)
    assert res.extent[0] == 0 and res.extent[1] == 0 and res.extent[2] == W


def test_pano_box_union():
    boxes = np.array([[100.0, 10, 200, 50], [150, 5, 300, 40]])
    assert np.allclose(pano_box_union(boxes, W), [100, 5, 300, 50])
    wrap = np.array([[2000.0, 10, 30, 50], [10, 20, 100, 60]])
    assert np.allclose(pano_box_union(wrap, W), [2000, 10, 100, 60])
    both = np.array([[1900.0, 0, 2040, 10], [20, 0, 60, 10]])
    assert np.allclose(pano_box_union(both, W), [1900, 0, 60, 10])
    full = np.array([[0.0, 0, W, 10], [20, 5, 60, 30]])
    assert np.allclose(pano_box_union(full, W), [0, 0, W, 30])
    rng = np.random.default_rng(5)
    for _ in range(50):
        u0 = rng.uniform(0, W, 4)
        bx = np.stack([u0, rng.uniform(0, 100, 4), (u0 + rng.uniform(1, 300, 4)) % W, rng.uniform(100, 200, 4)], 1)
        uni = pano_box_union(bx, W)
        for b in bx:
            span = (b[2] - b[0]) % W
            us = (b[0] + np.linspace(0, span, 20)) % W
            pts = np.stack([us, np.full(20, (b[1] + b[3]) / 2)], -1)
            assert in_extent(pts, uni, W).all()


@pytest.mark.parametrize("call, match", [
    (lambda: PinholeView(0.0, 0.0, 0.0, np.pi, 10, 10), r"fov: expected a field of view in \(0, pi\)"),
    (lambda: PinholeView(0.0, 0.0, 0.0, 0.0, 10, 10), r"fov: expected"),
    (lambda: PinholeView(0.0, 0.0, 0.0, -1.0, 10, 10), r"fov: expected"),
    (lambda: PinholeView(0.0, 0.0, 0.0, np.nan, 10, 10), r"fov: expected"),
    (lambda: PinholeView(0.0, 0.0, 0.0, np.radians(200.0), 10, 10), r"fov: expected"),
    (lambda: PinholeView(0.0, 0.0, 0.0, 1.0, 0, 10), "positive size"),
    (lambda: PinholeView(np.inf, 0.0, 0.0, 1.0, 10, 10), "yaw: expected a finite angle"),
    (lambda: ring_views(0, 1.0, 10), "positive integer"),
    (lambda: ring_views(2.5, 1.0, 10), "positive integer"),
    (lambda: equirect_to_perspective(np.zeros((10, 30)), PinholeView(0, 0, 0, 1, 4, 4)), "W == 2\\*H"),
    (lambda: equirect_to_perspective(np.zeros((10, 20)), "front"), "PinholeView"),
    (lambda: box_to_pano([10.0, 5, 5, 20], PinholeView(0, 0, 0, 1, 40, 40), W, H), "u0 < u1"),
    (lambda: segment_to_arc([[1.0, 2.0, 3.0]], PinholeView(0, 0, 0, 1, 40, 40)), r"shape \(N, 4\)"),
    (lambda: segment_to_arc([[1.0, 2.0, 1.0, 2.0]], PinholeView(0, 0, 0, 1, 40, 40)), "non-zero length"),
    (lambda: pano_box_union(np.zeros((0, 4)), W), "N >= 1"),
    (lambda: PinholeView(0, 0, 0, 1, 40, 40).pixel_to_ray([np.nan, 1.0]), "finite"),
])
def test_bad_input_raises_with_a_message(call, match):
    with pytest.raises(ValueError, match=match):
        call()
