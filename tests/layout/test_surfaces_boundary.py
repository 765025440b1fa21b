"""Tests of layout.surfaces.boundary: the ceiling-wall boundary snapped to the image's edges."""

from __future__ import annotations

import numpy as np
import pytest

from layout.labelmap import labels_from_boundaries, render_room_labels, room_boundaries
from layout.surfaces import estimate_surfaces
from layout.surfaces.boundary import ceiling_edge_path, edge_strength, move_ceiling_boundary

L_ROOM = np.array([[-1.0, -1.5], [3.0, -1.5], [3.0, 0.5], [1.0, 0.5], [1.0, 2.0], [-1.0, 2.0]])
GREY = np.array([0, 70, 215, 150, 120, 0], dtype=np.uint8)  # unknown, floor, ceiling, wall x, wall y, object


def true_ceiling_rows(labels: np.ndarray) -> np.ndarray:
    """First non-ceiling row of each column (the ceiling-wall boundary, as an integer row)."""
    return np.argmax(labels != 2, axis=0).astype(np.float64)


def rendered(width: int = 512) -> tuple[np.ndarray, np.ndarray]:
    """A rendered L-shaped room: (labels, a grey panorama painted from them)."""
    lab = render_room_labels(L_ROOM, 2.7, [0.0, 0.0], 1.5, width)
    return lab, np.repeat(GREY[lab][..., None], 3, axis=2)


def test_path_follows_the_edge_from_a_boundary_several_rows_off():
    lab, pano = rendered()
    truth = true_ceiling_rows(lab)
    off = truth + np.where(np.arange(lab.shape[1]) % 200 < 100, 6.0, -5.0)  # the labeller off by 5-6 rows
    path = ceiling_edge_path(edge_strength(pano, lab.shape), off, band=10)
    assert np.mean(np.abs(path - truth) <= 1) > 0.97


def test_jump_cost_keeps_the_path_on_a_long_edge_past_a_brighter_speck():
    h, w = 64, 128
    e = np.zeros((h, w))
    e[20] = 0.2
    e[24, 60:64] = 0.5  # a short, stronger edge nearby (a lamp, a picture frame)
    assert np.all(ceiling_edge_path(e, np.full(w, 22.0), band=5, jump_cost=0.2) == 20)
    free = ceiling_edge_path(e, np.full(w, 22.0), band=5, jump_cost=0.0)
    assert np.all(free[60:64] == 24) and np.all(free[:60] == 20)


def test_without_edges_the_path_stays_in_the_band_and_straight():
    lab, _ = rendered()
    flat = np.zeros((*lab.shape, 3), np.uint8) + 128
    e = edge_strength(flat, lab.shape)
    assert not e.any()
    # a level labeller's boundary is kept as it is (ties go to the labeller)
    np.testing.assert_array_equal(ceiling_edge_path(e, np.full(lab.shape[1], 40.2)), 40.0)
    # a curved one: the path stays within the band and does not jump (no edge pays for a step)
    cv = true_ceiling_rows(lab) + 0.3
    path = ceiling_edge_path(e, cv, band=10)
    assert np.all(np.abs(path - np.round(cv)) <= 10)
    assert np.abs(np.diff(path)).sum() <= np.abs(np.diff(np.round(cv))).sum()
    # NaN columns take the band of their neighbours; all NaN gives NaN
    cv[10:20] = np.nan
    assert np.all(np.isfinite(ceiling_edge_path(e, cv)))
    assert np.all(np.isnan(ceiling_edge_path(np.zeros((8, 16)), np.full(16, np.nan))))


