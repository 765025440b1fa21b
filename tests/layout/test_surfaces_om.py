"""Tests of layout.surfaces.orientation_map: column sweeps, arc rasters, the orientation map of box rooms."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from layout.labelmap import render_room_labels
from layout.surfaces.orientation_map import (
    OrientationMap,
    orientation_map,
    pole_frame,
    rasterize_arcs,
    sweep_columns,
)
from panogeom.coords import pixel_to_ray
from panogeom.lines import LineSegments
from panogeom.rotation import rot_z


def box_edges(lo, hi, camera, yaw: float = 0.0) -> LineSegments:
    """The 12 edges of an axis-aligned box room as arcs seen from ``camera``, the room turned by ``yaw``."""
    c = np.array(list(itertools.product([lo[0], hi[0]], [lo[1], hi[1]], [lo[2], hi[2]]))) - np.asarray(camera)
    pairs = [(i, j) for i, j in itertools.combinations(range(8), 2) if np.sum(c[i] != c[j]) == 1]
    R = rot_z(yaw)
    a = c[[i for i, _ in pairs]] @ R.T
    b = c[[j for _, j in pairs]] @ R.T
    return LineSegments.from_endpoints(a, b)


def box_labels(lo, hi, camera, width):
    floor = [[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]]
    return render_room_labels(floor, hi[2], camera[:2], camera[2], width)


LO, HI, CAM = np.array([-1.5, -2.5, 0.0]), np.array([3.5, 2.0, 2.7]), np.array([0.0, 0.0, 1.5])


def test_sweep_columns_matches_brute_force():
    rng = np.random.default_rng(3)
    for _ in range(20):
        S = rng.random((17, 9)) < 0.08
        B = rng.random((17, 9)) < 0.15
        out = sweep_columns(S, B)
        for c in range(9):
            run = 0
            runs = []
            for r in range(17):
                runs.append(run)
                run += int(B[r, c])
            runs = np.array(runs)
            for r in range(17):
                assert out[r, c] == bool(np.any(S[runs == runs[r], c]))


def test_sweep_columns_rejects_mismatched_shapes():
    with pytest.raises(ValueError, match="expected two"):
        sweep_columns(np.zeros((4, 4), bool), np.zeros((4, 5), bool))


def test_rasterize_arcs_marks_every_column_and_wraps_the_seam():
    rng = np.random.default_rng(5)
    a = rng.normal(size=(40, 3))
    b = a + 0.6 * rng.normal(size=(40, 3))
    w = 128
    m = rasterize_arcs(a, b, w)
    from panogeom.perspective import arc_points
    from panogeom.coords import ray_to_pixel

    for k in range(40):
        u = ray_to_pixel(arc_points(a[k], b[k], 400), w, w // 2)[:, 0].astype(int)
        cols = np.unique(u)
        hit = m[:, cols].any(axis=0)
        assert hit.all(), f"arc {k} misses columns {cols[~hit]}"
    seam = rasterize_arcs([[-1.0, 0.1, 0.0]], [[-1.0, -0.1, 0.0]], 64)  # across lon = +-pi
    cols = np.flatnonzero(seam.any(axis=0))
    assert 0 in cols and 63 in cols and len(cols) <= 6


def test_pole_frame_is_a_rotation_onto_each_axis():
    A = rot_z(0.4).T
    for k in range(3):
        Q = pole_frame(A, k)
        assert np.allclose(Q @ Q.T, np.eye(3)) and np.isclose(np.linalg.det(Q), 1.0)
        assert np.allclose(Q @ A[k], [0, 0, 1])
    with pytest.raises(ValueError, match="expected 0, 1 or 2"):
        pole_frame(np.eye(3), 3)


def test_box_room_orientation_map_agrees_with_the_analytic_labels():
    w = 256
    om = orientation_map(box_edges(LO, HI, CAM), w, om_width=256)
    truth = box_labels(LO, HI, CAM, w)
    assert isinstance(om, OrientationMap) and om.usable
    assert om.n_segments.tolist() == [4, 4, 4]
    lab = om.labels > 0
    assert om.coverage > 0.85
    assert np.mean(om.labels[lab] == truth[lab]) > 0.97
    assert om.labels.shape == (128, 256) and om.confidence.dtype == np.float32
    assert np.all(om.confidence[lab] > 0) and np.all(om.support <= 1.0)


def test_turning_the_room_a_quarter_turn_swaps_the_wall_labels():
    w = 256
    om0 = orientation_map(box_edges(LO, HI, CAM), w, om_width=256)
    om1 = orientation_map(box_edges(LO, HI, CAM, yaw=np.pi / 2), w, om_width=256)
    # turning the scene by +90 deg about z moves image content a quarter width to the left
    shifted = np.roll(om0.labels, -w // 4, axis=1)
    swap = np.array([0, 1, 2, 4, 3], np.uint8)[shifted]
    both = (swap > 0) & (om1.labels > 0)
    assert both.mean() > 0.8
    assert np.mean(om1.labels[both] == swap[both]) > 0.98


def test_axes_of_a_turned_room_give_labels_in_its_own_frame():
    yaw, w = np.deg2rad(30.0), 256
    segs = box_edges(LO, HI, CAM, yaw=yaw)
    axes = rot_z(yaw).T  # rows: the room's x, y, up in the panorama frame
    om = orientation_map(segs, w, axes, om_width=256)
    # the truth: labels of the unturned room, looked up along the turned rays
    truth0 = box_labels(LO, HI, CAM, 1024)
    uv = np.stack(np.meshgrid(np.arange(w) + 0.5, np.arange(w // 2) + 0.5), axis=-1)
    rays = pixel_to_ray(uv, w, w // 2) @ rot_z(yaw)  # R.T @ d
    from panogeom.coords import ray_to_pixel

    src = ray_to_pixel(rays, 1024, 512).astype(int)
    truth = truth0[src[..., 1], src[..., 0]]
    lab = om.labels > 0
    assert om.coverage > 0.8
    assert np.mean(om.labels[lab] == truth[lab]) > 0.97


def test_no_segments_give_an_empty_unusable_map():
    om = orientation_map(LineSegments.empty(), 64)
    assert not om.usable and om.coverage == 0.0 and om.n_segments.tolist() == [0, 0, 0]


def test_orientation_map_checks_its_inputs():
    segs = box_edges(LO, HI, CAM)
    with pytest.raises(ValueError, match="expected panogeom.lines.LineSegments"):
        orientation_map(np.zeros((3, 3)), 64)
    with pytest.raises(ValueError, match="expected an even panorama width"):
        orientation_map(segs, 63)
    with pytest.raises(ValueError, match="proper rotation"):
        orientation_map(segs, 64, np.diag([1.0, 1.0, -1.0]))
