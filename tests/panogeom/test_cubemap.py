"""Tests of panogeom.cubemap: equirect <-> cubemap, layouts, face conventions."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from panogeom.coords import pixel_grid_rays, ray_to_pixel
from panogeom.cubemap import (
    FACE_NAMES,
    cube_face_axes,
    cube_face_views,
    cube_to_ray,
    cubemap_faces,
    cubemap_to_equirect,
    equirect_to_cubemap,
    faces_to_cubemap,
    ray_to_cube,
)
from panogeom.perspective import equirect_to_perspective
from panogeom.sampling import sample_equirect
from panogeom.transform import procedural_pano

PANO_H = 512


@pytest.fixture(scope="module")
def pano():
    return procedural_pano(PANO_H)


def away_from_poles(height, deg=10.0):
    lat = 90.0 - 180.0 * (np.arange(height) + 0.5) / height
    return np.abs(lat) < 90.0 - deg


def test_face_table_matches_the_documented_axes():
    ax = cube_face_axes()
    # columns: image right, image down, viewing direction
    table = {
        "F": ([0, -1, 0], [0, 0, -1], [1, 0, 0]),
        "R": ([-1, 0, 0], [0, 0, -1], [0, -1, 0]),
        "B": ([0, 1, 0], [0, 0, -1], [-1, 0, 0]),
        "L": ([1, 0, 0], [0, 0, -1], [0, 1, 0]),
        "U": ([0, -1, 0], [1, 0, 0], [0, 0, 1]),
        "D": ([0, -1, 0], [-1, 0, 0], [0, 0, -1]),
    }
    for k, name in enumerate(FACE_NAMES):
        assert np.array_equal(ax[k], np.array(table[name], float).T), name
        assert np.isclose(np.linalg.det(ax[k]), 1.0)
    # each face is the 90-degree pinhole view of the same orientation
    for k, view in enumerate(cube_face_views(16)):
        assert np.allclose(view.R, ax[k], atol=1e-15)
        assert view.width == view.height == 16 and np.isclose(view.fov, np.pi / 2)


def test_face_centres_look_at_the_documented_longitudes():
    c = cube_to_ray(np.arange(6), np.full((6, 2), 8.0), 16)
    uv = ray_to_pixel(c[:4], 360, 180)
    # F at lon 0 (u = W/2), R at lon +90 (u = 3W/4), B at lon 180 (u = 0), L at lon -90 (u = W/4)
    assert np.allclose(np.mod(uv[:, 0] + 1, 360) - 1, [180, 270, 0, 90], atol=1e-9)
    assert np.allclose(c[4:], [[0, 0, 1], [0, 0, -1]])


@settings(max_examples=200, deadline=None)
@given(x=st.floats(-1, 1), y=st.floats(-1, 1), z=st.floats(-1, 1), s=st.integers(1, 700))
def test_ray_cube_round_trip(x, y, z, s):
    d = np.array([x, y, z])
    if np.linalg.norm(d) < 1e-6:
        return
    face, uv = ray_to_cube(d, s)
    assert 0 <= face <= 5 and np.all((uv >= 0) & (uv <= s))
    assert np.allclose(cube_to_ray(face, uv, s), d / np.linalg.norm(d), atol=1e-12)


def test_face_pixel_centres_follow_the_half_pixel_convention():
    s = 4
    rays = cube_to_ray(np.zeros(2, int), [[0.5, 2.0], [3.5, 2.0]], s)
    # pixel centre j sits at tan = 2 (j + 0.5) / S - 1 on the face plane
    assert np.allclose(rays[:, 1] / rays[:, 0], [0.75, -0.75])


@pytest.mark.parametrize("face_size", [128, 97])
def test_round_trip_equirect_cubemap_equirect(pano, face_size):
    faces = equirect_to_cubemap(pano, face_size)
    back = cubemap_to_equirect(faces, PANO_H // 2 if face_size < 100 else PANO_H)
    ref = pano if back.shape == pano.shape else sample_equirect(
        pano, ray_to_pixel(pixel_grid_rays(back.shape[1], back.shape[0]), pano.shape[1], pano.shape[0]))
    err = np.abs(back.astype(float) - ref)
    assert err[away_from_poles(back.shape[0])].mean() < 1.5
    assert back.dtype == pano.dtype and back.shape == ref.shape


def test_round_trip_at_full_resolution_and_across_face_edges(pano):
    faces = equirect_to_cubemap(pano, 320)
    back = cubemap_to_equirect(faces, PANO_H)
    err = np.abs(back.astype(float) - pano).max(axis=-1)
    rows = away_from_poles(PANO_H)
    assert err[rows].mean() < 1.5
    # equirect pixels whose bilinear footprint straddles two faces: no seam artefacts there
    face, uv = ray_to_cube(pixel_grid_rays(2 * PANO_H, PANO_H), 320)
    edge = np.any((uv < 1.0) | (uv > 319.0), axis=-1)
    assert edge.sum() > 1000
    assert err[edge].mean() < 1.5 and np.percentile(err[edge], 99) < 6
    # the poles (inside U and D) survive too
    assert err[~rows].mean() < 2.0


@pytest.mark.parametrize("interp", ["linear", "cubic"])
def test_face_edges_interpolate_like_face_interiors(interp):
    # faces rendered analytically from a steep smooth function: interpolating across a face edge
    # must be as accurate as inside a face (a clamped border would be off by ~half a pixel's slope)
    axis = np.array([0.5, -0.7, 0.4]) / np.linalg.norm([0.5, -0.7, 0.4])

    def f(d):
        return 1000.0 * (d @ axis) + 300.0 * d[..., 0] * d[..., 1]

    s = 32
    j = np.arange(s) + 0.5
    u, v = np.meshgrid(j, j)
    faces = [f(cube_to_ray(np.full(u.shape, k), np.stack([u, v], -1), s)).astype(np.float32) for k in range(6)]
    rays = pixel_grid_rays(256, 128)
    _, uv = ray_to_cube(rays, s)
    edge = np.any((uv < 0.5) | (uv > s - 0.5), axis=-1)
    err = np.abs(cubemap_to_equirect(faces, 128, interpolation=interp) - f(rays))
    assert edge.sum() > 500
    assert err[edge].max() <= err[~edge].max()


def test_equirect_to_cubemap_faces_are_perspective_views(pano):
    faces = equirect_to_cubemap(pano, 64)
    for face, view in zip(faces, cube_face_views(64)):
        assert np.array_equal(face, equirect_to_perspective(pano, view))


def test_agrees_with_py360convert(pano):
    p3 = pytest.importorskip("py360convert")
    s = 256
    ours = equirect_to_cubemap(pano, s)
    theirs = p3.e2c(pano, s, cube_format="list")
    # same face order and in-face orientation ...
    for name, a, b in zip(FACE_NAMES, ours, theirs):
        assert np.abs(a.astype(float) - b).mean() < 1.5, name
    # ... and its face pixel j samples tan = 2 j / (S - 1) - 1 (corner-aligned), so our faces
    # sampled at those positions reproduce it almost exactly
    jj = np.arange(s) * s / (s - 1)
    u, v = np.meshgrid(jj, jj)
    for k, b in enumerate(theirs):
        rays = cube_to_ray(np.full(u.shape, k), np.stack([u, v], -1), s)
        at_its_pixels = sample_equirect(pano, ray_to_pixel(rays, 2 * PANO_H, PANO_H))
        assert np.abs(at_its_pixels.astype(float) - b).mean() < 0.5, FACE_NAMES[k]
    # cubemaps made by one library are read correctly by the other
    rows = away_from_poles(PANO_H)
    mine_from_theirs = cubemap_to_equirect(theirs, PANO_H).astype(float)
    assert np.abs(mine_from_theirs - pano)[rows].mean() < 1.5
    theirs_from_mine = p3.c2e(ours, PANO_H, 2 * PANO_H, cube_format="list").astype(float)
    assert np.abs(theirs_from_mine - pano)[rows].mean() < 1.5
    assert p3.e2c(pano, s, cube_format="dice").shape == equirect_to_cubemap(pano, s, "dice").shape


def test_py360convert_c2e_grid_is_corner_aligned():
    p3 = pytest.importorskip("py360convert")
    axis = np.array([0.2, 0.9, -0.4]) / np.linalg.norm([0.2, 0.9, -0.4])

    def f(d):
        return 100.0 + 80.0 * (d @ axis)

    s, h = 64, 64
    w = 2 * h
    # its c2e reads face pixel j at our continuous coordinate j (tan = 2 j / S - 1) ...
    jj = np.arange(s, dtype=float)
    u, v = np.meshgrid(jj, jj)
    faces = [f(cube_to_ray(np.full(u.shape, k), np.stack([u, v], -1), s)).astype(np.float32) for k in range(6)]
    out = p3.c2e(faces, h, w, cube_format="list")
    # ... and writes its output on a corner-aligned lon/lat grid
    lon = -np.pi + 2 * np.pi * np.arange(w) / (w - 1)
    lat = np.pi / 2 - np.pi * np.arange(h) / (h - 1)
    lo, la = np.meshgrid(lon, lat)
    corner = f(np.stack([np.cos(la) * np.cos(lo), -np.cos(la) * np.sin(lo), np.sin(la)], -1))
    centre = f(pixel_grid_rays(w, h))
    assert np.abs(out - corner).mean() < 0.1 < np.abs(out - centre).mean()


def test_layouts_are_consistent(pano):
    s = 32
    lst = equirect_to_cubemap(pano, s, "list")
    dct = equirect_to_cubemap(pano, s, "dict")
    hor = equirect_to_cubemap(pano, s, "horizon")
    dice = equirect_to_cubemap(pano, s, "dice")
    assert list(dct) == list(FACE_NAMES)
    assert hor.shape == (s, 6 * s, 3) and dice.shape == (3 * s, 4 * s, 3)
    for k, name in enumerate(FACE_NAMES):
        assert np.array_equal(lst[k], dct[name])
        assert np.array_equal(lst[k], hor[:, k * s:(k + 1) * s])
    # dice: U above F; L F R B in the middle row; D below F
    cells = {"U": (0, 1), "L": (1, 0), "F": (1, 1), "R": (1, 2), "B": (1, 3), "D": (2, 1)}
    for name, (r, c) in cells.items():
        assert np.array_equal(dice[r * s:(r + 1) * s, c * s:(c + 1) * s], dct[name])
    for r, c in [(0, 0), (0, 2), (0, 3), (2, 0), (2, 2), (2, 3)]:
        assert not dice[r * s:(r + 1) * s, c * s:(c + 1) * s].any()
    # every layout converts back to the same panorama, with or without an explicit format
    ref = cubemap_to_equirect(lst, 64)
    for cm, fmt in [(dct, "dict"), (hor, "horizon"), (dice, "dice"), (np.stack(lst), "list")]:
        assert np.array_equal(cubemap_to_equirect(cm, 64), ref)
        assert np.array_equal(cubemap_to_equirect(cm, 64, fmt), ref)
    for fmt in ("list", "dict", "horizon", "dice"):
        again = cubemap_faces(faces_to_cubemap(lst, fmt))
        assert all(np.array_equal(a, b) for a, b in zip(again, lst))
    # neighbouring faces meet along matching edges in the dice
    assert np.abs(dice[s - 1, s:2 * s].astype(float) - dice[s, s:2 * s]).mean() < 8    # U | F
    assert np.abs(dice[s:2 * s, 2 * s - 1].astype(float) - dice[s:2 * s, 2 * s]).mean() < 8  # F | R


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32, np.float64])
@pytest.mark.parametrize("shape", [(64, 128), (64, 128, 1), (64, 128, 4)])
def test_dtypes_and_channels_are_kept(dtype, shape):
    img = np.random.default_rng(0).integers(0, 250, size=shape).astype(dtype)
    faces = equirect_to_cubemap(img, 24)
    assert all(f.dtype == dtype and f.shape == (24, 24) + shape[2:] for f in faces)
    back = cubemap_to_equirect(faces, 32)
    assert back.dtype == dtype and back.shape == (32, 64) + shape[2:]


def test_nearest_keeps_labels(pano):
    labels = (pano[..., 0] // 40).astype(np.uint8)
    faces = equirect_to_cubemap(labels, 50, interpolation="nearest")
    assert set(np.unique(np.stack(faces))) <= set(np.unique(labels))
    back = cubemap_to_equirect(faces, PANO_H, interpolation="nearest")
    assert set(np.unique(back)) <= set(np.unique(labels))
    assert (back == labels)[away_from_poles(PANO_H)].mean() > 0.97


def test_cubic_round_trip(pano):
    back = cubemap_to_equirect(equirect_to_cubemap(pano, 256, interpolation="cubic"), PANO_H,
                               interpolation="cubic")
    assert np.abs(back.astype(float) - pano)[away_from_poles(PANO_H)].mean() < 1.5


def test_constant_faces_give_the_documented_panorama():
    faces = [np.full((8, 8), 40 * k, np.uint8) for k in range(6)]
    face, uv = ray_to_cube(pixel_grid_rays(128, 64), 8)
    assert np.array_equal(cubemap_to_equirect(faces, 64, interpolation="nearest"), 40 * face)
    # bilinear blends neighbouring faces only within half a face pixel of an edge
    inner = np.all((uv > 0.5) & (uv < 7.5), axis=-1)
    assert np.array_equal(cubemap_to_equirect(faces, 64)[inner], 40 * face[inner])


F3 = np.zeros((8, 8, 3), np.uint8)


@pytest.mark.parametrize("call, match", [
    (lambda: equirect_to_cubemap(np.zeros((10, 30, 3)), 8), r"W == 2\*H, got 30x10"),
    (lambda: equirect_to_cubemap(np.zeros((10, 20, 2)), 8), r"C in \(1, 3, 4\)"),
    (lambda: equirect_to_cubemap(np.zeros((10, 20), bool), 8), "dtype, got bool"),
    (lambda: equirect_to_cubemap(np.zeros((10, 20)), 0), "face_size: expected a positive integer, got 0"),
    (lambda: equirect_to_cubemap(np.zeros((10, 20)), 2.5), "face_size: expected a positive integer"),
    (lambda: equirect_to_cubemap(np.zeros((10, 20)), 8, "cross"), "cube_format: expected one of"),
    (lambda: equirect_to_cubemap(np.zeros((10, 20)), 8, interpolation="area"), "interpolation"),
    (lambda: cubemap_to_equirect([F3] * 5, 16), "list of 6 faces"),
    (lambda: cubemap_to_equirect({k: F3 for k in "FRBLU"}, 16), "keys"),
    (lambda: cubemap_to_equirect([F3] * 5 + [np.zeros((9, 9, 3), np.uint8)], 16), "face D: expected shape"),
    (lambda: cubemap_to_equirect([F3] * 5 + [F3.astype(np.float32)], 16), "dtype uint8"),
    (lambda: cubemap_to_equirect([np.zeros((8, 9))] * 6, 16), "square face"),
    (lambda: cubemap_to_equirect([np.zeros((0, 0))] * 6, 16), "non-empty square face"),
    (lambda: cubemap_to_equirect(np.zeros((8, 40)), 16), "expected a list or dict of 6 faces"),
    (lambda: cubemap_to_equirect(np.zeros((8, 40)), 16, "horizon"), r"\(S, 6S\)"),
    (lambda: cubemap_to_equirect(np.zeros((9, 40)), 16, "dice"), r"\(3S, 4S\)"),
    (lambda: cubemap_to_equirect([F3] * 6, 0), "height: expected a positive integer"),
    (lambda: cubemap_to_equirect([F3] * 6, 16.5), "height: expected a positive integer"),
    (lambda: cube_to_ray(6, [1.0, 1.0], 8), "face indices in 0..5"),
    (lambda: ray_to_cube([0.0, 0.0, 0.0], 8), "non-zero"),
    (lambda: ray_to_cube([np.nan, 0.0, 1.0], 8), "finite"),
])
def test_bad_input_raises_with_a_message(call, match):
    with pytest.raises(ValueError, match=match):
        call()
