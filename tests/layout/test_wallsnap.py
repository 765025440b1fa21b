"""layout.wallsnap: walls moved onto the image's ceiling-wall edges."""

import numpy as np
import pytest

from layout.labelmap import render_room_labels, room_boundaries, shade_labels
from layout.polygon import is_simple
from layout.wallsnap import snap_ceiling_height, snap_room, snap_walls

H_CAM, CZ = 1.5, 2.6
L_ROOM = np.array([[-2.0, -1.5], [2.5, -1.5], [2.5, 0.5], [1.0, 0.5], [1.0, 2.0], [-2.0, 2.0]])


def _image(ceil_v: np.ndarray, noise: float = 0.0, seed: int = 0) -> np.ndarray:
    """A 512 x 1024 grey panorama: bright ceiling above the curve ``ceil_v`` (1024,), darker walls below."""
    rows = np.arange(512)[:, None] + 0.5
    img = np.where(rows < ceil_v[None, :], 215.0, 140.0)
    if noise:
        img = img + np.random.default_rng(seed).normal(0.0, noise, img.shape)
    return img


def _three_tone(floor: np.ndarray) -> np.ndarray:
    """The room ``floor`` seen from the camera, painted from its analytic labels (ceiling, walls, floor)."""
    return shade_labels(render_room_labels(floor, CZ, [0.0, 0.0], H_CAM, 1024), 3)


def _ceiling(floor: np.ndarray) -> np.ndarray:
    return room_boundaries(floor, CZ, [0.0, 0.0], H_CAM, 1024).ceil_v


def test_walls_the_labels_put_off_move_back_onto_the_edge():
    img = _image(_ceiling(L_ROOM), noise=6.0)
    guess = L_ROOM.copy()
    guess[1:3, 0] = 2.2  # wall 1 (x = 2.5) 12 % too near
    guess[4:6, 1] = 2.3  # wall 4 (y = 2.0) 15 % too far
    res = snap_walls(img, guess, CZ, H_CAM)
    assert res.moved.tolist() == [False, True, False, False, True, False]
    np.testing.assert_allclose(res.floor, L_ROOM, atol=0.02)  # within the grid's 0.75 % steps
    assert res.factor[1] == pytest.approx(2.5 / 2.2, rel=0.01) and res.factor[4] == pytest.approx(2.0 / 2.3, rel=0.01)
    assert np.all(res.peak[res.moved] >= 2.0) and np.all(res.columns >= 12)
    assert res.ceiling_z == CZ and res.height_walls == 0 and not res.vetoed.any()  # no floor crease to read


def test_the_ceiling_height_follows_the_walls_that_show_both_creases():
    """Walls where the floor-wall crease puts them, ceiling 12 % too high above the camera (the labels' ceiling
    boundary too high all round): the ratio of each wall's two creases moves the ceiling, the walls stay."""
    img = _three_tone(L_ROOM)
    res = snap_walls(img, L_ROOM, H_CAM + (CZ - H_CAM) * 1.12, H_CAM)
    assert res.height_walls >= 2
    assert res.ceiling_z == pytest.approx(CZ, abs=0.02)
    np.testing.assert_allclose(res.floor, L_ROOM, atol=0.02)
    # the same image with the ceiling given right: nothing to do
    res = snap_walls(img, L_ROOM, CZ, H_CAM)
    assert res.height_walls == 0 and res.ceiling_z == CZ and not res.moved.any()


def test_a_floor_crease_under_the_labels_wall_vetoes_a_ceiling_edge_elsewhere():
    """Wall 1 shows a crease 15 % farther at ceiling level only (the top of a tall cupboard standing in front of
    it looks like that), while its floor crease is where the labels put it: the wall stays."""
    b = room_boundaries(L_ROOM, CZ, [0.0, 0.0], H_CAM, 1024)
    far = L_ROOM.copy()
    far[1:3, 0] = 2.5 * 1.15
    ceil = np.where(b.wall_index == 1, room_boundaries(far, CZ, [0.0, 0.0], H_CAM, 1024).ceil_v, b.ceil_v)
    rows = np.arange(512)[:, None] + 0.5
    img = np.where(rows < ceil, 215.0, np.where(rows < b.floor_v, 140.0, 80.0))
    img = img + np.random.default_rng(4).normal(0.0, 6.0, img.shape)
    res = snap_walls(img, L_ROOM, CZ, H_CAM)
    assert res.vetoed[1] and not res.moved[1]
    assert res.height_walls == 0  # one wall's disagreement does not move the ceiling
    np.testing.assert_array_equal(res.floor, L_ROOM)
    # without its floor crease (floor and walls one grey) the ceiling edge alone moves the wall
    res = snap_walls(np.where(rows < ceil, 215.0, 140.0), L_ROOM, CZ, H_CAM)
    assert res.moved[1] and not res.vetoed.any() and res.floor[1, 0] == pytest.approx(2.5 * 1.15, abs=0.03)


