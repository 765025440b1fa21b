"""Tests of panogeom.texture: procedural patterns, lights, decor, camera model, shading."""

from __future__ import annotations

import numpy as np
import pytest

from panogeom.raycast import (LABEL_FLOOR, LABEL_WALL_X, LABEL_WALL_Y, RenderMesh, pose_matrix,
                              raycast_equirect, room_meshes, transform_mesh)
from panogeom.texture import (Decor, Material, MaterialStyle, Opening, PointLight, PostProcess, default_style,
                              material_albedo, place_openings, sample_decor, sample_lights, sample_palette,
                              sample_post, sample_styles, shade, value_noise)

BOX = [[-2.0, -1.5], [3.0, -1.5], [3.0, 2.5], [-2.0, 2.5]]
CZ = 2.7
CAM = [0.2, 0.1, 1.5]
NO_DECOR = Decor(skirting_height=0.0, door_probability=0.0, window_probability=0.0, light_fixtures=False)


def flat_styles() -> dict[int, MaterialStyle]:
    """Every material without pattern (contrast 0, no lines)."""
    return {int(m): MaterialStyle(m, contrast=0.0) for m in Material}


def cube(size: float, instance_id: int) -> RenderMesh:
    v = np.array([[x, y, z] for z in (0.0, size) for y in (-size / 2, size / 2) for x in (-size / 2, size / 2)])
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    f = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])
    return RenderMesh(v, f, labels=5, instance_ids=instance_id, material_ids=Material.PLASTIC, colors=(0.5, 0.5, 0.5))


@pytest.fixture(scope="module")
def scene():
    room = room_meshes(BOX, CZ, floor_material=Material.WOOD)
    obj = transform_mesh(cube(0.7, 3), pose_matrix(0.4, [1.5, 1.0, 0.0]))
    return [room, obj], raycast_equirect([room, obj], 256, CAM)


# ----------------------------------------------------------------------------- patterns


def test_value_noise_is_deterministic_smooth_and_seeded():
    pts = np.random.default_rng(0).uniform(0, 20, (5000, 2))
    a = value_noise(pts, seed=4, frequency=1.5, octaves=3)
    np.testing.assert_array_equal(a, value_noise(pts, seed=4, frequency=1.5, octaves=3))
    assert not np.allclose(a, value_noise(pts, seed=5, frequency=1.5, octaves=3))
    assert np.abs(a).max() <= 1.0 and a.std() > 0.1
    # Smooth: a 1 mm step changes the value far less than the spread of values.
    b = value_noise(pts + [0.001, 0.0], seed=4, frequency=1.5, octaves=3)
    assert np.abs(a - b).max() < 0.05 * a.std()
    with pytest.raises(ValueError, match="frequency"):
        value_noise(pts, frequency=0.0)


def test_tile_grout_lines_at_multiples_of_the_tile_size():
    style = MaterialStyle(Material.TILE, scale=0.3, length=0.3, line_width=0.006, line_color=(0.1, 0.1, 0.1),
                          contrast=0.0)
    x = np.linspace(0.001, 2.0, 4001)
    pts = np.column_stack([x, np.full_like(x, 0.15), np.zeros_like(x)])
    a = material_albedo(style, pts, np.tile([0.0, 0.0, 1.0], (len(x), 1)), (0.9, 0.9, 0.9))
    grout = np.abs(x - 0.3 * np.round(x / 0.3)) < 0.003
    np.testing.assert_allclose(a[grout], 0.1, atol=1e-6)
    np.testing.assert_allclose(a[~grout], 0.9, atol=1e-6)
    # Far away (footprint 10x the tile), the lines blend into their area fraction instead of aliasing.
    far = material_albedo(style, pts, np.tile([0.0, 0.0, 1.0], (len(x), 1)), (0.9, 0.9, 0.9), footprint=3.0)
    covered = 1 - (1 - 0.006 / 0.3) ** 2  # the footprint spans many tiles both ways: area fraction of grout
    np.testing.assert_allclose(far[:, 0], 0.9 - (0.9 - 0.1) * covered, atol=2e-3)


