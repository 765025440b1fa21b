"""Tests of layout.modelfit: model retrieval by box fit at a shared camera height."""

from __future__ import annotations

import math

import numpy as np
import pytest

from layout.modelfit import occluded_edges, room_misfit, select_models, wall_gap
from layout.sampler import DetectedObject, thin_footprints
from panogeom.project import world_box_to_pano

W, H = 1024, 512

# Per class: candidate sizes (l, w, h), several of nearly the same proportions (a box alone cannot tell them apart).
LIBRARY = {
    "bed": [(1.9, 0.95, 0.5), (2.05, 1.4, 0.55), (2.15, 1.65, 0.6), (2.25, 2.0, 0.65)],
    "chair": [(0.45, 0.45, 0.8), (0.55, 0.55, 0.95), (0.65, 0.7, 1.1)],
    "tv": [(0.2, 0.8, 0.5), (0.25, 1.1, 0.7), (0.3, 1.4, 0.85)],
}


def scene(seed: int, cam: float):
    """Objects of random true models at random places, their true boxes, and every candidate per object."""
    rng = np.random.default_rng(seed)
    truth, cands = [], []
    for k, cls in enumerate(["bed", "chair", "chair", "tv"]):
        j = int(rng.integers(len(LIBRARY[cls])))
        size = np.array(LIBRARY[cls][j])
        d, az, yaw = rng.uniform(2.0, 4.0), k * math.pi / 2 + rng.uniform(-0.4, 0.4), rng.uniform(0, 2 * math.pi)
        center = np.array([d * math.cos(az), d * math.sin(az), size[2] / 2])
        box = world_box_to_pano(center, size, yaw, W, H, camera_height=cam).extent
        truth.append(j)
        cands.append([DetectedObject(cls, box, s, yaw, model_id=f"{cls}-{i}") for i, s in enumerate(LIBRARY[cls])])
    return truth, cands


@pytest.mark.parametrize("seed", range(6))
def test_true_models_and_camera_height_from_true_boxes(seed):
    cam = 1.3 + 0.1 * seed
    truth, cands = scene(seed, cam)
    res = select_models(cands, W, H)
    assert res.index.tolist() == truth
    assert abs(res.camera_height - cam) < 0.02 * cam
    assert [o.model_id for o in res.objects] == [c[j].model_id for c, j in zip(cands, truth)]
    assert res.cost.shape == (4, 4) and np.isinf(res.cost[1, 3])  # chairs have 3 candidates
    assert np.all(np.diff(res.heights) > 0) and res.profile.shape == res.heights.shape


def test_a_known_camera_height_and_an_appearance_cost():
    truth, cands = scene(0, 1.5)
    known = select_models(cands, W, H, camera_height=1.5)
    assert known.index.tolist() == truth and known.camera_height == 1.5 and len(known.heights) == 1
    # a strong appearance cost against the true bed model overrides the box
    app = [np.zeros(len(c)) for c in cands]
    app[0][truth[0]] = 100.0
    res = select_models(cands, W, H, camera_height=1.5, appearance=app)
    assert res.index[0] != truth[0] and res.index[1:].tolist() == truth[1:]
    # ... and weights of zero ignore it
    assert select_models(cands, W, H, camera_height=1.5, appearance=app, appearance_weight=0.0,
                         pick_appearance_weight=0.0).index.tolist() == truth