def test_a_wall_without_an_edge_stays():
    """No crease anywhere (a uniform image, then noise alone): nothing moves."""
    guess = L_ROOM.copy()
    guess[1:3, 0] = 2.2
    for img in (np.full((512, 1024), 128.0), np.random.default_rng(1).normal(128.0, 20.0, (512, 1024))):
        res = snap_walls(img, guess, CZ, H_CAM)
        assert not res.moved.any()
        np.testing.assert_array_equal(res.floor, guess)


def test_an_edge_beyond_the_span_pulls_the_wall_to_the_span_s_end():
    img = _image(_ceiling(L_ROOM))
    guess = L_ROOM.copy()
    guess[1:3, 0] = 1.8  # the true wall is 39 % farther: outside the default span of 25 %
    res = snap_walls(img, guess, CZ, H_CAM)
    assert res.moved[1] and res.floor[1, 0] == pytest.approx(1.8 * 1.25)
    res = snap_walls(img, guess, CZ, H_CAM, span=1.45, steps=91)
    assert res.moved[1] and res.floor[1, 0] == pytest.approx(2.5, abs=0.02)


def test_masked_ceiling_columns_do_not_score_the_wall():
    img = _image(_ceiling(L_ROOM))
    guess = L_ROOM.copy()
    guess[1:3, 0] = 2.2
    seen = room_boundaries(guess, CZ, [0.0, 0.0], H_CAM, 1024).wall_index == 1
    mask = np.zeros((256, 512), bool)  # any panorama size
    mask[:, seen[::2]] = True  # the wall's columns at half the width
    res = snap_walls(img, guess, CZ, H_CAM, object_mask=mask)
    assert not res.moved[1] and res.columns[1] == 0 and np.isnan(res.peak[1])


def test_a_move_that_would_cross_another_wall_is_refused():
    """A C-shaped room: wall 2 (y = 1.0) faces the camera, wall 4 (y = 1.15) the other arm. The image shows a
    crease as if wall 2 stood at y = 1.2, past wall 4: the polygon would intersect itself, so wall 2 stays."""
    c_room = np.array([[-2.0, -1.5], [2.0, -1.5], [2.0, 1.0], [0.5, 1.0], [0.5, 1.15], [2.0, 1.15], [2.0, 2.5],
                       [-2.0, 2.5]])
    b = room_boundaries(c_room, CZ, [0.0, 0.0], H_CAM, 1024)
    far = _ceiling(np.array([[-2.0, -1.5], [2.0, -1.5], [2.0, 1.2], [-2.0, 1.2]]))
    ceil = np.where(b.wall_index == 2, far, b.ceil_v)
    res = snap_walls(_image(ceil), c_room, CZ, H_CAM)
    assert res.peak[2] >= 2.0  # the crease was found ...
    assert not res.moved[2]  # ... and refused
    moved = c_room.copy()
    moved[2:4, 1] = 1.2
    assert not is_simple(moved)  # what following it would have given
    assert is_simple(res.floor)


def test_colour_and_size_of_the_image_do_not_matter():
    grey = _image(_ceiling(L_ROOM))
    guess = L_ROOM.copy()
    guess[1:3, 0] = 2.2
    rgb = np.repeat(grey[..., None], 3, axis=2).astype(np.uint8)
    big = np.repeat(np.repeat(rgb, 2, axis=0), 2, axis=1)
    a = snap_walls(grey, guess, CZ, H_CAM)
    for img in (rgb, big):
        b = snap_walls(img, guess, CZ, H_CAM)
        assert b.moved.tolist() == a.moved.tolist()
        np.testing.assert_allclose(b.floor, a.floor, atol=0.02)


@pytest.mark.parametrize("kwargs, match", [
    (dict(image=np.zeros((100, 150))), "panorama"),
    (dict(floor=[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]), "polygon"),
    (dict(floor=[[-1.0, -1.0], [1.0, -1.0], [2.0, 1.0], [-1.0, 1.0]]), "Manhattan"),
    (dict(floor=[[1.0, 1.0], [2.0, 1.0], [2.0, 2.0], [1.0, 2.0]]), "around the camera"),
    (dict(ceiling_z=1.2), "camera_height < ceiling_z"),
    (dict(span=1.0), "span"),
    (dict(steps=60), "odd"),
    (dict(object_mask=np.zeros((10, 10), bool)), "object_mask"),
])
def test_bad_input_is_refused(kwargs, match):
    args = dict(image=np.zeros((64, 128)), floor=L_ROOM, ceiling_z=CZ, camera_height=H_CAM)
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        snap_walls(args.pop("image"), args.pop("floor"), args.pop("ceiling_z"), args.pop("camera_height"), **args)


