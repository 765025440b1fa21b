"""Tests of layout.scene: walls, objects, scenes and their JSON (scene@1, gt@1)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from layout.scene import GT_SCHEMA, SCENE_SCHEMA, Scene, SceneObject, scene_walls
from panogeom.coords import world_to_pixel
from panogeom.project import world_box_corners

L_ROOM = [[-1.0, -1.0], [3.0, -1.0], [3.0, 1.0], [1.0, 1.0], [1.0, 2.5], [-1.0, 2.5]]


def bed(yaw=0.5, **kw):
    return SceneObject("bed-0", "bed", [1.0, 0.0, 0.3], [2.0, 1.6, 0.6], yaw, "bed-03", 0.9, [10, 20, 30, 40], **kw)


def full_scene(**kw):
    objs = (bed(), SceneObject("plant-0", "plant", [-0.5, 2.0, 0.45], [0.4, 0.4, 0.9], 0.0))
    opts = dict(scale=1.07, image_file="pano.jpg", image_width=2048, image_height=1024, timing={"total": 1.5})
    opts.update(kw)
    return Scene(L_ROOM, 2.6, 1.55, objs, **opts)


def test_scene_json_round_trip_through_text():
    s = full_scene()
    d = s.to_json_dict()
    assert d["schema"] == SCENE_SCHEMA
    assert list(d) == ["schema", "image", "camera", "room", "objects", "scale", "timing_s"]
    assert d["objects"][1] == {"id": "plant-0", "class": "plant", "center": [-0.5, 2.0, 0.45], "size": [0.4, 0.4, 0.9],
                               "yaw_deg": 0.0, "model": None, "score": None, "bbox_pano": None}
    back = Scene.from_json_dict(json.loads(json.dumps(d)))
    assert back.to_json_dict() == d
    assert back.objects[0].yaw == pytest.approx(0.5, abs=1e-12)
    assert np.array_equal(back.floor, s.floor) and back.timing["total"] == 1.5


def test_unknown_values_are_null_and_read_back_as_none():
    s = Scene(L_ROOM, None, 1.6, (), rotation=None)
    d = s.to_json_dict()
    assert d["room"]["ceiling_z"] is None and d["camera"]["rotation"] is None and d["scale"] is None
    assert d["image"] == {"file": None, "width": None, "height": None} and d["timing_s"] == {}
    back = Scene.from_json_dict(json.loads(json.dumps(d)))
    assert back.ceiling_z is None and back.rotation is None and back.wall_height is None
    assert [w.height for w in back.walls] == [None] * 6


@settings(max_examples=60, deadline=None)
@given(st.floats(-50.0, 50.0, allow_nan=False))
def test_yaw_deg_always_in_range_and_round_trips(yaw):
    o = bed(yaw)
    assert 0.0 <= o.yaw < 2 * math.pi
    d = o.to_json_dict()
    assert 0.0 <= d["yaw_deg"] < 360.0
    back = SceneObject.from_json_dict(d)
    assert math.isclose(math.cos(back.yaw - yaw), 1.0, abs_tol=1e-12)


def test_yaw_just_below_zero_does_not_become_360():
    o = bed(-1e-18)
    assert o.yaw == 0.0 and o.to_json_dict()["yaw_deg"] == 0.0
    assert bed(2 * math.pi).yaw_deg == 0.0


def test_object_geometry_matches_panogeom():
    o = bed(1.1)
    assert np.allclose(o.corners, world_box_corners(o.center, o.size, 1.1))
    assert np.allclose(o.footprint, o.corners[:4, :2])


def test_walls_of_an_l_shaped_room():
    ws = scene_walls(L_ROOM, 2.5)
    assert [w.label for w in ws] == [4, 3, 4, 3, 4, 3]
    assert [w.length for w in ws] == [4.0, 2.0, 2.0, 1.5, 2.0, 3.5]
    # inward normals: the first wall (y = -1) faces +y; wall 3 (x = 1, above the reflex corner) faces -x
    assert ws[0].normal.tolist() == [0.0, 1.0] and ws[3].normal.tolist() == [-1.0, 0.0]
    assert ws[2].midpoint.tolist() == [2.0, 1.0] and all(w.height == 2.5 for w in ws)
    assert [w.index for w in full_scene().walls] == list(range(6))


def test_gt_json_corners_and_round_trip():
    s = full_scene()
    g = s.to_gt_json_dict()
    assert g["schema"] == GT_SCHEMA and g["camera_height_m"] == 1.55
    c = np.array(g["corners_px"])
    assert c.shape == (6, 4)
    fl = np.column_stack([s.floor, np.zeros(6)])
    ce = np.column_stack([s.floor, np.full(6, 2.6)])
    assert np.allclose(c[:, 2:], world_to_pixel(fl, 2048, 1024, 1.55))
    assert np.allclose(c[:, :2], world_to_pixel(ce, 2048, 1024, 1.55))
    assert np.all(c[:, 1] < 512) and np.all(c[:, 3] > 512)  # ceiling corners above the horizon, floor below
    back = Scene.from_json_dict(json.loads(json.dumps(g)))
    assert back.to_gt_json_dict() == g and back.rotation is None


def test_gt_corners_null_without_image_size():
    assert full_scene(image_width=None, image_height=None).to_gt_json_dict()["corners_px"] is None


@pytest.mark.parametrize("mutate, msg", [
    (lambda d: d.update(schema="pano2cad/scene@2"), "schema: expected 'pano2cad/scene@1'"),
    (lambda d: d.pop("room"), "scene: expected a key 'room'"),
    (lambda d: d["room"].pop("floor"), "room: expected a key 'floor'"),
    (lambda d: d["room"].update(floor=[[0, 0], [2, 0], [1, 1]]), "not Manhattan"),
    (lambda d: d["room"].update(floor=[[0, 0], [0, 2], [2, 2], [2, 0]]), "not counter-clockwise"),
    (lambda d: d["room"].update(ceiling_z=-1.0), "ceiling_z: expected a value above floor_z"),
    (lambda d: d["camera"].update(height_m=0), "camera_height: expected a finite number > 0"),
    (lambda d: d["camera"].update(rotation=[[1, 0, 0], [0, 1, 0], [0, 0, -1]]), "rotation"),
    (lambda d: d["objects"][0].update(yaw_deg=360.0), r"objects\[0\].yaw_deg: expected a value in \[0, 360\)"),
    (lambda d: d["objects"][0].pop("yaw_deg"), r"objects\[0\]: expected a key 'yaw_deg'"),
    (lambda d: d["objects"][0].update(size=[1, 0, 1]), "bed-0.size: expected 3 numbers > 0"),
    (lambda d: d["objects"][0].update(bbox_pano=[1, 2, 3]), "bed-0.bbox_pano: expected 4 finite numbers"),
    (lambda d: d["objects"][0].update(model=3), r"objects\[0\].model: expected a string or null"),
    (lambda d: d["objects"][1].update(id="bed-0"), "expected unique ids"),
    (lambda d: d["objects"][0].update({"class": "Bed"}), "cls: expected a lowercase class name"),
    (lambda d: d.update(objects={}), "objects: expected a JSON list"),
    (lambda d: d["timing_s"].update(total=-1), "expected seconds >= 0"),
    (lambda d: d.update(scale="big"), "scale: expected a number or null"),
])
def test_bad_scene_json_names_the_problem(mutate, msg):
    d = json.loads(json.dumps(full_scene().to_json_dict()))
    mutate(d)
    with pytest.raises(ValueError, match=msg):
        Scene.from_json_dict(d)


def test_bad_gt_json():
    g = full_scene().to_gt_json_dict()
    g["corners_px"] = g["corners_px"][:3]
    with pytest.raises(ValueError, match=r"corners_px: expected shape \(6, 4\)"):
        Scene.from_json_dict(g)
    with pytest.raises(ValueError, match="schema: expected 'pano2cad/gt@1'"):
        Scene.from_gt_json_dict(full_scene().to_json_dict())
    with pytest.raises(ValueError, match="gt: expected a key 'camera_height_m'"):
        Scene.from_gt_json_dict({"schema": GT_SCHEMA, "room": {"floor": L_ROOM, "ceiling_z": 2.5}, "objects": []})


def test_millimetre_rounded_floor_is_accepted():
    rounded = (np.array(L_ROOM) * 1.2345678).round(3)
    assert Scene(rounded, 2.5, 1.6).floor.shape == (6, 2)


def test_constructor_checks():
    with pytest.raises(ValueError, match="image_width: expected a positive integer"):
        Scene(L_ROOM, 2.5, 1.6, image_width=0)
    with pytest.raises(ValueError, match="objects: expected SceneObject items"):
        Scene(L_ROOM, 2.5, 1.6, ({"id": "x"},))  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="id: expected a non-empty string"):
        SceneObject("", "bed", [0, 0, 0], [1, 1, 1], 0.0)
    with pytest.raises(ValueError, match="bed-0.center: expected 3 finite numbers"):
        SceneObject("bed-0", "bed", [0, np.nan, 0], [1, 1, 1], 0.0)