@pytest.mark.parametrize("seed", range(3))
def test_the_pick_weight_picks_the_candidates_but_leaves_the_height(seed):
    """The camera height comes from the box misfit plus ``appearance_weight`` times the appearance; at that height
    each object takes the candidate of least box misfit plus ``pick_appearance_weight`` times it, except thin
    footprints (the TV), which keep ``appearance_weight``."""
    truth, cands = scene(seed, 1.5)
    rng = np.random.default_rng(seed)
    app = [rng.uniform(0.0, 0.6, len(c)) for c in cands]
    app[0][truth[0]] += 0.4  # the true bed a little worse in appearance
    assert int(np.argmin(app[0])) != truth[0]  # so the pick weight has something to change
    same = select_models(cands, W, H, appearance=app, pick_appearance_weight=1.0)
    assert same.index.tolist() == truth  # the box decides at weight 1
    heights = []
    for pick in (0.0, 3.0, 50.0):
        res = select_models(cands, W, H, appearance=app, pick_appearance_weight=pick)
        heights.append(res.camera_height)
        known = select_models(cands, W, H, appearance=app, camera_height=res.camera_height, appearance_weight=1.0,
                              pick_appearance_weight=1.0)
        rel = np.array([np.r_[a - a.min(), np.zeros(4 - len(a))] for a in app])  # (N, 4), chairs have 3
        w = np.array([1.0 if c[0].cls == "tv" else pick for c in cands])[:, None]  # thin TVs keep weight 1
        expect = np.argmin(known.cost - rel + w * rel, axis=1)  # box misfit (inf where no candidate) + pick
        assert res.index.tolist() == expect.tolist()
    assert heights[0] == heights[1] == heights[2] == same.camera_height
    # a large pick weight hands every object but the thin TV to its best appearance, the camera height stays
    assert res.index[:3].tolist() == [int(np.argmin(a)) for a in app[:3]]
    assert res.index[3] == same.index[3] == truth[3]
    with pytest.raises(ValueError, match="pick_appearance_weight"):
        select_models(cands, W, H, pick_appearance_weight=-1.0)


def test_the_pick_weighs_the_yaw_s_appearance_apart_from_the_model_s():
    """A bed's candidates: the four bed models at its yaw and turned 90 degrees. The appearance cost is a yaw part
    (the same for every model, as the orientation network's) plus a model part. The pick weighs the yaw's part
    (each candidate's object's best at that yaw) by ``pick_yaw_weight`` and the rest by ``pick_appearance_weight``:
    a strong yaw weight settles the yaw and leaves the model to the box."""
    cam = 1.5
    _, scene_cands = scene(1, cam)
    bed = scene_cands[0]
    cands = [[DetectedObject(o.cls, o.bbox_pano, o.size, o.yaw + t, model_id=o.model_id)
              for t in (0.0, 0.5 * math.pi) for o in bed]]
    yaw_part = np.repeat([0.4, 0.0], len(bed))  # the turn looks better, whatever the model
    model_part = np.tile([0.5, 0.3, 0.2, 0.0], 2)  # the appearance prefers the last model at both yaws
    app = [yaw_part + model_part]
    box = select_models(cands, W, H, camera_height=cam).cost[0]
    assert np.argmin(box) < 4 and np.argmin(box) != 3  # the box prefers the first yaw and another model
    for w_yaw, w_model in ((1.0, 1.0), (10.0, 3.0), (3.0, 10.0), (0.0, 0.0)):
        res = select_models(cands, W, H, camera_height=cam, appearance=app, pick_yaw_weight=w_yaw,
                            pick_appearance_weight=w_model)
        assert res.index[0] == int(np.argmin(box + w_yaw * yaw_part + w_model * model_part))
    # the yaw's weight alone: the appearance's yaw, the box's model at it
    res = select_models(cands, W, H, camera_height=cam, appearance=app, pick_yaw_weight=1e3,
                        pick_appearance_weight=0.0)
    assert res.index[0] == 4 + int(np.argmin(box[4:]))
    # the model's weight alone: the appearance's model, the box's yaw for it
    res = select_models(cands, W, H, camera_height=cam, appearance=app, pick_yaw_weight=0.0,
                        pick_appearance_weight=1e3)
    assert res.index[0] == (3 if box[3] <= box[7] else 7)
    with pytest.raises(ValueError, match="pick_yaw_weight"):
        select_models(cands, W, H, pick_yaw_weight=float("inf"))