def test_wood_plank_gaps_follow_the_axis():
    base = (0.6, 0.4, 0.2)
    y = np.linspace(0.0005, 1.0, 2000)
    pts = np.column_stack([np.full_like(y, 0.37), y, np.zeros_like(y)])
    up = np.tile([0.0, 0.0, 1.0], (len(y), 1))
    across_y = MaterialStyle(Material.WOOD, scale=0.2, length=50.0, line_width=0.004, line_color=(0, 0, 0), axis=0)
    along_y = MaterialStyle(Material.WOOD, scale=0.2, length=50.0, line_width=0.004, line_color=(0, 0, 0), axis=1)
    a = material_albedo(across_y, pts, up, base)
    gap = a.sum(axis=1) == 0
    # Planks run along x (axis 0): walking along y crosses a gap every plank width.
    np.testing.assert_allclose(np.unique(np.round(y[gap] / 0.2)) * 0.2, [0.0, 0.2, 0.4, 0.6, 0.8, 1.0], atol=1e-9)
    assert np.all(np.abs(y[gap] - 0.2 * np.round(y[gap] / 0.2)) <= 0.002 + 1e-9)
    # Planks along y: walking along y stays on one plank (the only gap would be a plank end, 50 m long).
    b = material_albedo(along_y, pts, up, base)
    assert (b.sum(axis=1) == 0).sum() <= 4


@pytest.mark.parametrize("material", list(Material))
def test_every_material_has_texture_and_stays_in_range(material):
    style = sample_styles(7)[int(material)]
    pts = np.random.default_rng(1).uniform(-3, 3, (4000, 3))
    n = np.tile([0.0, 1.0, 0.0], (len(pts), 1))
    a = material_albedo(style, pts, n, (0.5, 0.45, 0.4), footprint=0.002)
    assert a.dtype == np.float32 and a.min() >= 0 and a.max() <= 1
    assert a.std(axis=0).max() > 0.003  # not a flat colour
    np.testing.assert_array_equal(a, material_albedo(style, pts, n, (0.5, 0.45, 0.4), footprint=0.002))


def test_samplers_are_deterministic_and_valid():
    assert sample_styles(3)[Material.TILE].scale == sample_styles(3)[Material.TILE].scale
    p1, p2 = sample_palette(11), sample_palette(11)
    assert all(np.array_equal(p1[k], p2[k]) for k in p1)
    assert all(0 <= v.min() and v.max() <= 1 for v in p1.values())
    assert isinstance(sample_decor(2), Decor) and isinstance(sample_post(2), PostProcess)
    assert default_style(99).material == Material.PLASTIC


@pytest.mark.parametrize("make, match", [
    (lambda: MaterialStyle(Material.TILE, scale=0.0), "scale"),
    (lambda: MaterialStyle(Material.WOOD, axis=2), "axis"),
    (lambda: MaterialStyle(Material.WOOD, line_color=(2.0, 0, 0)), "line_color"),
    (lambda: PointLight([0, 0, np.nan]), "finite"),
    (lambda: PointLight([0, 0, 2], intensity=0.0), "intensity"),
    (lambda: PostProcess(gamma=-1.0), "gamma"),
    (lambda: PostProcess(white_balance=(1.0, 0.0, 1.0)), "white_balance"),
    (lambda: Decor(door_probability=1.5), "probability"),
])
def test_parameter_validation(make, match):
    with pytest.raises(ValueError, match=match):
        make()


# ----------------------------------------------------------------------------- lights and decor


def test_sample_lights_inside_the_room_with_clearance():
    room = room_meshes(BOX, CZ)
    lights = sample_lights(room, rng=3, n=5)
    assert len(lights) == 5
    for light in lights:
        x, y, z = light.position
        assert -2.0 + 0.35 <= x <= 3.0 - 0.35 and -1.5 + 0.35 <= y <= 2.5 - 0.35
        assert z == pytest.approx(CZ - 0.25)
        assert light.radius <= 0.125
    assert [tuple(l.position) for l in lights] == [tuple(l.position) for l in sample_lights(room, rng=3, n=5)]


