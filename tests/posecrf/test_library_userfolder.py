"""Loading a user's folder of CAD models: axes, units, clean-up, error report."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree

from posecrf.library import (
    ModelFileError,
    axes_rotation,
    builtin_library,
    load_model_file,
    load_model_folder,
    parse_metadata,
)

LIB = builtin_library()


def _write_in_file_frame(model, path: Path, front: str, up: str, scale: float, offset=(0.0, 0.0, 0.0)) -> None:
    """Write `model` as the user's exporter would: other axes, other units, one node per part."""
    r = axes_rotation(front, up)  # file -> canonical; rows form an orthonormal basis
    scene = trimesh.Scene()
    for pid, name in enumerate(model.part_names):
        sel = model.face_parts == pid
        v = (model.vertices @ r) * scale + np.asarray(offset)
        mesh = trimesh.Trimesh(v, model.faces[sel], face_colors=model.face_colors[sel], process=False)
        mesh.remove_unreferenced_vertices()
        scene.add_geometry(mesh, geom_name=name, node_name=name)
    scene.export(str(path))


def _write_meta(path: Path, **fields) -> None:
    path.write_text(json.dumps(fields))


def _max_nn_distance(a: np.ndarray, b: np.ndarray) -> float:
    return float(max(cKDTree(b).query(a)[0].max(), cKDTree(a).query(b)[0].max()))


@pytest.mark.parametrize(
    ("model_id", "suffix", "front", "up"),
    [("chair-04", ".glb", "+z", "+y"), ("bed-03", ".obj", "-y", "+z"), ("tv-03", ".glb", "+x", "-y")],
)
def test_rotated_centimetre_model_recovers_canonical_frame(tmp_path, model_id, suffix, front, up):
    ref = LIB[model_id]
    mesh_path = tmp_path / f"{model_id}-user{suffix}"
    _write_in_file_frame(ref, mesh_path, front, up, scale=100.0, offset=(12.0, -40.0, 7.0))
    _write_meta(tmp_path / f"{model_id}-user.json", **{"class": ref.cls, "front": front, "up": up, "units": "cm"})
    m = load_model_file(mesh_path)
    assert m.id == f"{model_id}-user" and m.cls == ref.cls and m.source == str(mesh_path)
    np.testing.assert_allclose(m.size, ref.size, atol=1e-5)
    assert _max_nn_distance(m.vertices, ref.vertices) < 1e-5
    assert {tuple(c) for c in m.face_colors} == {tuple(c) for c in ref.face_colors}
    assert set(m.part_names) == set(ref.part_names)  # glTF nodes and OBJ objects are parts


def test_per_axis_size_and_height_options(tmp_path):
    ref = LIB["table-01"]
    # the file has the table in millimetres-ish arbitrary units, y up, front at -z
    _write_in_file_frame(ref, tmp_path / "t.ply", "-z", "+y", scale=3.0)
    m = load_model_file(tmp_path / "t.ply", {"class": "table", "front": "-z", "up": "+y", "size": [1.8, 1.0, 0.72]})
    np.testing.assert_allclose(m.size, [1.8, 1.0, 0.72], atol=1e-6)
    m = load_model_file(tmp_path / "t.ply", {"class": "table", "front": "-z", "up": "+y", "height": 0.75, "symmetry": "two"})
    np.testing.assert_allclose(m.size, ref.size, atol=1e-5)
    assert m.symmetry == "two" and m.part_names == ("body",)


def test_materials_from_metadata(tmp_path):
    ref = LIB["tv-01"]
    _write_in_file_frame(ref, tmp_path / "tv.glb", "+x", "+z", 1.0)
    meta = {"class": "tv", "front": "+x", "up": "+z", "scale": 1.0, "material": "plastic", "materials": {"screen": "screen"}}
    m = load_model_file(tmp_path / "tv.glb", meta)
    assert m.part_materials[m.part_names.index("screen")] == "screen"
    assert m.material_mask("screen").sum() == 2
    with pytest.raises(ModelFileError, match=r"lacks"):
        load_model_file(tmp_path / "tv.glb", {**meta, "materials": {"knob": "metal"}})


