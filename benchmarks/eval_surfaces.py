"""Accuracy of the surface labels (layout.surfaces) on held-out synthetic rooms and on real panoramas.

Synthetic (``--synth``, default out/train/surfaces/test): a set the network
never saw, made with a seed outside the training and validation seeds of
layout/surfaces/weights/gc_net.json (checked; the default set is
``pano2cad synth --seed 2500 --rooms 40 --size 1024``; seed 0, the project's
evaluation set, is never used for training). The synthetic camera is
upright and wall-aligned, so the panorama is labelled as it is; object
masks are the ground truth ones (label 5, as a detector's masks would be
passed). Per room:

- fused: 5-class pixel accuracy of ``labels`` on non-object pixels
  (unknown counts as wrong);
- wall orientation: on ground-truth wall pixels that the fused map labels as
  a wall, the share with the right orientation ("strict": on all
  ground-truth wall pixels, the share labelled with the right wall label);
- GC: 4-class accuracy of the network's argmax (objects = clutter);
- layout: accuracy of the clutter-free ``layout`` map on non-object pixels;
- no masks: fused accuracy on non-object pixels when no object mask is given
  (GC alone must find the clutter);
- ablation of the wall-orientation evidence: orientation of the clutter-free
  layout map on all ground-truth wall pixels with both kinds of evidence,
  with the orientation map's votes only and with the boundary shape only.

Real (../shared/data/real/*/gt.json): rectified in "walls" mode with
panogeom.rectify, labelled, and the labels rotated back into the input
panorama (the labels.png contract); the reference is rendered from gt.json's
layout (layout.labelmap.render_room_labels; objects ignored, so furniture
pixels count as the floor or wall behind them). Floor / ceiling / wall
pixel accuracy of the fused labels (clutter and unknown count as wrong) and
of the clutter-free layout map, and the wall-orientation accuracy of the
layout map on the reference's wall pixels that it labels as a wall.

Prints Markdown; ``--update-docs`` replaces its section of docs/EVALUATION.md.
Run: ``.venv/bin/python benchmarks/eval_surfaces.py [--update-docs]``
"""

from __future__ import annotations

import sys as _sys
_sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parent))
from _docs import replace_section  # noqa: E402

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
REAL = REPO.parent / "shared" / "data" / "real"
SECTION = "## Surface labels (layout.surfaces)"
THREE = np.array([0, 1, 2, 3, 3, 0])  # label id -> 0 none, 1 floor, 2 ceiling, 3 wall


def read_rgb(path: Path) -> np.ndarray:
    bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if bgr is None:
        raise SystemExit(f"eval_surfaces: cannot read {path}")
    return np.ascontiguousarray(bgr[..., ::-1])


