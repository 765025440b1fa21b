import json

import numpy as np
import pytest

from apps.atomic import atomic_path, write_image, write_json


def test_failed_write_leaves_nothing(tmp_path):
    target = tmp_path / "scene.json"
    target.write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_path(target) as tmp:
            tmp.write_text("half")
            raise RuntimeError("killed")
    assert target.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.json"]


def test_json_refuses_nan(tmp_path):
    with pytest.raises(ValueError):
        write_json(tmp_path / "a.json", {"x": float("nan")})
    assert not (tmp_path / "a.json").exists()
    assert list(tmp_path.iterdir()) == []
    write_json(tmp_path / "a.json", {"x": None})
    assert json.loads((tmp_path / "a.json").read_text()) == {"x": None}


def test_write_image_png(tmp_path):
    from PIL import Image

    a = np.arange(12 * 24 * 3, dtype=np.uint8).reshape(12, 24, 3)
    write_image(tmp_path / "a.png", a)
    np.testing.assert_array_equal(np.asarray(Image.open(tmp_path / "a.png")), a)
    with pytest.raises(ValueError, match="expected a .png or .jpg"):
        write_image(tmp_path / "a.bmp", a)


def test_written_files_have_normal_permissions(tmp_path):
    import os

    write_json(tmp_path / "a.json", {})
    mask = os.umask(0)
    os.umask(mask)
    assert (tmp_path / "a.json").stat().st_mode & 0o777 == 0o666 & ~mask
