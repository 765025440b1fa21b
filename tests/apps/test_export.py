"""Exports of ``pano2cad run``: scene.glb / scene.obj, floor plan, overlay, labels; all written atomically."""

import math
import pathlib
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import trimesh
from PIL import Image

from apps.export import EXPORT_FILES, export_all
from apps.export.colors import LABEL_PALETTE, class_color
from apps.export.floorplan import floorplan_figure, format_length, write_floorplan
from apps.export.labels import colorize_labels, write_labels
from apps.export.mesh import ROOM_NODES, export_glb, export_obj, object_transform, scene_to_trimesh
from apps.export.overlay import FLOOR_EDGE_RGB, box_parts, draw_overlay, layout_polylines, write_overlay
from layout.polygon import points_in_polygon, signed_area
from layout.scene import Scene, SceneObject
from panogeom.coords import world_to_pixel
from panogeom.project import world_box_to_pano
from panogeom.rotation import rot_z
from posecrf.library import ModelLibrary
from posecrf.library.export import Z_UP_TO_Y_UP
from posecrf.library.procedural import BED_SPECS, TV_SPECS, build_model

W, H = 1024, 512
L_ROOM = [[-2.0, -1.5], [3.0, -1.5], [3.0, 2.5], [1.0, 2.5], [1.0, 1.0], [-2.0, 1.0]]


@pytest.fixture(scope="module")
def lib():
    return ModelLibrary([build_model(BED_SPECS[0]), build_model(TV_SPECS[0])])


def _obj(oid, cls, center_xy, size, yaw, model=None, camera_height=1.5, rotation=None):
    center = [center_xy[0], center_xy[1], 0.5 * size[2]]
    ext = world_box_to_pano(center, size, yaw, W, H, camera_height, rotation).extent
    return SceneObject(oid, cls, center, size, yaw, model, 0.9, ext)


def make_scene(lib, rotation=None, objects=True):
    """An L-shaped room; a bed and a TV from the library, a chair box across the seam, an unknown model."""
    R = np.eye(3) if rotation is None else rotation
    objs = ()
    if objects:
        objs = (
            _obj("bed-0", "bed", (2.0, 0.6), lib["bed-01"].size, math.pi / 2, "bed-01", rotation=R),
            _obj("tv-0", "tv", (0.0, -1.35), lib["tv-01"].size, math.pi / 2, "tv-01", rotation=R),
            _obj("chair-0", "chair", (-1.5, 0.0), [0.5, 0.5, 0.9], 0.0, None, rotation=R),
            _obj("lamp-0", "lamp", (0.6, 0.6), [0.3, 0.3, 1.6], 0.7, "lamp-99", rotation=R),
        )
    return Scene(L_ROOM, 2.6, 1.5, objs, rotation=R, image_width=W, image_height=H)


def _world_vertices(loaded, node):
    """Vertices of a loaded GLB node in the z-up world frame."""
    T, geom = loaded.graph.get(node)
    v = trimesh.transform_points(loaded.geometry[geom].vertices, T)
    return v @ Z_UP_TO_Y_UP[:3, :3]  # inverse of the y-up rotation, for row vectors


# ------------------------------------------------------------------ scene.glb / scene.obj


def test_object_transform_places_base_and_front():
    o = SceneObject("bed-0", "bed", [1.0, 2.0, 0.5], [2.0, 1.0, 1.0], math.radians(30))
    T = object_transform(o)
    np.testing.assert_allclose(T @ [0, 0, 0, 1], [1.0, 2.0, 0.0, 1.0], atol=1e-12)  # base centre
    np.testing.assert_allclose(T[:3, :3] @ [1, 0, 0], [math.cos(o.yaw), math.sin(o.yaw), 0], atol=1e-12)
    S = object_transform(o, [4.0, 1.0, 0.5])
    np.testing.assert_allclose(S @ [2.0, 0, 0.5, 1], T @ [1.0, 0, 1.0, 1], atol=1e-12)
    with pytest.raises(ValueError, match="model_size: expected 3 sizes > 0"):
        object_transform(o, [1.0, 0.0, 1.0])


