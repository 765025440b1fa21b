"""Tests of layout.polygon: areas, containment, distances, clipping, validity."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from layout.polygon import (
    outside_fraction,
    as_ccw,
    closest_segment,
    convex_in_polygon,
    convex_intersection_area,
    distance_to_boundary,
    has_repeated_vertex,
    is_ccw,
    is_manhattan,
    is_simple,
    oriented_rectangles,
    points_in_polygon,
    polygon_problems,
    project_to_segments,
    signed_area,
    validate_floor_polygon,
    wall_direction,
    wall_segments,
)

L_SHAPE = np.array([[0, 0], [4, 0], [4, 2], [2, 2], [2, 4], [0, 4]], float)
U_SHAPE = np.array([[0, 0], [5, 0], [5, 4], [3.5, 4], [3.5, 1.5], [1.5, 1.5], [1.5, 4], [0, 4]], float)


def in_l_shape(p: np.ndarray) -> np.ndarray:
    x, y = p[..., 0], p[..., 1]
    return (x > 0) & (y > 0) & (x < 4) & (y < 4) & ~((x > 2) & (y > 2))


def _in_convex(grid: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Independent membership for a CCW convex polygon: left of every edge."""
    a, b = poly, np.roll(poly, -1, axis=0)
    cross = (b[:, 0] - a[:, 0]) * (grid[:, None, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (grid[:, None, 0] - a[:, 0])
    return np.all(cross >= 0, axis=1)


def raster_area(poly_a: np.ndarray, poly_b: np.ndarray, n: int = 1000) -> float:
    """Brute force: fraction of a fine grid inside both convex polygons."""
    both = np.concatenate([poly_a, poly_b])
    lo, hi = both.min(axis=0), both.max(axis=0)
    xs = lo[0] + (np.arange(n) + 0.5) * (hi[0] - lo[0]) / n
    ys = lo[1] + (np.arange(n) + 0.5) * (hi[1] - lo[1]) / n
    grid = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
    inside = _in_convex(grid, poly_a)
    inside[inside] = _in_convex(grid[inside], poly_b)
    return float(inside.mean() * (hi[0] - lo[0]) * (hi[1] - lo[1]))


def test_signed_area_and_orientation():
    assert signed_area(L_SHAPE) == pytest.approx(12.0)
    cw = L_SHAPE[::-1]
    assert signed_area(cw) == pytest.approx(-12.0)
    assert bool(is_ccw(L_SHAPE)) and not bool(is_ccw(cw))
    fixed = as_ccw(cw)
    assert signed_area(fixed) == pytest.approx(12.0)
    assert np.array_equal(fixed[0], cw[0])
    # batched
    batch = np.stack([L_SHAPE, cw, L_SHAPE * 2])
    assert np.allclose(signed_area(batch), [12, -12, 48])


def test_area_is_translation_invariant_far_from_origin():
    assert signed_area(L_SHAPE + 1e6) == pytest.approx(12.0, abs=1e-6)


def test_points_in_polygon_matches_analytic_l_shape():
    rng = np.random.default_rng(0)
    pts = rng.uniform(-0.5, 4.5, size=(5000, 2))
    assert np.array_equal(points_in_polygon(pts, L_SHAPE), in_l_shape(pts))
    assert np.array_equal(points_in_polygon(pts, L_SHAPE[::-1]), in_l_shape(pts))
    # any leading shape
    assert points_in_polygon(pts.reshape(50, 100, 2), L_SHAPE).shape == (50, 100)


def test_points_in_polygon_margin():
    pts = np.array([[1.0, 1.0], [0.3, 1.0], [-0.2, 1.0], [3.0, 2.2], [3.0, 1.6]])
    assert points_in_polygon(pts, L_SHAPE, margin=0.5).tolist() == [True, False, False, False, False]
    assert points_in_polygon(pts, L_SHAPE, margin=-0.25).tolist() == [True, True, True, True, True]
    assert points_in_polygon(pts, L_SHAPE, margin=-0.1).tolist() == [True, True, False, False, True]


def test_project_to_segments_brute_force():
    rng = np.random.default_rng(1)
    starts = rng.uniform(-3, 3, size=(7, 2))
    ends = rng.uniform(-3, 3, size=(7, 2))
    pts = rng.uniform(-4, 4, size=(40, 2))
    proj = project_to_segments(pts, starts, ends)
    t = np.linspace(0, 1, 20001)
    samples = starts[:, None, :] + t[None, :, None] * (ends - starts)[:, None, :]  # (7, T, 2)
    brute = np.sqrt(((pts[:, None, None, :] - samples[None]) ** 2).sum(-1)).min(-1)
    assert np.allclose(proj.distance, brute, atol=1e-3)
    assert np.all((proj.t >= 0) & (proj.t <= 1))
    recon = np.sqrt(((pts[:, None, :] - proj.closest) ** 2).sum(-1))
    assert np.allclose(recon, proj.distance)


def test_project_to_degenerate_segment():
    proj = project_to_segments([[1.0, 1.0]], [[0.0, 0.0]], [[0.0, 0.0]])
    assert proj.distance[0, 0] == pytest.approx(np.sqrt(2))
    assert proj.t[0, 0] == 0.0


def test_closest_segment_and_distance_to_boundary():
    idx, d, c = closest_segment([[3.0, 1.9], [1.0, 3.9], [0.2, 2.0]], L_SHAPE)
    assert idx.tolist() == [2, 4, 5]
    assert np.allclose(d, [0.1, 0.1, 0.2])
    assert np.allclose(c, [[3.0, 2.0], [1.0, 4.0], [0.0, 2.0]])
    assert np.allclose(distance_to_boundary([[3.0, 1.9], [2.5, 2.5]], L_SHAPE), [0.1, 0.5])


@pytest.mark.parametrize("poly", [L_SHAPE, L_SHAPE[::-1], U_SHAPE])
def test_wall_normals_point_inward(poly):
    w = wall_segments(poly)
    assert len(w) == len(poly)
    assert np.allclose(np.linalg.norm(w.normal, axis=1), 1)
    assert np.allclose((w.normal * w.direction).sum(1), 0)
    probe = w.midpoint + 1e-3 * w.normal
    assert points_in_polygon(probe, poly).all()
    assert not points_in_polygon(w.midpoint - 1e-3 * w.normal, poly).any()
    assert np.allclose(w.length, np.linalg.norm(np.roll(poly, -1, 0) - poly, axis=1))


def test_wall_segments_rejects_zero_length_edge():
    with pytest.raises(ValueError, match="zero-length"):
        wall_segments([[0, 0], [1, 0], [1, 0], [0, 1]])


def test_oriented_rectangles():
    r = oriented_rectangles([[1.0, 2.0]], [np.pi / 2], [[2.0, 1.0]])[0]
    assert signed_area(r) == pytest.approx(2.0)
    # the front edge (corners 0, 1) lies along +y from the centre
    front_mid = r[:2].mean(axis=0)
    assert np.allclose(front_mid, [1.0, 3.0])
    with pytest.raises(ValueError, match="positive"):
        oriented_rectangles([0, 0], 0.0, [0.0, 1.0])


def test_convex_intersection_exact_cases():
    sq = oriented_rectangles([0.0, 0.0], 0.0, [2.0, 2.0])
    assert convex_intersection_area(sq, sq) == pytest.approx(4.0)
    assert convex_intersection_area(sq, sq + [2.0, 0.0]) == pytest.approx(0.0, abs=1e-12)  # touching
    assert convex_intersection_area(sq, sq + [3.0, 0.0]) == 0.0
    assert convex_intersection_area(sq, sq + [1.0, 0.0]) == pytest.approx(2.0)  # shared top/bottom edges
    small = oriented_rectangles([0.3, -0.2], 0.7, [0.5, 0.4])
    assert convex_intersection_area(sq, small) == pytest.approx(0.2)  # contained
    assert convex_intersection_area(small, sq) == pytest.approx(0.2)
    flush = oriented_rectangles([0.5, 0.0], 0.0, [1.0, 2.0])  # shares three edges with sq
    assert convex_intersection_area(sq, flush) == pytest.approx(2.0)
    diamond = oriented_rectangles([0.0, 0.0], np.pi / 4, [2.0, 2.0])
    assert convex_intersection_area(sq, diamond) == pytest.approx(8 * (np.sqrt(2) - 1))


def test_convex_intersection_matches_raster_within_one_percent():
    rng = np.random.default_rng(2)
    checked = 0
    for _ in range(30):
        a = oriented_rectangles(rng.uniform(-0.5, 0.5, 2), rng.uniform(0, 2 * np.pi), rng.uniform(0.3, 2.0, 2))
        b = oriented_rectangles(rng.uniform(-0.5, 0.5, 2), rng.uniform(0, 2 * np.pi), rng.uniform(0.3, 2.0, 2))
        exact = float(convex_intersection_area(a, b))
        if exact < 0.05:
            continue
        assert exact == pytest.approx(raster_area(a, b, n=500), rel=0.01)
        checked += 1
    assert checked >= 15


def test_convex_intersection_general_convex_and_batch():
    angles = np.linspace(0, 2 * np.pi, 7)[:-1]
    hexagon = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    tri = np.array([[-1.0, -0.5], [1.5, -0.2], [0.0, 1.2]])
    exact = float(convex_intersection_area(hexagon, tri))
    assert exact == pytest.approx(raster_area(hexagon, tri), rel=0.01)
    batch = convex_intersection_area(np.stack([hexagon, hexagon]), np.stack([tri, tri + 5]))
    assert batch.shape == (2,) and batch[0] == pytest.approx(exact) and batch[1] == 0.0
    with pytest.raises(ValueError, match="counter-clockwise"):
        convex_intersection_area(hexagon[::-1], tri)


@settings(max_examples=60, deadline=None)
@given(
    st.floats(-1, 1),
    st.floats(-1, 1),
    st.floats(0, 2 * np.pi),
    st.floats(0.2, 2.0),
    st.floats(0.2, 2.0),
)
def test_convex_intersection_properties(x, y, yaw, l, w):
    a = oriented_rectangles([0.0, 0.0], 0.3, [1.5, 1.0])
    b = oriented_rectangles([x, y], yaw, [l, w])
    ab = float(convex_intersection_area(a, b))
    assert ab == pytest.approx(float(convex_intersection_area(b, a)), abs=1e-9)
    assert -1e-12 <= ab <= min(1.5, l * w) + 1e-9
    # rigid motion of both leaves the area unchanged
    rot = np.array([[0.0, -1.0], [1.0, 0.0]])
    assert float(convex_intersection_area(a @ rot.T + 3, b @ rot.T + 3)) == pytest.approx(ab, abs=1e-9)


def test_convex_in_polygon_cases():
    boxes = oriented_rectangles(
        [[1.0, 1.0], [0.5, 3.5], [3.0, 3.0], [2.5, 1.5], [2.2, 2.2], [1.0, 1.0]],
        [0.0, 0.0, 0.0, 0.0, 0.0, np.pi / 4],
        [[1.0, 1.0], [1.0, 1.0], [1.0, 1.0], [1.0, 1.0], [1.0, 1.0], [2.9, 0.5]],
    )
    # flush in a corner, flush at the top of the arm, outside, inside, across the reflex corner, through a wall
    assert convex_in_polygon(boxes, L_SHAPE).tolist() == [True, True, False, True, False, False]


def test_convex_in_polygon_gap_with_corners_on_boundary():
    gap = np.array([[1.5, 1.5], [3.5, 1.5], [3.5, 4.0], [1.5, 4.0]])  # the U's gap: all corners on the boundary
    assert not bool(convex_in_polygon(gap, U_SHAPE))
    base = np.array([[0.0, 0.0], [5.0, 0.0], [5.0, 1.5], [0.0, 1.5]])  # the U's base, flush on three sides
    assert bool(convex_in_polygon(base, U_SHAPE))


def test_convex_in_polygon_agrees_with_sampling():
    rng = np.random.default_rng(3)
    n = 400
    rects = oriented_rectangles(rng.uniform(0, 4, (n, 2)), rng.uniform(0, 2 * np.pi, n), rng.uniform(0.2, 1.5, (n, 2)))
    exact = convex_in_polygon(rects, L_SHAPE)
    u = np.linspace(0, 1, 25)
    wts = np.stack(np.meshgrid(u, u), -1).reshape(-1, 2)
    # points of each rectangle: bilinear combination of its corners
    c = rects
    pts = (
        (1 - wts[:, 0, None]) * (1 - wts[:, 1, None]) * c[:, None, 0]
        + wts[:, 0, None] * (1 - wts[:, 1, None]) * c[:, None, 1]
        + wts[:, 0, None] * wts[:, 1, None] * c[:, None, 2]
        + (1 - wts[:, 0, None]) * wts[:, 1, None] * c[:, None, 3]
    )
    sampled = points_in_polygon(pts, L_SHAPE, margin=-1e-9).all(axis=1)
    assert np.all(sampled[exact])  # exact True -> every sample inside
    assert np.mean(exact == sampled) > 0.98
    assert 0.1 < exact.mean() < 0.9


def test_validity_checks():
    assert has_repeated_vertex([[0, 0], [1, 0], [1, 1], [0, 0]])
    assert not has_repeated_vertex(L_SHAPE)
    assert is_manhattan(L_SHAPE, axis_aligned=True)
    rot = L_SHAPE @ np.array([[np.cos(0.3), -np.sin(0.3)], [np.sin(0.3), np.cos(0.3)]]).T
    assert is_manhattan(rot) and not is_manhattan(rot, axis_aligned=True)
    assert not is_manhattan([[0, 0], [2, 0], [2, 1], [0.5, 1.2]])
    assert is_simple(L_SHAPE) and is_simple(U_SHAPE)
    assert not is_simple([[0, 0], [2, 0], [2, 2], [1, 2], [1, -1], [0, -1]])  # crosses itself
    # non-adjacent edges touching at a point (pinched polygon)
    assert not is_simple([[0, 0], [4, 0], [4, 2], [3, 2], [2, 0], [1, 2], [0, 2]])
    assert not is_simple([[0, 0], [2, 0], [1, 0], [1, 1]])  # folds back


def test_polygon_problems_and_validate():
    assert polygon_problems(L_SHAPE) == []
    assert any("counter-clockwise" in p for p in polygon_problems(L_SHAPE[::-1]))
    assert any("repeated vertex" in p for p in polygon_problems(np.vstack([L_SHAPE, L_SHAPE[:1]])))
    assert any("not simple" in p for p in polygon_problems([[0, 0], [2, 0], [2, 2], [1, 2], [1, -1], [0, -1]]))
    assert any("shorter than" in p for p in polygon_problems(L_SHAPE, min_edge=2.5))
    with pytest.raises(ValueError, match="not orthogonal"):
        validate_floor_polygon([[0, 0], [2, 0], [2, 1], [0.5, 1.2]])
    assert polygon_problems([[0, 0], [2, 0], [2, 1], [0.5, 1.2]], manhattan=False) == []


@pytest.mark.parametrize("bad", [np.zeros((2, 2)), np.zeros((4, 3)), [[0, 0], [1, np.nan], [1, 1]]])
def test_bad_polygon_input(bad):
    with pytest.raises(ValueError, match="expected"):
        signed_area(bad)


def test_bad_points_input():
    with pytest.raises(ValueError, match=r"\(\.\.\., 2\)"):
        points_in_polygon(np.zeros((3, 3)), L_SHAPE)
    with pytest.raises(ValueError, match="single polygon"):
        points_in_polygon([0.0, 0.0], np.stack([L_SHAPE, L_SHAPE]))


def test_outside_fraction_matches_area_in_an_l_shape():
    # a 2 x 2 footprint centred on the inner corner of the L: a quarter of it is outside
    quads = oriented_rectangles(np.array([[2.0, 2.0], [1.0, 1.0], [5.0, 1.0]]), np.zeros(3), np.full((3, 2), 2.0))
    share = outside_fraction(quads, L_SHAPE, samples=20)
    np.testing.assert_allclose(share, [0.25, 0.0, 1.0], atol=1e-9)
    # turned by 90 degrees the same footprint covers the same area; batched over leading axes
    assert outside_fraction(oriented_rectangles([2.0, 2.0], np.pi / 2, [2.0, 2.0]), L_SHAPE, samples=20) == 0.25
    assert outside_fraction(quads[None], L_SHAPE).shape == (1, 3)


def test_outside_fraction_margin_and_errors():
    touching = oriented_rectangles([4.05, 1.0], 0.0, [0.2, 0.2])  # half of it 0 - 0.15 m through the wall x = 4
    assert outside_fraction(touching, L_SHAPE, samples=20) == pytest.approx(0.75)
    assert outside_fraction(touching, L_SHAPE, samples=10, margin=0.2) == 0.0
    with pytest.raises(ValueError, match="quads"):
        outside_fraction(np.zeros((3, 2)), L_SHAPE)
    with pytest.raises(ValueError, match="margin"):
        outside_fraction(touching, L_SHAPE, margin=-1.0)
    with pytest.raises(ValueError, match="samples"):
        outside_fraction(touching, L_SHAPE, samples=0)


@pytest.mark.parametrize("shape", [L_SHAPE, U_SHAPE], ids=["L", "U"])
@pytest.mark.parametrize("turn_deg", [0.0, 10.0, 44.0, -30.0, 90.0, 135.0])
def test_wall_direction_of_turned_polygons(shape, turn_deg):
    t = np.radians(turn_deg)
    c, s = np.cos(t), np.sin(t)
    turned = (shape - [1.0, 2.0]) @ np.array([[c, s], [-s, c]])
    got = wall_direction(turned)
    assert -np.pi / 4 <= got < np.pi / 4
    want = (t + np.pi / 4) % (np.pi / 2) - np.pi / 4
    assert abs(got - want) < 1e-9
    assert abs(wall_direction(turned[::-1]) - want) < 1e-9  # the orientation of the outline does not matter


def test_wall_direction_weights_edges_by_length():
    """Two 10 m walls 2 degrees off the x axis, two 1 m walls along y: the mean lies near the long walls."""
    room = np.array([[0.0, 0.0], [10.0, 0.35], [10.0, 1.35], [0.0, 1.0]])  # the long sides rise 0.35 m over 10 m
    got = np.degrees(wall_direction(room))
    assert 1.5 < got < 2.0
    with pytest.raises(ValueError):
        wall_direction(np.zeros((2, 3, 2)) + [[0, 0], [1, 0], [1, 1]])
