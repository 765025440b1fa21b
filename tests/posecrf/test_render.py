"""Pose grid, pyrender renders (pose convention), square crops and the on-disk descriptor cache."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

from posecrf.cache import CACHE_ENV, cache_key, default_cache_dir, library_renders  # noqa: E402
from posecrf.library import Model3D, assemble_model, builtin_library  # noqa: E402
from posecrf.library.parts import box  # noqa: E402
from posecrf.mrf import LabelGrid  # noqa: E402
from posecrf.render import (  # noqa: E402
    PoseGrid,
    PoseRenderer,
    RenderError,
    RenderSettings,
    camera_pose_matrix,
    camera_setup,
    crop_square,
    look_at,
    mask_bbox,
    render_poses,
)

SMALL = RenderSettings(size=32, viewport=64)
TINY_GRID = PoseGrid(4, 2, math.radians(30.0))
RED = (230, 20, 20)
BLUE = (20, 20, 230)


def marker_model(model_id: str = "marker-01") -> Model3D:
    """A grey block with a red knob on its front (+x) and a blue cap on top."""
    parts = [
        box("body", "wood", (128, 128, 128), (0.6, 0.6, 0.6), (0.0, 0.0, 0.3)),
        box("knob", "plastic", RED, (0.1, 0.2, 0.2), (0.35, 0.0, 0.3)),
        box("cap", "plastic", BLUE, (0.3, 0.3, 0.02), (0.0, 0.0, 0.61)),
    ]
    return assemble_model(model_id, "marker", parts)


def _colour_mask(rgb: np.ndarray, colour: tuple[int, int, int]) -> np.ndarray:
    c = np.asarray(colour, dtype=np.float64)
    dom = int(np.argmax(c))
    other = [i for i in range(3) if i != dom]
    x = rgb.astype(np.float64)
    return (x[..., dom] > 60) & (x[..., dom] > 2.5 * x[..., other].max(axis=-1))


# --------------------------------------------------------------------------- pose grid
def test_default_grid_is_the_papers_360_poses():
    g = PoseGrid()
    assert g.size == 360 and g.shape == (72, 5)
    np.testing.assert_allclose(np.rad2deg(g.yaws), np.arange(0, 360, 5))
    np.testing.assert_allclose(np.rad2deg(g.pitches), [0, 11.25, 22.5, 33.75, 45])
    lg = g.label_grid()
    assert isinstance(lg, LabelGrid) and lg.shape == (72, 5) and lg.cyclic == (True, False)
    # labels in C order: label = i_yaw * n_pitch + i_pitch
    poses = g.poses()
    coords = lg.coords()
    np.testing.assert_allclose(poses[:, 0], g.yaws[coords[:, 0]])
    np.testing.assert_allclose(poses[:, 1], g.pitches[coords[:, 1]])
    # the grid metric is the paper's |dyaw| + |dpitch| in radians, yaw the short way round
    a, b = g.nearest_label(math.radians(355), 0.0), g.nearest_label(math.radians(10), math.radians(22.5))
    assert lg.distance(a, b) == pytest.approx(math.radians(15 + 22.5))


@settings(max_examples=60, deadline=None)
@given(st.floats(-20.0, 20.0), st.floats(0.0, math.radians(45.0)))
def test_nearest_label_is_within_half_a_step(yaw: float, pitch: float):
    g = PoseGrid()
    lab = int(g.nearest_label(yaw, pitch))
    y, p = g.poses()[lab]
    dy = abs((y - yaw + math.pi) % (2 * math.pi) - math.pi)
    assert dy <= g.yaw_step / 2 + 1e-9
    assert abs(p - pitch) <= g.pitch_step / 2 + 1e-9


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(n_yaw=0), "n_yaw"),
        (dict(n_pitch=2, pitch_max=math.pi / 2), "pitch_max"),
        (dict(n_pitch=1, pitch_max=0.3), "pitch_max"),
        (dict(n_pitch=3, pitch_max=0.0), "pitch_max"),
    ],
)
def test_pose_grid_rejects_bad_parameters(kwargs, match):
    with pytest.raises(ValueError, match=match):
        PoseGrid(**kwargs)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(size=4), "size"),
        (dict(fov=3.0), "fov"),
        (dict(margin=-0.1), "margin"),
        (dict(background=(0, 0, 300)), "background"),
        (dict(distance=-1.0), "distance"),
        (dict(light_elevation=2.0), "light_elevation"),
    ],
)
def test_render_settings_reject_bad_values(kwargs, match):
    with pytest.raises(ValueError, match=match):
        RenderSettings(**kwargs)


def test_settings_key_changes_with_every_field():
    base = RenderSettings()
    keys = {base.key()}
    for kw in (dict(size=48), dict(viewport=96), dict(fov=0.6), dict(margin=0.0), dict(background=(0, 0, 0)),
               dict(ambient=0.3), dict(light=2.0), dict(light_elevation=0.3), dict(distance=None)):
        keys.add(RenderSettings(**kw).key())
    assert len(keys) == 10


# --------------------------------------------------------------------------- geometry
def test_camera_sits_in_the_pose_direction_and_looks_at_the_centre():
    size = np.array([2.0, 1.0, 0.8])
    for yaw, pitch in [(0.0, 0.0), (math.pi / 2, 0.3), (4.0, math.radians(45))]:
        m = camera_pose_matrix(size, yaw, pitch, 3.0)
        centre = np.array([0.0, 0.0, 0.4])
        d = m[:3, 3] - centre
        np.testing.assert_allclose(np.linalg.norm(d), 3.0)
        np.testing.assert_allclose(d / 3.0, [math.cos(pitch) * math.cos(yaw), math.cos(pitch) * math.sin(yaw), math.sin(pitch)], atol=1e-12)
        np.testing.assert_allclose(-m[:3, 2], -d / 3.0, atol=1e-12)  # optical axis towards the centre
        assert abs(m[2, 0]) < 1e-12  # no roll: image x stays horizontal
        np.testing.assert_allclose(m[:3, :3].T @ m[:3, :3], np.eye(3), atol=1e-12)


def test_camera_setup_fits_the_bounding_sphere():
    size = [2.2, 1.8, 1.0]
    r = 0.5 * np.linalg.norm(size)
    d, fov = camera_setup(size, RenderSettings(fov=math.radians(40.0), distance=None))
    assert d == pytest.approx(r / math.sin(math.radians(20.0))) and fov == pytest.approx(math.radians(40.0))
    d2, fov2 = camera_setup([0.5, 0.5, 0.8], RenderSettings(distance=2.75))
    assert d2 == 2.75 and math.sin(fov2 / 2) * 2.75 == pytest.approx(0.5 * np.linalg.norm([0.5, 0.5, 0.8]))
    with pytest.raises(ValueError, match="model_size"):
        camera_setup([0.0, 0.0, 0.0], RenderSettings())


def test_look_at_rejects_coincident_points():
    with pytest.raises(ValueError, match="distinct"):
        look_at([1.0, 2.0, 3.0], [1.0, 2.0, 3.0])


def test_crop_square_cuts_the_mask_box_and_keeps_the_mask():
    rng = np.random.default_rng(0)
    img = rng.integers(0, 255, (50, 90, 3), dtype=np.uint8)
    m = np.zeros((50, 90), bool)
    m[10:30, 20:80] = True
    crop, cm = crop_square(img, m, size=24, margin=0.0)
    assert crop.shape == (24, 24, 3) and crop.dtype == np.uint8 and cm.all()
    crop, cm = crop_square(img, m, size=24, margin=0.25, background=(7, 8, 9))
    assert mask_bbox(cm) == (4, 4, 20, 20)  # margin of a quarter box = 4 px of 24 on each side
    np.testing.assert_array_equal(crop[0, 0], [7, 8, 9])
    with pytest.raises(ValueError, match="empty mask"):
        crop_square(img, np.zeros((50, 90), bool))
    with pytest.raises(ValueError, match=r"\(H, W, 3\) uint8"):
        crop_square(img.astype(np.float32), m)
    with pytest.raises(ValueError, match="mask"):
        crop_square(img, m[:10])


# --------------------------------------------------------------------------- renders
@pytest.fixture(scope="module")
def renderer():
    with PoseRenderer(RenderSettings(size=48, viewport=96, distance=None)) as r:
        yield r


def test_yaw_zero_looks_at_the_front_and_yaw_turns_counter_clockwise(renderer):
    """The module's pose convention: yaw = camera azimuth seen from the object, from its front (+x), CCW."""
    m = marker_model()
    front, _ = renderer.render(m, 0.0, 0.0)
    back, _ = renderer.render(m, math.pi, 0.0)
    left_side, _ = renderer.render(m, math.pi / 2, 0.0)  # camera on the model's +y side
    right_side, _ = renderer.render(m, 3 * math.pi / 2, 0.0)
    red_front = _colour_mask(front, RED)
    assert red_front.sum() > 100
    cols = np.flatnonzero(red_front.any(axis=0))
    assert abs(cols.mean() - front.shape[1] / 2) < 3  # the knob faces the camera, centred
    assert _colour_mask(back, RED).sum() == 0
    # from +y, looking towards -y with z up, image right = model -x: the front knob is on the LEFT
    w = left_side.shape[1]
    assert np.flatnonzero(_colour_mask(left_side, RED).any(axis=0)).mean() < w / 2 - 5
    assert np.flatnonzero(_colour_mask(right_side, RED).any(axis=0)).mean() > w / 2 + 5


