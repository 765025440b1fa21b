"""Room geometry from surface labels: speed at 1024x512 and accuracy on synthetic and real rooms.

Usage::

    python benchmarks/bench_roomgeom.py [--rooms 88] [--pc-rooms 24] [--update-docs]

Prints two markdown sections:

* "## Room geometry" (speed): wall-clock and CPU time of each stage of
  :func:`layout.roomgeom.estimate_room_geometry` at 1024x512 (labels to
  floor polygon; target < 1 s), the analytic label renderer and a batch of
  room hypotheses scored against a label map (the paper's E_s).
* "## Room geometry from labels" (accuracy): the synthetic set of
  ``--rooms`` rooms drawn by :func:`layout.rooms.generate_rooms` (seed
  2016), each seen from a camera at least 0.5 m from every wall - drawn
  uniformly, or the best of 8 draws by visible floor area - with the
  analytic ground-truth label maps and with corrupted ones
  (:func:`layout.labelmap.perturb_labels`: wobbly boundaries, wrong-label
  blobs, clutter hiding wall bottoms, masked object boxes) standing in for
  estimated labels; then the real panoramas of ../shared/data/real, their
  label maps rendered from gt.json, scored with :mod:`layout.metrics` and
  with shared/tools/score_scene.py, and their labels estimated by
  :func:`layout.surfaces.estimate_surfaces` after rectification, with the
  previous estimator's options and with the current defaults.

``--update-docs`` writes the sections into docs/BENCHMARKS.md and
docs/EVALUATION.md (only those sections; the files are re-read just before
writing, others edit them too).
"""

from __future__ import annotations

import sys as _sys
_sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parent))
from _docs import replace_section  # noqa: E402

import argparse
import importlib.util
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from layout.labelmap import (  # noqa: E402
    LabelCounts,
    perturb_labels,
    render_room_labels,
    room_boundaries,
    sample_camera_xy,
    shade_labels,
    visible_floor_fraction,
)
from layout.metrics import corner_error, iou_2d, iou_3d, pixel_error  # noqa: E402
from layout.roomgeom import RoomGeometryError, estimate_room_geometry, observe_columns  # noqa: E402
from layout.rooms import generate_rooms  # noqa: E402
from layout.wallsnap import snap_room  # noqa: E402

SHARED = ROOT.parent / "shared"
BENCH_DOC = ROOT / "docs" / "BENCHMARKS.md"
EVAL_DOC = ROOT / "docs" / "EVALUATION.md"
BENCH_SECTION = "## Room geometry"
EVAL_SECTION = "## Room geometry from labels"
WIDTH = 1024
CAM_H = 1.6
#: estimate_room_geometry options that reproduce the estimator before the ceiling-first change
LEGACY = dict(prefer="floor", shape_axis=False, ceiling_estimate="median", robust=False)


def _timed(fn, *args, **kwargs):
    w0, c0 = time.perf_counter(), time.process_time()
    out = fn(*args, **kwargs)
    return out, time.perf_counter() - w0, time.process_time() - c0


def _scenes(n, candidates, seed=2016):
    rng = np.random.default_rng(seed)
    rooms = generate_rooms(n, rng)
    out = []
    for i, room in enumerate(rooms):
        cam = sample_camera_xy(room.floor, rng, margin=0.5, candidates=candidates)
        out.append((i, room, cam))
    return out


# ---------------------------------------------------------------- speed


