"""Tests of layout.rooms: templates, the paper's perturbation, determinism."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from layout.polygon import is_manhattan, polygon_problems, signed_area
from layout.rooms import TEMPLATE_NAMES, Room, generate_room, generate_rooms, make_template, perturb_walls


@pytest.fixture(scope="module")
def many_rooms() -> list[Room]:
    return generate_rooms(400, 12345)


def _lengths(poly: np.ndarray) -> np.ndarray:
    return np.linalg.norm(np.roll(poly, -1, axis=0) - poly, axis=1)


@pytest.mark.parametrize("name", TEMPLATE_NAMES)
def test_templates_are_valid_floors(name):
    rng = np.random.default_rng(7)
    for _ in range(25):
        room = generate_room(rng, template=name)
        for poly in (room.floor, room.template_floor):
            assert polygon_problems(poly, min_edge=0.4) == []
            assert is_manhattan(poly, axis_aligned=True, tol=1e-9)
            assert signed_area(poly) > 0
        assert room.template == name
        assert room.floor.shape == room.template_floor.shape == (room.n_corners, 2)
        assert room.wall_lengths.min() >= 0.4
        ext = room.floor.max(0) - room.floor.min(0)
        assert np.all(ext >= 1.2) and np.all(ext <= 12.0)


def test_corner_counts_cover_4_to_12_and_more(many_rooms):
    counts = {r.n_corners for r in many_rooms}
    assert {4, 6, 8, 12} <= counts
    assert max(counts) >= 12
    per_template = {r.template for r in many_rooms}
    assert per_template == set(TEMPLATE_NAMES)


def test_expected_corner_counts_per_template():
    rng = np.random.default_rng(3)
    seen: dict[str, set[int]] = {n: set() for n in TEMPLATE_NAMES}
    for name in TEMPLATE_NAMES:
        for _ in range(40):
            seen[name].add(len(make_template(name, rng)))
    assert seen["rectangle"] == {4}
    assert seen["L"] == {6}
    assert seen["T"] == {8} and seen["U"] == {8}
    assert seen["plus"] == {12}
    assert seen["notched"] <= {8, 12, 16} and 8 in seen["notched"] and 12 in seen["notched"]
    assert seen["corridor"] == {4, 6, 8}


def test_corridor_width_and_rectangle_sides():
    rng = np.random.default_rng(4)
    for _ in range(40):
        c = generate_room(rng, template="corridor")
        if c.n_corners == 4:
            assert (c.floor.max(0) - c.floor.min(0)).min() >= 1.2 - 1e-9
        r = generate_room(rng, template="rectangle")
        sides = r.floor.max(0) - r.floor.min(0)
        assert np.all(sides >= 2.5 - 0.6 - 1e-9) and np.all(sides <= 8.0 + 0.6 + 1e-9)


def test_wall_height_distribution(many_rooms):
    h = np.array([r.ceiling_z for r in many_rooms])
    assert abs(h.mean() - 2.7) < 0.03
    assert abs(h.std(ddof=1) - 0.2) < 0.03


def test_offsets_uniform_and_only_on_long_walls(many_rooms):
    applied_offsets = []
    for r in many_rooms:
        tl = _lengths(r.template_floor)
        assert np.array_equal(r.offset_applied, tl > 0.7)
        assert np.all(r.offsets[~r.offset_applied] == 0.0)
        applied_offsets.append(r.offsets[r.offset_applied])
        # walls without offset keep their template length exactly
        assert np.allclose(_lengths(r.floor)[~r.offset_applied], tl[~r.offset_applied], atol=1e-9)
    off = np.concatenate(applied_offsets)
    assert off.size > 1000
    assert off.min() >= -0.3 and off.max() <= 0.3
    assert stats.kstest(off, "uniform", args=(-0.3, 0.6)).pvalue > 0.01
    n_short = sum(int((~r.offset_applied).sum()) for r in many_rooms)
    assert n_short > 20  # the templates do contain walls <= 0.7 m


def test_rectangle_offsets_add_up_per_axis():
    rng = np.random.default_rng(5)
    for _ in range(20):
        r = generate_room(rng, template="rectangle")
        tl, fl = _lengths(r.template_floor), _lengths(r.floor)
        for i in (0, 1):
            expected = tl[i] + r.offsets[i] + r.offsets[i + 2]
            assert fl[i] == pytest.approx(expected) and fl[i + 2] == pytest.approx(expected)


def test_each_wall_change_contains_its_own_offset():
    """Every length change is the wall's own offset plus offsets of parallel walls."""
    rng = np.random.default_rng(6)
    for _ in range(60):
        r = generate_room(rng)
        change = _lengths(r.floor) - _lengths(r.template_floor)
        e = np.roll(r.template_floor, -1, 0) - r.template_floor
        horiz = np.abs(e[:, 0]) > np.abs(e[:, 1])
        for i in np.flatnonzero(r.offset_applied):
            others = r.offsets[(horiz == horiz[i]) & (np.arange(r.n_corners) != i)]
            rest = change[i] - r.offsets[i]
            # rest is a sum of a subset of the parallel walls' offsets
            sums = {0.0}
            for o in others:
                sums |= {s + o for s in sums}
            assert min(abs(rest - s) for s in sums) < 1e-9