def test_one_thin_candidate_does_not_lighten_its_object_s_appearance_weight():
    """The pick weighs the appearance of all candidates of an object alike: a narrow single bed among the double
    beds (its footprint thin by :func:`layout.sampler.thin_footprints`) pays the pick weight like the rest, so the
    double bed the box fits best is picked though the narrow one looks a little more alike. Until session 25 the
    narrow bed alone kept the lighter weight of thin footprints and won here (on the tuning sets it was picked
    for beds of other models, docs/EVALUATION.md, "Session 25")."""
    cam = 1.5
    size, center = np.array([2.15, 1.65, 0.6]), np.array([3.0, 0.4, 0.3])
    box = world_box_to_pano(center, size, math.pi / 2, W, H, camera_height=cam).extent  # seen from its side
    sizes = [size, np.array([2.15, 1.05, 0.6]), np.array([1.4, 1.4, 1.4])]  # true, narrow (thin), far off
    cands = [[DetectedObject("bed", box, s, math.pi / 2, model_id=f"bed-{i}") for i, s in enumerate(sizes)]]
    box_only = select_models(cands, W, H, camera_height=cam).cost[0]
    assert box_only[0] < box_only[1] < box_only[2]
    assert thin_footprints([s[:2] for s in sizes]).tolist() == [False, True, False]
    gap = box_only[1] - box_only[0]
    assert box_only[2] - box_only[0] > 2.5 * gap
    # appearance: the narrow bed 0.5 gap, the true one 2/3 gap, the far-off one 0: at weight 3 for all the true bed
    # wins by gap / 3; had the narrow bed alone kept weight 1, it would win by gap / 3
    app = [np.array([2.0 * gap / 3.0, 0.5 * gap, 0.0])]
    res = select_models(cands, W, H, camera_height=cam, appearance=app, appearance_weight=1.0,
                        pick_appearance_weight=3.0)
    assert res.index.tolist() == [0]


def test_one_box_cut_by_an_occluder_does_not_move_the_camera_height():
    truth, cands = scene(3, 1.6)
    box = cands[1][0].bbox_pano.copy()
    box[3] -= 0.4 * (box[3] - box[1])  # the lower 40 % of the first chair hidden behind the bed
    cands[1] = [DetectedObject(o.cls, box, o.size, o.yaw, model_id=o.model_id) for o in cands[1]]
    res = select_models(cands, W, H)
    assert abs(res.camera_height - 1.6) < 0.03
    assert [res.index[i] for i in (0, 2, 3)] == [truth[i] for i in (0, 2, 3)]


def test_the_room_term_rejects_a_candidate_through_a_wall():
    """A bed along a side wall, its candidates the true yaw and a quarter turn (a HOG side view): an appearance
    cost slightly for the turn wins on the box alone; the floor polygon then rules the turn out, since fitted to
    the box it reaches 15 cm through the side wall. The appearance cost is set against the box misfit at an edge
    scale of 0.6 degrees (the default until session 21) and an appearance weight of 1 for the pick (3 since session
    22; the yaw's part 10 since session 32), which the test pins."""
    edge = math.radians(0.6)
    cam = 1.5
    size, center = np.array([2.0, 1.6, 0.6]), np.array([3.0, 0.4, 0.3])
    box = world_box_to_pano(center, size, math.pi, W, H, camera_height=cam).extent
    cands = [[DetectedObject("bed", box, size, math.pi + t, model_id="bed-0") for t in (0.0, 0.5 * math.pi)]]
    room = np.array([[-3.0, -3.0], [4.05, -3.0], [4.05, 1.25], [-3.0, 1.25]])  # back and side walls 5 cm away
    app = [np.array([3.1, 0.0])]
    fit = dict(edge_sigma=edge, camera_height=cam, appearance=app, pick_appearance_weight=1.0, pick_yaw_weight=1.0)
    assert select_models(cands, W, H, **fit).index.tolist() == [1]
    res = select_models(cands, W, H, **fit, floor=room, floor_camera_height=cam)
    assert res.index.tolist() == [0]
    # the floor is scaled with the camera height: the same room given at camera height 1 (units of it)
    same = select_models(cands, W, H, **fit, floor=room / cam, floor_camera_height=1.0)
    assert np.allclose(same.cost, res.cost)
    assert select_models(cands, W, H, **fit, floor=room, floor_camera_height=cam,
                         room_weight=0.0).index.tolist() == [1]
    # the term itself: 0 inside, rho(depth / sigma) outside, bounded by 1
    cost = room_misfit([[0.0, 0.0], [3.0, 0.4], [3.0, 0.4], [9.0, 0.0]], [0.0, 0.0, 0.5 * math.pi, 0.0],
                       [[2.0, 1.6]] * 4, room, 0.2)
    assert cost[0] == 0.0 and cost[1] == 0.0 and 0.3 < cost[2] < 0.5 and 0.99 < cost[3] < 1.0
    with pytest.raises(ValueError, match="floor_camera_height"):
        select_models(cands, W, H, floor=room)
    with pytest.raises(ValueError, match="floor: expected"):
        select_models(cands, W, H, floor=room[:2], floor_camera_height=cam)
    with pytest.raises(ValueError, match="room_sigma"):
        select_models(cands, W, H, floor=room, floor_camera_height=cam, room_sigma=0.0)