def speed_section(n_rooms=10, repeat=3):
    scenes = _scenes(n_rooms, 1, seed=7)
    rows = {k: [] for k in ("render", "observe", "columns", "columns_noisy", "pointcloud", "snap", "hyp", "iou")}
    for i, room, cam in scenes:
        lab, w, c = _timed(render_room_labels, room.floor, room.ceiling_z, cam, CAM_H, WIDTH)
        rows["render"].append((w, c))
        _, w, c = _timed(observe_columns, lab, CAM_H)
        rows["observe"].append((w, c))
        best = min((_timed(estimate_room_geometry, lab, CAM_H) for _ in range(repeat)), key=lambda t: t[1])
        rows["columns"].append(best[1:])
        noisy, mask = perturb_labels(lab, i)
        best = min((_timed(estimate_room_geometry, noisy, CAM_H, object_mask=mask) for _ in range(repeat)),
                   key=lambda t: t[1])
        rows["columns_noisy"].append(best[1:])
        # the wall snap of the corrupted labels' room, on a grey panorama painted from the clean label map
        grey = shade_labels(lab, i)
        geom = best[0]

        rows["snap"].append(min((_timed(snap_room, grey, geom.floor, geom.ceiling_z, CAM_H, object_mask=mask)
                                 for _ in range(repeat)), key=lambda t: t[1])[1:])
        if i < 5:
            _timed(estimate_room_geometry, lab, CAM_H, method="pointcloud")  # Open3D import and caches
            _, w, c = _timed(estimate_room_geometry, lab, CAM_H, method="pointcloud")
            rows["pointcloud"].append((w, c))
        counts = LabelCounts.from_labels(lab)
        floor = room.floor - cam
        scales = np.linspace(0.8, 1.2, 100)

        def score_batch():
            return counts.agreement(room_boundaries(floor, room.ceiling_z, [0.0, 0.0], CAM_H, WIDTH, scale=scales))

        _, w, c = _timed(score_batch)
        rows["hyp"].append((w, c))
        _, w, c = _timed(iou_3d, floor, room.ceiling_z, floor * 1.05 + 0.1, room.ceiling_z)
        rows["iou"].append((w, c))

    def fmt(key, digits=1):
        a = 1000.0 * np.asarray(rows[key])
        return f"{np.median(a[:, 0]):.{digits}f} | {a[:, 0].max():.{digits}f} | {np.median(a[:, 1]):.{digits}f}"

    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    lines = [
        BENCH_SECTION,
        "",
        "`python benchmarks/bench_roomgeom.py --update-docs` (this section is written by the script). "
        f"{n_rooms} random rooms of `layout.rooms` seen at {WIDTH}x{WIDTH // 2} from a camera 0.5 m or more from "
        f"the walls; wall-clock median and maximum over the rooms (best of {repeat} runs per room for the "
        "geometry), and the median CPU time of the process, the fairer figure on this shared 2-core machine.",
        "",
        "| stage | wall ms median | wall ms max | CPU ms median |",
        "|---|---:|---:|---:|",
        f"| analytic label map (`render_room_labels`) | {fmt('render')} |",
        f"| per-column boundaries and wall points (`observe_columns`) | {fmt('observe')} |",
        f"| **labels to floor polygon**, ground-truth labels (`estimate_room_geometry`, columns) | {fmt('columns')} |",
        f"| **labels to floor polygon**, corrupted labels + object mask | {fmt('columns_noisy')} |",
        f"| labels to floor polygon, paper route (`method=\"pointcloud\"`: 6 views, Open3D alignment, greedy "
        f"planes; {len(rows['pointcloud'])} rooms) | {fmt('pointcloud')} |",
        "| walls and ceiling height onto the image's creases (`layout.wallsnap.snap_room`: `snap_walls` + "
        "`snap_ceiling_height`, "
        f"the corrupted labels' room, a grey panorama painted from the labels) | {fmt('snap')} |",
        f"| 100 scale hypotheses scored against the labels (`room_boundaries` batch + `LabelCounts.agreement`) "
        f"| {fmt('hyp')} |",
        f"| exact `iou_3d` of two floor polygons | {fmt('iou', 2)} |",
        "",
        "Target: labels to floor polygon in under 1 s at 1024x512. "
        f"Environment: python {platform.python_version()}, numpy {np.__version__}, cpus {os.cpu_count()}, "
        f"load average (1 min) at the end {load:.1f}.",
        "",
    ]
    return "\n".join(lines)


# ---------------------------------------------------------------- accuracy


def _evaluate(scenes, noisy, method):
    res = []
    for i, room, cam in scenes:
        truth = room.floor - cam
        lab = render_room_labels(room.floor, room.ceiling_z, cam, CAM_H, WIDTH)
        mask = None
        if noisy:
            lab, mask = perturb_labels(lab, 10_000 + i)
        try:
            geo = estimate_room_geometry(lab, CAM_H, object_mask=mask, method=method)
        except RoomGeometryError:
            res.append(dict(iou3d=0.0, iou2d=0.0, corners=False, cerr=np.nan, herr=np.nan, pix=1.0, unc=True))
            continue
        ce = corner_error(geo.floor, truth)
        res.append(dict(iou3d=iou_3d(geo.floor, geo.ceiling_z, truth, room.ceiling_z), iou2d=iou_2d(geo.floor, truth),
                        corners=geo.n_corners == len(truth), cerr=ce.mean if ce.same_count else np.nan,
                        herr=abs(geo.ceiling_z - room.ceiling_z),
                        pix=pixel_error(geo.floor, geo.ceiling_z, truth, room.ceiling_z, CAM_H, 512),
                        unc=geo.uncertain))
    return res


