"""Reading user panoramas: every odd input either works or gives a UserError naming the file."""

import numpy as np
import pytest
from PIL import Image

from apps.errors import UserError
from apps.imageio import read_panorama


def _pano(h=64):
    rng = np.random.default_rng(0)
    return rng.integers(0, 255, (h, 2 * h, 3), dtype=np.uint8)


def test_rgb_png_round_trip(tmp_path):
    a = _pano()
    Image.fromarray(a).save(tmp_path / "p.png")
    p = read_panorama(tmp_path / "p.png")
    assert p.image.dtype == np.uint8 and p.image.shape == a.shape
    np.testing.assert_array_equal(p.image, a)
    assert p.original_size == (128, 64)


@pytest.mark.parametrize("mode", ["L", "RGBA", "P", "I;16"])
def test_other_modes_are_converted(tmp_path, mode):
    a = _pano()
    if mode == "I;16":
        img = Image.fromarray((a[..., 0].astype(np.uint16) * 257))
    elif mode == "P":
        img = Image.fromarray(a).convert("P")
    else:
        img = Image.fromarray(a).convert(mode)
    img.save(tmp_path / "p.png")
    p = read_panorama(tmp_path / "p.png")
    assert p.image.shape == (64, 128, 3) and p.image.dtype == np.uint8
    if mode == "I;16":
        np.testing.assert_allclose(p.image[..., 0], a[..., 0], atol=1)


def test_sixteen_bit_rgb_png(tmp_path):
    cv2 = pytest.importorskip("cv2")
    a = (_pano().astype(np.uint16) * 257)
    cv2.imwrite(str(tmp_path / "p16.png"), a[..., ::-1])
    p = read_panorama(tmp_path / "p16.png")
    assert p.image.dtype == np.uint8
    np.testing.assert_allclose(p.image.astype(int), (a // 257).astype(int), atol=1)


def test_downscale_to_working_width(tmp_path):
    Image.fromarray(_pano(200)).save(tmp_path / "big.jpg", quality=90)
    p = read_panorama(tmp_path / "big.jpg", max_width=100)
    assert p.image.shape == (50, 100, 3)
    assert p.original_size == (400, 200)


def test_missing_file(tmp_path):
    with pytest.raises(UserError, match="no such file"):
        read_panorama(tmp_path / "nope.jpg")


def test_not_equirectangular(tmp_path):
    Image.fromarray(np.zeros((200, 300, 3), np.uint8)).save(tmp_path / "photo.jpg")
    with pytest.raises(UserError, match=r"photo\.jpg: expected an equirectangular panorama .* got 300x200"):
        read_panorama(tmp_path / "photo.jpg")


def test_corrupt_jpeg(tmp_path):
    Image.fromarray(_pano()).save(tmp_path / "c.jpg")
    data = (tmp_path / "c.jpg").read_bytes()
    (tmp_path / "c.jpg").write_bytes(data[:200])
    with pytest.raises(UserError, match=r"c\.jpg: cannot read the image"):
        read_panorama(tmp_path / "c.jpg")


def test_not_an_image(tmp_path):
    (tmp_path / "notes.png").write_text("hello")
    with pytest.raises(UserError, match=r"notes\.png: cannot read the image"):
        read_panorama(tmp_path / "notes.png")


def test_folder(tmp_path):
    with pytest.raises(UserError, match="is a folder"):
        read_panorama(tmp_path)