def test_cleanup_merges_duplicates_and_drops_degenerate_faces(tmp_path):
    box = trimesh.creation.box((1.0, 1.0, 1.0))
    v = np.concatenate([box.vertices, box.vertices + 1e-9])  # near-duplicate vertex copies
    f = np.concatenate([box.faces, box.faces, box.faces[:3] + 8, [[0, 0, 1], [0, 1, 1]]])
    lines = [f"v {x:.12f} {y:.12f} {z:.12f}" for x, y, z in v] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in f]
    (tmp_path / "dup.obj").write_text("\n".join(lines) + "\n")
    m = load_model_file(tmp_path / "dup.obj", {"class": "box", "front": "+x", "up": "+z", "units": "m"})
    assert m.n_faces == 12 and len(m.vertices) == 8
    np.testing.assert_allclose(m.size, [1.0, 1.0, 1.0], atol=1e-6)


def test_huge_mesh_is_decimated_to_the_budget(tmp_path):
    sphere = trimesh.creation.icosphere(subdivisions=5, radius=30.0)  # 20480 faces, cm
    sphere.export(str(tmp_path / "ball.ply"))
    _write_meta(tmp_path / "ball.json", **{"class": "plant", "front": "+x", "up": "+z", "units": "cm"})
    m = load_model_file(tmp_path / "ball.ply", face_budget=2000)
    assert m.n_faces <= 2000 and m.symmetry == "full"
    np.testing.assert_allclose(m.size, 0.6, atol=0.01)


def test_folder_collects_errors_naming_files_and_loads_the_rest(tmp_path):
    for mid in ("chair-01", "plant-02"):
        ref = LIB[mid]
        _write_in_file_frame(ref, tmp_path / f"my-{mid}.glb", "-y", "+z", 100.0)
        _write_meta(tmp_path / f"my-{mid}.json", **{"class": ref.cls, "front": "-y", "up": "+z", "units": "cm"})
    (tmp_path / "broken.glb").write_bytes(b"glTF\x02\x00\x00\x00garbage-not-a-model")
    _write_meta(tmp_path / "broken.json", **{"class": "tv", "front": "+x", "up": "+z", "units": "m"})
    trimesh.creation.box((1, 1, 1)).export(str(tmp_path / "lonely.obj"))
    trimesh.creation.box((1, 1, 1)).export(str(tmp_path / "badmeta.ply"))
    _write_meta(tmp_path / "badmeta.json", **{"class": "bed", "front": "+x", "up": "+x", "units": "m"})
    trimesh.creation.box((1, 1, 1)).export(str(tmp_path / "nojson.stl"))
    (tmp_path / "nojson.json").write_text("{ not json")
    _write_meta(tmp_path / "orphan.json", **{"class": "bed", "front": "+x", "up": "+z", "units": "m"})
    (tmp_path / "notes.txt").write_text("ignored")

    res = load_model_folder(tmp_path)
    assert res.library.ids == ("my-chair-01", "my-plant-02")
    np.testing.assert_allclose(res.library["my-chair-01"].size, LIB["chair-01"].size, atol=1e-5)
    by_file = {e.file.name: e.message for e in res.errors}
    assert set(by_file) == {"broken.glb", "lonely.obj", "badmeta.json", "nojson.json", "orphan.json"}
    assert "cannot read mesh" in by_file["broken.glb"]
    assert "missing metadata" in by_file["lonely.obj"] and "lonely.json" in by_file["lonely.obj"]
    assert "orthogonal" in by_file["badmeta.json"]
    assert "invalid JSON" in by_file["nojson.json"]
    assert "without a mesh" in by_file["orphan.json"]
    assert not res.ok
    report = res.report()
    assert "2 models loaded, 5 failed" in report and "broken.glb" in report
    assert str(next(iter(res.errors))).startswith(str(tmp_path))
    # user models merge with the built-in library
    assert len(LIB.merged(res.library)) == len(LIB) + 2