def test_pitch_raises_the_camera(renderer):
    m = marker_model()
    level, _ = renderer.render(m, 0.0, 0.0)
    above, _ = renderer.render(m, 0.0, math.radians(45.0))
    assert _colour_mask(level, BLUE).sum() == 0  # the cap is above eye level
    assert _colour_mask(above, BLUE).sum() > 50


def test_render_crops_are_square_and_filled(renderer):
    m = builtin_library()["chair-03"]
    r = renderer.render_crops(m, TINY_GRID.poses())
    assert r.images.shape == (8, 48, 48, 3) and r.masks.shape == (8, 48, 48)
    margin_px = 48 * renderer.settings.margin / (1 + 2 * renderer.settings.margin)
    for k in range(8):
        x0, y0, x1, y1 = mask_bbox(r.masks[k])
        assert min(x0, y0) <= margin_px + 1.5 and max(48 - x1, 48 - y1) <= margin_px + 1.5
    assert np.all(r.aspect > 0)


def _broken(model: Model3D, vertices: np.ndarray) -> Model3D:
    object.__setattr__(model, "vertices", vertices)  # bypass the constructor's checks on purpose
    return model


def test_broken_models_raise_render_error_naming_them(renderer):
    flat = assemble_model("flat-01", "marker", [box("b", "wood", (90, 90, 90), (0.4, 0.4, 0.4), (0.0, 0.0, 0.2))])
    v = flat.vertices.copy()
    v[:, 2] = 0.0
    v[:, 1] = 0.0  # every triangle collapses onto the x axis: zero area
    with pytest.raises(RenderError, match="flat-01.*degenerate"):
        renderer.render(_broken(flat, v), 0.0, 0.0)
    m = marker_model("nan-01")
    nan = m.vertices.copy()
    nan[3, 1] = np.nan
    with pytest.raises(RenderError, match="nan-01.*NaN"):
        renderer.render(_broken(m, nan), 0.0, 0.0)


