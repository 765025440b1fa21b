"""How well a detector's boxes fit the objects' outlines at the true pose: the input of the model choice by box fit.

Run::

    pano2cad synth --rooms 30 --seed 7000 --size 1024 --out out/tune7000
    .venv/bin/python benchmarks/eval_box_edges.py out/tune7000 [--rooms 30] [--update-docs]

For every object of the set with at least 2000 visible pixels that the builtin detector finds (same class,
panorama-box IoU > 0.5 with its gt box), the four box edges are compared with the object's TRUE model outline
(:func:`layout.sampler.mesh_outline`, as in the pipeline; before session 28 the convex hull) at its true
position, yaw and camera height, two ways:

* as great circles (planes through the camera; :meth:`detect.detection.TileBox.edge_planes`): the angle by which
  the outline's extreme point lies inside each plane (0: the box edge touches the object); edges at the tile
  border are left out;
* the same, each edge the median over the tiles that see the object whole (``Detection.views``, what the
  pipeline's box fits use; objects seen whole by one tile only keep that tile's edges);
* each edge moved onto the object's grab-cut silhouette where it confirms the detector's edge within 3 degrees
  (:func:`detect.grabcut.silhouette_box`, what the pipeline's box fits use by default since session 18), the
  median over the views as above;
* with ``--refine``: every tile box refined by the box-edge network (:class:`detect.builtin.refine.BoxRefiner`,
  what the pipeline's box fits use by default since session 39), the median over the views as above; and the
  same, then moved onto the grab-cut silhouette;
* as the panorama box (lon/lat extent, ``Detection.box``): predicted minus detected edge angle.

Also printed per mode: the mean absolute residual, the share of edges within 0.5 degree of the outline and the
share more than 2 degrees off.

Printed per class and overall: median and median absolute deviation (MAD) per edge (left, top, right, bottom),
degrees. This is where the edge scale of :mod:`layout.modelfit` and the choice of great-circle edges come from.
"""

from __future__ import annotations

import sys as _sys
_sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parent))
from _docs import EVALUATION_MD, publish  # noqa: E402

import argparse
import json
from collections import defaultdict
from pathlib import Path

import numpy as np
from PIL import Image

SECTION = "## Detector box edges against the true outlines (model choice input)"