def test_duplicate_ids_and_implausible_units_are_reported(tmp_path):
    trimesh.creation.box((50.0, 50.0, 80.0)).export(str(tmp_path / "a.obj"))
    _write_meta(tmp_path / "a.json", **{"class": "box", "front": "+x", "up": "+z", "units": "cm", "id": "crate"})
    trimesh.creation.box((50.0, 50.0, 80.0)).export(str(tmp_path / "b.obj"))
    _write_meta(tmp_path / "b.json", **{"class": "box", "front": "+x", "up": "+z", "units": "cm", "id": "crate"})
    trimesh.creation.box((50.0, 50.0, 80.0)).export(str(tmp_path / "c.obj"))
    _write_meta(tmp_path / "c.json", **{"class": "box", "front": "+x", "up": "+z", "units": "m"})
    res = load_model_folder(tmp_path)
    assert res.library.ids == ("crate",)
    msgs = {e.file.name: e.message for e in res.errors}
    assert "duplicate model id 'crate'" in msgs["b.obj"]
    assert "implausible metric size" in msgs["c.json"]


def test_yaml_metadata_needs_pyyaml_or_loads(tmp_path):
    trimesh.creation.box((0.4, 0.4, 0.9)).export(str(tmp_path / "y.obj"))
    (tmp_path / "y.yaml").write_text("class: chair\nfront: '+x'\nup: '+z'\nunits: m\n")
    try:
        import yaml  # noqa: F401
    except ImportError:
        with pytest.raises(ModelFileError, match="pip install pyyaml"):
            load_model_file(tmp_path / "y.obj")
    else:
        np.testing.assert_allclose(load_model_file(tmp_path / "y.obj").size, [0.4, 0.4, 0.9], atol=1e-6)


def test_metadata_validation_messages():
    base = {"class": "chair", "front": "+x", "up": "+z", "units": "m"}
    with pytest.raises(ValueError, match="unknown metadata field"):
        parse_metadata({**base, "frnt": "+x"})
    with pytest.raises(ValueError, match="missing required metadata field 'class'"):
        parse_metadata({k: v for k, v in base.items() if k != "class"})
    with pytest.raises(ValueError, match="exactly one of"):
        parse_metadata({**base, "scale": 0.01})
    with pytest.raises(ValueError, match="exactly one of"):
        parse_metadata({k: v for k, v in base.items() if k != "units"})
    with pytest.raises(ValueError, match="front axis"):
        parse_metadata({**base, "front": "forward"})
    with pytest.raises(ValueError, match="'units'"):
        parse_metadata({**base, "units": "furlong"})
    with pytest.raises(ValueError, match="size"):
        parse_metadata({k: v for k, v in base.items() if k != "units"} | {"size": [1, 2]})
    with pytest.raises(ValueError, match="positive number"):
        parse_metadata({k: v for k, v in base.items() if k != "units"} | {"height": -1})
    with pytest.raises(ValueError, match="lowercase word"):
        parse_metadata({**base, "class": "Chair"})


def test_axes_rotation_is_proper_for_all_orthogonal_pairs():
    axes = ["+x", "-x", "+y", "-y", "+z", "-z"]
    n = 0
    for f in axes:
        for u in axes:
            if f[1] == u[1]:
                with pytest.raises(ValueError, match="orthogonal"):
                    axes_rotation(f, u)
                continue
            r = axes_rotation(f, u)
            np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
            assert np.linalg.det(r) == pytest.approx(1.0)
            n += 1
    assert n == 24  # the rotation group of the cube


def test_bad_paths(tmp_path):
    with pytest.raises(ValueError, match="not a directory"):
        load_model_folder(tmp_path / "missing")
    with pytest.raises(ModelFileError, match="does not exist"):
        load_model_file(tmp_path / "ghost.obj", {"class": "box", "front": "+x", "up": "+z", "units": "m"})
    with pytest.raises(ModelFileError, match="expected a mesh file"):
        load_model_file(tmp_path / "x.fbx")
    (tmp_path / "pts.ply").write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n")
    with pytest.raises(ModelFileError, match="no triangles"):
        load_model_file(tmp_path / "pts.ply", {"class": "box", "front": "+x", "up": "+z", "units": "m"})
