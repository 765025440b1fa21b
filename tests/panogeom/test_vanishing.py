"""Tests of panogeom.vanishing and panogeom.rectify: Manhattan frames and upright rectification."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from panogeom.coords import pixel_to_ray, ray_to_pixel
from panogeom.lines import LineSegments
from panogeom.rectify import Rectification, estimate_rectification, upright_rotation
from panogeom.rotation import matrix_to_axis_angle, rot_x, rot_y, rot_z
from panogeom.transform import procedural_pano, rotate_pano
from panogeom.vanishing import (
    VanishingPointError,
    assign_segments,
    estimate_manhattan_frame,
    vertical_hypotheses,
)

sys.path.insert(0, str(Path(__file__).resolve().parent))
from synthetic_rooms import make_room, random_rotation, render_room  # noqa: E402

REAL = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "real"
N_ROOMS = 16
WIDTH = 1024


def deg(x):
    return float(np.rad2deg(x))


def vertical_error_deg(axes, R_true):
    """Angle between the recovered up and the true up (row 2 of R_true, R_true: camera -> world)."""
    return deg(np.arctan2(np.linalg.norm(np.cross(axes[2], R_true[2])), axes[2] @ R_true[2]))


def heading_error_deg(axes, R_true):
    """Angle about the vertical between the recovered and true horizontal axes, modulo 90 degrees."""
    Q = axes @ R_true.T
    a = deg(np.arctan2(Q[1, 0], Q[0, 0]))
    return abs((a + 45.0) % 90.0 - 45.0)


@pytest.fixture(scope="module")
def tilted_rooms():
    """(room, R_true, pano, Rectification in 'walls' mode) for N_ROOMS random rooms and tilts."""
    rng = np.random.default_rng(2024)
    out = []
    for k in range(N_ROOMS):
        room = make_room(1000 + k)
        R = random_rotation(rng, 15.0)
        pano = render_room(room, R, WIDTH)
        out.append((room, R, pano, estimate_rectification(pano, "walls")))
    return out


# --- acceptance on synthetic tilted rooms ---------------------------------------------------------------------


def test_vertical_and_horizontal_axes_of_tilted_rooms(tilted_rooms):
    ev = np.array([vertical_error_deg(r.frame.axes, R) for _, R, _, r in tilted_rooms])
    eh = np.array([heading_error_deg(r.frame.axes, R) for _, R, _, r in tilted_rooms])
    tilts = np.array([deg(np.arccos(R[2, 2])) for _, R, _, _ in tilted_rooms])
    assert tilts.max() > 10.0  # the rotations really are tilted
    assert np.median(ev) < 0.3 and np.percentile(ev, 95) < 1.0, ev
    assert np.median(eh) < 0.5, eh


def test_walls_mode_rotation_is_the_true_one_up_to_quarter_turns(tilted_rooms):
    for _, R, _, r in tilted_rooms:
        Q = r.rotation @ R.T  # rectified <- world
        k = np.round(np.arctan2(Q[1, 0], Q[0, 0]) / (np.pi / 2))
        residual = Q @ rot_z(k * np.pi / 2).T
        assert deg(np.linalg.norm(matrix_to_axis_angle(residual))) < 1.0
        assert abs(r.heading) <= np.pi / 4 + 1e-9


def test_level_mode_keeps_the_heading(tilted_rooms):
    for _, R, pano, r in tilted_rooms[:4]:
        level = Rectification(upright_rotation(r.frame.axes, "level"), "level", r.frame, r.segments)
        x = level.rotation @ [1.0, 0.0, 0.0]
        assert abs(x[1]) < 1e-12 and x[0] > 0  # the input centre column stays at lon = 0
        assert np.allclose(level.rotation @ r.frame.axes[2], [0, 0, 1], atol=1e-12)
        assert level.heading == pytest.approx(0.0, abs=1e-12)
        # level and walls differ by a turn about the vertical only
        x_walls_in_level = level.rotation @ r.rotation[0]
        assert abs(x_walls_in_level[2]) < 1e-12
        assert np.arctan2(x_walls_in_level[1], x_walls_in_level[0]) == pytest.approx(r.heading, abs=1e-9)


def test_segment_labels_agree_with_the_true_frame(tilted_rooms):
    for _, R, _, r in tilted_rooms[:6]:
        lab = r.frame.labels
        truth = assign_segments(r.segments, R, np.deg2rad(2.0))  # rows of R: world axes in the camera frame
        # map the true axis index through the quarter turn of the recovered frame
        perm = np.argmax(np.abs(r.frame.axes @ R.T), axis=1)
        ok = (lab >= 0) & (truth >= 0)
        assert np.mean(perm[lab[ok]] == truth[ok]) > 0.97
        assert r.frame.inlier_fraction > 0.6 and r.frame.counts.min() > 20


def test_rectified_panorama_matches_an_upright_render(tilted_rooms):
    room, R, pano, r = tilted_rooms[0]
    rect = r.apply(pano)
    upright = render_room(room, R @ r.rotation.T, WIDTH)  # world <- rectified
    # the same upright view rendered directly: the pictures agree
    diff = np.abs(rect.astype(int) - upright.astype(int)).mean(axis=2)
    band = slice(WIDTH // 8, 3 * WIDTH // 8)  # away from the poles, where resampling blurs most
    assert np.median(diff[band]) < 3.0
    Rw = R @ r.rotation.T
    assert np.allclose(Rw @ [0, 0, 1.0], [0, 0, 1], atol=np.sin(np.deg2rad(0.5)))


# --- the estimator on exact arcs --------------------------------------------------------------------------------


def manhattan_arcs(R, n_per_axis=15, outliers=10, seed=0, noise=0.0):
    """Arcs along the rows of R (directions in the camera frame) plus random outliers."""
    rng = np.random.default_rng(seed)
    d = np.repeat(R, n_per_axis, axis=0)
    p = rng.normal(size=(len(d), 3))
    p -= np.sum(p * d, axis=1, keepdims=True) * d
    p /= np.linalg.norm(p, axis=1, keepdims=True)
    h = rng.uniform(0.1, 0.4, size=(len(d), 1))
    a, b = p + h * d, p - h * d
    if noise:
        a += rng.normal(scale=noise, size=a.shape)
        b += rng.normal(scale=noise, size=b.shape)
    oa, ob = rng.normal(size=(outliers, 3)), rng.normal(size=(outliers, 3))
    ob = oa + 0.3 * ob / np.linalg.norm(ob, axis=1, keepdims=True) * np.linalg.norm(oa, axis=1, keepdims=True)
    return LineSegments.from_endpoints(np.concatenate([a, oa]), np.concatenate([b, ob]))


@settings(max_examples=30, deadline=None)
@given(yaw=st.floats(-np.pi, np.pi), pitch=st.floats(-0.35, 0.35), roll=st.floats(-0.35, 0.35),
       seed=st.integers(0, 1000))
@example(yaw=0.21484375, pitch=-0.140625, roll=-0.140625, seed=552)  # outliers move the heading by 0.0504 deg
def test_exact_arcs_give_the_exact_frame(yaw, pitch, roll, seed):
    R = rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)  # camera -> world; rows: world axes in the camera
    f = estimate_manhattan_frame(manhattan_arcs(R, seed=seed, outliers=0))
    A = f.axes
    assert np.allclose(A @ A.T, np.eye(3), atol=1e-12) and np.linalg.det(A) > 0
    assert vertical_error_deg(A, R) < 1e-6 and A[2, 2] > 0
    assert heading_error_deg(A, R) < 1e-6
    # x is the horizontal axis closest to the input's centre-column direction
    ex = np.array([1.0, 0, 0]) - A[2, 0] * A[2]
    assert A[0] @ ex >= max(abs(A[1] @ ex), -(A[0] @ ex)) - 1e-12
    assert f.counts.tolist() == [15, 15, 15] and f.rmse < 1e-6
    assert np.all(f.significance > 8.0)
    # random outliers, some of which pass near an axis by chance (and count as its inliers), barely move it: by up to
    # about 0.05 deg in 1500 random cases of these ranges (the bound had been 0.05 deg, which an example found by
    # hypothesis passed with 0.0504 deg of heading error; now twice the observed tail)
    g = estimate_manhattan_frame(manhattan_arcs(R, seed=seed, outliers=15))
    assert vertical_error_deg(g.axes, R) < 0.1 and heading_error_deg(g.axes, R) < 0.1
    assert np.allclose(g.axes, A, atol=2e-3)


def test_noisy_arcs_are_refined_beyond_the_noise():
    R = rot_z(0.3) @ rot_x(0.12)
    f = estimate_manhattan_frame(manhattan_arcs(R, n_per_axis=60, outliers=40, seed=5, noise=0.003))
    assert vertical_error_deg(f.axes, R) < 0.1 and heading_error_deg(f.axes, R) < 0.1
    assert 0.0 < deg(f.rmse) < 1.0 and f.tilt == pytest.approx(np.arccos(R[2, 2]), abs=np.deg2rad(0.1))


def test_vertical_hypotheses_respect_the_tilt_cap():
    rng = np.random.default_rng(1)
    n = rng.normal(size=(80, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    h = vertical_hypotheses(n, np.ones(80), np.deg2rad(20.0))
    assert len(h) > 0 and np.all(h[:, 2] >= np.cos(np.deg2rad(20.0))) and np.allclose(np.linalg.norm(h, axis=1), 1)
    with pytest.raises(ValueError, match=r"weights: expected shape \(80,\)"):
        vertical_hypotheses(n, np.ones(3), 0.3)


# --- degenerate input -----------------------------------------------------------------------------------------


def test_blank_panorama_raises_a_named_error():
    with pytest.raises(VanishingPointError, match="found 0 line segments, need at least 12"):
        estimate_rectification(np.full((256, 512, 3), 200, np.uint8))
    assert issubclass(VanishingPointError, ValueError)


@pytest.mark.parametrize("kind", ["uniform", "blurred", "fine", "procedural"])
def test_noise_and_non_manhattan_images_raise(kind):
    rng = np.random.default_rng(7)
    if kind == "uniform":
        img = rng.integers(0, 256, (512, 1024, 3), dtype=np.uint8)
    elif kind == "blurred":
        img = cv2.GaussianBlur(rng.integers(0, 256, (512, 1024), dtype=np.uint8), (0, 0), 3)
    elif kind == "fine":
        img = cv2.GaussianBlur(rng.integers(0, 256, (512, 1024), dtype=np.uint8), (0, 0), 1.5)
    else:  # smooth colours and three soft great-circle bands: lines, but no Manhattan frame
        img = procedural_pano(512)
    with pytest.raises(VanishingPointError, match="line segments|meaningful|explains"):
        estimate_rectification(img)


def test_too_few_or_unstructured_segments_raise():
    with pytest.raises(VanishingPointError, match="found 5 line segments, need at least 12"):
        estimate_manhattan_frame(manhattan_arcs(np.eye(3), n_per_axis=1, outliers=2))
    only_vertical = manhattan_arcs(np.eye(3), n_per_axis=20, outliers=0).subset(np.arange(40, 60))
    with pytest.raises(VanishingPointError, match="no meaningful horizontal vanishing point"):
        estimate_manhattan_frame(only_vertical)
    rng = np.random.default_rng(0)
    a = rng.normal(size=(300, 3))
    b = a + 0.2 * rng.normal(size=(300, 3))
    with pytest.raises(VanishingPointError):
        estimate_manhattan_frame(LineSegments.from_endpoints(a, b))


def test_bad_arguments_raise_value_errors():
    segs = manhattan_arcs(np.eye(3))
    with pytest.raises(ValueError, match="segments: expected LineSegments, got ndarray"):
        estimate_manhattan_frame(np.zeros((3, 3)))
    with pytest.raises(ValueError, match=r"max_tilt: expected radians in \(0, pi/2\)"):
        estimate_manhattan_frame(segs, max_tilt=2.0)
    with pytest.raises(ValueError, match="mode: expected one of"):
        estimate_rectification(np.zeros((64, 128), np.uint8), mode="yaw")
    with pytest.raises(ValueError, match="mode: expected one of"):
        upright_rotation(np.eye(3), "up")
    with pytest.raises(ValueError, match="expected the up row"):
        upright_rotation(rot_x(np.pi), "level")
    with pytest.raises(ValueError, match="proper rotation"):
        upright_rotation(np.diag([1.0, -1.0, 1.0]), "level")


# --- mapping pixels and boxes ---------------------------------------------------------------------------------


def a_rectification(R):
    seg = manhattan_arcs(R)
    f = estimate_manhattan_frame(seg)
    return Rectification(upright_rotation(f.axes, "walls"), "walls", f, seg)


def in_box(uv, box, w):
    u0, v0, u1, v1 = box
    width = w if (u0 == 0 and u1 == w) else (u1 - u0) % w
    du = np.mod(uv[:, 0] - u0, w)
    return (du <= width + 1e-6) & (uv[:, 1] >= v0 - 1e-6) & (uv[:, 1] <= v1 + 1e-6)


@pytest.mark.parametrize("box", [[100.0, 150.0, 300.0, 260.0], [900.0, 200.0, 80.0, 300.0],
                                 [400.0, 0.0, 600.0, 60.0], [10.0, 470.0, 1000.0, 512.0]])
def test_boxes_contain_their_mapped_points_both_ways(box):
    w, h = 1024, 512
    r = a_rectification(rot_z(2.0) @ rot_y(0.2) @ rot_x(-0.15))
    rng = np.random.default_rng(0)
    u0, v0, u1, v1 = box
    span = (u1 - u0) % w
    pts = np.stack([np.mod(u0 + rng.uniform(0, span, 4000), w), rng.uniform(v0, v1, 4000)], axis=1)
    out = r.box_to_rectified(box, w, h)
    assert in_box(r.pixels_to_rectified(pts, w, h), out, w).all()
    back = r.box_to_input(out, w, h)
    assert in_box(pts, back, w).all()
    assert np.allclose(r.pixels_to_input(r.pixels_to_rectified(pts, w, h), w, h)[:, 1], pts[:, 1], atol=1e-6)


def test_box_around_a_pole_spans_the_full_width():
    r = a_rectification(rot_x(0.2))
    up_in_input = ray_to_pixel(r.rays_to_input([0.0, 0.0, 1.0]), 1024, 512)
    box = [up_in_input[0] - 40, up_in_input[1] - 20, up_in_input[0] + 40, up_in_input[1] + 20]
    out = r.box_to_rectified(box, 1024, 512)
    assert out[0] == 0.0 and out[2] == 1024.0 and out[1] == 0.0


def test_rays_and_pixels_map_both_ways():
    r = a_rectification(rot_z(-1.0) @ rot_x(0.25))
    rng = np.random.default_rng(4)
    uv = rng.uniform([0, 1], [1024, 511], size=(200, 2))
    back = r.pixels_to_input(r.pixels_to_rectified(uv, 1024, 512), 1024, 512)
    du = (back[:, 0] - uv[:, 0] + 512) % 1024 - 512
    assert np.abs(du).max() < 1e-6 and np.abs(back[:, 1] - uv[:, 1]).max() < 1e-6
    d = pixel_to_ray(uv, 1024, 512)
    assert np.allclose(r.rays_to_input(r.rays_to_rectified(d)), d)
    assert np.allclose(r.rays_to_rectified(r.frame.axes[2]), [0, 0, 1])
    with pytest.raises(ValueError, match="box: expected"):
        r.box_to_rectified([0, 10, 5, 5], 1024, 512)


# --- real panoramas -------------------------------------------------------------------------------------------


def corner_edge_tilts_deg(gt, R):
    """Tilt of each ground-truth vertical wall edge from the vertical after the rotation R, degrees."""
    w, h = gt["image"]["width"], gt["image"]["height"]
    cp = np.asarray(gt["corners_px"], float)
    c, f = pixel_to_ray(cp[:, :2], w, h) @ R.T, pixel_to_ray(cp[:, 2:], w, h) @ R.T
    n = np.cross(c, f)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return np.rad2deg(np.arcsin(np.abs(n[:, 2])))


def real_panoramas():
    if not REAL.is_dir():
        return []
    return sorted(p for p in REAL.iterdir() if (p / "gt.json").is_file())


@pytest.mark.skipif(not real_panoramas(), reason="shared/data/real is not available")
@pytest.mark.parametrize("folder", real_panoramas(), ids=lambda p: p.name)
def test_real_corners_are_vertical_after_rectification(folder):
    gt = json.loads((folder / "gt.json").read_text())
    pano = cv2.cvtColor(cv2.imread(str(folder / gt["image"]["file"])), cv2.COLOR_BGR2RGB)
    r = estimate_rectification(pano, "level")
    assert corner_edge_tilts_deg(gt, r.rotation).max() < 1.0
    # the same panorama tilted by a known rotation: rectification undoes it
    T = rot_z(0.3) @ rot_y(np.deg2rad(9.0)) @ rot_x(np.deg2rad(-6.0))  # tilted frame <- original
    tilted = rotate_pano(pano, T)
    rt = estimate_rectification(tilted, "level")
    assert deg(rt.tilt) > 9.0
    assert corner_edge_tilts_deg(gt, rt.rotation @ T).max() < 1.0
