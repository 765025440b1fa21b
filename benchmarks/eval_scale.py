"""Where the scale and position errors of the pipeline come from (figures of docs/EVALUATION.md, Table 2).

Run::

    pano2cad synth --rooms 88 --seed 0 --size 1024 --out out/eval88
    pano2cad eval --data out/eval88 --out out/table2_gtboxes --detector gt-boxes --samples 3000
    .venv/bin/python benchmarks/eval_scale.py out/eval88 out/table2_gtboxes [--update-docs]

1. Camera height of single objects from their gt box with the TRUE model, true yaw and the camera height left
   free (:func:`layout.sampler.initialise_objects`), predicting the box from the model's bounding cuboid, from
   its convex hull (:func:`layout.sampler.hull_outline`) or from its mesh outline
   (:func:`layout.sampler.mesh_outline`, the pipeline's): median relative error per class and the 90th
   percentile of its absolute value (objects with at least 3000 visible pixels, first 60 rooms).
2. From the eval run (scene_init.json = the sampler's initial hypothesis, scene.json = its result): camera-height
   error at initialisation and after sampling; per class the share of objects whose retrieved model is the
   true one, and the median position error at initialisation of those with the right and the wrong model;
   medians with context term (position, orientation, share flipped by more than 90 degrees) and the
   wall-height error, also the part of it that the scale alone makes (estimated camera height with the true
   wall-to-camera-height ratio).
3. The ceiling estimate on the run's own labels with the gt boxes masked: lowest well-supported mode of the
   wall-to-camera ratio against the median ratio (mean absolute error, camera heights). Objects are paired with the ground truth by id (gt-boxes runs keep the gt ids).
"""

from __future__ import annotations

import sys as _sys
_sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parent))
from _docs import replace_section  # noqa: E402

import argparse
import json
from collections import defaultdict
from pathlib import Path

import numpy as np

from layout.sampler import DetectedObject, hull_outline, initialise_objects, mesh_outline
from posecrf.library import builtin_library

SECTION = "## Where the scale and position errors come from (Table 2 breakdown)"
CLASSES = ("bed", "chair", "tv", "plant", "nightstand", "table", "sofa", "wardrobe")


def _rooms(data: Path) -> list[Path]:
    return sorted(p for p in data.iterdir() if (p / "gt.json").is_file())


def cuboid_vs_outline(data: Path, rooms: int = 60, min_visible: int = 3000) -> dict[str, tuple[int, np.ndarray]]:
    """Per class: (objects, (3, N) relative camera-height errors with the cuboid, the hull and the mesh outline)."""
    lib = builtin_library()
    outlines: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    errs: dict[str, list[list[float]]] = defaultdict(list)
    for room in _rooms(data)[:rooms]:
        gt = json.loads((room / "gt.json").read_text())
        h, w, hh = gt["camera_height_m"], gt["image"]["width"], gt["image"]["height"]
        for o in gt["objects"]:
            if o["bbox_pano"] is None or o["visible_px"] < min_visible * (w * hh) / (1024 * 512):
                continue
            if o["model"] not in outlines:
                m = lib[o["model"]]
                outlines[o["model"]] = (hull_outline(m.vertices), mesh_outline(m.vertices, m.faces))
            yaw = np.radians(o["yaw_deg"])
            dets = [DetectedObject(o["class"], o["bbox_pano"], o["size"], yaw, outline=ol)
                    for ol in (None, *outlines[o["model"]])]
            errs[o["class"]].append([d / h - 1 for d in initialise_objects(dets, w, hh).fitted_camera_heights])
    return {c: (len(v), np.array(v).T) for c, v in errs.items()}


def run_breakdown(data: Path, run: Path) -> dict:
    """Camera height before / after sampling, model retrieval and position / orientation medians of a run."""
    cam_init, cam_final, wall, wall_scale, names, ratio = [], [], [], [], [], []
    per: dict[str, dict[str, list]] = defaultdict(lambda: defaultdict(list))
    for room in _rooms(data):
        out = run / room.name
        if not (out / "scene.json").is_file() or not (out / "scene_init.json").is_file():
            continue
        gt = json.loads((room / "gt.json").read_text())
        init = json.loads((out / "scene_init.json").read_text())
        final = json.loads((out / "scene.json").read_text())
        h = gt["camera_height_m"]
        cam_init.append(init["camera"]["height_m"] / h - 1)
        cam_final.append(final["camera"]["height_m"] / h - 1)
        wall_gt = gt["room"]["ceiling_z"] - gt["room"].get("floor_z", 0.0)
        wall.append(abs((final["room"]["ceiling_z"] - final["room"]["floor_z"]) - wall_gt))
        # the part of the error that is the scale's: the wall height at the true wall-to-camera-height ratio
        wall_scale.append(abs(final["camera"]["height_m"] / h - 1) * wall_gt)
        names.append(room.name)
        # error of the layout's wall-to-camera-height ratio (the scale does not change it), camera heights
        ratio.append((final["room"]["ceiling_z"] - final["room"]["floor_z"]) / final["camera"]["height_m"]
                     - wall_gt / h)
        truth = {o["id"]: o for o in gt["objects"]}
        for which, scene in (("init", init), ("final", final)):
            for o in scene["objects"]:
                t = truth.get(o["id"])
                if t is None:
                    continue
                d = per[t["class"]]
                err = float(np.hypot(*(np.array(o["center"][:2]) - t["center"][:2])))
                d[f"pos_{which}"].append(err)
                if which == "init":
                    d["right_model"].append(o["model"] == t["model"])
                elif t.get("symmetry", "none") != "full" and t["class"] != "plant":
                    diff = abs((o["yaw_deg"] - t["yaw_deg"] + 180.0) % 360.0 - 180.0)
                    if t.get("symmetry") == "two":  # a 2-fold symmetric model looks the same turned by 180 deg
                        diff = min(diff, 180.0 - diff)
                    d["orient"].append(diff)
    return {"cam_init": np.array(cam_init), "cam_final": np.array(cam_final), "wall": np.array(wall),
            "wall_scale": np.array(wall_scale), "names": names, "ratio": np.array(ratio), "per": per}