def test_move_ceiling_boundary_relabels_only_ceiling_and_wall():
    lab, _ = rendered(256)
    truth = true_ceiling_rows(lab)
    wall = lab[lab.shape[0] // 2 - 1]  # the wall label of each column, just above the horizon
    crept = lab.copy()
    crept[:, 40:90] = move_ceiling_boundary(lab[:, 40:90], truth[40:90] + 7, wall[40:90])  # ceiling creeps down
    crept[: lab.shape[0] // 2, 100:104] = 0  # clutter / unknown in the upper half
    crept[60:70, 150:160] = 5  # an object
    assert (crept != lab).any()
    back = move_ceiling_boundary(crept, truth, wall)
    keep = (crept == 0) | (crept == 5) | (crept == 1)
    np.testing.assert_array_equal(back[keep], crept[keep])
    np.testing.assert_array_equal(back[~keep], lab[~keep])
    # a ceiling that climbs: wall pixels above the new boundary become ceiling
    up = move_ceiling_boundary(lab, truth + 3, wall)
    assert np.all(up[np.arange(lab.shape[1]) * 0 + (truth + 1).astype(int), np.arange(lab.shape[1])] == 2)
    # NaN columns are left alone
    nan_v = truth + 5
    nan_v[:50] = np.nan
    np.testing.assert_array_equal(move_ceiling_boundary(lab, nan_v, wall)[:, :50], lab[:, :50])


def test_moved_boundary_splits_rows_at_pixel_centres_like_the_renderer():
    # continuous boundary rows (the network's kind) put back into labels crept off them give the rendered labels:
    # a pixel row is ceiling when its centre lies above the boundary (labels_from_boundaries' rule); rounding the
    # boundary up instead leaves the rows whose centre is just below it ceiling
    b = room_boundaries(L_ROOM, 2.7, [0.0, 0.0], 1.5, 512)
    lab = labels_from_boundaries(b)
    frac = b.ceil_v - np.floor(b.ceil_v)
    assert np.count_nonzero((frac > 0.05) & (frac < 0.45)) > 50  # columns where the two rules differ
    wall = lab[lab.shape[0] // 2 - 1]
    crept = move_ceiling_boundary(lab, b.ceil_v + 4.0, wall)
    np.testing.assert_array_equal(move_ceiling_boundary(crept, b.ceil_v, wall), lab)


def test_bad_shapes_raise_value_errors():
    with pytest.raises(ValueError, match="edges"):
        ceiling_edge_path(np.zeros((8, 16)), np.zeros(15))
    with pytest.raises(ValueError, match="new_v"):
        move_ceiling_boundary(np.zeros((8, 16), np.uint8), np.zeros(15), np.zeros(16))
    with pytest.raises(ValueError, match="labels"):
        move_ceiling_boundary(np.zeros(16, np.uint8), np.zeros(16), np.zeros(16))
    with pytest.raises(ValueError, match="pano"):
        edge_strength(np.zeros((8, 8, 3), np.uint8), (8, 16))


def test_estimate_surfaces_snaps_the_ceiling_onto_a_visible_junction():
    lab, pano = rendered(512)
    truth = true_ceiling_rows(lab)
    # shade the top 12 rows of the walls over half the panorama: GC's boundary slips, the junction stays the
    # strongest step (ceiling 215 -> shade 175 -> wall 150 or 120)
    dim = pano.copy()
    h = lab.shape[0]
    cols = slice(0, 256)
    rows = np.arange(h)[:, None]
    band = (rows >= truth[None, cols]) & (rows < truth[None, cols] + 12) & (lab[:, cols] >= 3)
    dim[:, cols][band] = 175
    off = estimate_surfaces(dim)  # the default: no snap
    on = estimate_surfaces(dim, snap_ceiling=True)
    err_off = np.abs(off.columns.ceiling_v - truth)
    err_on = np.abs(on.columns.ceiling_v - truth)
    assert np.mean(err_on <= 1.5) > np.mean(err_off <= 1.5) + 0.5
    assert np.mean(err_on) < 0.75 * np.mean(err_off)
    # the label map and the columns agree on where the ceiling ends: no wall above it, no ceiling below it
    v = on.columns.ceiling_v[None, :]
    for m in (on.labels, on.layout):
        assert not ((rows < v) & ((m == 3) | (m == 4))).any()
        assert not ((rows >= v) & (rows < h // 2) & (m == 2)).any()