def test_glb_nodes_models_and_materials(tmp_path, lib):
    scene = make_scene(lib)
    back = trimesh.load(export_glb(scene, tmp_path / "scene.glb", lib))
    children = back.graph.transforms.children
    top = set(children[back.graph.base_frame])
    assert top == set(ROOM_NODES) | {"bed-0", "tv-0", "chair-0", "lamp-0"}
    models = {n for n in top - set(ROOM_NODES) if not any(c.endswith("/box") for c in children[n])}
    assert models == {"bed-0", "tv-0"}
    assert children["chair-0"] == ["chair-0/box"] and children["lamp-0"] == ["lamp-0/box"]
    parts = {c.split("/")[1] for c in children["bed-0"]}
    assert parts == set(lib["bed-01"].part_names)
    for name in ROOM_NODES:
        assert back.geometry[name].visual.material.name == name
    assert back.geometry["chair-0/box"].visual.material.name == "chair"
    assert tuple(back.geometry["chair-0/box"].visual.material.baseColorFactor[:3]) == class_color("chair")


def test_glb_geometry_is_y_up_and_matches_the_boxes(tmp_path, lib):
    scene = make_scene(lib)
    back = trimesh.load(export_glb(scene, tmp_path / "scene.glb", lib))
    # y up: heights along +y, world y along -z
    np.testing.assert_allclose(back.bounds, [[-2.0, 0.0, -2.5], [3.0, 2.6, 1.5]], atol=1e-6)
    children = back.graph.transforms.children
    for obj in scene.objects:
        v = np.concatenate([_world_vertices(back, c) for c in children[obj.id]])
        corners = obj.corners  # yaw is a multiple of 90 deg for the models, the boxes are exact
        if obj.id in ("bed-0", "tv-0", "chair-0"):
            np.testing.assert_allclose(v.min(axis=0), corners.min(axis=0), atol=1e-6, err_msg=obj.id)
            np.testing.assert_allclose(v.max(axis=0), corners.max(axis=0), atol=1e-6, err_msg=obj.id)
        else:
            np.testing.assert_allclose(np.sort(v, axis=0), np.sort(corners, axis=0), atol=1e-6)


def test_room_faces_point_into_the_room(tmp_path, lib):
    back = trimesh.load(export_glb(make_scene(lib, objects=False), tmp_path / "room.glb"))
    for name, expect_z in (("floor", 1.0), ("ceiling", -1.0)):
        v = _world_vertices(back, name)
        f = back.geometry[name].faces
        n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
        assert np.allclose(n[:, :2], 0) and np.all(np.sign(n[:, 2]) == expect_z)
        assert np.isclose(np.abs(n[:, 2]).sum() / 2, signed_area(np.array(L_ROOM)))  # area covered once
    v = _world_vertices(back, "walls")
    f = back.geometry["walls"].faces
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    probe = v[f].mean(axis=1)[:, :2] + 0.01 * n[:, :2]
    assert len(f) == 2 * len(L_ROOM) and np.allclose(n[:, 2], 0)
    assert points_in_polygon(probe, np.array(L_ROOM)).all()


def test_ceiling_can_be_left_out_and_unknown_ceiling_keeps_the_floor(tmp_path, lib):
    sc = scene_to_trimesh(make_scene(lib, objects=False), include_ceiling=False, y_up=False)
    assert set(sc.graph.nodes_geometry) == {"floor", "walls"}
    assert np.isclose(sc.bounds[1, 2], 2.6)  # z up kept, walls still to the ceiling height
    no_ceiling = Scene(L_ROOM, None, 1.5)
    assert set(scene_to_trimesh(no_ceiling).graph.nodes_geometry) == {"floor"}