def synthetic(folder: Path, record: dict, limit: int | None) -> tuple[list[str], dict]:
    from layout.surfaces import estimate_surfaces, fuse_surfaces, load_gc_net, orientation_map
    from layout.surfaces.gc_net import gc_targets
    from panogeom.lines import detect_line_segments

    rooms = sorted(d for d in folder.glob("room-*") if (d / "pano.png").is_file() and (d / "labels.png").is_file())
    if limit:
        rooms = rooms[:limit]
    if not rooms:
        raise SystemExit(f"eval_surfaces: no rooms in {folder}; make them with "
                         f".venv/bin/pano2cad synth --seed 2500 --rooms 40 --size 1024 --out {folder}")
    used = {s for part in ("train", "val") for src in record[part]["sources"] for s in src["seeds"]} | {0}
    seeds = {json.loads((d / "gt.json").read_text())["generator"]["seed"] for d in rooms}
    if seeds & used:
        raise SystemExit(f"eval_surfaces: {folder} has seeds {sorted(seeds)}, which overlap the network's "
                         f"training / validation seeds or seed 0 ({sorted(used)}): not a held-out set")
    gc = load_gc_net()
    acc = {k: [0, 0] for k in ("fused", "orient", "strict", "gc", "layout", "nomask", "unknown", "col_both",
                               "col_om", "col_shape")}
    per_room = []
    t_all = []
    for d in rooms:
        pano = read_rgb(d / "pano.png")
        gt = cv2.imread(str(d / "labels.png"), cv2.IMREAD_UNCHANGED)
        obj = gt == 5
        t = time.perf_counter()
        segs = detect_line_segments(pano)
        s = estimate_surfaces(pano, segs, object_mask=obj, gc=gc)
        t_all.append(time.perf_counter() - t)
        s0 = estimate_surfaces(pano, segs, gc=gc)
        om = orientation_map(segs, pano.shape[1])
        only_om = fuse_surfaces(s.gc_probs, om, object_mask=obj, shape_weight=0.0)
        only_shape = fuse_surfaces(s.gc_probs, om, object_mask=obj, om_weight=0.0)
        keep = ~obj
        wall = ((gt == 3) | (gt == 4)) & keep
        as_wall = wall & ((s.labels == 3) | (s.labels == 4))
        tg = gc_targets(gt)
        parts = {
            "fused": (np.sum(s.labels[keep] == gt[keep]), keep.sum()),
            "orient": (np.sum(s.labels[as_wall] == gt[as_wall]), as_wall.sum()),
            "strict": (np.sum(s.labels[wall] == gt[wall]), wall.sum()),
            "gc": (np.sum(np.argmax(s.gc_probs, axis=2) == tg), tg.size),
            "layout": (np.sum(s.layout[keep] == gt[keep]), keep.sum()),
            "nomask": (np.sum(s0.labels[keep] == gt[keep]), keep.sum()),
            "unknown": (np.sum(s.labels[keep] == 0), keep.sum()),
            "col_both": (np.sum(s.layout[wall] == gt[wall]), wall.sum()),
            "col_om": (np.sum(only_om.layout[wall] == gt[wall]), wall.sum()),
            "col_shape": (np.sum(only_shape.layout[wall] == gt[wall]), wall.sum()),
        }
        for k, (a, b) in parts.items():
            acc[k][0] += int(a)
            acc[k][1] += int(b)
        per_room.append({k: a / max(b, 1) for k, (a, b) in parts.items()})
        print(f"{d.name}: " + ", ".join(f"{k} {v:.4f}" for k, v in per_room[-1].items()), file=sys.stderr)
    pix = {k: a / max(b, 1) for k, (a, b) in acc.items()}
    mean = {k: float(np.mean([r[k] for r in per_room])) for k in acc}
    worst = {k: float(np.min([r[k] for r in per_room])) for k in acc}
    size = cv2.imread(str(rooms[0] / "pano.png")).shape
    lines = [f"Held-out synthetic set `{folder.name}`: {len(rooms)} rooms, seed(s) {sorted(seeds)}, "
             f"{size[1]}x{size[0]}; the network was trained on seeds "
             f"{sorted({s for src in record['train']['sources'] for s in src['seeds']})} and validated on "
             f"{sorted({s for src in record['val']['sources'] for s in src['seeds']})}. Median time of "
             f"`estimate_surfaces` (lines detected inside) {np.median(t_all):.2f} s wall per room.", "",
             "| metric | all pixels | mean over rooms | worst room | target |", "|---|---:|---:|---:|---:|"]
    names = [("fused", "fused 5-class accuracy, non-object pixels", ">= 93%"),
             ("orient", "wall orientation on pixels labelled wall", ">= 95%"),
             ("strict", "wall pixels with the right wall label (strict)", ""),
             ("gc", "GC 4-class accuracy (argmax)", ""),
             ("layout", "clutter-free layout map, non-object pixels", ""),
             ("nomask", "fused, no object mask given, non-object pixels", ""),
             ("unknown", "share of non-object pixels left unknown / clutter", ""),
             ("col_both", "wall orientation of the layout map, all wall pixels: OM + boundary shape", ""),
             ("col_om", "same, orientation map votes only (ablation)", ""),
             ("col_shape", "same, boundary shape only (ablation)", "")]
    for k, text, target in names:
        lines.append(f"| {text} | {100 * pix[k]:.1f}% | {100 * mean[k]:.1f}% | {100 * worst[k]:.1f}% | {target} |")
    return lines, pix


