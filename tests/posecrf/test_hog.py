"""Tests of posecrf.hog: properties of the paper's HOG variant and a loop-by-loop peer."""

from __future__ import annotations

import math

import numpy as np
import pytest

from posecrf.hog import descriptor_size, hog_descriptors, hog_distance


def naive_hog(gray: np.ndarray, cells: int, bins: int) -> np.ndarray:
    """Pixel-by-pixel reference of the documented definition (image already square-sized)."""
    s = gray.shape[0]
    cell_px = s // cells
    hist = np.zeros((cells, cells, bins))
    for y in range(s):
        for x in range(s):
            gx = gray[y, x + 1] - gray[y, x - 1] if 0 < x < s - 1 else 0.0
            gy = gray[y + 1, x] - gray[y - 1, x] if 0 < y < s - 1 else 0.0
            mag = math.hypot(gx, gy)
            ang = math.atan2(gy, gx) % math.pi
            t = ang * bins / math.pi - 0.5
            b0 = math.floor(t)
            frac = t - b0
            hist[y // cell_px, x // cell_px, b0 % bins] += mag * (1 - frac)
            hist[y // cell_px, x // cell_px, (b0 + 1) % bins] += mag * frac
    v = hist.ravel()
    n = np.linalg.norm(v)
    return v / n if n > 0 else v


def shape_image(size: int, kind: str) -> np.ndarray:
    yy, xx = np.mgrid[0:size, 0:size] / size
    if kind == "disc":
        img = ((xx - 0.5) ** 2 + (yy - 0.5) ** 2 < 0.1).astype(np.float64)
    elif kind == "bar":
        img = ((np.abs(xx - 0.5) < 0.1) & (np.abs(yy - 0.5) < 0.4)).astype(np.float64)
    else:
        img = (yy > xx).astype(np.float64)
    return (img * 200 + 30).astype(np.uint8)


def test_matches_pixel_loop_peer() -> None:
    rng = np.random.default_rng(0)
    img = rng.uniform(0, 1, (16, 16)).astype(np.float32)  # already at the working size: resize is the identity
    got = hog_descriptors([img], size=16, cells=4, bins=6)[0]
    ref = naive_hog(img.astype(np.float64), cells=4, bins=6)
    np.testing.assert_allclose(got, ref, rtol=1e-4, atol=1e-5)


def test_shape_norm_and_batching() -> None:
    rng = np.random.default_rng(1)
    imgs = [
        rng.integers(0, 256, (37, 81, 3), dtype=np.uint8),
        rng.uniform(0, 1, (200, 90)),
        rng.integers(0, 256, (5, 7), dtype=np.uint8),
    ]
    d = hog_descriptors(imgs)
    assert d.shape == (3, descriptor_size()) == (3, 144) and d.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, rtol=1e-5)
    for k, img in enumerate(imgs):
        np.testing.assert_array_equal(hog_descriptors([img])[0], d[k])
    assert hog_descriptors([]).shape == (0, 144)
    stack = rng.integers(0, 256, (4, 30, 30), dtype=np.uint8)
    np.testing.assert_array_equal(hog_descriptors(stack), hog_descriptors(list(stack)))


def test_unsigned_and_contrast_invariance() -> None:
    img = shape_image(96, "disc")
    d = hog_descriptors([img])[0]
    inverted = hog_descriptors([255 - img])[0]  # gradients flip sign: same unsigned orientations
    np.testing.assert_allclose(d, inverted, atol=1e-5)
    f = img.astype(np.float64) / 255.0
    np.testing.assert_allclose(hog_descriptors([f * 0.5])[0], d, atol=1e-5)
    np.testing.assert_allclose(hog_descriptors([f])[0], d, atol=1e-5)


def test_edge_orientation_bins() -> None:
    vertical_edge = np.zeros((64, 64), np.uint8)
    vertical_edge[:, 32:] = 255       # gradient along +x: angle 0 -> bins 0 and 8 share it
    horizontal_edge = vertical_edge.T.copy()  # gradient along +y: angle pi/2 -> bin 4
    hv = hog_descriptors([vertical_edge])[0].reshape(16, 9).sum(axis=0)
    hh = hog_descriptors([horizontal_edge])[0].reshape(16, 9).sum(axis=0)
    assert hv[0] == pytest.approx(hv[8]) and hv[0] > 0.4 and hv[1:8].max() < 1e-6
    assert int(np.argmax(hh)) == 4 and hh[4] > 0.9 * hh.sum()
    # the edge lies in the middle cell columns (1 and 2 of 0..3)
    per_cell = hog_descriptors([vertical_edge])[0].reshape(4, 4, 9).sum(axis=2)
    assert per_cell[:, [0, 3]].max() < 1e-6 and per_cell[:, 1:3].min() > 0


def test_mask_hides_background() -> None:
    rng = np.random.default_rng(2)
    obj = shape_image(80, "bar")
    mask = obj > 100
    a = np.where(mask, obj, rng.integers(0, 256, obj.shape)).astype(np.uint8)
    b = np.where(mask, obj, rng.integers(0, 256, obj.shape)).astype(np.uint8)
    da, db = hog_descriptors([a, b], masks=[mask, mask])
    np.testing.assert_allclose(da, db, atol=1e-6)
    # without the mask the clutter changes the descriptor
    assert float(hog_distance(*hog_descriptors([a, b]))[0, 0]) > 0.1
    # a None mask keeps the crop as it is
    np.testing.assert_array_equal(hog_descriptors([a], masks=[None]), hog_descriptors([a]))


def test_retrieval_prefers_same_shape_at_other_scale() -> None:
    queries = hog_descriptors([shape_image(60, "disc"), shape_image(60, "bar"), shape_image(60, "wedge")])
    library = hog_descriptors([shape_image(150, "wedge"), shape_image(150, "disc"), shape_image(150, "bar")])
    nearest = np.argmin(hog_distance(queries, library), axis=1)
    assert nearest.tolist() == [1, 2, 0]


def test_constant_image_gives_zero_vector() -> None:
    d = hog_descriptors([np.full((20, 30, 3), 77, np.uint8)])
    assert np.all(d == 0)


def test_hog_distance() -> None:
    rng = np.random.default_rng(3)
    a = rng.normal(size=(5, 144))
    b = rng.normal(size=(3, 144))
    d = hog_distance(a, b)
    assert d.shape == (5, 3)
    np.testing.assert_allclose(d, np.linalg.norm(a[:, None] - b[None], axis=2), rtol=1e-12)
    np.testing.assert_allclose(np.diag(hog_distance(a, a)), 0.0, atol=1e-12)
    np.testing.assert_allclose(hog_distance(a, a), hog_distance(a, a).T)
    assert hog_distance(a[0], b[1]).shape == (1, 1)


def test_bad_inputs() -> None:
    with pytest.raises(ValueError, match=r"images\[0\]: expected an \(h, w\) or \(h, w, 3\) image, got shape \(4, 4"):
        hog_descriptors([np.zeros((4, 4, 4), np.uint8)])
    with pytest.raises(ValueError, match=r"expected float values in \[0, 1\]"):
        hog_descriptors([np.full((4, 4), 2.0)])
    with pytest.raises(ValueError, match="expected finite values"):
        hog_descriptors([np.full((4, 4), np.nan)])
    with pytest.raises(ValueError, match="expected uint8 or float pixels"):
        hog_descriptors([np.zeros((4, 4), np.int32)])
    with pytest.raises(ValueError, match=r"masks\[0\]: expected shape \(4, 4\)"):
        hog_descriptors([np.zeros((4, 4), np.uint8)], masks=[np.ones((4, 5), bool)])
    with pytest.raises(ValueError, match="one mask"):
        hog_descriptors([np.zeros((4, 4), np.uint8)], masks=[])
    with pytest.raises(ValueError, match="size: expected a multiple of cells"):
        hog_descriptors([np.zeros((4, 4), np.uint8)], size=30)
    with pytest.raises(ValueError, match="background"):
        hog_descriptors([np.zeros((4, 4), np.uint8)], background=2.0)
    with pytest.raises(ValueError, match=r"same D"):
        hog_distance(np.zeros((2, 3)), np.zeros((2, 4)))