def test_object_id_clashing_with_a_room_node_is_refused(lib):
    s = Scene(L_ROOM, 2.6, 1.5, (SceneObject("walls", "table", [0.5, 0.5, 0.4], [1, 1, 0.8], 0.0),))
    with pytest.raises(ValueError, match="room node names"):
        scene_to_trimesh(s)


def test_obj_loads_with_its_materials(tmp_path, lib):
    scene = make_scene(lib)
    obj, mtl = export_obj(scene, tmp_path / "scene.obj", lib)
    assert mtl == tmp_path / "scene.mtl"
    text = obj.read_text()
    assert "mtllib scene.mtl" in text and "o ceiling" in text and "o bed-0/mattress" in text
    assert text.count("\no ") == text.count("\nusemtl ")  # every object names its material
    assert "newmtl floor" in mtl.read_text() and "newmtl chair" in mtl.read_text()
    back = trimesh.load(obj)
    glb = trimesh.load(export_glb(scene, tmp_path / "scene.glb", lib))
    np.testing.assert_allclose(back.bounds, glb.bounds, atol=1e-6)
    with pytest.raises(ValueError, match="expected a .obj file name"):
        export_obj(scene, tmp_path / "scene.glb", lib)
    chairs = tuple(SceneObject(f"chair-{k}", "chair", [x, 0.0, 0.45], [0.5, 0.5, 0.9], 0.0)
                   for k, x in enumerate((-1.0, 1.0)))
    _, mtl = export_obj(Scene(L_ROOM, 2.6, 1.5, chairs), tmp_path / "chairs.obj")
    names = [line.split()[1] for line in mtl.read_text().splitlines() if line.startswith("newmtl ")]
    assert sorted(names) == ["ceiling", "chair", "floor", "walls"]


# ------------------------------------------------------------------ floor plan


def test_floorplan_png_and_svg(tmp_path, lib):
    scene = make_scene(lib)
    png, svg = write_floorplan(scene, tmp_path / "floorplan.png", tmp_path / "floorplan.svg", dpi=80)
    img = Image.open(png)
    assert img.format == "PNG" and img.size[0] > 300
    root = ET.parse(svg).getroot()
    texts = [t for el in root.iter() if el.tag.endswith("text") for t in el.itertext()]
    joined = " ".join(texts)
    for wall in scene.walls:
        assert format_length(wall.length) in texts
    assert sorted(t for t in texts if t in {o.cls for o in scene.objects}) == ["bed", "chair", "lamp", "tv"]
    assert f"area {float(signed_area(np.array(L_ROOM))):.1f} m²" in joined and "wall height 2.60 m" in joined
    assert "1 m" in texts and "camera" in texts


@pytest.mark.parametrize(("floor", "step"), [([[-1, -1], [2, -1], [2, 1.5], [-1, 1.5]], 0.5),
                                             ([[-3, -2], [4, -2], [4, 3], [-3, 3]], 1.0)])
def test_floorplan_grid_step(floor, step):
    ax = floorplan_figure(Scene(floor, None, 1.6)).axes[0]
    for ticks in (ax.get_xticks(), ax.get_yticks()):
        np.testing.assert_allclose(np.diff(ticks), step)
        np.testing.assert_allclose(np.mod(ticks / step, 1.0), 0.0, atol=1e-9)
    assert ax.get_title().endswith("wall height unknown")


# ------------------------------------------------------------------ overlay


def _lit(img, uv):
    """Brightest pixel within one pixel of the continuous position uv."""
    u, v = int(np.floor(uv[0])) % img.shape[1], int(np.clip(np.floor(uv[1]), 1, img.shape[0] - 2))
    return img[v - 1:v + 2, [(u - 1) % img.shape[1], u, (u + 1) % img.shape[1]]].reshape(-1, 3).max(axis=0)


