"""Tests of layout.sampler: initialisation, closed-form camera height, the MAP sampler."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from layout.likelihood import observe_labels, render_scene_labels, surface_likelihood
from layout.placement import ObjectSpec, place_objects
from layout.polygon import convex_in_polygon, points_in_polygon
from layout.context import pair_overlap_areas
from layout.rooms import generate_room
from layout.sampler import (
    DetectedObject,
    PosteriorError,
    SamplerConfig,
    camera_height_estimates,
    fit_boxes,
    _Problem,
    _snap_yaws,
    initialise_objects,
    map_estimate,
    snap_to_walls,
)
from layout.likelihood import orientation_likelihood
from panogeom.project import world_box_to_pano

W = 512
SPECS = [ObjectSpec("bed", (2.05, 1.6, 0.55), "bed-a"), ObjectSpec("tv", (0.25, 1.1, 0.7), "tv-a"),
         ObjectSpec("chair", (0.5, 0.5, 0.9), "chair-a"), ObjectSpec("plant", (0.4, 0.4, 0.9), "plant-a", True)]


def synthetic(seed, *, yaw_noise_deg=3.0, template="rectangle", h0=1.6, width=W):
    """A placed room, its observed labels (objects as clutter), true boxes and noisy pose estimates."""
    rng = np.random.default_rng(seed)
    room = generate_room(rng, template=template)
    pl = place_objects(room, SPECS, rng).centered_on_camera()
    cam = pl.camera_height
    c = pl.centers
    s = np.array([o.size for o in pl.objects]).reshape(-1, 3)
    y = pl.yaws
    labels = render_scene_labels(pl.room.floor, pl.room.ceiling_z, cam, c, s, y, width=width, object_label=0)
    dets = []
    for o in pl.objects:
        box = world_box_to_pano(o.center, o.size, o.yaw, width, width // 2, camera_height=cam).extent
        yaw = o.yaw + (0.0 if o.symmetric else math.radians(yaw_noise_deg) * rng.normal())
        dets.append(DetectedObject(o.class_name, box, o.size, yaw, model_id=o.model_id, symmetric=o.symmetric))
    f = h0 / cam
    return pl, labels, dets, pl.room.floor * f, pl.room.ceiling_z * f


def check_valid(scene, cfg=SamplerConfig()):
    """The hard constraints of a returned scene."""
    assert np.isfinite(scene.floor).all() and math.isfinite(scene.camera_height) and math.isfinite(scene.scale)
    fp = np.array([o.footprint for o in scene.objects]).reshape(-1, 4, 2)
    assert convex_in_polygon(fp, scene.floor, tol=1e-5).all()
    c = np.array([o.center[:2] for o in scene.objects]).reshape(-1, 2)
    yaw = np.array([o.yaw for o in scene.objects])
    sizes = np.array([o.size[:2] for o in scene.objects]).reshape(-1, 2)
    if len(c) > 1:
        pair = pair_overlap_areas(c, yaw, sizes)
        assert pair.max() <= cfg.overlap_tol + 1e-12
    for o in scene.objects:
        assert o.center[2] + o.size[2] / 2 <= scene.ceiling_z + 1e-9


def test_initialisation_is_exact_with_true_boxes_and_poses():
    pl, _, dets, _, _ = synthetic(0, yaw_noise_deg=0.0)
    init = initialise_objects(dets, W, W // 2)
    assert np.allclose(init.centers, pl.centers, atol=2e-3)
    assert np.allclose(init.distance, np.hypot(pl.centers[:, 0], pl.centers[:, 1]), atol=2e-3)
    assert np.allclose(init.camera_heights, pl.camera_height, atol=5e-3)
    exact = camera_height_estimates(dets, pl.centers, W, W // 2)
    assert np.allclose(exact, pl.camera_height, atol=1e-3)


@settings(max_examples=30, deadline=None)
@given(st.floats(0.5, 5.0), st.floats(-np.pi, np.pi), st.floats(0, 2 * np.pi), st.floats(0.3, 2.2),
       st.floats(0.3, 2.2), st.floats(0.3, 2.0), st.floats(1.2, 1.9))
def test_initialisation_inverts_the_projection(dist, az, yaw, l, w, h, cam):
    """Wide and seam-crossing boxes included: the horizontal box extent and the model size give the centre back,
    whatever the camera height. Footprints closer than 0.5 m to the camera are left out: their box columns can fit
    several places, and the initialisation's multi-start does not always pick the true one (e.g. a table 0.43 m
    from the camera, box across the seam, placed 0.33 m off); the box fits start from there."""
    c = np.array([dist * np.cos(az), dist * np.sin(az), h / 2])
    from layout.sampler import _rect_distance

    near, _ = _rect_distance(c[None, :2], np.array([yaw]), np.array([[l, w]]))
    if near[0] < 0.5:
        return
    box = world_box_to_pano(c, [l, w, h], yaw, 1024, 512, camera_height=cam).extent
    det = DetectedObject("table", box, [l, w, h], yaw)
    got = initialise_objects([det], 1024, 512)
    assert np.allclose(got.centers[0], c, atol=1e-3 * max(1.0, dist))


def test_fit_boxes_fixes_an_edge_on_object():
    """A wardrobe 5.6 m away seen from its side with a 6 deg yaw error: its box width puts it about a metre
    off; all four edges (camera height fitted per object, then given) bring it back within centimetres."""
    c = np.array([-0.626, 5.601, 1.062])
    size = np.array([0.64, 1.52, 2.125])
    cam = 1.766
    box = world_box_to_pano(c, size, 0.0103, 1024, 512, camera_height=cam).extent
    det = DetectedObject("wardrobe", box, size, 0.0103 - math.radians(6.0))
    init = initialise_objects([det], 1024, 512)
    assert np.hypot(*(init.centers[0, :2] - c[:2])) > 0.5
    assert init.fitted_camera_heights[0] == pytest.approx(cam, abs=0.03)
    fitted, h = fit_boxes([det], init.centers, 1024, 512, camera_height=cam)
    assert np.hypot(*(fitted[0, :2] - c[:2])) < 0.15 and h[0] == cam


def test_map_estimate_deterministic_and_counts():
    pl, labels, dets, floor0, ceil0 = synthetic(1)
    lik = surface_likelihood(observe_labels(labels, [d.bbox_pano for d in dets], width=256), floor0, ceil0, 1.6)
    cfg = SamplerConfig(epochs=4, samples_per_epoch=10)
    a = map_estimate(lik, dets, image_width=W, image_height=W // 2, config=cfg, rng=7)
    b = map_estimate(lik, dets, image_width=W, image_height=W // 2, config=cfg, rng=7)
    assert a.scene.to_json_dict()["objects"] == b.scene.to_json_dict()["objects"]
    assert a.scene.scale == b.scene.scale and np.array_equal(a.history, b.history)
    imp = SamplerConfig.improved(epochs=3, samples_per_epoch=10)
    runs = [map_estimate(lik, dets, image_width=W, image_height=W // 2, config=imp, rng=r).scene.to_json_dict()
            for r in (7, 7, 8)]
    for r in runs:
        r.pop("timing_s")
    assert runs[0] == runs[1] and runs[0]["objects"] != runs[2]["objects"]
    assert a.n_samples == 2 + 4 * 10 and a.history.shape == (5, 6) and a.mode == "paper"
    assert np.all(np.diff(a.history[:, 4]) <= 1e-12)  # the seed's energy never increases
    assert a.energies.total <= a.history[0, 4] + 1e-12
    assert [o.id for o in a.scene.objects] == ["bed-0", "tv-0", "chair-0", "plant-0"]
    assert a.scene.camera_height == pytest.approx(a.scene.scale * 1.6)
    assert a.scene.wall_height == pytest.approx(a.scene.scale * ceil0)
    check_valid(a.scene)


def test_paper_budget_and_initial_wall_height():
    pl, labels, dets, floor0, ceil0 = synthetic(2)
    lik = surface_likelihood(observe_labels(labels, [d.bbox_pano for d in dets], width=128), floor0, ceil0, 1.6)
    res = map_estimate(lik, dets, image_width=W, image_height=W // 2, config=SamplerConfig(n_samples=300), rng=0)
    assert res.n_samples == 2 + 300 and res.history.shape == (13, 6)
    assert res.initial.wall_height == pytest.approx(2.5)
    assert 2.0 - 1e-9 <= res.scene.wall_height <= 3.5 + 1e-9
    check_valid(res.scene)


@pytest.mark.parametrize("seed, template", [(3, "rectangle"), (4, "L")])
def test_improved_recovers_scale_and_positions(seed, template):
    """The unit-level acceptance on small rooms: wall height within 5 cm, positions within 10 cm."""
    pl, labels, dets, floor0, ceil0 = synthetic(seed, template=template)
    obs = observe_labels(labels, [d.bbox_pano for d in dets], width=256, object_pixels="matched")
    lik = surface_likelihood(obs, floor0, ceil0, 1.6)
    eo = [None if d.symmetric else (lambda y, m=d.yaw: 1.0 - np.cos(y - m)) for d in dets]
    res = map_estimate(lik, dets, image_width=W, image_height=W // 2, orientation=eo,
                       config=SamplerConfig.improved(n_samples=800), rng=seed)
    assert abs(res.scene.wall_height - pl.room.ceiling_z) < 0.05
    pos = [np.hypot(*(o.center[:2] - np.array(g.center[:2]))) for o, g in zip(res.scene.objects, pl.objects)]
    assert np.mean(pos) < 0.10
    yaw_err = [abs(math.remainder(o.yaw - g.yaw, 2 * math.pi)) for o, g in zip(res.scene.objects, pl.objects)
               if not g.symmetric]
    assert np.mean(yaw_err) < math.radians(3.0)
    check_valid(res.scene)


def test_invalid_initial_state_is_repaired():
    """Starting at a 2.0 m wall height puts the far objects through the walls; the result is valid."""
    pl, labels, dets, floor0, ceil0 = synthetic(5)
    lik = surface_likelihood(observe_labels(labels, [d.bbox_pano for d in dets], width=128), floor0, ceil0, 1.6)
    cfg = SamplerConfig(initial_wall_height=2.0, epochs=2, samples_per_epoch=5)
    res = map_estimate(lik, dets, image_width=W, image_height=W // 2, config=cfg, rng=0)
    assert res.n_invalid >= 1
    check_valid(res.scene)


def test_repair_steps_aside_rather_than_sliding_out_of_an_arm():
    """A plant in a shallow arm of an L-shaped room reaches 6 cm through the arm's side wall, the one on the camera's
    side. Along its viewing ray alone it fits only 0.8 m nearer, out of the arm (farther, the arm's end wall stops it
    first); with a few centimetres across the ray it fits within 10 cm of where it stands (9 cm along, 3 cm across).
    The repair takes the least change (the old repair slid it 0.78 m)."""
    _, labels, _, _, _ = synthetic(5)
    floor = np.array([[-3.0, -2.0], [2.0, -2.0], [2.0, 1.7], [-0.34, 1.7], [-0.34, 2.5], [-2.6, 2.5], [-2.6, 1.7],
                      [-3.0, 1.7]])
    lik = surface_likelihood(observe_labels(labels, width=128), floor, 2.6, 1.6)
    start = np.array([-0.78, 1.92])
    box = world_box_to_pano(np.r_[start, 0.5], (1.0, 1.0, 1.0), 0.0, W, W // 2, camera_height=1.6).extent
    plant = DetectedObject("plant", box, (1.0, 1.0, 1.0), 0.0, symmetric=True)
    from layout.likelihood import orientation_likelihood

    prob = _Problem(lik, [plant], orientation_likelihood(None, ["plant"]), SamplerConfig.improved(), W, W // 2)
    assert not prob.object_ok(np.ones(1), start[None, None], np.zeros((1, 1)))[0, 0]
    _, xy, _ = prob.repair(1.0, start[None].copy(), np.zeros(1), grow_scale=False)
    assert prob.object_ok(np.ones(1), xy[None], np.zeros((1, 1)))[0, 0]
    assert np.hypot(*(xy[0] - start)) < 0.15


@pytest.mark.parametrize("mode", ["improved", "paper"])
def test_repair_turns_a_plant_in_place_where_that_fits(mode):
    """A 1 m plant stands by a reflex corner of an L-shaped room; at yaw 0 its square footprint's corner reaches 10 cm
    past the corner, at 45 degrees the footprint fits. A plant has no yaw to keep: the improved repair turns it in
    place (the least turn that fits) instead of moving it; the paper scheme's repair moves it, as before."""
    _, labels, _, _, _ = synthetic(5)
    floor = np.array([[-3.0, -2.0], [3.0, -2.0], [3.0, 2.0], [1.0, 2.0], [1.0, 3.5], [-3.0, 3.5]])
    lik = surface_likelihood(observe_labels(labels, width=128), floor, 2.6, 1.6)
    start = np.array([0.6, 1.6])
    box = world_box_to_pano(np.r_[start, 0.5], (1.0, 1.0, 1.0), 0.0, W, W // 2, camera_height=1.6).extent
    plant = DetectedObject("plant", box, (1.0, 1.0, 1.0), 0.0, symmetric=True)
    cfg = SamplerConfig.improved() if mode == "improved" else SamplerConfig()
    prob = _Problem(lik, [plant], orientation_likelihood(None, ["plant"]), cfg, W, W // 2)
    assert not prob.object_ok(np.ones(1), start[None, None], np.zeros((1, 1)))[0, 0]
    _, xy, yaw = prob.repair(1.0, start[None].copy(), np.zeros(1), grow_scale=False)
    assert prob.object_ok(np.ones(1), xy[None], yaw[None])[0, 0]
    if mode == "improved":
        np.testing.assert_array_equal(xy[0], start)
        turn = abs(math.degrees(math.remainder(float(yaw[0]), math.pi / 2)))
        assert 5.0 < turn <= 45.0
        # the least turn: one degree less does not fit
        smaller = yaw[0] - math.copysign(math.radians(1.0), math.remainder(float(yaw[0]), math.pi / 2))
        assert not prob.object_ok(np.ones(1), start[None, None], np.array([[smaller]]))[0, 0]
    else:
        assert yaw[0] == 0.0 and np.hypot(*(xy[0] - start)) > 0.05


@pytest.mark.parametrize("mode", ["improved", "paper"])
def test_repair_turns_a_plant_off_a_chair(mode):
    """A 1 m plant's square footprint overlaps a chair's by 13 x 13 cm at yaw 0; turned by 45 degrees it is clear.
    The improved repair turns the plant in place and moves nothing; the paper scheme's slides one of them."""
    _, labels, _, _, _ = synthetic(5)
    floor = np.array([[-3.0, -2.0], [4.0, -2.0], [4.0, 2.5], [-3.0, 2.5]])
    lik = surface_likelihood(observe_labels(labels, width=128), floor, 2.6, 1.6)
    start = np.array([[2.0, 0.0], [2.62, 0.62]])
    dets = []
    for (x, y), cls, size in zip(start, ("plant", "chair"), ((1.0, 1.0, 1.0), (0.5, 0.5, 0.9))):
        box = world_box_to_pano(np.r_[x, y, size[2] / 2], size, 0.0, W, W // 2, camera_height=1.6).extent
        dets.append(DetectedObject(cls, box, size, 0.0))
    cfg = SamplerConfig.improved() if mode == "improved" else SamplerConfig()
    prob = _Problem(lik, dets, orientation_likelihood(None, ["plant", "chair"]), cfg, W, W // 2)
    assert pair_overlap_areas(start, np.zeros(2), prob.size2)[0, 1] > 0.01
    _, xy, yaw = prob.repair(1.0, start.copy(), np.zeros(2), grow_scale=False)
    assert pair_overlap_areas(xy, yaw, prob.size2)[0, 1] <= cfg.overlap_tol
    assert prob.object_ok(np.ones(1), xy[None], yaw[None])[0].all()
    if mode == "improved":
        np.testing.assert_array_equal(xy, start)
        assert yaw[1] == 0.0 and 5.0 < abs(math.degrees(yaw[0])) <= 45.0
    else:
        assert np.abs(xy - start).max() > 0.05 and np.all(yaw == 0.0)


def test_impossible_scene_raises():
    pl, labels, dets, floor0, ceil0 = synthetic(6)
    lik = surface_likelihood(observe_labels(labels, width=128), floor0, ceil0, 1.6)
    huge = DetectedObject("wardrobe", [200.0, 100.0, 300.0, 200.0], [30.0, 30.0, 2.0], 0.0)
    with pytest.raises(PosteriorError, match="expected a hypothesis with every object inside the room"):
        map_estimate(lik, [huge], image_width=W, image_height=W // 2,
                     config=SamplerConfig(epochs=2, samples_per_epoch=5), rng=0)


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 10_000), st.floats(-0.3, 0.3), st.sampled_from(["paper", "improved"]))
def test_never_invalid_never_nan(seed, box_shift, mode):
    """Whatever the boxes (even shifted off their objects), the result is valid and finite, or an error."""
    pl, labels, dets, floor0, ceil0 = synthetic(seed % 50)
    moved = [DetectedObject(d.cls, d.bbox_pano + np.array([box_shift, 0, box_shift, 0]) * 40, d.size, d.yaw,
                            symmetric=d.symmetric) for d in dets]
    lik = surface_likelihood(observe_labels(labels, [d.bbox_pano for d in moved], width=128,
                                            object_pixels="matched"), floor0, ceil0, 1.6)
    cfg = (SamplerConfig(epochs=3, samples_per_epoch=8) if mode == "paper"
           else SamplerConfig.improved(epochs=2, samples_per_epoch=6))
    try:
        res = map_estimate(lik, moved, image_width=W, image_height=W // 2, config=cfg, rng=seed)
    except PosteriorError:
        return
    check_valid(res.scene)
    assert np.isfinite(res.history).all() and np.isfinite(res.energies.as_array()).all()


def test_no_objects_keeps_the_initial_scale():
    _, labels, _, floor0, ceil0 = synthetic(7)
    lik = surface_likelihood(observe_labels(labels, width=128), floor0, ceil0, 1.6)
    res = map_estimate(lik, [], image_width=W, image_height=W // 2, config=SamplerConfig(epochs=2), rng=0)
    assert res.scene.objects == () and res.scene.wall_height == pytest.approx(2.5)
    res = map_estimate(lik, [], image_width=W, image_height=W // 2, config=SamplerConfig.improved(epochs=2), rng=0)
    assert res.scene.scale == pytest.approx(1.0)  # no object, no scale cue: the assumed camera height stays


def test_fixed_scale():
    """A one-point wall-height range fixes the scale (a known camera height), in both schemes."""
    pl, labels, dets, floor0, ceil0 = synthetic(10)
    lik = surface_likelihood(observe_labels(labels, [d.bbox_pano for d in dets], width=128,
                                            object_pixels="matched"), floor0, ceil0, 1.6)
    wh = pl.room.ceiling_z
    for cfg in (SamplerConfig(epochs=3, samples_per_epoch=5), SamplerConfig.improved(epochs=3, samples_per_epoch=5)):
        fixed = replace(cfg, wall_height_range=(wh, wh), initial_wall_height=wh)
        res = map_estimate(lik, dets, image_width=W, image_height=W // 2, config=fixed, rng=0)
        assert res.scene.wall_height == pytest.approx(wh) and res.history[:, 5] == pytest.approx(wh)
        check_valid(res.scene)


def test_orientation_energy_forms_are_accepted():
    pl, labels, dets, floor0, ceil0 = synthetic(8)
    lik = surface_likelihood(observe_labels(labels, width=128), floor0, ceil0, 1.6)
    cfg = SamplerConfig(epochs=2, samples_per_epoch=5)
    by_class = map_estimate(lik, dets, image_width=W, image_height=W // 2, config=cfg, rng=0,
                            orientation=lambda cls, y: 1.0 - np.cos(y))
    tables = map_estimate(lik, dets, image_width=W, image_height=W // 2, config=cfg, rng=0,
                          orientation=[np.cos(np.linspace(0, 2 * np.pi, 36, endpoint=False))] * len(dets))
    assert by_class.energies.orientation > 0 and math.isfinite(tables.energies.orientation)


def test_config_and_input_errors():
    with pytest.raises(ValueError, match="mode: expected 'paper' or 'improved'"):
        SamplerConfig(mode="fast")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="epochs: expected an integer >= 1"):
        SamplerConfig(epochs=0)
    with pytest.raises(ValueError, match="wall_height_range: expected 0 < low <= high"):
        SamplerConfig(wall_height_range=(3.0, 2.0))
    with pytest.raises(ValueError, match="initial_wall_height: expected a value in"):
        SamplerConfig(initial_wall_height=4.0)
    with pytest.raises(ValueError, match="alignment: expected modes in"):
        SamplerConfig(alignment={"bed": "sideways"})
    with pytest.raises(ValueError, match="bbox_pano: expected finite"):
        DetectedObject("bed", [0, 10, 5, 5], [1, 1, 1], 0.0)
    with pytest.raises(ValueError, match=r"size: expected \(l, w, h\)"):
        DetectedObject("bed", [0, 0, 5, 5], [1, 0, 1], 0.0)
    _, labels, dets, floor0, ceil0 = synthetic(9)
    lik = surface_likelihood(observe_labels(labels, width=128), floor0, ceil0, 1.6)
    twins = [dets[0], DetectedObject(dets[1].cls, dets[1].bbox_pano, dets[1].size, dets[1].yaw, id="bed-0")]
    with pytest.raises(ValueError, match="objects: expected unique ids, got 'bed-0' twice"):
        map_estimate(lik, twins, image_width=W, image_height=W // 2)
    with pytest.raises(ValueError, match="objects: expected DetectedObject items, got dict"):
        map_estimate(lik, [{"cls": "bed"}], image_width=W, image_height=W // 2)  # type: ignore[list-item]
    with pytest.raises(ValueError, match="likelihood: expected a SurfaceLikelihood"):
        map_estimate(None, dets, image_width=W, image_height=W // 2)  # type: ignore[arg-type]


def _plant_vertices():
    """A potted plant: a 0.3 m pot under a 0.8 m wide crown (vertices of two stacked boxes)."""
    pot = [[x, y, z] for x in (-0.15, 0.15) for y in (-0.15, 0.15) for z in (0.0, 0.35)]
    crown = [[x, y, z] for x in (-0.4, 0.4) for y in (-0.4, 0.4) for z in (0.35, 1.2)]
    return np.array(pot + crown, float)


def test_outline_removes_the_cuboid_bias_of_a_narrow_base():
    """The lowest point of a plant is its pot, inside the cuboid of its crown: the cuboid puts the floor
    contact too near and the camera too high; the hull outline gives the true camera height."""
    from layout.sampler import hull_outline
    from panogeom.coords import world_to_pixel

    v = _plant_vertices()
    cam = 1.55
    uv = world_to_pixel(hull_outline(v, spacing=0.005) + [2.5, 1.0, 0.0], 1024, 512, camera_height=cam)
    box = [uv[:, 0].min(), uv[:, 1].min(), uv[:, 0].max(), uv[:, 1].max()]
    size = [0.8, 0.8, 1.2]
    plain = DetectedObject("plant", box, size, 0.0)
    outlined = DetectedObject("plant", box, size, 0.0, outline=hull_outline(v))
    h_plain = initialise_objects([plain], 1024, 512).fitted_camera_heights[0]
    h_outl = initialise_objects([outlined], 1024, 512).fitted_camera_heights[0]
    assert abs(h_plain - cam) > 0.01  # the bias the outline is for
    assert h_outl == pytest.approx(cam, abs=0.002)
    with pytest.raises(ValueError, match="outline"):
        DetectedObject("plant", box, size, 0.0, outline=np.zeros((2, 3)))


def _cuboids(boxes) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (8 K, 3) and triangles (12 K, 3) of K axis-aligned cuboids ``(x0, y0, z0, x1, y1, z1)``."""
    quads = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    verts, faces = [], []
    for k, (x0, y0, z0, x1, y1, z1) in enumerate(boxes):
        verts += [[x, y, z] for x in (x0, x1) for y in (y0, y1) for z in (z0, z1)]
        faces += [[8 * k + q[i] for i in t] for q in quads for t in ((0, 1, 2), (0, 2, 3))]
    return np.array(verts, float), np.array(faces)


def test_mesh_outline_follows_the_legs_where_the_hull_spans_the_gap():
    """A bed on four legs seen from near its foot: the hull's lowest edge runs along the floor between the
    legs, below what the image shows, and puts the camera too low (1.42 m for 1.5); the mesh outline does not."""
    from layout.sampler import hull_outline, mesh_outline
    from panogeom.coords import world_to_pixel

    legs = [(sx * 0.95 - 0.05, sy * 0.75 - 0.05, 0.0, sx * 0.95 + 0.05, sy * 0.75 + 0.05, 0.3)
            for sx in (-1, 1) for sy in (-1, 1)]
    v, f = _cuboids(legs + [(-1.0, -0.8, 0.3, 1.0, 0.8, 0.6)])
    cam, at = 1.5, np.array([1.9, 0.2, 0.0])  # its foot (+x, turned to face the camera) 0.9 m away
    rot = np.array([[-1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]])
    # the image extent of the surface: the mesh's edges sampled every 5 mm (a face's extremes lie on its edges)
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    t = np.linspace(0.0, 1.0, 401)[:, None, None]
    dense = (v[e[:, 0]] + t * (v[e[:, 1]] - v[e[:, 0]])).reshape(-1, 3)
    uv = world_to_pixel(dense @ rot.T + at, 1024, 512, camera_height=cam)
    box = [uv[:, 0].min(), uv[:, 1].min(), uv[:, 0].max(), uv[:, 1].max()]
    size = [2.0, 1.6, 0.6]
    fits = {}
    for name, outline in (("hull", hull_outline(v)), ("mesh", mesh_outline(v, f))):
        assert len(outline) <= 400
        det = DetectedObject("bed", box, size, np.pi, outline=outline)
        fits[name] = initialise_objects([det], 1024, 512).fitted_camera_heights[0]
    assert abs(fits["hull"] - cam) > 0.03  # the bias the mesh outline is for
    assert fits["mesh"] == pytest.approx(cam, abs=0.005)
    assert len(mesh_outline(v, f, max_points=10)) == 10
    for bad in ({"faces": f[:, :2]}, {"faces": f + 100}, {"vertices": v[:3]}, {"spacing": 0.0}):
        kw = {"vertices": v, "faces": f, **bad}
        with pytest.raises(ValueError):
            mesh_outline(**kw)


def test_box_scale_and_fixed_sampled_scale():
    """box_scale gives the improved initialisation's scale; sample_scale=False keeps it through the sampling."""
    from layout.sampler import box_scale

    pl, labels, dets, floor0, ceil0 = synthetic(3, yaw_noise_deg=0.0)
    lam, centers = box_scale(dets, W, W // 2, 1.6, ceil0)
    assert lam * 1.6 == pytest.approx(pl.camera_height, rel=0.01)
    assert np.allclose(centers[:, :2], pl.centers[:, :2], atol=0.05)
    lik = surface_likelihood(observe_labels(labels, [d.bbox_pano for d in dets], width=128,
                                            object_pixels="matched"), floor0, ceil0, 1.6)
    cfg = SamplerConfig.improved(epochs=4, samples_per_epoch=6, sample_scale=False)
    res = map_estimate(lik, dets, image_width=W, image_height=W // 2, config=cfg, rng=0)
    assert res.scene.scale == pytest.approx(lam) and np.all(res.history[:, 5] == res.history[0, 5])
    check_valid(res.scene)


def test_box_term_is_zero_at_the_truth_and_grows_off_it():
    """E_b: predicted box edges against the detection boxes, robust (at most 1 per edge)."""
    pl, labels, dets, floor0, ceil0 = synthetic(5, yaw_noise_deg=0.0)
    lik = surface_likelihood(observe_labels(labels, [d.bbox_pano for d in dets], width=128,
                                            object_pixels="matched"), floor0, ceil0, 1.6)
    cfg = SamplerConfig.improved(epochs=3, samples_per_epoch=5, box_weight=10.0)
    lam = pl.camera_height / 1.6
    from layout.sampler import _Problem
    from layout.likelihood import orientation_likelihood

    prob = _Problem(lik, dets, orientation_likelihood(None, [d.cls for d in dets]), cfg, W, W // 2)
    xy, yaw = pl.centers[None, :, :2], pl.yaws[None]
    moved = xy + np.array([0.3, 0.0])
    e = prob.box_energy(np.array([lam, lam, lam * 1.1]), np.concatenate([xy, moved, xy]), np.repeat(yaw, 3, 0))
    assert e[0] < 0.05 and e[1] > e[0] + 1.0 and e[2] > e[0] + 0.5 and np.all(e <= 4 * len(dets))
    res = map_estimate(lik, dets, image_width=W, image_height=W // 2, config=cfg, rng=0)
    assert res.energies.box >= 0 and res.energies.total >= cfg.box_weight * res.energies.box - 1e-9
    check_valid(res.scene)
    with pytest.raises(ValueError, match="box_weight"):
        SamplerConfig(box_weight=-1.0)


def test_one_object_inside_test_agrees_with_the_all_objects_test():
    """The repair step tests only the object it moves (``object_ok(which=j)``): the same answer as the test of
    every object, column j, for footprints inside, through a wall and on the camera."""
    pl, labels, dets, floor0, ceil0 = synthetic(5, yaw_noise_deg=0.0)
    lik = surface_likelihood(observe_labels(labels, [d.bbox_pano for d in dets], width=128,
                                            object_pixels="matched"), floor0, ceil0, 1.6)
    from layout.sampler import _Problem
    from layout.likelihood import orientation_likelihood

    prob = _Problem(lik, dets, orientation_likelihood(None, [d.cls for d in dets]), SamplerConfig.improved(), W,
                    W // 2)
    rng = np.random.default_rng(0)
    n = len(dets)
    lam = np.full(64, pl.camera_height / 1.6)
    xy = pl.centers[None, :, :2] + rng.normal(0.0, 0.8, (64, n, 2))
    xy[:4] = 0.05  # on the camera
    yaw = pl.yaws[None] + rng.normal(0.0, 0.5, (64, n))
    every = prob.object_ok(lam, xy, yaw)
    assert every.any() and not every.all()
    for j in range(n):
        one = prob.object_ok(lam, xy[:, [j]], yaw[:, [j]], which=j)
        assert one.shape == (64, 1) and np.array_equal(one[:, 0], every[:, j])


@pytest.mark.parametrize("seed", [3, 6])
def test_flip_moves_turn_a_back_to_front_object_round(seed):
    """A bed and a TV whose pose estimates point 180 degrees the wrong way (the HOG pose's common failure) are
    turned round by the flip proposals: their backs belong against a wall. Without flips they stay wrong."""
    pl, labels, dets, floor0, ceil0 = synthetic(seed)
    dets = [replace(d, yaw=d.yaw + math.pi) if d.cls in ("bed", "tv") else d for d in dets]
    obs = observe_labels(labels, [d.bbox_pano for d in dets], width=256, object_pixels="matched")
    lik = surface_likelihood(obs, floor0, ceil0, 1.6)

    def yaw_errors(cfg):
        res = map_estimate(lik, dets, image_width=W, image_height=W // 2, config=cfg, rng=seed)
        check_valid(res.scene)
        return [abs(math.remainder(o.yaw - g.yaw, 2 * math.pi)) for o, g in zip(res.scene.objects, pl.objects)
                if g.class_name in ("bed", "tv")]

    assert SamplerConfig.improved().flip_moves and not SamplerConfig().flip_moves
    assert max(yaw_errors(SamplerConfig.improved(n_samples=400))) < math.radians(10.0)
    assert min(yaw_errors(SamplerConfig.improved(n_samples=400, flip_moves=False, quarter_moves=False))) \
        > math.radians(90.0)


@pytest.mark.parametrize("seed", [3, 6])
def test_turns_are_not_offered_where_e_o_is_sure_of_the_yaw(seed):
    """The flipped bed and TV of the test above, with an E_o that prefers their (wrong) yaws: ``rise`` higher
    turned round, ``rise / 2`` turned by 90 degrees. A rise below ``turn_eo_margin`` lets the flips through; one
    above it stops them, although the room evidence would have paid for the turn (no margin: turned)."""
    pl, labels, dets, floor0, ceil0 = synthetic(seed)
    dets = [replace(d, yaw=d.yaw + math.pi) if d.cls in ("bed", "tv") else d for d in dets]
    obs = observe_labels(labels, [d.bbox_pano for d in dets], width=256, object_pixels="matched")
    lik = surface_likelihood(obs, floor0, ceil0, 1.6)

    def yaw_errors(rise, margin):
        eo = [(lambda y, y0=d.yaw: 0.5 * rise * (1.0 - np.cos(y - y0))) if d.cls in ("bed", "tv") else None
              for d in dets]
        cfg = SamplerConfig.improved(n_samples=400, turn_eo_margin=margin)
        res = map_estimate(lik, dets, image_width=W, image_height=W // 2, orientation=eo, config=cfg, rng=seed)
        check_valid(res.scene)
        return [abs(math.remainder(o.yaw - g.yaw, 2 * math.pi)) for o, g in zip(res.scene.objects, pl.objects)
                if g.class_name in ("bed", "tv")]

    assert SamplerConfig.improved().turn_eo_margin == 0.3 and SamplerConfig().turn_eo_margin == math.inf
    assert max(yaw_errors(0.1, 0.3)) < math.radians(10.0)
    assert min(yaw_errors(0.6, 0.3)) > math.radians(90.0)
    assert max(yaw_errors(0.6, math.inf)) < math.radians(10.0)
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="turn_eo_margin"):
            SamplerConfig(turn_eo_margin=bad)


def test_quarter_moves_turn_side_on_objects_round():
    """Beds whose pose estimates are 90 degrees off (a HOG side view), in 8 rooms: the quarter-turn proposals,
    each refitted to its box, turn most of them back; without them the yaw proposals (0.32 rad) never get
    there. A thin footprint (a TV) is never turned by 90 degrees, and neither is a bed whose E_o rises by more
    than ``turn_eo_margin`` at the turned yaws."""

    def turned(cfg, cls="bed", rise=0.0):
        ok = 0
        for seed in range(8):
            pl, labels, dets, floor0, ceil0 = synthetic(seed)
            dets = [replace(d, yaw=d.yaw + 0.5 * math.pi) if d.cls == cls else d for d in dets]
            obs = observe_labels(labels, [d.bbox_pano for d in dets], width=256, object_pixels="matched")
            lik = surface_likelihood(obs, floor0, ceil0, 1.6)
            eo = [(lambda y, y0=d.yaw: rise * np.sin(y - y0) ** 2) if d.cls == cls else None for d in dets]
            try:
                res = map_estimate(lik, dets, image_width=W, image_height=W // 2, orientation=eo, config=cfg,
                                   rng=seed)
            except PosteriorError:
                continue
            check_valid(res.scene)
            ok += sum(abs(math.remainder(o.yaw - g.yaw, 2 * math.pi)) < math.radians(10.0)
                      for o, g in zip(res.scene.objects, pl.objects) if g.class_name == cls)
        return ok

    assert SamplerConfig.improved().quarter_moves and not SamplerConfig().quarter_moves
    assert turned(SamplerConfig.improved(n_samples=400, box_weight=0.0)) >= 6  # of 8
    # the box term (the default) holds each bed to the box fit of its current yaw: it turns fewer back (as on the
    # tuning sets, docs/EVALUATION.md session 23), still most
    assert turned(SamplerConfig.improved(n_samples=400)) >= 5
    assert turned(SamplerConfig.improved(n_samples=400, quarter_moves=False)) == 0
    assert turned(SamplerConfig.improved(n_samples=400), cls="tv") == 0
    assert turned(SamplerConfig.improved(n_samples=400, box_weight=0.0), rise=0.5) == 0
    assert turned(SamplerConfig.improved(n_samples=400, box_weight=0.0, turn_eo_margin=math.inf), rise=0.5) >= 6


def test_a_given_scale_starts_the_improved_scheme_at_the_box_fit():
    """With the wall height given (a known camera height), the improved scheme's initial positions are fitted to
    all four box edges at that height; the paper's keep the width-only initialisation."""
    pl, labels, dets, floor0, ceil0 = synthetic(10, yaw_noise_deg=8.0)
    lik = surface_likelihood(observe_labels(labels, [d.bbox_pano for d in dets], width=128,
                                            object_pixels="matched"), floor0, ceil0, 1.6)
    truth = pl.centers[:, :2] * (1.6 / pl.camera_height)  # the likelihood's frame: camera 1.6 high
    errs = {}
    for cfg in (SamplerConfig(epochs=1, samples_per_epoch=2), SamplerConfig.improved(epochs=1, samples_per_epoch=2)):
        fixed = replace(cfg, wall_height_range=(ceil0, ceil0), initial_wall_height=ceil0)
        res = map_estimate(lik, dets, image_width=W, image_height=W // 2, config=fixed, rng=0)
        got = np.array([o.center[:2] for o in res.initial.objects])
        errs[cfg.mode] = np.hypot(*(got - truth).T)
    centers = initialise_objects(dets, W, W // 2).centers
    init = centers[:, :2]
    fitted = fit_boxes(dets, centers, W, W // 2, camera_height=1.6)[0][:, :2]
    assert np.allclose(errs["paper"], np.hypot(*(init - truth).T), atol=1e-9)
    assert np.allclose(errs["improved"], np.hypot(*(fitted - truth).T), atol=1e-9)
    assert errs["improved"].mean() < errs["paper"].mean()


def test_the_sampler_keeps_the_outline_and_edge_weights_of_its_objects():
    """map_estimate fits its initial positions with each object's outline and edge weights (as fit_boxes does
    with the same objects), not with the size cuboid: an object given an id and one without are placed alike."""
    from layout.sampler import hull_outline
    from panogeom.coords import world_to_pixel

    v = _plant_vertices()
    cam = 1.55
    uv = world_to_pixel(hull_outline(v, spacing=0.005) + [2.5, 1.0, 0.0], 1024, 512, camera_height=cam)
    box = [uv[:, 0].min(), uv[:, 1].min(), uv[:, 0].max(), uv[:, 1].max()]
    plant = DetectedObject("plant", box, [0.8, 0.8, 1.2], 0.0, outline=hull_outline(v),
                           edge_weights=[1.0, 0.0, 1.0, 1.0])
    floor = np.array([[-4.0, -4.0], [5.0, -4.0], [5.0, 5.0], [-4.0, 5.0]])
    labels = np.full((256, 512), 3, np.uint8)
    labels[:80], labels[180:] = 2, 1
    lik = surface_likelihood(observe_labels(labels, [box], width=128, object_pixels="matched"), floor, 2.6, cam)
    cfg = SamplerConfig.improved(n_samples=1, initial_camera_height=cam)
    want = fit_boxes([plant], initialise_objects([plant], 1024, 512).centers, 1024, 512, camera_height=cam)[0]
    cuboid = fit_boxes([replace(plant, outline=None, edge_weights=None)],
                       initialise_objects([plant], 1024, 512).centers, 1024, 512, camera_height=cam)[0]
    assert np.linalg.norm(want[0, :2] - [2.5, 1.0]) < 0.02
    assert np.linalg.norm(cuboid[0, :2] - [2.5, 1.0]) > 0.1  # what the sampler started from before
    for obj in (plant, replace(plant, id="plant-7")):
        res = map_estimate(lik, [obj], image_width=1024, image_height=512, config=cfg, rng=0)
        assert np.allclose(res.initial.objects[0].center[:2], want[0, :2], atol=1e-9)


def test_a_cut_edge_pulls_weakly_where_the_object_reaches_beyond_it():
    """cut_edges: the visible box of an object cut on the right by an occluder ends short of the object. The
    fit with that edge cut places it near where it is (a two-sided edge pulls it away); with every edge cut,
    the object is still held to its box from both sides."""
    from panogeom.coords import world_to_pixel

    size, cam, center = np.array([0.6, 0.6, 0.8]), 1.5, np.array([2.5, 0.8, 0.4])
    corners = np.array([[x, y, z] for x in (-0.3, 0.3) for y in (-0.3, 0.3) for z in (0.0, 0.8)]) + [2.5, 0.8, 0.0]
    uv = world_to_pixel(corners, 1024, 512, camera_height=cam)
    full = np.array([uv[:, 0].min(), uv[:, 1].min(), uv[:, 0].max(), uv[:, 1].max()])
    cut_box = full.copy()
    cut_box[2] -= 0.4 * (full[2] - full[0])  # an occluder hides the right 40 %
    start = [center * [1.2, 1.2, 1.0]]

    def fit(box, **kw):
        o = DetectedObject("chair", box, size, 0.0, **kw)
        return fit_boxes([o], start, 1024, 512, camera_height=cam)[0][0, :2]

    assert np.linalg.norm(fit(full) - center[:2]) < 0.01
    two_sided = np.linalg.norm(fit(cut_box) - center[:2])
    assert two_sided > 0.1  # the cut edge taken for the object's own
    cut = np.linalg.norm(fit(cut_box, cut_edges=[False, False, True, False]) - center[:2])
    assert cut < min(0.05, 0.4 * two_sided)  # only CUT_EDGE_BEYOND's weak pull is left
    # every edge cut: from behind, pulled in until the object covers its box; from in front, pushed back, since
    # the top of an object below the camera drops inside the box as it comes nearer
    every = DetectedObject("chair", full, size, 0.0, cut_edges=[True] * 4)
    for s in (1.6, 0.8):
        got = fit_boxes([every], [center * [s, s, 1.0]], 1024, 512, camera_height=cam)[0][0, :2]
        assert np.linalg.norm(got - center[:2]) < 0.03
    with pytest.raises(ValueError, match="cut_edges"):
        DetectedObject("chair", full, size, 0.0, cut_edges=[1, 0, 0, 0])


def test_snap_to_walls_in_a_turned_room():
    t = math.radians(20.0)
    rot = np.array([[math.cos(t), math.sin(t)], [-math.sin(t), math.cos(t)]])
    room = np.array([[0, 0], [4, 0], [4, 3], [2, 3], [2, 5], [0, 5]], float) @ rot
    yaw = np.radians([20.0 + 4.0, 110.0 - 9.9, 20.0 + 45.0, 200.0 + 10.5, -70.0 + 0.1])
    got = np.degrees(snap_to_walls(yaw, room, math.radians(10.0)))
    assert np.allclose(got, [20.0, 110.0, 65.0, 210.5, -70.0])
    assert np.array_equal(snap_to_walls(yaw, room, 0.0), yaw)
    with pytest.raises(ValueError, match="max_angle"):
        snap_to_walls(yaw, room, -0.1)


def test_map_estimate_snaps_yaws_onto_the_walls():
    """Pose estimates 6 degrees off the (axis-aligned) walls and an E_o that holds them there: with the snap the
    asymmetric objects end square to the walls, without it they do not; the plant keeps its yaw."""
    pl, labels, dets, floor0, ceil0 = synthetic(3, yaw_noise_deg=0.0)
    dets = [d if d.symmetric else replace(d, yaw=round(d.yaw / (math.pi / 2)) * math.pi / 2 + math.radians(6.0))
            for d in dets]
    obs = observe_labels(labels, [d.bbox_pano for d in dets], width=256, object_pixels="matched")
    lik = surface_likelihood(obs, floor0, ceil0, 1.6)
    eo = [None if d.symmetric else (lambda y, m=d.yaw: 5.0 * (1.0 - np.cos(y - m))) for d in dets]

    def off_axis_deg(snap):
        cfg = SamplerConfig.improved(n_samples=300, snap_yaw_deg=snap)
        res = map_estimate(lik, dets, image_width=W, image_height=W // 2, orientation=eo, config=cfg, rng=0)
        check_valid(res.scene)
        return [abs(math.degrees(math.remainder(o.yaw, math.pi / 2))) for o, d in zip(res.scene.objects, dets)
                if not d.symmetric], res

    assert SamplerConfig.improved().snap_yaw_deg == 10.0 and SamplerConfig().snap_yaw_deg == 0.0
    free, _ = off_axis_deg(0.0)
    assert max(free) > 2.0
    snapped, res = off_axis_deg(10.0)
    assert max(snapped) < 1e-9
    plant = [o for o, d in zip(res.scene.objects, dets) if d.symmetric][0]
    assert plant.yaw == pytest.approx(dets[[d.symmetric for d in dets].index(True)].yaw)
    with pytest.raises(ValueError, match="snap_yaw_deg"):
        SamplerConfig(snap_yaw_deg=50.0)


def test_snap_keeps_a_yaw_whose_turn_would_overlap_a_neighbour():
    """Two beds turned 8 degrees, side by side and touching: turning either onto the walls swings its corners
    into the other, so only a snap that keeps the hypothesis valid is taken."""
    pl, labels, dets, floor0, ceil0 = synthetic(3, yaw_noise_deg=0.0)
    lik = surface_likelihood(observe_labels(labels, width=128), floor0, ceil0, 1.6)
    bed = [d for d in dets if d.cls == "bed"][0]
    beds = [replace(bed, id="a"), replace(bed, id="b")]
    cfg = SamplerConfig.improved(keep_in_box=False)  # the boxes are the true bed's, not these two
    prob = _Problem(lik, beds, orientation_likelihood(None, ["bed", "bed"]), cfg, W, W // 2)
    t = math.radians(8.0)
    across = np.array([-math.sin(t), math.cos(t)]) * (bed.size[1] + 1e-3)  # 1 mm apart along their widths
    mid = np.array([-3.0, -1.2])  # well inside the 6.9 x 4.1 m room, 3.2 m from the camera
    assert points_in_polygon(mid, floor0)
    xy = np.array([mid - across / 2, mid + across / 2])
    yaw = np.array([t, t])
    assert prob.evaluate(np.array([1.0]), xy[None], yaw[None]).violation[0] == 0
    both = yaw.copy()
    both[:] = 0.0
    assert prob.evaluate(np.array([1.0]), xy[None], both[None]).violation[0] > 0
    got, evaluated = _snap_yaws(prob, 1.0, xy, yaw, math.radians(10.0))
    assert evaluated == 2
    assert prob.evaluate(np.array([1.0]), xy[None], got[None]).violation[0] == 0
    assert np.count_nonzero(got != yaw) <= 1


def test_improved_yaw_moves_are_narrow_and_keep_right_yaws():
    """The improved scheme proposes yaws with variance 0.003 rad^2 (the paper's 0.1 in paper mode): right initial
    yaws, held by an E_o, end within half a degree of the start without the wall snap."""
    assert SamplerConfig.improved().yaw_variance == 0.003 and SamplerConfig().yaw_variance == 0.1
    pl, labels, dets, floor0, ceil0 = synthetic(3, yaw_noise_deg=0.0)
    obs = observe_labels(labels, [d.bbox_pano for d in dets], width=256, object_pixels="matched")
    lik = surface_likelihood(obs, floor0, ceil0, 1.6)
    eo = [None if d.symmetric else (lambda y, m=d.yaw: 5.0 * (1.0 - np.cos(y - m))) for d in dets]
    cfg = SamplerConfig.improved(n_samples=600, snap_yaw_deg=0.0)
    res = map_estimate(lik, dets, image_width=W, image_height=W // 2, orientation=eo, config=cfg, rng=0)
    check_valid(res.scene)
    off = [abs(math.degrees(math.remainder(o.yaw - d.yaw, 2 * math.pi)))
           for o, d in zip(res.scene.objects, dets) if not d.symmetric]
    assert len(off) == 3 and max(off) < 0.5


def test_yaw_moves_are_wide_while_the_seed_is_invalid():
    """``invalid_yaw_variance``: an epoch whose seed violates a hard constraint draws its yaw moves with that
    variance (the improved scheme: the paper's 0.1), a valid seed with ``yaw_variance`` (0.003)."""
    from layout.sampler import _improved_epoch, _Problem, _State

    pl, labels, dets, floor0, ceil0 = synthetic(5, yaw_noise_deg=0.0)
    lik = surface_likelihood(observe_labels(labels, [d.bbox_pano for d in dets], width=128,
                                            object_pixels="matched"), floor0, ceil0, 1.6)
    cfg = SamplerConfig.improved(n_samples=300)
    assert cfg.yaw_variance == 0.003 and cfg.invalid_yaw_variance == 0.1 and SamplerConfig().invalid_yaw_variance is None
    prob = _Problem(lik, dets, orientation_likelihood(None, [d.cls for d in dets]), cfg, W, W // 2)
    lam = pl.camera_height / 1.6
    n = len(dets)

    class Recorder:
        """A numpy Generator that records the scales of the zero-mean normal draws of shape (n, s): the yaw moves."""

        def __init__(self):
            self.g, self.scales = np.random.default_rng(0), []

        def normal(self, loc=0.0, scale=1.0, size=None):
            if size == (n, int(cfg.samples_per_epoch)) and loc == 0.0:
                self.scales.append(float(scale))
            return self.g.normal(loc, scale, size)

        def __getattr__(self, name):
            return getattr(self.g, name)

    xy_ok, yaw_ok = pl.centers[:, :2].copy(), pl.yaws.copy()
    xy_bad = xy_ok.copy()
    xy_bad[0] = 0.02  # on the camera
    for xy, expected in ((xy_ok, 0.003), (xy_bad, 0.1)):
        seed = prob.evaluate(np.array([lam]), xy[None], yaw_ok[None])
        assert (seed.violation[0] > 0) == (expected == 0.1)
        rec = Recorder()
        _improved_epoch(prob, _State(lam, xy.copy(), yaw_ok.copy(), float(seed.key[0]), seed), 1.0, rec)
        assert rec.scales == [pytest.approx(math.sqrt(expected))]
    with pytest.raises(ValueError, match="invalid_yaw_variance"):
        SamplerConfig(invalid_yaw_variance=0.0)


def test_repair_never_turns_a_plant_onto_another_object():
    """The turn that clears the plant of one chair would put it on a second chair: the plant is not turned (one of
    them slides instead), so the repair cannot swap one overlap for another."""
    _, labels, _, _, _ = synthetic(5)
    floor = np.array([[-3.0, -2.0], [4.0, -2.0], [4.0, 2.5], [-3.0, 2.5]])
    lik = surface_likelihood(observe_labels(labels, width=128), floor, 2.6, 1.6)
    # chair 1 clips the plant's square corner; chair 2 sits where the turned plant's diamond tip would reach
    start = np.array([[2.0, 0.0], [2.62, 0.62], [2.0, 0.86]])
    dets = []
    for (x, y), cls, size in zip(start, ("plant", "chair", "chair"), ((1.0, 1.0, 1.0), (0.5, 0.5, 0.9),
                                                                       (0.5, 0.5, 0.9))):
        box = world_box_to_pano(np.r_[x, y, size[2] / 2], size, 0.0, W, W // 2, camera_height=1.6).extent
        dets.append(DetectedObject(cls, box, size, 0.0))
    prob = _Problem(lik, dets, orientation_likelihood(None, ["plant", "chair", "chair"]), SamplerConfig.improved(),
                    W, W // 2)
    pair = pair_overlap_areas(start, np.zeros(3), prob.size2)
    assert pair[0, 1] > 0.01 and pair[0, 2] == 0.0 and pair[1, 2] == 0.0
    turns, fit = prob._turns_in_place(1.0, start[0], 0.0, 0)
    cand = np.zeros((len(turns), 3))
    cand[:, 0] = turns
    areas = pair_overlap_areas(np.broadcast_to(start, (len(turns), 3, 2)), cand, prob.size2)
    assert np.any(fit & (areas[:, 0, 1] <= 1e-4)) and not np.any(fit & (areas[:, 0].max(axis=-1) <= 1e-4))
    _, xy, yaw = prob.repair(1.0, start.copy(), np.zeros(3), grow_scale=False)
    assert yaw[0] == 0.0
    assert pair_overlap_areas(xy, yaw, prob.size2)[np.triu_indices(3, 1)].max() <= 1e-4
