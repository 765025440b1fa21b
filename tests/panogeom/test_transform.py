"""Tests of panogeom.transform: rotating panoramas and panoramas from functions of direction."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from panogeom.coords import pixel_to_ray, world_to_pixel
from panogeom.rotation import axis_angle_to_matrix, rot_x, rot_z, ypr_to_matrix
from panogeom.transform import pano_from_directions, procedural_pano, rotate_pano, rotate_pixels

H = 256
W = 2 * H


def away_from_poles(height, deg=10.0):
    lat = 90.0 - 180.0 * (np.arange(height) + 0.5) / height
    return np.abs(lat) < 90.0 - deg


@pytest.fixture(scope="module")
def pano():
    return procedural_pano(H)


def test_procedural_pano_is_deterministic_and_textured(pano):
    assert pano.shape == (H, W, 3) and pano.dtype == np.uint8
    assert np.array_equal(pano, procedural_pano(H))
    assert not np.array_equal(pano, procedural_pano(H, seed=1))
    assert pano.std() > 15
    # smooth: neighbouring pixels differ little (band-limited), the seam included
    assert np.abs(np.diff(pano.astype(float), axis=1)).mean() < 3
    assert np.abs(pano[:, 0].astype(float) - pano[:, -1]).mean() < 3


def test_yaw_by_whole_columns_is_a_roll(pano):
    for k in (1, 7, -30, 256):
        out = rotate_pano(pano, rot_z(2 * np.pi * k / W))
        assert np.array_equal(out, np.roll(pano, -k, axis=1)), k


def test_identity_keeps_the_image(pano):
    assert np.array_equal(rotate_pano(pano, np.eye(3)), pano)
    labels = pano[..., 0] // 50
    assert np.array_equal(rotate_pano(labels, np.eye(3), "nearest"), labels)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_rotated_pano_equals_the_pattern_rendered_in_the_rotated_frame(pano, seed):
    R = axis_angle_to_matrix(np.random.default_rng(seed).normal(size=3))
    rotated = rotate_pano(pano, R).astype(float)
    expected = procedural_pano(H, rotation=R).astype(float)
    err = np.abs(rotated - expected)
    assert err.mean() < 1.5
    assert err[away_from_poles(H)].mean() < 1.5


def test_rotation_and_back(pano):
    R = ypr_to_matrix(0.4, -0.3, 0.2)
    back = rotate_pano(rotate_pano(pano, R), R.T)
    assert np.abs(back.astype(float) - pano).mean() < 2.0


def test_rotation_sense_matches_the_convention():
    # the spot seen at lon = 0 by the input appears at lon = -a after rot_z(a)
    img = pano_from_directions(lambda d: np.exp(-(1 - d[:, 0]) / 0.01), 128)
    out = rotate_pano(img, rot_z(np.pi / 2))
    i, j = np.unravel_index(np.argmax(out), out.shape)
    assert abs(j + 0.5 - 64) <= 1 and abs(i + 0.5 - 64) <= 1      # lon = -pi/2 is u = W/4
    # rot_x(pi/2) carries the input's left (+y, u = W/4) up to the zenith, while +x stays put
    left = pano_from_directions(lambda d: np.exp(-(1 - d[:, 1]) / 0.01), 128)
    out = rotate_pano(left + img, rot_x(np.pi / 2))
    assert out[:3].mean() > 0.9 and out[-3:].mean() < 0.01
    i, j = np.unravel_index(np.argmax(out[10:-10]), out[10:-10].shape)
    assert abs(j + 0.5 - 128) <= 1 and abs(i + 10.5 - 64) <= 1


def test_nearest_keeps_labels(pano):
    labels = (pano[..., 1] // 30).astype(np.uint8)
    out = rotate_pano(labels, ypr_to_matrix(1.0, 0.5, -0.2), "nearest")
    assert set(np.unique(out)) <= set(np.unique(labels))


@settings(max_examples=100, deadline=None)
@given(u=st.floats(0, W), v=st.floats(0, H), rv=st.tuples(*[st.floats(-3, 3)] * 3))
def test_rotate_pixels_moves_rays_and_inverts(u, v, rv):
    R = axis_angle_to_matrix(np.array(rv))
    out = rotate_pixels([u, v], R, W, H)
    assert np.allclose(pixel_to_ray(out, W, H), R @ pixel_to_ray([u, v], W, H), atol=1e-12)
    back = rotate_pixels(out, R, W, H, inverse=True)
    assert np.allclose(pixel_to_ray(back, W, H), pixel_to_ray([u, v], W, H), atol=1e-12)


def test_rotate_pixels_follows_the_image_content(pano):
    # a spot at a known input pixel lands where rotate_pixels says
    target = np.array([100.5, 60.5])
    d0 = pixel_to_ray(target, W, H)
    img = pano_from_directions(lambda d: np.exp(-(1 - d @ d0) / 2e-4), H).astype(np.float32)
    R = ypr_to_matrix(2.0, 0.7, 0.3)
    out = rotate_pano(img, R)
    expected = rotate_pixels(target, R, W, H)
    yy, xx = np.mgrid[0:H, 0:W] + 0.5
    win = (np.abs(xx - expected[0]) < 8) & (np.abs(yy - expected[1]) < 8)
    wgt = out * win
    assert np.hypot((wgt * xx).sum() / wgt.sum() - expected[0], (wgt * yy).sum() / wgt.sum() - expected[1]) < 0.5


def test_world_to_pixel_and_rotate_pixels_agree():
    # camera.rotation maps input directions into the world: moving input pixels by it gives world pixels
    rng = np.random.default_rng(9)
    R = axis_angle_to_matrix(rng.normal(size=3) * 0.3)
    pts = rng.normal(size=(40, 3)) * 3
    uv_in = world_to_pixel(pts, W, H, 1.6, rotation=R)
    uv_world = world_to_pixel(pts, W, H, 1.6)
    moved = rotate_pixels(uv_in, R, W, H)
    d = np.abs(moved - uv_world)
    d[:, 0] = np.minimum(d[:, 0], W - d[:, 0])
    assert d.max() < 1e-9


def test_pano_from_directions_shapes_and_rotation():
    assert pano_from_directions(lambda d: d, 8).shape == (8, 16, 3)
    img = pano_from_directions(lambda d: d[:, 0], 8)
    R = rot_z(np.pi)
    assert np.allclose(pano_from_directions(lambda d: d[:, 0], 8, rotation=R), np.roll(img, 8, axis=1))


@pytest.mark.parametrize("call, match", [
    (lambda: rotate_pano(np.zeros((10, 30)), np.eye(3)), r"W == 2\*H"),
    (lambda: rotate_pano(np.zeros((10, 20, 5)), np.eye(3)), r"C in \(1, 3, 4\)"),
    (lambda: rotate_pano(np.zeros((10, 20), np.complex64), np.eye(3)), "dtype"),
    (lambda: rotate_pano(np.zeros((10, 20)), np.eye(3) * 1.1), "R: expected an orthonormal matrix"),
    (lambda: rotate_pano(np.zeros((10, 20)), np.diag([1.0, -1.0, 1.0])), "reflection"),
    (lambda: rotate_pano(np.zeros((10, 20)), np.eye(2)), r"\(3, 3\) rotation"),
    (lambda: rotate_pano(np.zeros((10, 20)), np.eye(3), "area"), "interpolation"),
    (lambda: rotate_pixels([1.0, 2.0], np.eye(3), 30, 10), r"W == 2\*H"),
    (lambda: rotate_pixels([np.nan, 2.0], np.eye(3), 20, 10), "finite"),
    (lambda: pano_from_directions(lambda d: d[:5], 4), r"expected shape \(N,\) or \(N, C\)"),
    (lambda: pano_from_directions(lambda d: d[:, 0], 0), "height: expected a positive integer"),
    (lambda: pano_from_directions(lambda d: d[:, 0], 4.5), "height: expected a positive integer"),
    (lambda: procedural_pano(-3), "height: expected a positive integer"),
])
def test_bad_input_raises_with_a_message(call, match):
    with pytest.raises(ValueError, match=match):
        call()
