"""k-NN retrieval, the pose CRF, crop-relative -> world yaw (with a synthetic render round trip)."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

from panogeom.coords import pixel_to_ray  # noqa: E402
from posecrf.cache import library_renders  # noqa: E402
from posecrf.crops import (  # noqa: E402
    crop_view,
    extract_crop,
    outline_view,
    fold_yaw,
    object_pitch,
    pano_box_ray,
    relative_yaw,
    relative_yaw_shifts,
    view_azimuth,
    world_yaw,
)
from posecrf.hog import hog_distance  # noqa: E402
from posecrf.library import builtin_library  # noqa: E402
from posecrf.pose import estimate_poses, load_aux_folder, pose_unaries  # noqa: E402
from posecrf.render import (  # noqa: E402
    PoseGrid,
    PoseRenderer,
    RenderSettings,
    camera_setup,
    look_at,
    shared_offscreen_renderer,
)
from posecrf.retrieval import RenderIndex, crop_descriptors, render_descriptors  # noqa: E402

PITCH = math.radians(22.5)
GRID = PoseGrid(72, 2, PITCH)  # 5 deg yaw bins, pitch 0 and 22.5 deg
SETTINGS = RenderSettings(size=64, viewport=96)
IDS = ["tv-01", "tv-02", "tv-03", "chair-01", "chair-05", "chair-09", "table-01", "table-03", "plant-01", "plant-02"]


@pytest.fixture(scope="module")
def lib():
    return builtin_library()


@pytest.fixture(scope="module")
def renders(lib):
    return library_renders([lib[i] for i in IDS], grid=GRID, settings=SETTINGS, use_cache=False, workers=1)


@pytest.fixture(scope="module")
def renderer():
    with PoseRenderer(SETTINGS) as r:
        yield r


def _yaw_err(a: float, b: float, period: float = 2 * math.pi) -> float:
    d = abs((a - b) % period)
    return min(d, period - d)


# --------------------------------------------------------------------------- yaw conversion
@settings(max_examples=100, deadline=None)
@given(st.floats(-10, 10), st.floats(-math.pi, math.pi), st.floats(-1.2, 1.2))
def test_world_and_relative_yaw_are_inverse(yaw, azimuth, elevation):
    d = [math.cos(elevation) * math.cos(azimuth), math.cos(elevation) * math.sin(azimuth), math.sin(elevation)]
    rel = float(relative_yaw(yaw, d))
    assert 0.0 <= rel < 2 * math.pi
    assert _yaw_err(float(world_yaw(rel, d)), yaw) < 1e-9
    two = float(world_yaw(rel, d, "two"))
    assert 0.0 <= two < math.pi and _yaw_err(two, yaw, math.pi) < 1e-9


def test_world_yaw_cases_by_hand():
    # camera looks along +y (alpha = 90 deg) and sees the object's front: the object faces -y (270 deg)
    assert math.degrees(float(world_yaw(0.0, [0.0, 1.0, 0.0]))) == pytest.approx(270.0)
    # ... and sees its +y side (yaw_rel = 90 deg): the object's +y axis points along -y, its front along -x
    assert math.degrees(float(world_yaw(math.pi / 2, [0.0, 1.0, 0.0]))) == pytest.approx(180.0)
    assert float(view_azimuth([-1.0, 0.0, 0.0])) == pytest.approx(math.pi)
    assert math.degrees(float(object_pitch([1.0, 0.0, -math.sqrt(3.0)]))) == pytest.approx(60.0)
    assert math.degrees(float(fold_yaw(math.radians(200.0), "two"))) == pytest.approx(20.0)
    with pytest.raises(ValueError, match="full"):
        fold_yaw(0.3, "full")
    with pytest.raises(ValueError, match="horizontal component"):
        world_yaw(0.0, [0.0, 0.0, -1.0])


def test_relative_yaw_shifts_map_each_crops_relative_yaw_onto_the_first_ones():
    rays = np.array([[1.0, 0.2, -0.3], [0.6, 0.8, -0.1], [-0.5, 0.1, -0.6]])
    shifts = relative_yaw_shifts(rays)
    assert shifts.shape == (3,) and shifts[0] == 0.0
    for world in (0.0, 1.3, 4.0):
        rel = relative_yaw(world, rays)
        assert np.allclose(np.cos(rel - rel[0] - shifts), 1.0)
    with pytest.raises(ValueError, match="horizontal component"):
        relative_yaw_shifts([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])


def _world_render(model, yaw_world: float, azimuth: float, pitch: float, s: RenderSettings):
    """Render `model` placed in the world at `yaw_world`, seen from a camera at (0, 0, 1.6) m."""
    import pyrender

    dist, fov = camera_setup(model.size, s)
    d = np.array([math.cos(pitch) * math.cos(azimuth), math.cos(pitch) * math.sin(azimuth), -math.sin(pitch)])
    cam = np.array([0.0, 0.0, 1.6])
    centre = cam + dist * d
    pose = np.eye(4)
    c, si = math.cos(yaw_world), math.sin(yaw_world)
    pose[:3, :3] = [[c, -si, 0.0], [si, c, 0.0], [0.0, 0.0, 1.0]]
    pose[:3, 3] = centre - [0.0, 0.0, model.size[2] / 2]
    scene = pyrender.Scene(bg_color=[x / 255 for x in s.background] + [1.0], ambient_light=[s.ambient] * 3)
    scene.add(pyrender.Mesh.from_trimesh(model.mesh, smooth=False), pose=pose)
    cpose = look_at(cam, centre)
    scene.add(pyrender.PerspectiveCamera(yfov=fov, aspectRatio=1.0, znear=0.05, zfar=100.0), pose=cpose)
    scene.add(pyrender.DirectionalLight(intensity=s.light), pose=cpose)
    color, depth = shared_offscreen_renderer(s.viewport, s.viewport).render(scene)
    return color[..., :3].copy(), depth > 0, d


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / (a | b).sum())


def test_world_render_round_trip_pins_the_conversion(lib, renderer):
    """A model placed in a world scene looks exactly like its library render at relative_yaw(...)."""
    model = lib["chair-05"]
    yaw_world, azimuth, pitch = 1.1, 2.3, PITCH
    img, mask, d = _world_render(model, yaw_world, azimuth, pitch, SETTINGS)
    rel = float(relative_yaw(yaw_world, d))
    assert float(object_pitch(d)) == pytest.approx(pitch)
    lib_img, lib_mask = renderer.render(model, rel, pitch)
    assert _iou(mask, lib_mask) > 0.98
    assert np.abs(img.astype(int) - lib_img.astype(int)).mean() < 3.0
    # the plausible sign mistakes give other pictures
    for wrong in (-rel, rel + math.pi, math.pi - float(view_azimuth(d)) - yaw_world):  # sign, side, lon for azimuth
        _, wrong_mask = renderer.render(model, float(wrong), pitch)
        assert _iou(mask, wrong_mask) < 0.9


def test_world_render_round_trip_through_the_crf(lib, renders):
    """Pose CRF on the world render, then world_yaw: the object's world yaw comes back."""
    for mid, yaw_world, azimuth in [("chair-09", 4.0, -0.7), ("tv-02", 0.6, 1.9)]:
        img, mask, d = _world_render(lib[mid], yaw_world, azimuth, PITCH, SETTINGS)
        est = estimate_poses(renders, lib[mid].cls, [img], [mask]).estimates[0]
        assert est.model_id == mid
        assert _yaw_err(est.world_yaw(d), yaw_world) < math.radians(4.0)
        assert est.pitch == pytest.approx(PITCH)


