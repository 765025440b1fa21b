"""Tests of panogeom.coords: pixel <-> lon/lat <-> ray, world_to_pixel."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from panogeom.coords import (
    lonlat_to_pixel,
    lonlat_to_ray,
    pixel_grid,
    pixel_grid_rays,
    pixel_to_lonlat,
    pixel_to_ray,
    ray_to_lonlat,
    ray_to_pixel,
    world_to_pixel,
    wrap_u,
)
from panogeom.rotation import axis_angle_to_matrix

W, H = 2048, 1024


def seam_diff(u0, u1, width):
    """Horizontal distance across the seam."""
    d = np.abs(np.asarray(u0) - np.asarray(u1)) % width
    return np.minimum(d, width - d)


@settings(max_examples=400, deadline=None)
@given(u=st.floats(0.0, W), v=st.floats(0.0, H))
@example(u=0.0, v=512.0)          # left edge of the seam
@example(u=float(W), v=512.0)     # right edge of the seam
@example(u=1e-12, v=300.0)
@example(u=W - 1e-9, v=700.0)
@example(u=123.4, v=0.0)          # north pole
@example(u=1500.25, v=float(H))   # south pole
@example(u=0.0, v=0.0)
@example(u=777.0, v=1e-9)
@example(u=5.0, v=H - 1e-7)
def test_pixel_ray_pixel_round_trip(u, v):
    ray = pixel_to_ray([u, v], W, H)
    assert abs(np.linalg.norm(ray) - 1.0) < 1e-15
    back = ray_to_pixel(ray, W, H)
    assert 0.0 <= back[0] < W
    assert seam_diff(back[0], u, W) < 1e-9
    assert abs(back[1] - v) < 1e-9


@settings(max_examples=200, deadline=None)
@given(x=st.floats(-1, 1), y=st.floats(-1, 1), z=st.floats(-1, 1), scale=st.floats(1e-3, 1e3))
def test_ray_lonlat_ray_round_trip_any_length(x, y, z, scale):
    d = np.array([x, y, z])
    if np.linalg.norm(d) < 1e-6:
        return
    ll = ray_to_lonlat(d * scale)
    assert -np.pi <= ll[0] <= np.pi and -np.pi / 2 <= ll[1] <= np.pi / 2
    assert np.allclose(lonlat_to_ray(ll), d / np.linalg.norm(d), atol=1e-14)


def test_frame_directions_follow_conventions():
    # centre column looks along +x, a quarter width left of centre along +y, top is +z
    assert np.allclose(pixel_to_ray([W / 2, H / 2], W, H), [1, 0, 0], atol=1e-15)
    assert np.allclose(pixel_to_ray([W / 4, H / 2], W, H), [0, 1, 0], atol=1e-15)
    assert np.allclose(pixel_to_ray([3 * W / 4, H / 2], W, H), [0, -1, 0], atol=1e-15)
    assert np.allclose(pixel_to_ray([0.0, H / 2], W, H), [-1, 0, 0], atol=1e-15)
    assert np.allclose(pixel_to_ray([10.0, 0.0], W, H), [0, 0, 1], atol=1e-15)
    assert np.allclose(pixel_to_ray([10.0, H], W, H), [0, 0, -1], atol=1e-15)
    # moving right in the image turns right (clockwise seen from above: towards -y)
    r = pixel_to_ray([W / 2 + 10, H / 2], W, H)
    assert r[1] < 0 and r[0] > 0


def test_lonlat_pixel_formulas_and_inverse():
    uv = np.array([[0.0, 0.0], [W, H], [W / 2, H / 2], [W / 4, 3 * H / 4]])
    ll = pixel_to_lonlat(uv, W, H)
    assert np.allclose(ll, [[-np.pi, np.pi / 2], [np.pi, -np.pi / 2], [0, 0], [-np.pi / 2, -np.pi / 4]])
    assert np.allclose(lonlat_to_pixel(ll, W, H), uv, atol=1e-12)


def test_shapes_are_preserved_for_any_leading_shape():
    uv = np.random.default_rng(0).uniform(0, H, size=(3, 4, 5, 2))
    assert pixel_to_ray(uv, W, H).shape == (3, 4, 5, 3)
    assert ray_to_pixel(pixel_to_ray(uv, W, H), W, H).shape == uv.shape


def test_pixel_grid_centres_and_rays():
    g = pixel_grid(8, 4)
    assert g.shape == (4, 8, 2)
    assert g[0, 0].tolist() == [0.5, 0.5] and g[3, 7].tolist() == [7.5, 3.5]
    rays = pixel_grid_rays(8, 4)
    assert rays.shape == (4, 8, 3)
    assert np.allclose(np.linalg.norm(rays, axis=-1), 1.0)
    # symmetric about the horizon
    assert np.allclose(rays[0, :, 2], -rays[3, :, 2])


def test_wrap_u():
    assert np.allclose(wrap_u([-1.0, 0.0, W, W + 3.5, 2.5 * W], W), [W - 1, 0, 0, 3.5, W / 2])
    # a tiny negative value must not wrap to exactly W
    assert wrap_u(-1e-300, W) < W


def test_world_to_pixel_known_points():
    ch = 1.6
    # straight ahead at camera height -> image centre
    assert np.allclose(world_to_pixel([3.0, 0.0, ch], W, H, ch), [W / 2, H / 2])
    # floor point at 45 degrees below the horizon, to the left (+y)
    uv = world_to_pixel([0.0, ch, 0.0], W, H, ch)
    assert np.allclose(uv, [W / 4, 3 * H / 4])
    # the foot of the camera is the nadir
    assert np.isclose(world_to_pixel([0.0, 0.0, 0.0], W, H, ch)[1], H)


def test_world_to_pixel_with_rotation_projects_into_the_input_frame():
    rng = np.random.default_rng(3)
    R = axis_angle_to_matrix(rng.normal(size=3))
    pts = rng.normal(size=(50, 3)) * 3 + [0, 0, 1.6]
    uv_in = world_to_pixel(pts, W, H, 1.6, rotation=R)
    # R maps camera directions into the world: the input ray of each pixel, rotated, points at the point
    d_world = pixel_to_ray(uv_in, W, H) @ R.T
    expected = pts - [0, 0, 1.6]
    expected /= np.linalg.norm(expected, axis=1, keepdims=True)
    assert np.allclose(d_world, expected, atol=1e-12)


@pytest.mark.parametrize("call, match", [
    (lambda: pixel_to_ray([np.nan, 3.0], W, H), "finite"),
    (lambda: pixel_to_ray([1.0, 2.0, 3.0], W, H), r"shape \(\.\.\., 2\)"),
    (lambda: ray_to_pixel([0.0, 0.0, 0.0], W, H), "non-zero"),
    (lambda: ray_to_lonlat([[1.0, np.inf, 0.0]]), "finite"),
    (lambda: ray_to_pixel([[1.0, 0.0]], W, H), r"shape \(\.\.\., 3\)"),
    (lambda: pixel_to_lonlat([1.0, 1.0], 0, H), "positive finite"),
    (lambda: pixel_to_lonlat([1.0, 1.0], W, -5), "positive finite"),
    (lambda: pixel_grid(0, 4), "positive size"),
    (lambda: world_to_pixel([0.0, 0.0, 1.6], W, H, camera_height=1.6), "non-zero"),
    (lambda: world_to_pixel([1.0, 0.0, 1.6], W, H, rotation=np.eye(3) * 2), "orthonormal"),
    (lambda: pixel_to_ray("abc", W, H), "numeric"),
])
def test_bad_input_raises_with_a_message(call, match):
    with pytest.raises(ValueError, match=match):
        call()