def test_the_wall_gap_term_turns_a_bed_s_back_to_the_wall():
    """A bed with its head against the far wall, its candidates the true yaw and the half turn: a cuboid's box
    cannot tell them apart, and an appearance cost slightly for the turn picks it (0.05: since session 32 the pick
    weighs a yaw's appearance by 10). Told that beds stand with their back to a wall, the choice sees the turned
    bed's back 2 m clear of every wall and picks the true yaw."""
    cam = 1.5
    size, center = np.array([2.0, 1.6, 0.6]), np.array([3.0, 0.2, 0.3])
    box = world_box_to_pano(center, size, math.pi, W, H, camera_height=cam).extent
    cands = [[DetectedObject("bed", box, size, math.pi + t, model_id="bed-0") for t in (0.0, math.pi)]]
    room = np.array([[-3.0, -3.0], [4.0, -3.0], [4.0, 3.0], [-3.0, 3.0]])  # the head wall at x = 4
    fit = dict(camera_height=cam, appearance=[np.array([0.05, 0.0])], floor=room, floor_camera_height=cam)
    assert select_models(cands, W, H, **fit).index.tolist() == [1]
    assert select_models(cands, W, H, **fit, back_to_wall=[False]).index.tolist() == [1]
    res = select_models(cands, W, H, **fit, back_to_wall=[True])
    assert res.index.tolist() == [0]
    assert select_models(cands, W, H, **fit, back_to_wall=[True], gap_weight=0.0).index.tolist() == [1]
    # without a floor there is no wall to stand against
    assert select_models(cands, W, H, camera_height=cam, appearance=[np.array([0.05, 0.0])],
                         back_to_wall=[True]).index.tolist() == [1]
    # the term itself: 0 with the back on (or through) a wall, rho(gap / sigma) in the room, bounded by 1
    cost = wall_gap([[3.0, 0.2], [3.2, 0.2], [2.8, 0.2], [3.0, 0.2]], [math.pi, math.pi, math.pi, 0.0],
                    [2.0, 2.0, 2.0, 2.0], room, 0.2)
    assert cost[0] < 1e-12 and cost[1] == 0.0 and cost[2] == pytest.approx(0.5) and 0.99 < cost[3] < 1.0
    with pytest.raises(ValueError, match="back_to_wall: expected 1 booleans"):
        select_models(cands, W, H, **fit, back_to_wall=[True, False])
    with pytest.raises(ValueError, match="back_to_wall: expected 1 booleans"):
        select_models(cands, W, H, **fit, back_to_wall=[1])
    with pytest.raises(ValueError, match="gap_sigma"):
        select_models(cands, W, H, **fit, back_to_wall=[True], gap_sigma=-1.0)
    with pytest.raises(ValueError, match="gap_weight"):
        select_models(cands, W, H, **fit, back_to_wall=[True], gap_weight=float("nan"))


def test_input_errors():
    _, cands = scene(0, 1.5)
    with pytest.raises(ValueError, match=r"candidates\[1\]: expected at least one"):
        select_models([cands[0], []], W, H)
    other = DetectedObject("chair", [10.0, 260.0, 40.0, 300.0], (0.5, 0.5, 0.9), 0.0)
    with pytest.raises(ValueError, match=r"share its box"):
        select_models([cands[1] + [other]], W, H)
    with pytest.raises(ValueError, match=r"appearance\[0\]: expected 4 finite costs"):
        select_models(cands, W, H, appearance=[np.zeros(3)] + [np.zeros(len(c)) for c in cands[1:]])
    with pytest.raises(ValueError, match="camera_height: expected metres > 0"):
        select_models(cands, W, H, camera_height=-1.0)
    with pytest.raises(ValueError, match="height_range"):
        select_models(cands, W, H, height_range=(2.0, 1.0))
    empty = select_models([], W, H)
    assert empty.objects == () and math.isnan(empty.camera_height)