def measure(data: Path, rooms: int, min_visible: int = 2000, refine: Path | None = None) -> dict[str, dict[str, list]]:
    """Per mode ('planes', 'pano box', ...) and class: list of (4,) residuals in degrees (NaN: edge left out).
    With ``refine`` (weights of :class:`detect.builtin.refine.BoxRefiner`), also the refined edges."""
    from detect.backends import get_detector
    from detect.nms import pano_box_iou
    from detect.grabcut import silhouette_box
    from detect.tiles import detect_panorama
    from layout.sampler import DetectedObject, _BoxEdges, mesh_outline
    from posecrf.library import builtin_library

    lib = builtin_library()
    outlines: dict[str, np.ndarray] = {}
    det = get_detector("builtin")
    views = det.views()
    modes = ["planes", "planes, median of views", "silhouette, median of views", "pano box"]
    refiner = None
    if refine is not None:
        from detect.builtin.refine import BoxRefiner

        refiner = BoxRefiner(refine)
        modes[3:3] = ["network, median of views", "network + silhouette, median of views"]
    out: dict[str, dict[str, list]] = {m: defaultdict(list) for m in modes}
    for room in sorted(p for p in data.iterdir() if (p / "gt.json").is_file())[:rooms]:
        gt = json.loads((room / "gt.json").read_text())
        img = np.array(Image.open(room / gt["image"].get("file", "pano.png")).convert("RGB"))
        W, H = img.shape[1], img.shape[0]
        dets = [d for d in detect_panorama(img, det, views=views) if d.tile is not None]
        cam = float(gt["camera_height_m"])
        for o in gt["objects"]:
            if o["bbox_pano"] is None or o["visible_px"] < min_visible * (W * H) / (1024 * 512):
                continue
            same = [d for d in dets if d.label == o["class"]]
            if not same:
                continue
            iou = pano_box_iou(np.stack([d.box for d in same]), np.array([o["bbox_pano"]], float), W, H)[:, 0]
            if iou.max() <= 0.5:
                continue
            d = same[int(np.argmax(iou))]
            if o["model"] not in outlines:
                outlines[o["model"]] = mesh_outline(lib[o["model"]].vertices, lib[o["model"]].faces)
            yaw = np.radians(o["yaw_deg"])
            xy = np.array(o["center"], float)[None, None, :2]
            sets = d.edge_planes()
            sil = silhouette_box(img, d)
            modes = [("planes", d.tile.edge_planes()), ("planes, median of views", sets),
                     ("silhouette, median of views", sets if sil is None else sil.edge_planes()), ("pano box", None)]
            if refiner is not None:
                rd = refiner.refine(img, d)
                rsil = silhouette_box(img, rd)
                modes[3:3] = [("network, median of views", rd.edge_planes()),
                              ("network + silhouette, median of views",
                               rd.edge_planes() if rsil is None else rsil.edge_planes())]
            for mode, planes in modes:
                obj = DetectedObject(o["class"], d.box, o["size"], yaw, outline=outlines[o["model"]],
                                     edge_planes=planes)
                r = np.degrees(_BoxEdges([obj], W, H).residual(xy, np.array([[yaw]]), np.array([[cam]]))[0, 0])
                if planes is not None:
                    r[d.tile.border_edges()] = np.nan
                out[mode][o["class"]].append(r)
                out[mode]["all"].append(r)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("data", type=Path, help="a synthetic set (pano2cad synth output), not the evaluation set")
    ap.add_argument("--rooms", type=int, default=30)
    from detect.builtin.refine import DEFAULT_REFINE_WEIGHTS

    ap.add_argument("--refine", type=Path, nargs="?", const=DEFAULT_REFINE_WEIGHTS,
                    help="also the edges of the box-edge network (detect.builtin.refine; default: its committed "
                         "weights)")
    ap.add_argument("--update-docs", action="store_true", help="write the section into docs/EVALUATION.md")
    args = ap.parse_args(argv)
    res = measure(args.data, args.rooms, refine=args.refine)
    lines = [SECTION, "",
             f"`.venv/bin/python benchmarks/eval_box_edges.py {args.data} --rooms {args.rooms}"
             f"{' --refine' if args.refine else ''} --update-docs` (this "
             "section is written by the script; see its docstring). Builtin detector, objects with at least 2000 "
             "visible pixels found by it; residuals at the true model, pose and camera height, degrees (left, top, "
             "right, bottom).", "",
             "| edges as | class | objects | median | MAD | mean absolute | within 0.5 deg | over 2 deg |",
             "|---|---|---:|---|---|---|---|---|"]
    for mode, per in res.items():
        for cls in ["all"] + sorted(c for c in per if c != "all"):
            v = np.array(per[cls], float)
            med = np.nanmedian(v, axis=0)
            mad = np.nanmedian(np.abs(v - med), axis=0)
            a, known = np.abs(v), np.isfinite(v)
            near = np.sum((a < 0.5) & known, axis=0) / np.maximum(known.sum(axis=0), 1)
            far = np.sum((a > 2.0) & known, axis=0) / np.maximum(known.sum(axis=0), 1)
            mean = np.nanmean(a, axis=0)
            lines.append(f"| {mode} | {cls} | {len(v)} | {' / '.join(f'{x:+.2f}' for x in med)} | "
                         f"{' / '.join(f'{x:.2f}' for x in mad)} | {' / '.join(f'{x:.2f}' for x in mean)} | "
                         f"{' / '.join(f'{x:.2f}' for x in near)} | "
                         f"{' / '.join(f'{x:.2f}' for x in far)} |")
    publish(lines, args.update_docs, EVALUATION_MD, SECTION)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
