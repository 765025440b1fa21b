"""Tests of panogeom.rotation."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from panogeom.coords import ray_to_lonlat
from panogeom.rotation import (
    angle_difference,
    axis_angle_to_matrix,
    check_rotation,
    matrix_to_axis_angle,
    matrix_to_ypr,
    nearest_rotation,
    rot_x,
    rot_y,
    rot_z,
    ypr_to_matrix,
)

angle = st.floats(-np.pi + 1e-9, np.pi - 1e-9)


def wrapped(a):
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def is_rotation(R, tol=1e-12):
    return np.abs(R @ R.T - np.eye(3)).max() < tol and abs(np.linalg.det(R) - 1.0) < tol


@settings(max_examples=300, deadline=None)
@given(yaw=angle, pitch=st.floats(-np.pi / 2 + 1e-3, np.pi / 2 - 1e-3), roll=angle)
def test_ypr_round_trip(yaw, pitch, roll):
    R = ypr_to_matrix(yaw, pitch, roll)
    assert is_rotation(R)
    y2, p2, r2 = matrix_to_ypr(R)
    assert abs(wrapped(y2 - yaw)) < 1e-12
    assert abs(p2 - pitch) < 1e-12
    assert abs(wrapped(r2 - roll)) < 1e-12
    assert np.abs(ypr_to_matrix(y2, p2, r2) - R).max() < 1e-12


@settings(max_examples=100, deadline=None)
@given(yaw=angle, roll=angle, sign=st.sampled_from([-1.0, 1.0]), eps=st.sampled_from([0.0, 1e-14, 1e-9]))
def test_ypr_at_gimbal_lock_reproduces_the_matrix(yaw, roll, sign, eps):
    R = ypr_to_matrix(yaw, sign * (np.pi / 2 - eps), roll)
    y2, p2, r2 = matrix_to_ypr(R)
    assert np.abs(ypr_to_matrix(y2, p2, r2) - R).max() < 1e-12


@settings(max_examples=300, deadline=None)
@given(x=st.floats(-1, 1), y=st.floats(-1, 1), z=st.floats(-1, 1), theta=st.floats(1e-6, np.pi - 1e-3))
def test_axis_angle_round_trip(x, y, z, theta):
    axis = np.array([x, y, z])
    if np.linalg.norm(axis) < 1e-3:
        return
    rv = axis / np.linalg.norm(axis) * theta
    R = axis_angle_to_matrix(rv)
    assert is_rotation(R)
    assert np.abs(matrix_to_axis_angle(R) - rv).max() < 1e-12
    # the axis is fixed, the angle is the rotation angle
    assert np.allclose(R @ axis, axis, atol=1e-14)
    assert np.isclose(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1)), theta, atol=1e-7)


def test_zero_rotation_vector_is_identity():
    assert np.array_equal(axis_angle_to_matrix([0.0, 0.0, 0.0]), np.eye(3))
    assert np.allclose(matrix_to_axis_angle(np.eye(3)), 0.0)


def test_elementary_rotations_are_right_handed():
    assert np.allclose(rot_z(np.pi / 2) @ [1, 0, 0], [0, 1, 0])
    assert np.allclose(rot_x(np.pi / 2) @ [0, 1, 0], [0, 0, 1])
    assert np.allclose(rot_y(np.pi / 2) @ [0, 0, 1], [1, 0, 0])


def test_ypr_pointing_convention():
    # first column is the viewing direction; a view at yaw a looks at lon = -a
    for a in np.linspace(-3, 3, 7):
        f = ypr_to_matrix(a)[:, 0]
        assert np.isclose(ray_to_lonlat(f)[0], -a)
    # yaw turns counter-clockwise from +x towards +y
    assert np.allclose(ypr_to_matrix(np.pi / 2)[:, 0], [0, 1, 0])
    # pitch up positive
    assert ypr_to_matrix(0.0, 0.3)[2, 0] > 0
    # roll is right-handed about the viewing direction: up (third column) turns towards the right (-y)
    up = ypr_to_matrix(0.0, 0.0, 0.2)[:, 2]
    assert up[1] < 0 and up[2] > 0


def test_nearest_rotation_projects_noise_and_reflections():
    rng = np.random.default_rng(7)
    R = axis_angle_to_matrix(rng.normal(size=3))
    noisy = R + 1e-3 * rng.normal(size=(3, 3))
    Rn = nearest_rotation(noisy)
    assert is_rotation(Rn)
    assert np.abs(Rn - R).max() < 5e-3
    flip = np.diag([1.0, 1.0, -1.0])
    assert is_rotation(nearest_rotation(flip))
    assert np.allclose(nearest_rotation(R), R, atol=1e-12)


@pytest.mark.parametrize("M, match", [
    (np.eye(3) * 1.01, "orthonormal"),
    (np.diag([1.0, 1.0, -1.0]), "reflection"),
    (np.eye(4), r"\(3, 3\)"),
    (np.full((3, 3), np.nan), "finite"),
])
def test_check_rotation_rejects(M, match):
    with pytest.raises(ValueError, match=match):
        check_rotation(M)


@pytest.mark.parametrize("call, match", [
    (lambda: axis_angle_to_matrix([1.0, 2.0]), r"shape \(3,\)"),
    (lambda: ypr_to_matrix(np.nan), "yaw: expected a finite angle"),
    (lambda: ypr_to_matrix(0.0, np.inf), "pitch: expected a finite angle"),
    (lambda: matrix_to_ypr(np.ones((3, 3))), "orthonormal"),
    (lambda: nearest_rotation(np.ones((2, 2))), r"shape \(3, 3\)"),
])
def test_bad_input_raises_with_a_message(call, match):
    with pytest.raises(ValueError, match=match):
        call()


@settings(max_examples=200, deadline=None)
@given(a=st.floats(-20.0, 20.0), b=st.floats(-20.0, 20.0), fold=st.sampled_from([1, 2, 4]))
def test_angle_difference_is_the_smallest_turn(a, b, fold):
    d = float(angle_difference(a, b, fold))
    period = 2 * np.pi / fold
    assert 0.0 <= d <= period / 2 + 1e-12
    # b turned by +-d (mod the period) lands on a
    assert min(abs(wrapped(fold * (b + s * d - a))) for s in (1.0, -1.0)) < 1e-9 * fold


def test_angle_difference_broadcasts_and_checks_fold():
    out = angle_difference(np.deg2rad([[0.0], [90.0]]), np.deg2rad([180.0, 270.0, 5.0]))
    assert out.shape == (2, 3)
    assert np.allclose(np.rad2deg(out), [[180.0, 90.0, 5.0], [90.0, 180.0, 85.0]])
    with pytest.raises(ValueError, match="fold"):
        angle_difference(0.0, 1.0, fold=0)