def test_occluded_edges_nearer_box_in_front_and_across_the_seam():
    # a chair (bottom at 340) in front of the right part of a bed (bottom at 300): the bed's right and bottom edges
    boxes = [[100, 200, 200, 300], [150, 250, 260, 340], [600, 100, 640, 420]]
    cut = occluded_edges(boxes, 1024)
    assert cut.tolist() == [[False, False, True, True], [False] * 4, [False] * 4]
    # the same two boxes shifted across the seam (u0 > u1 wraps)
    shifted = [[(u0 + 900) % 1024, v0, (u1 + 900) % 1024, v1] for u0, v0, u1, v1 in boxes]
    assert occluded_edges(shifted, 1024).tolist() == cut.tolist()
    # a tall nearer box covering the whole of a small far one takes all four edges
    assert occluded_edges([[300, 280, 320, 300], [280, 150, 340, 330]], 1024)[0].all()
    assert occluded_edges([[1, 2, 3, 4]], 1024).shape == (1, 4)


def test_edge_weights_leave_a_cut_edge_out_of_the_fit():
    from layout.sampler import fit_boxes

    truth, cands = scene(1, 1.5)
    bed = cands[0][truth[0]]
    box = bed.bbox_pano.copy()
    box[3] -= 0.3 * (box[3] - box[1])  # bottom cut by an occluder
    cut = DetectedObject("bed", box, bed.size, bed.yaw)
    told = DetectedObject("bed", box, bed.size, bed.yaw, edge_weights=[1, 1, 1, 0])
    start = np.array([[2.0, 0.0, 0.3]])
    true_xy = fit_boxes([bed], start, W, H, camera_height=1.5)[0][0, :2]
    err_cut = np.hypot(*(fit_boxes([cut], start, W, H, camera_height=1.5)[0][0, :2] - true_xy))
    err_told = np.hypot(*(fit_boxes([told], start, W, H, camera_height=1.5)[0][0, :2] - true_xy))
    assert err_told < 0.02 and err_cut > 0.1
    with pytest.raises(ValueError, match="edge_weights: expected 4 finite weights"):
        DetectedObject("bed", box, bed.size, bed.yaw, edge_weights=[1, 1, 1])


def test_the_height_prior_decides_where_the_boxes_cannot():
    """One bed whose candidates are scaled copies of each other: each fits the box exactly at its own camera
    height, so only the prior (median 1.5 m) can choose; the default prior picks the bed seen at 1.5 m."""
    box = world_box_to_pano(np.array([3.0, 0.0, 0.3]), np.array([2.0, 1.6, 0.6]), math.pi, W, H,
                            camera_height=1.5).extent
    beds = [DetectedObject("bed", box, [s, 0.8 * s, 0.3 * s], math.pi) for s in (1.6, 2.0, 2.4)]
    res = select_models([beds], W, H)
    assert res.index.tolist() == [1] and abs(res.camera_height - 1.5) < 0.01
    free = select_models([beds], W, H, height_prior=None)  # some candidate at its own height: 1.2, 1.5 or 1.8 m
    assert abs(free.camera_height / (1.5 * (0.8, 1.0, 1.2)[free.index[0]]) - 1) < 0.02
    assert free.cost[0, free.index[0]] < 0.05
    with pytest.raises(ValueError, match="height_prior"):
        select_models([beds], W, H, height_prior=(0.0, 0.3))


def test_the_wall_prior_decides_with_the_room_s_wall_to_camera_ratio():
    """The same three scaled beds: each fits at its own camera height (1.2, 1.5 or 1.8 m). A room whose walls are
    2.6 / 1.8 camera heights high makes the wall prior (median 2.6 m) pick the bed seen at 1.8 m; a known camera
    height ignores it; a bad ratio or prior is refused."""
    box = world_box_to_pano(np.array([3.0, 0.0, 0.3]), np.array([2.0, 1.6, 0.6]), math.pi, W, H,
                            camera_height=1.5).extent
    beds = [DetectedObject("bed", box, [s, 0.8 * s, 0.3 * s], math.pi) for s in (1.6, 2.0, 2.4)]
    res = select_models([beds], W, H, height_prior=None, wall_ratio=2.6 / 1.8)
    assert res.index.tolist() == [2] and abs(res.camera_height - 1.8) < 0.02
    low = select_models([beds], W, H, height_prior=None, wall_ratio=2.6 / 1.2)
    assert low.index.tolist() == [0] and abs(low.camera_height - 1.2) < 0.02
    # without the ratio, or with the prior off, the default camera-height prior (median 1.5 m) decides
    assert select_models([beds], W, H).index.tolist() == [1]
    assert select_models([beds], W, H, wall_ratio=2.6 / 1.8, wall_prior=None).index.tolist() == [1]
    known = select_models([beds], W, H, camera_height=1.5, wall_ratio=2.6 / 1.8)
    assert known.camera_height == 1.5 and known.index.tolist() == [1]
    with pytest.raises(ValueError, match="wall_ratio"):
        select_models([beds], W, H, wall_ratio=-1.0)
    with pytest.raises(ValueError, match="wall_prior"):
        select_models([beds], W, H, wall_ratio=1.7, wall_prior=(2.6, 0.0))


