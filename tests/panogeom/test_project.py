"""Tests of panogeom.project: world polylines and oriented boxes in panorama pixels."""

from __future__ import annotations

import numpy as np
import pytest

from panogeom.coords import pixel_to_ray, world_to_pixel
from panogeom.project import BOX_EDGES, world_box_corners, world_box_to_pano, world_polyline_to_pano
from panogeom.rotation import axis_angle_to_matrix, rot_z

W, H = 1024, 512
CH = 1.6
CAM = np.array([0.0, 0.0, CH])


def in_extent(uv, ext, width, tol=1e-6):
    u, v = uv[..., 0], uv[..., 1]
    ok_v = (v >= ext[1] - tol) & (v <= ext[3] + tol)
    if ext[0] <= ext[2]:
        ok_u = (u >= ext[0] - tol) & (u <= ext[2] + tol)
    else:
        ok_u = (u >= ext[0] - tol) | (u <= ext[2] + tol)
    return ok_u & ok_v


def test_box_corners_follow_the_object_convention():
    c = world_box_corners([1.0, 2.0, 0.5], [2.0, 1.0, 1.0], 0.0)
    assert c.shape == (8, 3)
    assert np.allclose(c.mean(axis=0), [1.0, 2.0, 0.5])
    assert np.allclose(c[0], [2.0, 1.5, 0.0])       # front-right bottom: +l/2, -w/2
    assert np.allclose(c[5], [2.0, 2.5, 1.0])       # front-left top
    lengths = np.linalg.norm(c[BOX_EDGES[:, 1]] - c[BOX_EDGES[:, 0]], axis=1)
    assert np.allclose(sorted(lengths), [1.0] * 8 + [2.0] * 4)
    # yaw turns the front (+x of the object) counter-clockwise: yaw = 90 deg faces +y
    c90 = world_box_corners([0.0, 0.0, 0.5], [2.0, 1.0, 1.0], np.pi / 2)
    front = (c90[0] + c90[1]) / 2
    assert np.allclose(front[:2], [0.0, 1.0])
    # bottom ring is counter-clockwise seen from above
    b = c90[:4, :2]
    area = 0.5 * np.sum(b[:, 0] * np.roll(b[:, 1], -1) - np.roll(b[:, 0], -1) * b[:, 1])
    assert area > 0


def test_polyline_samples_lie_on_the_great_circle():
    rng = np.random.default_rng(0)
    for _ in range(20):
        P, Q = rng.normal(size=(2, 3)) * 3 + [0, 0, 1]
        R = axis_angle_to_matrix(rng.normal(size=3) * 0.2)
        pieces = world_polyline_to_pano(np.stack([P, Q]), W, H, CH, rotation=R, samples_per_segment=40)
        n_world = np.cross(P - CAM, Q - CAM)
        n_cam = R.T @ n_world / np.linalg.norm(n_world)
        for pl in pieces:
            assert np.abs(pixel_to_ray(pl, W, H) @ n_cam).max() < 1e-9
        assert np.allclose(pieces[0][0], world_to_pixel(P, W, H, CH, R))
        end = pieces[-1][-1]
        du = abs(end[0] - world_to_pixel(Q, W, H, CH, R)[0])
        assert min(du, W - du) < 1e-9 and abs(end[1] - world_to_pixel(Q, W, H, CH, R)[1]) < 1e-9


def test_equal_angular_sampling_of_a_segment_near_the_camera():
    pl = world_polyline_to_pano([[0.3, -3.0, 0.0], [0.3, 3.0, 0.0]], W, H, CH, samples_per_segment=9)[0]
    rays = pixel_to_ray(pl, W, H)
    steps = np.arccos(np.clip(np.sum(rays[1:] * rays[:-1], axis=1), -1, 1))
    assert np.allclose(steps, steps[0], atol=1e-9)


def test_segment_behind_the_camera_is_split_at_the_seam():
    pieces = world_polyline_to_pano([[-2.0, -1.0, 0.0], [-2.0, 1.0, 0.0]], W, H, CH, samples_per_segment=8)
    assert len(pieces) == 2
    a, b = pieces
    assert a[-1, 0] == W and b[0, 0] == 0.0         # moving left (+y) behind the camera: leaves at u = W
    assert a[-1, 1] == b[0, 1]
    # the cut is the exact crossing point (-2, 0, 0)
    assert np.isclose(a[-1, 1], world_to_pixel([-2.0, 0.0, 0.0], W, H, CH)[1], atol=1e-9)
    assert np.all(np.abs(np.diff(a[:, 0])) < W / 2) and np.all(np.abs(np.diff(b[:, 0])) < W / 2)
    # the other direction leaves through u = 0
    rev = world_polyline_to_pano([[-2.0, 1.0, 0.0], [-2.0, -1.0, 0.0]], W, H, CH, samples_per_segment=8)
    assert rev[0][-1, 0] == 0.0 and rev[1][0, 0] == W