def test_place_openings_on_walls():
    room = room_meshes([[0, 0], [6, 0], [6, 1], [5, 1], [5, 4], [0, 4]], CZ)
    ops = place_openings(room, Decor(door_probability=1.0, window_probability=1.0), rng=1)
    assert ops == place_openings(room, Decor(door_probability=1.0, window_probability=1.0), rng=1)
    doors = [o for o in ops if o.kind == "door"]
    assert len(doors) >= 3 and all(o.z0 == 0.0 and 1.9 < o.z1 <= 2.1 for o in doors)
    for o in ops:
        # Each opening lies on a wall of the polygon, inside the wall's extent.
        if o.normal_axis == 0:
            assert o.offset in (0.0, 6.0, 5.0)
        else:
            assert o.offset in (0.0, 1.0, 4.0)
        assert 0.7 <= o.s1 - o.s0 <= 2.0 and o.z1 <= CZ - 0.15 + 1e-9
    # No door fits on the 1 m walls of the notch.
    assert not any(o.kind == "door" and ((o.normal_axis, o.offset) in ((0, 6.0), (1, 1.0))) for o in ops)


# ----------------------------------------------------------------------------- shading


def test_shade_is_deterministic_for_a_seed(scene):
    meshes, r = scene
    kw = dict(materials=sample_styles(1), decor=sample_decor(1), post=sample_post(1))
    a = shade(r, meshes, rng=5, **kw)
    b = shade(r, meshes, rng=5, **kw)
    c = shade(r, meshes, rng=6, **kw)
    assert a.shape == (128, 256, 3) and a.dtype == np.uint8
    np.testing.assert_array_equal(a, b)
    assert np.abs(a.astype(int) - c.astype(int)).mean() > 0.5


def test_lambert_falloff_matches_the_formula():
    room = room_meshes(BOX, CZ, floor_color=(0.8, 0.8, 0.8))
    r = raycast_equirect(room, 256, CAM)
    light = PointLight([0.5, 0.5, 2.4], intensity=1.0, radius=0.0)
    img = shade(r, room, flat_styles(), [light], rng=0, decor=NO_DECOR, post=PostProcess(gamma=1.0),
                ambient=0.0, shadows=False).astype(np.float64)
    floor = (r.labels == LABEL_FLOOR) & (img[..., 1] > 30) & (img[..., 1] < 220)
    L = light.position - r.points[floor].astype(np.float64)
    d2 = (L**2).sum(axis=1)
    expected = L[:, 2] / np.sqrt(d2) / (1 + d2)  # floor normal is +z
    ratio = img[floor][:, 1] / expected
    assert floor.sum() > 500
    assert ratio.std() / ratio.mean() < 0.02  # one scale factor explains every floor pixel


def test_shadows_darken_the_floor_behind_an_object():
    room = room_meshes(BOX, CZ)
    block = transform_mesh(cube(0.8, 2), pose_matrix(0.0, [1.5, 0.0, 0.6]))  # floating block under the light
    r = raycast_equirect([room, block], 256, CAM)
    light = PointLight([1.5, 0.0, 2.4], radius=0.05)
    kw = dict(materials=flat_styles(), lights=[light], rng=0, decor=NO_DECOR, post=PostProcess(gamma=1.0),
              ambient=0.2)
    lit = shade(r, [room, block], shadows=False, **kw).astype(float)
    shadowed = shade(r, [room, block], shadows=True, **kw).astype(float)
    under = (r.labels == LABEL_FLOOR) & (np.abs(r.points[..., 0] - 1.5) < 0.2) & (np.abs(r.points[..., 1]) < 0.2)
    assert under.sum() > 3
    assert shadowed[under].mean() < 0.5 * lit[under].mean()
    far = (r.labels == LABEL_FLOOR) & (np.hypot(r.points[..., 0] + 1.0, r.points[..., 1] - 1.5) < 0.4)
    np.testing.assert_allclose(shadowed[far].mean(), lit[far].mean(), rtol=0.05)