# --------------------------------------------------------------------------- crops of a panorama
def test_crop_view_is_centred_on_the_box_and_covers_it():
    W, H = 1024, 512
    box = [1000.0, 300.0, 60.0, 380.0]  # wraps the seam
    view = crop_view(box, W, H, size=64, margin=0.1)
    np.testing.assert_allclose(view.direction, pano_box_ray(box, W, H), atol=1e-12)
    u = np.linspace(1000, 1084, 9) % W
    v = np.linspace(300, 380, 9)
    edge = np.concatenate([np.stack([u, np.full(9, 300.0)], 1), np.stack([u, np.full(9, 380.0)], 1),
                           np.stack([np.full(9, 1000.0), v], 1), np.stack([np.full(9, 60.0), v], 1)])
    uv, front = view.ray_to_pixel(pixel_to_ray(edge, W, H))
    assert front.all()
    assert uv[:, 0].min() >= 0 and uv[:, 0].max() <= view.width and uv[:, 1].min() >= 0 and uv[:, 1].max() <= view.height
    assert uv[:, 0].max() - uv[:, 0].min() > 0.8 * view.width  # tight up to the margin
    with pytest.raises(ValueError, match="W == 2\\*H"):
        crop_view(box, 1000, 512)
    with pytest.raises(ValueError, match="v0 < v1"):
        crop_view([10, 300, 50, 200], W, H)