def test_perturb_walls_keeps_closure_and_order():
    base = make_template("plus", 1)
    out = perturb_walls(base, 2)
    assert out is not None
    floor, offsets, applied = out
    assert floor.shape == base.shape
    assert polygon_problems(floor, min_edge=0.4) == []
    assert applied.all()  # every wall of a plus is >= 1.2 m
    with pytest.raises(ValueError, match="axis-aligned"):
        perturb_walls(base @ np.array([[0.8, -0.6], [0.6, 0.8]]).T, 0)


def test_determinism():
    a = generate_room(99)
    b = generate_room(99)
    assert np.array_equal(a.floor, b.floor) and a.ceiling_z == b.ceiling_z and a.template == b.template
    assert np.array_equal(a.offsets, b.offsets)
    g1, g2 = np.random.default_rng(5), np.random.default_rng(5)
    r1 = [generate_room(g1).floor for _ in range(5)]
    r2 = [generate_room(g2).floor for _ in range(5)]
    assert all(np.array_equal(x, y) for x, y in zip(r1, r2))
    assert not np.array_equal(generate_room(1).floor, generate_room(2).floor)


def test_room_is_immutable_and_translates():
    r = generate_room(0)
    with pytest.raises(ValueError):
        r.floor[0, 0] = 5.0
    t = r.translated([1.0, -2.0])
    assert np.allclose(t.floor, r.floor + [1.0, -2.0])
    assert t.area == pytest.approx(r.area)
    assert np.array_equal(t.offsets, r.offsets)


def test_room_validation():
    with pytest.raises(ValueError, match="counter-clockwise"):
        Room(
            floor=np.array([[0, 0], [0, 3], [4, 3], [4, 0]], float),
            ceiling_z=2.7,
            template="rectangle",
            template_floor=np.zeros((4, 2)),
            offsets=np.zeros(4),
            offset_applied=np.zeros(4, bool),
        )
    with pytest.raises(ValueError, match="offsets"):
        Room(
            floor=np.array([[0, 0], [4, 0], [4, 3], [0, 3]], float),
            ceiling_z=2.7,
            template="rectangle",
            template_floor=np.zeros((4, 2)),
            offsets=np.zeros(3),
            offset_applied=np.zeros(4, bool),
        )


def test_bad_arguments():
    with pytest.raises(ValueError, match="template name"):
        generate_room(0, template="hexagon")
    with pytest.raises(ValueError, match="template name"):
        make_template("circle", 0)
    with pytest.raises(ValueError, match="seed"):
        generate_room("abc")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="height_std"):
        generate_room(0, height_std=-1.0)
    with pytest.raises(ValueError, match="non-negative"):
        generate_rooms(-1, 0)
