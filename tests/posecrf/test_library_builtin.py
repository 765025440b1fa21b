"""Built-in procedural library: canonical frame, front directions, variety, determinism."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from posecrf.library import (
    MATERIALS,
    Model3D,
    ModelLibrary,
    assemble_model,
    builtin_library,
    canonicalize_vertices,
    material_index,
)
from posecrf.library.parts import box, cylinder, quad
from posecrf.library.procedural import ALL_SPECS, BED_SPECS, build_all, build_model

LIB = builtin_library()
ALL = list(LIB)
IDS = [m.id for m in ALL]


def test_counts_per_class_match_the_paper_and_clutter():
    counts = LIB.counts()
    assert counts["bed"] >= 9 and counts["chair"] >= 16 and counts["tv"] >= 6 and counts["plant"] >= 4
    for cls in ("sofa", "table", "nightstand", "wardrobe"):
        assert 2 <= counts[cls] <= 3, cls
    assert len(LIB) == len(ALL_SPECS)


@pytest.mark.parametrize("model", ALL, ids=IDS)
def test_model_is_canonical_light_and_clean(model: Model3D):
    v, f = model.vertices, model.faces
    lo, hi = v.min(axis=0), v.max(axis=0)
    assert abs((lo[0] + hi[0]) / 2) < 1e-6 and abs((lo[1] + hi[1]) / 2) < 1e-6
    assert abs(lo[2]) < 1e-9
    np.testing.assert_allclose(model.size, hi - lo, atol=1e-12)
    assert np.all(np.isfinite(v))
    assert 0 < model.n_faces < 5000
    tri = v[f]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    assert area.min() > 1e-10
    assert model.face_colors.shape == (len(f), 4) and model.face_colors.dtype == np.uint8
    assert model.face_parts.shape == (len(f),)
    assert set(np.unique(model.face_parts)) == set(range(len(model.part_names)))
    assert set(np.unique(model.face_materials)) <= set(range(len(MATERIALS)))
    # every used vertex is referenced (no loose points inflating the bbox)
    assert len(np.unique(f)) == len(v)
    # plausible real-world size: between 20 cm and 2.5 m in every direction
    assert np.all(model.size > 0.2) and np.all(model.size < 2.5), model.size
    assert model.source.startswith("procedural:")


def test_symmetry_fields_follow_the_class():
    for m in ALL:
        if m.cls == "plant":
            assert m.symmetry == "full"
        elif m.cls == "table":
            assert m.symmetry in ("two", "full")
        else:
            assert m.symmetry == "none", m.id
    assert {m.symmetry for m in LIB.by_class("table")} == {"two", "full"}


def test_class_sizes_are_realistic():
    for m in LIB.by_class("bed"):
        assert 1.95 <= m.size[0] <= 2.4 and 0.9 <= m.size[1] <= 2.3
    widths = sorted(s.width for s in BED_SPECS)
    assert widths[0] <= 1.0 and widths[-1] >= 1.8  # single ... king
    for m in LIB.by_class("chair"):
        assert 0.7 <= m.size[2] <= 1.35
    for m in LIB.by_class("tv"):
        assert m.size[1] > m.size[0]  # wider than deep
    diag = sorted(float(np.hypot(*_screen_extent(m))) for m in LIB.by_class("tv"))
    assert diag[0] < 0.85 and diag[-1] > 1.85  # 32" (0.81 m) ... 75" (1.9 m)


def _top_in_slab(model: Model3D, lo_frac: float, hi_frac: float) -> float:
    """Highest vertex whose x lies in [lo_frac, hi_frac] of the length (0 = back, 1 = front)."""
    x = model.vertices[:, 0] / model.size[0] + 0.5
    sel = (x >= lo_frac) & (x <= hi_frac)
    return float(model.vertices[sel, 2].max())


@pytest.mark.parametrize("model", LIB.by_class("bed"), ids=lambda m: m.id)
def test_bed_headboard_at_minus_x(model: Model3D):
    head = _top_in_slab(model, 0.0, 0.15)
    foot = _top_in_slab(model, 0.85, 1.0)
    assert head > foot + 0.1, (head, foot)
    assert any(n.startswith("headboard") for n in model.part_names)
    pillow = model.vertices[np.unique(model.faces[model.part_mask("pillow")])]
    assert pillow[:, 0].mean() < -0.25 * model.size[0]


@pytest.mark.parametrize("model", LIB.by_class("chair") + LIB.by_class("sofa"), ids=lambda m: m.id)
def test_chair_and_sofa_backrest_at_minus_x(model: Model3D):
    back = _top_in_slab(model, 0.0, 0.25)
    front = _top_in_slab(model, 0.75, 1.0)
    assert back > front + 0.15, (back, front)
    # the seat opening: nothing above seat height in the front-centre column
    v = model.vertices
    seat = model.vertices[np.unique(model.faces[model.part_mask("seat" if model.cls == "chair" else "seat_cushion")])]
    seat_top = seat[:, 2].max()
    column = (v[:, 0] > 0.3 * model.size[0]) & (np.abs(v[:, 1]) < 0.1)
    assert not np.any(v[column, 2] > seat_top + 0.05)


@pytest.mark.parametrize("model", LIB.by_class("tv"), ids=lambda m: m.id)
def test_tv_screen_faces_plus_x_and_is_thin(model: Model3D):
    mesh = model.mesh
    screen = model.material_mask("screen")
    assert screen.sum() == 2
    np.testing.assert_allclose(mesh.face_normals[screen], np.tile([1.0, 0.0, 0.0], (2, 1)), atol=1e-9)
    sv = model.vertices[np.unique(model.faces[screen])]
    assert np.ptp(sv[:, 0]) < 1e-9
    panel = model.vertices[np.unique(model.faces[model.part_mask("panel")])]
    assert np.ptp(panel[:, 0]) < 0.1
    assert sv[0, 0] > panel[:, 0].max()  # in front of the panel
    width, height = _screen_extent(model)
    assert abs(width / height - 16 / 9) < 1e-6


def _screen_extent(model: Model3D) -> tuple[float, float]:
    sv = model.vertices[np.unique(model.faces[model.material_mask("screen")])]
    return float(np.ptp(sv[:, 1])), float(np.ptp(sv[:, 2]))


@pytest.mark.parametrize("model", LIB.by_class("nightstand") + LIB.by_class("wardrobe"), ids=lambda m: m.id)
def test_handles_on_the_plus_x_front(model: Model3D):
    handles = model.vertices[np.unique(model.faces[model.part_mask("handle")])]
    assert handles[:, 0].min() > 0.4 * model.size[0]


def test_plants_are_round_and_centred():
    for m in LIB.by_class("plant"):
        assert abs(m.size[0] - m.size[1]) < 0.15 * m.size[0]
        pot = m.vertices[np.unique(m.faces[m.part_mask("pot")])]
        np.testing.assert_allclose(pot[:, :2].min(axis=0) + pot[:, :2].max(axis=0), 0.0, atol=0.05)
        assert m.material_mask("leaf").any()


def test_variants_are_pairwise_distinct():
    hashes = LIB.content_hashes()
    assert len(set(hashes.values())) == len(hashes)
    # visibly different, not only recoloured: distinct face counts or sizes within each class
    for cls in LIB.classes:
        shapes = {(m.n_faces, tuple(np.round(m.size, 2))) for m in LIB.by_class(cls)}
        assert len(shapes) == len(LIB.by_class(cls)), cls


def test_building_is_deterministic_and_cached():
    again = {m.id: m.content_hash() for m in build_all()}
    assert again == LIB.content_hashes()
    assert builtin_library() is LIB
    m1, m2 = build_model(ALL_SPECS[30]), build_model(ALL_SPECS[30])
    assert m1 is not m2 and m1.content_hash() == m2.content_hash()


def test_cached_models_cannot_be_mutated():
    m = LIB["chair-04"]
    h = m.content_hash()
    with pytest.raises(ValueError):
        m.vertices[0, 0] = 5.0
    with pytest.raises(ValueError):
        m.face_colors[0] = 0
    mesh = m.mesh
    mesh.vertices[:] += 1.0
    mesh.visual.face_colors[:] = 0
    assert LIB["chair-04"].content_hash() == h
    assert build_model(next(s for s in ALL_SPECS if s.id == "chair-04")).content_hash() == h
    with pytest.raises(AttributeError):
        m.id = "x"  # type: ignore[misc]


def test_pickled_models_stay_read_only_and_equal():
    import pickle

    m = pickle.loads(pickle.dumps(LIB["sofa-02"]))
    assert m.content_hash() == LIB["sofa-02"].content_hash() and m.part_names == LIB["sofa-02"].part_names
    with pytest.raises(ValueError):
        m.vertices[0, 0] = 1.0
    np.testing.assert_array_equal(m.size, LIB["sofa-02"].size)


def test_mesh_copy_carries_colours_and_part_indices():
    m = LIB["bed-03"]
    mesh = m.mesh
    np.testing.assert_array_equal(mesh.visual.face_colors, m.face_colors)
    np.testing.assert_array_equal(mesh.metadata["face_parts"], m.face_parts)
    assert mesh.metadata["model_id"] == "bed-03"
    assert m.part_materials[m.part_names.index("mattress")] == "fabric"


def test_library_lookup_and_errors():
    assert LIB["tv-02"].cls == "tv"
    assert LIB.get("nope") is None
    with pytest.raises(KeyError, match="no model 'nope'"):
        LIB["nope"]
    assert [m.cls for m in LIB.by_class("plant")] == ["plant"] * 4
    assert LIB.by_class("unicorn") == ()
    sub = LIB.subset(["tv", "plant"])
    assert len(sub) == 10 and sub.classes == ("tv", "plant")
    with pytest.raises(ValueError, match="unique model ids"):
        LIB.merged(sub)
    with pytest.raises(ValueError, match="expected Model3D"):
        ModelLibrary(["bed-01"])  # type: ignore[list-item]
    assert "bed-01" in LIB and len(list(iter(LIB))) == len(LIB)


def test_model_validation_messages():
    good = LIB["table-01"]
    kw = dict(
        vertices=good.vertices,
        faces=good.faces,
        face_colors=good.face_colors,
        face_parts=good.face_parts,
        part_names=good.part_names,
        part_materials=good.part_materials,
    )
    with pytest.raises(ValueError, match="canonical frame"):
        Model3D("t", "table", "two", **{**kw, "vertices": good.vertices + [0.5, 0.0, 0.0]})
    with pytest.raises(ValueError, match="lowercase class"):
        Model3D("t", "Table", "two", **kw)
    with pytest.raises(ValueError, match="symmetry"):
        Model3D("t", "table", "mirror", **kw)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="face_colors"):
        Model3D("t", "table", "two", **{**kw, "face_colors": good.face_colors[:-1]})
    with pytest.raises(ValueError, match="NaN"):
        bad = good.vertices.copy()
        bad[0, 0] = np.nan
        Model3D("t", "table", "two", **{**kw, "vertices": bad})
    with pytest.raises(ValueError, match="material name"):
        material_index("velvet")


def test_assemble_model_merges_named_parts_and_drops_degenerate_faces():
    legs = [cylinder("leg", "metal", (10, 10, 10), (x, 0, 0), (x, 0, 0.4), 0.02, 8) for x in (-0.2, 0.2)]
    top = box("top", "wood", (200, 150, 100), (0.5, 0.3, 0.03), (0.0, 0.0, 0.415))
    sliver = quad("top", "wood", (200, 150, 100), [(0, 0, 1), (1, 0, 1), (2, 0, 1), (3, 0, 1)])  # zero area
    m = assemble_model("bench-01", "bench", [*legs, top], symmetry="two")
    assert m.part_names == ("leg", "top")
    m2 = assemble_model("bench-01", "bench", [*legs, top, sliver], symmetry="two")
    assert m2.content_hash() == m.content_hash()
    with pytest.raises(ValueError, match="materials"):
        assemble_model("x-1", "x", [top, box("top", "metal", (1, 1, 1), (0.1, 0.1, 0.1))])
    with pytest.raises(ValueError, match="at least one part"):
        assemble_model("x-1", "x", [])
    with pytest.raises(ValueError, match="positive extents"):
        box("b", "wood", (1, 1, 1), (0.1, -0.1, 0.1))


@settings(max_examples=40, deadline=None, derandomize=True)
@given(arrays(np.float64, st.tuples(st.integers(1, 30), st.just(3)), elements=st.floats(-100, 100)))
def test_canonicalize_vertices_properties(v):
    c = canonicalize_vertices(v)
    lo, hi = c.min(axis=0), c.max(axis=0)
    tol = 1e-9 * max(1.0, float(np.abs(v).max()))
    assert abs(lo[0] + hi[0]) <= tol and abs(lo[1] + hi[1]) <= tol and abs(lo[2]) <= tol
    np.testing.assert_allclose(c - c[0], v - v[0], atol=tol * 4)


def test_canonicalize_rejects_bad_input():
    with pytest.raises(ValueError, match=r"\(V, 3\)"):
        canonicalize_vertices(np.zeros((4, 2)))
    with pytest.raises(ValueError, match="finite"):
        canonicalize_vertices([[0.0, np.inf, 0.0]])