def test_skirting_board_makes_a_straight_edge_on_the_walls(scene):
    meshes, r = scene
    decor = Decor(skirting_height=0.12, skirting_color=(1.0, 1.0, 1.0), door_probability=0, window_probability=0,
                  light_fixtures=False)
    room = room_meshes(BOX, CZ, wall_color=(0.25, 0.3, 0.35))
    r2 = raycast_equirect([room, meshes[1]], 256, CAM)
    img = shade(r2, [room, meshes[1]], flat_styles(), rng=0, decor=decor, shadows=False).astype(float)
    wall = np.isin(r2.labels, [LABEL_WALL_X, LABEL_WALL_Y])
    z = r2.points[..., 2]
    board = wall & (z < 0.09)
    above = wall & (z > 0.16) & (z < 0.4)
    assert board.sum() > 50 and above.sum() > 50
    assert img[board].mean() > 1.5 * img[above].mean()


def test_openings_draw_frames_on_the_wall(scene):
    meshes, r = scene
    door = Opening("door", 0, 3.0, 0.0, 0.9, 0.0, 2.05)  # on the wall x = 3, in front of the camera
    decor = Decor(skirting_height=0.0, frame_color=(1.0, 1.0, 1.0), door_color=(0.1, 0.05, 0.0),
                  light_fixtures=False)
    img = shade(r, meshes, flat_styles(), rng=0, decor=decor, openings=[door], shadows=False).astype(float)
    plain = shade(r, meshes, flat_styles(), rng=0, decor=decor, openings=[], shadows=False).astype(float)
    p = r.points
    on_wall = r.labels == LABEL_WALL_X
    inside = on_wall & (np.abs(p[..., 0] - 3.0) < 1e-3) & (p[..., 1] > 0.1) & (p[..., 1] < 0.8) & (p[..., 2] < 1.9)
    assert inside.sum() > 20
    assert img[inside].mean() < 0.5 * plain[inside].mean()
    outside = on_wall & (p[..., 1] < -0.5)
    # Elsewhere the wall is unchanged (up to the auto exposure moving by the door's share of pixels).
    assert np.abs(img[outside] - plain[outside]).max() <= 3


def test_textured_walls_are_not_flat(scene):
    meshes, r = scene
    img = shade(r, meshes, sample_styles(2), rng=2, decor=NO_DECOR, shadows=False, ambient=100.0,
                post=PostProcess())
    wall = np.isin(r.labels, [LABEL_WALL_X, LABEL_WALL_Y])
    flat = shade(r, meshes, flat_styles(), rng=2, decor=NO_DECOR, shadows=False, ambient=100.0, post=PostProcess())
    # Ambient-dominated lighting: what varies on the walls is the texture.
    assert img[wall].std(axis=0).max() > 1.5 * flat[wall].std(axis=0).max()


def test_post_processing_effects(scene):
    meshes, r = scene
    kw = dict(materials=flat_styles(), rng=0, decor=NO_DECOR, shadows=False)
    base = shade(r, meshes, post=PostProcess(), **kw).astype(float)
    noisy = shade(r, meshes, post=PostProcess(noise_sigma=0.02), **kw).astype(float)
    blurred = shade(r, meshes, post=PostProcess(blur_sigma=1.5), **kw).astype(float)
    bright = shade(r, meshes, post=PostProcess(exposure=1.5), **kw).astype(float)
    warm = shade(r, meshes, post=PostProcess(white_balance=(1.2, 1.0, 0.8)), **kw).astype(float)
    assert np.abs(noisy - base).mean() > 1.0 and abs(noisy.mean() - base.mean()) < 2.0
    grad = lambda im: np.abs(np.diff(im, axis=1)).mean()  # noqa: E731
    assert grad(blurred) < grad(base)
    assert bright.mean() > base.mean() + 5
    assert warm[..., 0].mean() > base[..., 0].mean() and warm[..., 2].mean() < base[..., 2].mean()


def test_shade_rejects_mismatched_scene(scene):
    meshes, r = scene
    with pytest.raises(ValueError, match="faces"):
        shade(r, meshes[0])
    with pytest.raises(ValueError, match="lights"):
        shade(r, meshes, lights=[(0, 0, 2)])
    with pytest.raises(ValueError, match="ambient"):
        shade(r, meshes, ambient=-1.0)