def _bed_outline():
    """A 2.0 x 1.6 x 0.6 m bed at yaw 2 rad, 2.2 m ahead and 1.4 m left of a camera 1.5 m high: its size, yaw,
    camera height, centre, hull outline (object frame) and the outline's points relative to the camera."""
    from layout.sampler import hull_outline

    size, yaw, cam = np.array([2.0, 1.6, 0.6]), 2.0, 1.5
    center = np.array([2.2, 1.4, 0.3])
    verts = np.array([[sx * size[0] / 2, sy * size[1] / 2, z] for sx in (-1, 1) for sy in (-1, 1)
                      for z in (0.0, size[2])])
    outline = hull_outline(verts)
    c, s = math.cos(yaw), math.sin(yaw)
    world = np.stack([center[0] + c * outline[:, 0] - s * outline[:, 1],
                      center[1] + s * outline[:, 0] + c * outline[:, 1], outline[:, 2] - cam], axis=1)
    return size, yaw, cam, center, outline, world


def test_edge_planes_of_a_tight_tile_box_are_touched_at_the_truth():
    """A box drawn tight around an object in a pitched, turned tile: as great circles its edges touch the outline
    at the true position (residual ~0), and the fit from a wrong start comes back to it."""
    from detect.detection import TileBox
    from layout.sampler import _BoxEdges, fit_boxes
    from panogeom.coords import ray_to_lonlat, lonlat_to_pixel
    from panogeom.perspective import PinholeView

    size, yaw, cam, center, outline, world = _bed_outline()
    lon_c = float(ray_to_lonlat(center[None] - [0, 0, cam])[0, 0])
    view = PinholeView(yaw=lon_c + 0.35, pitch=-0.45, roll=0.0, fov=math.radians(100), width=400, height=400)
    px, ok = view.ray_to_pixel(world)
    assert ok.all()
    tb = TileBox(view, [px[:, 0].min(), px[:, 1].min(), px[:, 0].max(), px[:, 1].max()])
    pano_box = lonlat_to_pixel(ray_to_lonlat(world), W, H)
    box = [pano_box[:, 0].min(), pano_box[:, 1].min(), pano_box[:, 0].max(), pano_box[:, 1].max()]
    obj = DetectedObject("bed", box, size, yaw, outline=outline, edge_planes=tb.edge_planes())
    r = _BoxEdges([obj], W, H).residual(center[None, None, :2], np.array([[yaw]]), np.array([[cam]]))[0, 0]
    assert np.abs(r).max() < 1e-6
    got = fit_boxes([obj], [[center[0] + 0.4, center[1] - 0.3, 0.3]], W, H, camera_height=cam)[0][0, :2]
    assert np.hypot(*(got - center[:2])) < 0.01
    with pytest.raises(ValueError, match="edge_planes: expected an outline"):
        DetectedObject("bed", box, size, yaw, edge_planes=tb.edge_planes())