def _row(name, res, seen):
    a = {k: np.array([r[k] for r in res], float) for k in res[0]}
    return (f"| {name} | {len(res)} | {100 * np.mean(seen):.1f} | {100 * a['iou3d'].mean():.1f} | "
            f"{100 * np.median(a['iou3d']):.1f} | {100 * a['iou2d'].mean():.1f} | {100 * a['corners'].mean():.0f} | "
            f"{100 * np.nanmedian(a['cerr']):.1f} | {100 * np.nanmean(a['herr']):.1f} | {100 * a['pix'].mean():.2f} | "
            f"{100 * a['unc'].mean():.0f} |")


def _score_scene_module():
    path = SHARED / "tools" / "score_scene.py"
    if not path.is_file():
        return None
    spec = importlib.util.spec_from_file_location("score_scene", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def real_rows():
    real = SHARED / "data" / "real"
    if not real.is_dir():
        return ["(../shared/data/real is absent: no real panoramas scored.)"]
    scorer = _score_scene_module()
    lines = ["| panorama | corners gt / ours | method | 3D IoU | 2D IoU | wall height error | score_scene 3D IoU | "
             "score_scene 2D IoU |", "|---|---|---|---:|---:|---:|---:|---:|"]
    per_method: dict[str, list[float]] = {}
    for d in sorted(p for p in real.iterdir() if (p / "gt.json").is_file()):
        gt = json.loads((d / "gt.json").read_text())
        floor = np.asarray(gt["room"]["floor"], float)
        ceil = float(gt["room"]["ceiling_z"])
        h = float(gt["camera_height_m"])
        w = int(gt["image"]["width"])
        lab = render_room_labels(floor, ceil, [0.0, 0.0], h, w)
        for method in ("columns", "pointcloud"):
            geo = estimate_room_geometry(lab, h, method=method)
            i3 = iou_3d(geo.floor, geo.ceiling_z, floor, ceil)
            i2 = iou_2d(geo.floor, floor)
            per_method.setdefault(method, []).append(i3)
            if scorer is not None:
                s = scorer.score_room({"room": geo.room_dict()}, gt)
                ext = f"{100 * s['iou3d']:.1f} | {100 * s['iou2d']:.1f}"
            else:
                ext = "- | -"
            lines.append(f"| {d.name} | {len(floor)} / {geo.n_corners} | {method} | {100 * i3:.1f} | {100 * i2:.1f} | "
                         f"{abs(geo.ceiling_z - ceil):.3f} | {ext} |")
    lines.append("")
    lines.append("Mean 3D IoU: " + ", ".join(f"{m} {100 * np.mean(v):.1f}%" for m, v in per_method.items())
                 + " (target >= 80%). Units: camera height = 1 (gt.json `scale_known: false`).")
    return lines


def furnished_rows(seeds=10, boxes=6):
    """Real rooms, labels rendered from gt.json plus furniture boxes over the floor boundary (the real-panorama
    test's ``furnish``: filled with floor or clutter), before and after: 3D IoU min / mean and corner counts."""
    real = SHARED / "data" / "real"
    path = ROOT / "tests" / "layout" / "test_roomgeom_real.py"
    if not real.is_dir() or not path.is_file():
        return ["(../shared/data/real or tests/layout/test_roomgeom_real.py is absent.)"]
    spec = importlib.util.spec_from_file_location("test_roomgeom_real", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    lines = ["| panorama | estimator | maps | 3D IoU % min | 3D IoU % mean | corners gt / ours (max) |",
             "|---|---|---:|---:|---:|---|"]
    for d in sorted(p for p in real.iterdir() if (p / "gt.json").is_file()):
        gt = json.loads((d / "gt.json").read_text())
        floor = np.asarray(gt["room"]["floor"], float)
        ceil = float(gt["room"]["ceiling_z"])
        h = float(gt["camera_height_m"])
        lab = render_room_labels(floor, ceil, [0.0, 0.0], h, int(gt["image"]["width"]))
        maps = [mod.furnish(lab, np.random.default_rng(s), boxes, fill) for s in range(seeds) for fill in (1, 0)]
        for name, kw in (("before (floor first)", LEGACY), ("**after** (default)", {})):
            ious, corners = [], []
            for m in maps:
                geo = estimate_room_geometry(m, h, **kw)
                ious.append(iou_3d(geo.floor, geo.ceiling_z, floor, ceil))
                corners.append(geo.n_corners)
            lines.append(f"| {d.name} | {name} | {len(maps)} | {100 * min(ious):.1f} | {100 * np.mean(ious):.1f} | "
                         f"{len(floor)} / {max(corners)} |")
    return lines


def estimated_label_rows():
    """Real panoramas with the project's own labels: rectify ("walls"), estimate_surfaces, room geometry.

    The ground truth is rotated into the rectified frame (``camera.rotation`` maps input-camera directions
    into it), so the polygons are compared where the estimator works.
    """
    real = SHARED / "data" / "real"
    if not real.is_dir():
        return ["(../shared/data/real is absent: no real panoramas scored.)"]
    import cv2

    from layout.surfaces import estimate_surfaces
    from panogeom.rectify import estimate_rectification

    lines = ["| panorama | labels | estimator | corners gt / ours | 3D IoU | 2D IoU | ceiling / gt (camera heights) |",
             "|---|---|---|---|---:|---:|---|"]
    means: dict[str, list[float]] = {}
    for d in sorted(p for p in real.iterdir() if (p / "gt.json").is_file()):
        gt = json.loads((d / "gt.json").read_text())
        img = cv2.imread(str(d / gt["image"]["file"]), cv2.IMREAD_COLOR)
        if img is None:
            lines.append(f"| {d.name} | (image unreadable) | | | | | |")
            continue
        img = cv2.cvtColor(img, cv2.COLOR_BGR2RGB)
        if img.shape[1] != WIDTH:
            img = cv2.resize(img, (WIDTH, WIDTH // 2), interpolation=cv2.INTER_AREA)
        rect = estimate_rectification(img, mode="walls")
        surf = estimate_surfaces(rect.apply(img))
        rot = np.asarray(rect.rotation, float)
        floor_in = np.asarray(gt["room"]["floor"], float)
        floor = (np.c_[floor_in, np.zeros(len(floor_in))] @ rot.T)[:, :2]
        ceil = float(gt["room"]["ceiling_z"])
        h = float(gt["camera_height_m"])
        for name, kw in (("before (floor first)", LEGACY), ("**after** (ceiling first, default)", {})):
            try:
                geo = estimate_room_geometry(surf.labels, h, **kw)
            except RoomGeometryError as exc:
                lines.append(f"| {d.name} | estimated | {name} | {len(floor)} / - | 0.0 | 0.0 | failed: {exc} |")
                means.setdefault(name, []).append(0.0)
                continue
            i3 = iou_3d(geo.floor, geo.ceiling_z, floor, ceil)
            means.setdefault(name, []).append(i3)
            lines.append(f"| {d.name} | estimated | {name} | {len(floor)} / {geo.n_corners} | {100 * i3:.1f} | "
                         f"{100 * iou_2d(geo.floor, floor):.1f} | {geo.ceiling_z:.2f} / {ceil:.2f} |")
    lines.append("")
    lines.append("Mean 3D IoU with estimated labels: " + ", ".join(f"{m} {100 * np.mean(v):.1f}%"
                                                                    for m, v in means.items()) + ".")
    return lines


def eval_section(n_rooms, pc_rooms):
    uniform = _scenes(n_rooms, 1)
    best8 = _scenes(n_rooms, 8)
    seen_u = [visible_floor_fraction(r.floor, c, width=512, cells=100) for _, r, c in uniform]
    seen_b = [visible_floor_fraction(r.floor, c, width=512, cells=100) for _, r, c in best8]
    templates = {}
    for _, r, _ in uniform:
        templates[r.template] = templates.get(r.template, 0) + 1
    head = ("| labels, camera, method | rooms | floor seen % | 3D IoU % mean | 3D IoU % median | 2D IoU % | "
            "exact corner count % | corner error cm (median) | wall height error cm | pixel error % | "
            "flagged uncertain % |")
    rows = [head, "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    t0 = time.perf_counter()
    for noisy in (False, True):
        for cam_name, scenes, seen in (("uniform camera", uniform, seen_u), ("best-of-8 camera", best8, seen_b)):
            lab_name = "corrupted" if noisy else "ground truth"
            res = _evaluate(scenes, noisy, "columns")
            rows.append(_row(f"{lab_name}, {cam_name}, columns", res, seen))
            rows.append(_row(f"{lab_name}, {cam_name}, columns, first {pc_rooms}", res[:pc_rooms], seen[:pc_rooms]))
            rows.append(_row(f"{lab_name}, {cam_name}, pointcloud, first {pc_rooms}",
                             _evaluate(scenes[:pc_rooms], noisy, "pointcloud"), seen[:pc_rooms]))
    elapsed = time.perf_counter() - t0
    lines = [
        EVAL_SECTION,
        "",
        "`python benchmarks/bench_roomgeom.py --update-docs` (this section is written by the script). "
        "`layout.roomgeom.estimate_room_geometry` turns a surface-label panorama (1024x512, camera height 1.6 m) "
        "into a Manhattan floor polygon and wall height. Synthetic set: "
        f"{n_rooms} rooms from `layout.rooms.generate_rooms({n_rooms}, 2016)` ("
        + ", ".join(f"{k} {v}" for k, v in sorted(templates.items()))
        + "), camera 0.5 m or more from every wall, drawn uniformly or as the best of 8 draws by visible floor "
        "area (`sample_camera_xy(candidates=8)`, where a photographer would stand). 'Ground truth' labels are "
        "the analytic label maps (`render_room_labels`); 'corrupted' labels (`perturb_labels`: boundaries "
        "wobbling by 2 px rms at 512 rows, 12 wrong-label blobs, 6 clutter bands over wall bottoms, 3 masked "
        "object boxes) stand in for estimated labels until the project's labeller is scored here. The point-"
        f"cloud route (the paper's) runs on the first {pc_rooms} rooms of each set. 'Floor seen' is the part of "
        "the floor visible from the camera: what no label map can show is completed as the smallest "
        "consistent extension behind the occluding corner, which is where the remaining IoU goes.",
        "",
        *rows,
        "",
        "Acceptance (issue 6): ground-truth labels mean 3D IoU >= 97% and exact corner count in >= 90% of rooms; "
        "estimated labels mean 3D IoU >= 90%.",
        "",
        "Real panoramas (../shared/data/real): label maps rendered from each gt.json (corners and camera height 1), "
        "so these rows check the geometry on real room shapes and camera placements, not a labeller.",
        "",
        *real_rows(),
        "",
        "The same real rooms with furniture: the label maps rendered from gt.json get 6 boxes standing on the "
        "floor-wall boundary, 4-16 % of the width wide, reaching 30-80 % of the way to the horizon, filled with "
        "floor (1) or clutter (0) labels (`furnish` of tests/layout/test_roomgeom_real.py, seeds 0-9, both "
        "fills), estimated with the previous estimator's options and with the defaults; the test asserts "
        "3D IoU > 95 % and at most 8 corners.",
        "",
        *furnished_rows(),
        "",
        "Real panoramas with the project's own labels (the most important rows): each pano.png rectified with "
        "`panogeom.rectify.estimate_rectification(pano, mode=\"walls\")`, labelled by "
        "`layout.surfaces.estimate_surfaces` (its `labels`, as committed when this section was written; the "
        "labeller is being retrained, so these figures move with it), then `estimate_room_geometry` with the "
        "options of the estimator before the ceiling-first change (`prefer=\"floor\", shape_axis=False, "
        "ceiling_estimate=\"median\", robust=False`) and with the defaults. Ground truth rotated into the "
        "rectified frame; units camera height = 1.",
        "",
        *estimated_label_rows(),
        "",
        f"Evaluation time {elapsed:.0f} s on {os.cpu_count()} cores.",
        "",
    ]
    return "\n".join(lines)


def update_docs(path: Path, title: str, section_name: str, section: str) -> None:
    """Replace our section of a docs file (benchmarks/_docs.py); ``title`` names a new file's kind."""
    replace_section(path, section, section_name)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                 formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    ap.add_argument("--rooms", type=int, default=88, help="synthetic rooms in the accuracy evaluation")
    ap.add_argument("--pc-rooms", type=int, default=24, help="rooms also run through the point-cloud route")
    ap.add_argument("--speed-only", action="store_true", help="skip the accuracy evaluation")
    ap.add_argument("--update-docs", action="store_true", help="write the sections into docs/BENCHMARKS.md and "
                                                               "docs/EVALUATION.md")
    args = ap.parse_args(argv)
    if args.rooms < 1 or not 1 <= args.pc_rooms <= args.rooms:
        ap.error(f"expected --rooms >= 1 and 1 <= --pc-rooms <= --rooms, got {args.rooms} and {args.pc_rooms}")
    speed = speed_section()
    print(speed)
    if args.update_docs:
        update_docs(BENCH_DOC, "Benchmarks", BENCH_SECTION, speed)
    if not args.speed_only:
        ev = eval_section(args.rooms, args.pc_rooms)
        print(ev)
        if args.update_docs:
            update_docs(EVAL_DOC, "Evaluation", EVAL_SECTION, ev)
    return 0


if __name__ == "__main__":
    sys.exit(main())
