"""layout.objectwalls: a wall that several objects agree stand beyond moves out to them; the sampler uses it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from layout.likelihood import observe_labels, render_scene_labels, surface_likelihood
from layout.objectwalls import move_walls_to_objects
from layout.polygon import is_ccw, oriented_rectangles, polygon_problems
from layout.sampler import DetectedObject, SamplerConfig, map_estimate
from panogeom.project import world_box_to_pano

ROOM = np.array([[-2.0, -1.5], [3.0, -1.5], [3.0, 2.0], [-2.0, 2.0]])  # wall 1: x = 3


def feet(centers, sizes=(0.5, 0.5), yaws=0.0):
    c = np.asarray(centers, float)
    return oriented_rectangles(c, np.broadcast_to(yaws, len(c)), np.broadcast_to(sizes, c.shape))


def test_agreeing_objects_move_the_wall_to_the_nearest_of_them():
    # three objects 0.30, 0.35 and 0.38 m beyond x = 3 (their far edges at 3.30 .. 3.38)
    res = move_walls_to_objects(ROOM, feet([[3.05, 0.0], [3.10, 1.0], [3.13, -1.0]]))
    assert [(m.wall, m.objects) for m in res.moves] == [(1, (0, 1, 2))]
    assert math.isclose(res.moves[0].distance, 0.30, abs_tol=1e-9)
    assert np.allclose(res.floor[[1, 2], 0], 3.30) and np.allclose(res.floor[[0, 3], 0], -2.0)
    assert is_ccw(res.floor) and not polygon_problems(res.floor)


def test_a_clockwise_room_moves_the_same_wall_out():
    cw = ROOM[::-1].copy()  # its wall 1 runs from (3, 2) to (3, -1.5)
    res = move_walls_to_objects(cw, feet([[3.05, 0.0], [3.10, 1.0], [3.13, -1.0]]))
    assert [m.wall for m in res.moves] == [1] and math.isclose(res.moves[0].distance, 0.30, abs_tol=1e-9)
    assert np.allclose(res.floor[[1, 2], 0], 3.30) and np.allclose(res.floor[[0, 3], 0], -2.0)


@pytest.mark.parametrize("centers", [
    [[3.05, 0.0]],                      # one object: more often the object is too far than the wall too near
    [[3.05, 0.0], [3.5, 1.0]],          # two that disagree (0.30 and 0.75 m beyond)
    [[3.05, 0.0], [0.5, 2.2]],          # two beyond different walls
    [[2.8, 0.0], [2.78, 1.0]],          # inside (0.05 and 0.03 m beyond: under min_depth)
])
def test_no_move_without_two_agreeing_objects(centers):
    res = move_walls_to_objects(ROOM, feet(centers))
    assert res.moves == () and np.array_equal(res.floor, ROOM)


def test_the_largest_agreeing_group_sets_the_move_and_options_are_checked():
    # depths 0.30, 0.32 (agree) and 0.9 (an object placed too far): the pair moves the wall by 0.30
    res = move_walls_to_objects(ROOM, feet([[3.05, 0.0], [3.07, 1.0], [3.65, -1.0]]))
    assert res.moves[0].objects == (0, 1) and math.isclose(res.moves[0].distance, 0.30, abs_tol=1e-9)
    # three required: none
    assert move_walls_to_objects(ROOM, feet([[3.05, 0.0], [3.07, 1.0], [3.65, -1.0]]), min_objects=3).moves == ()
    assert move_walls_to_objects(ROOM, np.zeros((0, 4, 2))).moves == ()
    with pytest.raises(ValueError, match="footprints"):
        move_walls_to_objects(ROOM, np.zeros((2, 3, 2)))
    with pytest.raises(ValueError, match="min_objects"):
        move_walls_to_objects(ROOM, feet([[3.05, 0.0]]), min_objects=0)


def _scene_against_far_wall(width=512):
    """Labels of ROOM with two chairs against its wall x = 3 (camera 1.6 m high), their true boxes."""
    centers = np.array([[2.75, -0.6, 0.45], [2.75, 0.9, 0.45]])
    sizes = np.array([[0.5, 0.5, 0.9]] * 2)
    yaws = np.array([math.pi, math.pi])
    labels = render_scene_labels(ROOM, 2.7, 1.6, centers, sizes, yaws, width=width, object_label=0)
    dets = [DetectedObject("chair", world_box_to_pano(c, s, y, width, width // 2, camera_height=1.6).extent, s, y)
            for c, s, y in zip(centers, sizes, yaws)]
    return labels, dets


def test_sampler_moves_a_far_wall_placed_short_out_to_the_objects():
    labels, dets = _scene_against_far_wall()
    short = ROOM.copy()
    short[[1, 2], 0] = 2.5  # the room step put the wall x = 3 half a metre short
    lik = surface_likelihood(observe_labels(labels, [d.bbox_pano for d in dets], width=128), short, 2.7, 1.6)
    cfg = SamplerConfig.improved(n_samples=60, initial_camera_height=1.6)
    res = map_estimate(lik, dets, image_width=512, image_height=256, config=cfg, rng=0)
    assert [m.wall for m in res.wall_moves] == [1] and 0.45 < res.wall_moves[0].distance < 0.52
    assert 2.95 < res.scene.floor[:, 0].max() < 3.02 and 2.95 < res.initial.floor[:, 0].max() < 3.02
    assert all(abs(o.center[0] - 2.75) < 0.05 for o in res.scene.objects)
    off = map_estimate(lik, dets, image_width=512, image_height=256, config=SamplerConfig.improved(
        n_samples=60, initial_camera_height=1.6, wall_move_objects=0), rng=0)
    assert off.wall_moves == () and math.isclose(off.scene.floor[:, 0].max(), 2.5)
    assert all(o.center[0] < 2.26 for o in off.scene.objects)  # pushed in, a quarter metre off
    with pytest.raises(ValueError, match="wall_move_objects"):
        SamplerConfig(wall_move_objects=-1)
    with pytest.raises(ValueError, match="wall_move_agree"):
        SamplerConfig(wall_move_agree=float("nan"))