def test_edge_residual_of_several_views_is_the_median_of_theirs():
    """An object seen whole in three tiles, one of them with a box 2 px too wide on every side: each edge's
    residual is the median of the three tiles' residuals (the two true ones: ~0), and with two views the
    mean; one plane set given as (1, 4, 3) is the same as (4, 3)."""
    from detect.detection import TileBox
    from layout.sampler import _BoxEdges
    from panogeom.perspective import PinholeView

    size, yaw, cam, center, outline, world = _bed_outline()
    lon_c = math.atan2(center[1], center[0])
    planes = []
    for dyaw, pitch, grow in ((0.3, -0.4, 2.0), (-0.2, -0.2, 0.0), (0.1, -0.6, 0.0)):
        view = PinholeView(yaw=lon_c + dyaw, pitch=pitch, roll=0.0, fov=math.radians(100), width=400, height=400)
        px, ok = view.ray_to_pixel(world)
        assert ok.all()
        box = np.array([px[:, 0].min(), px[:, 1].min(), px[:, 0].max(), px[:, 1].max()])
        box += grow * np.array([-1.0, -1.0, 1.0, 1.0])
        planes.append(TileBox(view, box).edge_planes())
    planes = np.stack(planes)
    box = [0.0, 200.0, 100.0, 300.0]  # unused with planes

    def residual(p):
        obj = DetectedObject("bed", box, size, yaw, outline=outline, edge_planes=p)
        return _BoxEdges([obj], W, H).residual(center[None, None, :2], np.array([[yaw]]), np.array([[cam]]))[0, 0]

    each = np.stack([residual(p) for p in planes])
    assert np.abs(each[1:]).max() < 1e-6 and np.all(each[0] > 1e-3)  # the wide box: the object inside every edge
    assert np.allclose(residual(planes), np.median(each, axis=0), atol=1e-9)
    assert np.allclose(residual(planes[:2]), each[:2].mean(axis=0), atol=1e-6)  # mean of the sines
    assert np.allclose(residual(planes[:1]), each[0], atol=1e-12)
    assert DetectedObject("bed", box, size, yaw, outline=outline, edge_planes=planes).region_planes.shape == (4, 3)
    # objects with different numbers of views fitted together
    objs = [DetectedObject("bed", box, size, yaw, outline=outline, edge_planes=p) for p in (planes, planes[0])]
    both = _BoxEdges(objs, W, H).residual(np.repeat(center[None, None, :2], 2, axis=1), np.full((1, 2), yaw),
                                          np.full((1, 2), cam))[0]
    assert np.allclose(both, [np.median(each, axis=0), each[0]], atol=1e-9)
    with pytest.raises(ValueError, match="edge_planes"):
        DetectedObject("bed", box, size, yaw, outline=outline, edge_planes=planes[:, :3])


def test_a_cut_plane_edge_pulls_weakly_only_where_the_object_reaches_beyond_it():
    """Edge planes and ``cut_edges``: a tile box 3 px too wide (the object inside every edge, residuals > 0) keeps
    its full residuals when its edges are cut; one 3 px too narrow (the object beyond every edge, residuals < 0)
    has them scaled by CUT_EDGE_BEYOND."""
    from detect.detection import TileBox
    from layout.sampler import CUT_EDGE_BEYOND, _BoxEdges
    from panogeom.perspective import PinholeView

    size, yaw, cam, center, outline, world = _bed_outline()
    view = PinholeView(yaw=math.atan2(center[1], center[0]) + 0.2, pitch=-0.4, roll=0.0, fov=math.radians(100),
                       width=400, height=400)
    px, ok = view.ray_to_pixel(world)
    assert ok.all()
    tight = np.array([px[:, 0].min(), px[:, 1].min(), px[:, 0].max(), px[:, 1].max()])
    for grow, sign, factor in ((3.0, 1.0, 1.0), (-3.0, -1.0, CUT_EDGE_BEYOND)):
        planes = TileBox(view, tight + grow * np.array([-1.0, -1.0, 1.0, 1.0])).edge_planes()

        def residual(cut):
            obj = DetectedObject("bed", [0.0, 200.0, 100.0, 300.0], size, yaw, outline=outline, edge_planes=planes,
                                 cut_edges=cut)
            return _BoxEdges([obj], W, H).residual(center[None, None, :2], np.array([[yaw]]),
                                                   np.array([[cam]]))[0, 0]

        whole = residual(None)
        assert np.all(sign * whole > 1e-4)
        assert np.allclose(residual(np.ones(4, bool)), factor * whole, atol=1e-12)
        mixed = residual(np.array([True, False, False, True]))
        assert np.allclose(mixed, whole * [factor, 1.0, 1.0, factor], atol=1e-12)
