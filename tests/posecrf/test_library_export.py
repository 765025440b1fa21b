"""GLB / OBJ export: colour-exact round trips, placements, atomic writes."""

from __future__ import annotations

import os

import numpy as np
import pytest
import trimesh

from posecrf.library import builtin_library, export_model, export_scene, load_model_file

LIB = builtin_library()


def _colour_set(mesh: trimesh.Trimesh) -> set[tuple[int, ...]]:
    return {tuple(int(x) for x in c[:3]) for c in mesh.visual.vertex_colors}


@pytest.mark.parametrize("suffix", [".glb", ".obj"])
@pytest.mark.parametrize("model_id", ["bed-02", "tv-04", "plant-03"])
def test_round_trip_keeps_geometry_colours_and_parts(tmp_path, suffix, model_id):
    m = LIB[model_id]
    path = export_model(m, tmp_path / f"{model_id}{suffix}")
    assert path.is_file()
    extra = {"split_objects": True, "group_material": False} if suffix == ".obj" else {}
    scene = trimesh.load(str(path), force="scene", process=False, **extra)
    assert {name.split("/", 1)[1] for name in scene.geometry} == set(m.part_names)
    mesh = scene.to_mesh()
    assert len(mesh.faces) == m.n_faces
    np.testing.assert_allclose(mesh.bounds, m.bounds, atol=1e-6)
    assert _colour_set(mesh) == {tuple(int(x) for x in c[:3]) for c in m.face_colors}
    # each part's faces are drawn in exactly the part's colours
    for name, geom in scene.geometry.items():
        part = name.split("/", 1)[1]
        want = {tuple(int(x) for x in c[:3]) for c in m.face_colors[m.part_mask(part)]}
        assert _colour_set(geom) == want, part


def test_exported_model_loads_back_through_the_user_folder_path(tmp_path):
    m = LIB["chair-08"]
    export_model(m, tmp_path / "wing.glb")
    back = load_model_file(tmp_path / "wing.glb", {"class": "chair", "front": "+x", "up": "+z", "units": "m"})
    np.testing.assert_allclose(back.size, m.size, atol=1e-6)
    assert set(back.part_names) == {f"0:chair-08/{p}" for p in m.part_names}


def test_export_scene_applies_placements(tmp_path):
    bed, tv = LIB["bed-01"], LIB["tv-02"]
    t_tv = np.eye(4)
    c, s = np.cos(np.pi / 2), np.sin(np.pi / 2)
    t_tv[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]  # yaw 90 deg: the screen faces +y
    t_tv[:3, 3] = (0.0, -2.0, 0.0)
    path = export_scene([(bed, np.eye(4)), (tv, t_tv)], tmp_path / "room.glb")
    scene = trimesh.load(str(path), force="scene")
    names = list(scene.geometry)
    assert any(n.startswith("0:bed-01/") for n in names) and any(n.startswith("1:tv-02/") for n in names)
    tv_mesh = trimesh.util.concatenate([g for n, g in scene.geometry.items() if n.startswith("1:")])
    np.testing.assert_allclose(tv_mesh.extents, tv.size[[1, 0, 2]], atol=1e-6)
    screen = scene.geometry["1:tv-02/screen"]
    np.testing.assert_allclose(screen.face_normals, [[0.0, 1.0, 0.0]] * 2, atol=1e-6)


def test_y_up_option_follows_the_gltf_convention(tmp_path):
    m = LIB["wardrobe-01"]
    back = trimesh.load(str(export_model(m, tmp_path / "w.glb", y_up=True)), force="mesh")
    np.testing.assert_allclose(back.extents, m.size[[0, 2, 1]], atol=1e-6)
    assert back.bounds[0, 1] == pytest.approx(0.0, abs=1e-9)  # standing on y = 0
    assert back.bounds[1, 1] == pytest.approx(m.size[2], abs=1e-6)


def test_atomic_write_replaces_and_leaves_no_temporary_files(tmp_path):
    target = tmp_path / "sub" / "m.obj"
    export_model(LIB["table-02"], target)
    first = target.read_bytes()
    export_model(LIB["table-03"], target)
    assert target.read_bytes() != first
    bad = np.eye(4)
    bad[0, 0] = -1.0  # a mirror
    before = target.read_bytes()
    with pytest.raises(ValueError, match="det > 0"):
        export_model(LIB["table-01"], target, transform=bad)
    assert target.read_bytes() == before
    assert sorted(os.listdir(target.parent)) == ["m.obj"]


def test_export_input_checks(tmp_path):
    with pytest.raises(ValueError, match=r"\.glb or \.obj"):
        export_model(LIB["tv-01"], tmp_path / "m.fbx")
    export_model(LIB["tv-01"], tmp_path / "m.bin", file_type="glb")
    assert (tmp_path / "m.bin").read_bytes()[:4] == b"glTF"
    with pytest.raises(ValueError, match="Model3D"):
        export_model("tv-01", tmp_path / "m.glb")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"\(4, 4\)"):
        export_scene([(LIB["tv-01"], np.eye(3))], tmp_path / "m.glb")
    with pytest.raises(ValueError, match="at least one"):
        export_scene([], tmp_path / "m.glb")
    with pytest.raises(ValueError, match="pair"):
        export_scene([LIB["tv-01"]], tmp_path / "m.glb")  # type: ignore[list-item]