# --------------------------------------------------------------------------- cache
def _lib():
    lib = builtin_library()
    return [lib["tv-01"], lib["chair-02"], lib["plant-01"]]


def test_cache_builds_once_then_loads(tmp_path: Path):
    models = _lib()
    first = library_renders(models, grid=TINY_GRID, settings=SMALL, cache_dir=tmp_path, workers=1)
    assert first.built == ("tv-01", "chair-02", "plant-01") and first.loaded == () and not first.failures
    files = sorted(p.name for p in tmp_path.iterdir())
    assert len(files) == 3 and all(f.endswith(".npz") for f in files)
    second = library_renders(models, grid=TINY_GRID, settings=SMALL, cache_dir=tmp_path, workers=1)
    assert second.built == () and second.loaded == ("tv-01", "chair-02", "plant-01")
    for a, b in zip(first.models, second.models):
        np.testing.assert_array_equal(a.descriptors, b.descriptors)
        assert a.descriptors.shape == (TINY_GRID.size, 144) and not a.descriptors.flags.writeable
    assert second.classes == ("tv", "chair", "plant") and second["plant-01"].symmetry == "full"
    # different render settings: a new key, everything rendered again next to the old files
    other = library_renders(models[:1], grid=TINY_GRID, settings=RenderSettings(size=32, viewport=64, margin=0.0),
                            cache_dir=tmp_path, workers=1)
    assert other.built == ("tv-01",) and len(list(tmp_path.iterdir())) == 4


def test_changed_model_is_rebuilt_alone(tmp_path: Path):
    a, b = marker_model("marker-01"), builtin_library()["tv-02"]
    library_renders([a, b], grid=TINY_GRID, settings=SMALL, cache_dir=tmp_path, workers=1)
    a2 = assemble_model("marker-01", "marker", [box("body", "wood", (128, 128, 128), (0.6, 0.5, 0.6), (0.0, 0.0, 0.3))])
    assert cache_key(a2, TINY_GRID, SMALL) != cache_key(a, TINY_GRID, SMALL)
    again = library_renders([a2, b], grid=TINY_GRID, settings=SMALL, cache_dir=tmp_path, workers=1)
    assert again.built == ("marker-01",) and again.loaded == ("tv-02",)


