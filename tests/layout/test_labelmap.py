"""Tests of layout.labelmap: analytic label rendering, boundaries, agreement counts, noise, camera sampling."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from layout.labelmap import (
    CEILING,
    FLOOR,
    OBJECT,
    UNKNOWN,
    WALL_X,
    WALL_Y,
    LabelCounts,
    labels_from_boundaries,
    observe_boundaries,
    perturb_labels,
    render_room_labels,
    room_boundaries,
    sample_camera_xy,
    visible_floor_fraction,
)
from layout.rooms import generate_room
from panogeom.coords import pixel_grid_rays

L_ROOM = np.array([[-1.0, -1.5], [3.0, -1.5], [3.0, 0.5], [1.0, 0.5], [1.0, 2.0], [-1.0, 2.0]])


def brute_force_labels(floor, ceiling_z, camera_xy, camera_height, width):
    """Per-pixel ray casting against the floor plane, the ceiling plane and every wall rectangle."""
    h = width // 2
    rays = pixel_grid_rays(width, h).reshape(-1, 3)
    cam = np.array([camera_xy[0], camera_xy[1], camera_height])
    best_t = np.full(len(rays), np.inf)
    label = np.zeros(len(rays), np.uint8)
    with np.errstate(divide="ignore", invalid="ignore"):
        for z, lab in ((0.0, FLOOR), (ceiling_z, CEILING)):
            t = (z - cam[2]) / rays[:, 2]
            p = cam[:2] + t[:, None] * rays[:, :2]
            ok = (t > 0) & np.isfinite(t)
            from layout.polygon import points_in_polygon

            ok &= points_in_polygon(np.where(ok[:, None], p, 0.0), floor)
            upd = ok & (t < best_t)
            best_t[upd], label[upd] = t[upd], lab
        poly = np.asarray(floor, float)
        for a, b in zip(poly, np.roll(poly, -1, axis=0)):
            e = b - a
            n = np.array([e[1], -e[0]])
            denom = rays[:, :2] @ n
            t = ((a - cam[:2]) @ n) / denom
            p = cam + t[:, None] * rays
            s = ((p[:, :2] - a) @ e) / (e @ e)
            ok = (t > 0) & (s >= 0) & (s <= 1) & (p[:, 2] >= 0) & (p[:, 2] <= ceiling_z)
            upd = ok & (t < best_t)
            best_t[upd] = t[upd]
            label[upd] = WALL_X if abs(e[0]) <= abs(e[1]) else WALL_Y
    return label.reshape(h, width)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_render_matches_brute_force_ray_casting(seed):
    rng = np.random.default_rng(seed)
    room = generate_room(rng, template=["rectangle", "L", "plus", "U"][seed])
    cam = sample_camera_xy(room.floor, rng, margin=0.5)
    fast = render_room_labels(room.floor, room.ceiling_z, cam, 1.6, 256)
    slow = brute_force_labels(room.floor, room.ceiling_z, cam, 1.6, 256)
    assert np.mean(fast == slow) > 0.995


def test_render_values_and_column_order():
    lab = render_room_labels(L_ROOM, 2.8, [0.0, 0.0], 1.6, 512)
    assert lab.shape == (256, 512) and lab.dtype == np.uint8
    assert set(np.unique(lab).tolist()) == {FLOOR, CEILING, WALL_X, WALL_Y}
    # every column reads ceiling, then one wall label, then floor, top to bottom
    for j in range(0, 512, 7):
        col = lab[:, j]
        changes = np.flatnonzero(np.diff(col.astype(int)))
        assert len(changes) == 2 and col[0] == CEILING and col[-1] == FLOOR


def test_room_boundaries_batch_equals_single_calls():
    scales = np.array([0.8, 1.0, 1.3])
    cams = np.array([[0.0, 0.0], [0.5, 0.2], [-0.3, 1.0]])
    batch = room_boundaries(L_ROOM, 2.7, cams, 1.6, 256, scale=scales)
    assert batch.floor_v.shape == (3, 256) and batch.valid.tolist() == [True, True, True]
    for k in range(3):
        one = room_boundaries(L_ROOM, 2.7, cams[k], 1.6, 256, scale=scales[k])
        np.testing.assert_allclose(batch.floor_v[k], one.floor_v)
        np.testing.assert_allclose(batch.ceil_v[k], one.ceil_v)
        np.testing.assert_array_equal(batch.wall_label[k], one.wall_label)


def test_room_boundaries_scale_is_a_dilation():
    b1 = room_boundaries(L_ROOM, 2.7, [0.0, 0.0], 1.6, 128)
    b2 = room_boundaries(L_ROOM * 2, 2.7 * 2, [0.0, 0.0], 3.2, 128)
    np.testing.assert_allclose(b1.floor_v, b2.floor_v, atol=1e-9)
    np.testing.assert_allclose(b1.ceil_v, b2.ceil_v, atol=1e-9)


def test_camera_outside_is_invalid_and_render_refuses_it():
    b = room_boundaries(L_ROOM, 2.7, [2.5, 1.5], 1.6, 128)
    assert not bool(b.valid)
    assert np.any(b.wall_label == UNKNOWN)
    with pytest.raises(ValueError, match="strictly inside"):
        render_room_labels(L_ROOM, 2.7, [2.5, 1.5], 1.6, 128)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(width=101), "positive even integer"),
        (dict(camera_height=3.0), "camera_height < ceiling_z"),
        (dict(floor=[[0, 0], [1, 0]]), r"shape \(\.\.\., N, 2\) with N >= 3"),
    ],
)
def test_render_rejects_bad_input(kwargs, match):
    args = dict(floor=L_ROOM, ceiling_z=2.7, camera_xy=[0.0, 0.0], camera_height=1.6, width=128)
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        render_room_labels(**args)


def test_observe_boundaries_round_trip_and_contacts():
    lab = render_room_labels(L_ROOM, 2.8, [0.0, 0.0], 1.6, 1024)
    b = room_boundaries(L_ROOM, 2.8, [0.0, 0.0], 1.6, 1024)
    ob = observe_boundaries(lab)
    assert ob.floor_contact.all() and ob.ceil_contact.all()
    assert np.max(np.abs(ob.floor_v - b.floor_v)) <= 0.5 + 1e-9
    assert np.max(np.abs(ob.ceil_v - b.ceil_v)) <= 0.5 + 1e-9
    np.testing.assert_array_equal(ob.wall_label, b.wall_label)
    # clutter hiding the bottom of the wall in some columns: no floor contact there
    cl = lab.copy()
    rows = np.arange(512)[:, None]
    band = (rows > b.floor_v[None, :] - 20) & (rows < b.floor_v[None, :] + 5)
    band[:, 600:] = False
    cl[band] = UNKNOWN
    ob2 = observe_boundaries(cl)
    assert not ob2.floor_contact[:600].any() and ob2.floor_contact[600:].all()
    assert ob2.ceil_contact.all()


def test_observe_boundaries_rejects_non_panorama():
    with pytest.raises(ValueError, match=r"W == 2\*H"):
        observe_boundaries(np.zeros((100, 300), np.uint8))
    with pytest.raises(ValueError, match="labels 0..5"):
        observe_boundaries(np.full((64, 128), 9, np.uint8))


def test_label_counts_agreement_equals_pixel_comparison():
    rng = np.random.default_rng(5)
    lab = render_room_labels(L_ROOM, 2.7, [0.0, 0.0], 1.6, 256)
    noisy, mask = perturb_labels(lab, rng)
    counts = LabelCounts.from_labels(noisy, mask)
    scales = np.array([0.9, 1.0, 1.15])
    b = room_boundaries(L_ROOM, 2.7, [0.0, 0.0], 1.6, 256, scale=scales)
    rendered = labels_from_boundaries(b)
    comparable = (noisy >= FLOOR) & (noisy <= WALL_Y) & ~mask
    direct = [int(np.sum((rendered[k] == noisy) & comparable)) for k in range(3)]
    assert counts.agreement(b).tolist() == direct
    assert counts.comparable == int(comparable.sum())
    assert int(np.argmin(counts.cost(b))) == 1


def test_perturb_labels_is_seeded_and_masks_objects():
    lab = render_room_labels(L_ROOM, 2.7, [0.0, 0.0], 1.6, 256)
    a, ma = perturb_labels(lab, 3)
    b, mb = perturb_labels(lab, 3)
    c, _ = perturb_labels(lab, 4)
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(ma, mb)
    assert not np.array_equal(a, c)
    assert ma.any() and np.all(a[ma] == OBJECT)
    assert 0.0 < np.mean(a != lab) < 0.25


def test_visible_floor_fraction_of_an_l_room():
    # camera in the lower-right part of the L sees the lower arm and a sliver of the upper one
    L = [[0, 0], [4, 0], [4, 1], [1, 1], [1, 4], [0, 4]]
    exact = (4.0 + 0.5 * 1.0 * 0.2) / 7.0
    assert visible_floor_fraction(L, [3.5, 0.5], cells=400) == pytest.approx(exact, abs=0.01)
    assert visible_floor_fraction(L, [0.5, 0.5]) == 1.0


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 10_000), margin=st.sampled_from([0.3, 0.5]))
def test_sample_camera_keeps_its_margin(seed, margin):
    from layout.polygon import distance_to_boundary, points_in_polygon

    room = generate_room(seed)
    xy = sample_camera_xy(room.floor, seed, margin=margin)
    assert bool(points_in_polygon(xy, room.floor))
    assert float(distance_to_boundary(xy, room.floor)) >= margin - 1e-9


def test_sample_camera_candidates_prefer_visibility():
    U = generate_room(7, template="U").floor
    one = [visible_floor_fraction(U, sample_camera_xy(U, s), width=256) for s in range(6)]
    best = [visible_floor_fraction(U, sample_camera_xy(U, s, candidates=6), width=256) for s in range(6)]
    assert np.mean(best) >= np.mean(one)


def test_sample_camera_fails_clearly_without_room():
    with pytest.raises(ValueError, match="room for a camera"):
        sample_camera_xy([[0, 0], [0.6, 0], [0.6, 0.6], [0, 0.6]], 0, margin=0.5, max_tries=512)


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 10_000))
def test_rendered_labels_are_what_observe_reads_back(seed):
    rng = np.random.default_rng(seed)
    room = generate_room(rng)
    cam = sample_camera_xy(room.floor, rng, margin=0.5)
    lab = render_room_labels(room.floor, room.ceiling_z, cam, 1.6, 256)
    again = labels_from_boundaries(room_boundaries(room.floor, room.ceiling_z, cam, 1.6, 256))
    np.testing.assert_array_equal(lab, again)
    ob = observe_boundaries(lab)
    assert np.all(ob.wall_label[ob.floor_contact] >= WALL_X)