def test_outline_view_of_a_pitched_tile_box_is_tighter_than_its_panorama_box():
    from panogeom.coords import ray_to_pixel
    from panogeom.perspective import PinholeView

    W, H = 1024, 512
    tile = PinholeView(yaw=0.7, pitch=-0.6, roll=0.0, fov=math.radians(90.0), width=448, height=448)
    px = np.array([[150.0, 200.0], [300.0, 200.0], [300.0, 330.0], [150.0, 330.0]])
    t = np.linspace(0.0, 1.0, 9)[:, None]
    edge = np.concatenate([px[k] + t * (px[(k + 1) % 4] - px[k]) for k in range(4)])
    rays = tile.pixel_to_ray(edge)
    centre = tile.pixel_to_ray(px.mean(0))
    view = outline_view(centre, rays, size=64, margin=0.0)
    uv, front = view.ray_to_pixel(rays)
    assert front.all()
    assert uv[:, 0].min() >= -1e-6 and uv[:, 0].max() <= view.width + 1e-6
    assert uv[:, 1].min() >= -1e-6 and uv[:, 1].max() <= view.height + 1e-6
    assert min(abs(uv[:, 0].min()), abs(view.width - uv[:, 0].max())) < 1e-6  # touches one side: tight
    # the same outline's panorama box (its lon/lat extent) needs a wider crop
    pp = ray_to_pixel(rays, W, H)
    loose = crop_view([pp[:, 0].min(), pp[:, 1].min(), pp[:, 0].max(), pp[:, 1].max()], W, H, size=64, margin=0.0)
    assert view.fov < loose.fov - math.radians(2.0)
    with pytest.raises(ValueError, match="within 90 degrees"):
        outline_view([1.0, 0.0, 0.0], [[-1.0, 0.0, 0.0]])
    with pytest.raises(ValueError, match="size"):
        outline_view(centre, rays, size=4)