@pytest.mark.parametrize("t", [0.88, 1.13])
def test_the_floor_crease_fixes_the_wall_height_the_ceiling_curves_leave_free(t):
    """Walls and ceiling given ``t`` times too far and too high above the camera (the same ceiling curves, what the
    wall snap fits): the floor-wall edges bring both back."""
    img = _three_tone(L_ROOM)
    res = snap_ceiling_height(img, L_ROOM * t, H_CAM + (CZ - H_CAM) * t, H_CAM)
    assert res.moved and res.factor * t == pytest.approx(1.0, abs=0.01)
    assert res.ceiling_z == pytest.approx(CZ, abs=0.02)
    np.testing.assert_allclose(res.floor, L_ROOM, atol=0.03)
    assert res.peak >= 2.0 and res.columns > 500


def test_without_a_floor_crease_the_height_stays():
    img = _image(_ceiling(L_ROOM), noise=6.0)  # ceiling edge only: walls and floor one grey
    res = snap_ceiling_height(img, L_ROOM * 1.1, H_CAM + (CZ - H_CAM) * 1.1, H_CAM)
    assert not res.moved and res.factor == 1.0
    np.testing.assert_array_equal(res.floor, L_ROOM * 1.1)


def test_floor_boundaries_under_objects_do_not_score_the_height():
    img = _three_tone(L_ROOM)
    mask = np.zeros((512, 1024), bool)
    mask[256:] = True  # every floor-wall boundary lies below the horizon
    res = snap_ceiling_height(img, L_ROOM * 1.1, H_CAM + (CZ - H_CAM) * 1.1, H_CAM, object_mask=mask)
    assert not res.moved and res.columns == 0 and np.isnan(res.peak)


def test_the_height_snap_checks_its_input_as_the_wall_snap():
    with pytest.raises(ValueError, match="camera_height < ceiling_z"):
        snap_ceiling_height(np.zeros((64, 128)), L_ROOM, 1.0, H_CAM)
    with pytest.raises(ValueError, match="panorama"):
        snap_ceiling_height(np.zeros((64, 64)), L_ROOM, CZ, H_CAM)


def test_snap_room_is_the_wall_snap_then_the_height_snap_on_its_room():
    """What the pipeline runs: the same result as the two functions called in turn (one gradient image for both)."""
    img = _three_tone(L_ROOM)
    guess = L_ROOM.copy()
    guess[1:3, 0] = 2.2
    cz = H_CAM + (CZ - H_CAM) * 1.1
    res = snap_room(img, guess, cz, H_CAM)
    walls = snap_walls(img, guess, cz, H_CAM)
    height = snap_ceiling_height(img, walls.floor, walls.ceiling_z, H_CAM)
    np.testing.assert_array_equal(res.walls.floor, walls.floor)
    assert res.walls.ceiling_z == walls.ceiling_z and res.walls.height_walls == walls.height_walls
    np.testing.assert_array_equal(res.floor, height.floor)
    assert res.ceiling_z == height.ceiling_z == res.height.ceiling_z
    assert res.walls.moved[1] and res.walls.height_walls >= 2  # this room needs both: wall 1 and the ceiling
    np.testing.assert_allclose(res.floor, L_ROOM, atol=0.03)
    assert res.ceiling_z == pytest.approx(CZ, abs=0.02)
    with pytest.raises(ValueError, match="camera_height < ceiling_z"):
        snap_room(img, guess, 1.0, H_CAM)


def test_shade_labels_paints_one_grey_per_label():
    from layout.labelmap import SHADES

    lab = np.array([[0, 1, 2, 3], [4, 5, 1, 2]], np.uint8)
    np.testing.assert_array_equal(shade_labels(lab, noise=0.0), np.asarray(SHADES)[lab])
    a, b = shade_labels(lab, 3), shade_labels(lab, 3)
    np.testing.assert_array_equal(a, b)  # seeded
    assert 0 < np.std(a - shade_labels(lab, noise=0.0)) < 20
    with pytest.raises(ValueError, match="0..5"):
        shade_labels(np.array([[0, 9]], np.uint8))