def ceiling_estimates(data: Path, run: Path) -> dict[str, float]:
    """Mean absolute ceiling error (camera heights) of the run's own labels (``label_ids.png``) with the gt boxes
    masked, for the two ceiling estimates of :func:`layout.roomgeom.estimate_room_geometry`."""
    from PIL import Image

    from layout.likelihood import boxes_mask
    from layout.roomgeom import RoomGeometryError, estimate_room_geometry

    errs: dict[str, list[float]] = {"lowest_mode": [], "median": []}
    for room in _rooms(data):
        f = run / room.name / "label_ids.png"
        if not f.is_file():
            continue
        gt = json.loads((room / "gt.json").read_text())
        lab = np.array(Image.open(f))
        boxes = [o["bbox_pano"] for o in gt["objects"] if o["bbox_pano"] is not None]
        mask = boxes_mask(np.array(boxes, float), lab.shape[1]) if boxes else None
        truth = gt["room"]["ceiling_z"] / gt["camera_height_m"]
        for mode, v in errs.items():
            try:
                v.append(abs(estimate_room_geometry(lab, 1.0, object_mask=mask, ceiling_estimate=mode).ceiling_z
                             - truth))
            except RoomGeometryError:
                continue
    return {m: float(np.mean(v)) for m, v in errs.items() if v}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("data", type=Path, help="the synthetic set (pano2cad synth output)")
    ap.add_argument("run", type=Path, help="a pano2cad eval --out folder of that set (gt-boxes)")
    ap.add_argument("--update-docs", action="store_true", help="write the section into docs/EVALUATION.md")
    args = ap.parse_args(argv)

    bias = cuboid_vs_outline(args.data)
    br = run_breakdown(args.data, args.run)
    lines = [SECTION, "",
             f"`.venv/bin/python benchmarks/eval_scale.py {args.data} {args.run} --update-docs` (this section is "
             "written by the script; see its docstring).", "",
             "Camera height of single objects from their gt box, true model and yaw (median relative error, and the 90th "
             "percentile of its absolute value):", "",
             "| class | objects | cuboid | hull outline | mesh outline | hull, 90th percentile of abs. error "
             "| mesh, 90th percentile |", "|---|---:|---:|---:|---:|---:|---:|"]
    for c in CLASSES:
        if c in bias:
            n, e = bias[c]
            med, p90 = np.median(e, axis=1), np.percentile(np.abs(e), 90, axis=1)
            lines.append(f"| {c} | {n} | {med[0]:+.1%} | {med[1]:+.1%} | {med[2]:+.1%} | {p90[1]:.1%} | {p90[2]:.1%} |")
    ci, cf = br["cam_init"], br["cam_final"]
    lines += ["", f"Camera height of the run ({len(ci)} rooms): median error {np.median(ci):+.1%} at initialisation "
              f"(mean absolute {np.mean(np.abs(ci)):.1%}), {np.median(cf):+.1%} after sampling (mean absolute "
              f"{np.mean(np.abs(cf)):.1%}); wall-height error median {100 * np.median(br['wall']):.1f} cm, mean "
              f"{100 * np.mean(br['wall']):.1f} cm; the scale's part alone (the estimated camera height times the "
              f"true wall-to-camera-height ratio) mean {100 * np.mean(br['wall_scale']):.1f} cm, the rest is the "
              "layout's ceiling estimate.", "",
              "Rooms with the largest wall-height errors: " + "; ".join(
                  f"{br['names'][i]} {100 * br['wall'][i]:.0f} cm (camera height {br['cam_final'][i]:+.1%}, "
                  f"wall-to-camera ratio {br['ratio'][i]:+.2f})" for i in np.argsort(-br["wall"])[:5]) + ".", "",
              "Ceiling of the run's labels with the gt boxes masked, mean absolute error in camera heights: "
              + ", ".join(f"{m.replace('_', ' ')} {e:.4f}" for m, e in ceiling_estimates(args.data, args.run).items())
              + " (the pipeline uses the median ratio when objects are masked).", "",
              "| class | right model | position at init, right / wrong model (median cm) | position with context "
              "(median cm) | orientation with context (median deg) | flipped > 90 deg |",
              "|---|---:|---:|---:|---:|---:|"]
    for c in CLASSES:
        d = br["per"].get(c)
        if not d:
            continue
        right = np.array(d["right_model"], bool)
        pos = np.array(d["pos_init"])
        r = f"{100 * np.median(pos[right]):.0f}" if right.any() else "n/a"
        wr = f"{100 * np.median(pos[~right]):.0f}" if (~right).any() else "n/a"
        o = np.array(d["orient"])
        ori = f"{np.median(o):.1f}" if o.size else "n/a"
        flip = f"{np.mean(o > 90):.0%}" if o.size else "n/a"
        lines.append(f"| {c} | {right.mean():.0%} ({right.sum()}/{len(right)}) | {r} / {wr} | "
                     f"{100 * np.median(d['pos_final']):.1f} | {ori} | {flip} |")
    text = "\n".join(lines) + "\n"
    print(text)
    if args.update_docs:
        replace_section(Path(__file__).resolve().parents[1] / "docs" / "EVALUATION.md", text, SECTION)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