def test_overlay_draws_the_room_corners_where_they_project(lib):
    R = rot_z(0.3)
    scene = make_scene(lib, rotation=R, objects=False)
    img = draw_overlay(np.zeros((H, W, 3), np.uint8), scene)
    for z in (0.0, 2.6):
        pts = np.column_stack([L_ROOM, np.full(len(L_ROOM), z)])
        for uv in world_to_pixel(pts, W, H, 1.5, R):
            assert _lit(img, uv).max() > 100, (z, uv)
    # exactly on a floor corner the floor edge colour is drawn (it is drawn last)
    uv = world_to_pixel([[3.0, -1.5, 0.0]], W, H, 1.5, R)[0]
    assert np.abs(img[int(uv[1]), int(uv[0])].astype(int) - FLOOR_EDGE_RGB).max() <= 40
    assert not img[H - 3:].any() and not img[:3].any()  # nothing near the poles


def test_overlay_follows_the_rotation_as_a_horizontal_shift(lib):
    shift = 64  # pixels: a turn of the input camera about z shifts the input panorama
    a = 2 * math.pi * shift / W
    base = draw_overlay(np.zeros((H, W, 3), np.uint8), make_scene(lib, objects=False))
    turned = draw_overlay(np.zeros((H, W, 3), np.uint8), make_scene(lib, rotation=rot_z(a), objects=False))
    diff = np.abs(np.roll(base, shift, axis=1).astype(int) - turned.astype(int)).max(axis=2)
    assert base.any() and (diff > 60).mean() < 1e-3