def test_failed_model_is_reported_by_name_and_skipped(tmp_path: Path):
    good = builtin_library()["tv-03"]
    bad = marker_model("broken-07")
    nan = bad.vertices.copy()
    nan[0, 0] = np.nan
    bad = _broken(bad, nan)
    with pytest.warns(UserWarning, match="broken-07"):
        res = library_renders([bad, good], grid=TINY_GRID, settings=SMALL, cache_dir=tmp_path, workers=1)
    assert [f.model_id for f in res.failures] == ["broken-07"] and "NaN" in res.failures[0].reason
    assert [m.model_id for m in res.models] == ["tv-03"]
    assert [p.name.split(".")[0] for p in tmp_path.iterdir()] == ["tv-03"]
    with pytest.raises(KeyError, match="broken-07"):
        res["broken-07"]


def test_interrupted_write_leaves_no_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    def boom(*args, **kwargs):
        raise KeyboardInterrupt("simulated interruption while writing")

    monkeypatch.setattr(np, "savez", boom)
    with pytest.raises(KeyboardInterrupt):
        library_renders([builtin_library()["tv-04"]], grid=TINY_GRID, settings=SMALL, cache_dir=tmp_path, workers=1)
    assert list(tmp_path.iterdir()) == []


def test_corrupt_cache_file_is_rebuilt(tmp_path: Path):
    m = builtin_library()["tv-05"]
    library_renders([m], grid=TINY_GRID, settings=SMALL, cache_dir=tmp_path, workers=1)
    (f,) = tmp_path.iterdir()
    f.write_bytes(b"not an npz file")
    res = library_renders([m], grid=TINY_GRID, settings=SMALL, cache_dir=tmp_path, workers=1)
    assert res.built == ("tv-05",) and res["tv-05"].descriptors.shape == (TINY_GRID.size, 144)


def test_cache_folder_follows_the_environment(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "c"))
    assert default_cache_dir() == tmp_path / "c"
    monkeypatch.delenv(CACHE_ENV)
    assert default_cache_dir() == Path.home() / ".cache" / "pano2cad" / "renders"


def test_no_cache_mode_writes_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "never"))
    res = library_renders(_lib()[:1], grid=TINY_GRID, settings=SMALL, use_cache=False, workers=1)
    assert res.cache_dir is None and len(res) == 1 and not (tmp_path / "never").exists()


def test_two_worker_processes_match_one(tmp_path: Path):
    models = _lib()[:2]
    one = library_renders(models, grid=TINY_GRID, settings=SMALL, use_cache=False, workers=1)
    two = library_renders(models, grid=TINY_GRID, settings=SMALL, cache_dir=tmp_path, workers=2)
    assert two.built == ("tv-01", "chair-02")
    for a, b in zip(one.models, two.models):
        np.testing.assert_allclose(a.descriptors, b.descriptors, atol=1e-6)


def test_render_poses_matches_the_renderer():
    m = builtin_library()["tv-06"]
    r = render_poses(m, TINY_GRID, SMALL)
    with PoseRenderer(SMALL) as pr:
        r2 = pr.render_crops(m, TINY_GRID.poses())
        np.testing.assert_array_equal(r.images, r2.images)
        with pytest.raises(ValueError, match="poses"):
            pr.render_crops(m, np.zeros((3, 3)))
    with pytest.raises(ValueError, match="closed"):
        pr.render(m, 0.0, 0.0)


def test_fresh_process_builds_with_forked_workers(tmp_path: Path):
    """Without an OpenGL context yet, workers are forked: no __main__ guard needed in a plain script."""
    import subprocess
    import sys

    script = (
        "import math, sys\n"
        "from posecrf.cache import library_renders, _start_method\n"
        "from posecrf.library import builtin_library\n"
        "from posecrf.render import PoseGrid, RenderSettings\n"
        "lib = builtin_library()\n"
        "assert _start_method() == 'fork', _start_method()\n"
        "r = library_renders([lib['tv-01'], lib['chair-02']], grid=PoseGrid(4, 2, math.radians(30.0)),\n"
        "                    settings=RenderSettings(size=32, viewport=64), cache_dir=sys.argv[1], workers=2)\n"
        "print(','.join(r.built))\n"
    )
    env = dict(os.environ, PYOPENGL_PLATFORM="egl", PYTHONPATH=str(Path(__file__).resolve().parents[2]))
    out = subprocess.run([sys.executable, "-c", script, str(tmp_path)], capture_output=True, text=True, env=env, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "tv-01,chair-02"
    grid = PoseGrid(4, 2, math.radians(30.0))
    one = library_renders([builtin_library()["tv-01"]], grid=grid, settings=SMALL, cache_dir=tmp_path, workers=1)
    here = library_renders([builtin_library()["tv-01"]], grid=grid, settings=SMALL, use_cache=False, workers=1)
    assert one.loaded == ("tv-01",)
    np.testing.assert_allclose(one["tv-01"].descriptors, here["tv-01"].descriptors, atol=1e-6)