def real() -> list[str]:
    from layout.labelmap import render_room_labels
    from layout.surfaces import estimate_surfaces
    from panogeom.rectify import estimate_rectification
    from panogeom.transform import rotate_pano

    rows = []
    for d in sorted(REAL.iterdir()) if REAL.is_dir() else []:
        if not (d / "gt.json").is_file():
            continue
        gt = json.loads((d / "gt.json").read_text())
        pano = read_rgb(d / gt["image"]["file"])
        H, W = pano.shape[:2]
        rect = estimate_rectification(pano, "walls")
        s = estimate_surfaces(rect.apply(pano), rect.segments.rotated(rect.rotation))
        labels = rotate_pano(s.labels, rect.rotation.T, "nearest")
        layout = rotate_pano(s.layout, rect.rotation.T, "nearest")
        truth = render_room_labels(gt["room"]["floor"], gt["room"]["ceiling_z"], [0.0, 0.0], gt["camera_height_m"], W)
        t3 = THREE[truth]
        wall = ((truth == 3) | (truth == 4)) & ((layout == 3) | (layout == 4))
        fused = float(np.mean(THREE[labels] == t3))
        lay = float(np.mean(THREE[layout] == t3))
        orient = float(np.mean(layout[wall] == truth[wall]))
        unknown = float(np.mean(labels == 0))
        rows.append((d.name, f"{W}x{H}", np.rad2deg(rect.tilt), fused, lay, orient, unknown, len(s.warnings)))
        print(f"{d.name}: fused {fused:.4f} layout {lay:.4f} orientation {orient:.4f}", file=sys.stderr)
    if not rows:
        return ["No real panoramas found (../shared/data/real)."]
    lines = ["Real panoramas (../shared/data/real): reference labels from gt.json's layout, objects ignored "
             "(furniture pixels count as the floor or wall behind them). Target: floor / ceiling / wall "
             ">= 85% on average.", "",
             "| panorama | size | tilt removed | floor/ceiling/wall, fused labels (clutter = wrong) | "
             "floor/ceiling/wall, clutter-free layout | wall orientation (layout, on wall pixels it calls wall) | "
             "unknown / clutter | warnings |",
             "|---|---|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r[0]} | {r[1]} | {r[2]:.2f} deg | {100 * r[3]:.1f}% | {100 * r[4]:.1f}% | "
                     f"{100 * r[5]:.1f}% | {100 * r[6]:.1f}% | {r[7]} |")
    lines.append(f"| **mean** | | | **{100 * np.mean([r[3] for r in rows]):.1f}%** | "
                 f"**{100 * np.mean([r[4] for r in rows]):.1f}%** | {100 * np.mean([r[5] for r in rows]):.1f}% | "
                 f"{100 * np.mean([r[6] for r in rows]):.1f}% | |")
    return lines


def update_docs(text: str, path: Path) -> None:
    """Replace this script's section (benchmarks/_docs.py)."""
    replace_section(path, text, SECTION)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--synth", default=str(REPO / "out" / "train" / "surfaces" / "test"))
    ap.add_argument("--rooms", type=int, default=None, help="use only the first N rooms")
    ap.add_argument("--update-docs", action="store_true", help="write the section into docs/EVALUATION.md")
    args = ap.parse_args(argv)
    from layout.surfaces.gc_net import DEFAULT_WEIGHTS

    record = json.loads(DEFAULT_WEIGHTS.with_suffix(".json").read_text())
    synth_lines, _ = synthetic(Path(args.synth), record, args.rooms)
    lines = [SECTION, "",
             "`.venv/bin/python benchmarks/eval_surfaces.py --update-docs` (this section is written by the "
             "script). `layout.surfaces.estimate_surfaces`: geometric-context network (weights "
             f"`layout/surfaces/weights/gc_net.pt`, {record['params']} parameters, {record['epochs_done']} epochs "
             f"on {record['train']['rooms']} synthetic rooms, validation accuracy "
             f"{100 * record['val_pixel_accuracy']:.1f}%) fused with the orientation map of the panorama's line "
             "segments (see the module docstring of layout/surfaces/fusion.py).", ""]
    lines += synth_lines + [""] + real()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    lines += ["", f"Environment: python {platform.python_version()}, numpy {np.__version__}, opencv {cv2.__version__}, "
                  f"{os.cpu_count()} CPUs, load average {load:.1f}.", ""]
    text = "\n".join(lines)
    print(text)
    if args.update_docs:
        update_docs(text, REPO / "docs" / "EVALUATION.md")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