def test_overlay_seam_crossing_box_and_wireframe(lib):
    scene = make_scene(lib)
    chair = next(o for o in scene.objects if o.id == "chair-0")
    u0, v0, u1, v1 = chair.bbox_pano
    assert u0 > u1  # the chair behind the camera wraps the seam
    only = Scene(L_ROOM, 2.6, 1.5, (chair,), image_width=W, image_height=H)
    boxes = draw_overlay(np.zeros((H, W, 3), np.uint8), only, layout=False, wireframes=False)
    row = int(v1) - 1  # the bottom edge runs from u0 to the seam and on from 0 to u1
    assert boxes[row, W - 2:].any() and boxes[row, :2].any()
    assert boxes[row, int(u0) - 1: int(u0) + 2].any() and boxes[row, int(u1) - 1: int(u1) + 2].any()
    assert not boxes[int(v0) + 2:, int(u1) + 4: int(u0) - 4].any()  # nothing between the two parts
    assert boxes[: int(v0), : int(u1)].any()  # the label, moved to the part at the left edge
    wire = draw_overlay(np.zeros((H, W, 3), np.uint8), only, layout=False, boxes=False)
    assert wire[:, :8].any() and wire[:, -8:].any() and not wire[:, W // 4: 3 * W // 4].any()
    lit = np.nonzero(wire.any(axis=2))
    assert lit[0].min() >= int(v0) - 2 and lit[0].max() <= int(np.ceil(v1)) + 2  # within the box extent


def test_box_parts():
    (closed,) = box_parts([10, 20, 30, 40], W)
    assert closed.tolist() == [[10, 20], [30, 20], [30, 40], [10, 40], [10, 20]]
    a, b = box_parts([1000, 20, 30, 40], W)
    assert a[:, 0].tolist() == [W, 1000, 1000, W] and b[:, 0].tolist() == [0, 30, 30, 0]
    with pytest.raises(ValueError, match="expected 4 finite numbers"):
        box_parts([1, 2, 3], W)


def test_overlay_rescales_boxes_to_the_image_and_keeps_the_input(lib):
    o = SceneObject("tv-0", "tv", [2.0, 0.0, 1.0], [0.2, 1.0, 0.6], math.pi, None, None, [1200, 400, 1300, 600])
    s = Scene(L_ROOM, 2.6, 1.5, (o,), image_width=2048, image_height=1024)
    src = np.zeros((H, W, 3), np.uint8)
    img = draw_overlay(src, s, layout=False, wireframes=False)
    assert not src.any()
    assert img[200:301, 599:602].any() and img[200:301, 649:652].any()  # the box's sides at half the pixels
    assert not img[:, :590].any() and not img[:, 660:].any()
    with pytest.raises(ValueError, match=r"expected an \(H, W, 3\) uint8 panorama with W == 2\*H"):
        draw_overlay(np.zeros((H, H, 3), np.uint8), s)


def test_layout_polylines_without_ceiling():
    pl = layout_polylines(Scene(L_ROOM, None, 1.5), W, H)
    assert pl["ceiling"] == [] and pl["corners"] == [] and len(pl["floor"]) >= 1


# ------------------------------------------------------------------ labels


def test_labels_colour_and_raw_ids(tmp_path):
    rng = np.random.default_rng(3)
    lab = rng.integers(0, 6, size=(32, 64)).astype(np.uint8)
    col = colorize_labels(lab)
    assert col.shape == (32, 64, 3) and (col[lab == 0] == 0).all()
    for k in range(6):
        assert (col[lab == k] == LABEL_PALETTE[k]).all()
    assert len({tuple(c) for c in LABEL_PALETTE}) == 6
    png, raw = write_labels(lab, tmp_path / "labels.png", tmp_path / "ids.png")
    np.testing.assert_array_equal(np.asarray(Image.open(png)), col)
    np.testing.assert_array_equal(np.asarray(Image.open(raw)), lab)
    with pytest.raises(ValueError, match="expected surface labels 0..5"):
        colorize_labels(np.full((4, 8), 6, np.uint8))
    with pytest.raises(ValueError, match="expected a .png file name"):
        write_labels(lab, tmp_path / "labels.jpg")


# ------------------------------------------------------------------ all together, atomically


def test_export_all(tmp_path, lib):
    scene = make_scene(lib)
    img = np.full((H, W, 3), 90, np.uint8)
    lab = np.ones((H, W), np.uint8)
    out = export_all(scene, tmp_path, image=img, labels=lab, library=lib)
    assert set(out) == set(EXPORT_FILES)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(EXPORT_FILES.values())
    empty = tmp_path / "empty"
    empty.mkdir()
    out = export_all(Scene(L_ROOM, 2.6, 1.5), empty)
    assert sorted(p.name for p in empty.iterdir()) == sorted(
        EXPORT_FILES[k] for k in ("glb", "obj", "mtl", "floorplan_png", "floorplan_svg"))
    with pytest.raises(ValueError, match="expected an existing output folder"):
        export_all(scene, tmp_path / "missing")


def test_failing_writers_leave_no_file(tmp_path, lib, monkeypatch):
    scene = make_scene(lib)
    (tmp_path / "scene.glb").write_bytes(b"old")

    def half_then_fail(self, data):
        with open(self, "wb") as fh:
            fh.write(data[: len(data) // 2])
        raise OSError("disk full")

    def save_half_then_fail(self, fp, *args, **kwargs):
        pathlib.Path(fp).write_bytes(b"\x89PNG half")
        raise OSError("disk full")

    monkeypatch.setattr(pathlib.Path, "write_bytes", half_then_fail)
    with pytest.raises(OSError, match="disk full"):
        export_glb(scene, tmp_path / "scene.glb", lib)
    with pytest.raises(OSError, match="disk full"):
        write_floorplan(scene, tmp_path / "floorplan.png", tmp_path / "floorplan.svg", dpi=40)
    with pytest.raises(OSError, match="disk full"):
        export_obj(scene, tmp_path / "scene.obj", lib)
    monkeypatch.undo()
    monkeypatch.setattr(Image.Image, "save", save_half_then_fail)
    with pytest.raises(OSError, match="disk full"):
        write_overlay(scene, np.zeros((H, W, 3), np.uint8), tmp_path / "overlay.png")
    with pytest.raises(OSError, match="disk full"):
        write_labels(np.zeros((H, W), np.uint8), tmp_path / "labels.png")
    assert [p.name for p in tmp_path.iterdir()] == ["scene.glb"]
    assert (tmp_path / "scene.glb").read_bytes() == b"old"
