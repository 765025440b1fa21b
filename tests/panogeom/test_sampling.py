"""Tests of panogeom.sampling: seam- and pole-correct resampling."""

from __future__ import annotations

import numpy as np
import pytest

from panogeom.coords import pixel_grid, pixel_to_ray
from panogeom.sampling import EquirectSampler, pad_equirect, sample_equirect
from panogeom.transform import pano_from_directions

H = 128
W = 2 * H
AXIS = np.array([0.3, -0.5, 0.81])


def smooth(d):
    """A smooth function on the sphere (no seam, no pole singularity)."""
    return 100.0 + 50.0 * (d @ AXIS) + 30.0 * d[:, 0] * d[:, 2]


@pytest.fixture(scope="module")
def smooth_pano():
    return pano_from_directions(smooth, H)


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.int16, np.float32, np.float64, np.int32])
@pytest.mark.parametrize("channels", [None, 1, 3, 4])
def test_pixel_centres_return_pixels_exactly(dtype, channels):
    rng = np.random.default_rng(0)
    shape = (16, 32) if channels is None else (16, 32, channels)
    img = rng.integers(0, 200, size=shape).astype(dtype)
    g = pixel_grid(32, 16)
    for interp in ("linear", "nearest", "cubic"):
        out = sample_equirect(img, g, interp)
        assert out.dtype == img.dtype and out.shape == img.shape
        assert np.array_equal(out, img), interp


def test_seam_interpolates_between_last_and_first_column():
    img = np.zeros((8, 16), np.float32)
    img[:, 0] = 10.0
    img[:, -1] = 30.0
    uv = np.array([[[0.0, 4.5], [16.0, 4.5], [-0.25, 4.5], [32.0, 4.5], [15.75, 4.5]]])
    out = sample_equirect(img, uv)[0]
    assert np.allclose(out, [20.0, 20.0, 25.0, 20.0, 25.0])


def test_pole_interpolates_across_the_pole():
    img = np.zeros((8, 16), np.float32)
    img[0, 3] = 40.0      # top row, column 3
    img[0, 3 + 8] = 0.0   # the column across the pole
    img[-1, 5] = 20.0
    # at v = 0 the sample is the mean of (u) and (u + W/2) in the first row
    out = sample_equirect(img, np.array([[[3.5, 0.0], [11.5, 0.0], [5.5, 8.0], [13.5, 8.0]]]))[0]
    assert np.allclose(out, [20.0, 20.0, 10.0, 10.0])


def test_pad_equirect_content():
    img = np.arange(4 * 8).reshape(4, 8)
    p = pad_equirect(img, 2)
    assert p.shape == (8, 12)
    assert np.array_equal(p[2:6, 2:10], img)
    assert np.array_equal(p[1, 2:10], np.roll(img[0], 4))   # row -1 is row 0 across the pole
    assert np.array_equal(p[0, 2:10], np.roll(img[1], 4))
    assert np.array_equal(p[6, 2:10], np.roll(img[3], 4))
    assert np.array_equal(p[7, 2:10], np.roll(img[2], 4))
    assert np.array_equal(p[:, 0:2], p[:, 8:10])             # seam wraps
    assert np.array_equal(p[:, 10:12], p[:, 2:4])


# OpenCV's bicubic kernel (a = -0.75) is only first-order accurate, hence its looser bound.
@pytest.mark.parametrize("interp, tol", [("linear", 0.05), ("cubic", 0.15)])
def test_smooth_function_is_reproduced_everywhere(smooth_pano, interp, tol):
    rng = np.random.default_rng(1)
    n = 4000
    uv = np.stack([rng.uniform(0, W, n), rng.uniform(0, H, n)], axis=-1)
    # force samples onto the seam and near both poles
    uv[:500, 0] = rng.uniform(-0.6, 0.6, 500) % W
    uv[500:1000, 1] = rng.uniform(0, 0.7, 500)
    uv[1000:1500, 1] = H - rng.uniform(0, 0.7, 500)
    got = sample_equirect(smooth_pano, uv[None], interp)[0]
    expected = smooth(pixel_to_ray(uv, W, H))
    assert np.abs(got - expected).max() < tol


def test_nearest_keeps_labels(smooth_pano):
    labels = (smooth_pano // 20).astype(np.uint8)
    rng = np.random.default_rng(2)
    uv = np.stack([rng.uniform(-5, W + 5, 3000), rng.uniform(0, H, 3000)], axis=-1)[None]
    out = sample_equirect(labels, uv, "nearest")[0]
    # the label is the one of the pixel containing the point
    j = np.floor(np.mod(uv[0, :, 0], W)).astype(int)
    i = np.minimum(np.floor(uv[0, :, 1]).astype(int), H - 1)
    assert np.array_equal(out, labels[i, j])


def test_sampler_reuse_matches_sample_equirect(smooth_pano):
    rng = np.random.default_rng(4)
    uv = np.stack([rng.uniform(0, W, (20, 30)), rng.uniform(0, H, (20, 30))], axis=-1)
    s = EquirectSampler.from_uv(uv, W, H)
    assert s.shape == (20, 30)
    for img in (smooth_pano, smooth_pano[..., None].repeat(3, axis=2).astype(np.float32)):
        assert np.array_equal(s(img), sample_equirect(img, uv))
    with pytest.raises(ValueError, match=r"expected a 256x128 panorama for this sampler, got 128x64"):
        s(np.zeros((64, 128)))
    assert not s.map_x.flags.writeable


@pytest.mark.parametrize("call, match", [
    (lambda: sample_equirect(np.zeros((10, 30)), np.zeros((1, 1, 2))), "W == 2\\*H, got 30x10"),
    (lambda: sample_equirect(np.zeros((10, 20, 2)), np.zeros((1, 1, 2))), r"C in \(1, 3, 4\)"),
    (lambda: sample_equirect(np.zeros((10, 20), bool), np.zeros((1, 1, 2))), "dtype, got bool"),
    (lambda: sample_equirect(np.zeros((10, 20), complex), np.zeros((1, 1, 2))), "dtype, got complex"),
    (lambda: sample_equirect(np.zeros((0, 0)), np.zeros((1, 1, 2))), "W == 2\\*H"),
    (lambda: sample_equirect(np.zeros((10, 20)), np.zeros((5, 2))), r"shape \(h, w, 2\)"),
    (lambda: sample_equirect(np.zeros((10, 20)), np.full((1, 1, 2), np.nan)), "finite"),
    (lambda: sample_equirect(np.zeros((10, 20)), np.zeros((1, 1, 2)), "area"), "interpolation"),
    (lambda: pad_equirect(np.zeros((4, 8)), 4), "pad < H=4"),
    (lambda: EquirectSampler.from_uv(np.zeros((1, 1, 2)), 30, 10), "W == 2\\*H"),
])
def test_bad_input_raises_with_a_message(call, match):
    with pytest.raises(ValueError, match=match):
        call()
