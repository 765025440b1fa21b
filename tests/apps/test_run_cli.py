"""`pano2cad run` on bad and odd input: exit 2 with one line, or success where the input is usable.

Never a traceback for a user mistake and never a partial scene.json.
"""

import json
import os
import resource
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

from apps.cli import main


@pytest.fixture(scope="module")
def room_png(tmp_path_factory):
    from apps.synth import make_room

    d = tmp_path_factory.mktemp("room")
    r = make_room(2, seed=21, width=512)
    Image.fromarray(r.rgb).save(d / "pano.png")
    (d / "gt.json").write_text(json.dumps(r.gt))
    return d


def _one_line_error(capsys, needle):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("pano2cad: error:") and needle in err[0], err
    return err[0]


def test_missing_file(tmp_path, capsys):
    assert main(["run", str(tmp_path / "nope.jpg"), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    _one_line_error(capsys, "nope.jpg")
    assert not (tmp_path / "o" / "scene.json").exists()


def test_corrupt_jpeg(tmp_path, capsys, room_png):
    data = (room_png / "pano.png").read_bytes()
    Image.open(room_png / "pano.png").save(tmp_path / "c.jpg")
    (tmp_path / "c.jpg").write_bytes((tmp_path / "c.jpg").read_bytes()[:300])
    assert data  # the source is fine; only the copy is cut
    assert main(["run", str(tmp_path / "c.jpg"), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    _one_line_error(capsys, "c.jpg")


def test_photo_3_by_2(tmp_path, capsys):
    Image.fromarray(np.zeros((200, 300, 3), np.uint8)).save(tmp_path / "photo.jpg")
    assert main(["run", str(tmp_path / "photo.jpg"), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    _one_line_error(capsys, "300x200")


def test_unwritable_out(tmp_path, capsys, room_png):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert main(["run", str(room_png / "pano.png"), "--out", str(blocker / "sub"), "--quiet"]) == 2
    _one_line_error(capsys, "cannot write")


def test_bad_options(tmp_path, capsys, room_png):
    assert main(["run", str(room_png / "pano.png"), "--out", str(tmp_path), "--samples", "0"]) == 2
    assert main(["run", str(room_png / "pano.png"), "--out", str(tmp_path), "--camera-height", "-1"]) == 2
    assert main(["run", str(room_png / "pano.png"), "--out", str(tmp_path), "--detector", "frob:x"]) == 2
    assert main(["run", str(room_png / "pano.png"), "--out", str(tmp_path), "--detector", "onnx:/no/model.onnx"]) == 2
    assert not (tmp_path / "scene.json").exists()


@pytest.mark.parametrize("mode", ["L", "RGBA", "I;16"])
def test_grayscale_rgba_16bit_are_accepted(tmp_path, room_png, mode):
    img = Image.open(room_png / "pano.png")
    if mode == "I;16":
        img = Image.fromarray(np.asarray(img.convert("L")).astype(np.uint16) * 257)
    else:
        img = img.convert(mode)
    img.save(tmp_path / "in.png")
    out = tmp_path / "o"
    assert main(["run", str(tmp_path / "in.png"), "--out", str(out), "--no-objects", "--size", "512", "--quiet"]) == 0
    scene = json.loads((out / "scene.json").read_text())
    assert scene["schema"] == "pano2cad/scene@1" and scene["objects"] == []
    assert len(scene["room"]["floor"]) >= 4


def test_no_detections_gives_layout_only(tmp_path, room_png):
    ann = tmp_path / "none.json"
    ann.write_text(json.dumps({"image": {"width": 512, "height": 256}, "objects": []}))
    out = tmp_path / "o"
    assert main(["run", str(room_png / "pano.png"), "--out", str(out), "--detector", f"annotations:{ann}",
                 "--size", "512", "--quiet"]) == 0
    scene = json.loads((out / "scene.json").read_text())
    assert scene["objects"] == []
    for f in ("scene.glb", "scene.obj", "floorplan.png", "floorplan.svg", "overlay.png", "labels.png", "report.html"):
        assert (out / f).is_file(), f


def test_objects_from_annotations_end_to_end(tmp_path, room_png):
    """Ground-truth boxes through pose estimation and sampling: objects come back with models and yaws."""
    out = tmp_path / "o"
    gt = json.loads((room_png / "gt.json").read_text())
    assert main(["run", str(room_png / "pano.png"), "--out", str(out), "--detector",
                 f"annotations:{room_png / 'gt.json'}", "--size", "512", "--quiet"]) == 0
    scene = json.loads((out / "scene.json").read_text())
    visible = [o for o in gt["objects"] if o["bbox_pano"] is not None]
    dropped = [w for w in scene["warnings"] if w.startswith("dropped")]
    assert len(scene["objects"]) + len(dropped) == len(visible)
    for o in scene["objects"]:
        assert o["model"] and 0 <= o["yaw_deg"] < 360 and len(o["bbox_pano"]) == 4
    assert scene["scale"] is None or scene["scale"] > 0
    assert set(scene["timing_s"]) >= {"rectify", "detect", "surfaces", "room", "posterior", "total"}


def test_huge_panorama_is_downscaled_within_memory(tmp_path):
    """A 9000x4500 JPEG runs at the working size with a peak resident memory well below 4 GB."""
    yy, xx = np.mgrid[0:4500, 0:9000]
    img = ((np.sin(xx / 300.0) + np.cos(yy / 200.0)) * 60 + 128).astype(np.uint8)
    Image.fromarray(np.stack([img, img[::-1], img], -1)).save(tmp_path / "big.jpg", quality=80)
    del yy, xx, img
    code = ("import resource, sys; from apps.cli import main; "
            f"rc = main(['run', {str(tmp_path / 'big.jpg')!r}, '--out', {str(tmp_path / 'o')!r}, '--no-objects', "
            "'--size', '512', '--quiet']); "
            "print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss); sys.exit(rc if rc in (0, 2) else 1)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600,
                       env=dict(os.environ, PYOPENGL_PLATFORM="egl"))
    # A panorama without lines or walls may be refused (exit 2, one line); it must never crash.
    assert r.returncode in (0, 2), r.stderr[-2000:]
    assert "Traceback" not in r.stderr
    peak_kb = int(r.stdout.strip().splitlines()[-1])
    assert peak_kb < 4 * 1024 * 1024, f"peak RSS {peak_kb / 1024:.0f} MB"
    if r.returncode == 0:
        scene = json.loads((tmp_path / "o" / "scene.json").read_text())
        assert scene["image"]["width"] == 512


def test_detection_keeps_the_ranked_candidates_for_average_precision(room_png):
    """The pipeline uses detections at the backend's threshold; evaluation ranks every candidate down to
    CANDIDATE_SCORE (AP integrates over all recall levels, a threshold would cut the curve)."""
    pytest.importorskip("torch")
    from apps.imageio import read_panorama
    from apps.pipeline import CANDIDATE_SCORE, _detect
    from apps.progress import Progress
    from detect.builtin import BuiltinDetector

    img = read_panorama(room_png / "pano.png", max_width=512).image
    used, cands = _detect(img, img, None, "builtin", Progress(quiet=True))
    thr = BuiltinDetector().score_threshold
    assert CANDIDATE_SCORE < thr and len(cands) > len(used)  # the fixture room has low-scored candidates
    assert all(d.score >= thr for d in used) and all(d.score >= CANDIDATE_SCORE for d in cands)
    assert {id(d) for d in used} <= {id(d) for d in cands}
    assert [d for d in cands if d.score >= thr] == used


def test_box_edges_refined_by_the_network_or_the_silhouettes_unless_told_not_to(tmp_path, room_png, monkeypatch):
    """`--box-edges net` (default) refines the tile detections' edges by the edge network before the box fits (stage
    ``refine``); `silhouette` moves them onto grab-cut silhouettes (stage ``edges``); `detector` fits the detector's
    edges as they are; a bad mode is refused."""
    pytest.importorskip("torch")
    import detect.grabcut
    from apps.pipeline import RunOptions
    from detect.builtin.refine import BoxRefiner

    assert RunOptions().box_edges == "net"
    calls, refined = [], []
    real, real_refine = detect.grabcut.silhouette_box, BoxRefiner.refine_detections

    def spy(*args, **kwargs):
        calls.append(real(*args, **kwargs))
        return calls[-1]

    def spy_refine(self, pano, dets):
        out = real_refine(self, pano, dets)
        refined.extend(zip(dets, out))
        return out

    monkeypatch.setattr(detect.grabcut, "silhouette_box", spy)
    monkeypatch.setattr(BoxRefiner, "refine_detections", spy_refine)
    timings, counts = {}, {}
    for mode in ("net", "silhouette", "detector"):
        out = tmp_path / mode.replace("+", "_")
        assert main(["run", str(room_png / "pano.png"), "--out", str(out), "--size", "512", "--samples", "20",
                     "--quiet", "--box-edges", mode]) == 0
        timings[mode] = json.loads((out / "scene.json").read_text())["timing_s"]
        counts[mode] = (len(calls), len(refined))
    assert counts["net"][0] == 0 and counts["net"][1] > 0
    assert any(not np.array_equal(a.tile.box, b.tile.box) for a, b in refined)
    assert counts["silhouette"][1] == counts["net"][1] and counts["silhouette"][0] > 0
    assert any(c is not None and c.snapped.any() for c in calls)
    assert counts["detector"] == counts["silhouette"]  # the detector mode made no call of either
    assert "refine" in timings["net"] and "edges" not in timings["net"]
    assert "edges" in timings["silhouette"] and "refine" not in timings["silhouette"]
    assert "edges" not in timings["detector"] and "refine" not in timings["detector"]
    with pytest.raises(ValueError, match="box_edges: expected one of"):
        RunOptions(box_edges="grabcut")


def test_object_mask_from_the_tile_regions_or_the_panorama_boxes(tmp_path, room_png, monkeypatch):
    """`--object-mask tiles` (default) leaves out of the labels only the region inside each detection's tile
    boxes; `--object-mask box` the whole panorama boxes, a superset; the labels the run writes differ."""
    pytest.importorskip("torch")
    import apps.pipeline as pl

    masks = {}
    real = pl.object_mask

    def spy(dets, shape, mode="tiles"):
        masks[mode] = real(dets, shape, mode)
        return masks[mode]

    monkeypatch.setattr(pl, "object_mask", spy)
    labels = {}
    for mode in ("tiles", "box"):
        out = tmp_path / mode
        assert main(["run", str(room_png / "pano.png"), "--out", str(out), "--size", "512", "--samples", "20",
                     "--quiet", "--object-mask", mode]) == 0
        labels[mode] = np.array(Image.open(out / "label_ids.png"))
    assert set(masks) == {"tiles", "box"} and masks["tiles"].any()
    assert not (masks["tiles"] & ~masks["box"]).any() and masks["tiles"].sum() < masks["box"].sum()
    assert (labels["tiles"] == 5).sum() < (labels["box"] == 5).sum()


def test_ceiling_boundary_from_the_boundary_network_or_the_labels(tmp_path, room_png, monkeypatch):
    """`--ceiling network` moves the labels' ceiling-wall boundary onto the boundary network's before the room
    step; `--ceiling labels` keeps the fused labels' own; a bad mode is refused."""
    pytest.importorskip("torch")
    import layout.surfaces.boundary_net as bn

    from apps.pipeline import RunOptions

    calls = []
    real = bn.load_boundary_net

    def spy(*args, **kwargs):
        calls.append(args)
        return real(*args, **kwargs)

    monkeypatch.setattr(bn, "load_boundary_net", spy)
    labels, used = {}, {}
    for mode in ("network", "labels"):
        out = tmp_path / mode
        n = len(calls)
        assert main(["run", str(room_png / "pano.png"), "--out", str(out), "--size", "512", "--no-objects",
                     "--quiet", "--ceiling", mode]) == 0
        used[mode] = len(calls) - n
        labels[mode] = np.array(Image.open(out / "label_ids.png"))
    assert used == {"network": 1, "labels": 0}
    upper = slice(0, labels["labels"].shape[0] // 2)
    assert not np.array_equal(labels["network"][upper], labels["labels"][upper])
    with pytest.raises(ValueError, match="ceiling: expected one of"):
        RunOptions(ceiling="edges")


def test_walls_snapped_to_the_image_edges_or_kept_where_the_labels_put_them(tmp_path, room_png, monkeypatch):
    """`--walls edges` (default) moves the room step's walls onto the image's ceiling-wall edges, then scales the
    room onto its floor-wall edges (`layout.wallsnap.snap_room`), and the scene carries that room; `--walls
    labels` makes no such call; a bad mode is refused."""
    import layout.wallsnap as ws

    from apps.pipeline import RunOptions

    calls = []
    real = ws.snap_room

    def spy(*args, **kwargs):
        res = real(*args, **kwargs)
        calls.append(res)
        return res

    monkeypatch.setattr(ws, "snap_room", spy)
    scenes = {}
    for mode in ("edges", "labels"):
        out = tmp_path / mode
        n = len(calls)
        assert main(["run", str(room_png / "pano.png"), "--out", str(out), "--size", "512", "--no-objects",
                     "--quiet", "--walls", mode]) == 0
        assert len(calls) - n == (mode == "edges")
        scenes[mode] = json.loads((out / "scene.json").read_text())
    snap = calls[0]
    assert snap.walls.moved.any()  # in this room two walls move, by 5 and 15 %
    s = scenes["edges"]["camera"]["height_m"] / 1.6  # the room step works at the default 1.6 m
    # the scene is the snapped room (turned back by the rectification's few hundredths of a degree)
    np.testing.assert_allclose(np.array(scenes["edges"]["room"]["floor"]), snap.floor * s, atol=5e-3)
    assert scenes["edges"]["room"]["ceiling_z"] == pytest.approx(snap.ceiling_z * s, abs=5e-3)
    assert not np.allclose(scenes["edges"]["room"]["floor"], scenes["labels"]["room"]["floor"], atol=5e-2)
    with pytest.raises(ValueError, match="walls: expected one of"):
        RunOptions(walls="ceiling")


def test_a_box_around_the_whole_panorama_gets_no_pose_but_the_run_finishes(tmp_path, room_png):
    """A detection 360 degrees wide (a bed under the camera, seen all around) has no perspective crop: the run
    goes on without a pose for it instead of failing (seen on ../shared/data/real/lgtnet_demo)."""
    gt = json.loads((room_png / "gt.json").read_text())
    objs = [o for o in gt["objects"] if o["bbox_pano"] is not None]
    wide = dict(objs[0], id="wide-0", bbox_pano=[0.0, 135.0, 512.0, 256.0])  # from just below the horizon
    ann = tmp_path / "ann.json"
    ann.write_text(json.dumps({"image": gt["image"], "objects": [wide] + objs[1:]}))
    out = tmp_path / "o"
    assert main(["run", str(room_png / "pano.png"), "--out", str(out), "--detector", f"annotations:{ann}",
                 "--size", "512", "--quiet"]) == 0
    scene = json.loads((out / "scene.json").read_text())
    assert "wide-0" not in {o["id"] for o in scene["objects"]}


def test_model_choice_by_box_fit_recovers_the_camera_height(tmp_path, room_png):
    """`--models box` (default) picks models and camera height from the boxes; `--models appearance` is the
    paper's nearest render. With the room's own boxes the box fit lands within 3 % of the true camera height.
    The room is read with the labels' own ceiling boundary (`--ceiling labels`): with the boundary network's
    (the default since session 19) this one room's camera height comes out 6.8 % high (1.635 m for 1.531 m),
    although over the 88 rooms of seed 0 the error fell (docs/EVALUATION.md, "Session 19")."""
    gt = json.loads((room_png / "gt.json").read_text())
    heights = {}
    for mode in ("box", "appearance"):
        out = tmp_path / mode
        assert main(["run", str(room_png / "pano.png"), "--out", str(out), "--detector",
                     f"annotations:{room_png / 'gt.json'}", "--size", "512", "--quiet", "--models", mode,
                     "--ceiling", "labels"]) == 0
        scene = json.loads((out / "scene.json").read_text())
        heights[mode] = scene["camera"]["height_m"]
        assert ("models" in scene["timing_s"]) == (mode == "box")
    assert abs(heights["box"] / gt["camera_height_m"] - 1) < 0.03


def test_ceiling_estimate_follows_the_object_mask(room_png, monkeypatch):
    """With detections masked the room step takes the median wall-to-camera ratio; without objects the lowest
    well-supported mode (the labeller's furniture-as-floor guard) stays."""
    import layout.roomgeom
    from apps.imageio import read_panorama
    from apps.pipeline import RunOptions, run_pipeline

    seen = []
    real = layout.roomgeom.estimate_room_geometry

    def spy(*args, **kwargs):
        seen.append(kwargs.get("ceiling_estimate", "lowest_mode"))
        return real(*args, **kwargs)

    monkeypatch.setattr(layout.roomgeom, "estimate_room_geometry", spy)
    pano = read_panorama(room_png / "pano.png", max_width=512).image
    run_pipeline(pano, RunOptions(detector=f"annotations:{room_png / 'gt.json'}", samples=50))
    assert seen[0] == "median"
    seen.clear()
    run_pipeline(pano, RunOptions(objects=False, samples=50))
    assert seen == ["lowest_mode"]


def test_eo_of_a_fully_symmetric_candidate_model_is_read_at_any_yaw():
    """A class can mix models with and without a yaw (tables: 'two' and 'full'); the model choice reads the E_o of
    every candidate at the candidate yaws, also of a fully symmetric one (it used to raise)."""
    from types import SimpleNamespace

    from apps.pipeline import _eo_at

    est = SimpleNamespace(pitch=0.2, e_o_at=lambda r, p, m: 1.0 + 0.1 * r)
    model = SimpleNamespace(id="table-x", symmetry="full")
    out = _eo_at(est, np.array([1.0, 0.5, 0.0]), model, np.array([0.0, np.pi / 2]))
    assert out.shape == (2,) and np.all(np.isfinite(out))


def test_eval_with_the_scale_from_gt_json(room_png, tmp_path, capsys):
    """`pano2cad eval --gt-scale`: each room runs at its own gt camera height; eval.json and table2.md."""
    import shutil

    data = tmp_path / "data" / "room-0000"
    data.mkdir(parents=True)
    for f in ("pano.png", "gt.json"):
        shutil.copy(room_png / f, data / f)
    gt = json.loads((data / "gt.json").read_text())
    out = tmp_path / "ev"
    assert main(["eval", "--data", str(data.parent), "--out", str(out), "--no-objects", "--gt-scale",
                 "--jobs", "1", "--size", "512", "--quiet"]) == 0
    scene = json.loads((out / "room-0000" / "scene.json").read_text())
    assert scene["camera"]["height_m"] == pytest.approx(gt["camera_height_m"])
    ev = json.loads((out / "eval.json").read_text())
    assert ev["summary"]["layout"]["n_rooms"] == 1 and ev["summary"]["layout"]["failed"] == 0
    assert ev["rooms"][0]["layout"]["camera_height_err"] == pytest.approx(0.0, abs=1e-9)
    assert ev["summary"]["layout"]["iou_3d"] > 0.5
    assert (out / "table2.md").is_file() and "Detection AP" not in (out / "table2.md").read_text()
    capsys.readouterr()
    assert main(["eval", "--data", str(data.parent), "--out", str(tmp_path / "ev2"), "--gt-scale",
                 "--camera-height", "1.5", "--quiet"]) == 2
    _one_line_error(capsys, "--gt-scale")


def test_room_without_boxes_is_kept_only_where_it_explains_more(monkeypatch):
    """Boxes over most of the floor-wall boundary (false detections on a real photo) can leave the masked room
    step explaining few of its wall columns: the panorama is labelled again without them and that room is kept
    only when its polygon explains a larger share of its own columns."""
    from types import SimpleNamespace

    import layout.roomgeom
    import layout.surfaces
    from apps.pipeline import _room_without_boxes

    pano = np.zeros((4, 8, 3), np.uint8)
    masked_surf, masked_geom = object(), SimpleNamespace(inlier_fraction=0.45)
    free_surf = SimpleNamespace(labels=np.zeros((4, 8), np.uint8), warnings=())
    monkeypatch.setattr(layout.surfaces, "estimate_surfaces", lambda pano, ceiling_net=None: free_surf)
    for free_inliers, expect_free in ((0.50, True), (0.45, False), (0.30, False)):
        free_geom = SimpleNamespace(inlier_fraction=free_inliers)
        monkeypatch.setattr(layout.roomgeom, "estimate_room_geometry", lambda labels, h, **kw: free_geom)
        notes: list[str] = []
        got = _room_without_boxes(pano, masked_surf, masked_geom, 1.6, True, notes)
        assert got == ((free_surf, free_geom) if expect_free else (masked_surf, masked_geom))
        assert notes == (["room geometry ignored the object boxes (with them masked the polygon explains 45.0% of "
                          "the observed wall columns, without them 50.0%)"] if expect_free else [])

    def fails(labels, h, **kw):
        raise layout.roomgeom.RoomGeometryError("no wall")

    monkeypatch.setattr(layout.roomgeom, "estimate_room_geometry", fails)
    assert _room_without_boxes(pano, masked_surf, masked_geom, 1.6, True, []) == (masked_surf, masked_geom)
