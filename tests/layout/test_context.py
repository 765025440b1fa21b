"""Tests of layout.context: the context prior E_ow + mu * E_oo."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from layout.context import alignment_cost, context_energy, context_prior, pair_overlap_areas
from layout.polygon import oriented_rectangles

ROOM = np.array([[0, 0], [4, 0], [4, 3], [0, 3]], float)
L_ROOM = np.array([[0, 0], [6, 0], [6, 2], [3, 2], [3, 5], [0, 5]], float)


def raster_overlap(centers, yaws, sizes, n=700):
    """Brute force E_oo: sum over pairs of grid cells inside both footprints."""
    rects = oriented_rectangles(centers, yaws, sizes)
    lo, hi = rects.reshape(-1, 2).min(0), rects.reshape(-1, 2).max(0)
    xs = lo[0] + (np.arange(n) + 0.5) * (hi[0] - lo[0]) / n
    ys = lo[1] + (np.arange(n) + 0.5) * (hi[1] - lo[1]) / n
    grid = np.stack(np.meshgrid(xs, ys), -1).reshape(-1, 2)
    cell = (hi[0] - lo[0]) * (hi[1] - lo[1]) / n**2
    masks = []
    for r in rects:
        a, b = r, np.roll(r, -1, 0)
        cross = (b[:, 0] - a[:, 0]) * (grid[:, None, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (grid[:, None, 0] - a[:, 0])
        masks.append(np.all(cross >= 0, axis=1))
    total = 0.0
    for j in range(len(rects)):
        for k in range(j + 1, len(rects)):
            total += np.count_nonzero(masks[j] & masks[k]) * cell
    return total


def test_hand_checked_wall_terms():
    # bed 2 x 1.6 m, centre 1 m from the wall x = 0 (1.5 m from y = 0 and y = 3)
    e = context_energy([[1.0, 1.5]], [0.0], [[2.0, 1.6]], ROOM)
    assert e.closest_wall.tolist() == [3]
    assert e.distance.tolist() == [1.0]
    assert np.allclose(e.wall_point, [[0.0, 1.5]])
    assert e.alignment.tolist() == [0.0]  # facing into the room: aligned
    assert float(e.total) == pytest.approx(1.0)
    assert float(e.prior) == pytest.approx(np.exp(-1.0))
    # turned by 30 degrees: 1 - cos 30
    e30 = context_energy([[1.0, 1.5]], [np.radians(30)], [[2.0, 1.6]], ROOM)
    assert float(e30.total) == pytest.approx(1.0 + 10 * (1 - np.cos(np.radians(30))))
    # facing the wall: aligned for "parallel", worst for "facing"
    e180 = context_energy([[1.0, 1.5]], [np.pi], [[2.0, 1.6]], ROOM)
    assert float(e180.total) == pytest.approx(1.0)
    e180f = context_energy([[1.0, 1.5]], [np.pi], [[2.0, 1.6]], ROOM, alignment="facing")
    assert float(e180f.total) == pytest.approx(1.0 + 10 * 2.0)
    # the printed term |n_o . n_w|: the aligned bed is penalised most
    lit = context_energy([[1.0, 1.5]], [0.0], [[2.0, 1.6]], ROOM, alignment="literal")
    assert float(lit.total) == pytest.approx(11.0)


def test_reflex_corner_tie_takes_the_better_aligned_wall():
    # (2.5, 1.5) in L_ROOM is nearest to the reflex corner (3, 2), shared by two walls
    for yaw in (0.0, np.pi / 2, np.pi, 1.5 * np.pi):
        e = context_energy([[2.5, 1.5]], [yaw], [[0.5, 0.5]], L_ROOM)
        assert e.distance[0] == pytest.approx(np.hypot(0.5, 0.5))
        assert e.alignment[0] == pytest.approx(0.0, abs=1e-12)
        shifted = context_energy([[2.5 + 7.3, 1.5 - 2.1]], [yaw], [[0.5, 0.5]], L_ROOM + [7.3, -2.1])
        assert float(shifted.total) == pytest.approx(float(e.total))


def test_closest_point_on_segment_vs_wall_midpoint():
    # object near the right end of the bottom wall of a 4 x 3 room
    c = [[3.5, 0.4]]
    e = context_energy(c, [np.pi / 2], [[0.5, 0.5]], ROOM)
    assert e.closest_wall.tolist() == [0] and e.distance[0] == pytest.approx(0.4)
    m = context_energy(c, [np.pi / 2], [[0.5, 0.5]], ROOM, wall_point="midpoint")
    # midpoints: (2, 0) at 1.552, (4, 1.5) at 1.208 -> the right wall's midpoint
    assert m.closest_wall.tolist() == [1]
    assert m.distance[0] == pytest.approx(np.hypot(0.5, 1.1))
    assert np.allclose(m.wall_point, [[4.0, 1.5]])


def test_axis_mode_and_weights_and_anchor():
    yaw = [np.pi / 2]  # sideways to the left wall
    e = context_energy([[1.0, 1.5]], yaw, [[2.0, 1.6]], ROOM, alignment="axis")
    assert float(e.alignment[0]) == pytest.approx(0.0, abs=1e-12)
    e45 = context_energy([[1.0, 1.5]], [np.pi / 4], [[2.0, 1.6]], ROOM, alignment="axis")
    assert float(e45.alignment[0]) == pytest.approx(1 - np.sqrt(0.5))
    w0 = context_energy([[1.0, 1.5]], [0.7], [[2.0, 1.6]], ROOM, alignment_weights=[0.0])
    assert float(w0.total) == pytest.approx(1.0)
    # anchor at the middle of the back edge: headboard on the wall -> distance 0
    back = context_energy([[1.0, 1.5]], [0.0], [[2.0, 1.6]], ROOM, anchor_offsets=[-1.0])
    assert float(back.total) == pytest.approx(0.0, abs=1e-12)


def test_alignment_cost_modes():
    d = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]])
    n = np.array([1.0, 0.0])
    assert alignment_cost(d, n, "parallel").tolist() == [0.0, 1.0, 0.0]
    assert alignment_cost(d, n, "facing").tolist() == [0.0, 1.0, 2.0]
    assert alignment_cost(d, n, "axis").tolist() == [0.0, 0.0, 0.0]
    assert alignment_cost(d, n, "literal").tolist() == [1.0, 0.0, 1.0]
    with pytest.raises(ValueError, match="alignment mode"):
        alignment_cost(d, n, "up")  # type: ignore[arg-type]


def test_overlap_matches_raster_within_one_percent():
    rng = np.random.default_rng(0)
    for _ in range(4):
        c = rng.uniform(0.5, 2.0, size=(4, 2))
        y = rng.uniform(0, 2 * np.pi, size=4)
        s = rng.uniform(0.5, 1.8, size=(4, 2))
        e = context_energy(c, y, s, L_ROOM)
        brute = raster_overlap(c, y, s)
        assert brute > 0.1
        assert float(e.overlap) == pytest.approx(brute, rel=0.01)
        assert float(e.total) == pytest.approx(float(e.wall) + 0.25 * float(e.overlap))


def test_pair_overlap_matrix():
    c = np.array([[0.0, 0.0], [1.0, 0.0], [5.0, 5.0]])
    m = pair_overlap_areas(c, np.zeros(3), np.full((3, 2), 2.0))
    assert np.allclose(m, m.T) and np.all(np.diag(m) == 0)
    assert m[0, 1] == pytest.approx(2.0) and m[0, 2] == 0 and m[1, 2] == 0


def test_batch_equals_loop():
    rng = np.random.default_rng(1)
    b, n_o = 64, 5
    c = rng.uniform(0.2, 4.5, size=(b, n_o, 2))
    y = rng.uniform(0, 2 * np.pi, size=(b, n_o))
    s = rng.uniform(0.3, 2.0, size=(n_o, 2))
    modes = ["facing", "parallel", "axis", "literal", "parallel"]
    opts = dict(alignment=modes, alignment_weights=[1, 1, 0.5, 1, 0], anchor_offsets=-0.5 * s[:, 0])
    batch = context_energy(c, y, s, L_ROOM, **opts)
    assert batch.total.shape == (b,) and batch.per_object.shape == (b, n_o)
    assert batch.pair_overlap.shape == (b, n_o, n_o)
    for i in range(b):
        one = context_energy(c[i], y[i], s, L_ROOM, **opts)
        for name in ("total", "wall", "overlap", "distance", "alignment", "pair_overlap", "per_object", "wall_point"):
            assert np.allclose(getattr(batch, name)[i], getattr(one, name), atol=1e-12), name
        assert np.array_equal(batch.closest_wall[i], one.closest_wall)
    assert np.allclose(batch.per_object.sum(-1), batch.total)
    assert np.allclose(batch.prior, np.exp(-batch.total))
    assert np.allclose(context_prior(c, y, s, L_ROOM, **opts), batch.prior)


def test_per_hypothesis_floors_equal_loop():
    rng = np.random.default_rng(2)
    b = 10
    scale = rng.uniform(0.8, 1.3, size=b)
    floors = L_ROOM[None] * scale[:, None, None]
    c = rng.uniform(0.5, 3, size=(b, 3, 2))
    y = rng.uniform(0, 6, size=(b, 3))
    s = np.array([[2.0, 1.6], [0.5, 0.5], [0.3, 1.1]])
    batch = context_energy(c, y, s, floors)
    loop = [float(context_energy(c[i], y[i], s, floors[i]).total) for i in range(b)]
    assert np.allclose(batch.total, loop)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 3), st.floats(-5, 5), st.floats(-5, 5), st.integers(0, 10_000))
def test_energy_invariant_under_room_symmetries(k, tx, ty, seed):
    """Rotating the whole scene by k * 90 degrees and translating it changes nothing."""
    rng = np.random.default_rng(seed)
    c = rng.uniform(0.3, 2.7, size=(4, 2))
    y = rng.uniform(0, 2 * np.pi, size=4)
    s = rng.uniform(0.3, 1.5, size=(4, 2))
    rot = np.linalg.matrix_power(np.array([[0.0, -1.0], [1.0, 0.0]]), k)
    t = np.array([tx, ty])
    e0 = context_energy(c, y, s, L_ROOM, alignment="facing")
    e1 = context_energy(c @ rot.T + t, y + k * np.pi / 2, s, L_ROOM @ rot.T + t, alignment="facing")
    assert float(e1.total) == pytest.approx(float(e0.total), abs=1e-9)


def test_input_validation():
    with pytest.raises(ValueError, match=r"centers of shape"):
        context_energy(np.zeros(3), np.zeros(3), np.ones((3, 2)), ROOM)
    with pytest.raises(ValueError, match="yaws of shape"):
        context_energy(np.zeros((2, 2)), np.zeros(3), np.ones((2, 2)), ROOM)
    with pytest.raises(ValueError, match="sizes of shape"):
        context_energy(np.zeros((2, 2)), np.zeros(2), np.ones((3, 2)), ROOM)
    with pytest.raises(ValueError, match="positive footprint"):
        context_energy(np.zeros((2, 2)), np.zeros(2), np.zeros((2, 2)), ROOM)
    with pytest.raises(ValueError, match="alignment modes"):
        context_energy(np.zeros((2, 2)), np.zeros(2), np.ones((2, 2)), ROOM, alignment=["facing", "sideways"])
    with pytest.raises(ValueError, match="one alignment mode or 2"):
        context_energy(np.zeros((2, 2)), np.zeros(2), np.ones((2, 2)), ROOM, alignment=["facing"])
    with pytest.raises(ValueError, match="nu_n >= 0"):
        context_energy(np.zeros((2, 2)), np.zeros(2), np.ones((2, 2)), ROOM, nu_n=-1.0)
    with pytest.raises(ValueError, match="wall_point"):
        context_energy(np.zeros((2, 2)), np.zeros(2), np.ones((2, 2)), ROOM, wall_point="centre")  # type: ignore
    with pytest.raises(ValueError, match="floor"):
        context_energy(np.zeros((2, 2)), np.zeros(2), np.ones((2, 2)), np.zeros((2, 2)))
    with pytest.raises(ValueError, match="finite centers"):
        context_energy(np.full((2, 2), np.nan), np.zeros(2), np.ones((2, 2)), ROOM)
