"""benchmarks/_hidden_walls.py: which rooms' corner count their panorama shows.

Views are made by casting rays from the camera against the floor polygon (no furniture): a wall point where each
ray meets the room, floor points along the ray before it.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

from layout.polygon import as_ccw, ray_hits

_PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "_hidden_walls.py"
_spec = importlib.util.spec_from_file_location("benchmarks_hidden_walls", _PATH)
hw = importlib.util.module_from_spec(_spec)
sys.modules[_spec.name] = hw  # dataclasses look their module up there
_spec.loader.exec_module(hw)

# room-0001 of the seed-0 set: a U whose upper arm lies behind the wall y = 2.27 at every angle from the camera
U_HIDDEN_ARM = [[5.26, 6.61], [-2.31, 6.61], [-2.31, 4.87], [3.2, 4.87], [3.2, 2.27], [-2.31, 2.27],
                [-2.31, -0.67], [5.26, -0.67]]
L_ALL_SEEN = [[-1.0, -1.5], [3.0, -1.5], [3.0, 0.5], [1.0, 0.5], [1.0, 2.0], [-1.0, 2.0]]


def ray_view(polygon, n=2048) -> "hw.ViewPoints":
    p = as_ccw(np.asarray(polygon, float))
    lon = (np.arange(n) + 0.5) * 2 * np.pi / n
    d = np.stack([np.cos(lon), np.sin(lon)], axis=1)
    dist, edge = ray_hits(p, d)
    q = np.roll(p, -1, axis=0)[edge]
    along_x = np.abs(q[:, 0] - p[edge, 0]) > np.abs(q[:, 1] - p[edge, 1])
    wall = d * dist[:, None]
    floor = (np.linspace(0.2, 0.95, 8)[:, None, None] * wall[None]).reshape(-1, 2)
    return hw.ViewPoints(inside=np.vstack([floor, wall]), wall=wall,
                         wall_label=np.where(along_x, 4, 3).astype(np.uint8), wall_column=np.arange(n))


def test_a_hidden_arm_leaves_the_corner_count_open():
    p = as_ccw(np.asarray(U_HIDDEN_ARM))
    view = ray_view(p)
    seen = hw.seen_walls(p, view)
    assert seen.sum() == 4 and hw.hidden_runs(seen) and max(k for _, k in hw.hidden_runs(seen)) == 4
    assert hw.explains_view(p, view)
    assert not hw.corner_count_shown(p, view)
    # the polygon that explains the view as well: the corridor closed where the arm starts, 6 corners
    assert any(len(q) == 6 and hw.explains_view(q, view) for f, k in hw.hidden_runs(seen)
               for q in hw.fewer_wall_polygons(p, f, k))


def test_a_room_seen_whole_shows_its_corner_count():
    p = as_ccw(np.asarray(L_ALL_SEEN))
    view = ray_view(p)
    assert hw.seen_walls(p, view).all()
    assert hw.hidden_runs(hw.seen_walls(p, view)) == []
    assert hw.corner_count_shown(p, view)


def test_a_polygon_that_hides_seen_points_does_not_explain_the_view():
    view = ray_view(L_ALL_SEEN)
    rect = [[-1.0, -1.5], [3.0, -1.5], [3.0, 0.5], [-1.0, 0.5]]  # cuts off the seen upper arm
    assert not hw.explains_view(as_ccw(np.asarray(rect)), view)
    assert not hw.explains_view(np.asarray(L_ALL_SEEN)[::-1], view)  # clockwise


@pytest.mark.parametrize("seen, runs", [([True] * 4, []), ([False] * 4, []),
                                        ([False, True, True, False], [(3, 2)])])
def test_hidden_runs_wrap_around(seen, runs):
    assert hw.hidden_runs(seen) == runs