def test_closed_room_outline_around_the_camera():
    floor = np.array([[3.0, -2.0, 0.0], [3.0, 2.5, 0.0], [-1.5, 2.5, 0.0], [-1.5, -2.0, 0.0]])
    pieces = world_polyline_to_pano(floor, W, H, CH, samples_per_segment=16, closed=True)
    assert len(pieces) == 1                        # one seam crossing, merged into one curve
    pl = pieces[0]
    assert {pl[0, 0], pl[-1, 0]} == {0.0, float(W)}
    assert np.all(np.abs(np.diff(pl[:, 0])) < W / 2)
    assert np.ptp(pl[:, 0]) == W                   # it goes all around
    # every vertex is on it
    for p in floor:
        assert np.min(np.linalg.norm(pl - world_to_pixel(p, W, H, CH), axis=1)) < 1e-9
    open_pieces = world_polyline_to_pano(floor, W, H, CH, samples_per_segment=16)
    assert len(open_pieces) == 2


def test_single_point_and_degenerate_segment():
    one = world_polyline_to_pano([[2.0, 0.0, 1.6]], W, H, CH)
    assert len(one) == 1 and np.allclose(one[0], [[W / 2, H / 2]])
    same = world_polyline_to_pano([[2.0, 1.0, 0.0], [2.0, 1.0, 0.0]], W, H, CH, samples_per_segment=4)
    assert np.allclose(same[0], world_to_pixel([2.0, 1.0, 0.0], W, H, CH))


def surface_points(center, size, yaw, n=12):
    """Points on all six faces of an oriented box."""
    t = np.linspace(-0.5, 0.5, n)
    a, b = np.meshgrid(t, t)
    a, b = a.ravel(), b.ravel()
    faces = []
    for axis in range(3):
        for sgn in (-0.5, 0.5):
            p = np.zeros((a.size, 3))
            others = [k for k in range(3) if k != axis]
            p[:, axis] = sgn
            p[:, others[0]], p[:, others[1]] = a, b
            faces.append(p)
    local = np.concatenate(faces) * size
    return local @ rot_z(yaw).T + center


BOXES = [
    ("in front", [2.5, 0.3, 0.4], [1.0, 0.6, 0.8], 0.3, None),
    ("behind, across the seam", [-3.0, 0.2, 0.5], [1.2, 2.0, 1.0], 1.0, None),
    ("lamp above the camera", [0.1, -0.2, 2.6], [0.8, 0.5, 0.3], 0.7, None),
    ("rug below the camera", [0.3, 0.2, 0.01], [2.0, 1.5, 0.02], 0.2, None),
    ("close to the zenith", [0.6, 0.1, 2.8], [0.4, 0.4, 0.2], 0.0, None),
    ("tilted camera", [1.5, -1.5, 1.0], [0.7, 0.7, 2.0], 2.0, axis_angle_to_matrix([0.1, -0.15, 0.4])),
    ("tilted, seam", [-2.0, 0.1, 1.2], [0.5, 3.0, 0.4], 0.0, axis_angle_to_matrix([0.2, 0.1, 0.0])),
]


@pytest.mark.parametrize("name, center, size, yaw, R", BOXES, ids=[b[0] for b in BOXES])
def test_box_extent_contains_the_projected_box_and_is_tight(name, center, size, yaw, R):
    res = world_box_to_pano(center, size, yaw, W, H, CH, rotation=R, samples_per_edge=24)
    pts = world_to_pixel(surface_points(np.array(center), np.array(size), yaw), W, H, CH, R)
    assert in_extent(pts, res.extent, W).all()
    assert in_extent(res.corners, res.extent, W).all()
    for pl in res.polylines:
        assert in_extent(pl, res.extent, W).all()
    assert len(res.edges) == 12
    # tight: the extent is not larger than the densely sampled box (plus a pixel), and it only
    # reaches a pole when the camera's up or down direction really passes through the box
    dense = world_to_pixel(surface_points(np.array(center), np.array(size), yaw, 60), W, H, CH, R)
    up = np.array([0.0, 0.0, 1.0]) if R is None else R[:, 2]
    s = np.linspace(0.0, 5.0, 5001)[:, None]
    local_up = (CAM + s * up - center) @ rot_z(yaw)
    local_down = (CAM - s * up - center) @ rot_z(yaw)
    hits_up = np.any(np.all(np.abs(local_up) <= np.array(size) / 2, axis=1))
    hits_down = np.any(np.all(np.abs(local_down) <= np.array(size) / 2, axis=1))
    v0, v1 = res.extent[1], res.extent[3]
    assert (v0 == 0) == hits_up and (v1 == H) == hits_down
    assert hits_up or dense[:, 1].min() - v0 < 1.0
    assert hits_down or v1 - dense[:, 1].max() < 1.0
    if not (res.extent[0] == 0 and res.extent[2] == W):
        width = (res.extent[2] - res.extent[0]) % W
        us = np.sort(np.mod(dense[:, 0] - res.extent[0], W))
        assert width - us[-1] < 1.0 and us[0] < 1.0