def test_extract_crop_samples_the_panorama():
    W, H = 512, 256
    pano = np.zeros((H, W, 3), np.uint8)
    pano[100:140, 200:260] = 255
    crop, view = extract_crop(pano, [200, 100, 260, 140], size=48, margin=0.2)
    assert crop.shape[1] == 48 and crop.dtype == np.uint8
    assert crop[crop.shape[0] // 2, 24].min() == 255 and crop[1, 1].max() == 0


# --------------------------------------------------------------------------- retrieval
def test_knn_and_e_o_match_brute_force(renders, renderer, lib):
    index = RenderIndex.from_renders(renders, "chair")
    r = renderer.render_crops(lib["chair-01"], [(0.4, 0.2), (3.0, 0.1)])
    q = render_descriptors(r.images, r.masks)
    dist = hog_distance(q, index.descriptors)
    nb = index.knn(q, 6)
    np.testing.assert_allclose(nb.distance, np.sort(dist, axis=1)[:, :6], atol=1e-5)
    np.testing.assert_array_equal(nb.model, nb.row // GRID.size)
    np.testing.assert_array_equal(nb.label, nb.row % GRID.size)
    e = index.e_o(q)
    assert e.shape == (2, 3, 72, 2)
    np.testing.assert_allclose(e.reshape(2, -1), dist, atol=1e-5)
    assert [index.model_ids[m] for m in index.nearest_model(q)] == ["chair-01", "chair-01"]
    with pytest.raises(ValueError, match="k: expected"):
        index.knn(q, 0)
    with pytest.raises(ValueError, match="class_name"):
        RenderIndex.from_renders(renders, "bed")


def test_crop_descriptors_prepare_like_the_renders(renderer, lib):
    rgb, mask = renderer.render(lib["tv-03"], 0.7, 0.1)
    r = renderer.render_crops(lib["tv-03"], [(0.7, 0.1)])
    a = crop_descriptors([rgb], [mask], SETTINGS)
    b = render_descriptors(r.images, r.masks)
    assert float(np.linalg.norm(a - b)) < 1e-5
    with pytest.raises(ValueError, match="one mask"):
        crop_descriptors([rgb], [mask, mask], SETTINGS)


# --------------------------------------------------------------------------- pose CRF
def test_unary_counts_votes_and_expands_symmetries():
    grid = PoseGrid(8, 2, 0.5)
    desc = np.eye(16, dtype=np.float32)[:16]
    rows = np.concatenate([desc, desc, desc])  # three models, identical renders
    index = RenderIndex("x", grid, ("a", "b", "c"), ("none", "two", "full"), rows)
    q = np.zeros((1, 16))
    q[0, 6] = 1.0  # label 6: yaw bin 3, pitch 0 - each model's render at label 6 is at distance 0
    unary, nb, votes = pose_unaries(index, q, k=3, tie_break=0.0)
    assert sorted(nb.model[0].tolist()) == [0, 1, 2] and set(nb.label[0].tolist()) == {6}
    # "none": label 6; "two": labels 6 and (3 + 4) * 2 = 14; "full": every yaw bin at pitch 0
    expect = np.zeros(16)
    expect[0::2] += 1
    expect[6] += 2
    expect[14] += 1
    np.testing.assert_array_equal(votes[0], expect)
    np.testing.assert_allclose(unary[0], np.exp(-expect))
    with pytest.raises(ValueError, match="tie_break"):
        pose_unaries(index, q, tie_break=-1.0)


@pytest.mark.parametrize("mid, yaw_deg", [("tv-01", 37.0), ("tv-03", 212.0), ("chair-01", 121.0), ("chair-05", 303.0)])
def test_off_grid_views_give_the_model_and_the_yaw(renders, renderer, lib, mid, yaw_deg):
    rgb, mask = renderer.render(lib[mid], math.radians(yaw_deg), PITCH)
    res = estimate_poses(renders, lib[mid].cls, [rgb], [mask])
    e = res.estimates[0]
    assert e.model_id == mid and e.symmetry == "none"
    assert math.degrees(_yaw_err(e.yaw_rel, math.radians(yaw_deg))) < 3.5
    grid_yaw = GRID.poses()[e.label, 0]
    assert math.degrees(_yaw_err(grid_yaw, math.radians(yaw_deg))) < 5.0  # the true bin or its neighbour
    assert 0.0 <= e.confidence <= 1.0 and e.confidence >= 0.5
    assert e.e_o.shape == (72, 2) and e.e_o_models.shape[1:] == (72, 2)
    # E_o at grid poses is the table; its minimum is near the true pose
    iy, ip = divmod(e.label, 2)
    assert e.e_o_at(GRID.yaws[iy], GRID.pitches[ip]) == pytest.approx(e.e_o[iy, ip])
    best_iy = int(np.argmin(e.e_o[:, ip]))
    assert math.degrees(_yaw_err(GRID.yaws[best_iy], math.radians(yaw_deg))) <= 5.0
    unrefined = estimate_poses(renders, lib[mid].cls, [rgb], [mask], refine=False).estimates[0]
    assert unrefined.yaw_rel == pytest.approx(grid_yaw)


def test_symmetric_models(renders, renderer, lib):
    rgb, mask = renderer.render(lib["plant-02"], 1.0, 0.0)
    e = estimate_poses(renders, "plant", [rgb], [mask]).estimates[0]
    assert e.yaw_rel is None and e.world_yaw([1.0, 0.0, 0.0]) is None and e.symmetry == "full"
    rgb, mask = renderer.render(lib["table-01"], math.radians(250.0), PITCH)
    e = estimate_poses(renders, "table", [rgb], [mask]).estimates[0]
    assert e.model_id == "table-01" and e.symmetry == "two"
    assert 0.0 <= e.yaw_rel < math.pi
    assert math.degrees(_yaw_err(e.yaw_rel, math.radians(250.0), math.pi)) < 3.0


def test_binary_term_pulls_crops_together(renders, renderer, lib):
    views = [renderer.render(lib["tv-02"], math.radians(y), PITCH) for y in (30.0, 42.0)]
    crops, masks = [v[0] for v in views], [v[1] for v in views]
    free = estimate_poses(renders, "tv", crops, masks, pairwise_weight=0.0)
    assert free.edges.shape == (0, 2) and free.estimates[0].label != free.estimates[1].label
    paper = estimate_poses(renders, "tv", crops, masks, edge_radius=None)
    assert paper.edges.tolist() == [[0, 1]] and paper.iterations >= 1
    assert paper.lower_bound <= paper.energy + 1e-9
    glued = estimate_poses(renders, "tv", crops, masks, pairwise_weight=1e4, edge_radius=None)
    assert glued.estimates[0].label == glued.estimates[1].label
    # edge_radius keeps only images closer to each other than to their K-th nearest render
    near = estimate_poses(renders, "tv", [crops[0], crops[0]], [masks[0], masks[0]])
    assert near.edges.tolist() == [[0, 1]]
    far_view = renderer.render(lib["tv-03"], math.radians(200.0), 0.0)
    far = estimate_poses(renders, "tv", [crops[0], far_view[0]], [masks[0], far_view[1]])
    assert far.edges.shape == (0, 2)


def test_aux_folder_adds_nodes(tmp_path: Path, renders, renderer, lib):
    import cv2

    for k, yaw in enumerate((0.5, 2.0)):
        rgb, mask = renderer.render(lib["tv-01"], yaw, 0.0)
        rgba = np.concatenate([rgb[..., ::-1], (mask * 255).astype(np.uint8)[..., None]], axis=2)
        cv2.imwrite(str(tmp_path / f"web{k}.png"), rgba)
    rgb, mask = renderer.render(lib["tv-02"], 4.0, 0.0)
    cv2.imwrite(str(tmp_path / "web2.jpg"), rgb[..., ::-1])
    cv2.imwrite(str(tmp_path / "web2_mask.png"), (mask * 255).astype(np.uint8))
    (tmp_path / "notes.txt").write_text("not an image")
    items = load_aux_folder(tmp_path)
    assert len(items) == 3 and all(m is not None for _, m in items)
    assert items[0][0].shape == (96, 96, 3) and items[0][1].sum() == pytest.approx(
        renderer.render(lib["tv-01"], 0.5, 0.0)[1].sum(), rel=0.01)
    target = renderer.render(lib["tv-01"], 0.55, 0.0)
    res = estimate_poses(renders, "tv", [target[0]], [target[1]], aux=tmp_path)
    assert len(res) == 1 and res.aux_labels.shape == (3,)
    assert res.edges.tolist() == [[0, 1]]  # only the auxiliary view of the same TV at a near pose is "near"
    assert abs(int(res.aux_labels[0]) - res.estimates[0].label) <= 2 * GRID.n_pitch
    (tmp_path / "broken.png").write_bytes(b"garbage")
    with pytest.raises(ValueError, match="broken.png"):
        load_aux_folder(tmp_path)
    with pytest.raises(ValueError, match="existing folder"):
        load_aux_folder(tmp_path / "missing")


def test_estimate_poses_checks_its_inputs(renders):
    img = np.zeros((20, 30, 3), np.uint8)
    with pytest.raises(ValueError, match="at least one target crop"):
        estimate_poses(renders, "tv", [])
    with pytest.raises(ValueError, match=r"crops\[0\]"):
        estimate_poses(renders, "tv", [img.astype(np.float32)])
    with pytest.raises(ValueError, match="class_name"):
        estimate_poses(renders, "sofa", [img])
    with pytest.raises(ValueError, match="masks"):
        estimate_poses(renders, "tv", [img], [None, None])
    with pytest.raises(ValueError, match="gamma"):
        estimate_poses(renders, "tv", [img], gamma=-1.0)