def test_box_special_cases():
    seam = world_box_to_pano([-3.0, 0.2, 0.5], [1.2, 2.0, 1.0], 1.0, W, H, CH)
    assert seam.wraps and seam.extent[0] > W / 2 > seam.extent[2]
    lamp = world_box_to_pano([0.1, -0.2, 2.6], [0.8, 0.5, 0.3], 0.7, W, H, CH)
    assert lamp.extent[0] == 0 and lamp.extent[1] == 0 and lamp.extent[2] == W and not lamp.wraps
    rug = world_box_to_pano([0.3, 0.2, 0.01], [2.0, 1.5, 0.02], 0.2, W, H, CH)
    assert rug.extent[3] == H
    around = world_box_to_pano([0.0, 0.0, 1.5], [5.0, 4.0, 3.0], 0.0, W, H, CH)
    assert np.array_equal(around.extent, [0, 0, W, H])
    front = world_box_to_pano([2.5, 0.0, 0.4], [1.0, 0.6, 0.8], 0.0, W, H, CH)
    assert not front.wraps and front.extent[0] < W / 2 < front.extent[2]


def test_box_edge_curves_bulge_and_the_extent_follows():
    # a long wall-top edge in front of the camera bulges up (towards the horizon's far side) between its corners
    res = world_box_to_pano([2.0, 0.0, 2.5], [0.2, 6.0, 0.2], 0.0, W, H, CH, samples_per_edge=2)
    assert res.extent[1] < res.corners[:, 1].min() - 5


@pytest.mark.parametrize("call, match", [
    (lambda: world_polyline_to_pano([[0.0, 0.0, CH]], W, H, CH), "away from the camera centre"),
    (lambda: world_polyline_to_pano([[-1.0, 0.0, CH], [1.0, 0.0, CH]], W, H, CH), "through it"),
    (lambda: world_polyline_to_pano(np.zeros((0, 3)), W, H), r"\(N, 3\) with N >= 1"),
    (lambda: world_polyline_to_pano([[1.0, 2.0]], W, H), r"shape \(\.\.\., 3\)"),
    (lambda: world_polyline_to_pano([[1.0, np.nan, 0.0]], W, H), "finite"),
    (lambda: world_polyline_to_pano([[1.0, 0.0, 0.0]], 1000, 512), r"W == 2\*H"),
    (lambda: world_polyline_to_pano([[1.0, 0.0, 0.0]], W, H, samples_per_segment=1), "integer >= 2"),
    (lambda: world_polyline_to_pano([[1.0, 0.0, 0.0]], W, H, rotation=np.ones((3, 3))), "orthonormal"),
    (lambda: world_polyline_to_pano([[1.0, 0.0, 0.0]], W, H, camera_height=np.nan), "camera_height"),
    (lambda: world_box_corners([0.0, 0.0], [1.0, 1.0, 1.0], 0.0), r"center: expected shape \(3,\)"),
    (lambda: world_box_corners([0.0, 0.0, 0.0], [1.0, 0.0, 1.0], 0.0), "all sizes > 0"),
    (lambda: world_box_corners([0.0, 0.0, 0.0], [1.0, 1.0, 1.0], np.inf), "yaw: expected a finite angle"),
    (lambda: world_box_to_pano([3.0, 0.0, 1.0], [1.0, 1.0, 1.0], 0.0, W, H, samples_per_edge=0), "integer >= 2"),
    (lambda: world_box_to_pano([0.5, 0.5, 1.2], [1.0, 1.0, 1.2], 0.0, W, H, CH), "through it"),
])
def test_bad_input_raises_with_a_message(call, match):
    with pytest.raises(ValueError, match=match):
        call()
